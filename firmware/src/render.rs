//! Where the frame server's frames come from on the board.
//!
//! * Frame mode ([`Frames::Ring`]): six frame slots in the cacheable
//!   `.frames` region ([`RingMemory`]); the FPGA's frame DMA renders into them
//!   (the software renderer where there is none, or where it failed), and
//!   rows go out as its rows-done counter covers them.
//! * Row mode ([`Frames::Rows`]): accelerators without the frame registers
//!   (map version 1) render a row per start, the next started before the
//!   current one is sent; the software renderer behind them.
//!
//! Either way a wedged accelerator is switched off after a few failures in
//! a row (logged once) and the model on the A9 takes over.

use core::cell::UnsafeCell;
use core::fmt::{self, Write};
use core::time::Duration;

use hal_avalon::sim::DmaTarget;
use hal_avalon::sources::PipelinedRows;
use hal_avalon::{Accelerator, Counted, RegisterPort};
use model::{Light, FRAME_BYTES, ROW_BYTES};
use rt_services::frames::fallback::{Fallback, FallbackEvent, WEDGED_AFTER};
use rt_services::{
    EngineError, FallbackEngine, FrameMemory, FrameRing, FrameSource, RowEngine, RowFrames, SoftwareRenderer, Watchdog,
    WatchdogError,
};
use soc::cache::{self, Lines};
use soc::global_timer::TimerDelay;

use crate::bench;
use crate::cpu::Caches;
use crate::limits::{RING_SLOTS, ROW_FRAMES};

/// How long a frame of the accelerator may go without a new row before it
/// counts as failed (a frame takes about 3.5 ms at 50 MHz).
pub const STALL_LIMIT: Duration = Duration::from_millis(500);

/// The frame ring's memory, in the `.frames` section (memory.x).
#[repr(C, align(4096))]
struct Slots(UnsafeCell<[u8; RING_SLOTS * FRAME_BYTES]>);

// SAFETY: only `RingMemory` touches the slots, from the main loop on core 0;
// the ring hands each slot to one writer (engine) and then to readers.
unsafe impl Sync for Slots {}

#[unsafe(link_section = ".frames")]
static SLOTS: Slots = Slots(UnsafeCell::new([0; RING_SLOTS * FRAME_BYTES]));

/// The frame slots: Normal write-back memory, kept clean. The FPGA-to-SDRAM
/// port writes DRAM behind both caches, so a row is invalidated by address
/// (L2, then L1) right before the CPU first reads it, after the counter
/// covered it; whatever the CPU writes (software renderer, simulated DMA)
/// is cleaned at once, so no dirty line can ever be evicted over the
/// FPGA's data (docs/frame-dma.md#caches). Rows are 1,440 bytes, 45 whole
/// lines, and the slots are page aligned.
#[derive(Clone, Copy)]
pub struct RingMemory {
    base: *mut u8,
    caches: Caches,
}

impl RingMemory {
    /// The `.frames` region.
    pub fn frames(caches: Caches) -> RingMemory {
        RingMemory { base: SLOTS.0.get().cast(), caches }
    }

    fn at(&self, slot: usize, y: u16, offset: usize, len: usize) -> Option<*mut u8> {
        let start = slot.checked_mul(FRAME_BYTES)? + usize::from(y) * ROW_BYTES + offset;
        (start + len <= RING_SLOTS * FRAME_BYTES).then(|| self.base.wrapping_add(start))
    }
}

impl FrameMemory for RingMemory {
    fn slot_address(&self, slot: usize) -> u32 {
        self.base as u32 + (slot * FRAME_BYTES) as u32
    }

    fn read_row(&mut self, slot: usize, y: u16, offset: usize, out: &mut [u8]) {
        let Some(src) = self.at(slot, y, offset, out.len()) else { return };
        if offset == 0 {
            // First read of the row since the counter covered it: drop any
            // copy the caches hold (the slot's previous frame, or a
            // speculative fill). The invalidation's `dsb` also orders the
            // row's loads after the counter read (docs/frame-dma.md).
            let row = src as usize;
            if let Some(lines) = Lines::exact(row, ROW_BYTES) {
                // SAFETY: the ring's lines are never dirty (every CPU write
                // is cleaned, see `write_row` and `DmaTarget::write`).
                unsafe { cache::invalidate_for_cpu(&self.caches, &lines) };
                bench::invalidated(lines.count());
            }
        }
        // SAFETY: `at` checked the range lies in the slots; the ring reads
        // only rows the engine has finished writing. (The copy is mem.rs's
        // `ldm`/`stm` memcpy: the socket keeps `out` word aligned with the
        // row, dwmac's `TX_SKEW`.)
        unsafe { core::ptr::copy_nonoverlapping(src, out.as_mut_ptr(), out.len()) };
    }

    fn write_row(&mut self, slot: usize, y: u16, row: &[u8; ROW_BYTES]) {
        let Some(dst) = self.at(slot, y, 0, ROW_BYTES) else { return };
        // SAFETY: `at` checked the range; the ring gives a slot to one
        // engine at a time and reads only rows written before.
        unsafe { core::ptr::copy_nonoverlapping(row.as_ptr(), dst, ROW_BYTES) };
        bench::cleaned(self.clean(dst as usize, ROW_BYTES));
    }
}

impl RingMemory {
    /// Keep the ring clean after the CPU wrote `start..start + len`; the
    /// lines cleaned.
    fn clean(&self, start: usize, len: usize) -> usize {
        let Some(lines) = Lines::covering(start, len) else { return 0 };
        cache::clean_for_device(&self.caches, &lines);
        lines.count()
    }
}

/// The simulated accelerator's frame DMA on the emulated board writes the
/// same slots.
impl DmaTarget for RingMemory {
    fn write(&mut self, addr: u32, bytes: &[u8]) -> bool {
        let Some(off) = addr.checked_sub(self.base as u32).map(|o| o as usize) else { return false };
        if off + bytes.len() > RING_SLOTS * FRAME_BYTES {
            return false;
        }
        // SAFETY: checked to lie in the slots, written by one engine at a time.
        unsafe { core::ptr::copy_nonoverlapping(bytes.as_ptr(), self.base.add(off), bytes.len()) };
        // Not counted: on the board the FPGA writes DRAM, the CPU cleans
        // nothing.
        self.clean(self.base as usize + off, bytes.len());
        true
    }
}

/// The accelerator driver as the firmware runs it, its bus accesses counted.
pub type Accel<P> = Accelerator<Counted<P>, TimerDelay<'static>>;

/// The driver over `port`, polling on the global timer.
pub fn accelerator<P: RegisterPort>(port: P, timer: &'static soc::global_timer::GlobalTimer) -> Accel<P> {
    Accelerator::new(Counted::new(port), TimerDelay(timer), hal_avalon::PollTimeout::DEFAULT)
}

/// The firmware's clock for the watchdog.
fn now() -> rt_services::Instant {
    rt_services::Instant::from_millis(crate::platform::TIMER.now_us() / 1000)
}

type Clock = fn() -> rt_services::Instant;
type Software = bench::TimedRows<SoftwareRenderer>;
/// The frame DMA first; where it fails, rows rendered into the ring by the
/// FPGA in row mode (when only the frame path failed the self-test) or by
/// the software renderer.
pub type RingEngine<P> = FallbackEngine<bench::TimedEngine<Watchdog<Accel<P>, Clock>>, RowEngine<RowSources<P>>>;
type RowSources<P> = Fallback<bench::TimedRows<PipelinedRows<Counted<P>, TimerDelay<'static>>>, Software>;

/// Frame mode's ring.
pub type Ring<P> = FrameRing<RingMemory, RingEngine<P>, RING_SLOTS>;

/// The frame server's frames.
// One value for the whole run, on `main`'s stack; the row variant's row
// buffers are the bigger one and there is no allocator to box it.
#[allow(clippy::large_enum_variant)]
pub enum Frames<P: RegisterPort> {
    /// Frame mode: whole frames in the ring.
    Ring(Ring<P>),
    /// Row mode: a row per start.
    Rows(RowFrames<RowSources<P>, ROW_FRAMES>),
}

/// Why a frame could not be delivered.
#[derive(Clone, Copy, Debug)]
pub enum RenderError {
    /// The accelerator failed the frame (under way: its client sees the
    /// connection close).
    Accelerator(WatchdogError<hal_avalon::Error>),
}

impl fmt::Display for RenderError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RenderError::Accelerator(e) => write!(f, "FPGA: {e}"),
        }
    }
}

impl core::error::Error for RenderError {}

impl<P: RegisterPort> Frames<P> {
    /// Frame mode with the accelerator `fpga` rendering whole frames, or
    /// `rows`, an accelerator fit for row mode only, rendering the ring's
    /// frames a row at a time (neither: the software renderer fills the
    /// ring), the ring's cache maintenance done with `caches`.
    pub fn ring(fpga: Option<Accel<P>>, rows: Option<Accel<P>>, caches: Caches) -> Frames<P> {
        let primary = fpga.map(|a| bench::TimedEngine::new(Watchdog::new(a, now as Clock, STALL_LIMIT)));
        let rows = Fallback::new(
            rows.map(|a| bench::TimedRows::new(PipelinedRows::new(a))),
            bench::TimedRows::new(SoftwareRenderer),
        );
        let engine = FallbackEngine::new(primary, RowEngine::new(rows));
        Frames::Ring(FrameRing::new(RingMemory::frames(caches), engine))
    }

    /// Row mode with the accelerator `fpga` (none: the software renderer).
    pub fn rows(fpga: Option<Accel<P>>) -> Frames<P> {
        let primary = fpga.map(|a| bench::TimedRows::new(PipelinedRows::new(a)));
        Frames::Rows(RowFrames::new(Fallback::new(primary, bench::TimedRows::new(SoftwareRenderer))))
    }

    /// Frame mode rendered in software, the accelerator `kept` only for its
    /// board I/O (it failed its self-test).
    pub fn ring_board_io_only(kept: Option<Accel<P>>, caches: Caches) -> Frames<P> {
        let mut frames = Frames::ring(kept, None, caches);
        if let Frames::Ring(r) = &mut frames {
            r.engine().keep_primary_off();
        }
        frames
    }

    /// Bus addresses of the ring's slots, in frame mode (the network
    /// camera points the MAC at its rows there).
    pub fn slot_addresses(&self) -> Option<[u32; RING_SLOTS]> {
        match self {
            Frames::Ring(r) => Some(core::array::from_fn(|i| r.slot_address(i))),
            Frames::Rows(_) => None,
        }
    }

    /// "frame mode" or "row mode", and what renders.
    pub fn describe(&mut self) -> &'static str {
        match (self.mode(), self) {
            ("frames", _) => "frame mode, FPGA frame DMA into the ring (software fallback)",
            ("rows", Frames::Ring(_)) => {
                "frame mode, FPGA rows into the ring (its frame DMA is not used; software fallback)"
            }
            (_, Frames::Ring(_)) => "frame mode, software renderer into the ring",
            ("rows", Frames::Rows(_)) => "row mode, FPGA rows (software fallback)",
            (_, Frames::Rows(_)) => "row mode, software renderer",
        }
    }

    /// How frames are made, as `/status` names it: `"frames"` (the FPGA's
    /// frame DMA), `"rows"` (the FPGA a row at a time) or `"software"`.
    pub fn mode(&mut self) -> &'static str {
        let (frames, rows) = match self {
            Frames::Ring(r) => (r.engine().primary_active(), r.engine().fallback().rows().primary_active()),
            Frames::Rows(r) => (false, r.rows().primary_active()),
        };
        match (frames, rows) {
            (true, _) => "frames",
            (false, true) => "rows",
            (false, false) => "software",
        }
    }

    /// Frames the ring completed (frame mode; wrapping), `None` in row
    /// mode.
    pub fn completed(&self) -> Option<u32> {
        match self {
            Frames::Ring(r) => Some(r.completed()),
            Frames::Rows(_) => None,
        }
    }

    /// Bus accesses to the accelerator so far.
    pub fn bus_accesses(&mut self) -> bench::Bus {
        let port = match self {
            Frames::Ring(r) => match r.engine().primary_active() {
                true => r.engine().primary().map(|t| t.inner().engine().port()),
                false => r.engine().fallback().rows().primary().map(|p| p.inner().accelerator().port()),
            },
            Frames::Rows(r) => r.rows().primary().map(|p| p.inner().accelerator().port()),
        };
        port.map_or(bench::Bus::default(), |c| bench::Bus {
            reads: c.reads,
            line_words: c.line_words,
            writes: c.writes,
        })
    }

    /// Report (once) what the accelerator did since the last call.
    pub fn report(&mut self, log: &mut impl Write) {
        match self {
            Frames::Ring(r) => {
                if r.engine().take_switched_off() {
                    let _ = writeln!(
                        log,
                        "FPGA: {WEDGED_AFTER} frames failed in a row: accelerator switched off, software from now on"
                    );
                }
                report_rows(r.engine().fallback().rows(), log);
            }
            Frames::Rows(r) => report_rows(r.rows(), log),
        }
    }
}

/// Report (once) what the accelerator did in row mode.
fn report_rows<P: RegisterPort>(rows: &mut RowSources<P>, log: &mut impl Write) {
    match rows.take_event() {
        Some(FallbackEvent::RowsFailed { error, total }) => {
            let _ = writeln!(log, "FPGA: {error}; row rendered in software ({total} so far)");
        }
        Some(FallbackEvent::SwitchedOff { error }) => {
            let _ = writeln!(
                log,
                "FPGA: {error}; {WEDGED_AFTER} rows failed in a row: accelerator switched off, software from now on"
            );
        }
        None => {}
    }
}

impl<P: RegisterPort> FrameSource for Frames<P> {
    type Frame = usize;
    type Error = RenderError;

    fn begin(&mut self, light: &Light) -> Result<Option<usize>, RenderError> {
        match self {
            Frames::Ring(r) => r.begin(light).map_err(ring_error),
            Frames::Rows(r) => r.begin(light).map_err(|never| match never {}),
        }
    }

    fn rows_ready(&mut self, frame: usize) -> Result<u16, RenderError> {
        match self {
            Frames::Ring(r) => r.rows_ready(frame).map_err(ring_error),
            Frames::Rows(r) => r.rows_ready(frame).map_err(|never| match never {}),
        }
    }

    fn copy_row(&mut self, frame: usize, y: u16, offset: usize, out: &mut [u8]) -> usize {
        let n = match self {
            Frames::Ring(r) => r.copy_row(frame, y, offset, out),
            Frames::Rows(r) => r.copy_row(frame, y, offset, out),
        };
        bench::copied(n);
        n
    }

    fn end(&mut self, frame: usize) {
        match self {
            Frames::Ring(r) => r.end(frame),
            Frames::Rows(r) => r.end(frame),
        }
    }
}

impl<P: RegisterPort> Frames<P> {
    /// Keep the slots of `mask` out of reuse while a transmit descriptor
    /// points into them (the camera's zero-copy rows); a mask of its own,
    /// which no camera call replaces.
    pub fn set_in_flight(&mut self, mask: u32) {
        if let Frames::Ring(r) = self {
            r.set_in_flight(mask)
        }
    }
}

/// The network camera resends rows from ring slots; row mode has none (the
/// camera runs in frame mode only, net.rs).
impl<P: RegisterPort> rt_services::camera::sender::SlotSource for Frames<P> {
    fn set_held(&mut self, mask: u32) {
        if let Frames::Ring(r) = self {
            r.set_held(mask)
        }
    }
}

fn ring_error(e: EngineError<WatchdogError<hal_avalon::Error>, core::convert::Infallible>) -> RenderError {
    match e {
        EngineError::Primary(e) => RenderError::Accelerator(e),
        EngineError::Fallback(never) => match never {},
    }
}
