//! The MAC: bring-up in the order the hardware needs, link configuration,
//! the MDIO bus, statistics.
//!
//! Bring-up (docs/platform.md#mac-bring-up; Linux `stmmac_hw_setup`, U-Boot
//! `designware.c` `_dw_eth_init`):
//!
//! 1. Find the PHY on MDIO and reset and configure it. MDIO works before the
//!    DMA reset; the PHY must be out of reset and driving its RX clock
//!    before the next step can finish.
//! 2. DMA software reset. On the Cyclone V it completes only with the PHY's
//!    RX clock running (Cyclone V TRM, EMAC "Initialization"), so a time-out
//!    resets the PHY once more and retries, a bounded number of times.
//! 3. Burst length, MAC address, both rings, DMA on. The transmitter and
//!    receiver stay off until [`Dwmac::set_link`] reports a link, which the
//!    main loop does whenever the [`LinkMonitor`](crate::phy::LinkMonitor)
//!    sees one: no waiting for a cable here.

use core::fmt;

use arbitrary_int::u6;
use embedded_hal::delay::DelayNs;

use crate::desc::{self, ChecksumInsertion, DescFormat, OWN};
use crate::filter::MulticastFilter;
use crate::phy::{self, Link, Mdio, MdioTimeout, PhyConfig, PhyError, PhyId, Speed};
use crate::regs::{gmii_access, BusMode, DmaStatus, MacConfig, OpMode, Regs};
use crate::ring::{DmaArea, BUFFER_SIZE, RX_RING, TX_RING};
use crate::sync::DmaSync;
use crate::wait::{wait_for, Timeout};

/// Largest frame handed to smoltcp (MTU 1500 + 14-byte Ethernet header).
pub const MAX_FRAME: usize = 1514;

/// Programmable burst length, in beats: 8 (U-Boot `designware.c` uses 8;
/// Linux stmmac's default is 8 too).
pub const BURST_LENGTH: u6 = u6::new(8);

/// How long the DMA software reset may take each attempt.
pub const RESET_TIMEOUT: Timeout = Timeout::new(100_000, 10);

/// PHY-reset-then-DMA-reset attempts before the bring-up gives up.
pub const RESET_ATTEMPTS: u8 = 3;

/// How long one MDIO transaction may take (64 bits at 2.5 MHz is 26 us).
pub const MDIO_TIMEOUT: Timeout = Timeout::new(10_000, 1);

/// How long a TX FIFO flush may take; QEMU never clears the bit, the
/// board does at once.
const FLUSH_TIMEOUT: Timeout = Timeout::new(1_000, 10);

/// Bring-up failures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Error {
    /// The DMA software reset did not finish in any attempt, each after a
    /// fresh PHY reset (no RX clock from the PHY?).
    ResetTimeout {
        /// Attempts made.
        attempts: u8,
    },
    /// The PHY could not be found or set up.
    Phy(PhyError),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::ResetTimeout { attempts } => {
                write!(f, "DMA software reset did not complete in {attempts} attempts (no RX clock from the PHY?)")
            }
            Error::Phy(e) => write!(f, "PHY: {e}"),
        }
    }
}

impl core::error::Error for Error {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            Error::Phy(e) => Some(e),
            Error::ResetTimeout { .. } => None,
        }
    }
}

impl From<PhyError> for Error {
    fn from(e: PhyError) -> Error {
        Error::Phy(e)
    }
}

/// The DMA software reset timed out (one attempt).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ResetTimeout;

/// Frame counters. They wrap (compare them by difference): the 64-bit
/// byte counts never do in practice, and a wrapping add is two
/// instructions on the per-packet path where a saturating one is eight.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Good frames handed to the stack.
    pub rx_frames: u32,
    /// Bytes of those frames (the stack reads them from the uncached ring).
    pub rx_bytes: u64,
    /// Frames dropped: error bit, split over descriptors, or too long.
    pub rx_dropped: u32,
    /// Frames handed to the DMA.
    pub tx_frames: u32,
    /// Bytes of those frames (headers included).
    pub tx_bytes: u64,
    /// Times smoltcp asked for a TX token while every descriptor was the
    /// MAC's (the stack keeps the segment and retries; nothing is dropped).
    pub tx_ring_full: u32,
    /// Split frames ([`Dwmac::send_split`]) handed to the DMA; also counted
    /// in `tx_frames` and `tx_bytes`.
    pub tx_split: u32,
    /// Times [`Dwmac::send_split`] found every descriptor the MAC's.
    pub tx_split_full: u32,
    /// Payload bytes of the split frames: sent from the caller's memory,
    /// never written by the CPU into a DMA buffer (within `tx_bytes`).
    pub tx_split_payload_bytes: u64,
}

/// The parts of the driver both tokens of a receive need.
pub(crate) struct Shared<'a, S> {
    pub(crate) regs: Regs,
    pub(crate) area: &'a DmaArea,
    pub(crate) sync: S,
    pub(crate) format: DescFormat,
    pub(crate) csum: ChecksumInsertion,
}

impl<S: DmaSync> Shared<'_, S> {
    /// After a descriptor word with OWN set: make it visible to the DMA
    /// before the poll demand that follows (docs in [`crate::sync`]).
    #[inline]
    pub(crate) fn publish(&self) {
        self.sync.dsb();
        self.sync.outer_sync();
        self.sync.dsb();
    }
}

/// Receive ring position and counters.
#[derive(Default)]
pub(crate) struct RxState {
    pub(crate) next: usize,
    pub(crate) frames: u32,
    pub(crate) bytes: u64,
    pub(crate) dropped: u32,
}

/// Transmit ring position, what the DMA still owns, and counters.
///
/// Descriptors `dirty`, `dirty + 1`, ... (`pending` of them, modulo the
/// ring) were handed to the DMA and not yet seen back; the DMA works
/// through a ring in order, so they come back in that order too.
pub(crate) struct TxState {
    /// Next descriptor to fill.
    pub(crate) next: usize,
    /// Oldest descriptor handed over and not yet seen back.
    pub(crate) dirty: usize,
    /// Descriptors handed over and not yet seen back (0..=TX_RING).
    pub(crate) pending: usize,
    /// Which pending descriptors carry a split frame.
    pub(crate) split: [bool; TX_RING],
    /// Split frames handed over since the driver was created.
    pub(crate) split_sent: u64,
    /// Split frames seen back (always the oldest: in order).
    pub(crate) split_done: u64,
    pub(crate) frames: u32,
    pub(crate) bytes: u64,
    pub(crate) ring_full: u32,
    pub(crate) split_frames: u32,
    pub(crate) split_full: u32,
    pub(crate) split_payload_bytes: u64,
}

impl TxState {
    pub(crate) const fn new() -> TxState {
        TxState {
            next: 0,
            dirty: 0,
            pending: 0,
            split: [false; TX_RING],
            split_sent: 0,
            split_done: 0,
            frames: 0,
            bytes: 0,
            ring_full: 0,
            split_frames: 0,
            split_full: 0,
            split_payload_bytes: 0,
        }
    }

    /// A fresh ring after a restart: counters zero, but split sequence
    /// numbers go on, and every frame in flight counts as done (the DMA
    /// was reset and reads none of them any more).
    pub(crate) const fn restarted(&self) -> TxState {
        let mut t = TxState::new();
        t.split_sent = self.split_sent;
        t.split_done = self.split_sent;
        t
    }
}

/// The MAC with its rings, barriers `S` and delay `D`.
pub struct Dwmac<'a, S, D> {
    pub(crate) shared: Shared<'a, S>,
    pub(crate) rx: RxState,
    pub(crate) tx: TxState,
    delay: D,
    /// The multicast frames the filter passes (written again on every
    /// link change, and by [`set_multicast`](Self::set_multicast)).
    multicast: MulticastFilter,
}

impl<'a, S: DmaSync, D: DelayNs> Dwmac<'a, S, D> {
    /// Take the MAC over. Reads only the HW feature register (descriptor
    /// format, checksum offload); nothing changes until
    /// [`bring_up`](Self::bring_up).
    pub fn new(regs: Regs, area: &'a DmaArea, sync: S, delay: D) -> Dwmac<'a, S, D> {
        let hw = regs.dma().hw_feature.read();
        let csum = if hw.txcoesel() { ChecksumInsertion::Full } else { ChecksumInsertion::Off };
        Dwmac {
            shared: Shared { regs, area, sync, format: DescFormat::from_hw_feature(hw), csum },
            rx: RxState::default(),
            tx: TxState::new(),
            delay,
            multicast: MulticastFilter::new(),
        }
    }

    /// Bring the MAC up to the point where only the link is missing: find
    /// and configure the PHY, reset the DMA (PHY first, with retries), then
    /// program address and rings and start both DMA engines. Returns the
    /// PHY for the [`LinkMonitor`](crate::phy::LinkMonitor).
    pub fn bring_up(&mut self, mac: [u8; 6], phy_config: &PhyConfig) -> Result<PhyId, Error> {
        let phy = phy::scan(self)?;
        reset_phy_then_dma(self, phy, phy_config)?;
        self.start(mac);
        Ok(phy)
    }

    /// Steps 3-6 after a completed DMA reset: burst length, MAC address,
    /// rings, interrupts off, status cleared, store-and-forward, DMA on.
    pub(crate) fn start(&mut self, mac: [u8; 6]) {
        let Shared { regs, area, format, .. } = &self.shared;
        regs.set_bus_mode(BusMode::DEFAULT.with_pbl(BURST_LENGTH));
        regs.set_address(mac);
        for i in 0..RX_RING {
            let d = area.rx_descriptor(i);
            d.set_word(1, desc::rx_control(*format, BUFFER_SIZE, i == RX_RING - 1));
            d.set_word(2, area.rx_buffer(i).bus_address());
            d.set_word(3, 0);
            d.set_word(0, OWN);
        }
        for i in 0..TX_RING {
            let d = area.tx_descriptor(i);
            for w in 0..4 {
                d.set_word(w, 0);
            }
        }
        self.rx = RxState::default();
        self.tx = self.tx.restarted();
        self.shared.publish();
        let (regs, area) = (&self.shared.regs, self.shared.area);
        regs.set_descriptor_lists(bus_address(area.rx_descriptor(0)), bus_address(area.tx_descriptor(0)));
        regs.disable_interrupts();
        regs.clear_status(DmaStatus::ALL_W1C);
        // Flush the TX FIFO; the board clears the bit, QEMU keeps it set:
        // wait briefly, then go on either way.
        regs.set_op_mode(OpMode::DEFAULT.with_ftf(true));
        let _ = wait_for(&mut self.delay, FLUSH_TIMEOUT, || (!regs.dma().op_mode.read().ftf()).then_some(()));
        // Store and forward both ways: checksum insertion needs it on TX.
        regs.set_op_mode(OpMode::DEFAULT.with_tsf(true).with_rsf(true).with_sr(true).with_st(true));
    }

    /// Let the multicast frames `filter` names through the MAC's frame
    /// filter, and no others ([`crate::filter`]): the hash table first,
    /// then the filter register that turns it on.
    pub fn set_multicast(&mut self, filter: MulticastFilter) {
        self.multicast = filter;
        let regs = &self.shared.regs;
        regs.set_hash_table(filter.bins());
        regs.set_frame_filter(filter.frame_filter());
    }

    /// The multicast frames the filter passes.
    pub fn multicast(&self) -> MulticastFilter {
        self.multicast
    }

    /// Configure the MAC for `link` (speed, duplex; the frame filter: own
    /// address, broadcast and the multicast groups of
    /// [`set_multicast`](Self::set_multicast)) with transmitter and receiver on, or turn
    /// both off while there is no link, as Linux's `stmmac_mac_link_up` /
    /// `stmmac_mac_link_down` do.
    ///
    /// With the receiver on, receive resumes as after a descriptor
    /// shortage (RU cleared, poll demand; see `RxState::recycle`). On the
    /// board that changes nothing: a poll demand only wakes a receive DMA
    /// suspended for want of descriptors (Cyclone V HPS register map, EMAC
    /// `Receive_Poll_Demand`), and RU is write-one-to-clear. QEMU's model
    /// (hw/net/npcm_gmac.c, up to 10.0.2) refuses frames while the receiver
    /// is off and keeps them queued, its `-nic dgram` backend reading no
    /// more until the model flushes; only a write that starts receive or
    /// clears RU does, so without this one frame that came before the link
    /// left the emulated board deaf (`cargo xtask qemu-test`, "frames while
    /// the link comes up").
    pub fn set_link(&mut self, link: Option<Link>) {
        let regs = &self.shared.regs;
        regs.set_hash_table(self.multicast.bins());
        regs.set_frame_filter(self.multicast.frame_filter());
        regs.set_config(mac_config(link));
        if link.is_some() {
            regs.clear_status(DmaStatus::DEFAULT.with_ru(true));
            regs.rx_poll_demand();
        }
    }

    /// The descriptor format in use.
    pub fn format(&self) -> DescFormat {
        self.shared.format
    }

    /// Whether the MAC inserts IPv4 and TCP/UDP checksums on transmit.
    pub fn checksum_insertion(&self) -> ChecksumInsertion {
        self.shared.csum
    }

    /// The Synopsys version register.
    pub fn version(&self) -> u32 {
        self.shared.regs.mac().version.read()
    }

    /// Whether the DMA has handed the next receive descriptor back (OWN
    /// clear): a frame waits for [`smoltcp`]'s next poll. One descriptor
    /// word read, so a busy sender can ask between packets and let the
    /// stack in as soon as something arrives.
    pub fn rx_waiting(&self) -> bool {
        self.shared.area.rx_descriptor(self.rx.next).word(0) & OWN == 0
    }

    /// Descriptors the CPU could fill now (transmit, OWN clear) and
    /// descriptors waiting for the DMA to receive into (OWN set): when idle,
    /// all of both rings, or something leaked.
    pub fn free_descriptors(&self) -> (usize, usize) {
        let tx = (0..TX_RING).filter(|i| self.shared.area.tx_descriptor(*i).word(0) & OWN == 0).count();
        let rx = (0..RX_RING).filter(|i| self.shared.area.rx_descriptor(*i).word(0) & OWN != 0).count();
        (tx, rx)
    }

    /// Frame counters.
    pub fn stats(&self) -> Stats {
        Stats {
            rx_frames: self.rx.frames,
            rx_bytes: self.rx.bytes,
            rx_dropped: self.rx.dropped,
            tx_frames: self.tx.frames,
            tx_bytes: self.tx.bytes,
            tx_ring_full: self.tx.ring_full,
            tx_split: self.tx.split_frames,
            tx_split_full: self.tx.split_full,
            tx_split_payload_bytes: self.tx.split_payload_bytes,
        }
    }

    fn mdio_wait_idle(&mut self) -> Result<(), MdioTimeout> {
        let regs = &self.shared.regs;
        wait_for(&mut self.delay, MDIO_TIMEOUT, || (!regs.mac().gmii_address.read().gb()).then_some(()))
            .ok_or(MdioTimeout)
    }
}

/// The two resets of the bring-up with the MDIO bus between them, so that
/// their order can be tested without a MAC.
pub trait Resets: Mdio {
    /// One DMA software reset, bounded by [`RESET_TIMEOUT`].
    fn reset_dma(&mut self) -> Result<(), ResetTimeout>;
}

/// Reset and configure the PHY, then reset the DMA; retry both up to
/// [`RESET_ATTEMPTS`] times while the DMA reset times out.
pub fn reset_phy_then_dma(bus: &mut impl Resets, phy: PhyId, cfg: &PhyConfig) -> Result<(), Error> {
    for _ in 0..RESET_ATTEMPTS {
        phy::configure(bus, phy, cfg)?;
        if bus.reset_dma().is_ok() {
            return Ok(());
        }
    }
    Err(Error::ResetTimeout { attempts: RESET_ATTEMPTS })
}

impl<S: DmaSync, D: DelayNs> Resets for Dwmac<'_, S, D> {
    fn reset_dma(&mut self) -> Result<(), ResetTimeout> {
        let regs = &self.shared.regs;
        regs.set_bus_mode(regs.dma().bus_mode.read().with_swr(true));
        wait_for(&mut self.delay, RESET_TIMEOUT, || (!regs.dma().bus_mode.read().swr()).then_some(()))
            .ok_or(ResetTimeout)
    }
}

impl<S, D: DelayNs> DelayNs for Dwmac<'_, S, D> {
    fn delay_ns(&mut self, ns: u32) {
        self.delay.delay_ns(ns)
    }
}

impl<S: DmaSync, D: DelayNs> Mdio for Dwmac<'_, S, D> {
    fn read(&mut self, phy: u8, reg: u8) -> Result<u16, MdioTimeout> {
        self.mdio_wait_idle()?;
        self.shared.regs.start_mdio(gmii_access(phy, reg, false), None);
        self.mdio_wait_idle()?;
        Ok(self.shared.regs.mac().gmii_data.read() as u16)
    }

    fn write(&mut self, phy: u8, reg: u8, value: u16) -> Result<(), MdioTimeout> {
        self.mdio_wait_idle()?;
        self.shared.regs.start_mdio(gmii_access(phy, reg, true), Some(value));
        self.mdio_wait_idle()
    }
}

/// MAC configuration for `link`: TE, RE, duplex, port select (PS = 0 for
/// 1000 Mbit/s, PS = 1 for 10/100, FES for 100); all off without a link.
pub fn mac_config(link: Option<Link>) -> MacConfig {
    let Some(link) = link else {
        return MacConfig::DEFAULT;
    };
    let c = MacConfig::DEFAULT.with_te(true).with_re(true).with_dm(link.full_duplex);
    match link.speed {
        Speed::M1000 => c,
        Speed::M100 => c.with_ps(true).with_fes(true),
        Speed::M10 => c.with_ps(true),
    }
}

/// Bus address of `p` (the firmware runs with an identity map).
pub(crate) fn bus_address<T>(p: &T) -> u32 {
    p as *const T as usize as u32
}
