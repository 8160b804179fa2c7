//! The board cost model of `cargo xtask bench-fw`: what the firmware's
//! per-frame counts (measured on the emulated board) would cost on a real
//! DE1-SoC, with every per-operation cost in [`CONSTANTS`] next to its
//! public source.
//!
//! The model is additive: the CPU's time per frame is the sum of its
//! instructions at a planning IPC and of each kind of memory or bus access
//! at its measured rate. That double-counts the instructions of the copy
//! loops (the bandwidth figures are `memcpy` measurements that include
//! them) and ignores overlap, so it errs on the slow side. A frame takes
//! the longest of the CPU's time, the FPGA's (rendering overlaps sending:
//! frames and rows are started ahead) and the wire's.
//!
//! "UviDTE" in the sources is the public repository
//! `UviDTE-FPSoC/CycloneVSoC-time-measurements`: bare-metal measurements on
//! a DE1-SoC (A9 at 800 MHz, library `memcpy`, means of 100 runs), its
//! spreadsheets `results/CycloneVSoC_HPS-FPGA_main_time_measurements.xlsx`
//! and `results/CycloneVSoC_baremetal_cache.xlsx`.

/// One per-operation cost and where it comes from.
pub struct Constant {
    /// What it is.
    pub name: &'static str,
    /// Its value, in the unit named.
    pub value: f64,
    /// The unit.
    pub unit: &'static str,
    /// The public source, and whether the figure is measured or estimated.
    pub source: &'static str,
}

/// The A9 clock.
pub const CPU_HZ: Constant = Constant {
    name: "A9 clock",
    value: 800e6,
    unit: "Hz",
    source: "Cyclone V SoC datasheet: 800 MHz speed grade -6 (DE1-SoC: 5CSEMA5F31C6); UviDTE's PMU runs at 800 MHz",
};
/// Instructions per cycle for driver and network-stack code.
pub const IPC: Constant = Constant {
    name: "instructions per cycle",
    value: 0.7,
    unit: "instr/cycle",
    source:
        "estimate: dual issue, one load/store pipe (GCC cortex-a9.md); 0.5-1.3 for such code, no public measurement",
};
/// A single 32-bit register read across the lightweight bridge.
pub const LW_READ: Constant = Constant {
    name: "LW bridge register read",
    value: 220e-9,
    unit: "s",
    source: "UviDTE HPS-FPGA xlsx, LW32 RD caches off at 50 MHz: 18.16 MB/s = 220 ns/word (upper bound, measured)",
};
/// A word of the line buffer read with multi-word loads.
pub const LW_BURST_WORD: Constant = Constant {
    name: "LW bridge burst read, per word",
    value: 52e-9,
    unit: "s",
    source: "UviDTE HPS-FPGA xlsx, LW32 RD caches on at 50 MHz: 76.2 MB/s = 52 ns/word (measured)",
};
/// A register write across the lightweight bridge (Strongly-ordered).
pub const LW_WRITE: Constant = Constant {
    name: "LW bridge register write",
    value: 260e-9,
    unit: "s",
    source:
        "UviDTE HPS-FPGA xlsx, LW32 WR single 4-byte memcpy: 15.38 MB/s = 260 ns/call (measured, includes the call)",
};
/// Reading DRAM through the caches (line fills after an invalidation).
pub const CACHED_READ: Constant = Constant {
    name: "cached DRAM read",
    value: 326.7e6,
    unit: "B/s",
    source: "UviDTE cache xlsx, L1+L2 on, 2 MB DDR -> FPGA memcpy: 326.7 MB/s (measured; bridge-bound, a lower bound)",
};
/// Reading DRAM mapped Normal non-cacheable.
pub const UNCACHED_READ: Constant = Constant {
    name: "uncached DRAM read",
    value: 42.9e6,
    unit: "B/s",
    source: "UviDTE cache xlsx, MMU on, D-cache off, 2 MB DDR -> FPGA memcpy: 42.9 MB/s (measured)",
};
/// What writing DRAM mapped Normal non-cacheable (the MAC's TX buffers)
/// costs beyond a cached write, whose instructions are already counted.
pub const UNCACHED_WRITE: Constant = Constant {
    name: "uncached DRAM write, extra",
    value: 2.08e-9,
    unit: "s/B",
    source: "derived from UviDTE cache xlsx, 2 MB FPGA -> DDR memcpy: 142.7 MB/s with DDR uncached, 203 MB/s cached (same source reads): 7.01 - 4.93 ns/B",
};
/// Maintaining one cache line on both levels (CP15 op + L2C-310 register
/// write).
pub const LINE_OP: Constant = Constant {
    name: "cache line maintenance (L1 + L2)",
    value: 50e-9,
    unit: "s",
    source: "estimate: one CP15 op (~10 ns) and one atomic L2C-310 by-PA write (~40 ns); no public measurement",
};
/// The FPGA's cycles per frame in frame mode, one lane.
pub const FPGA_FRAME_CYCLES: Constant = Constant {
    name: "FPGA cycles per frame, frame mode",
    value: 173_739.0,
    unit: "cycles",
    source: "cargo xtask rtl: Verilator co-simulation, LANES=1, with random memory back-pressure",
};
/// The FPGA's cycles per frame in row mode, one lane.
pub const FPGA_ROW_MODE_CYCLES: Constant = Constant {
    name: "FPGA cycles per frame, row mode",
    value: 207_360.0,
    unit: "cycles",
    source: "cargo xtask rtl: Verilator co-simulation, LANES=1: 576 cycles per row",
};
/// The fabric clock.
pub const FPGA_HZ: Constant = Constant {
    name: "FPGA clock",
    value: 50e6,
    unit: "Hz",
    source: "DE1-SoC CLOCK_50 (Terasic DE1-SoC user manual, clock circuitry)",
};
/// Gigabit Ethernet's byte rate on the wire.
pub const WIRE: Constant =
    Constant { name: "Gigabit Ethernet", value: 125e6, unit: "B/s", source: "IEEE 802.3: 1000 Mb/s" };
/// What each Ethernet frame adds on the wire beyond the bytes the MAC is
/// given: preamble and start delimiter, FCS, inter-frame gap.
pub const WIRE_PER_FRAME: Constant = Constant {
    name: "Ethernet preamble + FCS + gap",
    value: 24.0,
    unit: "B/frame",
    source: "IEEE 802.3: 8 preamble/SFD + 4 FCS + 12 inter-frame gap",
};

/// Every constant, for the table.
pub const CONSTANTS: [&Constant; 14] = [
    &CPU_HZ,
    &IPC,
    &LW_READ,
    &LW_BURST_WORD,
    &LW_WRITE,
    &CACHED_READ,
    &UNCACHED_READ,
    &UNCACHED_WRITE,
    &LINE_OP,
    &FPGA_FRAME_CYCLES,
    &FPGA_ROW_MODE_CYCLES,
    &FPGA_HZ,
    &WIRE,
    &WIRE_PER_FRAME,
];

/// What the firmware did for one frame (averages from the bench build).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameCounts {
    /// Guest instructions of streaming (busy time minus rendering).
    pub instructions: f64,
    /// Accelerator register reads.
    pub lw_reads: f64,
    /// Accelerator line-buffer words read in bursts.
    pub lw_line_words: f64,
    /// Accelerator register writes.
    pub lw_writes: f64,
    /// Cache lines invalidated before reading (each is then filled from
    /// DRAM: 32 bytes read through the caches).
    pub lines_invalidated: f64,
    /// Cache lines cleaned after CPU writes.
    pub lines_cleaned: f64,
    /// Bytes the CPU read from uncached memory.
    pub uncached_read: f64,
    /// Bytes the MAC sent (frames, without preamble, FCS and gap).
    pub mac_tx: f64,
    /// Of those, bytes the MAC read from the frame ring itself (the RTP
    /// rows of two-buffer descriptors); the CPU wrote the rest into its
    /// uncached TX buffers.
    pub mac_tx_zero_copy: f64,
    /// Ethernet frames sent.
    pub tx_frames: f64,
}

/// One cost of a frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Cost {
    /// What.
    pub name: &'static str,
    /// Seconds per frame.
    pub seconds: f64,
}

/// The estimate for one mode.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// The CPU's costs per frame.
    pub cpu: Vec<Cost>,
    /// The FPGA's time per frame.
    pub fpga: f64,
    /// The wire's time per frame.
    pub wire: f64,
}

impl Estimate {
    /// The CPU's time per frame.
    pub fn cpu_seconds(&self) -> f64 {
        self.cpu.iter().map(|c| c.seconds).sum()
    }

    /// Frames per second: the slowest of CPU, FPGA and wire.
    pub fn fps(&self) -> f64 {
        1.0 / self.cpu_seconds().max(self.fpga).max(self.wire)
    }

    /// What limits the rate.
    pub fn bound(&self) -> &'static str {
        let cpu = self.cpu_seconds();
        if cpu >= self.fpga && cpu >= self.wire {
            "CPU"
        } else if self.fpga >= self.wire {
            "FPGA"
        } else {
            "wire"
        }
    }
}

/// The board's time for a frame with `counts`, the FPGA taking
/// `fpga_cycles` per frame.
pub fn estimate(counts: &FrameCounts, fpga_cycles: f64) -> Estimate {
    let line = 32.0;
    let cpu = vec![
        Cost { name: "instructions", seconds: counts.instructions / (IPC.value * CPU_HZ.value) },
        Cost { name: "LW register reads", seconds: counts.lw_reads * LW_READ.value },
        Cost { name: "LW line-buffer bursts", seconds: counts.lw_line_words * LW_BURST_WORD.value },
        Cost { name: "LW register writes", seconds: counts.lw_writes * LW_WRITE.value },
        Cost { name: "cache maintenance", seconds: (counts.lines_invalidated + counts.lines_cleaned) * LINE_OP.value },
        Cost { name: "cached DRAM reads", seconds: counts.lines_invalidated * line / CACHED_READ.value },
        Cost { name: "uncached DRAM reads", seconds: counts.uncached_read / UNCACHED_READ.value },
        Cost {
            name: "uncached DRAM writes (TX)",
            seconds: (counts.mac_tx - counts.mac_tx_zero_copy).max(0.0) * UNCACHED_WRITE.value,
        },
    ];
    Estimate {
        cpu,
        fpga: fpga_cycles / FPGA_HZ.value,
        wire: (counts.mac_tx + counts.tx_frames * WIRE_PER_FRAME.value) / WIRE.value,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_copy_bytes_cost_the_wire_but_not_the_cpu() {
        let rows =
            FrameCounts { mac_tx: 540_720.0, mac_tx_zero_copy: 518_400.0, tx_frames: 360.0, ..Default::default() };
        let e = estimate(&rows, 0.0);
        assert!((e.cpu_seconds() - 22_320.0 * 2.08e-9).abs() < 1e-12, "only the headers are written by the CPU");
        assert!((e.wire - (540_720.0 + 360.0 * 24.0) / 125e6).abs() < 1e-12);
    }

    #[test]
    fn every_constant_is_positive_and_sourced() {
        for c in CONSTANTS {
            assert!(c.value > 0.0 && !c.source.is_empty(), "{}", c.name);
        }
    }

    #[test]
    fn the_slowest_of_cpu_fpga_and_wire_sets_the_rate() {
        // Nothing but the wire: one frame's payload in 1,448-byte segments.
        let segments = (518_400.0f64 / 1448.0).ceil();
        let wire_only = FrameCounts { mac_tx: 518_400.0 + 54.0 * segments, tx_frames: segments, ..Default::default() };
        let e = estimate(&wire_only, 0.0);
        assert_eq!(e.bound(), "wire");
        assert!((e.cpu_seconds() - wire_only.mac_tx * 2.08e-9).abs() < 1e-12, "only the TX writes");
        let wire = (518_400.0 + 78.0 * segments) / 125e6;
        assert!((e.wire - wire).abs() < 1e-12);
        // A billion instructions: about 1.8 s at 800 MHz and IPC 0.7.
        let slow = FrameCounts { instructions: 1e9, ..Default::default() };
        let e = estimate(&slow, FPGA_FRAME_CYCLES.value);
        assert!((e.fps() - 0.56).abs() < 0.01, "{}", e.fps());
        // No CPU work: the FPGA's 173,739 cycles at 50 MHz.
        let e = estimate(&FrameCounts::default(), FPGA_FRAME_CYCLES.value);
        assert_eq!(e.bound(), "FPGA");
        assert!((e.fps() - 287.8).abs() < 0.1);
    }
}
