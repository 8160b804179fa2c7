//! The two boards. Exactly one is built in, chosen by cargo feature, as
//! [`Active`]; what every board must provide is the [`Board`] trait, so the
//! compiler checks both (`cargo xtask test` builds both).

use core::fmt::Write;
use core::ops::Range;

use dwmac::phy::PhyConfig;
use hal_avalon::RegisterPort;
use soc::global_timer::GlobalTimer;
use soc::mmu::PagedSection;

use crate::cpu::Caches;
use crate::render::Frames;

#[cfg(all(feature = "qemu-npcm750", feature = "de1-soc"))]
compile_error!("select exactly one board feature: qemu-npcm750 or de1-soc");
#[cfg(not(any(feature = "qemu-npcm750", feature = "de1-soc")))]
compile_error!("select a board: --features qemu-npcm750 or --features de1-soc");

#[cfg(feature = "de1-soc")]
mod de1_soc;
#[cfg(feature = "qemu-npcm750")]
mod qemu_npcm750;

/// The board this build runs on.
#[cfg(feature = "de1-soc")]
pub type Active = de1_soc::De1Soc;
/// The board this build runs on.
#[cfg(all(feature = "qemu-npcm750", not(feature = "de1-soc")))]
pub type Active = qemu_npcm750::QemuNpcm750;

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
    /// How the accelerator's registers are reached.
    type Port: RegisterPort;

    /// The frames: the FPGA accelerator's if one answers and passes the
    /// boot self-test (`crate::selftest`; frame mode when its register map
    /// has the frame DMA, else row mode), else the software renderer's.
    /// `caches` maintains the frame ring.
    fn renderer(log: &mut impl Write, timer: &'static GlobalTimer, caches: Caches) -> Frames<Self::Port>;
}
