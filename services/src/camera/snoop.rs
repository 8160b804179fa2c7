//! What the frames the board receives tell the network camera.
//!
//! RTP leaves beside smoltcp, so its Ethernet header needs the client's (or
//! its gateway's) MAC address, and smoltcp 0.14 keeps its neighbour cache
//! to itself. [`Snooped`] learns the same thing from the frames that
//! arrive: the source MAC of the client's own IPv4 packets (its RTSP
//! connection) is the next hop towards it. It also notes ICMP port
//! unreachable about the camera's RTP packets (a crashed player's host
//! answers each with one): smoltcp's ICMP socket bound to a UDP port
//! checks the quoted UDP header's length against the quote, and a host
//! quotes at most 576 bytes of a 1,488-byte datagram (RFC 1812 section
//! 4.3.2.3; Linux quotes 528 of its payload), so it would never match.
//! [`Snoop`](crate::snoop::Snoop) wraps the MAC's smoltcp device to feed the table.

use core::net::Ipv4Addr;

use smoltcp::wire::{
    EthernetAddress, EthernetFrame, EthernetProtocol, Icmpv4Message, Icmpv4Packet, IpProtocol, Ipv4Packet, UdpPacket,
};

/// Peers remembered by [`Snooped`].
pub const PEERS: usize = 8;

/// ICMP port unreachable notes [`Snooped`] keeps until the service takes
/// them (more in one main-loop pass are dropped: the sender needs three).
pub const UNREACHABLE_NOTES: usize = 8;

/// What the received frames tell the camera: each peer's next-hop MAC
/// address (the newest [`PEERS`]), and the ICMP port unreachable answers
/// to its RTP packets.
#[derive(Clone, Debug)]
pub struct Snooped {
    entries: heapless::Deque<(Ipv4Addr, EthernetAddress), PEERS>,
    unreachable: heapless::Deque<Unreachable, UNREACHABLE_NOTES>,
    rtp_port: u16,
    /// Frames seen (wrapping): the caller stirs its clock into the camera's
    /// entropy when this moves ([`random::TimingPool`](super::random::TimingPool)).
    frames: u32,
}

/// An ICMP port unreachable about one of the camera's RTP packets, as
/// [`Snooped`] checked it: sent by the host the packet went to, quoting
/// the packet's ports and its RTP header's SSRC.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Unreachable {
    /// The client's address (the ICMP message's sender and the quoted
    /// packet's destination).
    pub client: Ipv4Addr,
    /// The quoted packet's destination port.
    pub port: u16,
    /// The quoted packet's SSRC: the stream it belongs to.
    pub ssrc: u32,
}

impl Snooped {
    /// Nothing learnt; port unreachable is noted for packets that left
    /// from `rtp_port`.
    pub const fn new(rtp_port: u16) -> Snooped {
        Snooped { entries: heapless::Deque::new(), unreachable: heapless::Deque::new(), rtp_port, frames: 0 }
    }

    /// Learn from one received Ethernet frame (anything but IPv4 is
    /// ignored, as are broadcast and multicast sources).
    pub fn learn(&mut self, frame: &[u8]) {
        self.frames = self.frames.wrapping_add(1);
        let Ok(eth) = EthernetFrame::new_checked(frame) else { return };
        if eth.ethertype() != EthernetProtocol::Ipv4 || !eth.src_addr().is_unicast() {
            return;
        }
        let Ok(ip) = Ipv4Packet::new_checked(eth.payload()) else { return };
        if ip.next_header() == IpProtocol::Icmp {
            self.note_unreachable(ip.src_addr(), ip.payload());
        }
        let (addr, mac) = (ip.src_addr(), eth.src_addr());
        if self.lookup(addr) == Some(mac) {
            return;
        }
        if let Some(i) = self.entries.iter().position(|(a, _)| *a == addr) {
            // Moved: forget the old entry (rare; keeps the order simple).
            let mut kept = heapless::Deque::new();
            for (j, e) in self.entries.iter().enumerate() {
                if j != i {
                    let _ = kept.push_back(*e);
                }
            }
            self.entries = kept;
        }
        if self.entries.is_full() {
            self.entries.pop_front();
        }
        let _ = self.entries.push_back((addr, mac));
    }

    /// An ICMP message from `sender`: destination unreachable, port
    /// unreachable (RFC 792 type 3 code 3), quoting a UDP datagram that
    /// left from our RTP port to `sender` itself (a port is unreachable
    /// only on the host that has it: anyone else's word is forged), with
    /// the RTP header's SSRC in the quote, so that the camera can check the
    /// packet was its stream's. RFC 792 promises only the UDP header, but
    /// current hosts quote up to 576 bytes (RFC 1812, section 4.3.2.3; Linux's
    /// `icmp_send`); a quote without the SSRC is not trusted.
    fn note_unreachable(&mut self, sender: Ipv4Addr, icmp: &[u8]) {
        let Ok(msg) = Icmpv4Packet::new_checked(icmp) else { return };
        if msg.msg_type() != Icmpv4Message::DstUnreachable || msg.msg_code() != 3 {
            return;
        }
        // The quote is cut short of the datagram's total length: only its
        // header is checked.
        let data = msg.data();
        if data.len() < 20 || data[0] >> 4 != 4 {
            return;
        }
        let quoted = Ipv4Packet::new_unchecked(data);
        let header = usize::from(quoted.header_len());
        if header < 20 || quoted.next_header() != IpProtocol::Udp {
            return;
        }
        if quoted.dst_addr() != sender {
            return;
        }
        // The UDP header, then the RTP header's first 12 bytes (SSRC last).
        let Some(udp) = msg.data().get(header..header + 8 + 12) else { return };
        let ssrc = u32::from_be_bytes([udp[16], udp[17], udp[18], udp[19]]);
        let udp = UdpPacket::new_unchecked(udp);
        if udp.src_port() == self.rtp_port && !self.unreachable.is_full() {
            let _ = self.unreachable.push_back(Unreachable { client: sender, port: udp.dst_port(), ssrc });
        }
    }

    /// The next hop towards `addr`, if a frame from it was seen.
    pub fn lookup(&self, addr: Ipv4Addr) -> Option<EthernetAddress> {
        self.entries.iter().rev().find(|(a, _)| *a == addr).map(|(_, m)| *m)
    }

    /// Frames received so far (wrapping).
    pub const fn frames_seen(&self) -> u32 {
        self.frames
    }

    /// The next port unreachable noted.
    pub fn take_unreachable(&mut self) -> Option<Unreachable> {
        self.unreachable.pop_front()
    }
}

impl crate::snoop::Learn for Snooped {
    fn learn(&mut self, frame: &[u8]) {
        Snooped::learn(self, frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec;
    use std::vec::Vec;

    /// An Ethernet frame from `sender` carrying ICMP `kind`/`code` about a
    /// UDP datagram from 10.0.2.15 port `src` to 10.0.2.2:`dst`, quoting
    /// `quote` bytes of it (past its IPv4 header; the RTP header's bytes,
    /// SSRC included, are 0xaa).
    fn icmp_frame(sender: [u8; 4], kind: u8, code: u8, src: u16, dst: u16, quote: usize) -> Vec<u8> {
        let mut quoted = vec![0x45, 0, 0x05, 0xd0, 0, 0, 0x40, 0, 64, 17, 0, 0, 10, 0, 2, 15, 10, 0, 2, 2];
        quoted.extend_from_slice(&src.to_be_bytes());
        quoted.extend_from_slice(&dst.to_be_bytes());
        quoted.extend_from_slice(&1_468u16.to_be_bytes());
        quoted.extend_from_slice(&[0, 0]);
        quoted.resize(20 + quote, 0xaa);
        let mut icmp = vec![kind, code, 0, 0, 0, 0, 0, 0];
        icmp.extend_from_slice(&quoted);
        let sum = !smoltcp::wire::checksum::data(&icmp);
        icmp[2..4].copy_from_slice(&sum.to_be_bytes());
        let total = (20 + icmp.len()) as u16;
        let mut ip = vec![0x45, 0, (total >> 8) as u8, total as u8, 0, 0, 0, 0, 64, 1, 0, 0];
        ip.extend_from_slice(&sender);
        ip.extend_from_slice(&[10, 0, 2, 15]);
        let sum = !smoltcp::wire::checksum::data(&ip);
        ip[10..12].copy_from_slice(&sum.to_be_bytes());
        let mut frame = vec![0x02, 0, 0, 0, 0, 1, 0x52, 0x54, 0, 0x12, 0x34, 0x57, 0x08, 0x00];
        frame.extend_from_slice(&ip);
        frame.extend_from_slice(&icmp);
        frame
    }

    const CLIENT: [u8; 4] = [10, 0, 2, 2];

    #[test]
    fn port_unreachable_about_an_rtp_packet_is_noted_and_the_next_hop_learnt() {
        let mut s = Snooped::new(5004);
        s.learn(&icmp_frame(CLIENT, 3, 3, 5004, 6000, 528));
        let noted = Unreachable { client: Ipv4Addr::new(10, 0, 2, 2), port: 6000, ssrc: 0xaaaa_aaaa };
        assert_eq!(s.take_unreachable(), Some(noted), "a truncated quote is enough");
        assert_eq!(s.lookup(Ipv4Addr::new(10, 0, 2, 2)), Some(EthernetAddress([0x52, 0x54, 0, 0x12, 0x34, 0x57])));
        s.learn(&icmp_frame(CLIENT, 3, 3, 5004, 6000, 20));
        assert_eq!(s.take_unreachable(), Some(noted), "the UDP header and the RTP header up to the SSRC");
        for (kind, code, src) in [(3, 1, 5004), (11, 0, 5004), (3, 3, 5005), (0, 0, 5004)] {
            s.learn(&icmp_frame(CLIENT, kind, code, src, 6000, 20));
            assert_eq!(s.take_unreachable(), None, "{kind}/{code} from {src}");
        }
        s.learn(&icmp_frame(CLIENT, 3, 3, 5004, 6000, 4));
        assert_eq!(s.take_unreachable(), None, "no whole UDP header quoted");
    }

    #[test]
    fn port_unreachable_from_anyone_but_the_client_or_without_the_ssrc_is_not_believed() {
        let mut s = Snooped::new(5004);
        s.learn(&icmp_frame([10, 0, 2, 3], 3, 3, 5004, 6000, 528));
        assert_eq!(s.take_unreachable(), None, "a third host's word about 10.0.2.2's port");
        s.learn(&icmp_frame([192, 168, 7, 7], 3, 3, 5004, 6000, 528));
        assert_eq!(s.take_unreachable(), None, "a router's or a stranger's");
        s.learn(&icmp_frame(CLIENT, 3, 3, 5004, 6000, 8));
        assert_eq!(s.take_unreachable(), None, "the UDP header alone: whose stream is not known");
    }
}
