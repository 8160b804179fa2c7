//! The DE1-SoC's renderer: the FPGA when the fabric is configured, the
//! bridge open and the accelerator answers and passes its self-test, else
//! the software renderer.

use core::fmt::{self, Write};

use hal_avalon::map::{ID_MAGIC, LINE_BUFFER_OFFSET, LW_BRIDGE_BASE};
use hal_avalon::MmioPort;
use soc::cyclone_v::FpgaMode;
use soc::global_timer::GlobalTimer;
use soc::mmu::MemType;

use super::Renderer;
use crate::cpu::Caches;
use crate::platform::de1_soc::managers;
use crate::platform::{De1Soc, PROBE};
use crate::render::{Accel, Frames};

impl Renderer for De1Soc {
    type Port = MmioPort;

    fn renderer(log: &mut impl Write, timer: &'static GlobalTimer, caches: Caches) -> Frames<MmioPort> {
        let mut frames = match fpga(timer) {
            Ok((accel, version)) => {
                let _ = writeln!(log, "FPGA: ray tracer, register map version {version}");
                match crate::selftest::gate(log, Some(accel), caches) {
                    Some(accel) if version >= hal_avalon::map::ID_VERSION_FRAMES => Frames::ring(Some(accel), caches),
                    Some(accel) => {
                        // A row-mode accelerator answered: its line buffer
                        // may now be Normal non-cacheable (burst reads).
                        let line = (LW_BRIDGE_BASE + LINE_BUFFER_OFFSET) as u32;
                        if crate::cpu::retype_page::<De1Soc>(line, MemType::NormalUncached, caches) {
                            let _ = writeln!(log, "mmu: line-buffer page {line:#010x} Normal non-cacheable");
                        }
                        Frames::rows(Some(accel))
                    }
                    None => Frames::ring(None, caches),
                }
            }
            Err(why) => {
                let _ = writeln!(log, "FPGA: {why}");
                crate::selftest::gate::<MmioPort>(log, None, caches);
                Frames::ring(None, caches)
            }
        };
        let _ = writeln!(log, "renderer: {}", frames.describe());
        frames
    }
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
