//! The boot-time self-test (feature `services`): does the accelerator
//! compute what the model says?
//!
//! [`run`] renders a few rows in row mode ([`Plan::rows`] at each of
//! [`Plan::row_lights`]) and one whole frame in frame mode
//! ([`Plan::frame_light`], into slot [`Plan::frame_slot`] of a
//! [`FrameMemory`]) and compares them with a reference row renderer (the
//! model on the CPU): every pixel of the rows, and the frame's
//! [`Plan::frame_rows`], each read the moment ROWS_DONE covers it (as the
//! frame server reads rows, so the write-completion rule is exercised on
//! silicon: docs/frame-dma.md#write-completion). Everything is bounded: rows
//! by the driver's [`PollTimeout`], the frame by
//! [`Plan::frame_wait`]. An accelerator whose map has no frame registers
//! (version 1) is tested in row mode only.
//!
//! The outcome is a [`SelfTestReport`] whose `Display` is the one log line:
//! `self-test: PASS ...` (what was checked) or `self-test: FAIL ...` (the
//! first differing pixel: mode, row, x, expected, got, light; or the
//! driver's error).
//!
//! # Cost on the board
//!
//! [`PLAN`] checks 19 rows (3 rows at 2 lights in row mode, 13 rows of the
//! frame) = 9,120 pixels. The reference renderer costs about 185 M
//! instructions a frame (`cargo xtask bench-fw`, guest instructions), 1,070
//! a pixel: 9.8 M instructions, 10.6 ms on the 925 MHz A9 at 1 instruction
//! a cycle, 17.4 ms at the board cost model's 800 MHz and IPC 0.7. The
//! accelerator's share is small beside it: 6 rows in row mode, about 27 us
//! each with the line-buffer read (docs/frame-dma.md's row-mode bridge
//! figures), and one frame, 173,739 cycles at 50 MHz = 3.5 ms, during which
//! the CPU already renders the reference rows of the rows that landed (the
//! frame's 13 reference rows take about 7 ms, so the CPU is the bound);
//! 13 x 45 cache lines invalidated, well under 0.1 ms. About 11 to 18 ms in
//! all: far under the second allowed. A failing accelerator costs at most
//! the driver's poll bound per row (10 ms) or [`Plan::frame_wait`] (0.5 s)
//! for the frame, plus the reference rows checked before.

use core::convert::Infallible;
use core::fmt;

use embedded_hal::delay::DelayNs;
use model::{row_to_rgb888, Light, ROW_BYTES, WIDTH};
use rt_services::{FrameMemory, RowSource};

use crate::driver::{Accelerator, Error, PollTimeout};
use crate::map::{FABRIC_HZ, FRAME_STALL_CYCLES, LINE_WORDS, ROWS};
use crate::port::RegisterPort;

/// What the self-test renders and checks.
#[derive(Clone, Copy, Debug)]
pub struct Plan<'a> {
    /// Rows rendered in row mode, each at every light of
    /// [`row_lights`](Self::row_lights).
    pub rows: &'a [u16],
    /// Lights of the row-mode rows (raw Q13.10 `[x, y, z]`).
    pub row_lights: &'a [[i32; 3]],
    /// The light of the frame-mode frame.
    pub frame_light: [i32; 3],
    /// Rows of the frame compared (each once ROWS_DONE covers it); the
    /// first and the last belong in it.
    pub frame_rows: &'a [u16],
    /// The slot of the frame memory the frame is rendered into.
    pub frame_slot: usize,
    /// How often, and how far apart, frame progress is read before the
    /// frame counts as timed out.
    pub frame_wait: PollTimeout,
}

/// The boot self-test: rows 0, 180 and 359 in row mode at two lights (one
/// with integer, one with fractional components), and rows 0, 30, ..., 330,
/// 359 of a frame at a third, in slot 0. The frame may take 0.5 s
/// (50,000 polls 10 us apart) against the FPGA's 3.5 ms.
pub const PLAN: Plan<'static> = Plan {
    rows: &[0, 180, 359],
    row_lights: &[[3 << 10, 4 << 10, -(2 << 10)], [1500, 2500, 700]],
    frame_light: [-(5 << 10), 6 << 10, 1 << 10],
    frame_rows: &[0, 30, 60, 90, 120, 150, 180, 210, 240, 270, 300, 330, 359],
    frame_slot: 0,
    frame_wait: PollTimeout::new(50_000, 10_000),
};

impl Plan<'_> {
    /// Pixels compared when every check runs (row mode and frame mode).
    pub fn pixels(&self) -> usize {
        (self.rows.len() * self.row_lights.len() + self.frame_rows.len()) * WIDTH
    }
}

/// Which half of the self-test.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Mode {
    /// A row per start, read from the line buffer.
    Row,
    /// A whole frame by DMA into memory.
    Frame,
}

impl fmt::Display for Mode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Mode::Row => "row mode",
            Mode::Frame => "frame mode",
        })
    }
}

/// What went wrong.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Problem {
    /// The first pixel that differs from the reference.
    Mismatch {
        /// Row.
        row: u16,
        /// Column.
        x: u16,
        /// The reference's `0x00RRGGBB`.
        expected: u32,
        /// The accelerator's `0x00RRGGBB` (in row mode the raw line-buffer
        /// word).
        got: u32,
    },
    /// The driver failed (timeout, bus fault, DMA error, no ray tracer).
    Driver {
        /// The row in row mode; none in frame mode or for the probe.
        row: Option<u16>,
        /// The driver's error.
        error: Error,
    },
    /// The frame was not done within [`Plan::frame_wait`].
    FrameTimeout {
        /// ROWS_DONE at the last read.
        rows: u16,
        /// Frame progress reads made.
        polls: u32,
        /// Their spacing in nanoseconds.
        interval_ns: u32,
    },
    /// The frame reported done with rows the self-test never saw covered.
    FrameIncomplete {
        /// ROWS_DONE when done was seen.
        rows: u16,
    },
    /// A light of the plan is not a valid Q13.10 light.
    BadLight,
}

/// A failed self-test: where, at which light, and what.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Failure {
    /// Row or frame mode.
    pub mode: Mode,
    /// The light (raw Q13.10).
    pub light: [i32; 3],
    /// What went wrong.
    pub problem: Problem,
}

/// The self-test's outcome.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Outcome {
    /// Every pixel compared equal.
    Pass {
        /// Whether the frame-mode half ran (no: map version 1).
        frame: bool,
        /// Pixels compared.
        pixels: usize,
    },
    /// The first failure.
    Fail(Failure),
}

/// The self-test's result with its plan; `Display` is the log line.
#[derive(Clone, Copy, Debug)]
pub struct SelfTestReport<'a> {
    /// What was planned.
    pub plan: &'a Plan<'a>,
    /// What happened.
    pub outcome: Outcome,
    /// Whether the frame half's abort went unconfirmed (busy never
    /// cleared): the test then waited [`UNCONFIRMED_ABORT_WAIT_NS`], past
    /// the frame DMA's own stall limit, before returning.
    pub abort_unconfirmed: bool,
}

/// How long the self-test waits after an abort that was not confirmed
/// before it gives the frame's slot back: the frame DMA stops by itself
/// within two stall periods of its last transfer (register map, "Stall
/// limit": `2 * FRAME_STALL_CYCLES` fabric clocks), doubled for margin;
/// about 10.5 ms at 50 MHz, once, and only on a failing accelerator.
pub const UNCONFIRMED_ABORT_WAIT_NS: u32 = (4 * FRAME_STALL_CYCLES as u64 * 1_000_000_000 / FABRIC_HZ as u64) as u32;

impl SelfTestReport<'_> {
    /// Whether the accelerator passed.
    pub fn passed(&self) -> bool {
        matches!(self.outcome, Outcome::Pass { .. })
    }

    /// The failure, if it failed.
    pub fn failure(&self) -> Option<&Failure> {
        match &self.outcome {
            Outcome::Fail(f) => Some(f),
            Outcome::Pass { .. } => None,
        }
    }
}

/// `(x, y, z)`.
struct RawLight([i32; 3]);

impl fmt::Display for RawLight {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [x, y, z] = self.0;
        write!(f, "({x}, {y}, {z})")
    }
}

/// Items separated by ", ".
struct List<'a, T>(&'a [T]);

impl<T: fmt::Display> fmt::Display for List<'_, T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, item) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{item}")?;
        }
        Ok(())
    }
}

impl fmt::Display for SelfTestReport<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let plan = self.plan;
        match self.outcome {
            Outcome::Pass { frame, pixels } => {
                write!(f, "self-test: PASS: row mode rows {} at light", List(plan.rows))?;
                for (i, l) in plan.row_lights.iter().enumerate() {
                    write!(f, "{}{}", if i == 0 { " " } else { " and " }, RawLight(*l))?;
                }
                if frame {
                    write!(
                        f,
                        "; frame mode {} rows ({}..={}) of a frame at light {}, each read once ROWS_DONE covered it",
                        plan.frame_rows.len(),
                        plan.frame_rows.iter().min().unwrap_or(&0),
                        plan.frame_rows.iter().max().unwrap_or(&0),
                        RawLight(plan.frame_light),
                    )?;
                } else {
                    f.write_str("; frame mode not tested (register map version 1)")?;
                }
                write!(f, "; {pixels} pixels equal the software renderer")
            }
            Outcome::Fail(Failure { mode, light, problem }) => {
                write!(f, "self-test: FAIL: {mode}, ")?;
                let light = RawLight(light);
                match problem {
                    Problem::Mismatch { row, x, expected, got } => {
                        write!(f, "row {row}, x {x}: expected {expected:#08x}, got {got:#08x} (light {light})")
                    }
                    Problem::Driver { row: Some(row), error } => write!(f, "row {row} (light {light}): {error}"),
                    Problem::Driver { row: None, error } => write!(f, "light {light}: {error}"),
                    Problem::FrameTimeout { rows, polls, interval_ns } => write!(
                        f,
                        "light {light}: frame not done after {polls} polls {interval_ns} ns apart (ROWS_DONE {rows})"
                    ),
                    Problem::FrameIncomplete { rows } => {
                        write!(f, "light {light}: frame done with ROWS_DONE {rows} of {ROWS}")
                    }
                    Problem::BadLight => write!(f, "light {light} is out of range"),
                }?;
                if self.abort_unconfirmed {
                    write!(
                        f,
                        "; the frame's abort was not confirmed: waited {} us, past the DMA's stall limit, before giving its slot back",
                        UNCONFIRMED_ABORT_WAIT_NS / 1000
                    )?;
                }
                Ok(())
            }
        }
    }
}

/// Run the self-test of `plan` on `accel`, the frame going to `mem`,
/// compared with `reference`; `delay` spaces the frame's progress reads.
///
/// Reads ID first ([`Accelerator::probe`]): the frame half runs only where
/// the map has the frame registers. A frame that fails a comparison is
/// still waited for (within [`Plan::frame_wait`]), so the accelerator no
/// longer writes `mem` when this returns, unless the frame timed out. The
/// first failure ends the test.
pub fn run<'a, P, D, M, R, W>(
    accel: &mut Accelerator<P, D>,
    mem: &mut M,
    reference: &mut R,
    delay: &mut W,
    plan: &'a Plan<'a>,
) -> SelfTestReport<'a>
where
    P: RegisterPort,
    D: DelayNs,
    M: FrameMemory,
    R: RowSource<Error = Infallible>,
    W: DelayNs,
{
    let mut abort_unconfirmed = false;
    let outcome = match check(accel, mem, reference, delay, plan, &mut abort_unconfirmed) {
        Ok(outcome) => outcome,
        Err(failure) => Outcome::Fail(failure),
    };
    SelfTestReport { plan, outcome, abort_unconfirmed }
}

/// After a failure in frame mode, whether the fault lies in the frame path
/// alone (the frame DMA, its port into memory: on the board most likely
/// the FPGA-to-SDRAM port left in reset) and not in the pipeline: row
/// mode renders the frame's failing row (the middle row when the frame
/// failed without a wrong pixel) at the frame's light equal to
/// `reference`. Then the accelerator may go on in row mode. `false` for
/// a failure in row mode, or when that row is wrong or fails too.
pub fn frame_path_only<P, D, R>(accel: &mut Accelerator<P, D>, reference: &mut R, failure: &Failure) -> bool
where
    P: RegisterPort,
    D: DelayNs,
    R: RowSource<Error = Infallible>,
{
    if failure.mode != Mode::Frame {
        return false;
    }
    let row = match failure.problem {
        Problem::Mismatch { row, .. } => row,
        Problem::BadLight => return false,
        _ => ROWS / 2,
    };
    let Ok(light) = light_of(Mode::Frame, failure.light) else { return false };
    let mut got = [0u32; LINE_WORDS];
    if accel.run_row(row, &light, &mut got).is_err() {
        return false;
    }
    let mut want = [0u32; WIDTH];
    reference_row(reference, row, &light, &mut want);
    got[..WIDTH] == want[..]
}

fn light_of(mode: Mode, raw: [i32; 3]) -> Result<Light, Failure> {
    Light::from_raw(raw[0], raw[1], raw[2]).map_err(|_| Failure { mode, light: raw, problem: Problem::BadLight })
}

fn check<P, D, M, R, W>(
    accel: &mut Accelerator<P, D>,
    mem: &mut M,
    reference: &mut R,
    delay: &mut W,
    plan: &Plan<'_>,
    abort_unconfirmed: &mut bool,
) -> Result<Outcome, Failure>
where
    P: RegisterPort,
    D: DelayNs,
    M: FrameMemory,
    R: RowSource<Error = Infallible>,
    W: DelayNs,
{
    let first_light = plan.row_lights.first().copied().unwrap_or(plan.frame_light);
    let caps = accel.probe().map_err(|error| Failure {
        mode: Mode::Row,
        light: first_light,
        problem: Problem::Driver { row: None, error },
    })?;
    let mut pixels = check_rows(accel, reference, plan)?;
    if !caps.frames() {
        return Ok(Outcome::Pass { frame: false, pixels });
    }
    pixels += check_frame(accel, mem, reference, delay, plan, abort_unconfirmed)?;
    Ok(Outcome::Pass { frame: true, pixels })
}

/// The frame half; pixels compared.
fn check_frame<P, D, M, R, W>(
    accel: &mut Accelerator<P, D>,
    mem: &mut M,
    reference: &mut R,
    delay: &mut W,
    plan: &Plan<'_>,
    abort_unconfirmed: &mut bool,
) -> Result<usize, Failure>
where
    P: RegisterPort,
    D: DelayNs,
    M: FrameMemory,
    R: RowSource<Error = Infallible>,
    W: DelayNs,
{
    let raw = plan.frame_light;
    let fail = |problem| Failure { mode: Mode::Frame, light: raw, problem };
    let light = light_of(Mode::Frame, raw)?;
    let slot = plan.frame_slot;
    accel.start_frame(mem.slot_address(slot), &light).map_err(|error| fail(Problem::Driver { row: None, error }))?;
    let result = compare_frame(accel, mem, reference, delay, plan, &light, fail);
    if result.is_err() {
        // A frame that failed or timed out is stopped before the slot is
        // used again. Should even the abort time out, the DMA's own stall
        // limit ends any frame that still writes within two stall periods
        // of its last transfer (register map, "Stall limit"): wait that
        // out before the slot goes to the software renderer.
        if accel.abort_frame().is_err() {
            *abort_unconfirmed = true;
            delay.delay_ns(UNCONFIRMED_ABORT_WAIT_NS);
        }
    }
    result
}

/// Compare the planned rows of the frame in progress as ROWS_DONE covers
/// them, until it is done.
fn compare_frame<P, D, M, R, W>(
    accel: &mut Accelerator<P, D>,
    mem: &mut M,
    reference: &mut R,
    delay: &mut W,
    plan: &Plan<'_>,
    light: &Light,
    fail: impl Fn(Problem) -> Failure,
) -> Result<usize, Failure>
where
    P: RegisterPort,
    D: DelayNs,
    M: FrameMemory,
    R: RowSource<Error = Infallible>,
    W: DelayNs,
{
    let slot = plan.frame_slot;
    let mut want = [0u32; WIDTH];
    let (mut want_bytes, mut got_bytes) = ([0u8; ROW_BYTES], [0u8; ROW_BYTES]);
    // Next entry of `frame_rows` to compare; the first mismatch.
    let mut next = 0;
    let mut mismatch = None;
    let mut polls = 0u32;
    loop {
        let progress = accel.frame_progress().map_err(|error| fail(Problem::Driver { row: None, error }))?;
        // Compare every planned row the counter now covers, and only those.
        while let Some(&row) = plan.frame_rows.get(next).filter(|&&row| row < progress.rows && mismatch.is_none()) {
            mem.read_row(slot, row, 0, &mut got_bytes);
            reference_row(reference, row, light, &mut want);
            row_to_rgb888(&want, &mut want_bytes);
            if let Some(x) = (0..WIDTH).find(|&x| got_bytes[3 * x..3 * x + 3] != want_bytes[3 * x..3 * x + 3]) {
                let rgb = |b: &[u8]| u32::from(b[0]) << 16 | u32::from(b[1]) << 8 | u32::from(b[2]);
                mismatch = Some(Problem::Mismatch {
                    row,
                    x: x as u16,
                    expected: rgb(&want_bytes[3 * x..]),
                    got: rgb(&got_bytes[3 * x..]),
                });
            }
            next += 1;
        }
        if progress.done {
            // The accelerator no longer writes the slot.
            if let Some(problem) = mismatch {
                return Err(fail(problem));
            }
            if next < plan.frame_rows.len() {
                return Err(fail(Problem::FrameIncomplete { rows: progress.rows }));
            }
            return Ok(plan.frame_rows.len() * WIDTH);
        }
        polls += 1;
        if polls >= plan.frame_wait.max_polls() {
            return Err(fail(Problem::FrameTimeout {
                rows: progress.rows,
                polls,
                interval_ns: plan.frame_wait.poll_interval_ns(),
            }));
        }
        delay.delay_ns(plan.frame_wait.poll_interval_ns());
    }
}

/// The row-mode half of the self-test alone: [`Plan::rows`] at each of
/// [`Plan::row_lights`] compared with `reference`; the pixels compared, or
/// the first failure. The frame registers are never touched, so it suits a
/// host whose frame DMA has nowhere safe to write (hps-linux under Linux).
/// Call [`Accelerator::probe`] first.
pub fn check_rows<P, D, R>(accel: &mut Accelerator<P, D>, reference: &mut R, plan: &Plan<'_>) -> Result<usize, Failure>
where
    P: RegisterPort,
    D: DelayNs,
    R: RowSource<Error = Infallible>,
{
    let mut want = [0u32; WIDTH];
    let mut got = [0u32; LINE_WORDS];
    let mut pixels = 0;
    for &raw in plan.row_lights {
        let light = light_of(Mode::Row, raw)?;
        for &row in plan.rows {
            let fail = |problem| Failure { mode: Mode::Row, light: raw, problem };
            accel.run_row(row, &light, &mut got).map_err(|error| fail(Problem::Driver { row: Some(row), error }))?;
            reference_row(reference, row, &light, &mut want);
            if let Some(x) = (0..WIDTH).find(|&x| got[x] != want[x]) {
                return Err(fail(Problem::Mismatch { row, x: x as u16, expected: want[x], got: got[x] }));
            }
            pixels += WIDTH;
        }
    }
    Ok(pixels)
}

fn reference_row<R: RowSource<Error = Infallible>>(reference: &mut R, y: u16, light: &Light, out: &mut [u32; WIDTH]) {
    match reference.render_row(y, light, out) {
        Ok(()) => {}
        Err(never) => match never {},
    }
}
