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
use crate::regs::{RegisterBlock, Regs};
use crate::ring::{DmaArea, BUFFER_SIZE, RX_RING, TX_RING, TX_SKEW};
use crate::sync::DmaSync;

const BLOCK_WORDS: usize = size_of::<RegisterBlock>() / 4;
const BUS_MODE: usize = 0x1000 / 4;
const TX_POLL: usize = 0x1004 / 4;
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

/// Records every barrier with the state of TX descriptor 0 and the
/// poll-demand register at that moment.
struct Recorder {
    events: RefCell<Vec<Seen>>,
    tx_desc0: *const u32,
    tx_poll: *const u32,
}

impl Recorder {
    fn record(&self, op: &'static str) {
        // SAFETY: both point into the test's live DMA area and register block;
        // volatile reads, as the driver's writes are volatile too.
        let (own, poll) = unsafe { (self.tx_desc0.read_volatile() & OWN != 0, self.tx_poll.read_volatile()) };
        self.events.borrow_mut().push(Seen { op, own, polled: poll != UNTOUCHED });
    }
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
            tx_desc0: self.area.tx_descriptor(0) as *const _ as *const u32,
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
        self.shared.sync.events.borrow_mut().clear()
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

#[test]
fn transmit_hands_over_in_order_own_dsb_cache_sync_dsb_poll() {
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let mut mac = rig.mac(true);
    started(&mut mac);
    mac.clear_events();
    transmit_one(&mut mac, 60, 0xab);
    let seen = |op, own, polled| Seen { op, own, polled };
    assert_eq!(
        mac.events(),
        [
            seen("dmb", false, false), // OWN seen clear, then the buffer is written
            seen("dsb", false, false), // buffer and control words, before OWN
            seen("dsb", true, false),  // OWN written, drained from the CPU ...
            seen("sync", true, false), // ... and from the L2C-310 store buffer ...
            seen("dsb", true, false),  // ... before the poll demand
        ]
    );
    drop(mac);
    assert_eq!(rig.regs.0[TX_POLL], 0, "poll demand written last");
}

#[test]
fn transmit_fills_a_normal_descriptor_and_wraps() {
    let mut rig = Rig::new(QEMU_HW_FEATURE);
    let mut mac = rig.mac(true);
    started(&mut mac);
    transmit_one(&mut mac, 60, 0xab);
    let w = mac.shared.area.tx_descriptor(0).words();
    assert_eq!(w[0], OWN);
    assert_eq!(w[1], (1 << 30) | (1 << 29) | (3 << 27) | 60, "normal: FS, LS, CIC full, TBS1 in TDES1");
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
}

#[test]
fn enhanced_descriptors_and_checksum_capabilities_follow_the_hw_feature_register() {
    let mut rig = Rig::new(QEMU_HW_FEATURE | (1 << 24));
    let mut mac = rig.mac(true);
    started(&mut mac);
    assert_eq!(mac.format(), DescFormat::Enhanced);
    assert_eq!(mac.shared.area.rx_descriptor(RX_RING - 1).word(1), (1 << 15) | BUFFER_SIZE as u32, "enhanced RER 15");
    transmit_one(&mut mac, 1514, 1);
    let w = mac.shared.area.tx_descriptor(0).words();
    assert_eq!(w[0], OWN | (1 << 29) | (1 << 28) | (3 << 22), "enhanced: OWN, LS, FS, CIC in TDES0");
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

    let frame: Vec<u8> = (0..60u8).collect();
    // QEMU's race: OWN clear and FS, but no LS yet: not ready.
    mac.dma_receive(0, &frame, desc::RDES0_FS);
    assert!(mac.receive(Instant::ZERO).is_none());
    mac.dma_receive(0, &frame, FS_LS);
    mac.clear_events();
    let (rx, _tx) = mac.receive(Instant::ZERO).expect("a frame");
    let got = rx.consume(|b| b.to_vec());
    assert_eq!(mac.events()[0].op, "dmb", "OWN seen clear, dmb before the buffer is read");
    assert_eq!(got, frame, "FCS stripped");
    assert_eq!(mac.shared.area.rx_descriptor(0).word(0), OWN, "descriptor returned");

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
            tx_ring_full: 0
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
