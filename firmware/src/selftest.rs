//! The boot self-test: right after the accelerator probe, before the
//! network starts, the accelerator renders a few rows in row mode and one
//! frame in frame mode (into ring slot 0, read through [`RingMemory`] with
//! its invalidate-before-read rule), compared with the model on the A9
//! (hal-avalon [`selftest`], plan [`PLAN`]). One log line says `self-test:
//! PASS ...` or `self-test: FAIL ...` (the first differing pixel). A
//! failure in frame mode alone, where row mode renders the failing row
//! right, leaves the accelerator in row mode (the frame path is at fault,
//! most likely the FPGA-to-SDRAM port); any other failed accelerator is
//! not used. One more line says which. No accelerator: one line says the
//! self-test was skipped. [`BootFacts`] keeps the outcome for `/status`.
//!
//! On the DE1-SoC it should take 11 to 18 ms (the model renders 19
//! reference rows, 9,120 pixels at about 1,070 instructions each, while the
//! FPGA renders one frame: hal-avalon `selftest`'s "Cost on the board");
//! the line ends with the time measured on the global timer. (On the
//! emulated board the simulated accelerator renders on the guest CPU too,
//! so there it takes about a second of QEMU time.)

use core::fmt::Write;

use hal_avalon::selftest::{self, PLAN};
use hal_avalon::RegisterPort;
use rt_services::SoftwareRenderer;
use soc::global_timer::TimerDelay;

use crate::cpu::Caches;
use crate::health::BootFacts;
use crate::render::{Accel, RingMemory};

/// The pixel (row, x) the `selftest-fault` build's simulated accelerator
/// gets wrong: a row the frame half checks (the row half does not), so
/// the test sees the frame path find it.
#[cfg_attr(not(feature = "selftest-fault"), allow(dead_code))]
pub const FAULT_PIXEL: (u16, u16) = (270, 123);

/// What the self-test leaves the accelerator fit for.
pub enum Gated<P: RegisterPort> {
    /// Everything it has: frame mode (row mode on a map without frames).
    Passed(Accel<P>),
    /// Row mode only: frame mode failed and row mode renders the failing
    /// row right (the frame path's fault, `selftest::frame_path_only`).
    RowsOnly(Accel<P>),
    /// Nothing: the software renderer makes every frame. The accelerator,
    /// if one answered, is kept for its board I/O (the displays show the
    /// fault code), never to render.
    Software(Option<Accel<P>>),
}

/// Self-test `fpga`, log the outcome and keep it in `facts`; what the
/// accelerator may do from now on.
pub fn gate<P: RegisterPort>(
    log: &mut impl Write,
    fpga: Option<Accel<P>>,
    caches: Caches,
    facts: &mut BootFacts,
) -> Gated<P> {
    let Some(mut accel) = fpga else {
        let why = "self-test: skipped (no accelerator): frames come from the software renderer, the model itself";
        let _ = writeln!(log, "{why}");
        facts.self_test = "skipped";
        facts.set_detail(why);
        return Gated::Software(None);
    };
    let start = crate::platform::TIMER.now_us();
    let report = selftest::run(
        &mut accel,
        &mut RingMemory::frames(caches),
        &mut SoftwareRenderer,
        &mut TimerDelay(&crate::platform::TIMER),
        &PLAN,
    );
    let us = crate::platform::TIMER.now_us().saturating_sub(start);
    let _ = writeln!(log, "{report} ({} ms)", us / 1000);
    facts.set_detail(report);
    let Some(failure) = report.failure().copied() else {
        facts.self_test = "pass";
        (facts.rows_passed, facts.frames_passed) = (true, true);
        return Gated::Passed(accel);
    };
    facts.self_test = "fail";
    if selftest::frame_path_only(&mut accel, &mut SoftwareRenderer, &failure) {
        facts.rows_passed = true;
        let _ = writeln!(
            log,
            "FPGA: frame mode failed, row mode renders the same row right: the FPGA renders rows over the bridge \
             (slower), VGA off; check that the FPGA-to-SDRAM port is out of reset (fpgaportrst)"
        );
        return Gated::RowsOnly(accel);
    }
    let _ = writeln!(log, "FPGA: failed its self-test: accelerator not used, software renderer from now on");
    Gated::Software(Some(accel))
}
