//! Host tests of the driver against register and descriptor memory that the
//! test plays the MAC for.

use std::cell::RefCell;
use std::ptr::NonNull;

use embedded_hal::delay::DelayNs;
use proptest::prelude::*;
use smoltcp::phy::{Checksum, Device, RxToken, TxToken};
use smoltcp::time::Instant;

use crate::desc::{self, ChecksumInsertion, DescFormat, OWN};
use crate::mac::{
    mac_config, reset_phy_then_dma, Dwmac, Error, ResetTimeout, Resets, Stats, MAX_FRAME, RESET_ATTEMPTS,
};
use crate::phy::{Link, Mdio, MdioTimeout, PhyConfig, PhyId, Speed, BMCR, BMCR_RESET};
use crate::regs::{DmaStatus, RegisterBlock, Regs};
use crate::ring::{DmaArea, BUFFER_SIZE, RX_RING, TX_RING, TX_SKEW};
use crate::sync::DmaSync;

mod split;

const BLOCK_WORDS: usize = size_of::<RegisterBlock>() / 4;
const BUS_MODE: usize = 0x1000 / 4;
const TX_POLL: usize = 0x1004 / 4;
const RX_POLL: usize = 0x1008 / 4;
const RX_BASE: usize = 0x100c / 4;
const TX_BASE: usize = 0x1010 / 4;
const STATUS: usize = 0x1014 / 4;
const OP_MODE: usize = 0x1018 / 4;
const HW_FEATURE: usize = 0x1058 / 4;
const MAC_CONFIG: usize = 0;
const ADDR_HI: usize = 0x40 / 4;
const ADDR_LO: usize = 0x44 / 4;

/// QEMU npcm-gmac's HW feature value: normal descriptors, TX checksum offload.
const QEMU_HW_FEATURE: u32 = 0x100d_4f37;
/// A value the driver never writes: a register still holding it was not written.
const UNTOUCHED: u32 = 0xdead_beef;
const MAC: [u8; 6] = [0x02, 0x00, 0x0a, 0x00, 0x02, 0x0f];

/// A register block in plain memory.
struct FakeRegs(Box<[u32; BLOCK_WORDS]>);

impl FakeRegs {
    fn new(hw_feature: u32) -> FakeRegs {
        let mut r = FakeRegs(Box::new([0; BLOCK_WORDS]));
        r.0[HW_FEATURE] = hw_feature;
        r.0[TX_POLL] = UNTOUCHED;
        r
    }
    fn regs(&mut self) -> Regs {
        let block = NonNull::new(self.0.as_mut_ptr().cast::<RegisterBlock>()).expect("boxed");
        // SAFETY: the boxed words outlive the driver in every test and are
        // laid out as a register block (same size, u32 alignment).
        unsafe { Regs::new(block) }
    }
    fn word_ptr(&mut self, index: usize) -> *mut u32 {
        &mut self.0[index]
    }
}

/// What a barrier saw when it ran.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Seen {
    op: &'static str,
    /// TX descriptor 0 had OWN set.
    own: bool,
    /// The TX poll-demand register had been written.
    polled: bool,
}

/// Words of a transmit buffer a [`TxSnapshot`] keeps: every header and
/// the test frames.
const SNAPSHOT_BUFFER_WORDS: usize = 64;

/// One transmit descriptor's four words, then the first
/// [`SNAPSHOT_BUFFER_WORDS`] of its buffer.
type TxSlot = [u32; 4 + SNAPSHOT_BUFFER_WORDS];

/// The whole transmit ring at one barrier.
type TxSnapshot = Vec<TxSlot>;

/// Records every barrier with the state of TX descriptor 0 and the
/// poll-demand register at that moment, and a snapshot of the transmit
/// ring ([`assert_drained_before_own`]).
struct Recorder {
    events: RefCell<Vec<Seen>>,
    snapshots: RefCell<Vec<TxSnapshot>>,
    area: *const DmaArea,
    tx_poll: *const u32,
}

impl Recorder {
    fn record(&self, op: &'static str) {
        // SAFETY: both point into the test's live DMA area and register block;
        // volatile reads, as the driver's writes are volatile too.
        let (area, poll) = unsafe { (&*self.area, self.tx_poll.read_volatile()) };
        let snapshot: TxSnapshot = (0..TX_RING)
            .map(|i| {
                let mut slot = [0; 4 + SNAPSHOT_BUFFER_WORDS];
                slot[..4].copy_from_slice(&area.tx_descriptor(i).words());
                // SAFETY: the buffer is live and word aligned; volatile reads
                // of words the driver may have a slice of between barriers,
                // never during one (the test is single-threaded).
                let words = unsafe { area.tx_buffer(i).bytes(4 * SNAPSHOT_BUFFER_WORDS) }.as_ptr().cast::<u32>();
                for (k, w) in slot[4..].iter_mut().enumerate() {
                    // SAFETY: within the buffer (`k` < SNAPSHOT_BUFFER_WORDS).
                    *w = unsafe { words.add(k).read_volatile() };
                }
                slot
            })
            .collect();
        let own = snapshot[0][0] & OWN != 0;
        self.events.borrow_mut().push(Seen { op, own, polled: poll != UNTOUCHED });
        self.snapshots.borrow_mut().push(snapshot);
    }
}

/// Check the transmit hand-over order over everything recorded: whenever a
/// descriptor's OWN is newly set at a barrier, its TDES1..3 and buffer are
/// what they were at the last drain (`dsb`, then the outer cache sync)
/// before that barrier, so they reached memory before OWN could (the
/// L2C-310 drains its store buffer out of program order: `crate::sync`).
/// Returns how many hand-overs it checked, so a test can see it checked
/// every frame it sent.
fn assert_drained_before_own(mac: &TestMac<'_>) -> usize {
    let events = mac.events();
    let snapshots = mac.shared.sync.snapshots.borrow();
    let mut checked = 0;
    for e in 1..events.len() {
        for i in 0..TX_RING {
            let (before, now) = (&snapshots[e - 1][i], &snapshots[e][i]);
            if now[0] & OWN == 0 || before[0] & OWN != 0 {
                continue;
            }
            let drain = (1..e).rev().find(|&s| events[s].op == "sync" && events[s - 1].op == "dsb");
            let Some(drain) = drain else {
                panic!("descriptor {i} given at barrier {e} with no drain before it");
            };
            assert_eq!(
                &snapshots[drain][i][1..],
                &now[1..],
                "descriptor {i} given at barrier {e}: TDES1..3 or its buffer changed after the last drain ({drain})"
            );
            checked += 1;
        }
    }
    checked
}

impl DmaSync for Recorder {
    fn dsb(&self) {
        self.record("dsb")
    }
    fn dmb(&self) {
        self.record("dmb")
    }
    fn outer_sync(&self) {
        self.record("sync")
    }
}

/// A delay whose every call also completes the DMA's software reset (or
/// not), the way the hardware would while the driver waits.
struct ResettingDelay {
    bus_mode: *mut u32,
    completes: bool,
}

impl DelayNs for ResettingDelay {
    fn delay_ns(&mut self, _ns: u32) {
        if self.completes {
            // SAFETY: points into the test's live register block.
            unsafe { *self.bus_mode &= !1 };
        }
    }
}

struct Rig {
    regs: FakeRegs,
    area: Box<DmaArea>,
}

type TestMac<'a> = Dwmac<'a, Recorder, ResettingDelay>;

impl Rig {
    fn new(hw_feature: u32) -> Rig {
        Rig { regs: FakeRegs::new(hw_feature), area: Box::new(DmaArea::new()) }
    }

    /// A driver over the rig, started as `bring_up` would (without a PHY).
    fn mac(&mut self, completes: bool) -> TestMac<'_> {
        let recorder = Recorder {
            events: RefCell::default(),
            snapshots: RefCell::default(),
            area: &*self.area,
            tx_poll: self.regs.word_ptr(TX_POLL),
        };
        let delay = ResettingDelay { bus_mode: self.regs.word_ptr(BUS_MODE), completes };
        let regs = self.regs.regs();
        Dwmac::new(regs, &self.area, recorder, delay)
    }
}

fn started(mac: &mut TestMac<'_>) {
    mac.reset_dma().expect("reset completes");
    mac.start_for_test(MAC);
}

impl TestMac<'_> {
    fn start_for_test(&mut self, addr: [u8; 6]) {
        // `bring_up` without the PHY part.
        self.start(addr)
    }
    fn events(&self) -> Vec<Seen> {
        self.shared.sync.events.borrow().clone()
    }
    fn clear_events(&self) {
        self.shared.sync.events.borrow_mut().clear();
        self.shared.sync.snapshots.borrow_mut().clear()
    }
    /// Play the DMA: write `frame` plus a 4-byte FCS into RX slot `i` and
    /// write RDES0 (OWN clear) with `flags`.
    fn dma_receive(&self, i: usize, frame: &[u8], flags: u32) {
        // SAFETY: the test plays the DMA, which owns the buffer here.
        unsafe { self.shared.area.rx_buffer(i).bytes_mut(0, frame.len()) }.copy_from_slice(frame);
        let fl = (frame.len() + 4) as u32;
        self.shared.area.rx_descriptor(i).set_word(0, (fl << 16) | flags);
    }
    /// Play the DMA: take TX slot `i` (clear OWN).
    fn dma_transmitted(&self, i: usize) {
        let d = self.shared.area.tx_descriptor(i);
        d.set_word(0, d.word(0) & !OWN);
    }
}

const FS_LS: u32 = desc::RDES0_FS | desc::RDES0_LS;

fn transmit_one(mac: &mut TestMac<'_>, len: usize, fill: u8) {
    let tok = mac.transmit(Instant::ZERO).expect("room to transmit");
    tok.consume(len, |b| b.fill(fill));
}

/// A `len`-byte frame whose headers say IPv4 and TCP (the rest `fill`).
fn transmit_tcp(mac: &mut TestMac<'_>, len: usize, fill: u8) {
    let tok = mac.transmit(Instant::ZERO).expect("room to transmit");
    tok.consume(len, |b| {
        b.fill(fill);
        b[12..14].copy_from_slice(&[0x08, 0x00]);
        b[14] = 0x45;
        b[14 + 6..14 + 8].fill(0);
        b[14 + 9] = 6;
    });
}

#[test]
fn start_builds_the_rings_and_starts_the_dma() {
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let dma_base = &*rig.area as *const DmaArea as usize as u32;
    let mut mac = rig.mac(true);
    started(&mut mac);
    assert_eq!(mac.format(), DescFormat::Normal);
    assert_eq!(mac.checksum_insertion(), ChecksumInsertion::Full, "QEMU has TXCOESEL");
    for i in 0..RX_RING {
        let w = mac.shared.area.rx_descriptor(i).words();
        assert_eq!(w[0], OWN, "descriptor {i} owned by the DMA");
        assert_eq!(w[1], desc::rx_control(DescFormat::Normal, BUFFER_SIZE, i == RX_RING - 1));
        assert_ne!(w[2], 0);
    }
    assert_eq!(mac.shared.area.tx_descriptor(0).word(0) & OWN, 0);
    drop(mac);
    let r = &rig.regs.0;
    assert_eq!(r[RX_BASE], dma_base, "RX ring first in the area");
    assert_eq!(r[TX_BASE], dma_base + (RX_RING * 16) as u32);
    assert_eq!(r[BUS_MODE], 8 << 8, "PBL 8, reset done");
    let op = r[OP_MODE];
    assert_eq!(op, (1 << 1) | (1 << 13) | (1 << 21) | (1 << 25), "SR, ST, TSF, RSF");
    assert_eq!(r[ADDR_HI], 0x0f02);
    assert_eq!(r[ADDR_LO], 0x000a_0002);
    assert_eq!(r[MAC_CONFIG], 0, "transmitter and receiver off until the link is up");
}

#[test]
fn a_dma_reset_that_never_completes_times_out() {
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let mut mac = rig.mac(false);
    assert_eq!(mac.reset_dma(), Err(ResetTimeout));
}

#[test]
fn link_changes_program_speed_and_duplex() {
    let gig = Link { speed: Speed::M1000, full_duplex: true };
    assert_eq!(mac_config(Some(gig)).raw_value(), (1 << 3) | (1 << 2) | (1 << 11));
    let fast = Link { speed: Speed::M100, full_duplex: false };
    assert_eq!(mac_config(Some(fast)).raw_value(), (1 << 3) | (1 << 2) | (1 << 15) | (1 << 14));
    let slow = Link { speed: Speed::M10, full_duplex: true };
    assert_eq!(mac_config(Some(slow)).raw_value(), (1 << 3) | (1 << 2) | (1 << 15) | (1 << 11));
    assert_eq!(mac_config(None).raw_value(), 0, "no link: TE and RE off");

    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let mut mac = rig.mac(true);
    started(&mut mac);
    mac.set_link(Some(fast));
    mac.set_link(Some(gig));
    drop(mac);
    assert_eq!(rig.regs.0[MAC_CONFIG], mac_config(Some(gig)).raw_value(), "the newest link wins");
}

/// The frame filter and hash table as the driver leaves them: before any
/// group, HPF alone (own unicast and broadcast: every multicast frame
/// dropped on the board); with mDNS and all-hosts joined, HMC|HPF and
/// their bins (192: `Hash_Table_Reg6` bit 0; 128: `Hash_Table_Reg4` bit
/// 0), kept across link changes.
#[test]
fn the_multicast_filter_is_programmed_and_survives_link_changes() {
    const FRAME_FILTER: usize = 0x04 / 4;
    const HASH: usize = 0x500 / 4;
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let mut mac = rig.mac(true);
    started(&mut mac);
    let gig = Some(Link { speed: Speed::M1000, full_duplex: true });
    mac.set_link(gig);
    drop(mac);
    assert_eq!(rig.regs.0[FRAME_FILTER], 0x400);
    assert_eq!(rig.regs.0[HASH..HASH + 8], [0; 8]);
    let mut mac = rig.mac(true);
    let mut filter = crate::MulticastFilter::new();
    filter.add_group(smoltcp::wire::Ipv4Address::new(224, 0, 0, 251));
    filter.add_group(smoltcp::wire::Ipv4Address::new(224, 0, 0, 1));
    mac.set_multicast(filter);
    mac.set_link(None);
    mac.set_link(gig);
    drop(mac);
    assert_eq!(rig.regs.0[FRAME_FILTER], 0x404);
    assert_eq!(rig.regs.0[HASH..HASH + 8], [0, 0, 0, 0, 1, 0, 1, 0]);
}

#[test]
fn link_up_resumes_receive_and_link_down_leaves_it() {
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let (status, rx_poll) = (rig.regs.word_ptr(STATUS), rig.regs.word_ptr(RX_POLL));
    let mut mac = rig.mac(true);
    started(&mut mac);
    let mark = || {
        // SAFETY: both point into the rig's live register block; the driver
        // runs on this thread only between the calls.
        unsafe {
            status.write_volatile(UNTOUCHED);
            rx_poll.write_volatile(UNTOUCHED);
        }
    };
    // SAFETY: as above, read only.
    let read = || unsafe { (status.read_volatile(), rx_poll.read_volatile()) };
    mark();
    mac.set_link(None);
    assert_eq!(read(), (UNTOUCHED, UNTOUCHED), "no link: receive left alone");
    mac.set_link(Some(Link { speed: Speed::M1000, full_duplex: true }));
    let ru = DmaStatus::DEFAULT.with_ru(true).raw_value();
    assert_eq!(read(), (ru, 0), "link up: RU alone written (cleared), then a receive poll demand");
}

#[test]
fn transmit_hands_over_in_order_drain_own_drain_poll() {
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let mut mac = rig.mac(true);
    started(&mut mac);
    mac.clear_events();
    transmit_one(&mut mac, 60, 0xab);
    let seen = |op, own, polled| Seen { op, own, polled };
    assert_eq!(
        mac.events(),
        [
            seen("dmb", false, false),  // OWN seen clear, then the buffer is written
            seen("dsb", false, false),  // buffer and control words drained from the CPU ...
            seen("sync", false, false), // ... and from the L2C-310 ...
            seen("dsb", false, false),  // ... before OWN
            seen("dsb", true, false),   // OWN written, drained from the CPU ...
            seen("sync", true, false),  // ... and from the L2C-310 store buffer ...
            seen("dsb", true, false),   // ... before the poll demand
        ]
    );
    drop(mac);
    assert_eq!(rig.regs.0[TX_POLL], 0, "poll demand written last");
}

#[test]
fn every_transmitted_frame_is_in_memory_before_its_own() {
    // 100 frames of changing length and contents through a ring of 32,
    // the DMA taking some every few frames: each hand-over drained first.
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let mut mac = rig.mac(true);
    started(&mut mac);
    mac.clear_events();
    let mut dma_next = 0;
    for k in 0..100 {
        transmit_one(&mut mac, 60 + k % 7, k as u8);
        if k % 5 == 4 {
            while mac.shared.area.tx_descriptor(dma_next).word(0) & OWN != 0 {
                mac.dma_transmitted(dma_next);
                dma_next = (dma_next + 1) % TX_RING;
            }
        }
    }
    assert_eq!(assert_drained_before_own(&mac), 100);
}

#[test]
fn transmit_fills_a_normal_descriptor_and_wraps() {
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let mut mac = rig.mac(true);
    started(&mut mac);
    transmit_one(&mut mac, 60, 0xab);
    let w = mac.shared.area.tx_descriptor(0).words();
    assert_eq!(w[0], OWN);
    assert_eq!(w[1], (1 << 30) | (1 << 29) | 60, "normal: FS, LS, TBS1 in TDES1; not IP: CIC 0");
    // SAFETY: the test plays the DMA and only reads.
    let buffer = unsafe { mac.shared.area.tx_buffer(0).bytes(62) };
    assert_eq!(buffer[TX_SKEW..], [0xab; 60], "the frame starts TX_SKEW bytes in");
    assert_eq!(w[2], mac.shared.area.tx_buffer(0).bus_address() + TX_SKEW as u32, "and so does its address");
    assert_eq!((w[2] as usize + 14) % 4, 0, "IP header word aligned");
    // The ring is full once every descriptor is owned by the DMA.
    for i in 1..TX_RING {
        transmit_one(&mut mac, 100, i as u8);
    }
    assert!(mac.transmit(Instant::ZERO).is_none(), "all descriptors owned by the DMA");
    assert_eq!(mac.stats().tx_ring_full, 1);
    assert_eq!(mac.shared.area.tx_descriptor(TX_RING - 1).word(1) & (1 << 25), 1 << 25, "TER on the last");
    mac.dma_transmitted(0);
    transmit_one(&mut mac, 42, 7);
    assert_eq!(mac.shared.area.tx_descriptor(0).word(1) & 0x7ff, 42, "wrapped to descriptor 0");
    assert_eq!(mac.stats().tx_frames, TX_RING as u32 + 1);
    assert_eq!(mac.stats().tx_bytes, 60 + (TX_RING as u64 - 1) * 100 + 42);
    mac.dma_transmitted(1);
    transmit_tcp(&mut mac, 60, 0);
    assert_eq!(mac.shared.area.tx_descriptor(1).word(1), (1 << 30) | (1 << 29) | (3 << 27) | 60, "TCP: CIC 3 in 28:27");
}

#[test]
fn enhanced_descriptors_and_checksum_capabilities_follow_the_hw_feature_register() {
    let mut rig = Rig::new(QEMU_HW_FEATURE | (1 << 24));
    let mut mac = rig.mac(true);
    started(&mut mac);
    assert_eq!(mac.format(), DescFormat::Enhanced);
    assert_eq!(mac.shared.area.rx_descriptor(RX_RING - 1).word(1), (1 << 15) | BUFFER_SIZE as u32, "enhanced RER 15");
    transmit_tcp(&mut mac, 1514, 1);
    let w = mac.shared.area.tx_descriptor(0).words();
    assert_eq!(w[0], OWN | (1 << 29) | (1 << 28) | (3 << 22), "enhanced: OWN, LS, FS, CIC 3 (TCP) in TDES0");
    assert_eq!(w[1], 1514, "enhanced: TBS1 in TDES1");
    let caps = mac.capabilities().checksum;
    assert!(matches!(caps.tcp, Checksum::Rx) && matches!(caps.ipv4, Checksum::Rx), "the MAC inserts them");
    assert!(matches!(caps.icmpv4, Checksum::Both), "ICMP stays in software");

    let mut plain = Rig::new(QEMU_HW_FEATURE & !(1 << 16));
    let mac = plain.mac(true);
    assert_eq!(mac.checksum_insertion(), ChecksumInsertion::Off);
    assert!(matches!(mac.capabilities().checksum.tcp, Checksum::Both), "no offload: smoltcp computes");
}

#[test]
fn receive_hands_over_good_frames_and_returns_descriptors() {
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let mut mac = rig.mac(true);
    started(&mut mac);
    assert!(mac.receive(Instant::ZERO).is_none(), "nothing yet");
    assert!(!mac.rx_waiting(), "nothing waits");

    let frame: Vec<u8> = (0..60u8).collect();
    // QEMU's race: OWN clear and FS, but no LS yet: not ready.
    mac.dma_receive(0, &frame, desc::RDES0_FS);
    assert!(mac.receive(Instant::ZERO).is_none());
    assert!(mac.rx_waiting(), "a frame on its way counts as waiting");
    mac.dma_receive(0, &frame, FS_LS);
    mac.clear_events();
    let (rx, _tx) = mac.receive(Instant::ZERO).expect("a frame");
    let got = rx.consume(|b| b.to_vec());
    assert_eq!(mac.events()[0].op, "dmb", "OWN seen clear, dmb before the buffer is read");
    assert_eq!(got, frame, "FCS stripped");
    assert_eq!(mac.shared.area.rx_descriptor(0).word(0), OWN, "descriptor returned");
    assert!(!mac.rx_waiting(), "taken: nothing waits");

    // A bad frame is dropped; the good one after it is delivered.
    mac.dma_receive(1, &frame, FS_LS | desc::RDES0_ES);
    mac.dma_receive(2, &frame[..20], FS_LS);
    let (rx, _tx) = mac.receive(Instant::ZERO).expect("the good frame");
    assert_eq!(rx.consume(|b| b.len()), 20);
    assert_eq!(
        mac.stats(),
        Stats {
            rx_frames: 2,
            rx_bytes: frame.len() as u64 + 20,
            rx_dropped: 1,
            tx_frames: 0,
            tx_bytes: 0,
            tx_ring_full: 0,
            tx_split: 0,
            tx_split_full: 0,
            tx_split_payload_bytes: 0,
        }
    );

    // A frame split over descriptors 3 and 4 is dropped once the DMA moved on.
    mac.dma_receive(3, &frame, desc::RDES0_FS);
    mac.dma_receive(4, &frame, desc::RDES0_LS);
    assert!(mac.receive(Instant::ZERO).is_none());
    assert_eq!(mac.stats().rx_dropped, 3);
    assert_eq!(mac.shared.area.rx_descriptor(3).word(0), OWN);
    assert_eq!(mac.shared.area.rx_descriptor(4).word(0), OWN);
}

#[test]
fn receive_waits_while_transmit_is_full() {
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let mut mac = rig.mac(true);
    started(&mut mac);
    for _ in 0..TX_RING {
        transmit_one(&mut mac, 60, 0);
    }
    mac.dma_receive(0, &[1; 60], FS_LS);
    assert!(mac.receive(Instant::ZERO).is_none(), "no TX room: the frame waits");
    mac.dma_transmitted(0);
    assert!(mac.receive(Instant::ZERO).is_some());
}

#[test]
fn receive_clears_rx_unavailable() {
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let status = rig.regs.word_ptr(STATUS);
    let mut mac = rig.mac(true);
    started(&mut mac);
    // SAFETY: points into the live fake register block.
    unsafe { *status = 1 << 7 };
    mac.dma_receive(0, &[1; 60], FS_LS);
    let (rx, _) = mac.receive(Instant::ZERO).expect("a frame");
    rx.consume(|_| ());
    // Write-1-to-clear: the fake memory holds the written value (RU).
    // SAFETY: as above.
    assert_eq!(unsafe { *status }, 1 << 7, "RU written back to clear it");
}

proptest! {
    /// Whatever the DMA writes into the receive descriptors (any status
    /// word, any length), the driver hands out only whole frames that fit,
    /// never reads past a buffer, and never panics.
    #[test]
    fn any_receive_descriptor_contents_are_safe(words in proptest::collection::vec(any::<u32>(), RX_RING), rounds in 1usize..4) {
        let mut rig = Rig::new(QEMU_HW_FEATURE);
        let mut mac = rig.mac(true);
        started(&mut mac);
        for _ in 0..rounds {
            for (i, w) in words.iter().enumerate() {
                mac.shared.area.rx_descriptor(i).set_word(0, *w);
            }
            for _ in 0..2 * RX_RING {
                let Some((rx, _tx)) = mac.receive(Instant::ZERO) else { break };
                let len = rx.consume(|b| b.len());
                prop_assert!(len <= MAX_FRAME);
            }
        }
    }
}

/// A PHY and a DMA reset that completes only after a PHY reset, and only
/// from the `works_from`-th DMA reset on.
struct Bench {
    log: Vec<&'static str>,
    phy_reset_pending: bool,
    dma_resets: u32,
    works_from: u32,
}

impl DelayNs for Bench {
    fn delay_ns(&mut self, _: u32) {}
}

impl Mdio for Bench {
    fn read(&mut self, _phy: u8, reg: u8) -> Result<u16, MdioTimeout> {
        Ok(if reg == 2 { 0x0022 } else { 0 })
    }
    fn write(&mut self, _phy: u8, reg: u8, value: u16) -> Result<(), MdioTimeout> {
        if reg == BMCR && value & BMCR_RESET != 0 {
            self.log.push("phy reset");
            self.phy_reset_pending = true;
        }
        Ok(())
    }
}

impl Resets for Bench {
    fn reset_dma(&mut self) -> Result<(), ResetTimeout> {
        self.log.push("dma reset");
        self.dma_resets += 1;
        let clock_running = std::mem::take(&mut self.phy_reset_pending);
        if clock_running && self.dma_resets >= self.works_from {
            Ok(())
        } else {
            Err(ResetTimeout)
        }
    }
}

#[test]
fn the_phy_is_reset_before_each_dma_reset_attempt() {
    let phy = PhyId { addr: 1, id1: 0x0022, id2: 0x1611 };
    let cfg = PhyConfig { ksz9021_skews: None, ksz9021_force_master: false };
    let mut ok_second = Bench { log: vec![], phy_reset_pending: false, dma_resets: 0, works_from: 2 };
    assert_eq!(reset_phy_then_dma(&mut ok_second, phy, &cfg), Ok(()));
    assert_eq!(ok_second.log, ["phy reset", "dma reset", "phy reset", "dma reset"]);

    let mut never = Bench { log: vec![], phy_reset_pending: false, dma_resets: 0, works_from: u32::MAX };
    assert_eq!(reset_phy_then_dma(&mut never, phy, &cfg), Err(Error::ResetTimeout { attempts: RESET_ATTEMPTS }));
    assert_eq!(never.dma_resets, u32::from(RESET_ATTEMPTS), "bounded");
    assert!(Error::ResetTimeout { attempts: 3 }.to_string().contains("3 attempts"));
}

/// The peer of the ping tests: its addresses and the frames it sends.
mod peer {
    use smoltcp::phy::ChecksumCapabilities;
    use smoltcp::wire::{
        ArpOperation, ArpPacket, ArpRepr, EthernetAddress, EthernetFrame, EthernetProtocol, EthernetRepr, Icmpv4Packet,
        Icmpv4Repr, IpProtocol, Ipv4Address, Ipv4Packet, Ipv4Repr, TcpControl, TcpPacket, TcpRepr, TcpSeqNumber,
    };

    pub const MAC: EthernetAddress = EthernetAddress([0x02, 0x00, 0x00, 0x00, 0x00, 0x01]);
    pub const IP: Ipv4Address = Ipv4Address::new(10, 0, 2, 2);
    pub const OURS: Ipv4Address = Ipv4Address::new(10, 0, 2, 15);

    fn ethernet(
        dst: EthernetAddress,
        ethertype: EthernetProtocol,
        len: usize,
        emit: impl FnOnce(&mut [u8]),
    ) -> Vec<u8> {
        let mut f = vec![0u8; 14 + len];
        let mut e = EthernetFrame::new_unchecked(&mut f[..]);
        EthernetRepr { src_addr: MAC, dst_addr: dst, ethertype }.emit(&mut e);
        emit(e.payload_mut());
        f
    }

    /// "Who has OURS? Tell IP."
    pub fn arp_request() -> Vec<u8> {
        let r = ArpRepr::EthernetIpv4 {
            operation: ArpOperation::Request,
            source_hardware_addr: MAC,
            source_protocol_addr: IP,
            target_hardware_addr: EthernetAddress([0; 6]),
            target_protocol_addr: OURS,
        };
        ethernet(EthernetAddress::BROADCAST, EthernetProtocol::Arp, r.buffer_len(), |b| {
            r.emit(&mut ArpPacket::new_unchecked(b))
        })
    }

    fn ipv4(to: EthernetAddress, protocol: IpProtocol, len: usize, emit: impl FnOnce(&mut [u8])) -> Vec<u8> {
        let ip = Ipv4Repr { src_addr: IP, dst_addr: OURS, next_header: protocol, payload_len: len, hop_limit: 64 };
        ethernet(to, EthernetProtocol::Ipv4, ip.buffer_len() + len, |b| {
            let mut p = Ipv4Packet::new_unchecked(b);
            ip.emit(&mut p, &ChecksumCapabilities::default());
            emit(p.payload_mut());
        })
    }

    /// An echo request with every checksum filled in, as a PC sends it.
    pub fn echo_request(to: EthernetAddress, data: &[u8]) -> Vec<u8> {
        let r = Icmpv4Repr::EchoRequest { ident: 0x4242, seq_no: 1, data };
        ipv4(to, IpProtocol::Icmp, r.buffer_len(), |b| {
            r.emit(&mut Icmpv4Packet::new_unchecked(b), &ChecksumCapabilities::default())
        })
    }

    /// A SYN to `port`.
    pub fn syn(to: EthernetAddress, port: u16) -> Vec<u8> {
        let r = TcpRepr {
            src_port: 50000,
            dst_port: port,
            control: TcpControl::Syn,
            seq_number: TcpSeqNumber(1000),
            ack_number: None,
            window_len: 8192,
            window_scale: None,
            max_seg_size: Some(1460),
            sack_permitted: false,
            sack_ranges: [None; 3],
            timestamp: None,
            payload: &[],
        };
        ipv4(to, IpProtocol::Tcp, r.buffer_len(), |b| {
            r.emit(&mut TcpPacket::new_unchecked(b), &IP.into(), &OURS.into(), &ChecksumCapabilities::default())
        })
    }
}

/// The board's side of the ping tests: the driver over enhanced descriptors
/// with the checksum engine (the Cyclone V EMAC's HW feature bits), smoltcp
/// on top, and the frames it transmits taken off the TX ring as the MAC
/// would, through the model of the MAC's checksum engine.
struct Board<'r> {
    mac: TestMac<'r>,
    iface: smoltcp::iface::Interface,
    sockets: smoltcp::iface::SocketSet<'static>,
    rx_next: usize,
    tx_next: usize,
}

impl<'r> Board<'r> {
    fn new(rig: &'r mut Rig) -> Board<'r> {
        use smoltcp::iface::{Config, Interface, SocketSet};
        use smoltcp::wire::{EthernetAddress, HardwareAddress, IpCidr};
        let mut mac = rig.mac(true);
        started(&mut mac);
        assert_eq!(mac.format(), DescFormat::Enhanced);
        assert_eq!(mac.checksum_insertion(), ChecksumInsertion::Full);
        let config = Config::new(HardwareAddress::Ethernet(EthernetAddress(MAC)));
        let mut iface = Interface::new(config, &mut mac, Instant::ZERO);
        iface.update_ip_addrs(|a| a.push(IpCidr::new(peer::OURS.into(), 24)).expect("room for one address"));
        Board { mac, iface, sockets: SocketSet::new(vec![]), rx_next: 0, tx_next: 0 }
    }

    /// The peer sends `frame`; smoltcp answers; every frame that left is
    /// returned with the CIC its descriptor asked for, before the engine.
    fn exchange(&mut self, frame: &[u8]) -> Vec<(ChecksumInsertion, Vec<u8>)> {
        self.mac.dma_receive(self.rx_next, frame, FS_LS);
        self.rx_next += 1;
        self.iface.poll(Instant::ZERO, &mut self.mac, &mut self.sockets);
        let mut out = vec![];
        let area = self.mac.shared.area;
        while area.tx_descriptor(self.tx_next).word(0) & OWN != 0 {
            let w = area.tx_descriptor(self.tx_next).words();
            let cic = desc::tx_checksum_insertion(DescFormat::Enhanced, [w[0], w[1]]);
            let len = (w[1] & 0x1fff) as usize;
            // SAFETY: the test plays the DMA, which owns the buffer now.
            let bytes = unsafe { area.tx_buffer(self.tx_next).bytes(TX_SKEW + len) }[TX_SKEW..].to_vec();
            self.mac.dma_transmitted(self.tx_next);
            self.tx_next += 1;
            out.push((cic, bytes));
        }
        out
    }
}

/// Whether `frame`'s IPv4 header, and its ICMP or TCP checksum, verify
/// (smoltcp's own checks, independent of the engine model).
fn checksums_verify(frame: &[u8]) -> Result<(), String> {
    use smoltcp::wire::{EthernetFrame, Icmpv4Packet, IpProtocol, Ipv4Packet, TcpPacket};
    let eth = EthernetFrame::new_checked(frame).map_err(|e| e.to_string())?;
    let ip = Ipv4Packet::new_checked(eth.payload()).map_err(|e| e.to_string())?;
    if !ip.verify_checksum() {
        return Err("IPv4 header checksum".into());
    }
    let ok = match ip.next_header() {
        IpProtocol::Icmp => Icmpv4Packet::new_checked(ip.payload()).map_err(|e| e.to_string())?.verify_checksum(),
        IpProtocol::Tcp => TcpPacket::new_checked(ip.payload())
            .map_err(|e| e.to_string())?
            .verify_checksum(&ip.src_addr().into(), &ip.dst_addr().into()),
        other => return Err(format!("unexpected protocol {other}")),
    };
    if ok {
        Ok(())
    } else {
        Err(format!("{} checksum", ip.next_header()))
    }
}

#[test]
fn a_ping_answered_through_the_driver_leaves_the_checksum_engine_with_valid_checksums() {
    use crate::gmac_csum_model::insert;
    use smoltcp::wire::{EthernetAddress, EthernetFrame, Icmpv4Packet, Icmpv4Repr, Ipv4Packet};
    let mut rig = Rig::new(QEMU_HW_FEATURE | (1 << 24));
    let mut board = Board::new(&mut rig);

    // ARP first (smoltcp answers IP only to neighbours it knows).
    let arp = board.exchange(&peer::arp_request());
    assert_eq!(arp.len(), 1, "one ARP reply");

    let data: Vec<u8> = (0..56u8).collect();
    let out = board.exchange(&peer::echo_request(EthernetAddress(MAC), &data));
    assert_eq!(out.len(), 1, "one echo reply");
    let (cic, reply) = &out[0];

    // On the wire, after the MAC's engine ran as the descriptor asked: both
    // checksums right.
    let mut wire = reply.clone();
    insert(&mut wire, *cic);
    assert_eq!(checksums_verify(&wire), Ok(()), "the echo reply as it leaves the MAC (CIC {cic:?})");
    assert_eq!(*cic, ChecksumInsertion::HeaderOnly, "ICMP: the IPv4 header only");
    assert_eq!(arp[0].0, ChecksumInsertion::Off, "ARP: no checksum insertion");
    // What the stack left to the MAC and what it filled in itself.
    let ip = Ipv4Packet::new_unchecked(&reply[14..]);
    assert_eq!(ip.checksum(), 0, "IPv4 header checksum left to the MAC");
    let icmp = Icmpv4Packet::new_unchecked(ip.payload());
    assert!(icmp.verify_checksum(), "ICMP checksum computed by smoltcp");
    let repr = Icmpv4Repr::parse(&icmp, &smoltcp::phy::ChecksumCapabilities::default()).expect("an echo reply");
    assert_eq!(repr, Icmpv4Repr::EchoReply { ident: 0x4242, seq_no: 1, data: &data });
    assert_eq!(EthernetFrame::new_unchecked(&reply[..]).dst_addr(), peer::MAC);

    // The old descriptor (CIC 3 on every frame) on the same reply: the
    // databook's engine corrupts the ICMP checksum the stack filled in.
    let mut old = reply.clone();
    insert(&mut old, ChecksumInsertion::Full);
    assert_eq!(checksums_verify(&old), Err("ICMP checksum".into()));
}

#[test]
fn a_syn_ack_through_the_driver_keeps_full_insertion_and_verifies_after_the_engine() {
    use crate::gmac_csum_model::insert;
    use smoltcp::socket::tcp;
    use smoltcp::wire::{EthernetAddress, Ipv4Packet, TcpPacket};
    let mut rig = Rig::new(QEMU_HW_FEATURE | (1 << 24));
    let mut board = Board::new(&mut rig);
    let mut socket = tcp::Socket::new(tcp::SocketBuffer::new(vec![0; 1024]), tcp::SocketBuffer::new(vec![0; 1024]));
    socket.listen(7878).expect("listen");
    board.sockets.add(socket);
    board.exchange(&peer::arp_request());

    let out = board.exchange(&peer::syn(EthernetAddress(MAC), 7878));
    assert_eq!(out.len(), 1, "one SYN-ACK");
    let (cic, segment) = &out[0];
    assert_eq!(*cic, ChecksumInsertion::Full, "TCP: header and payload with the pseudo-header");
    let ip = Ipv4Packet::new_unchecked(&segment[14..]);
    assert_eq!(TcpPacket::new_unchecked(ip.payload()).checksum(), 0, "TCP checksum left to the MAC");
    let mut wire = segment.clone();
    insert(&mut wire, *cic);
    assert_eq!(checksums_verify(&wire), Ok(()));
    // Without insertion the segment would leave with zero checksums.
    assert!(checksums_verify(segment).is_err());
}
