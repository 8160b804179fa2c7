//! What every board provides: addresses, network defaults and its set-up
//! steps ([`Board`]). The bottom of the binary's layers: it imports nothing
//! of the binary, and the modules below the boards (`cpu`, `net`, `render`,
//! ...) take a `B: Board` instead of naming a board; the boards
//! (`crate::boards`) build on them.

use core::fmt::Write;
use core::ops::Range;

use dwmac::phy::PhyConfig;
use soc::mmu::PagedSection;

/// What a board provides: addresses, network defaults and its set-up steps.
pub trait Board {
    /// Printed at start-up.
    const NAME: &'static str;
    /// The log UART (16550, 32-bit registers at a stride of 4).
    const UART0: usize;
    /// The Cortex-A9 MPCore private region (global timer at +0x200).
    const PERIPHBASE: usize;
    /// The global timer's rate until [`Board::timer_hz`] has measured it.
    const TIMER_HZ: u32;
    /// The L2C-310.
    const L2C: usize;
    /// The DesignWare MAC used.
    const EMAC: usize;
    /// DRAM from address 0, in MiB.
    const DRAM_MIB: u32;
    /// Sections (MiB indexes) mapped Strongly-ordered: the FPGA bridge
    /// windows.
    const STRONGLY_ORDERED: &'static [Range<u32>];
    /// A section mapped page by page (the accelerator's: all
    /// Strongly-ordered until a row-mode accelerator answers the probe,
    /// then its line-buffer page Normal non-cacheable for burst reads,
    /// `cpu::retype_page`).
    const PAGED: Option<PagedSection<'static>>;
    /// The interface's Ethernet address.
    const MAC_ADDR: [u8; 6];
    /// IPv4 address with prefix length (overridable with `FW_IPV4`).
    const DEFAULT_IPV4: &'static str;
    /// Default gateway (overridable with `FW_GATEWAY`).
    const DEFAULT_GATEWAY: &'static str;
    /// PHY settings.
    const PHY: PhyConfig;

    /// The global timer's rate (PERIPHCLK), from the clocks where the board
    /// can read them.
    fn timer_hz(log: &mut impl Write) -> u32;
    /// Board set-up before the MAC: resets, watchdog, pin routing.
    fn init(log: &mut impl Write);
}
