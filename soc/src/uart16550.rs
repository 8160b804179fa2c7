//! A 16550-compatible UART with 32-bit registers at a stride of 4: the
//! Synopsys DesignWare APB UART of the Cyclone V HPS and the NPCM7xx UART
//! QEMU models. Transmit only; the boot loader (or QEMU) set the baud rate
//! and line format.
//!
//! Registers: TI PC16550D data sheet, table 2 (register numbers) and 8.4
//! (LSR), 8.5 (FCR); Cyclone V HPS TRM (cv_5v4), UART chapter, register map
//! (`rbr_thr_dll` 0x00 .. `lsr` 0x14, 32-bit stride).

use core::mem::offset_of;
use core::ptr::NonNull;

use bitbybit::bitfield;
use volatile_register::{RO, RW, WO};

/// Line status register (0x14).
#[bitfield(u32)]
#[derive(Debug, PartialEq, Eq)]
pub struct Lsr {
    /// TEMT: transmitter (FIFO and shift register) empty.
    #[bit(6, r)]
    pub temt: bool,
    /// THRE: transmit holding register (with FIFOs on: the TX FIFO) empty.
    #[bit(5, r)]
    pub thre: bool,
}

/// FIFO control register (0x08, write-only).
#[bitfield(u32, default = 0)]
#[derive(Debug, PartialEq, Eq)]
pub struct Fcr {
    /// XFIFOR: reset the transmit FIFO.
    #[bit(2, w)]
    pub xfifor: bool,
    /// FIFOE: FIFOs on.
    #[bit(0, w)]
    pub fifoe: bool,
}

/// Bytes the transmit FIFO holds (16550: 16; the Cyclone V UART has 128,
/// so 16 is safe on both).
pub const TX_FIFO_DEPTH: usize = 16;

/// The registers the driver uses.
#[repr(C)]
pub struct RegisterBlock {
    /// 0x00 transmit holding register (write).
    pub thr: WO<u32>,
    /// 0x04 interrupt enable.
    pub ier: RW<u32>,
    /// 0x08 FIFO control (write).
    pub fcr: WO<Fcr>,
    /// 0x0c line control.
    pub lcr: RW<u32>,
    /// 0x10 modem control.
    pub mcr: RW<u32>,
    /// 0x14 line status.
    pub lsr: RO<Lsr>,
}

const _: () = {
    assert!(offset_of!(RegisterBlock, thr) == 0x00);
    assert!(offset_of!(RegisterBlock, fcr) == 0x08);
    assert!(offset_of!(RegisterBlock, lsr) == 0x14);
    assert!(size_of::<RegisterBlock>() == 0x18);
};

/// How many LSR polls [`Uart16550::write_blocking`] waits for room per byte
/// before dropping it: a UART that never drains must not hang a fault
/// handler (one byte at 115,200 baud is 87 us; a poll takes well over 10 ns).
pub const MAX_POLLS: u32 = 200_000;

/// A 16550 UART.
pub struct Uart16550 {
    regs: NonNull<RegisterBlock>,
}

impl Uart16550 {
    /// The UART at `regs`; no register is touched until the first call.
    ///
    /// # Safety
    ///
    /// `regs` points to a 16550 register block at a 4-byte stride (mapped
    /// Device, or the MMU is off), or to memory laid out as one that outlives
    /// the value (host tests). Several handles may write the same UART (the
    /// log and the panic handler): a byte interleaved with another writer's
    /// is the only consequence.
    pub const unsafe fn new(regs: NonNull<RegisterBlock>) -> Uart16550 {
        Uart16550 { regs }
    }

    fn regs(&self) -> &RegisterBlock {
        // SAFETY: `new`'s contract; the fields are volatile cells.
        unsafe { self.regs.as_ref() }
    }

    /// Turn the FIFOs on (and empty the transmit FIFO), so that
    /// [`room`](Self::room) may report [`TX_FIFO_DEPTH`] bytes.
    pub fn enable_fifos(&mut self) {
        // SAFETY: FIFO control only changes buffering.
        unsafe { self.regs().fcr.write(Fcr::DEFAULT.with_fifoe(true).with_xfifor(true)) }
    }

    /// Bytes that can be written now without waiting: the whole FIFO when
    /// it is empty, else none (the 16550 only reports "empty").
    pub fn room(&mut self) -> usize {
        if self.regs().lsr.read().thre() {
            TX_FIFO_DEPTH
        } else {
            0
        }
    }

    /// Write one byte without checking for room.
    pub fn write_unchecked(&mut self, byte: u8) {
        // SAFETY: a THR write queues one byte for transmission.
        unsafe { self.regs().thr.write(u32::from(byte)) }
    }

    /// Write one byte, waiting (boundedly) for the holding register; returns
    /// `false` if the byte was dropped because the UART never drained.
    pub fn write_blocking(&mut self, byte: u8) -> bool {
        for _ in 0..MAX_POLLS {
            if self.regs().lsr.read().thre() {
                self.write_unchecked(byte);
                return true;
            }
            core::hint::spin_loop();
        }
        false
    }
}

impl crate::log::Transmit for Uart16550 {
    fn room(&mut self) -> usize {
        Uart16550::room(self)
    }

    fn push(&mut self, byte: u8) {
        self.write_unchecked(byte)
    }
}

/// Blocking text output (`\n` becomes `\r\n`) for the panic and fault
/// handlers, where nothing may be deferred.
impl core::fmt::Write for Uart16550 {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for b in s.bytes() {
            if b == b'\n' {
                self.write_blocking(b'\r');
            }
            self.write_blocking(b);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::fmt::Write;

    fn uart(words: &mut [u32; 6]) -> Uart16550 {
        // SAFETY: `words` outlives the UART and covers offsets 0..0x18.
        unsafe { Uart16550::new(NonNull::new(words.as_mut_ptr().cast()).expect("array")) }
    }

    #[test]
    fn writes_bytes_when_the_transmitter_is_empty() {
        let mut w = [0u32; 6];
        w[5] = 1 << 5; // LSR.THRE
        let mut u = uart(&mut w);
        u.write_str("A\n").unwrap();
        assert_eq!(u.room(), TX_FIFO_DEPTH);
        u.enable_fifos();
        // The last byte written is the '\n' after the inserted '\r'.
        assert_eq!(w[0], u32::from(b'\n'));
        assert_eq!(w[2], 0b101, "FIFO enable and TX FIFO reset");
    }

    #[test]
    fn a_full_transmitter_drops_bytes_instead_of_hanging() {
        let mut w = [0u32; 6];
        let mut u = uart(&mut w);
        assert!(!u.write_blocking(b'x'));
        assert_eq!(u.room(), 0);
        assert_eq!(w[0], 0);
    }
}
