//! Where the frames a session sends come from.
//!
//! A [`FrameSource`] hands out frames, reports how many of a frame's rows can
//! be read, and copies row bytes straight into the transport's buffer (the
//! socket's), so a row is copied by the CPU once. Two sources:
//!
//! * [`RowFrames`] (row mode): renders one row at a time with a
//!   [`RowSource`] (the model, the FPGA's row registers) into a single row
//!   buffer per frame. A session's rows are rendered as it sends them.
//! * [`FrameRing`] (frame mode): whole frames in `SLOTS` slots of a
//!   [`FrameMemory`] (the FPGA-to-SDRAM frame buffers on the board), filled
//!   by a [`FrameEngine`] (the FPGA's frame DMA, or a software renderer that
//!   writes the same memory) one frame after another; rows become readable
//!   as the engine's rows-done counter covers them.

use core::fmt;

use model::{row_to_rgb888, Light, FRAME_BYTES, HEIGHT, ROW_BYTES, WIDTH};

use crate::rows::RowSource;

/// Rows of a frame.
pub const ROWS: u16 = HEIGHT as u16;

/// Frames for sessions.
pub trait FrameSource {
    /// A frame a session holds.
    type Frame: Copy + Eq + fmt::Debug;
    /// Why a frame could not be rendered.
    type Error: fmt::Display + fmt::Debug;

    /// Begin a frame for `light`; `Ok(None)` while no slot is free (ask
    /// again later).
    fn begin(&mut self, light: &Light) -> Result<Option<Self::Frame>, Self::Error>;

    /// Rows `0..n` of `frame` that can be copied now. May do work (render a
    /// row, read the accelerator's counter); never blocks for long.
    fn rows_ready(&mut self, frame: Self::Frame) -> Result<u16, Self::Error>;

    /// Copy bytes `offset..` of row `y` of `frame` into `out` (as many as fit
    /// and the row has); returns how many. Only for rows below what
    /// [`rows_ready`](Self::rows_ready) reported.
    fn copy_row(&mut self, frame: Self::Frame, y: u16, offset: usize, out: &mut [u8]) -> usize;

    /// The session is done with `frame` (sent, or abandoned): its slot may
    /// be reused.
    fn end(&mut self, frame: Self::Frame);
}

// ---- Row mode -------------------------------------------------------------------

/// One frame of [`RowFrames`]: its light and its newest row.
struct RowSlot {
    light: Light,
    rendered: u16,
    bytes: [u8; ROW_BYTES],
}

/// Row mode: frames rendered a row at a time by `R`, each holding only its
/// newest row (1,440 bytes), for up to `N` frames at once.
pub struct RowFrames<R, const N: usize> {
    rows: R,
    slots: [Option<RowSlot>; N],
    words: [u32; WIDTH],
}

impl<R: RowSource, const N: usize> RowFrames<R, N> {
    /// Frames rendered by `rows`.
    pub fn new(rows: R) -> RowFrames<R, N> {
        RowFrames { rows, slots: [const { None }; N], words: [0; WIDTH] }
    }

    /// The row source.
    pub fn rows(&mut self) -> &mut R {
        &mut self.rows
    }
}

impl<R: RowSource, const N: usize> FrameSource for RowFrames<R, N>
where
    R::Error: fmt::Display,
{
    type Frame = usize;
    type Error = R::Error;

    fn begin(&mut self, light: &Light) -> Result<Option<usize>, R::Error> {
        let Some(i) = self.slots.iter().position(Option::is_none) else {
            return Ok(None);
        };
        self.slots[i] = Some(RowSlot { light: *light, rendered: 0, bytes: [0; ROW_BYTES] });
        Ok(Some(i))
    }

    /// Renders the next row when asked: a session asks once it has sent
    /// every row rendered so far, so the single row buffer is free again.
    fn rows_ready(&mut self, frame: usize) -> Result<u16, R::Error> {
        let Some(slot) = self.slots.get_mut(frame).and_then(Option::as_mut) else {
            return Ok(0);
        };
        if slot.rendered < ROWS {
            self.rows.render_row(slot.rendered, &slot.light, &mut self.words)?;
            row_to_rgb888(&self.words, &mut slot.bytes);
            slot.rendered += 1;
        }
        Ok(slot.rendered)
    }

    fn copy_row(&mut self, frame: usize, y: u16, offset: usize, out: &mut [u8]) -> usize {
        match self.slots.get(frame).and_then(Option::as_ref) {
            Some(slot) if slot.rendered == y + 1 => copy_from(&slot.bytes, offset, out),
            _ => 0,
        }
    }

    fn end(&mut self, frame: usize) {
        if let Some(s) = self.slots.get_mut(frame) {
            *s = None;
        }
    }
}

/// Copy `row[offset..]` into the front of `out`; bytes copied.
fn copy_from(row: &[u8], offset: usize, out: &mut [u8]) -> usize {
    let src = row.get(offset..).unwrap_or(&[]);
    let n = src.len().min(out.len());
    out[..n].copy_from_slice(&src[..n]);
    n
}

// ---- Frame mode -----------------------------------------------------------------

/// The memory frame slots live in.
pub trait FrameMemory {
    /// Bus address of slot `slot`, for an engine that writes by DMA.
    fn slot_address(&self, slot: usize) -> u32;

    /// Copy bytes `offset..offset + out.len()` of row `y` of `slot` into
    /// `out`. The engine's counter covered the row; an implementation on
    /// real memory issues the barrier that orders this read after the
    /// counter's.
    fn read_row(&mut self, slot: usize, y: u16, offset: usize, out: &mut [u8]);

    /// Write a whole row of `slot` (for a software engine).
    fn write_row(&mut self, slot: usize, y: u16, row: &[u8; ROW_BYTES]);
}

/// What renders frames into a [`FrameMemory`], one at a time.
pub trait FrameEngine<M: FrameMemory> {
    /// Why a frame failed.
    type Error: fmt::Display + fmt::Debug + Copy;

    /// Start rendering `light` into `slot`; the previous frame is finished.
    fn start(&mut self, mem: &mut M, slot: usize, light: &Light) -> Result<(), Self::Error>;

    /// Rows `0..n` of the frame in progress that have landed. May do work
    /// (a software engine renders a row per call); never blocks for long.
    fn progress(&mut self, mem: &mut M) -> Result<u16, Self::Error>;

    /// Stop the frame in progress after a failure and return once nothing
    /// more of it can land in memory; an error if that cannot be confirmed
    /// (the slot must then stay out of use). Bounded. An engine that writes
    /// nothing on its own (a software renderer) has nothing to stop.
    fn abort(&mut self, _mem: &mut M) -> Result<(), Self::Error> {
        Ok(())
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum SlotState<E> {
    Free,
    /// Waiting for the engine.
    Queued(Light),
    /// Being rendered; `rows` landed so far.
    Rendering(u16),
    /// All rows landed.
    Ready,
    /// Released while the engine still writes it: freed when it finishes.
    Abandoned,
    /// The engine failed it (and stopped writing it); rows `0..n` had
    /// landed and may still be copied.
    Failed(E, u16),
    /// The engine failed it and could not confirm that it stopped writing:
    /// out of use until an abort succeeds. Rows `0..n` had landed (the
    /// engine writes rows in order) and may still be copied.
    Quarantined(E, u16),
    /// Released while quarantined: freed once an abort succeeds.
    Lost,
}

/// Frame mode: `SLOTS` whole frames in `M`, rendered by `E` in the order
/// they were begun.
pub struct FrameRing<M, E: FrameEngine<M>, const SLOTS: usize>
where
    M: FrameMemory,
{
    mem: M,
    engine: E,
    slots: [SlotState<E::Error>; SLOTS],
    /// Begin order of the queued slots (a slot number per entry).
    queue: heapless::Deque<usize, SLOTS>,
    rendering: Option<usize>,
    /// The light of the frame in progress.
    rendering_light: Option<Light>,
    /// Slots `begin` skips (bit `i`: slot `i`): their frame is on a
    /// display, or about to be.
    pinned: u32,
    /// Slots `begin` also skips: held by a second owner (the RTP repair
    /// windows, [`crate::camera::SlotSource::set_held`]), apart from the
    /// display's pins.
    held: u32,
    /// The newest complete frame, while its slot still holds it.
    newest: Option<Completed>,
    /// Frames completed so far (wrapping).
    completed: u32,
}

/// A complete frame in a [`FrameRing`] slot: the newest one, as
/// [`FrameRing::newest_complete`] reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Completed {
    /// The slot holding it.
    pub slot: usize,
    /// Its number among the ring's completed frames (wrapping): a new
    /// number is a new frame, even in the same slot.
    pub seq: u32,
    /// The light it was rendered for.
    pub light: Light,
}

impl<M: FrameMemory, E: FrameEngine<M>, const SLOTS: usize> FrameRing<M, E, SLOTS> {
    /// A ring over `mem` rendered by `engine`, every slot free.
    pub fn new(mem: M, engine: E) -> FrameRing<M, E, SLOTS> {
        const { assert!(SLOTS <= 32, "the pin set is a 32-bit mask") };
        FrameRing {
            mem,
            engine,
            slots: [SlotState::Free; SLOTS],
            queue: heapless::Deque::new(),
            rendering: None,
            rendering_light: None,
            pinned: 0,
            held: 0,
            newest: None,
            completed: 0,
        }
    }

    /// The newest frame all of whose rows landed, whichever request it
    /// was rendered for, as long as its slot still holds it (its session
    /// may have ended: a slot is reused only by a later `begin`, which
    /// skips pinned slots).
    pub fn newest_complete(&self) -> Option<Completed> {
        self.newest
    }

    /// Keep `slot` out of reuse (`begin` skips it) until [`unpin`]ned: its
    /// frame is on a display or about to be. Its session may still read
    /// and end it as usual. Out-of-range slots are ignored.
    ///
    /// [`unpin`]: Self::unpin
    pub fn pin(&mut self, slot: usize) {
        if slot < SLOTS {
            self.pinned |= 1 << slot;
        }
    }

    /// Let `slot` be reused again once no session holds it.
    pub fn unpin(&mut self, slot: usize) {
        if slot < SLOTS {
            self.pinned &= !(1 << slot);
        }
    }

    /// Whether `slot` is pinned.
    pub fn is_pinned(&self, slot: usize) -> bool {
        slot < SLOTS && self.pinned & (1 << slot) != 0
    }

    /// Slots held by the RTP repair windows (bit `i`: slot `i`).
    pub fn held(&self) -> u32 {
        self.held
    }

    /// Keep the slots of `mask` out of reuse as well as the pinned ones,
    /// replacing the previous mask (the RTP sender's repair windows; a
    /// frame still being sent is held by its session anyway).
    pub fn set_held(&mut self, mask: u32) {
        self.held = mask;
    }

    /// Bus address of `slot` in the ring's memory.
    pub fn slot_address(&self, slot: usize) -> u32 {
        self.mem.slot_address(slot)
    }

    /// A free slot `begin` may take: not held by a frame, not pinned.
    fn takeable(&self, slot: usize) -> bool {
        matches!(self.slots[slot], SlotState::Free) && !self.is_pinned(slot) && self.held & (1 << slot) == 0
    }

    /// The engine.
    pub fn engine(&mut self) -> &mut E {
        &mut self.engine
    }

    /// Slots neither held by a frame nor pinned (free for `begin`).
    pub fn free_slots(&self) -> usize {
        (0..SLOTS).filter(|&i| self.takeable(i)).count()
    }

    /// Slots out of use because a failed frame's engine could not confirm
    /// that it stopped writing them.
    pub fn quarantined_slots(&self) -> usize {
        self.slots.iter().filter(|s| matches!(s, SlotState::Quarantined(..) | SlotState::Lost)).count()
    }

    /// Advance the engine: progress of the frame in progress, the next
    /// queued frame started when it is done (or failed). A failed frame is
    /// aborted before its slot can be used again.
    fn pump(&mut self) {
        if let Some(slot) = self.rendering {
            let result = self.engine.progress(&mut self.mem);
            let stopped = match result {
                Ok(rows) => {
                    if let SlotState::Rendering(r) = &mut self.slots[slot] {
                        *r = rows.min(ROWS);
                    }
                    if rows < ROWS {
                        return;
                    }
                    true
                }
                Err(_) => self.engine.abort(&mut self.mem).is_ok(),
            };
            let light = self.rendering_light.take();
            if let (Ok(_), SlotState::Rendering(_) | SlotState::Abandoned, true, Some(light)) =
                (result, self.slots[slot], stopped, light)
            {
                self.completed = self.completed.wrapping_add(1);
                self.newest = Some(Completed { slot, seq: self.completed, light });
            }
            self.slots[slot] = match (result, self.slots[slot], stopped) {
                (Ok(_), SlotState::Rendering(_), _) => SlotState::Ready,
                (_, SlotState::Abandoned, true) => SlotState::Free,
                (_, SlotState::Abandoned, false) => SlotState::Lost,
                (Err(e), SlotState::Rendering(rows), true) => SlotState::Failed(e, rows),
                (Err(e), SlotState::Rendering(rows), false) => SlotState::Quarantined(e, rows),
                (Err(e), _, true) => SlotState::Failed(e, 0),
                (Err(e), _, false) => SlotState::Quarantined(e, 0),
                (Ok(_), other, _) => other,
            };
            self.rendering = None;
        }

        while let Some(slot) = self.queue.pop_front() {
            let SlotState::Queued(light) = self.slots[slot] else {
                continue;
            };
            match self.engine.start(&mut self.mem, slot, &light) {
                Ok(()) => {
                    self.slots[slot] = SlotState::Rendering(0);
                    self.rendering = Some(slot);
                    self.rendering_light = Some(light);
                    return;
                }
                Err(e) => self.slots[slot] = SlotState::Failed(e, 0),
            }
        }
    }
}

impl<M: FrameMemory, E: FrameEngine<M>, const SLOTS: usize> FrameRing<M, E, SLOTS> {
    /// Quarantined slots return once the engine, idle, confirms that
    /// nothing more lands (tried only when no slot is free).
    fn reclaim(&mut self) {
        let quarantined = self.slots.iter().any(|s| matches!(s, SlotState::Quarantined(..) | SlotState::Lost));
        if !quarantined || self.rendering.is_some() || self.engine.abort(&mut self.mem).is_err() {
            return;
        }
        for state in &mut self.slots {
            *state = match *state {
                SlotState::Quarantined(e, rows) => SlotState::Failed(e, rows),
                SlotState::Lost => SlotState::Free,
                other => other,
            };
        }
    }
}

impl<M: FrameMemory, E: FrameEngine<M>, const SLOTS: usize> FrameSource for FrameRing<M, E, SLOTS> {
    type Frame = usize;
    type Error = E::Error;

    fn begin(&mut self, light: &Light) -> Result<Option<usize>, E::Error> {
        // No slot free: advance the engine (an abandoned frame frees its
        // slot when it finishes), then try to reclaim quarantined slots.
        if !(0..SLOTS).any(|i| self.takeable(i)) {
            self.pump();
        }
        if !(0..SLOTS).any(|i| self.takeable(i)) {
            self.reclaim();
        }
        let Some(slot) = (0..SLOTS).find(|&i| self.takeable(i)) else {
            return Ok(None);
        };
        if self.newest.is_some_and(|n| n.slot == slot) {
            // Its frame is about to be overwritten.
            self.newest = None;
        }
        self.slots[slot] = SlotState::Queued(*light);
        // A free slot is in no queue entry, so there is room.
        let _ = self.queue.push_back(slot);
        if self.rendering.is_none() {
            self.pump();
        }
        Ok(Some(slot))
    }

    fn rows_ready(&mut self, frame: usize) -> Result<u16, E::Error> {
        self.pump();
        match self.slots.get(frame) {
            Some(SlotState::Rendering(rows)) => Ok(*rows),
            Some(SlotState::Ready) => Ok(ROWS),
            Some(SlotState::Failed(e, _) | SlotState::Quarantined(e, _)) => Err(*e),
            _ => Ok(0),
        }
    }

    fn copy_row(&mut self, frame: usize, y: u16, offset: usize, out: &mut [u8]) -> usize {
        let landed = match self.slots.get(frame) {
            Some(SlotState::Rendering(rows) | SlotState::Failed(_, rows) | SlotState::Quarantined(_, rows)) => {
                y < *rows
            }
            Some(SlotState::Ready) => y < ROWS,
            _ => false,
        };
        if !landed || offset >= ROW_BYTES {
            return 0;
        }
        let n = out.len().min(ROW_BYTES - offset);
        self.mem.read_row(frame, y, offset, &mut out[..n]);
        n
    }

    fn end(&mut self, frame: usize) {
        let Some(state) = self.slots.get_mut(frame) else {
            return;
        };
        *state = match state {
            SlotState::Rendering(_) => SlotState::Abandoned,
            SlotState::Quarantined(..) | SlotState::Lost => SlotState::Lost,
            _ => SlotState::Free,
        };
    }
}

/// Frame slots in a byte slice (host memory: tests, host simulations):
/// slot `i` at byte `i * FRAME_BYTES`, bus address `base` + that.
pub struct SliceMemory<'a> {
    base: u32,
    bytes: &'a mut [u8],
}

impl<'a> SliceMemory<'a> {
    /// Slots in `bytes` (whole frames only), at bus address `base`.
    pub fn new(base: u32, bytes: &'a mut [u8]) -> SliceMemory<'a> {
        SliceMemory { base, bytes }
    }
}

impl FrameMemory for SliceMemory<'_> {
    fn slot_address(&self, slot: usize) -> u32 {
        self.base.wrapping_add((slot * FRAME_BYTES) as u32)
    }

    fn read_row(&mut self, slot: usize, y: u16, offset: usize, out: &mut [u8]) {
        let at = slot * FRAME_BYTES + usize::from(y) * ROW_BYTES + offset;
        if let Some(src) = self.bytes.get(at..at + out.len()) {
            out.copy_from_slice(src);
        }
    }

    fn write_row(&mut self, slot: usize, y: u16, row: &[u8; ROW_BYTES]) {
        let at = slot * FRAME_BYTES + usize::from(y) * ROW_BYTES;
        if let Some(dst) = self.bytes.get_mut(at..at + ROW_BYTES) {
            dst.copy_from_slice(row);
        }
    }
}

/// A software frame engine: renders one row per [`FrameEngine::progress`]
/// call with `R` into the slot, so rows become readable through the same
/// counter the FPGA's frame DMA keeps.
pub struct RowEngine<R> {
    rows: R,
    job: Option<(usize, Light, u16)>,
    words: [u32; WIDTH],
    bytes: [u8; ROW_BYTES],
}

impl<R: RowSource> RowEngine<R> {
    /// An engine rendering with `rows`.
    pub fn new(rows: R) -> RowEngine<R> {
        RowEngine { rows, job: None, words: [0; WIDTH], bytes: [0; ROW_BYTES] }
    }
}

impl<R: RowSource, M: FrameMemory> FrameEngine<M> for RowEngine<R>
where
    R::Error: fmt::Display + Copy,
{
    type Error = R::Error;

    fn start(&mut self, _mem: &mut M, slot: usize, light: &Light) -> Result<(), R::Error> {
        self.job = Some((slot, *light, 0));
        Ok(())
    }

    fn progress(&mut self, mem: &mut M) -> Result<u16, R::Error> {
        let Some((slot, light, rows)) = &mut self.job else {
            return Ok(ROWS);
        };
        if *rows < ROWS {
            self.rows.render_row(*rows, light, &mut self.words)?;
            row_to_rgb888(&self.words, &mut self.bytes);
            mem.write_row(*slot, *rows, &self.bytes);
            *rows += 1;
        }
        Ok(*rows)
    }
}

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
/// [`WEDGED_AFTER`](crate::fallback::WEDGED_AFTER) failed frames in a row
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

    /// `true` once, right after the primary was switched off.
    pub fn take_switched_off(&mut self) -> bool {
        core::mem::take(&mut self.switched_off)
    }

    fn failed(&mut self) {
        self.consecutive += 1;
        if self.consecutive >= crate::fallback::WEDGED_AFTER {
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
    use crate::rows::SoftwareRenderer;

    /// An engine that lands `step` rows per progress call, failing the
    /// frame of a chosen light.
    struct Dma {
        started: Vec<usize>,
        rows: u16,
        step: u16,
        fail_light: Option<Light>,
        current: Option<Light>,
    }

    impl FrameEngine<SliceMemory<'_>> for Dma {
        type Error = &'static str;
        fn start(&mut self, _: &mut SliceMemory<'_>, slot: usize, light: &Light) -> Result<(), &'static str> {
            self.started.push(slot);
            self.rows = 0;
            self.current = Some(*light);
            Ok(())
        }
        fn progress(&mut self, _: &mut SliceMemory<'_>) -> Result<u16, &'static str> {
            if self.current == self.fail_light {
                return Err("bus error");
            }
            self.rows = (self.rows + self.step).min(ROWS);
            Ok(self.rows)
        }
    }

    fn light(x: f64) -> Light {
        Light::from_world(x, 4.0, -2.0).unwrap()
    }

    #[test]
    fn frames_render_in_begin_order_and_rows_appear_as_they_land() {
        let mut mem = vec![0u8; 3 * FRAME_BYTES];
        let dma = Dma { started: vec![], rows: 0, step: 100, fail_light: None, current: None };
        let mut ring = FrameRing::<_, _, 3>::new(SliceMemory::new(0x1000, &mut mem), dma);
        let (a, b) = (ring.begin(&light(1.0)).unwrap().unwrap(), ring.begin(&light(2.0)).unwrap().unwrap());
        assert_eq!(ring.rows_ready(b).unwrap(), 0, "queued behind a");
        assert_eq!(ring.rows_ready(a).unwrap(), 200, "a progressed on each call");
        assert_eq!(ring.rows_ready(a).unwrap(), 300);
        assert_eq!(ring.rows_ready(a).unwrap(), ROWS, "a done, b started");
        assert_eq!(ring.rows_ready(b).unwrap(), 100);
        assert_eq!(ring.engine().started, [a, b]);
        assert_eq!(ring.copy_row(b, 99, 0, &mut [0; 8]), 8);
        assert_eq!(ring.copy_row(b, 100, 0, &mut [0; 8]), 0, "a row not landed is not copied");
        assert_eq!(ring.copy_row(a, 359, ROW_BYTES - 3, &mut [0; 8]), 3, "the row's end");
    }

    #[test]
    fn a_slot_released_mid_render_is_freed_only_when_the_engine_is_done() {
        let mut mem = vec![0u8; 2 * FRAME_BYTES];
        let dma = Dma { started: vec![], rows: 0, step: 150, fail_light: None, current: None };
        let mut ring = FrameRing::<_, _, 2>::new(SliceMemory::new(0, &mut mem), dma);
        let a = ring.begin(&light(1.0)).unwrap().unwrap();
        let b = ring.begin(&light(2.0)).unwrap().unwrap();
        assert_eq!(ring.begin(&light(3.0)).unwrap(), None, "both slots taken");
        ring.end(a); // the client left while the DMA writes a
        assert_eq!(ring.free_slots(), 0, "a is still being written");
        // Asking for a slot advances the engine: a is freed once finished.
        let mut tries = 0;
        let c = loop {
            tries += 1;
            if let Some(c) = ring.begin(&light(3.0)).unwrap() {
                break c;
            }
            assert!(tries < 10, "a never freed");
        };
        assert_eq!(c, a);
        assert_eq!(ring.engine().started, [a, b], "a was freed when it finished and b started");
        assert!(ring.rows_ready(b).unwrap() < ROWS, "b still rendering: a's slot came back first");
    }

    #[test]
    fn a_failed_frame_reports_its_error_and_the_next_one_renders() {
        let mut mem = vec![0u8; 2 * FRAME_BYTES];
        let dma = Dma { started: vec![], rows: 0, step: 360, fail_light: Some(light(1.0)), current: None };
        let mut ring = FrameRing::<_, _, 2>::new(SliceMemory::new(0, &mut mem), dma);
        let a = ring.begin(&light(1.0)).unwrap().unwrap();
        let b = ring.begin(&light(2.0)).unwrap().unwrap();
        assert_eq!(ring.rows_ready(a), Err("bus error"));
        assert_eq!(ring.rows_ready(b), Ok(ROWS));
        ring.end(a);
        ring.end(b);
        assert_eq!(ring.free_slots(), 2);
    }

    #[test]
    fn the_software_engine_fills_the_slot_with_the_models_frame() {
        let mut mem = vec![0u8; FRAME_BYTES];
        let mut ring = FrameRing::<_, _, 1>::new(SliceMemory::new(0, &mut mem), RowEngine::new(SoftwareRenderer));
        let l = light(3.0);
        let f = ring.begin(&l).unwrap().unwrap();
        let mut rows = 0;
        let mut calls = 0;
        while rows < ROWS {
            rows = ring.rows_ready(f).unwrap();
            calls += 1;
        }
        assert_eq!(calls, 360, "one row per call: the main loop stays responsive");
        let mut out = vec![0u8; FRAME_BYTES];
        for y in 0..ROWS {
            ring.copy_row(f, y, 0, &mut out[usize::from(y) * ROW_BYTES..][..ROW_BYTES]);
        }
        assert!(out == model::render_frame(&l));
    }

    #[test]
    fn row_frames_hold_one_row_per_frame() {
        let mut frames = RowFrames::<SoftwareRenderer, 2>::new(SoftwareRenderer);
        let l = light(-2.0);
        let a = frames.begin(&l).unwrap().unwrap();
        assert!(frames.begin(&l).unwrap().is_some());
        assert_eq!(frames.begin(&l).unwrap(), None, "two frames at most");
        assert_eq!(frames.copy_row(a, 0, 0, &mut [0; 4]), 0, "nothing rendered yet");
        assert_eq!(frames.rows_ready(a).unwrap(), 1);
        let mut row = vec![0u8; ROW_BYTES];
        assert_eq!(frames.copy_row(a, 0, 0, &mut row), ROW_BYTES);
        assert_eq!(row, model::render_frame(&l)[..ROW_BYTES]);
        assert_eq!(frames.rows_ready(a).unwrap(), 2);
        assert_eq!(frames.copy_row(a, 0, 0, &mut row), 0, "row 0 is gone once row 1 is rendered");
        frames.end(a);
        assert!(frames.begin(&l).unwrap().is_some());
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

    #[test]
    fn the_newest_complete_frame_is_reported_and_pinned_slots_are_not_reused() {
        let mut mem = vec![0u8; 3 * FRAME_BYTES];
        let dma = Dma { started: vec![], rows: 0, step: 360, fail_light: None, current: None };
        let mut ring = FrameRing::<_, _, 3>::new(SliceMemory::new(0x1000, &mut mem), dma);
        assert_eq!(ring.newest_complete(), None);
        let a = ring.begin(&light(1.0)).unwrap().unwrap();
        assert_eq!(ring.newest_complete(), None, "rendering, not complete");
        assert_eq!(ring.rows_ready(a).unwrap(), ROWS);
        let first = ring.newest_complete().unwrap();
        assert_eq!((first.slot, first.light), (a, light(1.0)));
        ring.pin(a);
        ring.end(a);
        assert_eq!(ring.free_slots(), 2, "a's session ended, but a is pinned");
        assert_eq!(ring.newest_complete(), Some(first), "its bytes are still there");
        let b = ring.begin(&light(2.0)).unwrap().unwrap();
        let c = ring.begin(&light(3.0)).unwrap().unwrap();
        assert!(a != b && a != c);
        assert_eq!(ring.begin(&light(4.0)).unwrap(), None, "the pinned slot is skipped");
        // Asking for a slot advanced the engine: b and c complete in turn.
        while ring.rows_ready(c).unwrap() < ROWS {}
        assert_eq!(ring.rows_ready(b).unwrap(), ROWS);
        let newest = ring.newest_complete().unwrap();
        assert_eq!((newest.slot, newest.light), (c, light(3.0)), "the last to complete");
        assert_ne!(newest.seq, first.seq);
        ring.end(b);
        ring.unpin(a);
        assert_eq!(ring.free_slots(), 2, "a and b");
        assert_eq!(ring.slot_address(2), 0x1000 + 2 * FRAME_BYTES as u32);
    }

    #[test]
    fn reusing_the_newest_frames_slot_forgets_it() {
        let mut mem = vec![0u8; FRAME_BYTES];
        let mut ring = FrameRing::<_, _, 1>::new(SliceMemory::new(0, &mut mem), RowEngine::new(SoftwareRenderer));
        let f = ring.begin(&light(1.0)).unwrap().unwrap();
        while ring.rows_ready(f).unwrap() < ROWS {}
        ring.end(f);
        assert!(ring.newest_complete().is_some());
        let g = ring.begin(&light(2.0)).unwrap().unwrap();
        assert_eq!(ring.newest_complete(), None, "slot reused: the frame is being overwritten");
        ring.end(g);
    }

    #[test]
    fn a_frame_abandoned_mid_render_still_completes_as_the_newest() {
        let mut mem = vec![0u8; 2 * FRAME_BYTES];
        let dma = Dma { started: vec![], rows: 0, step: 200, fail_light: None, current: None };
        let mut ring = FrameRing::<_, _, 2>::new(SliceMemory::new(0, &mut mem), dma);
        let a = ring.begin(&light(1.0)).unwrap().unwrap();
        ring.end(a);
        let b = ring.begin(&light(2.0)).unwrap().unwrap();
        while ring.rows_ready(b).unwrap() < ROWS {}
        assert_eq!(ring.newest_complete().map(|c| c.slot), Some(b));
    }
}
