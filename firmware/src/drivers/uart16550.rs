//! Transmit-only driver for a 16550-compatible UART with 32-bit registers at
//! a stride of 4 (the DesignWare APB UART of the Cyclone V HPS and the NPCM7xx
//! UART). Baud rate and line format are left as the boot loader (or QEMU)
//! set them.

use core::fmt;

use super::mmio::Mmio;

/// Transmit holding register (write): register 0, offset 0x00.
/// Source: TI PC16550D data sheet, table 2 (register 0 = THR on write).
pub const THR: usize = 0x00;
/// Line status register: register 5 at a stride of 4 = offset 0x14.
/// Source: TI PC16550D data sheet, table 2; Cyclone V HPS TRM (cv_5v4),
/// UART chapter, register `lsr` at offset 0x14.
pub const LSR: usize = 0x14;
/// LSR bit 5, THRE: the transmit holding register is empty.
/// Source: TI PC16550D data sheet, section 8.4 (LSR bit 5).
pub const LSR_THRE: u32 = 1 << 5;

/// How many LSR polls to wait for room before dropping a byte: a UART that
/// never drains must not hang the firmware (about 1 ms at 115,200 baud is
/// 90 us per byte; a poll takes well over 10 ns).
pub const MAX_POLLS: u32 = 200_000;

/// A 16550 UART used for the log.
pub struct Uart16550 {
    regs: Mmio,
    dropped: u32,
}

impl Uart16550 {
    /// A UART at `regs`; no register is touched until the first write.
    pub const fn new(regs: Mmio) -> Uart16550 {
        Uart16550 { regs, dropped: 0 }
    }

    /// Send one byte, waiting (boundedly) for room in the transmitter.
    pub fn write_byte(&mut self, byte: u8) {
        let mut polls = 0;
        while self.regs.read(LSR) & LSR_THRE == 0 {
            polls += 1;
            if polls >= MAX_POLLS {
                self.dropped = self.dropped.saturating_add(1);
                return;
            }
            core::hint::spin_loop();
        }
        self.regs.write(THR, u32::from(byte));
    }

    /// Bytes dropped because the transmitter stayed full.
    pub fn dropped(&self) -> u32 {
        self.dropped
    }
}

impl fmt::Write for Uart16550 {
    /// Write `s`, turning `\n` into `\r\n` for terminals.
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for b in s.bytes() {
            if b == b'\n' {
                self.write_byte(b'\r');
            }
            self.write_byte(b);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::fmt::Write;

    #[test]
    fn writes_bytes_to_thr_when_the_transmitter_is_empty() {
        let mut regs = [0u32; 8];
        regs[LSR / 4] = LSR_THRE;
        // SAFETY: `regs` outlives the UART and covers offsets 0..0x20.
        let mut uart = Uart16550::new(unsafe { Mmio::new(regs.as_mut_ptr() as usize) });
        uart.write_str("A\n").unwrap();
        // The last byte written is the '\n' after the inserted '\r'.
        assert_eq!(regs[THR / 4], u32::from(b'\n'));
        assert_eq!(uart.dropped(), 0);
    }

    #[test]
    fn a_full_transmitter_drops_bytes_instead_of_hanging() {
        let mut regs = [0u32; 8];
        // SAFETY: as above.
        let mut uart = Uart16550::new(unsafe { Mmio::new(regs.as_mut_ptr() as usize) });
        uart.write_byte(b'x');
        assert_eq!(uart.dropped(), 1);
        assert_eq!(regs[THR / 4], 0);
    }
}
