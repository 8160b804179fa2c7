//! What the server renders with: a [`Board`] (rt-services-std's: one engine, one
//! ring, every service within its quota, as on bare metal) built from the
//! accelerator behind the bridge ([`fpga`]), hal-avalon's simulated one
//! ([`simulated`]) or the model in software ([`software`]), and what
//! `/status` says of it ([`Facts`]).
//!
//! With the accelerator, frame mode is used where the kernel set memory
//! aside for it ([`frame_memory()`], [`DmaRing`]: a u-dma-buf
//! buffer, the SDRAM ports out of reset) and the boot self-test's frame
//! half passes there; otherwise rows over the lightweight bridge (the
//! seed's way), with the reason in the log and `/status`. The frame
//! registers are never given an address outside that buffer: a frame DMA
//! started anywhere else would write over whatever memory is there.

use std::sync::Arc;
use std::time::{Duration, Instant};

use embedded_hal::delay::DelayNs;
use hal_avalon::selftest::{self, Outcome, SelfTestReport, PLAN};
use hal_avalon::{Accelerator, PollTimeout, RegisterPort};
use rt_services::frames::{FallbackEngine, Watchdog};
use rt_services::{FrameRing, RowEngine, SoftwareRenderer};
use rt_services_std::board::{self, Board};
use rt_services_std::Facts;
use rt_services_std::SelfTest;

use crate::frame_memory::{self, DmaRing};
use crate::panel::{Identity, PanelRing, RING_SLOTS};
use crate::preflight::{self, Finding, Report, System};

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
/// its `PLAN`), for row mode.
pub fn row_self_test<P: RegisterPort, D: DelayNs>(accel: &mut Accelerator<P, D>) -> SelfTest {
    match selftest::check_rows(accel, &mut SoftwareRenderer, &PLAN) {
        Ok(pixels) => SelfTest {
            result: "pass",
            detail: format!(
                "self-test: pass: {} rows, {pixels} pixels equal the model's (row mode)",
                PLAN.rows.len() * PLAN.row_lights.len()
            ),
        },
        Err(failure) => {
            let report = SelfTestReport { plan: &PLAN, outcome: Outcome::Fail(failure), abort_unconfirmed: false };
            SelfTest { result: "fail", detail: report.to_string() }
        }
    }
}

/// The ring frame mode would render into on `sys`: the u-dma-buf buffer
/// mapped, or why frame mode is not tried (no buffer fit for the ring, or
/// the SDRAM ports the DMA writes through held in reset).
pub fn frame_memory(sys: &System) -> Result<DmaRing, String> {
    let buffer = frame_memory::find(&sys.sysfs, &sys.dev, frame_memory::RING_BYTES).map_err(|e| e.to_string())?;
    if let Finding::Bad(seen) = preflight::sdram_ports(sys) {
        return Err(format!("frame mode not tried: {seen}; rendering rows over the lightweight bridge"));
    }
    DmaRing::open(&buffer, RING_SLOTS)
        .map_err(|e| format!("frame mode not tried: {e}; rendering rows over the lightweight bridge"))
}

/// A board on the accelerator behind `port` (already checked by
/// [`preflight`]), after its self-test: frame mode into
/// `memory` when there is one and the self-test passes there, rows when
/// there is none (`Err`: why) or only the frame path failed; an
/// accelerator that fails otherwise is refused (the caller may fall back
/// to [`software`] when told to).
pub fn fpga<P>(port: P, report: &Report, memory: Result<DmaRing, String>) -> Result<(Arc<Board>, Facts), SelfTest>
where
    P: RegisterPort + Send + 'static,
{
    let mut accel = Accelerator::new(port, PollDelay, PollTimeout::DEFAULT);
    let caps = match accel.probe() {
        Ok(caps) => caps,
        Err(e) => return Err(SelfTest { result: "fail", detail: format!("self-test: FAIL: {e}") }),
    };
    let mut ring = match memory {
        Ok(ring) if caps.frames() => ring,
        Ok(_) => {
            let why = format!("register map version {} has no frame DMA: rendering rows", caps.version);
            return rows(accel, report, &why, true);
        }
        Err(why) => return rows(accel, report, &why, true),
    };
    let outcome = selftest::run(&mut accel, &mut ring, &mut SoftwareRenderer, &mut PollDelay, &PLAN);
    let detail = outcome.to_string();
    match outcome.failure().copied() {
        None => {
            let self_test = SelfTest { result: "pass", detail: format!("{detail} (frame mode into {ring:?})") };
            let identity = Identity { name: host_name(), frames_passed: true };
            let panel = PanelRing::new(FrameRing::new(ring, frame_engine(accel)), true, identity);
            let vga = panel.vga().to_string();
            let board = Board::new(panel, "FPGA frame DMA into the u-dma-buf ring");
            Ok((board, Facts { mode: "frames".into(), vga, ..fpga_facts(report, self_test) }))
        }
        Some(failure) if selftest::frame_path_only(&mut accel, &mut SoftwareRenderer, &failure) => {
            let why = format!(
                "{detail}; row mode renders that row right: the frame path is at fault (check that the boot loader \
                 released the FPGA-to-SDRAM ports, fpgaportrst): rendering rows over the lightweight bridge"
            );
            rows(accel, report, &why, false)
        }
        Some(_) => Err(SelfTest { result: "fail", detail }),
    }
}

/// Row mode on `accel` after the row self-test; `why` says why not frames,
/// `by_choice` whether that is no fault (no frame memory, no frame DMA in
/// the image) rather than a frame path that failed (code E4).
fn rows<P>(
    mut accel: Accelerator<P, PollDelay>,
    report: &Report,
    why: &str,
    by_choice: bool,
) -> Result<(Arc<Board>, Facts), SelfTest>
where
    P: RegisterPort + Send + 'static,
{
    let mut self_test = row_self_test(&mut accel);
    if self_test.result != "pass" {
        return Err(self_test);
    }
    self_test.detail = format!("{}; {why}", self_test.detail);
    // A frame path that failed shows E4 (rows only), as the firmware's.
    let identity = Identity { name: host_name(), frames_passed: by_choice };
    let ring = FrameRing::new(rt_services_std::SharedMemory::new(RING_SLOTS), RowEngine::new(accel));
    let panel = PanelRing::new(ring, false, identity);
    let vga = panel.vga().to_string();
    let board = Board::new(panel, "FPGA rows into the ring");
    Ok((board, Facts { mode: "rows".into(), vga, ..fpga_facts(report, self_test) }))
}

/// A frame that lands no row for this long fails instead of holding its
/// slot and every frame begun after it (the firmware's `STALL_LIMIT`).
pub const STALL_LIMIT: Duration = Duration::from_millis(500);

/// The program's clock for the watchdog.
fn now() -> rt_services::Instant {
    static START: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
    let start = *START.get_or_init(Instant::now);
    rt_services::Instant::from_millis(u64::try_from(start.elapsed().as_millis()).unwrap_or(u64::MAX))
}

type Clock = fn() -> rt_services::Instant;

/// Frame mode's engine, as the firmware's: the frame DMA watched for
/// stalls ([`STALL_LIMIT`]); after `WEDGED_AFTER` failed frames in a row it
/// is switched off (kept for the board I/O) and the software renderer
/// fills the ring.
pub type FrameModeEngine<P> = FallbackEngine<Watchdog<Accelerator<P, PollDelay>, Clock>, RowEngine<SoftwareRenderer>>;

fn frame_engine<P: RegisterPort>(accel: Accelerator<P, PollDelay>) -> FrameModeEngine<P> {
    FallbackEngine::new(Some(Watchdog::new(accel, now as Clock, STALL_LIMIT)), RowEngine::new(SoftwareRenderer))
}

/// The host's name (`/proc/sys/kernel/hostname`), for the displays.
fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|n| n.trim().to_string())
        .ok()
        .filter(|n| !n.is_empty())
        .unwrap_or_else(|| "raytracer".into())
}

/// What a board on the FPGA says of itself.
fn fpga_facts(report: &Report, self_test: SelfTest) -> Facts {
    Facts {
        renderer: "fpga".into(),
        register_map: Some(report.register_map),
        fpga_build: Some(report.build_id),
        bridges: format!("{}; {}", report.fpga, report.bridge),
        ..facts(self_test)
    }
}

/// How often the board's own work runs ([`Board::tick`]): the display's
/// refresh is 16.8 ms, and each frame shown waits for one.
pub const TICK_EVERY: Duration = Duration::from_millis(4);

/// Run `board`'s own work (the monitor, the keys, the LEDs and displays)
/// every [`TICK_EVERY`] on a thread of its own, for the program's life.
pub fn drive(board: Arc<Board>) {
    std::thread::spawn(move || loop {
        if let Some(line) = board.tick() {
            eprintln!("hps-linux: {line}");
        }
        std::thread::sleep(TICK_EVERY);
    });
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
    (board::simulated(), facts)
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
