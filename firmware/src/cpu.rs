//! CPU-level pieces: the barriers and cache sync the MAC driver orders its
//! DMA hand-overs with, the MMU and cache set-up, and the probe load.
//!
//! CP15 registers and barriers come from aarch32-cpu. Its traps (see
//! docs/platform.md#cortex-a9-start-up): the set/way loops hold no barrier
//! (bracketed with `dsb` here), and TTBCR has no wrapper (written by hand
//! below).

use core::fmt::Write;
use core::sync::atomic::{compiler_fence, AtomicPtr, Ordering};

use aarch32_cpu::asm::{dmb, dsb, isb};
use aarch32_cpu::cache::invalidate_l1_data_cache;
use aarch32_cpu::register::{BpIAll, Dacr, Iciallu, Sctlr, TlbIAll, Ttbr0};
use dwmac::DmaSync;
use soc::cache::{CacheOps, Lines};
use soc::l2c310::L2c310;
use soc::mmu::{sections_of, MemType, MemoryMap, PageTable, PAGES, SECTIONS};
use static_cell::ConstStaticCell;

use crate::platform::Board;

/// Cortex-A9 L1 data cache geometry (both boards: 32 KiB, 4-way, 32-byte
/// lines, 256 sets; ARM DDI 0388 Cortex-A9 TRM 7.1): log2 ways, line, sets
/// (also the reset entry's set/way loop, start.rs).
pub const L1_WAYS_LOG2: usize = 2;
pub const L1_LINE_LOG2: usize = 5;
pub const L1_SETS_LOG2: usize = 8;

/// The Cortex-A9 with its L2C-310: by-address cache maintenance on both
/// levels for the frame ring (`soc::cache` has the sequences), and the MAC
/// driver's barriers (`outer_sync` drains the L2C-310's store buffer). The
/// map is flat: an address is both the virtual one CP15 takes and the
/// physical one the L2C-310 takes.
#[derive(Clone, Copy)]
pub struct Caches {
    /// The L2 cache controller.
    pub l2: &'static L2c310,
}

// Inline: a cache line operation is one CP15 instruction or one L2C-310
// register write, done for every line of every row the CPU reads or writes.
impl CacheOps for Caches {
    #[inline(always)]
    fn l1_invalidate(&self, addr: usize) {
        aarch32_cpu::cache::invalidate_data_cache_line_to_poc(addr as u32)
    }

    #[inline(always)]
    fn l1_clean(&self, addr: usize) {
        aarch32_cpu::cache::clean_data_cache_line_to_poc(addr as u32)
    }

    #[inline(always)]
    fn l2_invalidate(&self, addr: usize) {
        // SAFETY: `soc::cache::invalidate_for_cpu`'s contract: the line is
        // clean.
        unsafe { self.l2.invalidate_line(addr as u32) }
    }

    #[inline(always)]
    fn l2_clean(&self, addr: usize) {
        self.l2.clean_line(addr as u32)
    }

    #[inline(always)]
    fn l2_sync(&self) {
        self.l2.cache_sync()
    }

    #[inline(always)]
    fn dsb(&self) {
        dsb()
    }
}

// Inline: each is one instruction or one register write, on the
// transmit path several times a packet.
impl DmaSync for Caches {
    #[inline(always)]
    fn dsb(&self) {
        dsb()
    }

    #[inline(always)]
    fn dmb(&self) {
        dmb()
    }

    #[inline(always)]
    fn outer_sync(&self) {
        self.l2.cache_sync()
    }
}

/// The first-level table: 4096 section entries, 16 KiB aligned (ARM ARM
/// B3.5.1: TTBR0 with TTBCR.N = 0). Not aarch32-cpu's `L1Table`, which is
/// aligned to 1 MiB.
#[repr(C, align(16384))]
struct L1Table([u32; SECTIONS]);

/// Build the flat map, turn on the L2C-310, then the MMU and the L1 caches
/// and branch prediction. Call once, on core 0, with the MMU off (the reset
/// entry made sure of that).
pub fn enable_mmu_and_caches<B: Board>(log: &mut impl Write) -> L2c310 {
    static TABLE: ConstStaticCell<L1Table> = ConstStaticCell::new(L1Table([0; SECTIONS]));
    static PAGE_TABLE: ConstStaticCell<PageTable> = ConstStaticCell::new(PageTable([0; PAGES]));
    // SAFETY: the board's L2C-310 register block; with the MMU off every
    // access is Strongly-ordered, afterwards the block is mapped Device.
    // Only the value returned here uses it from now on.
    let l2 = unsafe { L2c310::new(crate::platform::register_block(B::L2C)) };

    unsafe extern "C" {
        static __sdma: u8;
        static __edma: u8;
        static __sframes: u8;
        static __eframes: u8;
    }
    // Only the symbols' addresses are taken, never their contents.
    let dma = sections_of(&raw const __sdma as usize..&raw const __edma as usize);
    let frames = sections_of(&raw const __sframes as usize..&raw const __eframes as usize);
    // The frame ring stays cacheable: it is read through the caches after
    // an invalidation by address (render.rs, docs/frame-dma.md#caches).
    let uncached = [dma.clone()];
    let map = MemoryMap {
        dram_mib: B::DRAM_MIB,
        uncached: &uncached,
        strongly_ordered: B::STRONGLY_ORDERED,
        paged: B::PAGED,
    };
    let (Some(table), Some(pages)) = (TABLE.try_take(), PAGE_TABLE.try_take()) else {
        let _ = writeln!(log, "mmu: already on");
        return l2;
    };
    let pages_addr = pages.0.as_ptr() as u32;
    map.fill(&mut table.0, pages, pages_addr);
    PAGED_TABLE.store(pages, Ordering::Release);

    // L2: invalidate all ways, then enable (the L2C-310 must be invalidated
    // before it is enabled; ARM DDI 0246 2.3.1). The reset entry cleaned and
    // turned off a boot loader's L2 whatever SCTLR said; should it still be
    // on, it is cleaned and turned off here first (writing the auxiliary
    // control or enabling over stale lines is not allowed while it is on).
    if let Err(e) = l2.flush_and_disable() {
        let _ = writeln!(log, "mmu: {e} while turning the L2 off");
    }
    let l2_on = match l2.invalidate_all() {
        Ok(()) => {
            l2.set_enabled(true);
            true
        }
        Err(e) => {
            let _ = writeln!(log, "mmu: {e}; L2 left off");
            false
        }
    };

    // L1 D-cache contents are unknown after reset: invalidate before use.
    dsb();
    compiler_fence(Ordering::SeqCst);
    invalidate_l1_data_cache::<L1_WAYS_LOG2, L1_LINE_LOG2, L1_SETS_LOG2>();
    compiler_fence(Ordering::SeqCst);
    dsb();
    TlbIAll::write();
    Iciallu::write();
    BpIAll::write();
    write_ttbcr_zero();
    Dacr::write(Dacr::new_with_raw_value(DACR_ALL_CLIENT));
    // SAFETY: the table is complete, 16 KiB aligned and maps every address
    // the firmware uses to itself; table walks are non-cacheable (IRGN/RGN 0),
    // and the table is never changed once the MMU is on.
    unsafe { Ttbr0::write(Ttbr0::new_with_raw_value(0).with_address(table.0.as_ptr() as usize)) };
    dsb();
    isb();
    // `Sctlr::modify` ends with `dsb` + `isb` on Armv7-A.
    Sctlr::modify(|s| {
        s.set_m(true);
        s.set_c(true);
        s.set_i(true);
        s.set_z(true);
        s.set_a(false);
    });
    let s = Sctlr::read();
    let _ = writeln!(
        log,
        "mmu: on; {} MiB cached (frames {:#010x}..{:#010x} too), DMA {:#010x}..{:#010x} uncached, {} FPGA window(s) strongly-ordered, L1 I/D {}, L2 {} (ID {:#010x})",
        B::DRAM_MIB,
        frames.start << 20,
        frames.end << 20,
        dma.start << 20,
        dma.end << 20,
        B::STRONGLY_ORDERED.len(),
        if s.c() && s.i() { "on" } else { "off" },
        if l2_on { "on" } else { "off" },
        l2.cache_id(),
    );
    l2
}

/// The second-level table of the board's paged section, once the MMU is on
/// ([`retype_page`] changes it).
static PAGED_TABLE: AtomicPtr<PageTable> = AtomicPtr::new(core::ptr::null_mut());

/// Map the 4 KiB page at `addr` of the board's paged section with type
/// `ty` while the MMU is on: write the small-page entry, clean it to the
/// point of coherence (table walks are non-cacheable: TTBR0 IRGN/RGN 0),
/// then invalidate the TLB and branch predictor, `dsb`, `isb` (ARM ARM DDI
/// 0406C B3.10.1, "General TLB maintenance requirements"; B3.10.2 on
/// cleaning table writes for a walk that does not look in the caches).
/// False when `addr` is not in the paged section or the MMU set-up did not
/// run. Core 0 only, from the board set-up.
#[cfg_attr(not(feature = "de1-soc"), expect(dead_code, reason = "only the DE1-SoC has a line buffer"))]
pub fn retype_page<B: Board>(addr: u32, ty: MemType, caches: Caches) -> bool {
    let (Some(paged), Some(pages)) = (B::PAGED, core::ptr::NonNull::new(PAGED_TABLE.load(Ordering::Acquire))) else {
        return false;
    };
    // SAFETY: the table was handed over by `enable_mmu_and_caches` (its
    // `&'static mut` is not used after that); only core 0 runs, and this is
    // the only reference made while it lives; the hardware only reads it.
    let table = unsafe { &mut *pages.as_ptr() };
    let Some(i) = table.retype(paged.section, addr, ty) else {
        return false;
    };
    let entry = &table.0[i] as *const u32 as usize;
    if let Some(lines) = Lines::covering(entry, 4) {
        soc::cache::clean_for_device(&caches, &lines);
    }
    dsb();
    TlbIAll::write();
    BpIAll::write();
    dsb();
    isb();
    true
}

/// DACR: every domain "client" (permissions from the table).
const DACR_ALL_CLIENT: u32 = 0x5555_5555;

/// TTBCR = 0: TTBR0 translates the whole address space, short descriptors.
/// Hand-written: aarch32-cpu 0.4 has no TTBCR (ARM ARM B4.1.153: `mcr p15,
/// 0, Rt, c2, c0, 2`).
fn write_ttbcr_zero() {
    // SAFETY: with the MMU off, TTBCR only takes effect once it is enabled,
    // with the table installed right after.
    unsafe { core::arch::asm!("mcr p15, 0, {0}, c2, c0, 2", in(reg) 0u32, options(nostack, preserves_flags)) };
}
