//! Host tests of [`crate::split`]: a fake DMA walks the transmit ring as
//! the MAC does, assembles each frame from buffer 1 and buffer 2, runs the
//! checksum engine model over it, and reads payload memory only through a
//! recording port.

use std::cell::RefCell;

use smoltcp::phy::{Device, TxToken};
use smoltcp::time::Instant;
use smoltcp::wire::{EthernetFrame, IpAddress, Ipv4Address, Ipv4Packet, UdpPacket};

use super::{
    assert_drained_before_own, started, transmit_one, transmit_tcp, Rig, Seen, TestMac, QEMU_HW_FEATURE, TX_POLL,
};
use crate::desc::{self, ChecksumInsertion, DescFormat, OWN};
use crate::gmac_csum_model::{insert, ones_sum};
use crate::mac::MAX_FRAME;
use crate::ring::{BUFFER_SIZE, TX_RING, TX_SKEW};
use crate::split::{SplitError, SplitSeq};

/// The Cyclone V EMAC's feature bits as far as the driver reads them:
/// enhanced descriptors, checksum engine.
const CYCLONE_V_HW_FEATURE: u32 = QEMU_HW_FEATURE | (1 << 24);
/// QEMU's without TXCOESEL (bit 16): no checksum engine.
const NO_ENGINE_HW_FEATURE: u32 = QEMU_HW_FEATURE & !(1 << 16);

/// One RTP packet: 62 header bytes, one 1,440-byte row.
const HEADER: usize = 14 + 20 + 8 + 12 + 8;
const ROW: usize = 1440;
/// Where the frame ring sits on the bus (an SDRAM address the FPGA writes;
/// not a host address: the driver could not dereference it if it tried).
const FRAME_RING_BUS: u32 = 0x3000_0000;
const ROWS: usize = 8;

const SRC: Ipv4Address = Ipv4Address::new(10, 0, 2, 15);
const DST: Ipv4Address = Ipv4Address::new(10, 0, 2, 2);

/// Who read payload memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Port {
    /// The MAC's DMA.
    Dma,
    /// The CPU (the driver or the firmware around it).
    Cpu,
}

/// The frame ring in SDRAM: bytes the FPGA wrote, reachable only through
/// [`PixelMemory::read`], which logs every access with its port.
struct PixelMemory {
    bytes: Vec<u8>,
    log: RefCell<Vec<(Port, u32, usize)>>,
}

impl PixelMemory {
    /// `ROWS` rows of distinct, position-dependent bytes (as the FPGA would
    /// write them).
    fn new() -> PixelMemory {
        let bytes = (0..ROWS * ROW).map(|i| (i * 7 + i / ROW * 13) as u8).collect();
        PixelMemory { bytes, log: RefCell::default() }
    }

    /// Bus address of row `r`.
    fn row_bus(r: usize) -> u32 {
        FRAME_RING_BUS + (r * ROW) as u32
    }

    fn contains(&self, addr: u32, len: usize) -> bool {
        addr >= FRAME_RING_BUS && (addr - FRAME_RING_BUS) as usize + len <= self.bytes.len()
    }

    /// Read `len` bytes at bus address `addr` through `port`, logged.
    fn read(&self, port: Port, addr: u32, len: usize) -> Vec<u8> {
        assert!(self.contains(addr, len), "{port:?} read outside the frame ring: {addr:#x}+{len}");
        self.log.borrow_mut().push((port, addr, len));
        let at = (addr - FRAME_RING_BUS) as usize;
        self.bytes[at..at + len].to_vec()
    }

    fn bytes_read(&self, port: Port) -> usize {
        self.log.borrow().iter().filter(|(p, ..)| *p == port).map(|(.., len)| len).sum()
    }

    /// Row `r` as the test expects it on the wire (the test's own copy,
    /// taken without the port: this is the reference, not the CPU).
    fn expected_row(&self, r: usize) -> &[u8] {
        &self.bytes[r * ROW..(r + 1) * ROW]
    }
}

/// A frame as it left the MAC.
#[derive(Debug)]
struct Sent {
    descriptor: usize,
    /// Buffer 2's size (0: a one-buffer, smoltcp frame).
    len2: usize,
    csum: ChecksumInsertion,
    wire: Vec<u8>,
}

/// TDES0/TDES1 as the DMA reads them, written out bit by bit from the
/// sources (Linux `stmmac/descs.h` `TDES1_*` / `ETDES0_*` / `ETDES1_*`,
/// QEMU `npcm_gmac.h` `TX_DESC_TDES1_*`), independent of the driver's
/// constants so that a wrong bit in `desc.rs` fails here too.
fn dma_view(format: DescFormat, [t0, t1]: [u32; 2]) -> desc::TxFields {
    let bit = |w: u32, n: u32| w & (1 << n) != 0;
    let field = |w: u32, hi: u32, lo: u32| ((w >> lo) & ((1 << (hi - lo + 1)) - 1)) as usize;
    match format {
        DescFormat::Normal => desc::TxFields {
            first: bit(t1, 29),
            last: bit(t1, 30),
            end_of_ring: bit(t1, 25),
            chained: bit(t1, 24),
            len1: field(t1, 10, 0),
            len2: field(t1, 21, 11),
            csum: ChecksumInsertion::from_bits(field(t1, 28, 27) as u32),
        },
        DescFormat::Enhanced => desc::TxFields {
            first: bit(t0, 28),
            last: bit(t0, 29),
            end_of_ring: bit(t0, 21),
            chained: bit(t0, 20),
            len1: field(t1, 12, 0),
            len2: field(t1, 28, 16),
            csum: ChecksumInsertion::from_bits(field(t0, 23, 22) as u32),
        },
    }
}

/// The MAC's transmit DMA: walks the ring from descriptor 0 as the
/// databook and QEMU's `gmac_try_send_next_packet` do.
struct FakeDma {
    next: usize,
}

impl FakeDma {
    /// Resolve a bus address in the driver's transmit buffers.
    fn tx_buffer_bytes(mac: &TestMac<'_>, addr: u32, len: usize) -> Option<Vec<u8>> {
        let area = mac.shared.area;
        (0..TX_RING).find_map(|j| {
            let base = area.tx_buffer(j).bus_address();
            let off = addr.checked_sub(base)? as usize;
            if off + len > BUFFER_SIZE {
                return None;
            }
            // SAFETY: the test plays the DMA, which owns the buffer while
            // its descriptor has OWN set; read only.
            let bytes = unsafe { area.tx_buffer(j).bytes(off + len) };
            Some(bytes[off..].to_vec())
        })
    }

    /// Bytes at bus address `addr`: a transmit buffer or the frame ring.
    fn read(mac: &TestMac<'_>, pixels: &PixelMemory, addr: u32, len: usize) -> Vec<u8> {
        if let Some(b) = Self::tx_buffer_bytes(mac, addr, len) {
            return b;
        }
        pixels.read(Port::Dma, addr, len)
    }

    /// Send up to `limit` frames: every descriptor with OWN set, in ring
    /// order; each is a whole frame (FS and LS), buffer 2 read unless TCH.
    fn run(&mut self, mac: &TestMac<'_>, pixels: &PixelMemory, limit: usize) -> Vec<Sent> {
        let area = mac.shared.area;
        let format = mac.format();
        let mut out = vec![];
        while out.len() < limit && area.tx_descriptor(self.next).word(0) & OWN != 0 {
            let w = area.tx_descriptor(self.next).words();
            let f = dma_view(format, [w[0], w[1]]);
            assert_eq!(f, desc::tx_fields(format, [w[0], w[1]]), "the driver's decoder agrees");
            assert!(f.first && f.last, "descriptor {}: one descriptor per frame", self.next);
            assert!(!f.chained, "ring mode: TDES3 is buffer 2");
            let mut wire = Self::read(mac, pixels, w[2], f.len1);
            if f.len2 > 0 {
                wire.extend(Self::read(mac, pixels, w[3], f.len2));
            }
            insert(&mut wire, f.csum);
            out.push(Sent { descriptor: self.next, len2: f.len2, csum: f.csum, wire });
            area.tx_descriptor(self.next).set_word(0, w[0] & !OWN);
            assert_eq!(f.end_of_ring, self.next == TX_RING - 1, "TER exactly on the last descriptor");
            self.next = if f.end_of_ring { 0 } else { self.next + 1 };
        }
        out
    }
}

/// The 62-byte header of RTP packet `seq` carrying a `ROW`-byte row, as
/// the firmware builds it: both checksum fields 0 (the MAC fills them).
fn rtp_header(seq: u16) -> Vec<u8> {
    let mut h = vec![0u8; HEADER];
    h[0..6].copy_from_slice(&[0x02, 0, 0, 0, 0, 0x01]);
    h[6..12].copy_from_slice(&super::MAC);
    h[12..14].copy_from_slice(&[0x08, 0x00]);
    let ip = &mut h[14..34];
    ip[0] = 0x45;
    ip[2..4].copy_from_slice(&((20 + 8 + 12 + 8 + ROW) as u16).to_be_bytes());
    ip[6] = 0x40; // DF
    ip[8] = 64;
    ip[9] = 17;
    ip[12..16].copy_from_slice(&SRC.octets());
    ip[16..20].copy_from_slice(&DST.octets());
    let udp = &mut h[34..42];
    udp[0..2].copy_from_slice(&5004u16.to_be_bytes());
    udp[2..4].copy_from_slice(&5004u16.to_be_bytes());
    udp[4..6].copy_from_slice(&((8 + 12 + 8 + ROW) as u16).to_be_bytes());
    let rtp = &mut h[42..54];
    rtp[0] = 0x80;
    rtp[1] = 96;
    rtp[2..4].copy_from_slice(&seq.to_be_bytes());
    // RFC 4175: extended sequence number, then one line header.
    h[56..58].copy_from_slice(&((ROW) as u16).to_be_bytes());
    h[58..60].copy_from_slice(&seq.to_be_bytes());
    h
}

/// Check a split frame on the wire: header (but for the two checksum
/// fields) then row `r`, both checksums right and not 0.
fn assert_rtp_on_wire(sent: &Sent, header: &[u8], pixels: &PixelMemory, r: usize) {
    let wire = &sent.wire;
    assert_eq!(wire.len(), HEADER + ROW);
    assert_eq!(&wire[HEADER..], pixels.expected_row(r), "row {r} follows the header");
    let mut masked = wire[..HEADER].to_vec();
    masked[24..26].fill(0);
    masked[40..42].fill(0);
    assert_eq!(masked, header, "the header as the CPU wrote it, checksum fields aside");
    let eth = EthernetFrame::new_checked(&wire[..]).expect("Ethernet");
    let ip = Ipv4Packet::new_checked(eth.payload()).expect("IPv4");
    assert!(ip.verify_checksum(), "IPv4 header checksum");
    let udp = UdpPacket::new_checked(ip.payload()).expect("UDP");
    assert_ne!(udp.checksum(), 0, "the MAC inserted a UDP checksum");
    assert!(udp.verify_checksum(&IpAddress::Ipv4(SRC), &IpAddress::Ipv4(DST)), "UDP checksum");
    // Independently: pseudo-header + UDP header + data sum to 0xFFFF.
    let pseudo = u32::from(ones_sum(0, &wire[26..34])) + 17 + (8 + 12 + 8 + ROW) as u32;
    assert_eq!(ones_sum(pseudo, &wire[34..]), 0xffff);
}

#[test]
fn an_rtp_row_leaves_as_header_plus_row_with_valid_checksums_and_the_cpu_reads_no_pixel() {
    for (hw, format) in [(QEMU_HW_FEATURE, DescFormat::Normal), (CYCLONE_V_HW_FEATURE, DescFormat::Enhanced)] {
        let mut rig = Rig::new(hw);
        let mut mac = rig.mac(true);
        started(&mut mac);
        assert_eq!(mac.format(), format);
        let pixels = PixelMemory::new();
        let mut dma = FakeDma { next: 0 };

        let header = rtp_header(1);
        let seq = mac.send_split(&header, PixelMemory::row_bus(3), ROW).expect("room");
        assert_eq!(seq, SplitSeq(0));
        // The descriptor: header slot in buffer 1, the row's bus address in TDES3.
        let w = mac.shared.area.tx_descriptor(0).words();
        assert_eq!(w[2], mac.shared.area.tx_buffer(0).bus_address() + TX_SKEW as u32);
        assert_eq!(w[3], PixelMemory::row_bus(3));
        let f = desc::tx_fields(format, [w[0], w[1]]);
        assert_eq!((f.len1, f.len2, f.csum), (HEADER, ROW, ChecksumInsertion::Full), "{format:?}");
        assert_eq!(pixels.bytes_read(Port::Dma), 0, "nothing read before the DMA runs");

        let sent = dma.run(&mac, &pixels, usize::MAX);
        assert_eq!(sent.len(), 1);
        assert_rtp_on_wire(&sent[0], &header, &pixels, 3);
        assert_eq!(pixels.bytes_read(Port::Cpu), 0, "{format:?}: the CPU read no pixel byte");
        assert_eq!(*pixels.log.borrow(), [(Port::Dma, PixelMemory::row_bus(3), ROW)], "the DMA read the row once");
        assert!(mac.split_done(seq));
        let stats = mac.stats();
        assert_eq!((stats.tx_split, stats.tx_frames, stats.tx_bytes), (1, 1, (HEADER + ROW) as u64));
        assert_eq!(stats.tx_split_payload_bytes, ROW as u64, "the row, which the CPU never wrote");
    }
}

/// `header` behind `TX_SKEW` zero bytes, as the words of a transmit buffer.
fn padded_words(header: &[u8]) -> Vec<u32> {
    let mut bytes = vec![0u8; TX_SKEW];
    bytes.extend_from_slice(header);
    assert_eq!(bytes.len() % 4, 0);
    bytes.chunks_exact(4).map(|c| u32::from_ne_bytes([c[0], c[1], c[2], c[3]])).collect()
}

#[test]
fn a_header_given_as_words_leaves_as_the_same_header_given_as_bytes() {
    for hw in [QEMU_HW_FEATURE, CYCLONE_V_HW_FEATURE, NO_ENGINE_HW_FEATURE] {
        let mut rig = Rig::new(hw);
        let mut mac = rig.mac(true);
        started(&mut mac);
        let pixels = PixelMemory::new();
        let mut dma = FakeDma { next: 0 };
        let header = rtp_header(7);
        let a = mac.send_split(&header, PixelMemory::row_bus(5), ROW).expect("room");
        let cic = mac.checksum_for(&header);
        let b = mac.send_split_words(&padded_words(&header), cic, PixelMemory::row_bus(5), ROW).expect("room");
        assert_eq!((a, b), (SplitSeq(0), SplitSeq(1)));
        let (d0, d1) = (mac.shared.area.tx_descriptor(0).words(), mac.shared.area.tx_descriptor(1).words());
        assert_eq!(d1[0], d0[0], "TDES0 (neither ends the ring)");
        assert_eq!((d1[1], d1[3]), (d0[1], d0[3]), "lengths, checksum insertion and buffer 2 alike");
        assert_eq!(d1[2], mac.shared.area.tx_buffer(1).bus_address() + TX_SKEW as u32, "its own header slot");
        let sent = dma.run(&mac, &pixels, usize::MAX);
        assert_eq!(sent.len(), 2);
        assert_eq!(sent[0].wire, sent[1].wire, "{hw:#x}: the same frame on the wire");
        assert_eq!(sent[0].csum, sent[1].csum);
        assert_eq!(pixels.bytes_read(Port::Cpu), 0);
        assert_eq!(mac.stats().tx_bytes, 2 * (HEADER + ROW) as u64);
    }
    // Headers too short for an Ethernet header, the padding included.
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let mut mac = rig.mac(true);
    started(&mut mac);
    let off = ChecksumInsertion::Off;
    assert_eq!(mac.send_split_words(&[], off, 0, ROW), Err(SplitError::Length));
    assert_eq!(mac.send_split_words(&[0; 3], off, 0, ROW), Err(SplitError::Length), "10 bytes after the padding");
    assert_eq!(mac.send_split_words(&[0; 4], off, 0, 0), Ok(SplitSeq(0)), "14 bytes: just an Ethernet header");
}

#[test]
fn a_run_leaves_as_its_frames_sent_one_by_one_and_stops_where_the_ring_is_full() {
    // 40 frames, row k % ROWS of the ring each: in two runs (the first
    // stops at the ring's 32), or one by one with the DMA keeping up.
    let header = |k: usize| padded_words(&rtp_header(k as u16));
    for hw in [QEMU_HW_FEATURE, CYCLONE_V_HW_FEATURE, NO_ENGINE_HW_FEATURE] {
        let pixels = PixelMemory::new();
        let mut rig = Rig::new(hw);
        let mut mac = rig.mac(true);
        started(&mut mac);
        let cic = mac.checksum_for(&rtp_header(0));
        let mut dma = FakeDma { next: 0 };
        let mut one_by_one = vec![];
        for k in 0..40 {
            mac.send_split_words(&header(k), cic, PixelMemory::row_bus(k % ROWS), ROW).expect("room");
            if k % 16 == 15 {
                one_by_one.extend(dma.run(&mac, &pixels, usize::MAX));
            }
        }
        one_by_one.extend(dma.run(&mac, &pixels, usize::MAX));
        let want_stats = mac.stats();

        // Rows 0..ROWS repeat every ROWS frames: a run's payloads are
        // consecutive, so the runs go ROWS frames at a time.
        let mut rig = Rig::new(hw);
        let mut mac = rig.mac(true);
        started(&mut mac);
        let mut dma = FakeDma { next: 0 };
        let mut runs = vec![];
        let mut sent = 0;
        let mut results = vec![];
        while sent < 40 {
            let n = (40 - sent).min(ROWS);
            let base = sent;
            let r = mac
                .send_split_run(n, header(0).len(), cic, PixelMemory::row_bus(0), ROW as u32, ROW, |k, out| {
                    out.copy_from_slice(&header(base + k))
                })
                .expect("lengths");
            results.push(r);
            sent += r.0;
            if r.0 < n || sent % 32 == 0 {
                runs.extend(dma.run(&mac, &pixels, usize::MAX));
            }
        }
        runs.extend(dma.run(&mac, &pixels, usize::MAX));
        assert_eq!(results[0], (ROWS, Some(SplitSeq(ROWS as u64 - 1))), "{hw:#x}");
        assert_eq!(results.last().map(|r| r.1), Some(Some(SplitSeq(39))));
        let wire = |v: &[Sent]| v.iter().map(|s| (s.wire.clone(), s.csum, s.len2)).collect::<Vec<_>>();
        assert_eq!(wire(&runs), wire(&one_by_one), "{hw:#x}: the same frames on the wire");
        assert_eq!(mac.stats(), want_stats, "{hw:#x}: the same counts");
        assert_eq!(pixels.bytes_read(Port::Cpu), 0);

        // Two descriptors left: a run of three takes two; then the ring is
        // full: nothing taken, counted as full; a bad length refused.
        for k in 0..TX_RING - 2 {
            mac.send_split_words(&header(k), cic, PixelMemory::row_bus(0), ROW).expect("room");
        }
        let r = mac.send_split_run(3, header(0).len(), cic, PixelMemory::row_bus(0), 0, ROW, |k, out| {
            out.copy_from_slice(&header(k))
        });
        assert_eq!(r, Ok((2, Some(SplitSeq(40 + TX_RING as u64 - 1)))));
        let full = mac.stats().tx_split_full;
        let r = mac
            .send_split_run(3, header(0).len(), cic, PixelMemory::row_bus(0), 0, ROW, |_, _| panic!("no slot to fill"));
        assert_eq!((r, mac.stats().tx_split_full), (Ok((0, None)), full + 1));
        let r = mac.send_split_run(1, 3, cic, 0, 0, ROW, |_, _| panic!("no slot to fill"));
        assert_eq!(r, Err(SplitError::Length), "10 header bytes after the padding");
    }
}

#[test]
fn without_the_checksum_engine_a_split_frame_goes_out_as_the_caller_built_it() {
    let mut rig = Rig::new(NO_ENGINE_HW_FEATURE);
    let mut mac = rig.mac(true);
    started(&mut mac);
    assert_eq!(mac.checksum_insertion(), ChecksumInsertion::Off);
    let pixels = PixelMemory::new();
    // The caller fills the IPv4 header checksum and leaves UDP's at 0 ("none").
    let mut header = rtp_header(9);
    let h = !ones_sum(0, &header[14..34]);
    header[24..26].copy_from_slice(&h.to_be_bytes());
    mac.send_split(&header, PixelMemory::row_bus(0), ROW).expect("room");
    let sent = FakeDma { next: 0 }.run(&mac, &pixels, usize::MAX);
    assert_eq!(sent[0].csum, ChecksumInsertion::Off);
    assert_eq!(&sent[0].wire[..HEADER], &header[..], "nothing inserted");
    assert_eq!(&sent[0].wire[HEADER..], pixels.expected_row(0));
    let ip = Ipv4Packet::new_checked(&sent[0].wire[14..]).expect("IPv4");
    assert!(ip.verify_checksum());
    assert_eq!(pixels.bytes_read(Port::Cpu), 0);
}

#[test]
fn split_send_hands_over_with_the_same_barriers_as_send() {
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let tx_poll = rig.regs.word_ptr(TX_POLL);
    let mut mac = rig.mac(true);
    started(&mut mac);
    mac.clear_events();
    mac.send_split(&rtp_header(0), PixelMemory::row_bus(0), ROW).expect("room");
    let seen = |op, own, polled| Seen { op, own, polled };
    assert_eq!(
        mac.events(),
        [
            seen("dsb", false, false),  // header slot and descriptor words drained ...
            seen("sync", false, false), // ... from the CPU and the L2C-310 ...
            seen("dsb", false, false),  // ... before OWN
            seen("dsb", true, false),   // OWN drained from the CPU ...
            seen("sync", true, false),  // ... and from the L2C-310 ...
            seen("dsb", true, false),   // ... before the poll demand
        ]
    );
    drop(mac);
    // SAFETY: points into the live fake register block.
    assert_eq!(unsafe { *tx_poll }, 0, "poll demand written last");
}

#[test]
fn every_split_frame_and_run_is_in_memory_before_its_own() {
    // Runs of 1 to 32 (wrapping the ring), single frames by bytes and by
    // words, and a smoltcp frame between them; the DMA takes what is
    // there after each step. Every header differs (its sequence number),
    // so a header still on its way at OWN would show.
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let mut mac = rig.mac(true);
    started(&mut mac);
    mac.clear_events();
    let pixels = PixelMemory::new();
    let mut dma = FakeDma { next: 0 };
    let cic = mac.checksum_for(&rtp_header(0));
    let words = padded_words(&rtp_header(0)).len();
    let mut seq = 0u16;
    let mut sent = 0;
    for (step, n) in [1, 32, 5, 31, 2, 17, 32, 3].into_iter().enumerate() {
        let base = seq;
        let (taken, _) = mac
            .send_split_run(n, words, cic, PixelMemory::row_bus(n % ROWS), 0, ROW, |k, out| {
                out.copy_from_slice(&padded_words(&rtp_header(base + k as u16)))
            })
            .expect("lengths");
        assert_eq!(taken, n, "the DMA took everything before");
        seq += n as u16;
        sent += dma.run(&mac, &pixels, usize::MAX).len();
        mac.send_split(&rtp_header(seq), PixelMemory::row_bus(step % ROWS), ROW).expect("room");
        mac.send_split_words(&padded_words(&rtp_header(seq + 1)), cic, PixelMemory::row_bus(0), ROW).expect("room");
        seq += 2;
        transmit_one(&mut mac, 60, step as u8);
        sent += dma.run(&mac, &pixels, usize::MAX).len();
    }
    assert_eq!(sent, 123 + 3 * 8);
    assert_eq!(assert_drained_before_own(&mac), sent);
}

#[test]
fn the_ring_fills_reports_full_and_wraps_in_both_formats() {
    for hw in [QEMU_HW_FEATURE, CYCLONE_V_HW_FEATURE] {
        let mut rig = Rig::new(hw);
        let mut mac = rig.mac(true);
        started(&mut mac);
        let pixels = PixelMemory::new();
        let mut dma = FakeDma { next: 0 };
        assert_eq!(mac.tx_free(), TX_RING);
        let headers: Vec<Vec<u8>> = (0..3 * TX_RING as u16).map(rtp_header).collect();
        let row_of = |n: usize| n % ROWS;
        for (n, h) in headers.iter().enumerate().take(TX_RING) {
            let seq = mac.send_split(h, PixelMemory::row_bus(row_of(n)), ROW).expect("room");
            assert_eq!(seq, SplitSeq(n as u64));
        }
        assert_eq!(mac.tx_free(), 0);
        assert_eq!(mac.tx_in_flight(), TX_RING);
        assert_eq!(mac.split_in_flight(), TX_RING);
        let next = mac.send_split(&headers[TX_RING], PixelMemory::row_bus(0), ROW);
        assert_eq!(next, Err(SplitError::Full), "a full ring says so instead of waiting");
        assert_eq!(mac.stats().tx_split_full, 1);
        assert!(mac.transmit(Instant::ZERO).is_none(), "and smoltcp finds no room either");

        // The DMA sends 5; 5 fit again, at descriptors 0..5 (wrapped).
        let first = dma.run(&mac, &pixels, 5);
        assert_eq!(mac.tx_free(), 5);
        assert_eq!(mac.split_completed(), SplitSeq(5));
        for (n, h) in headers.iter().enumerate().skip(TX_RING).take(5) {
            mac.send_split(h, PixelMemory::row_bus(row_of(n)), ROW).expect("room after the DMA sent 5");
        }
        assert_eq!(mac.send_split(&headers[0], 0, ROW), Err(SplitError::Full));
        assert_eq!(mac.shared.area.tx_descriptor(4).word(3), PixelMemory::row_bus(row_of(TX_RING + 4)), "wrapped");

        let rest = dma.run(&mac, &pixels, usize::MAX);
        let all: Vec<Sent> = first.into_iter().chain(rest).collect();
        assert_eq!(all.len(), TX_RING + 5);
        for (n, sent) in all.iter().enumerate() {
            assert_eq!(sent.descriptor, n % TX_RING);
            assert_rtp_on_wire(sent, &headers[n], &pixels, row_of(n));
        }
        assert_eq!(mac.tx_free(), TX_RING);
        assert_eq!(mac.split_completed(), SplitSeq(TX_RING as u64 + 5));
        assert_eq!(pixels.bytes_read(Port::Cpu), 0);
        assert_eq!(pixels.bytes_read(Port::Dma), (TX_RING + 5) * ROW, "every row read once, by the DMA");
    }
}

#[test]
fn split_frames_interleave_with_smoltcp_transmits() {
    for hw in [QEMU_HW_FEATURE, CYCLONE_V_HW_FEATURE] {
        let mut rig = Rig::new(hw);
        let mut mac = rig.mac(true);
        started(&mut mac);
        let pixels = PixelMemory::new();
        let mut dma = FakeDma { next: 0 };
        let (h0, h1) = (rtp_header(0), rtp_header(1));

        transmit_tcp(&mut mac, 60, 0x11);
        let s0 = mac.send_split(&h0, PixelMemory::row_bus(0), ROW).expect("room");
        transmit_one(&mut mac, 42, 0x22);
        let s1 = mac.send_split(&h1, PixelMemory::row_bus(1), ROW).expect("room");
        // smoltcp's token after split frames: the next descriptor, one buffer.
        let tok = mac.transmit(Instant::ZERO).expect("room");
        tok.consume(100, |b| b.fill(0x33));
        assert_eq!((mac.tx_in_flight(), mac.split_in_flight()), (5, 2));

        // The DMA takes the TCP frame only: both split frames still in flight.
        let sent = dma.run(&mac, &pixels, 1);
        assert_eq!((sent[0].len2, sent[0].csum), (0, ChecksumInsertion::Full), "smoltcp: one buffer, TCP");
        assert_eq!((mac.tx_in_flight(), mac.split_in_flight()), (4, 2));
        assert!(!mac.split_done(s0) && !mac.split_done(s1));
        // Then the first split frame: it is done, the second is not.
        let sent2 = dma.run(&mac, &pixels, 1);
        assert_rtp_on_wire(&sent2[0], &h0, &pixels, 0);
        assert!(mac.split_done(s0) && !mac.split_done(s1));
        assert_eq!((mac.tx_in_flight(), mac.split_in_flight()), (3, 1));
        // The rest, in order.
        let rest = dma.run(&mac, &pixels, usize::MAX);
        assert_eq!(rest.len(), 3);
        assert_eq!((rest[0].len2, rest[0].wire.clone()), (0, vec![0x22; 42]), "ARP-like frame as built");
        assert_rtp_on_wire(&rest[1], &h1, &pixels, 1);
        assert_eq!((rest[2].len2, rest[2].wire.clone()), (0, vec![0x33; 100]));
        assert!(mac.split_done(s1));
        assert_eq!((mac.tx_in_flight(), mac.split_in_flight(), mac.tx_free()), (0, 0, TX_RING));
        assert_eq!(mac.stats().tx_frames, 5);
        assert_eq!(mac.stats().tx_split, 2);
        assert_eq!(pixels.bytes_read(Port::Cpu), 0);
    }
}

#[test]
fn bad_lengths_are_refused_without_using_a_descriptor() {
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let mut mac = rig.mac(true);
    started(&mut mac);
    let h = rtp_header(0);
    assert_eq!(mac.send_split(&h[..13], 0, 0), Err(SplitError::Length), "no room for an Ethernet header");
    assert_eq!(mac.send_split(&h, FRAME_RING_BUS, MAX_FRAME - HEADER + 1), Err(SplitError::Length));
    assert_eq!(mac.send_split(&h, FRAME_RING_BUS, usize::MAX), Err(SplitError::Length));
    assert_eq!(mac.tx_in_flight(), 0);
    assert_eq!(mac.shared.area.tx_descriptor(0).word(0), 0);
    assert_eq!(mac.send_split(&h, FRAME_RING_BUS, MAX_FRAME - HEADER), Ok(SplitSeq(0)), "exactly MAX_FRAME");
}

#[test]
fn sequence_numbers_go_on_across_a_restart_and_nothing_stays_in_flight() {
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let mut mac = rig.mac(true);
    started(&mut mac);
    for n in 0..3 {
        mac.send_split(&rtp_header(n), PixelMemory::row_bus(0), ROW).expect("room");
    }
    assert_eq!(mac.split_completed(), SplitSeq(0));
    mac.start_for_test(super::MAC);
    assert_eq!(mac.split_completed(), SplitSeq(3), "the reset DMA reads none of them any more");
    assert_eq!(mac.tx_in_flight(), 0);
    let seq = mac.send_split(&rtp_header(3), PixelMemory::row_bus(0), ROW).expect("room");
    assert_eq!(seq, SplitSeq(3));
    assert!(!mac.split_done(seq));
}

/// Whatever order split sends, smoltcp sends and DMA progress come in, the
/// driver's view of what is in flight matches the DMA's, every frame leaves
/// intact and in order, and the CPU reads no payload.
mod interleavings {
    use super::*;
    use proptest::prelude::*;

    #[derive(Clone, Debug)]
    enum Step {
        Split(usize),
        Smoltcp(usize),
        Dma(usize),
    }

    fn step() -> impl Strategy<Value = Step> {
        prop_oneof![
            (0..ROWS).prop_map(Step::Split),
            (14usize..200).prop_map(Step::Smoltcp),
            (0usize..8).prop_map(Step::Dma),
        ]
    }

    proptest! {
        #[test]
        fn in_flight_tracking_matches_the_dma(enhanced: bool, steps in proptest::collection::vec(step(), 1..200)) {
            let mut rig = Rig::new(if enhanced { CYCLONE_V_HW_FEATURE } else { QEMU_HW_FEATURE });
            let mut mac = rig.mac(true);
            started(&mut mac);
            let pixels = PixelMemory::new();
            let mut dma = FakeDma { next: 0 };
            // What was handed over and not yet sent: Some((seq, row, header)) for split frames.
            let mut queue: std::collections::VecDeque<Option<(SplitSeq, usize, Vec<u8>)>> = Default::default();
            let mut sent_split = 0u64;
            for s in steps {
                match s {
                    Step::Split(r) => {
                        let h = rtp_header(r as u16);
                        match mac.send_split(&h, PixelMemory::row_bus(r), ROW) {
                            Ok(seq) => {
                                prop_assert!(queue.len() < TX_RING);
                                prop_assert_eq!(seq, SplitSeq(sent_split));
                                sent_split += 1;
                                queue.push_back(Some((seq, r, h)));
                            }
                            Err(e) => {
                                prop_assert_eq!(e, SplitError::Full);
                                prop_assert_eq!(queue.len(), TX_RING);
                            }
                        }
                    }
                    Step::Smoltcp(len) => match mac.transmit(Instant::ZERO) {
                        Some(tok) => {
                            tok.consume(len, |b| b.fill(len as u8));
                            queue.push_back(None);
                        }
                        None => prop_assert_eq!(queue.len(), TX_RING),
                    },
                    Step::Dma(n) => {
                        for sent in dma.run(&mac, &pixels, n) {
                            match queue.pop_front().expect("the DMA sends only what was handed over") {
                                Some((seq, r, h)) => {
                                    prop_assert!(mac.split_done(seq));
                                    assert_rtp_on_wire(&sent, &h, &pixels, r);
                                }
                                None => prop_assert_eq!(sent.len2, 0),
                            }
                        }
                    }
                }
                prop_assert_eq!(mac.tx_in_flight(), queue.len());
                prop_assert_eq!(mac.tx_free(), TX_RING - queue.len());
                prop_assert_eq!(mac.split_in_flight(), queue.iter().flatten().count());
                if let Some((seq, ..)) = queue.iter().flatten().next() {
                    prop_assert!(!mac.split_done(*seq));
                    prop_assert_eq!(mac.split_completed(), *seq);
                }
            }
            prop_assert_eq!(pixels.bytes_read(Port::Cpu), 0);
        }
    }
}

#[test]
fn the_payload_bus_address_is_not_a_host_address_the_driver_could_read() {
    // The frame ring's bus range does not overlap the driver's transmit
    // buffers as the fake DMA resolves them, so every payload byte the DMA
    // gets went through the recording port.
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let mac = rig.mac(true);
    for j in 0..TX_RING {
        let base = mac.shared.area.tx_buffer(j).bus_address();
        let end = base.wrapping_add(BUFFER_SIZE as u32);
        let ring_end = FRAME_RING_BUS + (ROWS * ROW) as u32;
        assert!(end <= FRAME_RING_BUS || base >= ring_end, "transmit buffer {j} at {base:#x} overlaps the frame ring");
    }
}
