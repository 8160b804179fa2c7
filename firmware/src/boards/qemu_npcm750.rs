//! The emulated board's renderer: the software renderer, or (feature
//! `sim-accelerator`) hal-avalon's simulated accelerator behind the real
//! driver, on the guest's clock.

use core::fmt::Write;

use hal_avalon::map::{Csr, FABRIC_HZ, LINE_WORDS};
use hal_avalon::sim::{DmaTarget, SimAccelerator};
use hal_avalon::RegisterPort;
use soc::global_timer::GlobalTimer;

use super::Renderer;
use crate::cpu::Caches;
use crate::health::BootFacts;
use crate::platform::QemuNpcm750;
use crate::render::{Frames, RingMemory};
use crate::selftest::Gated;

impl Renderer for QemuNpcm750 {
    /// No FPGA; the `sim-accelerator` build puts hal-avalon's simulated
    /// accelerator behind the real driver (its frame DMA writing the same
    /// ring), so the emulated board runs the FPGA's code paths.
    type Port = ClockedSim;

    /// Frame mode, or row mode with the `row-mode` feature.
    fn renderer(
        log: &mut impl Write,
        timer: &'static GlobalTimer,
        caches: Caches,
        facts: &mut BootFacts,
    ) -> Frames<Self::Port> {
        facts.bridges = crate::health::str_of("not a board (emulated: no bridges, no SDRAM ports)");
        let fpga = cfg!(feature = "sim-accelerator").then(|| {
            // `frame-port-fault`: the frame DMA's memory never answers, as
            // with the FPGA-to-SDRAM port held in reset.
            let port = FramePort { mem: RingMemory::frames(caches), held: cfg!(feature = "frame-port-fault") };
            let mut sim = SimAccelerator::with_memory(port, 2);
            // A row per status read: the main loop stays responsive.
            sim.set_frame_rows_per_poll(1);
            // `selftest-fault`: one wrong pixel, for the self-test to catch.
            if cfg!(feature = "selftest-fault") {
                sim.set_wrong_pixel(Some(crate::selftest::FAULT_PIXEL));
            }
            crate::render::accelerator(ClockedSim::new(sim, timer), timer)
        });
        let mut fpga = fpga;
        if let Some(accel) = &mut fpga {
            let build = accel.port_mut().read(Csr::BuildId);
            let _ = writeln!(
                log,
                "FPGA: simulated, register map version {}, {}",
                hal_avalon::map::ID_VERSION,
                crate::health::BuildId(build)
            );
            (facts.fpga_answers, facts.register_map, facts.fpga_build) =
                (true, Some(hal_avalon::map::ID_VERSION), Some(build));
        }
        let mut frames = match (crate::selftest::gate(log, fpga, caches, facts), cfg!(feature = "row-mode")) {
            (Gated::Passed(accel), true) => Frames::rows(Some(accel)),
            (Gated::Passed(accel), false) => Frames::ring(Some(accel), None, caches),
            (Gated::RowsOnly(accel), _) => Frames::ring(None, Some(accel), caches),
            (Gated::Software(_), true) => Frames::rows(None),
            (Gated::Software(kept), false) => Frames::ring_board_io_only(kept, caches),
        };
        let _ = writeln!(log, "renderer: {}", frames.describe());
        frames
    }
}

/// The simulated frame DMA's memory: the ring, or nothing that answers
/// (`held`: the FPGA-to-SDRAM port in reset).
pub struct FramePort {
    mem: RingMemory,
    held: bool,
}

impl DmaTarget for FramePort {
    fn write(&mut self, addr: u32, bytes: &[u8]) -> bool {
        !self.held && self.mem.write(addr, bytes)
    }

    fn read(&mut self, addr: u32, out: &mut [u8]) -> bool {
        !self.held && self.mem.read(addr, out)
    }

    fn answers(&self) -> bool {
        !self.held
    }
}

/// The simulated accelerator with the board's time: before each register
/// access it lets the fabric clocks (50 MHz) pass that the global timer
/// counted since the last one, so the VGA counter moves at 59.5 frames per
/// second of guest time and keys debounce as in the fabric (nothing else
/// advances the simulated device's time; its frames still land a row per
/// status read).
pub struct ClockedSim {
    sim: SimAccelerator<FramePort>,
    timer: &'static GlobalTimer,
    /// The timer's count at the last access.
    last: u64,
    /// Fabric clocks times the timer rate not yet passed (the remainder).
    rest: u128,
}

impl ClockedSim {
    /// `sim`, its time from now on taken from `timer`.
    pub fn new(sim: SimAccelerator<FramePort>, timer: &'static GlobalTimer) -> ClockedSim {
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
