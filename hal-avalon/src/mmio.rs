//! Memory-mapped access to the accelerator on the board.
//!
//! [`RegisterBlock`] lays the CSR block and the line buffer out at the
//! offsets of [`crate::map`]; [`Mmio`] is the [`RegisterPort`] over it. This
//! module holds the crate's only raw-pointer code: [`Mmio::new`].

use volatile_register::{RO, RW, WO};

use crate::map::{Csr, CSR_OFFSET, LINE_BUFFER_OFFSET, LINE_WORDS, LW_BRIDGE_BASE};
use crate::port::RegisterPort;

/// The CSR block, at [`CSR_OFFSET`] of the bridge window.
#[repr(C)]
pub struct CsrBlock {
    /// `0x00` CONTROL.
    pub control: WO<u32>,
    /// `0x04` STATUS.
    pub status: RO<u32>,
    /// `0x08` ROW_Y.
    pub row_y: RW<u32>,
    /// `0x0C` LIGHT_X.
    pub light_x: RW<u32>,
    /// `0x10` LIGHT_Y.
    pub light_y: RW<u32>,
    /// `0x14` LIGHT_Z.
    pub light_z: RW<u32>,
    /// `0x18` ID.
    pub id: RO<u32>,
}

/// Words between the end of the CSR block and the line buffer.
const GAP_WORDS: usize = (LINE_BUFFER_OFFSET - CSR_OFFSET - core::mem::size_of::<CsrBlock>()) / 4;

/// The accelerator's whole address range: CSR block, then line buffer.
#[repr(C)]
pub struct RegisterBlock {
    /// The CSR block.
    pub csr: CsrBlock,
    // Unmapped CSR offsets: never accessed.
    _reserved: [RO<u32>; GAP_WORDS],
    /// The line buffer: pixel `x` at word `x`, `0x00RRGGBB`.
    pub line: [RO<u32>; LINE_WORDS],
}

// The layout is the register map.
const _: () = {
    use core::mem::offset_of;
    assert!(offset_of!(RegisterBlock, csr) == 0);
    assert!(offset_of!(CsrBlock, control) == Csr::Control.offset());
    assert!(offset_of!(CsrBlock, status) == Csr::Status.offset());
    assert!(offset_of!(CsrBlock, row_y) == Csr::RowY.offset());
    assert!(offset_of!(CsrBlock, light_x) == Csr::LightX.offset());
    assert!(offset_of!(CsrBlock, light_y) == Csr::LightY.offset());
    assert!(offset_of!(CsrBlock, light_z) == Csr::LightZ.offset());
    assert!(offset_of!(CsrBlock, id) == Csr::Id.offset());
    assert!(offset_of!(RegisterBlock, line) == LINE_BUFFER_OFFSET - CSR_OFFSET);
};

/// The accelerator's registers through memory-mapped I/O: the board's
/// [`RegisterPort`].
pub struct Mmio {
    regs: &'static RegisterBlock,
}

// SAFETY: `Mmio` owns its register block exclusively (the contract of
// `Mmio::new`); moving that ownership to another execution context is sound.
unsafe impl Send for Mmio {}

impl Mmio {
    /// The accelerator at the address the FPGA design places it: the
    /// lightweight bridge base plus [`CSR_OFFSET`].
    ///
    /// # Safety
    ///
    /// As [`Mmio::new`]; in particular the FPGA must be configured with the
    /// ray tracer and the lightweight bridge out of reset and visible, since a
    /// read from an unconfigured fabric or a bridge in reset can hang or abort.
    pub unsafe fn lightweight_bridge() -> Mmio {
        // SAFETY: forwarded to the caller (same contract).
        unsafe { Mmio::new(LW_BRIDGE_BASE + CSR_OFFSET) }
    }

    /// The accelerator whose CSR block starts at `base`.
    ///
    /// # Safety
    ///
    /// * `base` is 4-byte aligned and the `size_of::<RegisterBlock>()` bytes
    ///   from it are device registers (or memory) readable and writable with
    ///   32-bit accesses for the rest of the program;
    /// * no other `Mmio` or other code accesses that range while this one
    ///   exists;
    /// * the range is mapped Strongly-ordered or Device, so that accesses
    ///   reach the bridge in program order and are not cached.
    pub unsafe fn new(base: usize) -> Mmio {
        // SAFETY: the caller guarantees an aligned, live, exclusively owned
        // register range for `'static`; all fields are volatile cells.
        let regs = unsafe { &*(base as *const RegisterBlock) };
        Mmio { regs }
    }

    /// The register block, for accesses this port does not offer.
    pub fn registers(&self) -> &RegisterBlock {
        self.regs
    }
}

/// Wait until earlier register writes have completed.
///
/// Reads and writes travel separate AXI channels through the bridge, so a
/// STATUS read could overtake the CONTROL write just before it and see a
/// stale done. A `dsb` waits for the write's response; with the window mapped
/// Strongly-ordered that response comes from the accelerator itself.
#[inline(always)]
fn write_barrier() {
    #[cfg(target_arch = "arm")]
    // SAFETY: `dsb` only waits for outstanding memory accesses; it touches no
    // registers, stack or flags.
    unsafe {
        core::arch::asm!("dsb sy", options(nostack, preserves_flags));
    }
    #[cfg(not(target_arch = "arm"))]
    core::sync::atomic::fence(core::sync::atomic::Ordering::SeqCst);
}

impl RegisterPort for Mmio {
    fn read(&mut self, csr: Csr) -> u32 {
        let c = &self.regs.csr;
        match csr {
            // CONTROL is write-only and reads 0: no bus access needed.
            Csr::Control => 0,
            Csr::Status => c.status.read(),
            Csr::RowY => c.row_y.read(),
            Csr::LightX => c.light_x.read(),
            Csr::LightY => c.light_y.read(),
            Csr::LightZ => c.light_z.read(),
            Csr::Id => c.id.read(),
        }
    }

    fn write(&mut self, csr: Csr, value: u32) {
        let c = &self.regs.csr;
        // SAFETY: each is a single volatile 32-bit store to a register of the
        // block `Mmio::new` was given; its side effects on the accelerator
        // are the ones the register map documents.
        unsafe {
            match csr {
                Csr::Control => c.control.write(value),
                Csr::RowY => c.row_y.write(value),
                Csr::LightX => c.light_x.write(value),
                Csr::LightY => c.light_y.write(value),
                Csr::LightZ => c.light_z.write(value),
                // Read-only registers ignore writes: skip the bus access.
                Csr::Status | Csr::Id => return,
            }
        }
        write_barrier();
    }

    fn read_line(&mut self, out: &mut [u32; LINE_WORDS]) {
        for (word, reg) in out.iter_mut().zip(self.regs.line.iter()) {
            *word = reg.read();
        }
    }
}
