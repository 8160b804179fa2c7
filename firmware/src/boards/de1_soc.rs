//! The DE1-SoC's renderer: the FPGA when the fabric is configured, the
//! bridge open and the accelerator answers and passes its self-test, else
//! the software renderer.

use core::fmt::{self, Write};

use hal_avalon::map::{ID_MAGIC, LINE_BUFFER_OFFSET, LW_BRIDGE_BASE};
use hal_avalon::{MmioPort, RegisterPort};
use soc::cyclone_v::FpgaMode;
use soc::global_timer::GlobalTimer;
use soc::mmu::MemType;

use heapless::String;
use soc::cyclone_v::FPGAPORTRST_RELEASED;

use super::Renderer;
use crate::cpu::Caches;
use crate::health::BootFacts;
use crate::platform::de1_soc::managers;
use crate::platform::{De1Soc, PROBE};
use crate::render::{Accel, Frames};
use crate::selftest::Gated;

impl Renderer for De1Soc {
    type Port = MmioPort;

    fn renderer(
        log: &mut impl Write,
        timer: &'static GlobalTimer,
        caches: Caches,
        facts: &mut BootFacts,
    ) -> Frames<MmioPort> {
        facts.bridges = bridge_state();
        let _ = writeln!(log, "FPGA: bridges and SDRAM ports: {}", facts.bridges);
        let (accel, version) = match fpga(timer) {
            Ok(found) => found,
            Err(why) => {
                let _ = writeln!(log, "FPGA: {why}");
                crate::selftest::gate::<MmioPort>(log, None, caches, facts);
                facts.set_detail(format_args!("self-test: skipped: {why}"));
                let mut frames = Frames::ring(None, None, caches);
                let _ = writeln!(log, "renderer: {}", frames.describe());
                return frames;
            }
        };
        let mut accel = accel;
        let build = accel.port_mut().read(hal_avalon::map::Csr::BuildId);
        let _ = writeln!(log, "FPGA: ray tracer, register map version {version}, {}", crate::health::BuildId(build));
        (facts.fpga_answers, facts.register_map, facts.fpga_build) = (true, Some(version), Some(build));
        let mut frames = match crate::selftest::gate(log, Some(accel), caches, facts) {
            Gated::Passed(accel) if version >= hal_avalon::map::ID_VERSION_FRAMES => {
                Frames::ring(Some(accel), None, caches)
            }
            Gated::Passed(accel) => {
                burst_line_buffer(log, caches);
                Frames::rows(Some(accel))
            }
            Gated::RowsOnly(accel) => {
                burst_line_buffer(log, caches);
                Frames::ring(None, Some(accel), caches)
            }
            Gated::Software(kept) => Frames::ring_board_io_only(kept, caches),
        };
        let _ = writeln!(log, "renderer: {}", frames.describe());
        frames
    }
}

/// A row-mode accelerator answered: its line buffer may now be Normal
/// non-cacheable (burst reads).
fn burst_line_buffer(log: &mut impl Write, caches: Caches) {
    let line = (LW_BRIDGE_BASE + LINE_BUFFER_OFFSET) as u32;
    if crate::cpu::retype_page::<De1Soc>(line, MemType::NormalUncached, caches) {
        let _ = writeln!(log, "mmu: line-buffer page {line:#010x} Normal non-cacheable");
    }
}

/// The bridges' resets and `fpgaportrst`, in words, as read now.
fn bridge_state() -> String<96> {
    let b = managers().bridges();
    let held = |r: bool| if r { "held in reset" } else { "out of reset" };
    // SAFETY: a Cyclone V HPS (this board's build); the SDRAM controller's
    // registers are mapped Device by the firmware's table.
    let ports = unsafe { soc::cyclone_v::fpgaportrst() };
    let mut s = String::new();
    let _ = write!(
        s,
        "lwhps2fpga {}, fpgaportrst {ports:#x}{}",
        held(b.lwhps2fpga()),
        if ports & FPGAPORTRST_RELEASED == FPGAPORTRST_RELEASED { "" } else { " (the FPGA's ports held: want 0x311)" }
    );
    s
}

/// Why the FPGA path is not used.
#[derive(Debug)]
enum NoFpga {
    NotUserMode(Result<FpgaMode, u8>),
    BridgeInReset,
    Abort,
    Probe(hal_avalon::Error),
}

impl fmt::Display for NoFpga {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NoFpga::NotUserMode(mode) => write!(f, "not in user mode (FPGA manager mode {mode:?})"),
            NoFpga::BridgeInReset => f.write_str("lightweight bridge held in reset"),
            NoFpga::Abort => f.write_str("no accelerator: the ID read ended in an external abort"),
            NoFpga::Probe(e) => write!(f, "{e}"),
        }
    }
}

/// The accelerator when the fabric is in user mode, the lightweight bridge
/// is out of reset and visible, and the ID register answers (without a bus
/// hang: an empty fabric aborts the read, which the data-abort handler
/// turns into a failed probe).
fn fpga(timer: &'static GlobalTimer) -> Result<(Accel<MmioPort>, u16), NoFpga> {
    let m = managers();
    match m.fpga_mode() {
        Ok(FpgaMode::User) => {}
        other => return Err(NoFpga::NotUserMode(other)),
    }
    if m.bridges().lwhps2fpga() {
        return Err(NoFpga::BridgeInReset);
    }
    m.remap_bridges();
    let id_addr = LW_BRIDGE_BASE + hal_avalon::map::CSR_OFFSET + hal_avalon::map::Csr::Id.offset();
    let id = PROBE.probe(|| probe_read(id_addr)).ok_or(NoFpga::Abort)?;
    if id >> 16 != u32::from(ID_MAGIC) {
        return Err(NoFpga::Probe(hal_avalon::Error::NotPresent { id }));
    }
    // SAFETY: the fabric is in user mode, the bridge is out of reset and
    // visible, and a ray tracer answered the ID read; the window is mapped
    // Strongly-ordered and only the accelerator driver uses it.
    let port = unsafe { MmioPort::lightweight_bridge() };
    let mut accel = crate::render::accelerator(port, timer);
    let caps = accel.probe().map_err(NoFpga::Probe)?;
    Ok((accel, caps.version))
}

/// Read one 32-bit word at `addr` with a single A32 `ldr` whose destination
/// is 0 beforehand, with asynchronous aborts unmasked around it and a `dsb`
/// after it, so that an external abort the load causes is taken inside this
/// routine: the data-abort handler then resumes after the `ldr` (precise) or
/// where the abort was taken (imprecise), and the word reads 0. Used inside
/// `PROBE.probe`, which reports the abort.
fn probe_read(addr: usize) -> u32 {
    let value: u32;
    // SAFETY: `addr` is a device register the caller may read; an abort is
    // recovered by the handler (see above) and leaves `value` = 0. `cpsie a`
    // / `cpsid a` only toggle the asynchronous-abort mask (aarch32-cpu's
    // `Cpsr::write` cannot: it writes CPSR_fc, not the A bit).
    unsafe {
        core::arch::asm!(
            "cpsie a",
            "mov {v}, #0",
            "ldr {v}, [{a}]",
            "dsb",
            "isb",
            "cpsid a",
            v = out(reg) value,
            a = in(reg) addr,
            options(nostack),
        );
    }
    value
}
