//! The bench build's measurements (`cargo xtask bench-fw`, feature
//! `bench`): the guest time of each frame's start and of its rendering, and
//! per frame the bytes the CPU copied and read from uncached memory. Under
//! QEMU's `-icount shift=0` a guest nanosecond is a guest instruction.
//! Without the feature every hook here compiles to nothing.

use core::fmt::Write;
#[cfg(feature = "bench")]
use core::sync::atomic::{AtomicU32, AtomicU64, Ordering};

use model::{Light, WIDTH};
use rt_protocol::frames::ROWS;
use rt_protocol::{FrameEngine, FrameMemory, RowSource};

#[cfg(feature = "bench")]
static RENDER_NS: AtomicU64 = AtomicU64::new(0);
#[cfg(feature = "bench")]
static FRAMES: AtomicU32 = AtomicU32::new(0);
#[cfg(feature = "bench")]
static COPIED: AtomicU64 = AtomicU64::new(0);
#[cfg(feature = "bench")]
static UNCACHED: AtomicU64 = AtomicU64::new(0);

/// The CPU copied `n` bytes of a row into the socket.
#[inline(always)]
pub fn copied(n: usize) {
    #[cfg(feature = "bench")]
    COPIED.fetch_add(n as u64, Ordering::Relaxed);
    let _ = n;
}

/// The CPU read `n` bytes from uncached memory.
#[inline(always)]
pub fn uncached_read(n: usize) {
    #[cfg(feature = "bench")]
    UNCACHED.fetch_add(n as u64, Ordering::Relaxed);
    let _ = n;
}

#[cfg(feature = "bench")]
fn frame_started() {
    RENDER_NS.store(0, Ordering::Relaxed);
    let _ = writeln!(crate::log::Log, "bench: frame start {}", crate::TIMER.now_ns());
}

#[cfg(feature = "bench")]
fn frame_rendered() {
    let _ = writeln!(crate::log::Log, "bench: frame rendered {}", RENDER_NS.load(Ordering::Relaxed));
    FRAMES.fetch_add(1, Ordering::Relaxed);
}

/// Run `f`, adding its guest time to the frame's rendering.
#[inline(always)]
fn timed<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(feature = "bench")]
    {
        let t0 = crate::TIMER.now_ns();
        let r = f();
        RENDER_NS.fetch_add(crate::TIMER.now_ns().saturating_sub(t0), Ordering::Relaxed);
        r
    }
    #[cfg(not(feature = "bench"))]
    f()
}

/// Counters the main loop prints once per frame.
#[derive(Default)]
pub struct Counts {
    #[cfg(feature = "bench")]
    seen: u32,
    #[cfg(feature = "bench")]
    last: [u64; 5],
}

impl Counts {
    /// After a frame's rendering finished: one line with what the CPU and
    /// the bus did since the previous one (LW-bridge accesses, the MAC's TX
    /// bytes come from the caller).
    pub fn report(&mut self, bus: (u32, u32), tx_bytes: u64, log: &mut impl Write) {
        #[cfg(feature = "bench")]
        {
            let frames = FRAMES.load(Ordering::Relaxed);
            if frames == self.seen {
                return;
            }
            self.seen = frames;
            let now = [
                u64::from(bus.0),
                u64::from(bus.1),
                COPIED.load(Ordering::Relaxed),
                UNCACHED.load(Ordering::Relaxed),
                tx_bytes,
            ];
            let d: [u64; 5] = core::array::from_fn(|i| now[i].wrapping_sub(self.last[i]));
            self.last = now;
            let _ = writeln!(
                log,
                "bench: counts lw_reads={} lw_writes={} cpu_copied={} uncached_read={} mac_tx={}",
                d[0], d[1], d[2], d[3], d[4]
            );
        }
        let _ = (bus, tx_bytes, log);
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

/// A frame engine whose time counts as the frame's.
pub struct TimedEngine<E> {
    engine: E,
    #[cfg(feature = "bench")]
    reported: bool,
}

impl<E> TimedEngine<E> {
    /// Time `engine`.
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
        timed(|| self.engine.start(mem, slot, light))
    }

    fn progress(&mut self, mem: &mut M) -> Result<u16, E::Error> {
        let rows = timed(|| self.engine.progress(mem))?;
        #[cfg(feature = "bench")]
        if rows >= ROWS && !self.reported {
            self.reported = true;
            frame_rendered();
        }
        Ok(rows)
    }
}
