//! Host tests of the ring handling against register and descriptor memory
//! that the test plays the DMA for.

use core::cell::Cell;

use smoltcp::phy::{Device, RxToken, TxToken};
use smoltcp::time::Instant;

use super::*;
use crate::drivers::clock::Clock;

const REG_WORDS: usize = FORBIDDEN_FROM / 4;

/// Fake register block: plain memory.
struct Regs(Box<[u32; REG_WORDS]>);

impl Regs {
    fn new(hw_feature: u32) -> Regs {
        let mut r = Regs(Box::new([0; REG_WORDS]));
        r.0[DMA_HW_FEATURE / 4] = hw_feature;
        r
    }
    fn mmio(&mut self) -> Mmio {
        // SAFETY: the block outlives the driver in every test and covers
        // every offset below FORBIDDEN_FROM.
        unsafe { Mmio::new(self.0.as_mut_ptr() as usize) }
    }
}

/// A clock whose every reading also completes the DMA's software reset, the
/// way the hardware would while the driver waits.
struct ResettingClock {
    bus_mode: *mut u32,
    now: Cell<u64>,
    completes: bool,
}

impl Clock for ResettingClock {
    fn now_us(&self) -> u64 {
        if self.completes {
            // SAFETY: points into the test's live register block.
            unsafe { *self.bus_mode &= !BUS_MODE_SWR };
        }
        let t = self.now.get();
        self.now.set(t + 100);
        t
    }
}

fn clock(regs: &mut Regs, completes: bool) -> ResettingClock {
    ResettingClock { bus_mode: &mut regs.0[DMA_BUS_MODE / 4], now: Cell::new(0), completes }
}

const MAC: [u8; 6] = [0x02, 0x00, 0x0a, 0x00, 0x02, 0x0f];
const QEMU_HW_FEATURE: u32 = 0x100d_4f37;

impl Dwmac<'_> {
    fn rx_words(&self, i: usize) -> [u32; 4] {
        self.rx.desc[i].words()
    }
    fn tx_words(&self, i: usize) -> [u32; 4] {
        self.tx.desc[i].words()
    }
    /// Play the DMA: write `frame` plus a 4-byte FCS into RX slot `i` and
    /// write RDES0 (OWN clear) with `flags`.
    fn dma_receive(&mut self, i: usize, frame: &[u8], flags: u32) {
        self.rx.buf[i].0[..frame.len()].copy_from_slice(frame);
        let fl = (frame.len() + 4) as u32;
        self.rx.desc[i].write(0, (fl << 16) | flags);
    }
    /// Play the DMA: take TX slot `i` (clear OWN).
    fn dma_transmitted(&mut self, i: usize) {
        let w0 = self.tx.desc[i].read(0);
        self.tx.desc[i].write(0, w0 & !OWN);
    }
}

const FS_LS: u32 = desc::RDES0_FS | desc::RDES0_LS;

#[test]
fn init_builds_the_rings_and_starts_the_dma() {
    let mut regs = Regs::new(QEMU_HW_FEATURE);
    let mut dma = Box::new(DmaArea::new());
    let dma_base = &*dma as *const DmaArea as usize as u32;
    let c = clock(&mut regs, true);
    let mac = Dwmac::new(regs.mmio(), &mut dma, MAC, &c).unwrap();
    assert_eq!(mac.format(), DescFormat::Normal);
    for i in 0..RX_RING {
        let w = mac.rx_words(i);
        assert_eq!(w[0], OWN, "descriptor {i} owned by the DMA");
        assert_eq!(w[1], desc::rx_control(DescFormat::Normal, BUFFER_SIZE, i == RX_RING - 1));
        assert_ne!(w[2], 0);
    }
    assert_eq!(mac.rx_words(RX_RING - 1)[1] & (1 << 25), 1 << 25, "RER on the last");
    assert_eq!(mac.tx_words(0)[0] & OWN, 0);
    drop(mac);
    let r = &regs.0;
    assert_eq!(r[DMA_RX_BASE / 4], dma_base, "RX ring first in the area");
    assert_eq!(r[DMA_TX_BASE / 4], dma_base + (RX_RING * 16) as u32);
    assert_eq!(r[DMA_BUS_MODE / 4], 8 << 8, "PBL 8, reset done");
    let op = r[DMA_OP_MODE / 4];
    assert_eq!(op & (OP_MODE_SR | OP_MODE_ST), OP_MODE_SR | OP_MODE_ST);
    assert_eq!(r[MAC_ADDR0_HI / 4], 0x0f02);
    assert_eq!(r[MAC_ADDR0_LO / 4], 0x000a_0002);
    assert_eq!(r[MAC_CONFIG / 4] & (MAC_CONFIG_TE | MAC_CONFIG_RE), 0, "off until the link is up");
}

#[test]
fn a_reset_that_never_completes_times_out() {
    let mut regs = Regs::new(QEMU_HW_FEATURE);
    let mut dma = Box::new(DmaArea::new());
    let c = clock(&mut regs, false);
    assert_eq!(Dwmac::new(regs.mmio(), &mut dma, MAC, &c).err(), Some(Error::ResetTimeout));
}

#[test]
fn set_link_programs_speed_and_duplex() {
    let gig = Link { speed: Speed::M1000, full_duplex: true };
    assert_eq!(mac_config(gig), MAC_CONFIG_TE | MAC_CONFIG_RE | MAC_CONFIG_DM);
    let fast = Link { speed: Speed::M100, full_duplex: false };
    assert_eq!(mac_config(fast), MAC_CONFIG_TE | MAC_CONFIG_RE | MAC_CONFIG_PS | MAC_CONFIG_FES);
    let slow = Link { speed: Speed::M10, full_duplex: true };
    assert_eq!(mac_config(slow), MAC_CONFIG_TE | MAC_CONFIG_RE | MAC_CONFIG_PS | MAC_CONFIG_DM);
}

fn transmit_one(mac: &mut Dwmac<'_>, len: usize, fill: u8) {
    let tok = mac.transmit(Instant::ZERO).expect("room to transmit");
    tok.consume(len, |b| b.fill(fill));
}

#[test]
fn transmit_fills_a_normal_descriptor_and_wraps() {
    let mut regs = Regs::new(QEMU_HW_FEATURE);
    let mut dma = Box::new(DmaArea::new());
    let c = clock(&mut regs, true);
    let mut mac = Dwmac::new(regs.mmio(), &mut dma, MAC, &c).unwrap();
    transmit_one(&mut mac, 60, 0xab);
    let w = mac.tx_words(0);
    assert_eq!(w[0], OWN);
    assert_eq!(w[1], (1 << 30) | (1 << 29) | 60, "normal: FS, LS, TBS1 in TDES1");
    assert_eq!(mac.tx.buf[0].0[..60], [0xab; 60]);
    assert_eq!(w[2], &mac.tx.buf[0] as *const Buffer as usize as u32);
    // The ring is full once every descriptor is owned by the DMA.
    for i in 1..TX_RING {
        transmit_one(&mut mac, 100, i as u8);
    }
    assert!(mac.transmit(Instant::ZERO).is_none(), "all descriptors owned by the DMA");
    assert_eq!(mac.tx_words(TX_RING - 1)[1] & (1 << 25), 1 << 25, "TER on the last");
    mac.dma_transmitted(0);
    transmit_one(&mut mac, 42, 7);
    assert_eq!(mac.tx_words(0)[1] & 0x7ff, 42, "wrapped to descriptor 0");
    assert_eq!(mac.stats().tx_frames, TX_RING as u32 + 1);
}

#[test]
fn transmit_uses_enhanced_descriptors_when_bit_24_is_set() {
    let mut regs = Regs::new(QEMU_HW_FEATURE | (1 << 24));
    let mut dma = Box::new(DmaArea::new());
    let c = clock(&mut regs, true);
    let mut mac = Dwmac::new(regs.mmio(), &mut dma, MAC, &c).unwrap();
    assert_eq!(mac.format(), DescFormat::Enhanced);
    assert_eq!(mac.rx_words(RX_RING - 1)[1], (1 << 15) | BUFFER_SIZE as u32, "enhanced RER 15");
    transmit_one(&mut mac, 1514, 1);
    let w = mac.tx_words(0);
    assert_eq!(w[0], OWN | (1 << 29) | (1 << 28), "enhanced: OWN, LS, FS in TDES0");
    assert_eq!(w[1], 1514, "enhanced: TBS1 in TDES1");
}

#[test]
fn receive_hands_over_good_frames_and_returns_descriptors() {
    let mut regs = Regs::new(QEMU_HW_FEATURE);
    let mut dma = Box::new(DmaArea::new());
    let c = clock(&mut regs, true);
    let mut mac = Dwmac::new(regs.mmio(), &mut dma, MAC, &c).unwrap();
    assert!(mac.receive(Instant::ZERO).is_none(), "nothing yet");

    let frame: Vec<u8> = (0..60u8).collect();
    // QEMU's race: OWN clear and FS, but no LS yet: not ready.
    mac.dma_receive(0, &frame, desc::RDES0_FS);
    assert!(mac.receive(Instant::ZERO).is_none());
    mac.dma_receive(0, &frame, FS_LS);
    let (rx, _tx) = mac.receive(Instant::ZERO).expect("a frame");
    let got = rx.consume(|b| b.to_vec());
    assert_eq!(got, frame, "FCS stripped");
    assert_eq!(mac.rx_words(0)[0], OWN, "descriptor returned");

    // A bad frame is dropped; the good one after it is delivered.
    mac.dma_receive(1, &frame, FS_LS | desc::RDES0_ES);
    mac.dma_receive(2, &frame[..20], FS_LS);
    let (rx, _tx) = mac.receive(Instant::ZERO).expect("the good frame");
    assert_eq!(rx.consume(|b| b.len()), 20);
    assert_eq!(mac.stats(), Stats { rx_frames: 2, rx_dropped: 1, tx_frames: 0 });

    // A frame split over descriptors 3 and 4 is dropped once the DMA moved on.
    mac.dma_receive(3, &frame, desc::RDES0_FS);
    mac.dma_receive(4, &frame, desc::RDES0_LS);
    assert!(mac.receive(Instant::ZERO).is_none());
    assert_eq!(mac.stats().rx_dropped, 3);
    assert_eq!(mac.rx_words(3)[0], OWN);
    assert_eq!(mac.rx_words(4)[0], OWN);
}

#[test]
fn receive_waits_while_transmit_is_full() {
    let mut regs = Regs::new(QEMU_HW_FEATURE);
    let mut dma = Box::new(DmaArea::new());
    let c = clock(&mut regs, true);
    let mut mac = Dwmac::new(regs.mmio(), &mut dma, MAC, &c).unwrap();
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
    let mut regs = Regs::new(QEMU_HW_FEATURE);
    let mut dma = Box::new(DmaArea::new());
    let c = clock(&mut regs, true);
    let status = &mut regs.0[DMA_STATUS / 4] as *mut u32;
    let mut mac = Dwmac::new(regs.mmio(), &mut dma, MAC, &c).unwrap();
    // SAFETY: points into the live fake register block.
    unsafe { *status = STATUS_RU };
    mac.dma_receive(0, &[1; 60], FS_LS);
    let (rx, _) = mac.receive(Instant::ZERO).unwrap();
    rx.consume(|_| ());
    // Write-1-to-clear: the fake memory holds the written value (RU).
    // SAFETY: as above.
    assert_eq!(unsafe { *status }, STATUS_RU, "RU written back to clear it");
}
