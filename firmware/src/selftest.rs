//! The boot self-test: right after the accelerator probe, before the
//! network starts, the accelerator renders a few rows in row mode and one
//! frame in frame mode (into ring slot 0, read through [`RingMemory`] with
//! its invalidate-before-read rule), compared with the model on the A9
//! (hal-avalon [`selftest`], plan [`PLAN`]). One log line says `self-test:
//! PASS ...` or `self-test: FAIL ...` (the first differing pixel); a failed
//! accelerator is not used, and one more line says so. No accelerator: one
//! line says the self-test was skipped.
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
use crate::render::{Accel, RingMemory};

/// The pixel (row, x) the `selftest-fault` build's simulated accelerator
/// gets wrong: a row the frame half checks (the row half does not), so
/// the test sees the frame path find it.
#[cfg_attr(not(feature = "selftest-fault"), allow(dead_code))]
pub const FAULT_PIXEL: (u16, u16) = (270, 123);

/// Self-test `fpga` and log the outcome; the accelerator back if it
/// passed, none (the software renderer) if it failed or there is none.
pub fn gate<P: RegisterPort>(log: &mut impl Write, fpga: Option<Accel<P>>, caches: Caches) -> Option<Accel<P>> {
    let Some(mut accel) = fpga else {
        let _ = writeln!(
            log,
            "self-test: skipped (no accelerator): frames come from the software renderer, the model itself"
        );
        return None;
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
    if report.passed() {
        return Some(accel);
    }
    let _ = writeln!(log, "FPGA: failed its self-test: accelerator not used, software renderer from now on");
    None
}
