//! Test support: a model of the GMAC's transmit checksum engine, written
//! from the databook text (STM32 RM0090 rev 21, 33.5.2 "Transmit checksum
//! offload", pp. 1144-1146, the same Synopsys GMAC core as the Cyclone V
//! EMAC; CIC encodings from its TDES0 description, bits 23:22), so that a
//! frame the driver hands over can be checked as it would leave the wire.
//!
//! What the text says, and how it is modelled:
//!
//! * CIC 0: nothing is inserted.
//! * IP header checksum (CIC 1, 2, 3): an IPv4 datagram is detected by
//!   EtherType 0x0800 and version 4; "the input frame's checksum field is
//!   ignored during calculation and replaced by the calculated value".
//! * TCP/UDP/ICMP checksum (CIC 2, 3): payloads other than TCP, UDP and
//!   ICMP, and fragmented IP frames, are bypassed. Two modes:
//!   - first mode (CIC 2, "pseudo-header checksum is not calculated in
//!     hardware"): "the pseudo-header is not included in the checksum
//!     calculation and is assumed to be present in the input frame's
//!     checksum field. The checksum field is included in the checksum
//!     calculation, and then replaced by the final calculated checksum."
//!   - second mode (CIC 3): "the checksum field is ignored, the TCP, UDP, or
//!     ICMPv6 pseudo-header data are included into the checksum calculation,
//!     and the checksum field is overwritten with the final calculated
//!     value."
//!   - "for ICMP-over-IPv4 packets, the checksum field in the ICMP packet
//!     must always be 0x0000 in both modes, because pseudo-headers are not
//!     defined for such packets. If it does not equal 0x0000, an incorrect
//!     checksum may be inserted." The text names no mechanism; the model
//!     takes the one the first mode describes, the only one the text gives
//!     for a field that is not ignored: for ICMPv4, in both modes, the
//!     existing field is summed with the message and replaced by the
//!     complement. A zero field gives the right checksum; a correct one
//!     sums to 0xFFFF and is replaced by 0x0000, which is wrong.
//! * The payload length comes from the IP header's total length.
//!
//! Not modelled (the firmware sends none of it): IPv6, VLAN tags, IP
//! options beyond IHL, the 0 -> 0xFFFF rule of UDP (the text does not say),
//! the transmit status bits.

use crate::desc::ChecksumInsertion;

const ETH_HEADER: usize = 14;
const PROTO_ICMP: u8 = 1;
const PROTO_TCP: u8 = 6;
const PROTO_UDP: u8 = 17;

/// One's-complement sum of `data` as big-endian 16-bit words (odd length:
/// padded with a zero byte), folded to 16 bits (RFC 1071).
pub fn ones_sum(mut acc: u32, data: &[u8]) -> u16 {
    let mut chunks = data.chunks_exact(2);
    for w in &mut chunks {
        acc += u32::from(u16::from_be_bytes([w[0], w[1]]));
    }
    if let [last] = chunks.remainder() {
        acc += u32::from(*last) << 8;
    }
    while acc > 0xffff {
        acc = (acc & 0xffff) + (acc >> 16);
    }
    acc as u16
}

/// What the engine did to a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Done {
    /// Nothing (CIC 0, or not IPv4).
    Nothing,
    /// The IPv4 header checksum only.
    Header,
    /// The IPv4 header checksum and the payload's.
    HeaderAndPayload,
}

/// Run the engine over `frame` (Ethernet header on, no FCS) as CIC `cic`
/// asks, in place.
pub fn insert(frame: &mut [u8], cic: ChecksumInsertion) -> Done {
    if cic == ChecksumInsertion::Off || frame.len() < ETH_HEADER + 20 {
        return Done::Nothing;
    }
    if frame[12..14] != [0x08, 0x00] || frame[ETH_HEADER] >> 4 != 4 {
        return Done::Nothing;
    }
    let ip = &mut frame[ETH_HEADER..];
    let ihl = usize::from(ip[0] & 0x0f) * 4;
    if ihl < 20 || ip.len() < ihl {
        return Done::Nothing;
    }
    // IP header: the field is ignored (taken as 0) and replaced.
    ip[10..12].fill(0);
    let h = !ones_sum(0, &ip[..ihl]);
    ip[10..12].copy_from_slice(&h.to_be_bytes());
    if cic == ChecksumInsertion::HeaderOnly {
        return Done::Header;
    }
    let total = usize::from(u16::from_be_bytes([ip[2], ip[3]]));
    let fragment = u16::from_be_bytes([ip[6], ip[7]]) & 0x3fff != 0;
    let protocol = ip[9];
    let field = match protocol {
        PROTO_TCP => 16,
        PROTO_UDP => 6,
        PROTO_ICMP => 2,
        _ => return Done::Header,
    };
    if fragment || total < ihl + field + 2 || ip.len() < total {
        return Done::Header;
    }
    let pseudo = {
        let len = (total - ihl) as u32;
        // Source and destination address, zero + protocol, length (RFC 793 3.1).
        u32::from(ones_sum(0, &ip[12..20])) + u32::from(protocol) + len
    };
    let payload = &mut ip[ihl..total];
    let second_mode = cic == ChecksumInsertion::Full;
    let sum = match (protocol, second_mode) {
        // ICMPv4, both modes: no pseudo-header; the field is not ignored.
        (PROTO_ICMP, _) => ones_sum(0, payload),
        // Second mode: field ignored, pseudo-header included.
        (_, true) => {
            payload[field..field + 2].fill(0);
            ones_sum(pseudo, payload)
        }
        // First mode: the field (holding the pseudo-header sum) included.
        (_, false) => ones_sum(0, payload),
    };
    payload[field..field + 2].copy_from_slice(&(!sum).to_be_bytes());
    Done::HeaderAndPayload
}

#[cfg(test)]
mod tests {
    use super::*;
    use smoltcp::phy::ChecksumCapabilities;
    use smoltcp::wire::{
        EthernetAddress, EthernetFrame, EthernetProtocol, EthernetRepr, Icmpv4Packet, Icmpv4Repr, IpProtocol,
        Ipv4Address, Ipv4Packet, Ipv4Repr, TcpControl, TcpPacket, TcpRepr, TcpSeqNumber,
    };
    use ChecksumInsertion::{Full, HeaderOnly, NoPseudoHeader, Off};

    const A: Ipv4Address = Ipv4Address::new(10, 0, 0, 1);
    const B: Ipv4Address = Ipv4Address::new(10, 0, 0, 2);

    /// An IPv4 frame around `payload_len` bytes written by `emit`, with
    /// checksums as `caps` says (smoltcp writes 0 where it leaves a field).
    fn ipv4_frame(protocol: IpProtocol, payload_len: usize, emit: impl FnOnce(&mut [u8])) -> Vec<u8> {
        let ip = Ipv4Repr { src_addr: A, dst_addr: B, next_header: protocol, payload_len, hop_limit: 64 };
        let eth = EthernetRepr {
            src_addr: EthernetAddress([2, 0, 0, 0, 0, 1]),
            dst_addr: EthernetAddress([2, 0, 0, 0, 0, 2]),
            ethertype: EthernetProtocol::Ipv4,
        };
        let mut f = vec![0u8; 14 + ip.buffer_len() + payload_len];
        let mut e = EthernetFrame::new_unchecked(&mut f[..]);
        eth.emit(&mut e);
        let mut p = Ipv4Packet::new_unchecked(e.payload_mut());
        let mut none = ChecksumCapabilities::ignored();
        none.ipv4 = smoltcp::phy::Checksum::None;
        ip.emit(&mut p, &none);
        emit(p.payload_mut());
        f
    }

    fn echo_reply(icmp_checksum_filled: bool) -> Vec<u8> {
        let data = [0x5a; 24];
        let r = Icmpv4Repr::EchoReply { ident: 0x1234, seq_no: 7, data: &data };
        ipv4_frame(IpProtocol::Icmp, r.buffer_len(), |b| {
            let mut caps = ChecksumCapabilities::ignored();
            if icmp_checksum_filled {
                caps.icmpv4 = smoltcp::phy::Checksum::Both;
            }
            r.emit(&mut Icmpv4Packet::new_unchecked(b), &caps);
        })
    }

    fn syn_ack(tcp_field: impl FnOnce(&mut TcpPacket<&mut [u8]>)) -> Vec<u8> {
        let r = TcpRepr {
            src_port: 7878,
            dst_port: 50000,
            control: TcpControl::Syn,
            seq_number: TcpSeqNumber(1000),
            ack_number: Some(TcpSeqNumber(2000)),
            window_len: 4096,
            window_scale: None,
            max_seg_size: Some(1460),
            sack_permitted: false,
            sack_ranges: [None; 3],
            timestamp: None,
            payload: &[],
        };
        ipv4_frame(IpProtocol::Tcp, r.buffer_len(), |b| {
            let mut p = TcpPacket::new_unchecked(b);
            r.emit(&mut p, &A.into(), &B.into(), &ChecksumCapabilities::ignored());
            tcp_field(&mut p);
        })
    }

    fn ip_ok(f: &[u8]) -> bool {
        Ipv4Packet::new_unchecked(&f[14..]).verify_checksum()
    }
    fn icmp_ok(f: &[u8]) -> bool {
        Icmpv4Packet::new_unchecked(Ipv4Packet::new_unchecked(&f[14..]).payload()).verify_checksum()
    }
    fn tcp_ok(f: &[u8]) -> bool {
        TcpPacket::new_unchecked(Ipv4Packet::new_unchecked(&f[14..]).payload()).verify_checksum(&A.into(), &B.into())
    }

    #[test]
    fn the_sum_is_rfc_1071s() {
        // RFC 1071 4.1's example bytes: 00 01 f2 03 f4 f5 f6 f7 sum to ddf2.
        assert_eq!(ones_sum(0, &[0x00, 0x01, 0xf2, 0x03, 0xf4, 0xf5, 0xf6, 0xf7]), 0xddf2);
        assert_eq!(ones_sum(0, &[0xff]), 0xff00, "odd length pads on the right");
    }

    #[test]
    fn cic_0_leaves_the_frame_and_cic_1_fills_only_the_ip_header() {
        let f = echo_reply(false);
        let mut off = f.clone();
        assert_eq!(insert(&mut off, Off), Done::Nothing);
        assert_eq!(off, f);
        assert!(!ip_ok(&f), "smoltcp left the IP header checksum 0");
        let mut one = f.clone();
        assert_eq!(insert(&mut one, HeaderOnly), Done::Header);
        assert!(ip_ok(&one));
        assert_eq!(one[14 + 20..], f[14 + 20..], "the payload is untouched");
        // The IP field is ignored: a garbage value is replaced all the same.
        let mut garbage = f.clone();
        garbage[14 + 10..14 + 12].copy_from_slice(&[0xde, 0xad]);
        insert(&mut garbage, HeaderOnly);
        assert_eq!(garbage, one);
    }

    #[test]
    fn icmp_with_a_zero_field_comes_out_right_in_both_modes() {
        for cic in [NoPseudoHeader, Full] {
            let mut f = echo_reply(false);
            assert_eq!(insert(&mut f, cic), Done::HeaderAndPayload);
            assert!(ip_ok(&f) && icmp_ok(&f), "{cic:?}");
        }
    }

    #[test]
    fn icmp_with_its_checksum_filled_in_comes_out_wrong_under_cic_2_and_3_and_right_under_cic_1() {
        let filled = echo_reply(true);
        assert!(icmp_ok(&filled), "smoltcp's own checksum is right");
        for cic in [NoPseudoHeader, Full] {
            let mut f = filled.clone();
            insert(&mut f, cic);
            assert!(ip_ok(&f));
            assert!(!icmp_ok(&f), "{cic:?}: the databook's warning");
            assert_eq!(f[14 + 20 + 2..14 + 20 + 4], [0, 0], "a valid field sums to 0xFFFF; its complement is 0");
        }
        let mut f = filled.clone();
        insert(&mut f, HeaderOnly);
        assert!(ip_ok(&f) && icmp_ok(&f), "CIC 1 keeps the stack's ICMP checksum");
    }

    #[test]
    fn tcp_in_the_second_mode_ignores_the_field_and_adds_the_pseudo_header() {
        let mut zero = syn_ack(|p| p.set_checksum(0));
        insert(&mut zero, Full);
        assert!(ip_ok(&zero) && tcp_ok(&zero));
        let mut garbage = syn_ack(|p| p.set_checksum(0xbeef));
        insert(&mut garbage, Full);
        assert_eq!(garbage, zero, "the field is ignored");
    }

    #[test]
    fn tcp_in_the_first_mode_needs_the_pseudo_header_sum_in_the_field() {
        let pseudo = |f: &[u8]| {
            let ip = Ipv4Packet::new_unchecked(&f[14..]);
            let len = u32::from(ip.total_len()) - 20;
            ones_sum(u32::from(ones_sum(0, &f[14 + 12..14 + 20])) + 6 + len, &[])
        };
        let mut f = syn_ack(|p| p.set_checksum(0));
        let seed = pseudo(&f);
        let mut seeded = f.clone();
        seeded[14 + 20 + 16..14 + 20 + 18].copy_from_slice(&seed.to_be_bytes());
        insert(&mut seeded, NoPseudoHeader);
        assert!(tcp_ok(&seeded), "pseudo-header sum in the field: right");
        insert(&mut f, NoPseudoHeader);
        assert!(!tcp_ok(&f), "a zero field leaves the pseudo-header out: wrong");
    }

    #[test]
    fn fragments_and_other_protocols_get_the_header_only() {
        let mut frag = syn_ack(|p| p.set_checksum(0));
        frag[14 + 6] = 0x20; // MF
        assert_eq!(insert(&mut frag, Full), Done::Header);
        assert!(!tcp_ok(&frag));
        let mut igmp = echo_reply(false);
        igmp[14 + 9] = 2;
        assert_eq!(insert(&mut igmp, Full), Done::Header);
        let mut arp = echo_reply(false);
        arp[12..14].copy_from_slice(&[0x08, 0x06]);
        let before = arp.clone();
        assert_eq!(insert(&mut arp, Full), Done::Nothing);
        assert_eq!(arp, before);
    }
}
