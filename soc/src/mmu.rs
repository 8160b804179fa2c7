//! The flat (identity) map: one short-descriptor section entry per MiB.
//!
//! Entry format: ARM Architecture Reference Manual ARMv7-A/R (DDI 0406C)
//! B3.5.1 "Short-descriptor translation table format", figure B3-4
//! (section): bits 1:0 = 0b10, B 2, C 3, XN 4, domain 8:5, `AP[1:0]` 11:10,
//! `TEX[2:0]` 14:12, `AP[2]` 15, S 16, nG 17, base 31:20; memory types per
//! table B3-10 (TEX/C/B with TEX remap off).
//!
//! One section may instead point to a second-level table of 4 KiB small
//! pages (figure B3-4, "page table" entry; figure B3-5, small page), for a
//! window whose pages need different types: the accelerator's CSR page
//! Strongly-ordered, its line-buffer page Normal non-cacheable so that an
//! `ldm` reads it in one burst.
//!
//! Pure functions, so that the host can test the entries the firmware
//! installs (aarch32-cpu's `mmu` module is compiled only for Arm targets).

use core::ops::Range;

/// Memory types of the flat map.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemType {
    /// Normal memory, inner and outer write-back write-allocate: code, data,
    /// stacks.
    NormalCached,
    /// Normal memory, non-cacheable: the MAC's rings and the frame ring, so
    /// the DMA masters and the CPU see the same bytes without cache
    /// maintenance (still bufferable: see the `dwmac` crate's `sync`).
    NormalUncached,
    /// Shareable Device memory, never executed: peripheral registers.
    Device,
    /// Strongly-ordered memory, never executed: the FPGA bridge windows, so
    /// that every access reaches the fabric in program order and a write
    /// completes (its response returns) before the next access starts
    /// (DDI 0406C A3.5.7), which the accelerator driver relies on.
    StronglyOrdered,
    /// Not mapped: any access faults.
    Fault,
}

/// Number of 1 MiB sections in the 4 GiB address space.
pub const SECTIONS: usize = 4096;

/// The section entry mapping the MiB at `index << 20` to itself with type
/// `ty`, read/write at PL1, domain 0, global.
pub const fn section_entry(index: u32, ty: MemType) -> u32 {
    const SECTION: u32 = 0b10;
    const B: u32 = 1 << 2;
    const C: u32 = 1 << 3;
    const XN: u32 = 1 << 4;
    const AP_RW: u32 = 0b11 << 10;
    const TEX_001: u32 = 0b001 << 12;
    let base = (index & 0xfff) << 20;
    match ty {
        // TEX 001, C 1, B 1: outer and inner write-back, write-allocate.
        MemType::NormalCached => base | SECTION | AP_RW | TEX_001 | C | B,
        // TEX 001, C 0, B 0: outer and inner non-cacheable.
        MemType::NormalUncached => base | SECTION | AP_RW | TEX_001 | XN,
        // TEX 000, C 0, B 1: shareable Device.
        MemType::Device => base | SECTION | AP_RW | B | XN,
        // TEX 000, C 0, B 0: Strongly-ordered.
        MemType::StronglyOrdered => base | SECTION | AP_RW | XN,
        MemType::Fault => 0,
    }
}

/// Entries of a second-level (small page) table: 256 pages of 4 KiB.
pub const PAGES: usize = 256;

/// A second-level table, 1 KiB aligned (ARM ARM B3.5.1).
#[repr(C, align(1024))]
pub struct PageTable(pub [u32; PAGES]);

/// The memory types of the 4 KiB pages of one section.
#[derive(Clone, Copy, Debug)]
pub struct PagedSection<'a> {
    /// The section (MiB index).
    pub section: u32,
    /// The type of every page not listed in `pages`.
    pub default: MemType,
    /// Page ranges (indexes 0..256 within the section) and their types.
    pub pages: &'a [(Range<u32>, MemType)],
}

impl PagedSection<'_> {
    /// The type of page `page` (0..256).
    pub fn memory_type(&self, page: u32) -> MemType {
        self.pages.iter().find(|(r, _)| r.contains(&page)).map_or(self.default, |(_, t)| *t)
    }

    /// Fill a second-level table with this section's pages.
    pub fn fill(&self, table: &mut PageTable) {
        let base = self.section << 20;
        for (i, e) in (0u32..).zip(table.0.iter_mut()) {
            *e = small_page_entry(base | i << 12, self.memory_type(i));
        }
    }
}

impl PageTable {
    /// Map the 4 KiB page holding `addr`, in section `section`, with type
    /// `ty`; the entry's index, or `None` when `addr` is outside the
    /// section. The caller makes the change visible to the table walk and
    /// invalidates the TLB (ARM ARM B3.10.1).
    pub fn retype(&mut self, section: u32, addr: u32, ty: MemType) -> Option<usize> {
        if addr >> 20 != section {
            return None;
        }
        let i = ((addr >> 12) & 0xff) as usize;
        self.0[i] = small_page_entry(addr, ty);
        Some(i)
    }
}

/// The first-level entry that points to the second-level table at bus
/// address `table` (1 KiB aligned): bits 1:0 = 0b01, domain 0, base 31:10.
pub const fn page_table_entry(table: u32) -> u32 {
    (table & !0x3ff) | 0b01
}

/// The small-page entry mapping the 4 KiB at `addr` to itself with type
/// `ty`, read/write at PL1 (figure B3-5: XN 0, bit 1 = 1, B 2, C 3,
/// `AP[1:0]` 5:4, `TEX[2:0]` 8:6, `AP[2]` 9, S 10, nG 11, base 31:12).
pub const fn small_page_entry(addr: u32, ty: MemType) -> u32 {
    const SMALL: u32 = 0b10;
    const XN: u32 = 1 << 0;
    const B: u32 = 1 << 2;
    const C: u32 = 1 << 3;
    const AP_RW: u32 = 0b11 << 4;
    const TEX_001: u32 = 0b001 << 6;
    let base = addr & !0xfff;
    match ty {
        MemType::NormalCached => base | SMALL | AP_RW | TEX_001 | C | B,
        MemType::NormalUncached => base | SMALL | AP_RW | TEX_001 | XN,
        MemType::Device => base | SMALL | AP_RW | B | XN,
        MemType::StronglyOrdered => base | SMALL | AP_RW | XN,
        MemType::Fault => 0,
    }
}

/// What the board maps where, in sections (MiB indexes).
#[derive(Clone, Copy, Debug)]
pub struct MemoryMap<'a> {
    /// DRAM from address 0, mapped Normal cached.
    pub dram_mib: u32,
    /// Parts of DRAM mapped Normal non-cacheable instead.
    pub uncached: &'a [Range<u32>],
    /// Windows mapped Strongly-ordered.
    pub strongly_ordered: &'a [Range<u32>],
    /// A section mapped page by page, if any (overrides the above for it).
    pub paged: Option<PagedSection<'a>>,
}

impl MemoryMap<'_> {
    /// The type of section `index`: Strongly-ordered windows first, then
    /// uncached DRAM, cached DRAM, and Device for everything else.
    pub fn memory_type(&self, index: u32) -> MemType {
        let within = |rs: &[Range<u32>]| rs.iter().any(|r| r.contains(&index));
        if within(self.strongly_ordered) {
            MemType::StronglyOrdered
        } else if within(self.uncached) {
            MemType::NormalUncached
        } else if index < self.dram_mib {
            MemType::NormalCached
        } else {
            MemType::Device
        }
    }

    /// Fill a first-level table with this map, and `pages` (at bus
    /// address `pages_addr`) with the paged section's pages.
    pub fn fill(&self, table: &mut [u32; SECTIONS], pages: &mut PageTable, pages_addr: u32) {
        for (i, e) in (0u32..).zip(table.iter_mut()) {
            *e = section_entry(i, self.memory_type(i));
        }
        if let Some(p) = &self.paged {
            p.fill(pages);
            if let Some(e) = table.get_mut(p.section as usize) {
                *e = page_table_entry(pages_addr);
            }
        }
    }
}

/// The sections `[start, end)` covering the bytes `[start, end)`.
pub const fn sections_of(bytes: Range<usize>) -> Range<u32> {
    let first = (bytes.start >> 20) as u32;
    let last = ((bytes.end + 0xf_ffff) >> 20) as u32;
    first..if last > first { last } else { first + 1 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn section_entries_match_the_architecture_manual() {
        let e = section_entry(0x001, MemType::NormalCached);
        assert_eq!(e & 0b11, 0b10, "section");
        assert_eq!(e >> 20, 0x001, "base");
        assert_eq!((e >> 12) & 0b111, 0b001, "TEX");
        assert_eq!((e >> 2) & 0b11, 0b11, "C and B");
        assert_eq!((e >> 10) & 0b11, 0b11, "AP[1:0] full access");
        assert_eq!(e & (1 << 15), 0, "AP[2] clear");
        assert_eq!((e >> 5) & 0xf, 0, "domain 0");
        assert_eq!(e & (1 << 4), 0, "executable");
        assert_eq!(e, 0x0010_1c0e);
        assert_eq!(section_entry(0x040, MemType::NormalUncached), 0x0400_1c12, "TEX 001 C0 B0 XN");
        assert_eq!(section_entry(0xf08, MemType::Device), 0xf080_0c16, "TEX 000 C0 B1 XN");
        assert_eq!(section_entry(0xff2, MemType::StronglyOrdered), 0xff20_0c12, "TEX 000 C0 B0 XN");
        assert_eq!(section_entry(0x123, MemType::Fault), 0);
    }

    #[test]
    fn the_de1_soc_map_puts_the_bridge_strongly_ordered() {
        // Lightweight HPS-to-FPGA bridge: 0xFF20_0000, 2 MiB.
        let lw = sections_of(0xff20_0000..0xff40_0000);
        assert_eq!(lw, 0xff2..0xff4);
        let dma = sections_of(0x0400_0000..0x0400_4000);
        assert_eq!(dma, 0x040..0x041, "a partial MiB is a whole section");
        let map = MemoryMap { dram_mib: 1024, uncached: &[dma], strongly_ordered: &[lw], paged: None };
        let mut t = [0u32; SECTIONS];
        map.fill(&mut t, &mut PageTable([0; PAGES]), 0);
        assert_eq!(t[0x001], section_entry(0x001, MemType::NormalCached));
        assert_eq!(t[0x040], section_entry(0x040, MemType::NormalUncached));
        assert_eq!(t[0x3ff], section_entry(0x3ff, MemType::NormalCached), "last MiB of DRAM");
        assert_eq!(t[0x400], section_entry(0x400, MemType::Device));
        for i in [0xff2, 0xff3] {
            let e = t[i];
            assert_eq!((e >> 12) & 0b111, 0, "TEX 000");
            assert_eq!((e >> 2) & 0b11, 0, "C 0 B 0: Strongly-ordered, not Device");
            assert_eq!(e >> 20, i as u32);
        }
        assert_eq!(t[0xff4], section_entry(0xff4, MemType::Device), "the window ends");
        assert_eq!(t[0xff7], section_entry(0xff7, MemType::Device), "EMAC1 stays Device");
        for (i, e) in t.iter().enumerate() {
            assert_eq!((*e >> 20) as usize, i, "flat");
        }
    }

    #[test]
    fn the_line_buffer_page_starts_strongly_ordered_and_is_retyped_alone() {
        // The DE1-SoC's paged section before the probe: every page
        // Strongly-ordered, the line buffer (0xFF20_1000) included.
        let paged = PagedSection { section: 0xff2, default: MemType::StronglyOrdered, pages: &[] };
        let mut pages = PageTable([0; PAGES]);
        paged.fill(&mut pages);
        let before = pages.0;
        assert_eq!(before[1], small_page_entry(0xff20_1000, MemType::StronglyOrdered));
        assert_eq!((before[1] >> 6) & 0b111, 0, "TEX 000: no speculative access");
        // After a row-mode accelerator answered: that page alone Normal
        // non-cacheable.
        assert_eq!(pages.retype(0xff2, 0xff20_1000, MemType::NormalUncached), Some(1));
        assert_eq!(pages.0[1], small_page_entry(0xff20_1000, MemType::NormalUncached));
        assert_eq!((pages.0[1] >> 6) & 0b111, 0b001, "TEX 001: Normal");
        for i in (0..PAGES).filter(|i| *i != 1) {
            assert_eq!(pages.0[i], before[i], "page {i} unchanged");
        }
        assert_eq!(pages.retype(0xff2, 0xff30_1000, MemType::NormalUncached), None, "another section");
    }

    #[test]
    fn the_line_buffer_page_is_normal_uncached_and_the_csr_page_strongly_ordered() {
        // The accelerator: CSRs at 0xFF20_0000, line buffer at 0xFF20_1000.
        let lw = sections_of(0xff20_0000..0xff40_0000);
        let paged = PagedSection {
            section: 0xff2,
            default: MemType::StronglyOrdered,
            pages: &[(1..2, MemType::NormalUncached)],
        };
        let map = MemoryMap { dram_mib: 1024, uncached: &[], strongly_ordered: &[lw], paged: Some(paged) };
        let mut t = [0u32; SECTIONS];
        let mut pages = PageTable([0; PAGES]);
        map.fill(&mut t, &mut pages, 0x0011_8400);
        assert_eq!(t[0xff2], 0x0011_8401, "page-table entry: base 31:10, bits 1:0 = 01, domain 0");
        assert_eq!(t[0xff3], section_entry(0xff3, MemType::StronglyOrdered), "the second MiB stays a section");
        let csr = pages.0[0];
        assert_eq!(csr & !0xfff, 0xff20_0000);
        assert_eq!(csr & 0b11, 0b11, "small page, XN");
        assert_eq!((csr >> 6) & 0b111, 0, "TEX 000");
        assert_eq!((csr >> 2) & 0b11, 0, "C 0 B 0: Strongly-ordered");
        let line = pages.0[1];
        assert_eq!(line & !0xfff, 0xff20_1000);
        assert_eq!((line >> 6) & 0b111, 0b001, "TEX 001");
        assert_eq!((line >> 2) & 0b11, 0, "C 0 B 0: Normal non-cacheable");
        assert_eq!((line >> 4) & 0b11, 0b11, "AP full access");
        assert_eq!(pages.0[2], small_page_entry(0xff20_2000, MemType::StronglyOrdered));
        assert_eq!(pages.0[255] & !0xfff, 0xff2f_f000);
    }
}
