//! Start-up pieces around aarch32-rt: the reset entry, parking the second
//! core, exception handlers that report on the UART, the panic handler.
//!
//! Why aarch32-rt 0.5: its reset code already sets VBAR, initialises `.data`
//! and `.bss`, sets one stack per mode and (feature `eabi-fpu`) turns VFP on,
//! and its exception trampolines save state before calling Rust. Two things
//! it leaves to the board, done here:
//!
//! * `_start`: QEMU (and a ROM) enter with SCTLR.V = 1, which makes the CPU
//!   use the high vectors at 0xffff_0000 and ignore VBAR. The reset entry
//!   clears SCTLR.V before branching to aarch32-rt's `_default_start`.
//! * `_asm_secondary_core_park`: QEMU starts both cores at the ELF entry; the
//!   second one must never touch memory the first initialises. It sleeps in
//!   `wfe` forever (on the DE1-SoC the preloader keeps core 1 in reset, so
//!   this only runs under QEMU).

use core::fmt::Write;

use aarch32_rt::exception;

use crate::log::Log;

// The reset entry. Runs on every core before any stack exists: registers
// only. SCTLR bit 13 (V): ARM ARM (DDI 0406C) B4.1.130.
core::arch::global_asm!(
    r#"
    .pushsection .text._start, "ax", %progbits
    .arm
    .global _start
    .type _start, %function
    .p2align 2
_start:
    mrc     p15, 0, r0, c1, c0, 0
    bic     r0, r0, #(1 << 13)
    mcr     p15, 0, r0, c1, c0, 0
    isb
    b       _default_start
    .size _start, . - _start
    .popsection

    .pushsection .text._asm_secondary_core_park, "ax", %progbits
    .arm
    .global _asm_secondary_core_park
    .type _asm_secondary_core_park, %function
    .p2align 2
_asm_secondary_core_park:
    wfe
    b       _asm_secondary_core_park
    .size _asm_secondary_core_park, . - _asm_secondary_core_park
    .popsection

    .pushsection .text._asm_fiq_handler, "ax", %progbits
    .arm
    .global _asm_fiq_handler
    .type _asm_fiq_handler, %function
    .p2align 2
_asm_fiq_handler:
    b       fiq_fault
    .size _asm_fiq_handler, . - _asm_fiq_handler
    .popsection
    "#
);

/// Mask interrupts and stop for good (after the reason went to the UART).
pub fn halt() -> ! {
    let _ = writeln!(Log, "halted.");
    loop {
        // SAFETY: masking IRQ/FIQ and waiting for an interrupt have no
        // memory effects.
        unsafe { core::arch::asm!("cpsid if", "wfi", options(nomem, nostack)) };
    }
}

fn cp15_fault_registers() -> (u32, u32, u32, u32) {
    let (dfsr, dfar, ifsr, ifar): (u32, u32, u32, u32);
    // SAFETY: reads of the fault status/address registers (DDI 0406C
    // B4.1.52 DFSR, B4.1.51 DFAR, B4.1.96 IFSR, B4.1.95 IFAR) have no side
    // effects.
    unsafe {
        core::arch::asm!(
            "mrc p15, 0, {0}, c5, c0, 0",
            "mrc p15, 0, {1}, c6, c0, 0",
            "mrc p15, 0, {2}, c5, c0, 1",
            "mrc p15, 0, {3}, c6, c0, 2",
            out(reg) dfsr, out(reg) dfar, out(reg) ifsr, out(reg) ifar,
            options(nomem, nostack, preserves_flags)
        );
    }
    (dfsr, dfar, ifsr, ifar)
}

#[exception(Undefined)]
fn undefined(addr: usize) -> ! {
    let _ = writeln!(Log, "\nFAULT: undefined instruction at {addr:#010x}");
    halt()
}

#[exception(PrefetchAbort)]
fn prefetch_abort(addr: usize) -> ! {
    let (_, _, ifsr, ifar) = cp15_fault_registers();
    let _ = writeln!(Log, "\nFAULT: prefetch abort at {addr:#010x}: IFSR {ifsr:#010x} IFAR {ifar:#010x}");
    halt()
}

#[exception(DataAbort)]
fn data_abort(addr: usize) -> ! {
    let (dfsr, dfar, _, _) = cp15_fault_registers();
    let _ = writeln!(Log, "\nFAULT: data abort at pc {addr:#010x}: DFSR {dfsr:#010x} DFAR {dfar:#010x}");
    halt()
}

#[exception(SupervisorCall)]
fn supervisor_call(arg: u32, _frame: &aarch32_rt::Frame) -> u32 {
    let _ = writeln!(Log, "\nFAULT: unexpected SVC #{arg}");
    halt()
}

#[exception(HypervisorCall)]
fn hypervisor_call(hsr: u32, _frame: &aarch32_rt::Frame) -> u32 {
    let _ = writeln!(Log, "\nFAULT: unexpected HVC (HSR {hsr:#010x})");
    halt()
}

#[aarch32_rt::irq]
fn irq() {
    // Interrupts stay masked; getting here means something unmasked them.
    let _ = writeln!(Log, "\nFAULT: unexpected IRQ");
    halt()
}

/// FIQ entry (FIQs stay masked): report and stop, on the FIQ stack.
#[unsafe(no_mangle)]
extern "C" fn fiq_fault() -> ! {
    let _ = writeln!(Log, "\nFAULT: unexpected FIQ");
    halt()
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    let _ = writeln!(Log, "\nPANIC: {info}");
    halt()
}
