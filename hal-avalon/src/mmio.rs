//! Memory-mapped access to the accelerator on the board.
//!
//! [`RegisterBlock`] lays the CSR block and the line buffer out at the
//! offsets of [`crate::map`]; [`MmioPort`] is the [`RegisterPort`] over it.
//! This module holds the crate's only raw-pointer code.
//!
//! # Ordering
//!
//! The driver writes ROW_Y, LIGHT_* and CONTROL, then polls STATUS. Reads
//! and writes travel separate AXI channels through the bridge, so on a
//! Device mapping a STATUS read could overtake the CONTROL write before it
//! and see a stale done. The firmware maps the bridge window
//! Strongly-ordered instead (its MMU table; ARM ARM DDI 0406C A3.5.7:
//! an access to Strongly-ordered memory completes, write response
//! included, before the next one starts), which orders every access in
//! program order without a barrier per write.

use core::ptr::NonNull;

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
    /// `0x1C` FRAME_BASE.
    pub frame_base: RW<u32>,
    /// `0x20` FRAME_CONTROL.
    pub frame_control: WO<u32>,
    /// `0x24` FRAME_STATUS.
    pub frame_status: RO<u32>,
    /// `0x28` ROWS_DONE.
    pub rows_done: RO<u32>,
    /// `0x2C` VGA_CONTROL.
    pub vga_control: RW<u32>,
    /// `0x30` VGA_BASE.
    pub vga_base: RW<u32>,
    /// `0x34` VGA_STATUS (write 1 to clear).
    pub vga_status: RW<u32>,
    /// `0x38` KEYS (write 1 to clear).
    pub keys: RW<u32>,
    /// `0x3C` SWITCHES.
    pub switches: RO<u32>,
    /// `0x40` LEDS.
    pub leds: RW<u32>,
    /// `0x44` HEX_LO.
    pub hex_lo: RW<u32>,
    /// `0x48` HEX_HI.
    pub hex_hi: RW<u32>,
    /// `0x4C` BUILD_ID (read-only).
    pub build_id: RO<u32>,
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
    assert!(offset_of!(CsrBlock, frame_base) == Csr::FrameBase.offset());
    assert!(offset_of!(CsrBlock, frame_control) == Csr::FrameControl.offset());
    assert!(offset_of!(CsrBlock, frame_status) == Csr::FrameStatus.offset());
    assert!(offset_of!(CsrBlock, rows_done) == Csr::RowsDone.offset());
    assert!(offset_of!(CsrBlock, vga_control) == Csr::VgaControl.offset());
    assert!(offset_of!(CsrBlock, vga_base) == Csr::VgaBase.offset());
    assert!(offset_of!(CsrBlock, vga_status) == Csr::VgaStatus.offset());
    assert!(offset_of!(CsrBlock, keys) == Csr::Keys.offset());
    assert!(offset_of!(CsrBlock, switches) == Csr::Switches.offset());
    assert!(offset_of!(CsrBlock, leds) == Csr::Leds.offset());
    assert!(offset_of!(CsrBlock, hex_lo) == Csr::HexLo.offset());
    assert!(offset_of!(CsrBlock, hex_hi) == Csr::HexHi.offset());
    assert!(offset_of!(CsrBlock, build_id) == Csr::BuildId.offset());
    assert!(offset_of!(RegisterBlock, line) == LINE_BUFFER_OFFSET - CSR_OFFSET);
};

/// The accelerator's registers through memory-mapped I/O: the board's
/// [`RegisterPort`]. Holds a raw pointer, never a reference to device
/// memory.
pub struct MmioPort {
    regs: NonNull<RegisterBlock>,
}

// SAFETY: `MmioPort` owns its register block exclusively (the contract of
// `MmioPort::new`); moving that ownership to another execution context is
// sound.
unsafe impl Send for MmioPort {}

impl MmioPort {
    /// The accelerator at the address the FPGA design places it: the
    /// lightweight bridge base plus [`CSR_OFFSET`].
    ///
    /// # Safety
    ///
    /// As [`MmioPort::new`]; in particular the FPGA must be configured with
    /// the ray tracer and the lightweight bridge out of reset and visible,
    /// since a read from an unconfigured fabric or a bridge in reset can hang
    /// or abort.
    pub unsafe fn lightweight_bridge() -> MmioPort {
        // SAFETY: forwarded to the caller (same contract).
        unsafe { MmioPort::new(LW_BRIDGE_BASE + CSR_OFFSET) }
    }

    /// The accelerator whose CSR block starts at `base`.
    ///
    /// # Safety
    ///
    /// * `base` is 4-byte aligned and the `size_of::<RegisterBlock>()` bytes
    ///   from it are device registers (or memory) readable and writable with
    ///   32-bit accesses for the rest of the program;
    /// * no other `MmioPort` or other code accesses that range while this
    ///   one exists;
    /// * the range is mapped Strongly-ordered, so that accesses reach the
    ///   bridge in program order, each complete before the next (see the
    ///   module documentation), and are not cached.
    pub unsafe fn new(base: usize) -> MmioPort {
        // A null base cannot satisfy the contract; keep the constructor
        // total anyway.
        let regs = NonNull::new(base as *mut RegisterBlock).unwrap_or(NonNull::dangling());
        MmioPort { regs }
    }

    /// The register block, for accesses this port does not offer.
    pub fn registers(&self) -> &RegisterBlock {
        // SAFETY: `new`'s contract: an aligned, live, exclusively owned
        // register range; every field is a volatile cell.
        unsafe { self.regs.as_ref() }
    }
}

impl RegisterPort for MmioPort {
    fn read(&mut self, csr: Csr) -> u32 {
        let c = &self.registers().csr;
        match csr {
            // CONTROL registers are write-only and read 0: no bus access.
            Csr::Control | Csr::FrameControl => 0,
            Csr::Status => c.status.read(),
            Csr::RowY => c.row_y.read(),
            Csr::LightX => c.light_x.read(),
            Csr::LightY => c.light_y.read(),
            Csr::LightZ => c.light_z.read(),
            Csr::Id => c.id.read(),
            Csr::FrameBase => c.frame_base.read(),
            Csr::FrameStatus => c.frame_status.read(),
            Csr::RowsDone => c.rows_done.read(),
            Csr::VgaControl => c.vga_control.read(),
            Csr::VgaBase => c.vga_base.read(),
            Csr::VgaStatus => c.vga_status.read(),
            Csr::Keys => c.keys.read(),
            Csr::Switches => c.switches.read(),
            Csr::Leds => c.leds.read(),
            Csr::HexLo => c.hex_lo.read(),
            Csr::HexHi => c.hex_hi.read(),
            Csr::BuildId => c.build_id.read(),
        }
    }

    fn write(&mut self, csr: Csr, value: u32) {
        let c = &self.registers().csr;
        // SAFETY: each is a single volatile 32-bit store to a register of the
        // block `MmioPort::new` was given; its side effects on the accelerator
        // are the ones the register map documents.
        unsafe {
            match csr {
                Csr::Control => c.control.write(value),
                Csr::RowY => c.row_y.write(value),
                Csr::LightX => c.light_x.write(value),
                Csr::LightY => c.light_y.write(value),
                Csr::LightZ => c.light_z.write(value),
                // Read-only registers ignore writes: skip the bus access.
                Csr::FrameBase => c.frame_base.write(value),
                Csr::FrameControl => c.frame_control.write(value),
                Csr::VgaControl => c.vga_control.write(value),
                Csr::VgaBase => c.vga_base.write(value),
                Csr::VgaStatus => c.vga_status.write(value),
                Csr::Keys => c.keys.write(value),
                Csr::Leds => c.leds.write(value),
                Csr::HexLo => c.hex_lo.write(value),
                Csr::HexHi => c.hex_hi.write(value),
                Csr::Status | Csr::Id | Csr::FrameStatus | Csr::RowsDone | Csr::Switches | Csr::BuildId => {}
            }
        }
    }

    /// On the Cortex-A9: a `dmb` (the line buffer may sit in a Normal
    /// page, unordered against the STATUS read that said done), then
    /// four-word `ldm`/`stm` bursts: the firmware maps the line-buffer page
    /// Normal non-cacheable, where an `ldm` becomes one bus burst instead of
    /// four single reads (docs/frame-dma.md#row-mode). Elsewhere: one
    /// volatile read per word.
    fn read_line(&mut self, out: &mut [u32; LINE_WORDS]) {
        #[cfg(target_arch = "arm")]
        {
            const _: () = assert!(LINE_WORDS.is_multiple_of(4));
            dmb();
            let src = self.registers().line.as_ptr();
            // SAFETY: `src` is the 480-word line buffer of the block
            // `MmioPort::new` was given (reads have no side effects), `out`
            // is 480 aligned words; the loop copies exactly LINE_WORDS / 4
            // groups of four words and clobbers only the named registers.
            unsafe {
                core::arch::asm!(
                    "2:",
                    "ldm {src}!, {{r3, r4, r5, r8}}",
                    "stm {dst}!, {{r3, r4, r5, r8}}",
                    "subs {n}, {n}, #1",
                    "bne 2b",
                    src = inout(reg) src => _,
                    dst = inout(reg) out.as_mut_ptr() => _,
                    n = inout(reg) (LINE_WORDS / 4) as u32 => _,
                    out("r3") _, out("r4") _, out("r5") _, out("r8") _,
                    options(nostack),
                );
            }
        }
        #[cfg(not(target_arch = "arm"))]
        for (word, reg) in out.iter_mut().zip(self.registers().line.iter()) {
            *word = reg.read();
        }
    }
}

/// A full-system data memory barrier (`dmb sy`, ARM DDI 0406C A8.8.43):
/// aarch32-cpu's on bare metal. On ARM Linux (hps-linux) that crate does
/// not build (its `instruction_set` attributes need a target that has both
/// instruction sets), so the same instruction is written here.
#[cfg(all(target_arch = "arm", target_os = "none"))]
fn dmb() {
    aarch32_cpu::asm::dmb();
}

/// See the bare-metal `dmb` above.
#[cfg(all(target_arch = "arm", not(target_os = "none")))]
fn dmb() {
    // SAFETY: a barrier: no memory, register or flag is changed.
    unsafe { core::arch::asm!("dmb sy", options(nostack, preserves_flags)) };
}
