//! QEMU 10's `npcm750-evb` (Nuvoton NPCM750, 2x Cortex-A9): the emulated
//! board of the tests. Addresses: QEMU `hw/arm/npcm7xx.c` (memory map and
//! device list) and docs/platform.md#two-targets.

use core::fmt::Write;
use core::ops::Range;

use dwmac::phy::PhyConfig;
use soc::mmu::PagedSection;

use super::Board;

/// QEMU's npcm750-evb.
pub enum QemuNpcm750 {}

impl Board for QemuNpcm750 {
    const NAME: &'static str = "qemu-npcm750 (QEMU npcm750-evb)";
    /// UART0: 16550, 32-bit registers at a stride of 4, no baud set-up
    /// needed (npcm7xx.c `NPCM7XX_UART0_BA`).
    const UART0: usize = 0xf000_1000;
    /// MPCore PERIPHBASE (QEMU's CBAR reads 0xf03f_e100: masked 0xffff_e000).
    const PERIPHBASE: usize = 0xf03f_e000;
    /// QEMU's A9 global timer ticks every 10 ns at prescaler 0
    /// (`hw/timer/a9gtimer.c`): 100 MHz, the one rate not read from clocks.
    const TIMER_HZ: u32 = 100_000_000;
    /// L2C-310 (npcm7xx.c `NPCM7XX_L2C_BA`).
    const L2C: usize = 0xf03f_c000;
    /// gmac0, the first `-nic ...,model=npcm-gmac` (npcm7xx.c `npcm7xx_gmac_addr`).
    const EMAC: usize = 0xf080_2000;
    /// QEMU's default `-m` for this machine: 512 MiB.
    const DRAM_MIB: u32 = 512;
    /// No FPGA.
    const STRONGLY_ORDERED: &'static [Range<u32>] = &[];
    const PAGED: Option<PagedSection<'static>> = None;
    /// QEMU's conventional NIC address 52:54:00:12:34:56 (slirp does not care).
    const MAC_ADDR: [u8; 6] = [0x52, 0x54, 0x00, 0x12, 0x34, 0x56];
    /// QEMU's PHY (address 0, ID 0x0362/0x5e6a) needs no skews.
    const PHY: PhyConfig = PhyConfig { ksz9021_skews: None, ksz9021_force_master: false };

    fn timer_hz(_log: &mut impl Write) -> u32 {
        Self::TIMER_HZ
    }

    /// Nothing to set up: QEMU's MAC comes out of reset ready.
    fn init(_log: &mut impl Write) {}
}
