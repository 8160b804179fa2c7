//! What the server renders with: a [`Board`] (hps-sim's: one engine, one
//! ring, every service within its quota, as on bare metal) built from the
//! accelerator behind the bridge ([`fpga`]), hal-avalon's simulated one
//! ([`simulated`]) or the model in software ([`software`]), and what
//! `/status` says of it ([`Facts`]).
//!
//! Under Linux the FPGA renders rows (the seed's way, row mode over the
//! lightweight bridge) into a ring in the process's memory: its frame DMA
//! needs physically contiguous, cache-coherent memory at a bus address
//! (docs/linux.md, "Frame mode"), which an ordinary process does not have.
//! The accelerator's frame registers are never touched here: a frame DMA
//! started at an address the kernel did not set aside would write over
//! whatever memory is there.

use std::sync::Arc;
use std::time::{Duration, Instant};

use embedded_hal::delay::DelayNs;
use hal_avalon::selftest::{self, Outcome, SelfTestReport, PLAN};
use hal_avalon::{Accelerator, PollTimeout, RegisterPort};
use hps_sim::board::{self, Board};
use hps_sim::web::Facts;
use hps_sim::SelfTest;
use rt_services::SoftwareRenderer;

use crate::preflight::Report;

/// Delays the driver's STATUS polls: short waits spin (a row is about
/// 12 us of the FPGA's, and the kernel's shortest sleep is tens of
/// microseconds: sleeping there would cost more than the row), longer ones
/// sleep.
#[derive(Clone, Copy, Debug, Default)]
pub struct PollDelay;

/// Waits up to this long spin; longer ones sleep.
const SPIN_UP_TO: Duration = Duration::from_micros(100);

impl DelayNs for PollDelay {
    fn delay_ns(&mut self, ns: u32) {
        let wait = Duration::from_nanos(u64::from(ns));
        if wait > SPIN_UP_TO {
            std::thread::sleep(wait);
            return;
        }
        let until = Instant::now() + wait;
        while Instant::now() < until {
            std::hint::spin_loop();
        }
    }
}

/// The FPGA's rows, compared with the model's, at start: the row half of
/// the firmware's boot self-test (hal-avalon `selftest::check_rows` with
/// its `PLAN`); its frame half would start the frame DMA.
pub fn row_self_test<P: RegisterPort, D: DelayNs>(accel: &mut Accelerator<P, D>) -> SelfTest {
    match selftest::check_rows(accel, &mut SoftwareRenderer, &PLAN) {
        Ok(pixels) => SelfTest {
            result: "pass",
            detail: format!(
                "self-test: pass: {} rows, {pixels} pixels equal the model's (row mode; frame mode not used under Linux)",
                PLAN.rows.len() * PLAN.row_lights.len()
            ),
        },
        Err(failure) => {
            let report = SelfTestReport { plan: &PLAN, outcome: Outcome::Fail(failure), abort_unconfirmed: false };
            SelfTest { result: "fail", detail: report.to_string() }
        }
    }
}

/// A board rendering rows on the accelerator behind `port` (already
/// checked by [`preflight`](crate::preflight)), with its self-test; an
/// accelerator that fails the self-test is refused (the caller may fall
/// back to [`software`] when told to).
pub fn fpga<P>(port: P, report: &Report) -> Result<(Arc<Board>, Facts), SelfTest>
where
    P: RegisterPort + Send + 'static,
{
    let mut accel = Accelerator::new(port, PollDelay, PollTimeout::DEFAULT);
    if let Err(e) = accel.probe() {
        return Err(SelfTest { result: "fail", detail: format!("self-test: FAIL: {e}") });
    }
    let self_test = row_self_test(&mut accel);
    if self_test.result != "pass" {
        return Err(self_test);
    }
    let board = board::rows_into_ring(accel, "FPGA rows into the ring");
    let facts = Facts {
        renderer: "fpga".into(),
        mode: "rows".into(),
        register_map: Some(report.register_map),
        fpga_build: Some(report.build_id),
        bridges: format!("{}; {}", report.fpga, report.bridge),
        ..facts(self_test)
    };
    Ok((board, facts))
}

/// A board on hal-avalon's simulated accelerator (frame mode into host
/// memory): the program's own tests, and trying it without a board.
pub fn simulated() -> (Arc<Board>, Facts) {
    let self_test = SelfTest { result: "skipped", detail: "self-test: skipped (simulated accelerator)".into() };
    let facts = Facts {
        renderer: "simulated".into(),
        mode: "frames".into(),
        register_map: Some(hal_avalon::map::ID_VERSION),
        fpga_build: Some(0),
        bridges: "not a board (simulated accelerator)".into(),
        ..facts(self_test)
    };
    (board::simulated(hps_sim::Faults::default()), facts)
}

/// A board rendering with the model in software (no FPGA: asked for with
/// `--software-fallback` when the accelerator cannot be used, and said so
/// in `/status`); `why` is the reason.
pub fn software(why: &str) -> (Arc<Board>, Facts) {
    let self_test = SelfTest { result: "skipped", detail: format!("self-test: skipped: {why}") };
    let facts = Facts {
        renderer: "software".into(),
        mode: "software".into(),
        register_map: None,
        fpga_build: None,
        bridges: why.into(),
        ..facts(self_test)
    };
    (board::rows_into_ring(rt_services::SoftwareRenderer, "software renderer into the ring"), facts)
}

/// What every board of this program says.
fn facts(self_test: SelfTest) -> Facts {
    Facts {
        renderer: String::new(),
        link: "Linux".into(),
        mode: String::new(),
        version: env!("CARGO_PKG_VERSION").into(),
        register_map: None,
        fpga_build: None,
        bridges: String::new(),
        vga: "off: hps-linux does not drive the VGA output".into(),
        address_from: "Linux".into(),
        self_test,
    }
}
