//! The UART log: [`Log`] queues text in a ring buffer that the main loop
//! drains as the UART's FIFO takes it ([`drain`]), so a log line costs the
//! A9 a copy, not milliseconds at 115,200 baud. Start-up, which waits
//! anyway, flushes after each step ([`flush`]); fault handlers write through
//! [`Fault`], which empties the ring first and then writes directly.
//! Everything logged is also kept in a history of the newest
//! [`HISTORY_BYTES`], which `/log` answers with ([`Tail`]).

use core::cell::UnsafeCell;
use core::fmt;
use core::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use heapless::HistoryBuf;
use rt_services::web::status::{copy_tail, LogTail};
use soc::log::LogRing;
use soc::uart16550::Uart16550;

/// Bytes the ring holds (about a hundred log lines).
const RING_BYTES: usize = 8192;

/// Bytes of history kept for `/log`.
pub const HISTORY_BYTES: usize = 8192;

/// What the UART has yet to take, and the history.
struct Rings {
    uart: LogRing<RING_BYTES>,
    history: HistoryBuf<u8, HISTORY_BYTES>,
}

/// The rings, with a flag that makes a re-entrant use (a fault while the
/// main loop is inside the ring) skip instead of aliasing it.
struct Shared {
    ring: UnsafeCell<Rings>,
    busy: AtomicBool,
}

// SAFETY: one core, no interrupt handlers; exception handlers that may
// interrupt a ring access find `busy` set and leave the ring alone.
unsafe impl Sync for Shared {}

static SHARED: Shared = Shared {
    ring: UnsafeCell::new(Rings { uart: LogRing::new(), history: HistoryBuf::new() }),
    busy: AtomicBool::new(false),
};

/// Run `f` on the rings unless they are already in use.
fn with_rings<R>(f: impl FnOnce(&mut Rings) -> R) -> Option<R> {
    if SHARED.busy.swap(true, Ordering::Acquire) {
        return None;
    }
    // SAFETY: `busy` was clear and is now set: this is the only reference.
    let r = f(unsafe { &mut *SHARED.ring.get() });
    SHARED.busy.store(false, Ordering::Release);
    Some(r)
}

/// The log UART's address, set once by [`init`] (0 until then: nothing is
/// written). Handed in by the composition root (`main`), so the log
/// depends on no board.
static UART_BASE: AtomicUsize = AtomicUsize::new(0);

fn uart() -> Option<Uart16550> {
    let base = UART_BASE.load(Ordering::Relaxed);
    let block = core::ptr::NonNull::new(base as *mut _)?;
    // SAFETY: `init` was given the board's UART0, mapped Device (or the MMU
    // is off); writers of the same UART only interleave bytes.
    Some(unsafe { Uart16550::new(block) })
}

/// Queue text for the UART.
#[derive(Clone, Copy, Debug, Default)]
pub struct Log;

impl fmt::Write for Log {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        // Text written while the ring is busy (only from a fault) is lost.
        let _ = with_rings(|r| {
            r.history.extend_from_slice(s.as_bytes());
            r.uart.write_str(s)
        });
        Ok(())
    }
}

/// Move what the UART's FIFO takes now; never waits.
pub fn drain() {
    if let Some(mut u) = uart() {
        let _ = with_rings(|r| r.uart.drain(&mut u));
    }
}

/// Log to the 16550 at `uart_base` (the board's UART0) and switch its
/// FIFOs on, so that a drain moves 16 bytes at a time. First thing at
/// start-up (it empties the transmit FIFO).
pub fn init(uart_base: usize) {
    UART_BASE.store(uart_base, Ordering::Relaxed);
    if let Some(mut u) = uart() {
        u.enable_fifos();
    }
}

/// Send everything queued, waiting for the UART (start-up only).
pub fn flush() {
    let Some(mut u) = uart() else { return };
    let _ = with_rings(|r| {
        // Bounded: each round either moves bytes or finds the FIFO full;
        // a UART that never drains costs about 2 s, then the rest waits.
        for _ in 0..200_000 {
            if r.uart.is_empty() {
                break;
            }
            r.uart.drain(&mut u);
        }
    });
}

/// Blocking output for fault and panic handlers: empties the ring first.
#[derive(Clone, Copy, Debug, Default)]
pub struct Fault;

impl fmt::Write for Fault {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        flush();
        match uart() {
            Some(mut u) => u.write_str(s),
            None => Ok(()),
        }
    }
}

/// The log's newest lines, for `/log`.
#[derive(Clone, Copy, Debug, Default)]
pub struct Tail;

impl LogTail for Tail {
    fn tail(&self, out: &mut [u8]) -> usize {
        with_rings(|r| {
            let (old, new) = r.history.as_slices();
            copy_tail([old, new], r.history.len() == HISTORY_BYTES, out)
        })
        .unwrap_or(0)
    }
}
