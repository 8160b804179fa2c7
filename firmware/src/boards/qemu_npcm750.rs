//! QEMU 10's `npcm750-evb` (Nuvoton NPCM750, 2x Cortex-A9): the emulated
//! board of the tests. Every constant: `shared/PLATFORM.md`, table "Two
//! targets, one firmware", column "QEMU npcm750-evb", unless noted.

use core::fmt::Write;

use firmware::drivers::global_timer::GlobalTimer;
use firmware::drivers::phy::PhyConfig;

use crate::render::Renderer;

/// Printed at start-up.
pub const NAME: &str = "qemu-npcm750 (QEMU npcm750-evb)";
/// UART0: 16550, 32-bit registers at a stride of 4, no baud set-up needed.
pub const UART0_BASE: usize = 0xf000_1000;
/// MPCore PERIPHBASE (QEMU's CBAR reads 0xf03f_e100: masked 0xffff_e000).
pub const PERIPHBASE: usize = 0xf03f_e000;
/// Global timer rate: QEMU's A9 global timer ticks every 10 ns at
/// prescaler 0 (PLATFORM.md: 100 MHz).
pub const GLOBAL_TIMER_HZ: u32 = 100_000_000;
/// L2C-310.
pub const L2C_BASE: usize = 0xf03f_c000;
/// gmac0, the first `-nic ...,model=npcm-gmac`.
pub const EMAC_BASE: usize = 0xf080_2000;
/// DRAM (QEMU's default `-m` for this machine: 512 MiB).
pub const DRAM_MIB: u32 = 512;
/// QEMU's conventional NIC address 52:54:00:12:34:56 (slirp does not care).
pub const MAC_ADDR: [u8; 6] = [0x52, 0x54, 0x00, 0x12, 0x34, 0x56];
/// Slirp's default guest address (QEMU docs, "Network emulation", user
/// networking: guest 10.0.2.15, gateway 10.0.2.2).
pub const DEFAULT_IPV4: &str = "10.0.2.15/24";
/// Slirp's gateway.
pub const DEFAULT_GATEWAY: &str = "10.0.2.2";
/// QEMU's PHY (address 0, ID 0x0362/0x5e6a) needs no skews.
pub const PHY: PhyConfig = PhyConfig { ksz9021_skews: None, ksz9021_force_master: false };
/// QEMU's link is up at once; a short wait is plenty.
pub const LINK_TIMEOUT_US: u64 = 1_000_000;

/// Nothing to set up: QEMU's MAC comes out of reset ready.
pub fn init(_log: &mut impl Write) {}

/// The software renderer (the emulated board has no FPGA).
pub fn renderer(log: &mut impl Write, _timer: &'static GlobalTimer) -> Renderer {
    let _ = writeln!(log, "renderer: software (model on the A9)");
    Renderer::software()
}
