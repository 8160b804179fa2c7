//! The ARM CoreLink L2C-310 (PL310) level 2 cache controller.
//!
//! Registers: CoreLink Level 2 Cache Controller L2C-310 Technical Reference
//! Manual (ARM DDI 0246), section 3.3 "Register summary"; the same offsets
//! as Linux `arch/arm/include/asm/hardware/cache-l2x0.h`. Bases: Cyclone V
//! 0xFFFE_F000, QEMU npcm750 0xF03F_C000 (docs/platform.md#two-targets).
//!
//! The cache sync (0x730) drains the controller's store buffer: Linux's
//! `wmb()` ends in it on this SoC (`arch/arm/include/asm/barrier.h`:
//! `dsb(st)` then `outer_sync()`, which for the L2C-310 is `l2c210_sync`,
//! a write of 0 to 0x730 with no poll), and the firmware's DMA hand-overs do
//! the same (see the `dwmac` crate's `sync` module). The Cyclone V reports
//! CACHE_ID 0x4100_30c9 (r3p3), on which background operations are atomic,
//! so no wait follows the sync.
//!
//! The by-address operations (invalidate 0x770, clean 0x7B0; also AMD
//! UG585 Zynq-7000 TRM, `reg7_inv_pa`) take the physical address of a
//! 32-byte line (the L2C-310's line length is fixed) and are atomic from
//! r3p0 on (DDI 0246H, "Cache maintenance operations": they stall the
//! slave ports until complete), so they are not polled either.
//! None of the controller errata Linux works around applies to r3p3
//! (`arch/arm/mm/cache-l2x0.c`: 588369 is r0p0-r1p0, 727915 r2p0, 753970
//! r3p0, 769419 r0p0-r3p1).

use core::mem::offset_of;
use core::ptr::NonNull;

use bitbybit::bitfield;
use volatile_register::{RO, RW};

/// Control register (0x100).
#[bitfield(u32, default = 0)]
#[derive(Debug, PartialEq, Eq)]
pub struct Control {
    /// L2 cache enable.
    #[bit(0, rw)]
    pub enable: bool,
}

/// Auxiliary control register (0x104), the field the driver reads.
#[bitfield(u32)]
#[derive(Debug, PartialEq, Eq)]
pub struct AuxControl {
    /// Associativity: 16 ways when set, 8 when clear.
    #[bit(16, r)]
    pub sixteen_ways: bool,
}

/// The registers used, at their offsets (reserved words in between).
#[repr(C)]
pub struct RegisterBlock {
    /// 0x000 cache ID (part, revision).
    pub cache_id: RO<u32>,
    /// 0x004 cache type.
    pub cache_type: RO<u32>,
    _r0: [u32; (0x100 - 0x008) / 4],
    /// 0x100 control.
    pub control: RW<Control>,
    /// 0x104 auxiliary control.
    pub aux_control: RW<AuxControl>,
    _r1: [u32; (0x730 - 0x108) / 4],
    /// 0x730 cache sync.
    pub cache_sync: RW<u32>,
    _r2: [u32; (0x770 - 0x734) / 4],
    /// 0x770 invalidate line by physical address.
    pub invalidate_line_pa: RW<u32>,
    _r3: [u32; (0x77c - 0x774) / 4],
    /// 0x77C invalidate by way.
    pub invalidate_way: RW<u32>,
    _r4: [u32; (0x7b0 - 0x780) / 4],
    /// 0x7B0 clean line by physical address.
    pub clean_line_pa: RW<u32>,
    _r5: [u32; (0x7fc - 0x7b4) / 4],
    /// 0x7FC clean and invalidate by way.
    pub clean_invalidate_way: RW<u32>,
}

const _: () = {
    assert!(offset_of!(RegisterBlock, control) == 0x100);
    assert!(offset_of!(RegisterBlock, aux_control) == 0x104);
    assert!(offset_of!(RegisterBlock, cache_sync) == 0x730);
    assert!(offset_of!(RegisterBlock, invalidate_line_pa) == 0x770);
    assert!(offset_of!(RegisterBlock, invalidate_way) == 0x77c);
    assert!(offset_of!(RegisterBlock, clean_line_pa) == 0x7b0);
    assert!(offset_of!(RegisterBlock, clean_invalidate_way) == 0x7fc);
    assert!(size_of::<RegisterBlock>() == 0x800);
};

/// A way operation did not finish within its poll budget.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WayOpTimeout;

impl core::fmt::Display for WayOpTimeout {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("L2C-310 way operation did not finish")
    }
}

impl core::error::Error for WayOpTimeout {}

/// The L2C-310's line length (fixed at 32 bytes; DDI 0246H).
pub const LINE_BYTES: usize = 32;

/// Register reads a whole-cache way operation may take (a 512 KiB cache is
/// 16,384 lines; each read is tens of nanoseconds).
pub const WAY_OP_POLLS: u32 = 1_000_000;

/// The L2 cache controller.
pub struct L2c310 {
    regs: NonNull<RegisterBlock>,
}

// SAFETY: the handle is the address of a fixed register block with no
// per-core state; the core that holds it may change (the firmware keeps it
// in a static cell).
unsafe impl Send for L2c310 {}

impl L2c310 {
    /// The controller whose registers are at `regs`.
    ///
    /// # Safety
    ///
    /// `regs` points to an L2C-310 register block (mapped Device or
    /// Strongly-ordered, or the MMU is off), or to memory laid out as one
    /// that outlives the value (host tests); only this value writes it.
    pub const unsafe fn new(regs: NonNull<RegisterBlock>) -> L2c310 {
        L2c310 { regs }
    }

    fn regs(&self) -> &RegisterBlock {
        // SAFETY: `new`'s contract; the fields are volatile cells.
        unsafe { self.regs.as_ref() }
    }

    /// The cache ID register (0x4100_30c9 on the Cyclone V: r3p3).
    pub fn cache_id(&self) -> u32 {
        self.regs().cache_id.read()
    }

    /// Whether the cache is on.
    pub fn is_enabled(&self) -> bool {
        self.regs().control.read().enable()
    }

    /// All ways of this configuration (8 or 16).
    pub fn way_mask(&self) -> u32 {
        if self.regs().aux_control.read().sixteen_ways() {
            0xffff
        } else {
            0xff
        }
    }

    /// Drain the store buffer: every earlier write has reached memory once
    /// this register write completes.
    #[inline]
    pub fn cache_sync(&self) {
        // SAFETY: a cache sync only drains buffers.
        unsafe { self.regs().cache_sync.write(0) }
    }

    /// Invalidate the line holding physical address `pa` (its data is
    /// discarded, dirty or not).
    ///
    /// # Safety
    ///
    /// The line holds no data the program still needs that only the cache
    /// has (it is clean, or its memory is about to be overwritten).
    #[inline]
    pub unsafe fn invalidate_line(&self, pa: u32) {
        // SAFETY: the caller's promise; the write only starts the operation.
        unsafe { self.regs().invalidate_line_pa.write(pa & !(LINE_BYTES as u32 - 1)) }
    }

    /// Write the line holding physical address `pa` back to memory if dirty
    /// (it stays valid).
    #[inline]
    pub fn clean_line(&self, pa: u32) {
        // SAFETY: cleaning writes dirty data back; nothing is lost.
        unsafe { self.regs().clean_line_pa.write(pa & !(LINE_BYTES as u32 - 1)) }
    }

    /// Invalidate every line (no write-back): before enabling, when the
    /// contents are stale (DDI 0246 2.3.1: the cache must be invalidated
    /// before it is enabled).
    pub fn invalidate_all(&self) -> Result<(), WayOpTimeout> {
        let mask = self.way_mask();
        // SAFETY: invalidating discards the cache's contents; the caller does
        // this only while the cache is off or its contents are clean.
        unsafe { self.regs().invalidate_way.write(mask) };
        self.wait_way(|r| r.invalidate_way.read())
    }

    /// Write back and invalidate every line.
    pub fn clean_invalidate_all(&self) -> Result<(), WayOpTimeout> {
        let mask = self.way_mask();
        // SAFETY: cleaning writes dirty lines back; nothing is lost.
        unsafe { self.regs().clean_invalidate_way.write(mask) };
        self.wait_way(|r| r.clean_invalidate_way.read())
    }

    fn wait_way(&self, pending: impl Fn(&RegisterBlock) -> u32) -> Result<(), WayOpTimeout> {
        for _ in 0..WAY_OP_POLLS {
            if pending(self.regs()) == 0 {
                self.cache_sync();
                return Ok(());
            }
        }
        Err(WayOpTimeout)
    }

    /// Whenever the enable bit (control register bit 0) is set, whatever
    /// the CPU's SCTLR says: clean and invalidate every way, cache sync, and
    /// turn the cache off, the L2C-310 TRM's order for disabling (DDI 0246,
    /// 2.3.1 and 3.3.10: clean and invalidate before the enable bit is
    /// cleared). A boot loader that ran `dcache off` (U-Boot's
    /// `cache_disable`: L1 and MMU off) leaves the L2 on. The cache goes off
    /// even when the way operation times out. Returns whether it was on.
    /// The firmware's reset entry does the same in assembly before any
    /// memory is written (firmware/src/start.rs).
    pub fn flush_and_disable(&self) -> Result<bool, WayOpTimeout> {
        if !self.is_enabled() {
            return Ok(false);
        }
        let cleaned = self.clean_invalidate_all();
        self.cache_sync();
        self.set_enabled(false);
        cleaned.map(|()| true)
    }

    /// Turn the cache on or off (call [`invalidate_all`](Self::invalidate_all)
    /// before turning it on, [`clean_invalidate_all`](Self::clean_invalidate_all)
    /// before turning it off).
    pub fn set_enabled(&self, on: bool) {
        // SAFETY: the caller keeps the contents consistent (see above).
        unsafe { self.regs().control.write(Control::DEFAULT.with_enable(on)) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block() -> Box<[u32; 0x200]> {
        Box::new([0; 0x200])
    }

    fn l2(words: &mut [u32; 0x200]) -> L2c310 {
        // SAFETY: the boxed words outlive the handle in each test.
        unsafe { L2c310::new(NonNull::new(words.as_mut_ptr().cast()).expect("box")) }
    }

    #[test]
    fn sync_writes_zero_to_0x730() {
        let mut w = block();
        w[0x730 / 4] = 0xdead_beef;
        l2(&mut w).cache_sync();
        assert_eq!(w[0x730 / 4], 0);
    }

    #[test]
    fn way_masks_follow_associativity_and_operations_complete() {
        let mut w = block();
        let c = l2(&mut w);
        // A fake whose way register never clears: the wait gives up.
        assert_eq!(c.way_mask(), 0xff);
        assert_eq!(c.invalidate_all(), Err(WayOpTimeout));
        assert_eq!(w[0x77c / 4], 0xff);
        w[0x104 / 4] = 1 << 16;
        w[0x77c / 4] = 0;
        let c = l2(&mut w);
        assert_eq!(c.way_mask(), 0xffff);
        c.set_enabled(true);
        assert!(c.is_enabled());
        assert_eq!(w[0x100 / 4], 1);
    }

    #[test]
    fn an_enabled_cache_is_cleaned_and_turned_off_and_a_disabled_one_left_alone() {
        let mut w = block();
        let c = l2(&mut w);
        assert_eq!(c.flush_and_disable(), Ok(false));
        assert!(w.iter().all(|x| *x == 0), "off: nothing written");

        // On, 16 ways, a sync register holding junk; the fake's way register
        // keeps the written mask, so the wait runs out.
        w[0x100 / 4] = 1;
        w[0x104 / 4] = 1 << 16;
        w[0x730 / 4] = 0xdead_beef;
        let c = l2(&mut w);
        assert_eq!(c.flush_and_disable(), Err(WayOpTimeout));
        assert_eq!(w[0x7fc / 4], 0xffff, "clean and invalidate all 16 ways");
        assert_eq!(w[0x730 / 4], 0, "cache sync");
        assert_eq!(w[0x100 / 4], 0, "off even after the time-out");
        assert_eq!(w[0x77c / 4], 0, "no invalidate-only way operation: dirty lines are written back");
    }

    #[test]
    fn line_operations_write_the_line_address_to_their_registers() {
        let mut w = block();
        let c = l2(&mut w);
        // SAFETY: a fake register block; no cache is involved.
        unsafe { c.invalidate_line(0x0410_0025) };
        c.clean_line(0x0410_1fff);
        assert_eq!(w[0x770 / 4], 0x0410_0020);
        assert_eq!(w[0x7b0 / 4], 0x0410_1fe0);
    }
}
