//! The Cortex-A9 MPCore global timer: a 64-bit up-counter clocked by
//! PERIPHCLK, the firmware's monotonic clock.
//!
//! Registers: ARM Cortex-A9 MPCore Technical Reference Manual (DDI 0407),
//! section 4.3 "Global timer", table 4-6, at PERIPHBASE + 0x200.
//! PERIPHCLK on the Cyclone V is `mpu_periph_clk` = MPU clock / 4 (Cyclone V
//! TRM, clock manager; Linux `socfpga.dtsi` fixed-factor clock
//! `mpu_periph_clk`, divider 4); the rate is set at boot from the clock
//! manager ([`crate::cyclone_v::mpu_clock_hz`]). QEMU's A9 model runs it at
//! 100 MHz (`hw/timer/a9gtimer.c`, a tick every 10 ns at prescaler 0).

use core::mem::offset_of;
use core::ptr::NonNull;
use core::sync::atomic::{AtomicU32, Ordering};

use bitbybit::bitfield;
use volatile_register::{RO, RW};

/// Offset of the global timer in the MPCore private region.
pub const PERIPHBASE_OFFSET: usize = 0x200;

/// Control register (0x08).
#[bitfield(u32, default = 0)]
#[derive(Debug, PartialEq, Eq)]
pub struct Control {
    /// Prescaler: the counter increments every `prescaler + 1` PERIPHCLK.
    #[bits(8..=15, rw)]
    pub prescaler: u8,
    /// Timer enable.
    #[bit(0, rw)]
    pub enable: bool,
}

/// The global timer's registers (the comparator is not used).
#[repr(C)]
pub struct RegisterBlock {
    /// 0x00 counter bits 31:0.
    pub counter_lo: RO<u32>,
    /// 0x04 counter bits 63:32.
    pub counter_hi: RO<u32>,
    /// 0x08 control.
    pub control: RW<Control>,
}

const _: () = {
    assert!(offset_of!(RegisterBlock, counter_lo) == 0x00);
    assert!(offset_of!(RegisterBlock, counter_hi) == 0x04);
    assert!(offset_of!(RegisterBlock, control) == 0x08);
    assert!(size_of::<RegisterBlock>() == 0x0c);
};

/// The global timer and the rate it counts at.
pub struct GlobalTimer {
    regs: NonNull<RegisterBlock>,
    hz: AtomicU32,
}

// SAFETY: the handle is only read from (the counter) and written once at
// start-up on one core; no interrupt handler uses it. Sharing it as a
// `static` between the main loop and the fault handlers is sound.
unsafe impl Sync for GlobalTimer {}

impl GlobalTimer {
    /// The timer whose registers are at `regs` (PERIPHBASE + 0x200), counting
    /// at `hz` until [`set_rate`](Self::set_rate) says otherwise.
    ///
    /// # Safety
    ///
    /// `regs` points to the global timer's register block (mapped Device or
    /// Strongly-ordered), or to memory laid out as one that lives as long as
    /// the value (host tests); only this value writes its control register.
    pub const unsafe fn new(regs: NonNull<RegisterBlock>, hz: u32) -> GlobalTimer {
        GlobalTimer { regs, hz: AtomicU32::new(hz) }
    }

    fn regs(&self) -> &RegisterBlock {
        // SAFETY: `new`'s contract; the fields are volatile cells.
        unsafe { self.regs.as_ref() }
    }

    /// Start counting with prescaler 0; a running counter keeps its value.
    pub fn start(&self) {
        // SAFETY: enabling the counter is its only effect.
        unsafe { self.regs().control.write(Control::DEFAULT.with_enable(true)) }
    }

    /// Set the counting rate (PERIPHCLK), as measured from the clocks.
    pub fn set_rate(&self, hz: u32) {
        self.hz.store(hz, Ordering::Relaxed);
    }

    /// Counter frequency in Hz.
    pub fn hz(&self) -> u32 {
        self.hz.load(Ordering::Relaxed)
    }

    /// The 64-bit counter, read high-low-high so a carry between the two
    /// halves is never seen (DDI 0407 4.3.1).
    pub fn ticks(&self) -> u64 {
        let r = self.regs();
        loop {
            let hi = r.counter_hi.read();
            let lo = r.counter_lo.read();
            if r.counter_hi.read() == hi {
                return (u64::from(hi) << 32) | u64::from(lo);
            }
        }
    }

    /// The counter's low 32 bits (one register read): for intervals
    /// shorter than its wrap (42.9 s at 100 MHz), as `wrapping_sub`.
    #[inline]
    pub fn ticks_low(&self) -> u32 {
        self.regs().counter_lo.read()
    }

    /// Microseconds since the counter started.
    pub fn now_us(&self) -> u64 {
        ticks_to_us(self.ticks(), self.hz())
    }

    /// Nanoseconds since the counter started.
    pub fn now_ns(&self) -> u64 {
        ticks_to_ns(self.ticks(), self.hz())
    }

    /// Busy-wait `ns` nanoseconds (at least one tick).
    pub fn spin_ns(&self, ns: u32) {
        let start = self.ticks();
        let ticks = (u64::from(ns) * u64::from(self.hz())).div_ceil(1_000_000_000).max(1);
        while self.ticks().wrapping_sub(start) < ticks {
            core::hint::spin_loop();
        }
    }
}

/// An `embedded-hal` delay on the global timer.
#[derive(Clone, Copy)]
pub struct TimerDelay<'t>(pub &'t GlobalTimer);

impl embedded_hal::delay::DelayNs for TimerDelay<'_> {
    fn delay_ns(&mut self, ns: u32) {
        self.0.spin_ns(ns)
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
    fn reads_the_64_bit_counter_and_starts() {
        let mut words = [50u32, 1, 0];
        let regs = NonNull::new(words.as_mut_ptr().cast::<RegisterBlock>()).expect("array");
        // SAFETY: `words` outlives the timer and is laid out as the block.
        let t = unsafe { GlobalTimer::new(regs, 100_000_000) };
        t.start();
        assert_eq!(t.ticks(), (1 << 32) + 50);
        assert_eq!(t.now_us(), ((1u64 << 32) + 50) / 100);
        t.set_rate(200_000_000);
        assert_eq!(t.now_us(), ((1u64 << 32) + 50) / 200);
        assert_eq!(words[2], 1, "enable, prescaler 0");
    }
}
