//! A smoltcp device that shows every received frame to the board's own
//! listeners before smoltcp takes it (feature `smoltcp`): the camera's
//! table of peers and ICMP notes ([`Snooped`](crate::camera::service::Snooped)),
//! the link-local claim's and the housekeeping's notes ([`LinkNotes`](crate::address::assign::LinkNotes)).
//! smoltcp 0.14 keeps its neighbour cache and ARP handling to itself, and
//! answers no ARP from 0.0.0.0, so these learn from the frames instead.

use smoltcp::phy::{self, Device, DeviceCapabilities};
use smoltcp::time::Instant;

/// Something that learns from received Ethernet frames.
pub trait Learn {
    /// Look at one received frame (any kind; ignore what does not matter).
    fn learn(&mut self, frame: &[u8]);
}

impl<L: Learn + ?Sized> Learn for &mut L {
    fn learn(&mut self, frame: &[u8]) {
        (**self).learn(frame)
    }
}

impl<A: Learn, B: Learn> Learn for (A, B) {
    fn learn(&mut self, frame: &[u8]) {
        self.0.learn(frame);
        self.1.learn(frame);
    }
}

/// Frames received from another device that sends with the board's own
/// MAC address: two boards made from one card image (whose `mac=` line is
/// the same) on one network. A switch never sends a station its own
/// frames back, so any such frame is another device's; both boards then
/// lose frames as the switch moves the address between its ports.
#[derive(Clone, Copy, Debug)]
pub struct MacClashes {
    own: [u8; 6],
    /// Frames seen so far.
    pub count: u32,
}

impl MacClashes {
    /// Watch for `own` as a source address.
    pub const fn new(own: [u8; 6]) -> MacClashes {
        MacClashes { own, count: 0 }
    }
}

impl Learn for MacClashes {
    fn learn(&mut self, frame: &[u8]) {
        if frame.get(6..12) == Some(&self.own[..]) {
            self.count = self.count.saturating_add(1);
        }
    }
}

/// A smoltcp device whose received frames `peers` sees first.
pub struct Snoop<'d, D, L> {
    /// The device.
    pub inner: &'d mut D,
    /// What learns from its frames.
    pub peers: &'d mut L,
}

/// A received frame's token, shown to the learner on its way in.
pub struct SnoopRx<'p, R, L> {
    inner: R,
    peers: &'p mut L,
}

impl<R: phy::RxToken, L: Learn> phy::RxToken for SnoopRx<'_, R, L> {
    fn consume<T, F: FnOnce(&[u8]) -> T>(self, f: F) -> T {
        let peers = self.peers;
        self.inner.consume(|frame| {
            peers.learn(frame);
            f(frame)
        })
    }
}

impl<D: Device, L: Learn> Device for Snoop<'_, D, L> {
    type RxToken<'a>
        = SnoopRx<'a, D::RxToken<'a>, L>
    where
        Self: 'a;
    type TxToken<'a>
        = D::TxToken<'a>
    where
        Self: 'a;

    fn receive(&mut self, timestamp: Instant) -> Option<(Self::RxToken<'_>, Self::TxToken<'_>)> {
        let (rx, tx) = self.inner.receive(timestamp)?;
        Some((SnoopRx { inner: rx, peers: self.peers }, tx))
    }

    fn transmit(&mut self, timestamp: Instant) -> Option<Self::TxToken<'_>> {
        self.inner.transmit(timestamp)
    }

    fn capabilities(&self) -> DeviceCapabilities {
        self.inner.capabilities()
    }
}

/// TCP connection attempts (a SYN without ACK) to some ports, noted as
/// they arrive: a service whose sockets all listen ([`FrameService::quiet`],
/// [`WebService::quiet`]) has nothing to do until one comes for its port
/// (smoltcp moves a listening socket only on a SYN), so the main loop
/// skips it meanwhile.
///
/// [`FrameService::quiet`]: crate::seed::service::FrameService::quiet
/// [`WebService::quiet`]: crate::web::service::WebService::quiet
#[derive(Clone, Debug)]
pub struct SynWatch<const N: usize> {
    ports: [u16; N],
    seen: u32,
}

impl<const N: usize> SynWatch<N> {
    /// Watch `ports` (at most 32).
    pub const fn new(ports: [u16; N]) -> SynWatch<N> {
        assert!(N <= 32);
        SynWatch { ports, seen: 0 }
    }

    /// Whether a SYN to `ports[i]` arrived since the last call for it.
    pub fn take(&mut self, i: usize) -> bool {
        let bit = 1u32 << i;
        let seen = self.seen & bit != 0;
        self.seen &= !bit;
        seen
    }
}

impl<const N: usize> Learn for SynWatch<N> {
    /// Read straight from the bytes (Ethernet II, IPv4, TCP; RFC 791 and
    /// RFC 9293 layouts): this runs on every received frame.
    fn learn(&mut self, frame: &[u8]) {
        // Ethertype IPv4, protocol TCP.
        if frame.len() < 14 + 20 + 20 || frame[12..14] != [0x08, 0x00] || frame[14 + 9] != 6 {
            return;
        }
        let tcp = 14 + usize::from(frame[14] & 0x0f) * 4;
        let Some(header) = frame.get(tcp..tcp + 14) else { return };
        // Flags: SYN set, ACK clear.
        if header[13] & 0x12 != 0x02 {
            return;
        }
        let port = u16::from_be_bytes([header[2], header[3]]);
        if let Some(i) = self.ports.iter().position(|p| *p == port) {
            self.seen |= 1 << i;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An Ethernet/IPv4/TCP frame to `port` with `flags`.
    fn segment(port: u16, flags: u8) -> std::vec::Vec<u8> {
        let mut f = std::vec![0u8; 14 + 20 + 20];
        f[12] = 0x08;
        f[14] = 0x45;
        f[14 + 9] = 6;
        f[34 + 2..34 + 4].copy_from_slice(&port.to_be_bytes());
        f[34 + 12] = 0x50;
        f[34 + 13] = flags;
        f
    }

    /// A frame whose source is the board's own MAC is another device's;
    /// frames from others, to the board or anywhere, are not counted.
    #[test]
    fn frames_from_another_device_with_our_mac_are_counted() {
        const OWN: [u8; 6] = [0x02, 0xde, 0x1c, 0, 0x46, 0x0a];
        let mut c = MacClashes::new(OWN);
        let mut frame = segment(80, 0x02);
        frame[..6].copy_from_slice(&OWN);
        frame[6..12].copy_from_slice(&[0x02, 0, 0, 0, 0, 1]);
        c.learn(&frame);
        c.learn(&frame[..10]);
        assert_eq!(c.count, 0, "to us, from another MAC; a runt");
        frame[..6].fill(0xff);
        frame[6..12].copy_from_slice(&OWN);
        c.learn(&frame);
        c.learn(&frame);
        assert_eq!(c.count, 2);
    }

    #[test]
    fn only_a_syn_to_a_watched_port_is_noted_once() {
        let mut w = SynWatch::new([7878, 80]);
        w.learn(&segment(80, 0x12));
        w.learn(&segment(80, 0x10));
        w.learn(&segment(8554, 0x02));
        assert!(!w.take(0) && !w.take(1), "a SYN-ACK, an ACK, another port");
        w.learn(&segment(80, 0x02));
        assert!(!w.take(0));
        assert!(w.take(1));
        assert!(!w.take(1), "taken");
        let mut udp = segment(7878, 0x02);
        udp[14 + 9] = 17;
        w.learn(&udp);
        w.learn(&segment(7878, 0x02)[..40]);
        assert!(!w.take(0), "UDP, a cut frame");
    }
}
