//! Checksum insertion chosen per frame.
//!
//! The MAC's transmit checksum engine (STM32 RM0090 rev 21, 33.5.2 "Transmit
//! checksum offload"; the same Synopsys GMAC as the Cyclone V EMAC) works on
//! what it finds in each frame:
//!
//! * the IPv4 header checksum (CIC >= 1): the field is ignored and replaced;
//! * the TCP/UDP/ICMP checksum (CIC 2 and 3): CIC 3 ignores the field and
//!   adds the pseudo-header, **but** "for ICMP-over-IPv4 packets, the
//!   checksum field in the ICMP packet must always be 0x0000 in both modes,
//!   because pseudo-headers are not defined for such packets. If it does not
//!   equal 0x0000, an incorrect checksum may be inserted into the packet."
//!
//! smoltcp fills in ICMP checksums itself (QEMU's model never inserts them,
//! docs/platform.md#qemus-npcm-gmac), so an ICMP frame must not go out with
//! CIC 2/3. Per frame, then:
//!
//! | frame | CIC |
//! |---|---|
//! | IPv4, TCP or UDP, not a fragment | the configured value (3 when the MAC has the engine) |
//! | IPv4, anything else (ICMP, fragments, other protocols) | 1: the IPv4 header only |
//! | IPv6, TCP / UDP / ICMPv6 | the configured value (no IPv4 header; ICMPv6 has a pseudo-header) |
//! | not IP (ARP), or too short to tell | 0 |
//!
//! Fragments get CIC 1 because the engine bypasses fragmented IP frames'
//! payload anyway (same section, note b); the firmware does not fragment.

use crate::desc::ChecksumInsertion;

/// Ethernet header: destination, source, type (IEEE 802.3 clause 3.1.1).
const ETHERTYPE_AT: usize = 12;
const ETH_HEADER: usize = 14;
/// EtherType of IPv4 (RFC 894) and IPv6 (RFC 2464).
const ETHERTYPE_IPV4: u16 = 0x0800;
const ETHERTYPE_IPV6: u16 = 0x86dd;
/// IP protocol numbers (IANA): ICMP 1, TCP 6, UDP 17, ICMPv6 58.
const PROTO_TCP: u8 = 6;
const PROTO_UDP: u8 = 17;
const PROTO_ICMPV6: u8 = 58;
/// IPv4 header (RFC 791 3.1): version 4 in the top nibble of byte 0, flags
/// and fragment offset in bytes 6-7 (MF = 0x2000, offset 12:0), protocol at
/// byte 9; 20 bytes without options.
const IPV4_MIN_HEADER: usize = 20;
const IPV4_MF_AND_OFFSET: u16 = 0x3fff;
/// IPv6 header (RFC 8200 3): next header at byte 6, 40 bytes.
const IPV6_HEADER: usize = 40;

/// The CIC for `frame` (a whole Ethernet frame, from the destination
/// address on) when the MAC was set up for `configured`.
pub fn for_frame(frame: &[u8], configured: ChecksumInsertion) -> ChecksumInsertion {
    if configured == ChecksumInsertion::Off {
        return ChecksumInsertion::Off;
    }
    let Some(ip) = frame.get(ETH_HEADER..) else {
        return ChecksumInsertion::Off;
    };
    match u16::from_be_bytes([frame[ETHERTYPE_AT], frame[ETHERTYPE_AT + 1]]) {
        ETHERTYPE_IPV4 if ip.len() >= IPV4_MIN_HEADER && ip[0] >> 4 == 4 => {
            let fragment = u16::from_be_bytes([ip[6], ip[7]]) & IPV4_MF_AND_OFFSET != 0;
            match ip[9] {
                PROTO_TCP | PROTO_UDP if !fragment => configured,
                _ => ChecksumInsertion::HeaderOnly,
            }
        }
        ETHERTYPE_IPV6 if ip.len() >= IPV6_HEADER && ip[0] >> 4 == 6 => match ip[6] {
            PROTO_TCP | PROTO_UDP | PROTO_ICMPV6 => configured,
            _ => ChecksumInsertion::Off,
        },
        _ => ChecksumInsertion::Off,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ChecksumInsertion::{Full, HeaderOnly, Off};

    /// An Ethernet frame with `ethertype` and `ip` behind it.
    fn frame(ethertype: u16, ip: &[u8]) -> Vec<u8> {
        let mut f = vec![0u8; 12];
        f.extend_from_slice(&ethertype.to_be_bytes());
        f.extend_from_slice(ip);
        f
    }

    fn ipv4(protocol: u8, flags_offset: u16) -> Vec<u8> {
        let mut h = vec![0u8; 28];
        h[0] = 0x45;
        h[6..8].copy_from_slice(&flags_offset.to_be_bytes());
        h[9] = protocol;
        h
    }

    #[test]
    fn tcp_and_udp_keep_the_configured_value_everything_else_in_ipv4_gets_the_header_only() {
        assert_eq!(for_frame(&frame(0x0800, &ipv4(6, 0)), Full), Full, "TCP");
        assert_eq!(for_frame(&frame(0x0800, &ipv4(17, 0x4000)), Full), Full, "UDP, DF set");
        assert_eq!(for_frame(&frame(0x0800, &ipv4(1, 0)), Full), HeaderOnly, "ICMP");
        assert_eq!(for_frame(&frame(0x0800, &ipv4(2, 0)), Full), HeaderOnly, "IGMP");
        assert_eq!(for_frame(&frame(0x0800, &ipv4(6, 0x2000)), Full), HeaderOnly, "first fragment (MF)");
        assert_eq!(for_frame(&frame(0x0800, &ipv4(17, 0x0010)), Full), HeaderOnly, "later fragment");
    }

    #[test]
    fn frames_that_are_not_ip_go_out_untouched() {
        assert_eq!(for_frame(&frame(0x0806, &[0; 28]), Full), Off, "ARP");
        assert_eq!(for_frame(&frame(0x0800, &ipv4(6, 0)[..19]), Full), Off, "IPv4 header cut short");
        let mut v6 = ipv4(6, 0);
        v6[0] = 0x65;
        assert_eq!(for_frame(&frame(0x0800, &v6), Full), Off, "type IPv4, version 6");
        assert_eq!(for_frame(&[0; 13], Full), Off, "no EtherType");
        assert_eq!(for_frame(&[], Full), Off);
    }

    #[test]
    fn ipv6_payloads_with_a_pseudo_header_keep_the_configured_value() {
        let mut h = vec![0u8; 40];
        h[0] = 0x60;
        for (next, want) in [(6, Full), (17, Full), (58, Full), (0, Off), (44, Off)] {
            h[6] = next;
            assert_eq!(for_frame(&frame(0x86dd, &h), Full), want, "next header {next}");
        }
    }

    #[test]
    fn without_the_engine_every_frame_is_off() {
        for f in [frame(0x0800, &ipv4(6, 0)), frame(0x0800, &ipv4(1, 0)), frame(0x0806, &[0; 28])] {
            assert_eq!(for_frame(&f, Off), Off);
        }
    }
}
