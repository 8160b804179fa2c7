//! A smoltcp device that shows every received frame to the board's own
//! listeners before smoltcp takes it (feature `smoltcp`): the camera's
//! table of peers and ICMP notes ([`Snooped`](crate::camera::service::Snooped)),
//! the link-local claim's ARP notes ([`ArpNotes`](crate::address::assign::ArpNotes)).
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
