//! The UART log: a zero-sized writer usable anywhere, exception handlers
//! and the panic handler included.

use core::fmt;

use firmware::drivers::mmio::Mmio;
use firmware::drivers::uart16550::Uart16550;

use crate::boards::board;

/// Writes to the board's UART0.
#[derive(Clone, Copy, Debug, Default)]
pub struct Log;

impl fmt::Write for Log {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        // SAFETY: UART0_BASE is the board's 16550 register block, mapped as
        // device memory (or the MMU is off); only transmit registers are
        // touched, and a byte interleaved with another writer is harmless.
        let mut uart = Uart16550::new(unsafe { Mmio::new(board::UART0_BASE) });
        uart.write_str(s)
    }
}
