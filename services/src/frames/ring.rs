//! Frame mode: whole frames in the slots of a [`FrameMemory`], rendered by a
//! [`FrameEngine`] one after another in the order they were begun
//! ([`FrameRing`]), with the software engine ([`RowEngine`]) and host
//! memory ([`SliceMemory`]).

use core::fmt;

use model::{row_to_rgb888, Light, FRAME_BYTES, ROW_BYTES, WIDTH};

use super::rows::RowSource;
use super::{FrameSource, ROWS};

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
    /// windows, [`crate::camera::sender::SlotSource::set_held`]), apart from the
    /// display's pins.
    held: u32,
    /// Slots `begin` also skips: a transmit descriptor still points into
    /// them (the board's zero-copy rows, [`set_in_flight`](Self::set_in_flight)).
    /// A mask of its own, so that no other owner's update can drop it.
    in_flight: u32,
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
            in_flight: 0,
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

    /// Keep the slots of `mask` out of reuse while a transmit descriptor
    /// points into them, replacing the previous in-flight mask (and only
    /// it: the pins and the repair windows' holds are masks of their own).
    pub fn set_in_flight(&mut self, mask: u32) {
        self.in_flight = mask;
    }

    /// Slots a transmit descriptor points into (bit `i`: slot `i`).
    pub fn in_flight(&self) -> u32 {
        self.in_flight
    }

    /// Change row `y` of the complete frame in `slot` in place (read,
    /// `edit`, written back through the memory, which keeps the caches
    /// clean for a DMA reader): for the owner of a frame that nobody else
    /// reads, before anyone else sees it (the monitor's caption on its own
    /// attract frames). Nothing happens unless all the frame's rows have
    /// landed and its owner has not ended it.
    pub fn edit_row(&mut self, slot: usize, y: u16, edit: &mut dyn FnMut(&mut [u8; ROW_BYTES])) {
        if y >= ROWS || !matches!(self.slots.get(slot), Some(SlotState::Ready)) {
            return;
        }
        let mut row = [0u8; ROW_BYTES];
        self.mem.read_row(slot, y, 0, &mut row);
        edit(&mut row);
        self.mem.write_row(slot, y, &row);
    }

    /// Bus address of `slot` in the ring's memory.
    pub fn slot_address(&self, slot: usize) -> u32 {
        self.mem.slot_address(slot)
    }

    /// A free slot `begin` may take: not held by a frame, not pinned.
    fn takeable(&self, slot: usize) -> bool {
        matches!(self.slots[slot], SlotState::Free) && (self.pinned | self.held | self.in_flight) & (1 << slot) == 0
    }

    /// The engine.
    pub fn engine(&mut self) -> &mut E {
        &mut self.engine
    }

    /// The memory, for tests that look at what a slot holds.
    #[cfg(test)]
    pub(crate) fn memory(&mut self) -> &mut M {
        &mut self.mem
    }

    /// Frames completed since the ring was made (wrapping).
    pub fn completed(&self) -> u32 {
        self.completed
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
            // Ended whole (Ready, then Free) and still held by a repair
            // window: its bytes stay until the window lets it go (a late
            // output finishes its frame from there).
            Some(SlotState::Free) => self.held & (1 << frame) != 0,
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

    /// The row source.
    pub fn rows(&mut self) -> &mut R {
        &mut self.rows
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

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::frames::rows::SoftwareRenderer;

    /// An engine that lands `step` rows per progress call, failing the
    /// frame of a chosen light.
    pub(crate) struct Dma {
        pub(crate) started: Vec<usize>,
        pub(crate) rows: u16,
        pub(crate) step: u16,
        pub(crate) fail_light: Option<Light>,
        pub(crate) current: Option<Light>,
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

    pub(crate) fn light(x: f64) -> Light {
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

    /// A frame's rows stay readable after its end while a repair window
    /// holds its slot (a late viewer finishes it from there), not after.
    #[test]
    fn an_ended_frame_is_readable_while_held() {
        let mut mem = vec![0u8; FRAME_BYTES];
        let mut ring = FrameRing::<_, _, 1>::new(SliceMemory::new(0, &mut mem), RowEngine::new(SoftwareRenderer));
        let f = ring.begin(&light(1.0)).unwrap().unwrap();
        while ring.rows_ready(f).unwrap() < ROWS {}
        let mut row = [0u8; ROW_BYTES];
        ring.set_held(1 << f);
        ring.end(f);
        assert_eq!(ring.copy_row(f, ROWS - 1, 0, &mut row), ROW_BYTES);
        assert!(row[..] == model::render_frame(&light(1.0))[FRAME_BYTES - ROW_BYTES..]);
        ring.set_held(0);
        assert_eq!(ring.copy_row(f, 0, 0, &mut row), 0, "let go: the slot may be rendered into again");
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

    #[test]
    fn slots_under_a_descriptor_stay_out_of_use_whatever_the_holds_say() {
        let mut mem = vec![0u8; 2 * FRAME_BYTES];
        let mut ring = FrameRing::<_, _, 2>::new(SliceMemory::new(0, &mut mem), RowEngine::new(SoftwareRenderer));
        let a = ring.begin(&light(1.0)).unwrap().unwrap();
        while ring.rows_ready(a).unwrap() < ROWS {}
        ring.end(a);
        ring.set_in_flight(1 << a);
        ring.set_held(1 << a);
        ring.set_held(0); // the repair windows let go: the descriptors still point there
        assert_eq!(ring.free_slots(), 1, "only the other slot");
        let b = ring.begin(&light(2.0)).unwrap().unwrap();
        assert_ne!(a, b);
        assert_eq!(ring.begin(&light(3.0)).unwrap(), None, "a is still under a descriptor");
        ring.set_in_flight(0);
        assert_eq!(ring.begin(&light(3.0)).unwrap(), Some(a));
    }
}
