//! The boot self-test (`hal_avalon::selftest`) against the simulated
//! accelerator: it passes on a correct one, finds an injected wrong pixel
//! in row and frame mode, reads a frame's rows only once ROWS_DONE covers
//! them, and gives up within its bounds on an accelerator that never
//! finishes.

use std::cell::RefCell;
use std::rc::Rc;

use hal_avalon::map::{
    Csr, FRAME_CONTROL_ABORT, FRAME_CONTROL_START, FRAME_STATUS_ABORTED, FRAME_STATUS_DONE, ID_MAGIC,
};
use hal_avalon::selftest::{self, Mode, Outcome, Plan, Problem, PLAN};
use hal_avalon::sim::{CountingDelay, DmaTarget, Fault, SimAccelerator};
use hal_avalon::{Accelerator, Error, PollTimeout, RegisterPort};
use model::{Light, FRAME_BYTES, ROW_BYTES, WIDTH};
use rt_services::{FrameMemory, SoftwareRenderer};

const BASE: u32 = 0x0410_0000;
const SLOTS: usize = 2;

/// What the port and the memory share: the bytes, every ROWS_DONE value the
/// driver read, and for every row read, how many ROWS_DONE reads preceded it.
#[derive(Default)]
struct Shared {
    bytes: Vec<u8>,
    rows_done_reads: Vec<u16>,
    row_reads: Vec<(u16, usize)>,
}

type Handle = Rc<RefCell<Shared>>;

/// The frame memory: written by the simulated DMA, read by the self-test.
#[derive(Clone)]
struct Memory(Handle);

impl DmaTarget for Memory {
    fn write(&mut self, addr: u32, bytes: &[u8]) -> bool {
        let Some(off) = addr.checked_sub(BASE).map(|o| o as usize) else { return false };
        match self.0.borrow_mut().bytes.get_mut(off..off + bytes.len()) {
            Some(dst) => {
                dst.copy_from_slice(bytes);
                true
            }
            None => false,
        }
    }
}

impl FrameMemory for Memory {
    fn slot_address(&self, slot: usize) -> u32 {
        BASE + (slot * FRAME_BYTES) as u32
    }

    fn read_row(&mut self, slot: usize, y: u16, offset: usize, out: &mut [u8]) {
        let mut s = self.0.borrow_mut();
        let polls = s.rows_done_reads.len();
        s.row_reads.push((y, polls));
        let at = slot * FRAME_BYTES + usize::from(y) * ROW_BYTES + offset;
        out.copy_from_slice(&s.bytes[at..at + out.len()]);
    }

    fn write_row(&mut self, _slot: usize, _y: u16, _row: &[u8; ROW_BYTES]) {
        panic!("the self-test never writes the frame memory");
    }
}

/// The simulated accelerator with hooks: ROWS_DONE that lags the rows that
/// landed, frames that never finish, another ID; every ROWS_DONE read is
/// recorded.
struct Hooked {
    sim: SimAccelerator<Memory>,
    shared: Handle,
    /// ROWS_DONE as reported: at most one row more per read, never ahead
    /// of the rows that landed (`None`: no lag).
    lagged: Option<u16>,
    stall_frames: bool,
    id: Option<u32>,
    /// FRAME_CONTROL writes with the abort bit.
    aborts: u32,
    /// Aborts are ignored: a stalled frame stays busy (a port left in
    /// reset, a wedged design).
    deaf_to_aborts: bool,
}

impl RegisterPort for Hooked {
    fn read(&mut self, csr: Csr) -> u32 {
        let value = self.sim.read(csr);
        match csr {
            Csr::Id => self.id.unwrap_or(value),
            Csr::RowsDone => {
                let rows = match &mut self.lagged {
                    Some(lagged) => {
                        *lagged = (*lagged + 1).min(value as u16);
                        *lagged
                    }
                    None => value as u16,
                };
                self.shared.borrow_mut().rows_done_reads.push(rows);
                u32::from(rows)
            }
            // Done only once the lagging counter caught up.
            Csr::FrameStatus => match self.lagged {
                Some(lagged) if lagged < 360 => value & !FRAME_STATUS_DONE,
                _ => value,
            },
            _ => value,
        }
    }

    fn write(&mut self, csr: Csr, value: u32) {
        if let Csr::FrameControl = csr {
            if let Some(lagged) = &mut self.lagged {
                *lagged = 0;
            }
        }
        if csr == Csr::FrameControl && value & FRAME_CONTROL_ABORT != 0 {
            self.aborts += 1;
            if self.deaf_to_aborts {
                return;
            }
            // A stalled frame still obeys an abort.
            self.sim.set_fault(None);
        }
        self.sim.write(csr, value);
        if csr == Csr::FrameControl && value & FRAME_CONTROL_START != 0 && self.stall_frames {
            self.sim.set_fault(Some(Fault::StuckBusy));
        }
    }

    fn read_line(&mut self, out: &mut [u32; 480]) {
        self.sim.read_line(out)
    }
}

struct Bench {
    accel: Accelerator<Hooked, CountingDelay>,
    mem: Memory,
    shared: Handle,
    delay: CountingDelay,
}

impl Bench {
    fn new() -> Bench {
        let shared: Handle =
            Rc::new(RefCell::new(Shared { bytes: vec![0xa5; SLOTS * FRAME_BYTES], ..Shared::default() }));
        let mem = Memory(shared.clone());
        let sim = SimAccelerator::with_memory(mem.clone(), 2);
        let port = Hooked {
            sim,
            shared: shared.clone(),
            lagged: None,
            stall_frames: false,
            id: None,
            aborts: 0,
            deaf_to_aborts: false,
        };
        Bench {
            accel: Accelerator::new(port, CountingDelay::default(), PollTimeout::new(100, 1_000)),
            mem,
            shared,
            delay: CountingDelay::default(),
        }
    }

    fn sim(&mut self) -> &mut SimAccelerator<Memory> {
        &mut self.accel.port_mut().sim
    }

    fn run<'a>(&mut self, plan: &'a Plan<'a>) -> selftest::SelfTestReport<'a> {
        selftest::run(&mut self.accel, &mut self.mem, &mut SoftwareRenderer, &mut self.delay, plan)
    }
}

fn model_pixel(y: u16, x: u16, raw: [i32; 3]) -> u32 {
    let light = Light::from_raw(raw[0], raw[1], raw[2]).expect("plan light");
    let mut row = [0u32; WIDTH];
    model::render_row(y, &light, &mut row);
    row[usize::from(x)]
}

#[test]
fn passes_on_the_simulated_accelerator() {
    let mut b = Bench::new();
    let report = b.run(&PLAN);
    assert_eq!(report.outcome, Outcome::Pass { frame: true, pixels: PLAN.pixels() }, "{report}");
    assert_eq!(PLAN.pixels(), 19 * 480);
    let line = report.to_string();
    assert!(line.starts_with("self-test: PASS: row mode rows 0, 180, 359 at light (3072, 4096, -2048) and (1500, 2500, 700); frame mode 13 rows (0..=359)"), "{line}");
    assert!(line.ends_with("9120 pixels equal the software renderer"), "{line}");
    // Every planned row of the frame read once, in the slot, and the frame
    // finished: the accelerator is idle.
    let reads: Vec<u16> = b.shared.borrow().row_reads.iter().map(|r| r.0).collect();
    assert_eq!(reads, PLAN.frame_rows);
    assert!(!b.sim().is_busy());
    assert_eq!(b.sim().frames_started(), 1);
}

#[test]
fn a_wrong_pixel_in_a_row_mode_row_is_the_failure_reported() {
    let mut b = Bench::new();
    b.sim().set_wrong_pixel(Some((180, 77)));
    let report = b.run(&PLAN);
    let light = PLAN.row_lights[0];
    let expected = model_pixel(180, 77, light);
    let failure = report.failure().copied().expect("fails");
    assert_eq!(failure.mode, Mode::Row);
    assert_eq!(failure.light, light);
    assert_eq!(failure.problem, Problem::Mismatch { row: 180, x: 77, expected, got: expected ^ 0xff_ffff });
    assert_eq!(
        report.to_string(),
        format!(
            "self-test: FAIL: row mode, row 180, x 77: expected {expected:#08x}, got {:#08x} (light (3072, 4096, -2048))",
            expected ^ 0xff_ffff
        )
    );
    // Stopped at the first failure: no frame.
    assert_eq!(b.sim().frames_started(), 0);
}

#[test]
fn a_wrong_pixel_in_a_frame_row_is_the_failure_reported_after_the_frame_ends() {
    let mut b = Bench::new();
    // Row 270 is checked in frame mode only.
    b.sim().set_wrong_pixel(Some((270, 123)));
    let report = b.run(&PLAN);
    let expected = model_pixel(270, 123, PLAN.frame_light);
    let failure = report.failure().copied().expect("fails");
    assert_eq!(failure.mode, Mode::Frame);
    assert_eq!(failure.light, PLAN.frame_light);
    assert_eq!(failure.problem, Problem::Mismatch { row: 270, x: 123, expected, got: expected ^ 0xff_ffff });
    let line = report.to_string();
    assert!(line.starts_with("self-test: FAIL: frame mode, row 270, x 123: expected 0x"), "{line}");
    assert!(line.ends_with("(light (-5120, 6144, 1024))"), "{line}");
    // The frame was let finish: nothing writes the slot any more.
    assert!(!b.sim().is_busy());
    // No row after the failing one was compared.
    assert_eq!(b.shared.borrow().row_reads.last().map(|r| r.0), Some(270));
}

#[test]
fn a_wrong_pixel_that_row_mode_renders_too_is_not_blamed_on_the_frame_path() {
    let mut b = Bench::new();
    b.sim().set_wrong_pixel(Some((270, 123)));
    let report = b.run(&PLAN);
    let failure = report.failure().copied().expect("fails");
    assert!(!selftest::frame_path_only(&mut b.accel, &mut SoftwareRenderer, &failure));
}

#[test]
fn a_frame_that_never_lands_with_sound_rows_is_the_frame_paths_fault() {
    let mut b = Bench::new();
    b.accel.port_mut().stall_frames = true;
    let plan = Plan { frame_wait: PollTimeout::new(200, 5_000), ..PLAN };
    let failure = b.run(&plan).failure().copied().expect("fails");
    assert!(selftest::frame_path_only(&mut b.accel, &mut SoftwareRenderer, &failure));
    // A failure in row mode is never the frame path's.
    let row_failure = selftest::Failure { mode: Mode::Row, ..failure };
    assert!(!selftest::frame_path_only(&mut b.accel, &mut SoftwareRenderer, &row_failure));
}

#[test]
fn frame_rows_are_read_the_moment_a_lagging_rows_done_covers_them() {
    let mut b = Bench::new();
    b.accel.port_mut().lagged = Some(0);
    let report = b.run(&PLAN);
    assert!(report.passed(), "{report}");
    let s = b.shared.borrow();
    assert_eq!(s.row_reads.len(), PLAN.frame_rows.len());
    // The counter lags: rows landed well before ROWS_DONE said so.
    assert!(s.rows_done_reads.len() >= 360, "{} ROWS_DONE reads", s.rows_done_reads.len());
    for &(y, polls) in &s.row_reads {
        assert!(polls >= 1, "row {y} read before any ROWS_DONE read");
        let covering = s.rows_done_reads[polls - 1];
        assert!(covering > y, "row {y} read when ROWS_DONE was {covering}");
        if polls >= 2 {
            let before = s.rows_done_reads[polls - 2];
            assert!(before <= y, "row {y} read late: ROWS_DONE covered it already at {before}");
        }
    }
}

#[test]
fn a_frame_that_never_finishes_times_out_within_the_bound() {
    let mut b = Bench::new();
    b.accel.port_mut().stall_frames = true;
    let plan = Plan { frame_wait: PollTimeout::new(200, 5_000), ..PLAN };
    let report = b.run(&plan);
    let failure = report.failure().copied().expect("fails");
    assert_eq!(failure.mode, Mode::Frame);
    let Problem::FrameTimeout { rows, polls: 200, interval_ns: 5_000 } = failure.problem else { panic!("{failure:?}") };
    assert!(rows < 360);
    // 200 progress reads (two registers each), 199 waits between them.
    assert_eq!(b.shared.borrow().rows_done_reads.len(), 200);
    assert_eq!(b.delay.total_ns, 199 * 5_000);
    assert!(report.to_string().contains("frame not done after 200 polls 5000 ns apart"), "{report}");
    assert_eq!(b.accel.port().aborts, 1, "the timed-out frame is aborted");
    assert_eq!(b.accel.port_mut().sim.read(Csr::FrameStatus), FRAME_STATUS_ABORTED, "idle: the slot is free");
}

#[test]
fn a_frame_whose_abort_is_not_confirmed_keeps_its_slot_past_the_dma_stall_limit() {
    let mut b = Bench::new();
    b.accel.port_mut().stall_frames = true;
    b.accel.port_mut().deaf_to_aborts = true;
    let plan = Plan { frame_wait: PollTimeout::new(200, 5_000), ..PLAN };
    let report = b.run(&plan);
    assert!(matches!(report.failure().map(|f| f.problem), Some(Problem::FrameTimeout { .. })), "{report}");
    assert!(b.accel.port().aborts >= 1, "the abort was tried");
    assert!(report.abort_unconfirmed, "{report}");
    // The progress waits, then the stall limit's wait, in full: the slot
    // goes to the software renderer only after the DMA stopped by itself.
    assert!(b.delay.total_ns >= 199 * 5_000 + u64::from(selftest::UNCONFIRMED_ABORT_WAIT_NS), "{}", b.delay.total_ns);
    const { assert!(selftest::UNCONFIRMED_ABORT_WAIT_NS >= 2 * 2_621_440, "two stall periods at 50 MHz at least") };
    assert!(report.to_string().contains("abort was not confirmed"), "{report}");
}

#[test]
fn a_stuck_row_fails_with_the_drivers_timeout() {
    let mut b = Bench::new();
    b.sim().set_fault(Some(Fault::StuckBusy));
    let report = b.run(&PLAN);
    let failure = report.failure().copied().expect("fails");
    assert_eq!(failure.mode, Mode::Row);
    assert!(matches!(failure.problem, Problem::Driver { row: Some(0), error: Error::Timeout { .. } }), "{failure:?}");
    assert!(report
        .to_string()
        .starts_with("self-test: FAIL: row mode, row 0 (light (3072, 4096, -2048)): accelerator timed out"));
}

#[test]
fn no_accelerator_fails_the_probe() {
    let mut b = Bench::new();
    b.sim().set_fault(Some(Fault::Absent));
    let report = b.run(&PLAN);
    let failure = report.failure().copied().expect("fails");
    assert_eq!(failure.problem, Problem::Driver { row: None, error: Error::NotPresent { id: 0xffff_ffff } });
}

#[test]
fn map_version_1_is_tested_in_row_mode_only() {
    let mut b = Bench::new();
    b.accel.port_mut().id = Some(u32::from(ID_MAGIC) << 16 | 1);
    let report = b.run(&PLAN);
    assert_eq!(report.outcome, Outcome::Pass { frame: false, pixels: 6 * 480 });
    assert!(report.to_string().contains("frame mode not tested (register map version 1)"), "{report}");
    assert_eq!(b.sim().frames_started(), 0);
}
