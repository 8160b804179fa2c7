//! Start-up pieces around aarch32-rt: the reset entry, parking the second
//! core, exception handlers that report on the UART, the panic handler.
//!
//! aarch32-rt 0.5's reset code sets VBAR, initialises `.data` and `.bss`,
//! sets one stack per mode, turns VFP on (`eabi-fpu`) and calls `main`; its
//! exception trampolines save state before calling Rust. What it leaves to
//! the board is done here:
//!
//! * `_start`, the reset entry: registers only, no stack, because it may
//!   follow a boot loader that left the MMU and caches on (U-Boot's `go`
//!   does; docs/board-bring-up.md#u-boot). With the D-cache on, the
//!   start-up code's `.bss` zeroing would land in dirty lines that a later
//!   cache disable throws away, so the caches are turned off first, in
//!   assembly: D-cache off, clean and invalidate L1 by set/way (when SCTLR
//!   has the D-cache or the MMU on), then, whenever the L2C-310's enable
//!   bit is set, whatever SCTLR says (U-Boot's `dcache off` leaves the L2
//!   on), clean and invalidate it by way, sync and turn it off; then MMU and
//!   I-cache off. Constants are built with `movw`/`movt`: no literal-pool
//!   load reads stale DRAM once the D-cache is off.
//!   Then, on every entry, the I-cache and branch predictor are invalidated
//!   and SCTLR.V is cleared (QEMU and the boot ROM enter with high vectors,
//!   which would make the CPU ignore VBAR). The sequence is ARM's
//!   (Cortex-A9 TRM DDI 0388, "Cache operations"; L2C-310 TRM DDI 0246
//!   3.3.10) and what U-Boot's `cleanup_before_linux` does in C.
//! * `_asm_secondary_core_park`: QEMU starts both cores at the ELF entry;
//!   `_start` sends every core but core 0 there before it touches memory
//!   or a cache (a second core running the rest late would overwrite the
//!   entry record and could turn off the L2 under core 0), and it sleeps in
//!   `wfe` forever (on the DE1-SoC the preloader keeps core 1 in reset).

use core::fmt::Write;
use core::mem::offset_of;
use core::sync::atomic::{AtomicU32, Ordering};

use aarch32_cpu::register::{Dfar, Dfsr, Ifar, Ifsr};
use aarch32_rt::exception;
use soc::l2c310::{RegisterBlock, WAY_OP_POLLS};

use crate::platform::Active;
use crate::platform::Board;
use crate::{cpu, log};

core::arch::global_asm!(
    r#"
    .pushsection .text._start, "ax", %progbits
    .arm
    .global _start
    .type _start, %function
    .p2align 2
_start:
    @ No load from memory until the L2C-310 is clean and off: every constant
    @ is built with movw/movt (a literal-pool load after the D-cache is off
    @ would read DRAM under a dirty line). `cargo xtask image` checks this
    @ in the disassembly (xtask/src/images/entry_check.rs).
    @ 0. Only core 0 goes on: QEMU starts every core at the ELF entry, and a
    @    late core 1 would overwrite the entry record and could turn off an
    @    L2 that core 0 has since enabled.
    mrc     p15, 0, r0, c0, c0, 5       @ MPIDR
    ands    r0, r0, #0xff               @ Aff0: the core within the cluster
    bne     _asm_secondary_core_park
    mrc     p15, 0, r0, c1, c0, 0       @ SCTLR
    movw    r1, #:lower16:{entry_sctlr} @ kept for the boot log (.uninit:
    movt    r1, #:upper16:{entry_sctlr} @ the start-up code does not zero it)
    str     r0, [r1]
    tst     r0, #((1 << 2) | (1 << 0))  @ D-cache (C) or MMU (M) on?
    beq     3f
    @ 1. D-cache off: no new line is allocated from here on.
    bic     r1, r0, #(1 << 2)
    mcr     p15, 0, r1, c1, c0, 0
    isb
    @ 2. Clean and invalidate L1 D by set/way (cpu.rs's L1 geometry): way
    @    in the top bits, set above the line offset.
    mov     r5, #0
1:  mov     r3, #0
2:  lsl     r4, r5, #{way_shift}
    orr     r4, r4, r3, lsl #{line_log2}
    mcr     p15, 0, r4, c7, c14, 2      @ DCCISW
    add     r3, r3, #1
    cmp     r3, #{sets}
    blo     2b
    add     r5, r5, #1
    cmp     r5, #{ways}
    blo     1b
    dsb
3:  @ 3. L2C-310 on? Whatever SCTLR says (U-Boot's `dcache off` turns the
    @    MMU and D-cache off but leaves the L2 on): clean and invalidate
    @    every way, bounded wait, cache sync, L2 off (soc::l2c310's
    @    register block, poll budget and `flush_and_disable`).
    movw    r6, #{l2c_lo}
    movt    r6, #{l2c_hi}
    ldr     r1, [r6, #{control}]
    tst     r1, #1
    beq     4f
    ldr     r1, [r6, #{aux_control}]    @ aux control bit 16: 16 ways
    mov     r2, #0xff
    tst     r1, #(1 << 16)
    orrne   r2, r2, #0xff00
    str     r2, [r6, #{clean_invalidate_way}]
    movw    r7, #{polls_lo}
    movt    r7, #{polls_hi}
6:  ldr     r1, [r6, #{clean_invalidate_way}]
    tst     r1, r2
    beq     7f
    subs    r7, r7, #1
    bne     6b
7:  mov     r1, #0
    str     r1, [r6, #{cache_sync}]
    str     r1, [r6, #{control}]
    dsb
4:  @ 4. MMU, D-cache and I-cache off (already off when SCTLR said so).
    bic     r0, r0, #((1 << 0) | (1 << 2))
    bic     r0, r0, #(1 << 12)
    mcr     p15, 0, r0, c1, c0, 0
    isb
    @ Every entry: invalidate the I-cache and branch predictor, clear SCTLR.V.
    mov     r0, #0
    mcr     p15, 0, r0, c7, c5, 0       @ ICIALLU
    mcr     p15, 0, r0, c7, c5, 6       @ BPIALL
    dsb
    isb
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
    "#,
    l2c_lo = const Active::L2C & 0xffff,
    l2c_hi = const Active::L2C >> 16,
    control = const offset_of!(RegisterBlock, control),
    aux_control = const offset_of!(RegisterBlock, aux_control),
    cache_sync = const offset_of!(RegisterBlock, cache_sync),
    clean_invalidate_way = const offset_of!(RegisterBlock, clean_invalidate_way),
    polls_lo = const WAY_OP_POLLS & 0xffff,
    polls_hi = const WAY_OP_POLLS >> 16,
    way_shift = const 32 - cpu::L1_WAYS_LOG2,
    line_log2 = const cpu::L1_LINE_LOG2,
    sets = const 1 << cpu::L1_SETS_LOG2,
    ways = const 1 << cpu::L1_WAYS_LOG2,
    entry_sctlr = sym ENTRY_SCTLR,
);

/// SCTLR as the reset entry found it (written by `_start` before anything
/// else, in `.uninit` so the start-up code leaves it alone).
#[unsafe(link_section = ".uninit.ENTRY_SCTLR")]
pub static ENTRY_SCTLR: AtomicU32 = AtomicU32::new(0);

/// What the reset entry found, for the boot log.
pub fn entry_state() -> EntryState {
    EntryState(ENTRY_SCTLR.load(Ordering::Relaxed))
}

/// SCTLR at entry.
#[derive(Clone, Copy)]
pub struct EntryState(u32);

impl core::fmt::Display for EntryState {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let on = |bit: u32| if self.0 & (1 << bit) != 0 { "on" } else { "off" };
        write!(f, "SCTLR {:#010x} at entry (MMU {}, D-cache {}, I-cache {})", self.0, on(0), on(2), on(12))?;
        if self.0 & ((1 << 0) | (1 << 2)) != 0 {
            f.write_str(": cleaned and turned off before start-up")?;
        }
        Ok(())
    }
}

/// Mask interrupts and stop for good (after the reason went to the UART).
pub fn halt() -> ! {
    let _ = writeln!(log::Fault, "halted.");
    loop {
        aarch32_cpu::asm::irq_disable();
        aarch32_cpu::asm::wfi();
    }
}

#[exception(Undefined)]
fn undefined(addr: usize) -> ! {
    let _ = writeln!(log::Fault, "\nFAULT: undefined instruction at {addr:#010x}");
    halt()
}

#[exception(PrefetchAbort)]
fn prefetch_abort(addr: usize) -> ! {
    let (ifsr, ifar) = (Ifsr::read().raw_value(), Ifar::read().0);
    let _ = writeln!(log::Fault, "\nFAULT: prefetch abort at {addr:#010x}: IFSR {ifsr:#010x} IFAR {ifar:#010x}");
    halt()
}

/// A data abort: during the accelerator probe an external abort means "no
/// accelerator" and execution resumes (soc::abort); anything else is fatal.
#[exception(DataAbort)]
unsafe fn data_abort(addr: usize) -> usize {
    let dfsr = Dfsr::read().raw_value();
    if let Some(resume) = crate::platform::PROBE.on_data_abort(dfsr, addr) {
        return resume;
    }
    let dfar = Dfar::read().0;
    let _ = writeln!(log::Fault, "\nFAULT: data abort at pc {addr:#010x}: DFSR {dfsr:#010x} DFAR {dfar:#010x}");
    halt()
}

#[exception(SupervisorCall)]
fn supervisor_call(arg: u32, _frame: &aarch32_rt::Frame) -> u32 {
    let _ = writeln!(log::Fault, "\nFAULT: unexpected SVC #{arg}");
    halt()
}

#[exception(HypervisorCall)]
fn hypervisor_call(hsr: u32, _frame: &aarch32_rt::Frame) -> u32 {
    let _ = writeln!(log::Fault, "\nFAULT: unexpected HVC (HSR {hsr:#010x})");
    halt()
}

#[aarch32_rt::irq]
fn irq() {
    // Interrupts stay masked; getting here means something unmasked them.
    let _ = writeln!(log::Fault, "\nFAULT: unexpected IRQ");
    halt()
}

/// FIQ entry (FIQs stay masked): report and stop, on the FIQ stack.
#[unsafe(no_mangle)]
extern "C" fn fiq_fault() -> ! {
    let _ = writeln!(log::Fault, "\nFAULT: unexpected FIQ");
    halt()
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    let _ = writeln!(log::Fault, "\nPANIC: {info}");
    halt()
}
