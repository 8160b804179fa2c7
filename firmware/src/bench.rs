//! The bench build's measurements (`cargo xtask bench-fw`, feature
//! `bench`). Under QEMU's `-icount shift=0` a guest nanosecond is a guest
//! instruction, so the times below are instruction counts.
//!
//! * per frame: the guest time of its start and of its rendering (the
//!   software renderer, or the simulated accelerator: FPGA work, not the
//!   board's CPU);
//! * busy time: main-loop iterations that moved anything (a frame sent or
//!   received, bytes copied, rendering). The rest is waiting for the peer's
//!   ACKs, which on the emulated link takes guest time that a board at
//!   line rate would spend waiting on the wire;
//! * counts for the board's cost model: accelerator bus accesses, bytes the
//!   CPU copied, cache lines maintained, bytes it read from uncached memory
//!   and bytes the MAC sent (written by the CPU into uncached buffers).
//!
//! Without the feature every hook here compiles to nothing.

use core::fmt::Write;
#[cfg(feature = "bench")]
use core::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};

use model::{Light, WIDTH};
use rt_services::frames::ROWS;
use rt_services::{FrameEngine, FrameMemory, RowSource};

// Times are kept in timer ticks (no division on the measured path) and
// converted to nanoseconds when printed.
// The frame's rendering is the total's growth since its start (one add on
// the measured path, not two).
#[cfg(feature = "bench")]
static RENDER_AT_START: AtomicU32 = AtomicU32::new(0);
/// Inside a `timed` region (a nested one adds nothing).
#[cfg(feature = "bench")]
static TIMING: AtomicBool = AtomicBool::new(false);
#[cfg(feature = "bench")]
static RENDER_TICKS: AtomicU32 = AtomicU32::new(0);
#[cfg(feature = "bench")]
static BUSY_TICKS: AtomicU64 = AtomicU64::new(0);
#[cfg(feature = "bench")]
static BUSY_LOOPS: AtomicU64 = AtomicU64::new(0);
#[cfg(feature = "bench")]
static FRAMES: AtomicU32 = AtomicU32::new(0);
#[cfg(feature = "bench")]
static COPIED: AtomicU64 = AtomicU64::new(0);
#[cfg(feature = "bench")]
static INVALIDATED: AtomicU64 = AtomicU64::new(0);
#[cfg(feature = "bench")]
static CLEANED: AtomicU64 = AtomicU64::new(0);
#[cfg(feature = "bench")]
static CAMERA_TICKS: AtomicU64 = AtomicU64::new(0);
#[cfg(feature = "bench")]
static WEB_TICKS: AtomicU64 = AtomicU64::new(0);
#[cfg(feature = "bench")]
static STARTED_TICKS: AtomicU64 = AtomicU64::new(0);
#[cfg(feature = "bench")]
static RENDERED_TICKS: AtomicU32 = AtomicU32::new(0);

/// Accelerator bus accesses (from hal-avalon's `Counted` port).
#[derive(Clone, Copy, Default)]
#[cfg_attr(not(feature = "bench"), allow(dead_code))] // read by the bench build only
pub struct Bus {
    /// Single register reads.
    pub reads: u32,
    /// Line-buffer words read in bursts.
    pub line_words: u32,
    /// Register writes.
    pub writes: u32,
}

/// What the MAC moved (from its statistics).
#[derive(Clone, Copy, Default)]
#[cfg_attr(not(feature = "bench"), allow(dead_code))] // read by the bench build only
pub struct Mac {
    /// Frames sent plus frames received.
    pub frames: u32,
    /// Frames sent.
    pub tx_frames: u32,
    /// Bytes sent.
    pub tx_bytes: u64,
    /// Of those, payload the MAC read from the frame ring (zero-copy).
    pub tx_zero_copy: u64,
    /// Bytes received.
    pub rx_bytes: u64,
}

/// The CPU copied `n` bytes of a row into the socket.
#[inline(always)]
pub fn copied(n: usize) {
    #[cfg(feature = "bench")]
    COPIED.fetch_add(n as u64, Ordering::Relaxed);
    let _ = n;
}

/// `n` cache lines invalidated (both levels) before a read.
#[inline(always)]
pub fn invalidated(n: usize) {
    #[cfg(feature = "bench")]
    INVALIDATED.fetch_add(n as u64, Ordering::Relaxed);
    let _ = n;
}

/// `n` cache lines cleaned (both levels) after a CPU write.
#[inline(always)]
pub fn cleaned(n: usize) {
    #[cfg(feature = "bench")]
    CLEANED.fetch_add(n as u64, Ordering::Relaxed);
    let _ = n;
}

// The frame's times are kept and logged by `Counts::report`, after the
// main-loop iteration: formatting a line inside it would count as the
// iteration's streaming work.
#[cfg(feature = "bench")]
fn frame_started() {
    RENDER_AT_START.store(RENDER_TICKS.load(Ordering::Relaxed), Ordering::Relaxed);
    STARTED_TICKS.store(crate::platform::TIMER.ticks(), Ordering::Relaxed);
}

#[cfg(feature = "bench")]
fn frame_rendered() {
    let total = RENDER_TICKS.load(Ordering::Relaxed);
    RENDERED_TICKS.store(total.wrapping_sub(RENDER_AT_START.load(Ordering::Relaxed)), Ordering::Relaxed);
    FRAMES.fetch_add(1, Ordering::Relaxed);
}

#[cfg(feature = "bench")]
fn ns(ticks: u64) -> u64 {
    soc::global_timer::ticks_to_ns(ticks, crate::platform::TIMER.hz())
}

/// Run `f` (the network camera's poll), adding its guest time to the
/// camera's, which the bench prints apart.
#[inline(always)]
pub fn camera<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(feature = "bench")]
    {
        let t0 = crate::platform::TIMER.ticks();
        let r = f();
        CAMERA_TICKS.fetch_add(crate::platform::TIMER.ticks().wrapping_sub(t0), Ordering::Relaxed);
        r
    }
    #[cfg(not(feature = "bench"))]
    f()
}

/// Run `f` (the web page's poll), adding its guest time to the web
/// page's, which the bench prints apart.
#[inline(always)]
pub fn web<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(feature = "bench")]
    {
        let t0 = crate::platform::TIMER.ticks();
        let r = f();
        WEB_TICKS.fetch_add(crate::platform::TIMER.ticks().wrapping_sub(t0), Ordering::Relaxed);
        r
    }
    #[cfg(not(feature = "bench"))]
    f()
}

/// Run `f`, adding its guest time to the frame's rendering; inside
/// another `timed` it only runs `f` (the outer one counts it).
#[inline(always)]
fn timed<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(feature = "bench")]
    {
        // Single core, main loop only: plain loads and stores, no
        // read-modify-write loops, and the timer's low word (the regions
        // last well under its 43 s wrap): what lies outside the two timer
        // reads counts as the CPU's, so keep it short.
        if TIMING.load(Ordering::Relaxed) {
            return f();
        }
        TIMING.store(true, Ordering::Relaxed);
        let t0 = crate::platform::TIMER.ticks_low();
        let r = f();
        let dt = crate::platform::TIMER.ticks_low().wrapping_sub(t0);
        RENDER_TICKS.store(RENDER_TICKS.load(Ordering::Relaxed).wrapping_add(dt), Ordering::Relaxed);
        TIMING.store(false, Ordering::Relaxed);
        r
    }
    #[cfg(not(feature = "bench"))]
    f()
}

/// Run `f`, the work of a simulated device (the emulated board's
/// accelerator, which the board's FPGA does): its time counts as the
/// frame's rendering, not as the CPU's. The driver's own work around it
/// (register reads, the watchdog) counts as the CPU's.
#[inline(always)]
#[cfg_attr(not(feature = "qemu-npcm750"), allow(dead_code))] // the emulated board's device
pub fn device<R>(f: impl FnOnce() -> R) -> R {
    timed(f)
}

/// One main-loop iteration: counts as busy if it moved anything.
pub struct Iteration {
    #[cfg(feature = "bench")]
    t0: u64,
    #[cfg(feature = "bench")]
    before: (u32, u64, u64),
}

impl Iteration {
    #[cfg(feature = "bench")]
    fn marks(mac_frames: u32) -> (u32, u64, u64) {
        (mac_frames, COPIED.load(Ordering::Relaxed), u64::from(RENDER_TICKS.load(Ordering::Relaxed)))
    }

    /// At the top of the loop; `mac_frames` from [`Mac::frames`].
    #[inline(always)]
    pub fn start(mac_frames: u32) -> Iteration {
        let _ = mac_frames;
        Iteration {
            #[cfg(feature = "bench")]
            t0: crate::platform::TIMER.ticks(),
            #[cfg(feature = "bench")]
            before: Self::marks(mac_frames),
        }
    }

    /// At the bottom.
    #[inline(always)]
    pub fn end(self, mac_frames: u32) {
        #[cfg(feature = "bench")]
        if Self::marks(mac_frames) != self.before {
            BUSY_TICKS.fetch_add(crate::platform::TIMER.ticks().wrapping_sub(self.t0), Ordering::Relaxed);
            BUSY_LOOPS.fetch_add(1, Ordering::Relaxed);
        }
        let _ = mac_frames;
    }
}

/// Counters the main loop prints once per frame.
#[derive(Default)]
pub struct Counts {
    #[cfg(feature = "bench")]
    seen: u32,
    #[cfg(feature = "bench")]
    last: [u64; 13],
    /// The render ticks (32 bits, wrapping) at the last report, and their
    /// 64-bit total.
    #[cfg(feature = "bench")]
    render_seen: u32,
    #[cfg(feature = "bench")]
    render_total: u64,
}

impl Counts {
    /// After a frame's rendering finished: one line with what the CPU, the
    /// bus and the MAC did since the previous one.
    pub fn report(&mut self, bus: Bus, mac: Mac, log: &mut impl Write) {
        #[cfg(feature = "bench")]
        {
            let frames = FRAMES.load(Ordering::Relaxed);
            if frames == self.seen {
                return;
            }
            self.seen = frames;
            let render = RENDER_TICKS.load(Ordering::Relaxed);
            self.render_total += u64::from(render.wrapping_sub(self.render_seen));
            self.render_seen = render;
            let now = [
                u64::from(bus.reads),
                u64::from(bus.line_words),
                u64::from(bus.writes),
                COPIED.load(Ordering::Relaxed),
                INVALIDATED.load(Ordering::Relaxed),
                CLEANED.load(Ordering::Relaxed),
                mac.rx_bytes,
                mac.tx_bytes,
                mac.tx_zero_copy,
                u64::from(mac.tx_frames),
                ns(BUSY_TICKS.load(Ordering::Relaxed)),
                ns(self.render_total),
                BUSY_LOOPS.load(Ordering::Relaxed),
            ];
            let d: [u64; 13] = core::array::from_fn(|i| now[i].wrapping_sub(self.last[i]));
            self.last = now;
            // The camera's poll, the frame source's calls (and so the
            // rendering they drive) included; finer timers cost more than
            // they show (each timer read is some 20 instructions a row).
            let _ = writeln!(
                log,
                "bench: frame rendered {} ns, started at {} ns",
                ns(u64::from(RENDERED_TICKS.load(Ordering::Relaxed))),
                ns(STARTED_TICKS.load(Ordering::Relaxed))
            );
            let camera = ns(CAMERA_TICKS.swap(0, Ordering::Relaxed));
            let _ = writeln!(log, "bench: camera {camera} ns (rendering included)");
            let web = ns(WEB_TICKS.swap(0, Ordering::Relaxed));
            let _ = writeln!(log, "bench: web {web} ns (rendering included)");
            let _ = writeln!(
                log,
                "bench: counts lw_reads={} lw_line_words={} lw_writes={} cpu_copied={} lines_invalidated={} lines_cleaned={} uncached_read={} mac_tx={} mac_tx_zero_copy={} tx_frames={} busy_ns={} render_ns={} busy_loops={}",
                d[0], d[1], d[2], d[3], d[4], d[5], d[6], d[7], d[8], d[9], d[10], d[11], d[12]
            );
        }
        let _ = (bus, mac, log);
    }
}

/// A row source whose rendering time counts as the frame's.
pub struct TimedRows<R>(R);

impl<R> TimedRows<R> {
    /// Time `rows`.
    pub fn new(rows: R) -> TimedRows<R> {
        TimedRows(rows)
    }

    /// The row source.
    pub fn inner(&mut self) -> &mut R {
        &mut self.0
    }
}

impl<R: RowSource> RowSource for TimedRows<R> {
    type Error = R::Error;

    fn render_row(&mut self, y: u16, light: &Light, out: &mut [u32; WIDTH]) -> Result<(), R::Error> {
        #[cfg(feature = "bench")]
        if y == 0 {
            frame_started();
        }
        let r = timed(|| self.0.render_row(y, light, out));
        #[cfg(feature = "bench")]
        if y + 1 == ROWS {
            frame_rendered();
        }
        let _ = ROWS;
        r
    }
}

/// A frame engine whose frames' start and end the bench logs. Its time is
/// not the frame's: the simulated device's is, measured at its port
/// ([`device`]), and the driver's polling around it is the CPU's, as on
/// the board.
pub struct TimedEngine<E> {
    engine: E,
    #[cfg(feature = "bench")]
    reported: bool,
}

impl<E> TimedEngine<E> {
    /// Report `engine`'s frames.
    pub fn new(engine: E) -> TimedEngine<E> {
        TimedEngine {
            engine,
            #[cfg(feature = "bench")]
            reported: false,
        }
    }

    /// The engine.
    pub fn inner(&mut self) -> &mut E {
        &mut self.engine
    }
}

impl<M: FrameMemory, E: FrameEngine<M>> FrameEngine<M> for TimedEngine<E> {
    type Error = E::Error;

    fn start(&mut self, mem: &mut M, slot: usize, light: &Light) -> Result<(), E::Error> {
        #[cfg(feature = "bench")]
        {
            frame_started();
            self.reported = false;
        }
        self.engine.start(mem, slot, light)
    }

    fn progress(&mut self, mem: &mut M) -> Result<u16, E::Error> {
        let rows = self.engine.progress(mem)?;
        #[cfg(feature = "bench")]
        if rows >= ROWS && !self.reported {
            self.reported = true;
            frame_rendered();
        }
        Ok(rows)
    }

    fn abort(&mut self, mem: &mut M) -> Result<(), E::Error> {
        self.engine.abort(mem)
    }
}
