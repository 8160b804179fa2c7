//! Cache maintenance by address for memory another bus master shares
//! without coherence: the FPGA's frame DMA writes the frame ring through the
//! FPGA-to-SDRAM port, which goes straight to the SDRAM controller, past
//! both the A9's L1 and the L2C-310 (docs/frame-dma.md#caches).
//!
//! The sequences are the L2C-310 TRM's robust code sequences for a
//! non-exclusive L1/L2 arrangement (ARM DDI 0246H, r3p3; the
//! same order as Linux `arch/arm/mm/dma-mapping.c`, outer before inner when
//! the device wrote, inner before outer when the CPU did):
//!
//! * before the CPU reads what a device wrote ([`invalidate_for_cpu`]):
//!   invalidate L2 by address, cache sync, `dsb`, invalidate L1 by address,
//!   `dsb`. Invalidating L1 first would let a speculative line fill between
//!   the two steps bring the stale L2 copy back into L1; the `dsb` after the
//!   sync makes the L2 operations complete before the first L1 invalidate
//!   (a CP15 operation is not ordered after an earlier store to the L2C's
//!   registers without one: ARM DDI 0406C, B2.2.9).
//! * after the CPU wrote what a device reads, or overwrites ([`clean_for_device`]):
//!   clean L1 by address, `dsb`, clean L2 by address, cache sync. A dirty
//!   line left behind could be evicted over the device's later writes.
//!
//! Both caches have 32-byte lines (Cortex-A9 TRM DDI 0388 7.1; L2C-310
//! fixed), and the firmware's map is flat, so a line's virtual and physical
//! addresses are the same. Only whole lines are invalidated: a range that
//! does not start and end on line boundaries is refused ([`Lines::exact`]),
//! since invalidating a partly covered line would discard its neighbour's
//! data; cleaning may round out ([`Lines::covering`]).

use core::ops::Range;

/// The line length of both cache levels.
pub const LINE_BYTES: usize = 32;

/// The operations the sequences are made of. The firmware implements them
/// with CP15 and the L2C-310; tests record them.
pub trait CacheOps {
    /// L1 data cache: invalidate the line at `addr` (DCIMVAC).
    fn l1_invalidate(&self, addr: usize);
    /// L1 data cache: clean the line at `addr` to the point of coherence
    /// (DCCMVAC), which on this core is the L2C-310's side.
    fn l1_clean(&self, addr: usize);
    /// L2: invalidate the line at `addr`.
    fn l2_invalidate(&self, addr: usize);
    /// L2: clean the line at `addr`.
    fn l2_clean(&self, addr: usize);
    /// L2: cache sync (wait until the operations above are done and the
    /// store buffer is drained).
    fn l2_sync(&self);
    /// Data synchronization barrier.
    fn dsb(&self);
}

/// A range of whole cache lines.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Lines(Range<usize>);

impl Lines {
    /// The lines of `start..start + len`, if it begins and ends on line
    /// boundaries.
    pub fn exact(start: usize, len: usize) -> Option<Lines> {
        let end = start.checked_add(len)?;
        (start.is_multiple_of(LINE_BYTES) && end.is_multiple_of(LINE_BYTES)).then_some(Lines(start..end))
    }

    /// The lines `start..start + len` touches, rounded out to line
    /// boundaries: for cleaning, which never loses data, so a partly
    /// covered line may be included.
    pub fn covering(start: usize, len: usize) -> Option<Lines> {
        let end = start.checked_add(len)?.checked_next_multiple_of(LINE_BYTES)?;
        Some(Lines(start - start % LINE_BYTES..end))
    }

    /// How many lines.
    pub fn count(&self) -> usize {
        (self.0.end - self.0.start) / LINE_BYTES
    }

    fn addrs(&self) -> impl Iterator<Item = usize> {
        self.0.clone().step_by(LINE_BYTES)
    }
}

/// Make what a device wrote to `lines` visible to the CPU's next loads.
///
/// # Safety
///
/// The lines hold nothing the CPU wrote that has not reached memory (they
/// are clean: every CPU write to them went through [`clean_for_device`]),
/// or losing it is intended.
#[inline]
pub unsafe fn invalidate_for_cpu(ops: &impl CacheOps, lines: &Lines) {
    for a in lines.addrs() {
        ops.l2_invalidate(a);
    }
    ops.l2_sync();
    ops.dsb();
    for a in lines.addrs() {
        ops.l1_invalidate(a);
    }
    ops.dsb();
}

/// Write what the CPU wrote to `lines` back to memory, for a device to read
/// (or before a device overwrites it).
#[inline]
pub fn clean_for_device(ops: &impl CacheOps, lines: &Lines) {
    for a in lines.addrs() {
        ops.l1_clean(a);
    }
    ops.dsb();
    for a in lines.addrs() {
        ops.l2_clean(a);
    }
    ops.l2_sync();
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::RefCell;

    #[derive(Debug, PartialEq, Clone, Copy)]
    enum Op {
        L1Inv(usize),
        L1Clean(usize),
        L2Inv(usize),
        L2Clean(usize),
        Sync,
        Dsb,
    }

    #[derive(Default)]
    struct Record(RefCell<Vec<Op>>);

    impl CacheOps for Record {
        fn l1_invalidate(&self, a: usize) {
            self.0.borrow_mut().push(Op::L1Inv(a));
        }
        fn l1_clean(&self, a: usize) {
            self.0.borrow_mut().push(Op::L1Clean(a));
        }
        fn l2_invalidate(&self, a: usize) {
            self.0.borrow_mut().push(Op::L2Inv(a));
        }
        fn l2_clean(&self, a: usize) {
            self.0.borrow_mut().push(Op::L2Clean(a));
        }
        fn l2_sync(&self) {
            self.0.borrow_mut().push(Op::Sync);
        }
        fn dsb(&self) {
            self.0.borrow_mut().push(Op::Dsb);
        }
    }

    #[test]
    fn only_whole_lines_are_accepted() {
        assert_eq!(Lines::exact(0x1000, 1440).map(|l| l.count()), Some(45), "a row is 45 lines");
        assert_eq!(Lines::exact(0x1000, 0).map(|l| l.count()), Some(0));
        assert!(Lines::exact(0x1004, 32).is_none(), "start inside a line");
        assert!(Lines::exact(0x1000, 40).is_none(), "end inside a line");
        assert!(Lines::exact(usize::MAX - 31, 64).is_none(), "wraps");
        assert_eq!(Lines::covering(0x1004, 40), Lines::exact(0x1000, 64), "rounded out both ways");
        assert_eq!(Lines::covering(0x1000, 32), Lines::exact(0x1000, 32));
        assert!(Lines::covering(usize::MAX - 8, 4).is_none(), "wraps");
    }

    #[test]
    fn invalidation_goes_outer_first_then_inner_then_barrier() {
        let r = Record::default();
        // SAFETY: a recording fake; no cache is touched.
        unsafe { invalidate_for_cpu(&r, &Lines::exact(0x40, 64).expect("whole lines")) };
        use Op::*;
        assert_eq!(*r.0.borrow(), [L2Inv(0x40), L2Inv(0x60), Sync, Dsb, L1Inv(0x40), L1Inv(0x60), Dsb]);
    }

    #[test]
    fn cleaning_goes_inner_first_then_outer_then_sync() {
        let r = Record::default();
        clean_for_device(&r, &Lines::exact(0x40, 64).expect("whole lines"));
        use Op::*;
        assert_eq!(*r.0.borrow(), [L1Clean(0x40), L1Clean(0x60), Dsb, L2Clean(0x40), L2Clean(0x60), Sync]);
    }
}
