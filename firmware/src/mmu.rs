//! Turn on the MMU (flat identity map) and the caches: L1 I/D, branch
//! prediction and the L2C-310. DRAM is normal write-back memory except the
//! DMA section (`.dma`, see memory.x), which is normal non-cacheable so the
//! MAC and the CPU agree without maintenance; everything else is device
//! memory.
//!
//! Sequence: ARM Cortex-A9 TRM (DDI 0388) and ARM ARM (DDI 0406C) B3.
//! L2C-310 registers: CoreLink L2C-310 TRM (DDI 0246), 3.3: control 0x100,
//! auxiliary control 0x104 (bit 16 associativity), invalidate by way 0x77c,
//! clean and invalidate by way 0x7fc, cache sync 0x730.

use core::fmt::Write;

use aarch32_cpu::cache::{clean_and_invalidate_l1_data_cache, invalidate_l1_data_cache};
use firmware::arch::{build_flat_table, dsb, MemType, SECTIONS};
use firmware::drivers::clock::{wait_for, Clock};
use firmware::drivers::mmio::Mmio;

/// Cortex-A9 L1 data cache geometry (both boards: 32 KiB, 4-way, 32-byte
/// lines, 256 sets; DDI 0388 7.1): log2 ways, log2 line, log2 sets.
const L1_WAYS_LOG2: usize = 2;
const L1_LINE_LOG2: usize = 5;
const L1_SETS_LOG2: usize = 8;

const SCTLR_M: u32 = 1 << 0;
const SCTLR_A: u32 = 1 << 1;
const SCTLR_C: u32 = 1 << 2;
const SCTLR_Z: u32 = 1 << 11;
const SCTLR_I: u32 = 1 << 12;

const L2_CTRL: usize = 0x100;
const L2_AUX_CTRL: usize = 0x104;
const L2_SYNC: usize = 0x730;
const L2_INV_WAY: usize = 0x77c;
const L2_CLEAN_INV_WAY: usize = 0x7fc;

/// The first-level table: 4096 section entries, 16 KiB aligned.
#[repr(C, align(16384))]
struct L1Table([u32; SECTIONS]);

fn sctlr() -> u32 {
    let v: u32;
    // SAFETY: reading SCTLR has no side effects.
    unsafe { core::arch::asm!("mrc p15, 0, {}, c1, c0, 0", out(reg) v, options(nomem, nostack, preserves_flags)) };
    v
}

/// # Safety
/// Changing SCTLR changes how all memory is accessed; the caller keeps the
/// mappings and cache contents consistent.
unsafe fn set_sctlr(v: u32) {
    // SAFETY: forwarded to the caller.
    unsafe {
        core::arch::asm!("mcr p15, 0, {}, c1, c0, 0", "isb", in(reg) v, options(nostack, preserves_flags));
    }
}

/// Section index range `[start, end)` of the DMA region (from the linker).
fn dma_sections() -> (u32, u32) {
    unsafe extern "C" {
        static __sdma: u8;
        static __edma: u8;
    }
    // Only the symbols' addresses are taken, never their contents.
    let (s, e) = (&raw const __sdma as usize, &raw const __edma as usize);
    ((s >> 20) as u32, ((e + 0xf_ffff) >> 20).max((s >> 20) + 1) as u32)
}

/// Build the table and turn on the MMU, L1 and L2 caches. Call once, first
/// thing in `kmain`, on core 0.
pub fn enable(dram_mib: u32, l2c_base: usize, clock: &impl Clock, log: &mut impl Write) {
    static mut TABLE: L1Table = L1Table([0; SECTIONS]);
    // SAFETY: L2C base is the board's L2C-310 register block; with the MMU
    // off every access is strongly ordered, afterwards the block is mapped
    // as device memory. Only this function touches it.
    let l2 = unsafe { Mmio::new(l2c_base) };

    // Coming from a boot loader that left the caches on: write everything
    // back and turn them off before changing the map.
    let old = sctlr();
    if old & (SCTLR_C | SCTLR_M) != 0 {
        clean_and_invalidate_l1_data_cache::<L1_WAYS_LOG2, L1_LINE_LOG2, L1_SETS_LOG2>();
        if l2.read(L2_CTRL) & 1 != 0 {
            l2.write(L2_CLEAN_INV_WAY, l2_way_mask(&l2));
            let _ = wait_for(clock, 100_000, || (l2.read(L2_CLEAN_INV_WAY) == 0).then_some(()));
            l2.write(L2_SYNC, 0);
            l2.write(L2_CTRL, 0);
        }
        dsb();
        // SAFETY: caches were just cleaned; identity map before and after.
        unsafe { set_sctlr(old & !(SCTLR_C | SCTLR_M | SCTLR_I)) };
        let _ = writeln!(log, "mmu: boot loader left MMU/caches on (SCTLR {old:#010x}); cleaned and turned off");
    }

    let (dma_lo, dma_hi) = dma_sections();
    // SAFETY: `enable` runs once, on core 0, before anything else uses the
    // table; nothing else names `TABLE`.
    let table = unsafe { &mut *(&raw mut TABLE) };
    build_flat_table(&mut table.0, |i| {
        if (dma_lo..dma_hi).contains(&i) {
            MemType::NormalUncached
        } else if i < dram_mib {
            MemType::NormalCached
        } else {
            MemType::Device
        }
    });
    dsb();

    // L2: invalidate all ways, wait, enable (the L2C-310 must be invalidated
    // before it is enabled; DDI 0246 2.3.1).
    if l2.read(L2_CTRL) & 1 == 0 {
        l2.write(L2_INV_WAY, l2_way_mask(&l2));
        if wait_for(clock, 100_000, || (l2.read(L2_INV_WAY) == 0).then_some(())).is_some() {
            l2.write(L2_SYNC, 0);
            l2.write(L2_CTRL, 1);
        } else {
            let _ = writeln!(log, "mmu: L2 invalidate timed out; L2 left off");
        }
    }

    invalidate_l1_data_cache::<L1_WAYS_LOG2, L1_LINE_LOG2, L1_SETS_LOG2>();
    let ttbr0 = table.0.as_ptr() as u32;
    // SAFETY: invalidating TLBs/I-cache/branch predictor and programming the
    // translation registers is sound while the MMU is off; the table maps
    // every address the firmware uses to itself.
    unsafe {
        core::arch::asm!(
            "mcr p15, 0, {zero}, c8, c7, 0",  // TLBIALL
            "mcr p15, 0, {zero}, c7, c5, 0",  // ICIALLU
            "mcr p15, 0, {zero}, c7, c5, 6",  // BPIALL
            "mcr p15, 0, {zero}, c2, c0, 2",  // TTBCR = 0: TTBR0 only
            "mcr p15, 0, {dacr}, c3, c0, 0",  // DACR: all domains client
            "mcr p15, 0, {ttbr}, c2, c0, 0",  // TTBR0, non-cacheable walks
            "dsb",
            "isb",
            zero = in(reg) 0u32,
            dacr = in(reg) 0x5555_5555u32,
            ttbr = in(reg) ttbr0,
            options(nostack, preserves_flags)
        );
        set_sctlr((sctlr() | SCTLR_M | SCTLR_C | SCTLR_I | SCTLR_Z) & !SCTLR_A);
    }
    let _ = writeln!(
        log,
        "mmu: on; {dram_mib} MiB cached, DMA {:#010x}..{:#010x} uncached, L1 I/D {}, L2 {}",
        dma_lo << 20,
        dma_hi << 20,
        if sctlr() & SCTLR_C != 0 { "on" } else { "off" },
        if l2.read(L2_CTRL) & 1 != 0 { "on" } else { "off" },
    );
}

/// All-ways mask of the L2C-310: 16 ways if aux control bit 16, else 8.
fn l2_way_mask(l2: &Mmio) -> u32 {
    if l2.read(L2_AUX_CTRL) & (1 << 16) != 0 { 0xffff } else { 0xff }
}
