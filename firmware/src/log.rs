//! The UART log: [`Log`] queues text in a ring buffer that the main loop
//! drains as the UART's FIFO takes it ([`drain`]), so a log line costs the
//! A9 a copy, not milliseconds at 115,200 baud. Start-up, which waits
//! anyway, flushes after each step ([`flush`]); fault handlers write through
//! [`Fault`], which empties the ring first and then writes directly.

use core::cell::UnsafeCell;
use core::fmt;
use core::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use soc::log::LogRing;
use soc::uart16550::Uart16550;

/// Bytes the ring holds (about a hundred log lines).
const RING_BYTES: usize = 8192;

/// The ring, with a flag that makes a re-entrant use (a fault while the
/// main loop is inside the ring) skip instead of aliasing it.
struct Shared {
    ring: UnsafeCell<LogRing<RING_BYTES>>,
    busy: AtomicBool,
}

// SAFETY: one core, no interrupt handlers; exception handlers that may
// interrupt a ring access find `busy` set and leave the ring alone.
unsafe impl Sync for Shared {}

static SHARED: Shared = Shared { ring: UnsafeCell::new(LogRing::new()), busy: AtomicBool::new(false) };

/// Run `f` on the ring unless it is already in use.
fn with_ring<R>(f: impl FnOnce(&mut LogRing<RING_BYTES>) -> R) -> Option<R> {
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
        let _ = with_ring(|r| r.write_str(s));
        Ok(())
    }
}

/// Move what the UART's FIFO takes now; never waits.
pub fn drain() {
    if let Some(mut u) = uart() {
        let _ = with_ring(|r| r.drain(&mut u));
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
    let _ = with_ring(|r| {
        // Bounded: each round either moves bytes or finds the FIFO full;
        // a UART that never drains costs about 2 s, then the rest waits.
        for _ in 0..200_000 {
            if r.is_empty() {
                break;
            }
            r.drain(&mut u);
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
