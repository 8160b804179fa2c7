//! The boards' facts: what every board provides ([`Board`]: addresses,
//! network defaults and its set-up steps), the one built in ([`Active`]),
//! and the two pieces of hardware every module may reach (the clock,
//! [`TIMER`], and the accelerator probe's guard, [`PROBE`]). The bottom of
//! the binary's layers: it imports nothing of the binary; the modules above
//! take a `B: Board` instead of naming a board, and the boards' renderers
//! (`crate::boards`) compose them.

use core::fmt::Write;
use core::ops::Range;
use core::ptr::NonNull;

use dwmac::phy::PhyConfig;
use soc::abort::ProbeGuard;
use soc::global_timer::{GlobalTimer, PERIPHBASE_OFFSET};
use soc::mmu::PagedSection;

#[cfg(all(feature = "qemu-npcm750", feature = "de1-soc"))]
compile_error!("select exactly one board feature: qemu-npcm750 or de1-soc");
#[cfg(not(any(feature = "qemu-npcm750", feature = "de1-soc")))]
compile_error!("select a board: --features qemu-npcm750 or --features de1-soc");

#[cfg(feature = "de1-soc")]
pub mod de1_soc;
#[cfg(feature = "qemu-npcm750")]
pub mod qemu_npcm750;

#[cfg(feature = "de1-soc")]
pub use de1_soc::De1Soc;
#[cfg(feature = "qemu-npcm750")]
pub use qemu_npcm750::QemuNpcm750;

/// The board this build runs on.
#[cfg(feature = "de1-soc")]
pub type Active = De1Soc;
/// The board this build runs on.
#[cfg(all(feature = "qemu-npcm750", not(feature = "de1-soc")))]
pub type Active = QemuNpcm750;

/// The MPCore global timer: the firmware's clock (smoltcp's `Instant`).
pub static TIMER: GlobalTimer =
    // SAFETY: PERIPHBASE + 0x200 is the board's MPCore global timer (ARM DDI
    // 0407 4.3), mapped Device once the MMU is on; only this value writes it.
    unsafe { GlobalTimer::new(register_block(Active::PERIPHBASE + PERIPHBASE_OFFSET), Active::TIMER_HZ) };

/// The accelerator probe's guard, shared with the data-abort handler.
pub static PROBE: ProbeGuard = ProbeGuard::new();

/// A register block's address as the non-null pointer the handles take.
pub const fn register_block<T>(addr: usize) -> NonNull<T> {
    match NonNull::new(addr as *mut T) {
        Some(p) => p,
        None => panic!("register block at address 0"),
    }
}

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
    /// The interface's Ethernet address when the settings name none.
    const MAC_ADDR: [u8; 6];
    /// PHY settings.
    const PHY: PhyConfig;

    /// The global timer's rate (PERIPHCLK), from the clocks where the board
    /// can read them.
    fn timer_hz(log: &mut impl Write) -> u32;
    /// Board set-up before the MAC: resets, watchdog, pin routing.
    fn init(log: &mut impl Write);

    /// Light the board's own status LED (the HPS LED), or not; boards
    /// without one ignore it.
    fn status_led(_on: bool) {}
}
