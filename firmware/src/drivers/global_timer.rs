//! The Cortex-A9 MPCore global timer: a 64-bit up-counter clocked by
//! PERIPHCLK, used as the firmware's monotonic clock (smoltcp's `Instant`).
//!
//! Register offsets: ARM Cortex-A9 MPCore TRM (DDI 0407), section 4.3
//! "Global timer", table 4-6 (relative to PERIPHBASE + 0x200).

use super::clock::Clock;
use super::mmio::Mmio;

/// Counter bits 31:0.
pub const COUNTER_LO: usize = 0x00;
/// Counter bits 63:32.
pub const COUNTER_HI: usize = 0x04;
/// Control: bit 0 timer enable, bits 15:8 prescaler (DDI 0407 4.3.2).
pub const CONTROL: usize = 0x08;
/// Control bit 0: the counter runs.
pub const CONTROL_ENABLE: u32 = 1 << 0;

/// The global timer.
pub struct GlobalTimer {
    regs: Mmio,
    hz: u32,
}

impl GlobalTimer {
    /// The timer at `regs` (PERIPHBASE + 0x200), counting at `hz`
    /// (PERIPHCLK with prescaler 0).
    pub const fn new(regs: Mmio, hz: u32) -> GlobalTimer {
        GlobalTimer { regs, hz }
    }

    /// Start counting with prescaler 0; a running counter keeps its value.
    pub fn start(&self) {
        self.regs.write(CONTROL, CONTROL_ENABLE);
    }

    /// Counter frequency in Hz.
    pub fn hz(&self) -> u32 {
        self.hz
    }

    /// The 64-bit counter, read high-low-high so a carry between the two
    /// halves is never seen (DDI 0407 4.3.1).
    pub fn ticks(&self) -> u64 {
        loop {
            let hi = self.regs.read(COUNTER_HI);
            let lo = self.regs.read(COUNTER_LO);
            if self.regs.read(COUNTER_HI) == hi {
                return (u64::from(hi) << 32) | u64::from(lo);
            }
        }
    }

    /// Nanoseconds since the counter started.
    pub fn now_ns(&self) -> u64 {
        ticks_to_ns(self.ticks(), self.hz)
    }

    /// Now, as a smoltcp instant.
    pub fn instant(&self) -> smoltcp::time::Instant {
        smoltcp::time::Instant::from_micros(i64::try_from(self.now_us()).unwrap_or(i64::MAX))
    }
}

impl Clock for GlobalTimer {
    fn now_us(&self) -> u64 {
        ticks_to_us(self.ticks(), self.hz)
    }
}

/// Convert `ticks` of a `hz` counter to microseconds without overflow for
/// any 64-bit tick count (and without 128-bit division).
pub const fn ticks_to_us(ticks: u64, hz: u32) -> u64 {
    if hz == 0 {
        return 0;
    }
    let hz = hz as u64;
    (ticks / hz) * 1_000_000 + (ticks % hz) * 1_000_000 / hz
}

/// Convert `ticks` of a `hz` counter to nanoseconds (saturating after
/// about 584 years).
pub const fn ticks_to_ns(ticks: u64, hz: u32) -> u64 {
    if hz == 0 {
        return 0;
    }
    let hz = hz as u64;
    (ticks / hz).saturating_mul(1_000_000_000).saturating_add((ticks % hz) * 1_000_000_000 / hz)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_convert_to_microseconds() {
        assert_eq!(ticks_to_us(100, 100_000_000), 1);
        assert_eq!(ticks_to_us(150_000_000, 100_000_000), 1_500_000);
        // 231.25 MHz (a 925 MHz MPU clock / 4): not a whole number of MHz.
        assert_eq!(ticks_to_us(231_250_000 * 3 + 231_250, 231_250_000), 3_001_000);
        // No overflow near the top of the counter.
        assert_eq!(ticks_to_us(u64::MAX, 200_000_000), u64::MAX / 200);
        assert_eq!(ticks_to_us(5, 0), 0);
        assert_eq!(ticks_to_ns(7, 100_000_000), 70);
        assert_eq!(ticks_to_ns(200_000_001, 200_000_000), 1_000_000_005);
    }

    #[test]
    fn reads_the_64_bit_counter() {
        let mut regs = [0u32; 4];
        regs[COUNTER_LO / 4] = 50;
        regs[COUNTER_HI / 4] = 1;
        // SAFETY: `regs` outlives the timer and covers 0..0x10.
        let t = GlobalTimer::new(unsafe { Mmio::new(regs.as_mut_ptr() as usize) }, 100_000_000);
        t.start();
        assert_eq!(t.ticks(), (1 << 32) + 50);
        assert_eq!(t.now_us(), ((1u64 << 32) + 50) / 100);
        drop(t);
        assert_eq!(regs[CONTROL / 4], CONTROL_ENABLE);
    }
}
