//! CPU barriers and the pure parts of the Armv7-A MMU set-up (short-descriptor
//! section entries), shared by the binary and the host tests.

/// Data synchronisation barrier: every earlier memory access (normal memory
/// seen by a DMA master included) completes before any later one, device
/// register writes included. ARM ARM (DDI 0406C) A3.8.3.
#[inline]
pub fn dsb() {
    #[cfg(target_arch = "arm")]
    // SAFETY: `dsb sy` only orders memory accesses; it has no other effect.
    unsafe {
        core::arch::asm!("dsb sy", options(nostack, preserves_flags))
    };
    #[cfg(not(target_arch = "arm"))]
    core::sync::atomic::fence(core::sync::atomic::Ordering::SeqCst);
}

/// Memory types of the flat (identity) map, one per 1 MiB section.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemType {
    /// Normal memory, inner and outer write-back write-allocate: code, data,
    /// stacks.
    NormalCached,
    /// Normal memory, non-cacheable: DMA descriptors and buffers, so the MAC
    /// and the CPU see the same bytes without cache maintenance.
    NormalUncached,
    /// Shareable device memory, never executed: peripheral registers.
    Device,
    /// Not mapped: any access faults (and the abort handler reports it).
    Fault,
}

/// Number of 1 MiB sections in the 4 GiB address space.
pub const SECTIONS: usize = 4096;

/// The short-descriptor first-level "section" entry mapping the 1 MiB at
/// `index << 20` to itself with type `ty`, read/write at PL1, domain 0.
///
/// Bit positions: ARM ARM (DDI 0406C) B3.5.1 "Short-descriptor translation
/// table format", figure B3-4 (section): bits 1:0 = 0b10, B 2, C 3, XN 4,
/// domain 8:5, `AP[1:0]` 11:10, `TEX[2:0]` 14:12, `AP[2]` 15, S 16, nG 17, base
/// 31:20; memory attributes per table B3-10 (TEX/C/B encodings).
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
        // TEX 000, C 0, B 1: shareable device.
        MemType::Device => base | SECTION | AP_RW | B | XN,
        MemType::Fault => 0,
    }
}

/// Fill a first-level table with the identity map given by `ty_of(index)`.
pub fn build_flat_table(table: &mut [u32; SECTIONS], ty_of: impl Fn(u32) -> MemType) {
    for (i, e) in table.iter_mut().enumerate() {
        let i = i as u32;
        *e = section_entry(i, ty_of(i));
    }
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

        let u = section_entry(0x040, MemType::NormalUncached);
        assert_eq!(u, 0x0400_1c12, "TEX 001 C0 B0 XN");
        let d = section_entry(0xf08, MemType::Device);
        assert_eq!(d, 0xf080_0c16, "TEX 000 C0 B1 XN");
        assert_eq!(section_entry(0x123, MemType::Fault), 0);
    }

    #[test]
    fn flat_table_maps_each_megabyte_to_itself() {
        let mut t = [0u32; SECTIONS];
        build_flat_table(&mut t, |i| if i < 512 { MemType::NormalCached } else { MemType::Device });
        assert_eq!(t[0] >> 20, 0);
        assert_eq!(t[511] >> 20, 511);
        assert_eq!(t[4095] >> 20, 4095);
        assert_eq!(t[511] & 0b1100, 0b1100);
        assert_eq!(t[512] & 0b1100, 0b0100);
    }
}
