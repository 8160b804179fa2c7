//! The `rtp` module against independent parsers and encoders: smoltcp's
//! Ethernet, IPv4 and UDP parsers, `rtp-types` for the RTP header, and
//! `rtcp-types` for sender reports, SDES and NACKs.

use std::net::{Ipv4Addr, SocketAddrV4};

use model::ROW_BYTES;
use rt_services::camera::frame_header::FRAME_HEADER_BYTES;
use rt_services::camera::frame_header::{self, Endpoints, HeaderTemplate, UdpChecksum};
use rt_services::camera::packetiser::Packetiser;
use rt_services::camera::wire::rtcp::{self, write_sdes_cname, NackRequests};
use rt_services::camera::wire::rtp::RowPacket;
use rtcp_types::prelude::*;
use smoltcp::phy::ChecksumCapabilities;
use smoltcp::wire::{
    checksum, EthernetAddress, EthernetFrame, EthernetProtocol, EthernetRepr, IpAddress, IpProtocol, Ipv4Packet,
    Ipv4Repr, UdpPacket, UdpRepr,
};

const BOARD: SocketAddrV4 = SocketAddrV4::new(Ipv4Addr::new(192, 168, 1, 50), 5004);
const CLIENT: SocketAddrV4 = SocketAddrV4::new(Ipv4Addr::new(192, 168, 1, 10), 6000);

fn endpoints() -> Endpoints {
    Endpoints {
        src_mac: EthernetAddress([0x02, 0x00, 0x00, 0x00, 0x00, 0x01]),
        dst_mac: EthernetAddress([0x02, 0x00, 0x00, 0x00, 0x00, 0x02]),
        src: BOARD,
        dst: CLIENT,
        ttl: 64,
    }
}

/// A row whose bytes say where they are.
fn row_bytes(y: u16) -> Vec<u8> {
    (0..ROW_BYTES).map(|i| (i as u16).wrapping_mul(7).wrapping_add(y) as u8).collect()
}

/// The frame on the wire: the template's header (buffer 1) and the row
/// (buffer 2), as the MAC's DMA gathers them.
fn on_the_wire(t: &mut HeaderTemplate, s: &Packetiser, p: &RowPacket) -> Vec<u8> {
    let mut frame = vec![0u8; FRAME_HEADER_BYTES];
    t.write(s, p, &mut frame).unwrap();
    frame.extend(row_bytes(p.row));
    frame
}

#[test]
fn the_62_byte_header_parses_back_with_smoltcp_and_rtp_types() {
    let mut session = Packetiser::new(0xcafe_f00d, 0x0000_ffff, 1_000);
    let mut t = HeaderTemplate::new(&endpoints(), UdpChecksum::Zero, 0xfffe);
    let f = session.begin_frame(90_000);
    for (i, y) in [358u16, 359].into_iter().enumerate() {
        let p = session.next_packet(f, y).unwrap();
        let frame = on_the_wire(&mut t, &session, &p);
        assert_eq!(frame.len(), 14 + 1_488);

        let eth = EthernetFrame::new_checked(&frame[..]).unwrap();
        let eth_repr = EthernetRepr::parse(&eth).unwrap();
        assert_eq!(eth_repr.src_addr, endpoints().src_mac);
        assert_eq!(eth_repr.dst_addr, endpoints().dst_mac);
        assert_eq!(eth_repr.ethertype, EthernetProtocol::Ipv4);

        let ip = Ipv4Packet::new_checked(eth.payload()).unwrap();
        assert!(ip.verify_checksum(), "IPv4 header checksum");
        assert_eq!((ip.total_len(), ip.header_len()), (1_488, 20));
        assert_eq!(ip.ident(), 0xfffe_u16.wrapping_add(i as u16), "identification increments and wraps");
        assert!(ip.dont_frag() && !ip.more_frags() && ip.frag_offset() == 0);
        let ip_repr = Ipv4Repr::parse(&ip, &ChecksumCapabilities::default()).unwrap();
        assert_eq!((ip_repr.src_addr, ip_repr.dst_addr), (*BOARD.ip(), *CLIENT.ip()));
        assert_eq!((ip_repr.next_header, ip_repr.payload_len, ip_repr.hop_limit), (IpProtocol::Udp, 1_468, 64));

        let udp = UdpPacket::new_checked(ip.payload()).unwrap();
        assert_eq!((udp.src_port(), udp.dst_port(), udp.len(), udp.checksum()), (5004, 6000, 1_468, 0));
        let (src, dst) = (IpAddress::Ipv4(*BOARD.ip()), IpAddress::Ipv4(*CLIENT.ip()));
        let udp_repr = UdpRepr::parse(&udp, &src, &dst, &ChecksumCapabilities::default()).unwrap();
        assert_eq!((udp_repr.src_port, udp_repr.dst_port), (5004, 6000));

        let rtp = rtp_types::RtpPacket::parse(udp.payload()).unwrap();
        assert_eq!((rtp.version(), rtp.padding(), rtp.extension(), rtp.n_csrcs()), (2, None, None, 0));
        assert_eq!((rtp.payload_type(), rtp.ssrc(), rtp.timestamp()), (96, 0xcafe_f00d, 91_000));
        assert_eq!(rtp.marker_bit(), y == 359);
        assert_eq!(rtp.sequence_number(), p.seq as u16);
        let payload = rtp.payload();
        assert_eq!(payload.len(), 8 + ROW_BYTES);
        let word = |i: usize| u16::from_be_bytes([payload[i], payload[i + 1]]);
        assert_eq!(u32::from(word(0)) << 16 | u32::from(rtp.sequence_number()), p.seq, "extended sequence number");
        assert_eq!((word(2), word(4) >> 15, word(4) & 0x7fff), (1_440, 0, y), "Length, F, Line No");
        assert_eq!((word(6) >> 15, word(6) & 0x7fff), (0, 0), "C, Offset");
        assert_eq!(payload[8..], row_bytes(y));
    }
    assert_eq!(t.next_ident(), 0);
}

#[test]
fn an_offloaded_udp_checksum_comes_out_right_from_either_engine_mode() {
    let mut session = Packetiser::new(7, 0, 0);
    let mut t = HeaderTemplate::new(&endpoints(), UdpChecksum::Offload, 0);
    let f = session.begin_frame(0);
    let p = session.next_packet(f, 100).unwrap();
    let mut frame = on_the_wire(&mut t, &session, &p);
    let (src, dst) = (IpAddress::Ipv4(*BOARD.ip()), IpAddress::Ipv4(*CLIENT.ip()));
    let udp_at = 14 + 20;

    // CIC 2: the engine sums the UDP datagram as it is (the field holding
    // the pseudo-header sum) and stores the complement.
    let mut cic2 = frame.clone();
    let sum = !checksum::data(&cic2[udp_at..]);
    let sum = if sum == 0 { 0xffff } else { sum };
    cic2[udp_at + 6..udp_at + 8].copy_from_slice(&sum.to_be_bytes());
    let udp = UdpPacket::new_checked(&cic2[udp_at..]).unwrap();
    assert_ne!(udp.checksum(), 0);
    assert!(udp.verify_checksum(&src, &dst), "CIC 2 result");

    // CIC 3: the engine ignores the field and adds the pseudo-header itself.
    let mut udp = UdpPacket::new_checked(&mut frame[udp_at..]).unwrap();
    udp.fill_checksum(&src, &dst);
    assert_eq!(udp.checksum(), sum, "both modes agree");
}

#[test]
fn a_retransmission_repeats_the_rtp_header_with_a_new_ip_identification() {
    let mut session = Packetiser::new(7, 40, 0);
    let mut t = HeaderTemplate::new(&endpoints(), UdpChecksum::Zero, 10);
    let f = session.begin_frame(0);
    let p = session.next_packet(f, 3).unwrap();
    let first = on_the_wire(&mut t, &session, &p);
    let again = on_the_wire(&mut t, &session, &p);
    assert_eq!(first[14 + 28..], again[14 + 28..], "the RTP packet is the same");
    let ident = |f: &[u8]| Ipv4Packet::new_checked(&f[14..]).unwrap().ident();
    assert_eq!((ident(&first), ident(&again)), (10, 11));
    assert!(Ipv4Packet::new_checked(&again[14..]).unwrap().verify_checksum());
    assert!(t.write(&session, &p, &mut [0; 61]).is_err());
}

#[test]
fn a_nack_from_rtcp_types_yields_the_lost_sequence_numbers() {
    let media = 0x1234_5678;
    // Lost: 0xfffe, 0xffff, 0x0000 (across the wrap), 0x0005, 0x0020.
    let lost: [u16; 5] = [0xfffe, 0xffff, 0x0000, 0x0005, 0x0020];
    let mut nack = rtcp_types::Nack::builder();
    for s in lost {
        nack = nack.add_rtp_sequence(s);
    }
    let fb = rtcp_types::TransportFeedback::builder_owned(nack).sender_ssrc(0xdead_beef).media_ssrc(media);
    let compound = rtcp_types::Compound::builder()
        .add_packet(rtcp_types::ReceiverReport::builder(0xdead_beef))
        .add_packet(
            rtcp_types::Sdes::builder().add_chunk(
                rtcp_types::SdesChunk::builder(0xdead_beef)
                    .add_item(rtcp_types::SdesItem::builder(rtcp_types::SdesItem::CNAME, "client")),
            ),
        )
        .add_packet(fb);
    let mut buf = vec![0u8; compound.calculate_size().unwrap()];
    compound.write_into(&mut buf).unwrap();
    assert_eq!(buf[1], 201, "RR first");

    // The sender is at extended number 0x0003_0040.
    // (rtcp-types orders FCI entries by their 16-bit PID, 0x0000 first.)
    let mut got: Vec<u32> = NackRequests::new(&buf, media, Some(0x0003_0040)).collect();
    got.sort_unstable();
    assert_eq!(got, [0x0002_fffe, 0x0002_ffff, 0x0003_0000, 0x0003_0005, 0x0003_0020]);
    assert_eq!(NackRequests::new(&buf, media + 1, Some(0x0003_0040)).count(), 0, "another stream's");
}

#[test]
fn rtcp_types_reads_the_sender_report_and_cname() {
    let mut session = Packetiser::new(0x0bad_cafe, 0, 12_345);
    let f = session.begin_frame(0);
    for y in 0..10 {
        session.next_packet(f, y).unwrap();
    }
    let ntp = rtcp::ntp_timestamp(std::time::Duration::new(1_700_000_000, 250_000_000));
    let sr = session.sender_report(ntp, 90_000);
    let mut buf = [0u8; 64];
    let n = sr.write(&mut buf).unwrap();
    let n = n + write_sdes_cname(session.ssrc(), b"rt@de1-soc", &mut buf[n..]).unwrap();

    let mut packets = rtcp_types::Compound::parse(&buf[..n]).unwrap();
    let Some(Ok(rtcp_types::Packet::Sr(parsed))) = packets.next() else { panic!("an SR first") };
    assert_eq!(parsed.ssrc(), 0x0bad_cafe);
    assert_eq!(parsed.ntp_timestamp(), ntp);
    assert_eq!(parsed.rtp_timestamp(), 12_345 + 90_000);
    assert_eq!((parsed.packet_count(), parsed.octet_count()), (10, 10 * 1_448));
    assert_eq!(parsed.n_reports(), 0);
    let Some(Ok(rtcp_types::Packet::Sdes(sdes))) = packets.next() else { panic!("then SDES") };
    let chunk = sdes.chunks().next().unwrap();
    assert_eq!(chunk.ssrc(), 0x0bad_cafe);
    let item = chunk.items().next().unwrap();
    assert_eq!((item.type_(), item.value()), (rtcp_types::SdesItem::CNAME, &b"rt@de1-soc"[..]));
    assert!(packets.next().is_none());
}

proptest::proptest! {
    /// The template's words (incremental IPv4 checksum, fields patched into
    /// big-endian words) against a header built the plain way: smoltcp's
    /// emitters with the identification set and the checksum computed over
    /// the whole IPv4 header, and `Packetiser::emit` for the rest.
    #[test]
    fn the_header_words_equal_a_header_built_field_by_field(
        macs in proptest::array::uniform12(proptest::num::u8::ANY),
        src in proptest::num::u32::ANY, dst in proptest::num::u32::ANY,
        ports in (proptest::num::u16::ANY, proptest::num::u16::ANY),
        offload in proptest::bool::ANY, ident in proptest::num::u16::ANY,
        ssrc in proptest::num::u32::ANY, seq in proptest::num::u32::ANY,
        timestamp in proptest::num::u32::ANY, row in 0u16..360,
        before in (proptest::num::u32::ANY, proptest::num::u32::ANY, 0u16..360),
    ) {
        let e = Endpoints {
            src_mac: EthernetAddress(macs[..6].try_into().unwrap()),
            dst_mac: EthernetAddress(macs[6..].try_into().unwrap()),
            src: SocketAddrV4::new(Ipv4Addr::from(src), ports.0),
            dst: SocketAddrV4::new(Ipv4Addr::from(dst), ports.1),
            ttl: (ports.0 % 255) as u8 + 1,
        };
        let checksum_mode = if offload { UdpChecksum::Offload } else { UdpChecksum::Zero };
        let mut t = HeaderTemplate::new(&e, checksum_mode, ident.wrapping_sub(1));
        let session = Packetiser::new(ssrc, 0, 0);
        // A packet before: the template keeps the last header and
        // overwrites only the per-packet fields.
        t.words(&session, &RowPacket { seq: before.0, timestamp: before.1, row: before.2 });
        let p = RowPacket { seq, timestamp, row };
        let words = *t.words(&session, &p);

        let mut want = [0u8; FRAME_HEADER_BYTES];
        EthernetRepr { src_addr: e.src_mac, dst_addr: e.dst_mac, ethertype: EthernetProtocol::Ipv4 }
            .emit(&mut EthernetFrame::new_unchecked(&mut want[..14]));
        let ip_repr = Ipv4Repr {
            src_addr: *e.src.ip(),
            dst_addr: *e.dst.ip(),
            next_header: IpProtocol::Udp,
            payload_len: 1_468,
            hop_limit: e.ttl,
        };
        let mut ip = Ipv4Packet::new_unchecked(&mut want[14..34]);
        ip_repr.emit(&mut ip, &ChecksumCapabilities::ignored());
        ip.set_ident(ident);
        ip.fill_checksum();
        let mut udp = UdpPacket::new_unchecked(&mut want[34..42]);
        udp.set_src_port(ports.0);
        udp.set_dst_port(ports.1);
        udp.set_len(1_468);
        udp.set_checksum(if offload {
            checksum::pseudo_header_v4(e.src.ip(), e.dst.ip(), IpProtocol::Udp, 1_468)
        } else {
            0
        });
        session.emit(&p, &mut want[42..]).unwrap();

        proptest::prop_assert_eq!(words.bytes(), want);
        let memory: Vec<u8> = words.0.iter().flat_map(|w| w.to_ne_bytes()).collect();
        proptest::prop_assert_eq!(&memory[..frame_header::HEADER_PAD], &[0u8; frame_header::HEADER_PAD][..], "padding");
        proptest::prop_assert_eq!(&memory[frame_header::HEADER_PAD..], &want[..]);
        proptest::prop_assert_eq!(t.next_ident(), ident.wrapping_add(1));
    }
}
