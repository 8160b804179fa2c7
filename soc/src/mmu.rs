//! The flat (identity) map: one short-descriptor section entry per MiB.
//!
//! Entry format: ARM Architecture Reference Manual ARMv7-A/R (DDI 0406C)
//! B3.5.1 "Short-descriptor translation table format", figure B3-4
//! (section): bits 1:0 = 0b10, B 2, C 3, XN 4, domain 8:5, `AP[1:0]` 11:10,
//! `TEX[2:0]` 14:12, `AP[2]` 15, S 16, nG 17, base 31:20; memory types per
//! table B3-10 (TEX/C/B with TEX remap off).
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

/// What the board maps where, in sections (MiB indexes).
#[derive(Clone, Copy, Debug)]
pub struct MemoryMap<'a> {
    /// DRAM from address 0, mapped Normal cached.
    pub dram_mib: u32,
    /// Parts of DRAM mapped Normal non-cacheable instead.
    pub uncached: &'a [Range<u32>],
    /// Windows mapped Strongly-ordered.
    pub strongly_ordered: &'a [Range<u32>],
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

    /// Fill a first-level table with this map.
    pub fn fill(&self, table: &mut [u32; SECTIONS]) {
        for (i, e) in (0u32..).zip(table.iter_mut()) {
            *e = section_entry(i, self.memory_type(i));
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
        let map = MemoryMap { dram_mib: 1024, uncached: &[dma], strongly_ordered: &[lw] };
        let mut t = [0u32; SECTIONS];
        map.fill(&mut t);
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
}
