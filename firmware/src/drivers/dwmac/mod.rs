//! Polling driver for the Synopsys DesignWare GMAC (DWC Ethernet MAC 3.x):
//! the Cyclone V HPS EMACs and QEMU's `npcm-gmac`.
//!
//! * One receive and one transmit ring in ring mode, one buffer of
//!   [`BUFFER_SIZE`] bytes per descriptor, one frame per descriptor.
//! * The descriptor format (normal or enhanced) comes from the HW feature
//!   register at start-up ([`desc::DescFormat::from_hw_feature`]).
//! * No interrupts: smoltcp's poll loop calls [`smoltcp::phy::Device`].
//! * The rings and buffers live in a [`DmaArea`] the caller places in memory
//!   the CPU does not cache (the binary maps it non-cacheable), so only
//!   barriers are needed around ownership hand-overs.
//! * MDIO is exposed as [`phy::Mdio`](super::phy::Mdio) through [`Dwmac::mdio`].

pub mod desc;
mod device;
pub mod regs;

use core::fmt;

pub use device::{DwmacRxToken, DwmacTxToken};

use self::desc::{DescFormat, OWN};
use self::regs::*;
use super::clock::{wait_for, Clock};
use super::mmio::Mmio;
use super::phy::{Link, Mdio, MdioTimeout, Speed};
use crate::arch::dsb;

/// Receive descriptors.
pub const RX_RING: usize = 64;
/// Transmit descriptors.
pub const TX_RING: usize = 32;
/// Bytes per buffer: a whole Ethernet frame (1514) plus FCS, rounded up to
/// a multiple of the bus width; fits both formats' buffer-1 size fields.
pub const BUFFER_SIZE: usize = 1536;
/// Largest frame handed to smoltcp (MTU 1500 + 14-byte Ethernet header).
pub const MAX_FRAME: usize = 1514;

const _: () = assert!(BUFFER_SIZE <= DescFormat::Normal.max_buffer());
const _: () = assert!(BUFFER_SIZE % 8 == 0);

/// One 4-word DMA descriptor (bus mode ATDS off: 16 bytes, contiguous).
#[repr(C, align(16))]
pub struct Descriptor {
    words: [u32; 4],
}

impl Descriptor {
    /// A zeroed descriptor.
    pub const ZERO: Descriptor = Descriptor { words: [0; 4] };

    #[inline]
    fn read(&self, i: usize) -> u32 {
        // SAFETY: `i < 4` at every call site; the word is plain memory the
        // DMA may also write, hence the volatile access.
        unsafe { core::ptr::read_volatile(&self.words[i]) }
    }

    #[inline]
    fn write(&mut self, i: usize, v: u32) {
        // SAFETY: as in `read`.
        unsafe { core::ptr::write_volatile(&mut self.words[i], v) }
    }

    /// The four words, read once each (for diagnostics and tests).
    pub fn words(&self) -> [u32; 4] {
        [self.read(0), self.read(1), self.read(2), self.read(3)]
    }
}

/// One frame buffer.
#[repr(C, align(32))]
pub struct Buffer(pub [u8; BUFFER_SIZE]);

/// Everything the MAC's DMA reads or writes: both descriptor rings and all
/// buffers. Place it in memory mapped non-cacheable.
#[repr(C, align(64))]
pub struct DmaArea {
    rx_desc: [Descriptor; RX_RING],
    tx_desc: [Descriptor; TX_RING],
    rx_buf: [Buffer; RX_RING],
    tx_buf: [Buffer; TX_RING],
}

impl DmaArea {
    /// A zeroed area (for a `static` or a host test).
    pub const fn new() -> DmaArea {
        DmaArea {
            rx_desc: [Descriptor::ZERO; RX_RING],
            tx_desc: [Descriptor::ZERO; TX_RING],
            rx_buf: [const { Buffer([0; BUFFER_SIZE]) }; RX_RING],
            tx_buf: [const { Buffer([0; BUFFER_SIZE]) }; TX_RING],
        }
    }
}

impl Default for DmaArea {
    fn default() -> Self {
        DmaArea::new()
    }
}

/// Bus address of `p` (the firmware runs with an identity map).
fn bus_addr<T>(p: &T) -> u32 {
    p as *const T as usize as u32
}

/// Driver errors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Error {
    /// The DMA software reset did not finish (on the board it needs the
    /// PHY's RX clock).
    ResetTimeout,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::ResetTimeout => f.write_str("DMA software reset did not complete (no PHY RX clock?)"),
        }
    }
}

/// Frame counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Good frames handed to the stack.
    pub rx_frames: u32,
    /// Frames dropped: error bit, split over descriptors, or too long.
    pub rx_dropped: u32,
    /// Frames handed to the DMA.
    pub tx_frames: u32,
}

struct RxRing<'a> {
    desc: &'a mut [Descriptor; RX_RING],
    buf: &'a mut [Buffer; RX_RING],
    next: usize,
    frames: u32,
    dropped: u32,
}

struct TxRing<'a> {
    desc: &'a mut [Descriptor; TX_RING],
    buf: &'a mut [Buffer; TX_RING],
    next: usize,
    frames: u32,
}

/// The MAC with its rings.
pub struct Dwmac<'a> {
    regs: Mmio,
    format: DescFormat,
    rx: RxRing<'a>,
    tx: TxRing<'a>,
}

/// How long the DMA software reset may take.
pub const RESET_TIMEOUT_US: u64 = 100_000;

impl<'a> Dwmac<'a> {
    /// Bring the MAC up to the point where only the link is missing
    /// (PLATFORM.md "Minimal MAC bring-up" steps 2-6): reset the DMA, set
    /// the burst length and the MAC address, build both rings, start both
    /// DMA engines. The transmitter and receiver stay off until
    /// [`Dwmac::set_link`].
    pub fn new(regs: Mmio, dma: &'a mut DmaArea, mac: [u8; 6], clock: &impl Clock) -> Result<Dwmac<'a>, Error> {
        let format = DescFormat::from_hw_feature(regs.read(DMA_HW_FEATURE));

        regs.modify(DMA_BUS_MODE, |v| v | BUS_MODE_SWR);
        wait_for(clock, RESET_TIMEOUT_US, || (regs.read(DMA_BUS_MODE) & BUS_MODE_SWR == 0).then_some(()))
            .ok_or(Error::ResetTimeout)?;
        regs.write(DMA_BUS_MODE, BUS_MODE_PBL << BUS_MODE_PBL_SHIFT);

        let (hi, lo) = mac_address_regs(mac);
        regs.write(MAC_ADDR0_HI, hi);
        regs.write(MAC_ADDR0_LO, lo);

        let DmaArea { rx_desc, tx_desc, rx_buf, tx_buf } = dma;
        for (i, (d, b)) in rx_desc.iter_mut().zip(rx_buf.iter()).enumerate() {
            d.write(1, desc::rx_control(format, BUFFER_SIZE, i == RX_RING - 1));
            d.write(2, bus_addr(b));
            d.write(3, 0);
            d.write(0, OWN);
        }
        for d in tx_desc.iter_mut() {
            d.words = [0; 4];
        }
        dsb();
        regs.write(DMA_RX_BASE, bus_addr(&rx_desc[0]));
        regs.write(DMA_TX_BASE, bus_addr(&tx_desc[0]));
        regs.write(DMA_INT_ENABLE, 0);
        regs.write(DMA_STATUS, STATUS_W1C);

        // Flush the TX FIFO; QEMU keeps the bit set, the board clears it:
        // wait briefly, then go on either way.
        regs.write(DMA_OP_MODE, OP_MODE_FTF);
        let _ = wait_for(clock, 1_000, || (regs.read(DMA_OP_MODE) & OP_MODE_FTF == 0).then_some(()));
        regs.write(DMA_OP_MODE, OP_MODE_TSF | OP_MODE_RSF | OP_MODE_SR | OP_MODE_ST);

        Ok(Dwmac {
            regs,
            format,
            rx: RxRing { desc: rx_desc, buf: rx_buf, next: 0, frames: 0, dropped: 0 },
            tx: TxRing { desc: tx_desc, buf: tx_buf, next: 0, frames: 0 },
        })
    }

    /// The descriptor format in use.
    pub fn format(&self) -> DescFormat {
        self.format
    }

    /// The Synopsys version register.
    pub fn version(&self) -> u32 {
        self.regs.read(VERSION)
    }

    /// Frame counters.
    pub fn stats(&self) -> Stats {
        Stats { rx_frames: self.rx.frames, rx_dropped: self.rx.dropped, tx_frames: self.tx.frames }
    }

    /// Configure the MAC for the negotiated `link` and turn the transmitter
    /// and receiver on, frame filter 0 (own address and broadcast)
    /// (PLATFORM.md step 8).
    pub fn set_link(&mut self, link: Link) {
        self.regs.write(MAC_FRAME_FILTER, 0);
        self.regs.write(MAC_CONFIG, mac_config(link));
    }

    /// The MDIO bus of this MAC, with `clock` for its time-outs.
    pub fn mdio<'c, C: Clock>(&self, clock: &'c C) -> DwmacMdio<'c, C> {
        DwmacMdio { regs: self.regs, clock }
    }
}

/// MAC configuration register value for `link`: TE, RE, duplex, port
/// select (PS = 0 for 1000 Mbit/s, PS = 1 for 10/100, FES for 100).
pub const fn mac_config(link: Link) -> u32 {
    let mut v = MAC_CONFIG_TE | MAC_CONFIG_RE;
    if link.full_duplex {
        v |= MAC_CONFIG_DM;
    }
    match link.speed {
        Speed::M1000 => {}
        Speed::M100 => v |= MAC_CONFIG_PS | MAC_CONFIG_FES,
        Speed::M10 => v |= MAC_CONFIG_PS,
    }
    v
}

/// The MAC's MDIO bus (GMII address/data registers).
pub struct DwmacMdio<'c, C> {
    regs: Mmio,
    clock: &'c C,
}

/// How long one MDIO transaction may take (about 64 bits at 2.5 MHz is
/// 26 us).
pub const MDIO_TIMEOUT_US: u64 = 10_000;

impl<C: Clock> DwmacMdio<'_, C> {
    fn wait_idle(&self) -> Result<(), MdioTimeout> {
        wait_for(self.clock, MDIO_TIMEOUT_US, || (self.regs.read(GMII_ADDR) & GMII_BUSY == 0).then_some(()))
            .ok_or(MdioTimeout)
    }
}

impl<C: Clock> Mdio for DwmacMdio<'_, C> {
    fn read(&mut self, phy: u8, reg: u8) -> Result<u16, MdioTimeout> {
        self.wait_idle()?;
        self.regs.write(GMII_ADDR, gmii_addr(phy, reg, false));
        self.wait_idle()?;
        Ok(self.regs.read(GMII_DATA) as u16)
    }

    fn write(&mut self, phy: u8, reg: u8, value: u16) -> Result<(), MdioTimeout> {
        self.wait_idle()?;
        self.regs.write(GMII_DATA, u32::from(value));
        self.regs.write(GMII_ADDR, gmii_addr(phy, reg, true));
        self.wait_idle()
    }
}

#[cfg(test)]
mod tests;
