//! A block of 32-bit memory-mapped registers.

/// Base address of a block of 32-bit device registers, read and written
/// with volatile accesses at byte offsets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mmio {
    base: usize,
}

impl Mmio {
    /// A register block at `base`.
    ///
    /// # Safety
    ///
    /// `base + offset` must be valid for 32-bit volatile reads and writes
    /// for every offset the owner of this value will use: a device register
    /// block (mapped as device or strongly-ordered memory on the target), or
    /// plain memory that lives as long as this value (host tests). Whoever
    /// holds a copy may touch the registers, so copies must stay within one
    /// driver.
    pub const unsafe fn new(base: usize) -> Mmio {
        Mmio { base }
    }

    /// The base address.
    pub const fn base(&self) -> usize {
        self.base
    }

    /// Read the register at byte offset `offset`.
    #[inline]
    pub fn read(&self, offset: usize) -> u32 {
        // SAFETY: `new`'s contract makes `base + offset` a valid, aligned
        // 32-bit register for this block.
        unsafe { core::ptr::read_volatile((self.base + offset) as *const u32) }
    }

    /// Write `value` to the register at byte offset `offset`.
    #[inline]
    pub fn write(&self, offset: usize, value: u32) {
        // SAFETY: as in `read`.
        unsafe { core::ptr::write_volatile((self.base + offset) as *mut u32, value) }
    }

    /// Read-modify-write the register at `offset`.
    #[inline]
    pub fn modify(&self, offset: usize, f: impl FnOnce(u32) -> u32) {
        let v = self.read(offset);
        self.write(offset, f(v));
    }
}
