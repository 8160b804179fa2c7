//! Engines around engines: [`FallbackEngine`] renders with a primary (the
//! FPGA) and falls back to a second (the CPU) where it fails, switching a
//! wedged primary off; [`Watchdog`] fails a frame that stops landing rows.

use core::fmt;

use model::Light;

use super::ring::{FrameEngine, FrameMemory};
use super::ROWS;

/// An engine used for a frame: the primary or the fallback.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Using {
    Primary,
    Fallback,
}

/// A failure of [`FallbackEngine`]'s primary or fallback engine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EngineError<P, F> {
    /// The primary engine failed the frame.
    Primary(P),
    /// The fallback engine failed the frame.
    Fallback(F),
}

impl<P: fmt::Display, F: fmt::Display> fmt::Display for EngineError<P, F> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EngineError::Primary(e) => fmt::Display::fmt(e, f),
            EngineError::Fallback(e) => write!(f, "fallback renderer: {e}"),
        }
    }
}

/// Frames from a primary engine (the FPGA's frame DMA) with a fallback (the
/// model on the CPU): a frame the primary cannot start is rendered by the
/// fallback; a frame that fails under way fails (its client sees the
/// connection close, not a wrong frame). After
/// [`WEDGED_AFTER`](crate::frames::fallback::WEDGED_AFTER) failed frames in a row
/// the primary is switched off for good.
pub struct FallbackEngine<P, F> {
    /// Kept after it is switched off, to stop a frame it may still write.
    primary: Option<P>,
    active: bool,
    fallback: F,
    using: Using,
    consecutive: u32,
    switched_off: bool,
}

impl<P, F> FallbackEngine<P, F> {
    /// `primary` first (none: the fallback only), `fallback` where it fails.
    pub fn new(primary: Option<P>, fallback: F) -> FallbackEngine<P, F> {
        let active = primary.is_some();
        FallbackEngine { primary, active, fallback, using: Using::Fallback, consecutive: 0, switched_off: false }
    }

    /// Whether the primary engine is still in use.
    pub fn primary_active(&self) -> bool {
        self.active
    }

    /// The primary engine, while it is in use.
    pub fn primary(&mut self) -> Option<&mut P> {
        self.primary.as_mut().filter(|_| self.active)
    }

    /// The primary engine, switched off or not (its device may have more
    /// than the frames to offer: a display, board I/O).
    pub fn primary_kept(&mut self) -> Option<&mut P> {
        self.primary.as_mut()
    }

    /// The fallback engine.
    pub fn fallback(&mut self) -> &mut F {
        &mut self.fallback
    }

    /// Stop using the primary from now on, keeping it (its device may
    /// have more than frames to offer: board I/O), without the
    /// switch-off event (a caller's own decision, logged by it).
    pub fn keep_primary_off(&mut self) {
        self.active = false;
    }

    /// `true` once, right after the primary was switched off.
    pub fn take_switched_off(&mut self) -> bool {
        core::mem::take(&mut self.switched_off)
    }

    fn failed(&mut self) {
        self.consecutive += 1;
        if self.consecutive >= crate::frames::fallback::WEDGED_AFTER {
            self.switch_off();
        }
    }

    fn switch_off(&mut self) {
        if self.active {
            self.active = false;
            self.switched_off = true;
        }
    }
}

impl<M: FrameMemory, P: FrameEngine<M>, F: FrameEngine<M>> FrameEngine<M> for FallbackEngine<P, F> {
    type Error = EngineError<P::Error, F::Error>;

    fn start(&mut self, mem: &mut M, slot: usize, light: &Light) -> Result<(), Self::Error> {
        if let Some(p) = self.primary.as_mut().filter(|_| self.active) {
            match p.start(mem, slot, light) {
                Ok(()) => {
                    self.using = Using::Primary;
                    return Ok(());
                }
                Err(_) => self.failed(),
            }
        }
        self.using = Using::Fallback;
        self.fallback.start(mem, slot, light).map_err(EngineError::Fallback)
    }

    fn progress(&mut self, mem: &mut M) -> Result<u16, Self::Error> {
        match (self.using, &mut self.primary) {
            (Using::Primary, Some(p)) => match p.progress(mem) {
                Ok(rows) => {
                    if rows >= ROWS {
                        self.consecutive = 0;
                    }
                    Ok(rows)
                }
                Err(e) => {
                    self.failed();
                    Err(EngineError::Primary(e))
                }
            },
            _ => self.fallback.progress(mem).map_err(EngineError::Fallback),
        }
    }

    /// Stops the primary (switched off or not: a frame it failed may still
    /// be writing) and, if it rendered the last frame, the fallback. A
    /// primary that cannot confirm it stopped is switched off at once.
    fn abort(&mut self, mem: &mut M) -> Result<(), Self::Error> {
        if let Some(p) = &mut self.primary {
            if let Err(e) = p.abort(mem) {
                self.switch_off();
                return Err(EngineError::Primary(e));
            }
        }
        match self.using {
            Using::Primary => Ok(()),
            Using::Fallback => self.fallback.abort(mem).map_err(EngineError::Fallback),
        }
    }
}

/// An engine error, or a frame that stopped making progress.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WatchdogError<E> {
    /// The engine reported an error.
    Engine(E),
    /// No new row landed within the watchdog's limit.
    Stalled {
        /// Rows that had landed.
        rows: u16,
    },
}

impl<E: fmt::Display> fmt::Display for WatchdogError<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WatchdogError::Engine(e) => fmt::Display::fmt(e, f),
            WatchdogError::Stalled { rows } => write!(f, "frame stalled after {rows} rows"),
        }
    }
}

/// An engine whose frames must keep landing rows: no new row for `limit`
/// of `clock` time fails the frame instead of leaving its client waiting.
/// The clock is read only when a poll finds no new row (the stall is timed
/// from the first such poll, at most one poll interval after the last
/// row): a frame that keeps landing rows costs no clock reads.
pub struct Watchdog<E, C> {
    engine: E,
    clock: C,
    limit: core::time::Duration,
    rows: u16,
    /// When the rows stopped moving (`None`: they moved at the last poll).
    since: Option<crate::time::Instant>,
}

impl<E, C: FnMut() -> crate::time::Instant> Watchdog<E, C> {
    /// Watch `engine` with `clock`, allowing `limit` between rows.
    pub fn new(engine: E, mut clock: C, limit: core::time::Duration) -> Watchdog<E, C> {
        let since = Some(clock());
        Watchdog { engine, clock, limit, rows: 0, since }
    }

    /// The engine.
    pub fn engine(&mut self) -> &mut E {
        &mut self.engine
    }
}

impl<M: FrameMemory, E: FrameEngine<M>, C: FnMut() -> crate::time::Instant> FrameEngine<M> for Watchdog<E, C> {
    type Error = WatchdogError<E::Error>;

    fn start(&mut self, mem: &mut M, slot: usize, light: &Light) -> Result<(), Self::Error> {
        self.rows = 0;
        self.since = Some((self.clock)());
        self.engine.start(mem, slot, light).map_err(WatchdogError::Engine)
    }

    fn progress(&mut self, mem: &mut M) -> Result<u16, Self::Error> {
        let rows = self.engine.progress(mem).map_err(WatchdogError::Engine)?;
        if rows != self.rows {
            self.rows = rows;
            self.since = None;
        } else if rows < ROWS {
            let now = (self.clock)();
            match self.since {
                None => self.since = Some(now),
                Some(t) if now.saturating_duration_since(t) > self.limit => {
                    return Err(WatchdogError::Stalled { rows });
                }
                Some(_) => {}
            }
        }
        Ok(rows)
    }

    fn abort(&mut self, mem: &mut M) -> Result<(), Self::Error> {
        self.engine.abort(mem).map_err(WatchdogError::Engine)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frames::ring::tests::{light, Dma};
    use crate::frames::rows::SoftwareRenderer;
    use crate::frames::{FrameRing, FrameSource, RowEngine, SliceMemory};
    use model::{FRAME_BYTES, ROW_BYTES};

    /// An engine whose frames never land a row; it stops writing on an
    /// abort only while `stoppable`.
    struct Stalling {
        writing: bool,
        stoppable: bool,
        aborts: u32,
    }

    impl FrameEngine<SliceMemory<'_>> for Stalling {
        type Error = &'static str;
        fn start(&mut self, _: &mut SliceMemory<'_>, _: usize, _: &Light) -> Result<(), &'static str> {
            self.writing = true;
            Ok(())
        }
        fn progress(&mut self, _: &mut SliceMemory<'_>) -> Result<u16, &'static str> {
            Ok(0)
        }
        fn abort(&mut self, _: &mut SliceMemory<'_>) -> Result<(), &'static str> {
            self.aborts += 1;
            if self.stoppable {
                self.writing = false;
                Ok(())
            } else {
                Err("still busy")
            }
        }
    }

    fn stalling_ring<'m>(
        mem: &'m mut [u8],
        stoppable: bool,
        now: &'m core::cell::Cell<u64>,
    ) -> FrameRing<SliceMemory<'m>, Watchdog<Stalling, impl FnMut() -> crate::time::Instant + 'm>, 1> {
        let clock = move || crate::time::Instant::from_millis(now.get());
        let engine = Watchdog::new(
            Stalling { writing: false, stoppable, aborts: 0 },
            clock,
            core::time::Duration::from_millis(500),
        );
        FrameRing::new(SliceMemory::new(0, mem), engine)
    }

    #[test]
    fn a_failing_primary_engine_falls_back_and_is_switched_off_after_three_frames() {
        let mut mem = vec![0u8; FRAME_BYTES];
        let bad = light(1.0);
        let dma = Dma { started: vec![], rows: 0, step: 360, fail_light: Some(bad), current: None };
        let engine = FallbackEngine::new(Some(dma), RowEngine::new(SoftwareRenderer));
        let mut ring = FrameRing::<_, _, 1>::new(SliceMemory::new(0, &mut mem), engine);
        for _ in 0..3 {
            let f = ring.begin(&bad).unwrap().unwrap();
            assert!(matches!(ring.rows_ready(f), Err(EngineError::Primary("bus error"))));
            ring.end(f);
        }
        assert!(!ring.engine().primary_active(), "wedged: off");
        assert!(ring.engine().take_switched_off());
        assert!(!ring.engine().take_switched_off(), "reported once");
        // The software engine renders from now on, right.
        let f = ring.begin(&bad).unwrap().unwrap();
        while ring.rows_ready(f).unwrap() < ROWS {}
        let mut row = vec![0u8; ROW_BYTES];
        ring.copy_row(f, 200, 0, &mut row);
        assert_eq!(row, model::render_frame(&bad)[200 * ROW_BYTES..201 * ROW_BYTES]);
    }

    #[test]
    fn a_stalled_frame_fails_after_the_watchdog_limit() {
        use core::cell::Cell;
        let now = Cell::new(0u64);
        let clock = || crate::time::Instant::from_millis(now.get());
        let dma = Dma { started: vec![], rows: 0, step: 0, fail_light: None, current: None };
        let mut mem = vec![0u8; FRAME_BYTES];
        let engine = Watchdog::new(dma, clock, core::time::Duration::from_millis(500));
        let mut ring = FrameRing::<_, _, 1>::new(SliceMemory::new(0, &mut mem), engine);
        let f = ring.begin(&light(2.0)).unwrap().unwrap();
        now.set(400);
        assert_eq!(ring.rows_ready(f), Ok(0), "within the limit");
        now.set(501);
        assert_eq!(ring.rows_ready(f), Err(WatchdogError::Stalled { rows: 0 }));
    }

    #[test]
    fn the_watchdog_reads_its_clock_only_when_no_row_landed_and_times_a_stall_from_then() {
        use core::cell::Cell;
        let (now, reads) = (Cell::new(0u64), Cell::new(0u32));
        let clock = || {
            reads.set(reads.get() + 1);
            crate::time::Instant::from_millis(now.get())
        };
        let dma = Dma { started: vec![], rows: 0, step: 4, fail_light: None, current: None };
        let mut engine = Watchdog::new(dma, clock, core::time::Duration::from_millis(500));
        let mut mem = vec![0u8; FRAME_BYTES];
        let mut mem = SliceMemory::new(0, &mut mem);
        engine.start(&mut mem, 0, &light(2.0)).unwrap();
        let at_start = reads.get();
        for i in 1..=10 {
            assert_eq!(engine.progress(&mut mem), Ok(4 * i));
        }
        assert_eq!(reads.get(), at_start, "rows kept landing: no clock read");
        // The rows stop at 40: the stall counts from the first poll that
        // saw none, not from the start 10 s earlier.
        engine.engine().step = 0;
        now.set(10_000);
        assert_eq!(engine.progress(&mut mem), Ok(40));
        now.set(10_500);
        assert_eq!(engine.progress(&mut mem), Ok(40), "500 ms: within the limit");
        now.set(10_501);
        assert_eq!(engine.progress(&mut mem), Err(WatchdogError::Stalled { rows: 40 }));
    }

    #[test]
    fn the_watchdog_aborts_a_stalled_frame_before_its_slot_is_reused() {
        let now = core::cell::Cell::new(0u64);
        let mut mem = vec![0u8; FRAME_BYTES];
        let mut ring = stalling_ring(&mut mem, true, &now);
        let f = ring.begin(&light(2.0)).unwrap().unwrap();
        now.set(501);
        assert_eq!(ring.rows_ready(f), Err(WatchdogError::Stalled { rows: 0 }));
        assert_eq!(ring.engine().engine().aborts, 1, "aborted when it failed");
        assert!(!ring.engine().engine().writing, "stopped before the slot is released");
        ring.end(f);
        assert_eq!(ring.free_slots(), 1);
        assert_eq!(ring.quarantined_slots(), 0);
    }

    #[test]
    fn a_frame_that_cannot_be_stopped_keeps_its_slot_until_an_abort_succeeds() {
        let now = core::cell::Cell::new(0u64);
        let mut mem = vec![0u8; FRAME_BYTES];
        let mut ring = stalling_ring(&mut mem, false, &now);
        let f = ring.begin(&light(2.0)).unwrap().unwrap();
        now.set(501);
        assert_eq!(ring.rows_ready(f), Err(WatchdogError::Stalled { rows: 0 }));
        assert_eq!(ring.rows_ready(f), Err(WatchdogError::Stalled { rows: 0 }), "the error stays");
        ring.end(f);
        assert_eq!((ring.free_slots(), ring.quarantined_slots()), (0, 1), "still written: out of use");
        assert_eq!(ring.begin(&light(3.0)).unwrap(), None, "no slot while the engine may write it");
        assert_eq!(ring.engine().engine().aborts, 2, "tried again when a slot was wanted");
        ring.engine().engine().stoppable = true;
        assert_eq!(ring.begin(&light(3.0)).unwrap(), Some(f), "back once the engine stopped");
        assert_eq!(ring.engine().engine().aborts, 3);
    }

    #[test]
    fn a_primary_that_cannot_stop_its_frame_is_switched_off_at_once() {
        let mut mem = vec![0u8; FRAME_BYTES];
        let stuck = Stalling { writing: false, stoppable: false, aborts: 0 };
        let engine = FallbackEngine::new(Some(stuck), RowEngine::new(SoftwareRenderer));
        let mut ring = FrameRing::<_, _, 1>::new(SliceMemory::new(0, &mut mem), engine);
        let mut m = vec![0u8; FRAME_BYTES];
        let mut scratch = SliceMemory::new(0, &mut m);
        let f = ring.begin(&light(1.0)).unwrap().unwrap();
        assert!(ring.engine().primary_active());
        assert!(FrameEngine::abort(ring.engine(), &mut scratch).is_err());
        assert!(!ring.engine().primary_active(), "a device that cannot stop is wedged");
        assert!(ring.engine().take_switched_off());
        ring.end(f);
    }
}
