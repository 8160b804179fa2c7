//! QEMU 10's `npcm750-evb` (Nuvoton NPCM750, 2x Cortex-A9): the emulated
//! board of the tests. Addresses: QEMU `hw/arm/npcm7xx.c` (memory map and
//! device list) and docs/platform.md#two-targets.

use core::fmt::Write;
use core::ops::Range;

use dwmac::phy::PhyConfig;
use hal_avalon::map::{Csr, FABRIC_HZ, LINE_WORDS};
use hal_avalon::sim::SimAccelerator;
use hal_avalon::RegisterPort;
use soc::global_timer::GlobalTimer;
use soc::mmu::PagedSection;

use super::{Board, Renderer};
use crate::cpu::Caches;
use crate::render::{Frames, RingMemory};

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
    /// Slirp's default guest address (QEMU documentation, "Network
    /// emulation", user networking: guest 10.0.2.15, gateway 10.0.2.2).
    const DEFAULT_IPV4: &'static str = "10.0.2.15/24";
    const DEFAULT_GATEWAY: &'static str = "10.0.2.2";
    /// QEMU's PHY (address 0, ID 0x0362/0x5e6a) needs no skews.
    const PHY: PhyConfig = PhyConfig { ksz9021_skews: None, ksz9021_force_master: false };

    fn timer_hz(_log: &mut impl Write) -> u32 {
        Self::TIMER_HZ
    }

    /// Nothing to set up: QEMU's MAC comes out of reset ready.
    fn init(_log: &mut impl Write) {}
}

impl Renderer for QemuNpcm750 {
    /// No FPGA; the `sim-accelerator` build puts hal-avalon's simulated
    /// accelerator behind the real driver (its frame DMA writing the same
    /// ring), so the emulated board runs the FPGA's code paths.
    type Port = ClockedSim;

    /// Frame mode, or row mode with the `row-mode` feature.
    fn renderer(log: &mut impl Write, timer: &'static GlobalTimer, caches: Caches) -> Frames<Self::Port> {
        let fpga = cfg!(feature = "sim-accelerator").then(|| {
            let mut sim = SimAccelerator::with_memory(RingMemory::frames(caches), 2);
            // A row per status read: the main loop stays responsive.
            sim.set_frame_rows_per_poll(1);
            // `selftest-fault`: one wrong pixel, for the self-test to catch.
            if cfg!(feature = "selftest-fault") {
                sim.set_wrong_pixel(Some(crate::selftest::FAULT_PIXEL));
            }
            crate::render::accelerator(ClockedSim::new(sim, timer), timer)
        });
        let fpga = crate::selftest::gate(log, fpga, caches);
        let mut frames = if cfg!(feature = "row-mode") { Frames::rows(fpga) } else { Frames::ring(fpga, caches) };
        let _ = writeln!(log, "renderer: {}", frames.describe());
        frames
    }
}

/// The simulated accelerator with the board's time: before each register
/// access it lets the fabric clocks (50 MHz) pass that the global timer
/// counted since the last one, so the VGA counter moves at 59.5 frames per
/// second of guest time and keys debounce as in the fabric (nothing else
/// advances the simulated device's time; its frames still land a row per
/// status read).
pub struct ClockedSim {
    sim: SimAccelerator<RingMemory>,
    timer: &'static GlobalTimer,
    /// The timer's count at the last access.
    last: u64,
    /// Fabric clocks times the timer rate not yet passed (the remainder).
    rest: u128,
}

impl ClockedSim {
    /// `sim`, its time from now on taken from `timer`.
    pub fn new(sim: SimAccelerator<RingMemory>, timer: &'static GlobalTimer) -> ClockedSim {
        ClockedSim { sim, timer, last: timer.ticks(), rest: 0 }
    }

    fn catch_up(&mut self) {
        let now = self.timer.ticks();
        let ticks = now.wrapping_sub(self.last);
        self.last = now;
        let hz = u128::from(self.timer.hz().max(1));
        let scaled = u128::from(ticks) * u128::from(FABRIC_HZ) + self.rest;
        self.rest = scaled % hz;
        let mut clocks = scaled / hz;
        while clocks > 0 {
            let step = u32::try_from(clocks).unwrap_or(u32::MAX);
            self.sim.pass_clocks(step);
            clocks -= u128::from(step);
        }
    }
}

// The simulated device's work is the FPGA's on the board: the bench
// counts it as rendering, not as the CPU's (`bench::device`).
impl RegisterPort for ClockedSim {
    fn read(&mut self, csr: Csr) -> u32 {
        crate::bench::device(|| {
            self.catch_up();
            self.sim.read(csr)
        })
    }

    fn write(&mut self, csr: Csr, value: u32) {
        crate::bench::device(|| {
            self.catch_up();
            self.sim.write(csr, value)
        })
    }

    fn read_line(&mut self, out: &mut [u32; LINE_WORDS]) {
        crate::bench::device(|| {
            self.catch_up();
            self.sim.read_line(out)
        })
    }
}
