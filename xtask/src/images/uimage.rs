//! The DE1-SoC payload: an ELF's loadable bytes as a raw binary, and the
//! U-Boot legacy image around it (`mkimage -A arm -O u-boot -T standalone
//! -C none`).
//!
//! Legacy header (64 bytes, big-endian; U-Boot `include/image.h`, struct
//! `legacy_img_hdr`; summarised in docs/platform.md "Boot without
//! Linux"): magic 0x27051956, header CRC-32 (computed with this field 0),
//! time, data size, load address, entry point, data CRC-32, OS, arch, type,
//! compression, 32-byte name.

use crate::support::Result;

/// Legacy image magic.
pub const IH_MAGIC: u32 = 0x2705_1956;
/// OS code "U-Boot" (firmware run as is).
pub const IH_OS_U_BOOT: u8 = 17;
/// Architecture code ARM.
pub const IH_ARCH_ARM: u8 = 2;
/// Image type "standalone program".
pub const IH_TYPE_STANDALONE: u8 = 1;
/// Compression none.
pub const IH_COMP_NONE: u8 = 0;
/// Header length.
pub const HEADER_LEN: usize = 64;
/// Name field length.
pub const NAME_LEN: usize = 32;

/// The 64-byte legacy header for `data`.
pub fn legacy_header(data: &[u8], load: u32, entry: u32, time: u32, name: &str) -> [u8; HEADER_LEN] {
    let mut h = [0u8; HEADER_LEN];
    let put = |h: &mut [u8; HEADER_LEN], at: usize, v: u32| h[at..at + 4].copy_from_slice(&v.to_be_bytes());
    put(&mut h, 0, IH_MAGIC);
    put(&mut h, 8, time);
    put(&mut h, 12, data.len() as u32);
    put(&mut h, 16, load);
    put(&mut h, 20, entry);
    put(&mut h, 24, crc32fast::hash(data));
    h[28] = IH_OS_U_BOOT;
    h[29] = IH_ARCH_ARM;
    h[30] = IH_TYPE_STANDALONE;
    h[31] = IH_COMP_NONE;
    let n = name.as_bytes();
    let n = &n[..n.len().min(NAME_LEN - 1)];
    h[32..32 + n.len()].copy_from_slice(n);
    let hcrc = crc32fast::hash(&h);
    put(&mut h, 4, hcrc);
    h
}

/// Header followed by `data`.
pub fn legacy_image(data: &[u8], load: u32, entry: u32, time: u32, name: &str) -> Vec<u8> {
    let mut out = legacy_header(data, load, entry, time, name).to_vec();
    out.extend_from_slice(data);
    out
}

/// The raw memory image of a 32-bit little-endian ELF: every `PT_LOAD`
/// segment's file bytes at its physical (load) address, gaps zero-filled,
/// starting at the lowest one. Returns (start address, bytes, entry).
pub fn elf32_to_binary(elf: &[u8]) -> Result<(u32, Vec<u8>, u32)> {
    let u16_at = |o: usize| elf.get(o..o + 2).map(|b| u16::from_le_bytes([b[0], b[1]]));
    let u32_at = |o: usize| elf.get(o..o + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
    if elf.get(0..4) != Some(b"\x7fELF") || elf.get(4) != Some(&1) || elf.get(5) != Some(&1) {
        return Err("not a 32-bit little-endian ELF".into());
    }
    let bad = || "truncated ELF".to_string();
    let entry = u32_at(24).ok_or_else(bad)?;
    let phoff = u32_at(28).ok_or_else(bad)? as usize;
    let phentsize = u16_at(42).ok_or_else(bad)? as usize;
    let phnum = u16_at(44).ok_or_else(bad)? as usize;
    let mut segments = Vec::new();
    for i in 0..phnum {
        let p = phoff + i * phentsize;
        const PT_LOAD: u32 = 1;
        if u32_at(p).ok_or_else(bad)? != PT_LOAD {
            continue;
        }
        let offset = u32_at(p + 4).ok_or_else(bad)? as usize;
        let paddr = u32_at(p + 12).ok_or_else(bad)?;
        let filesz = u32_at(p + 16).ok_or_else(bad)? as usize;
        if filesz == 0 {
            continue; // .bss, stacks, the DMA area: nothing to load
        }
        let bytes = elf.get(offset..offset + filesz).ok_or_else(bad)?;
        segments.push((paddr, bytes));
    }
    let start = segments.iter().map(|s| s.0).min().ok_or("ELF has no loadable bytes")?;
    let end = segments.iter().map(|s| s.0 as usize + s.1.len()).max().unwrap_or(start as usize);
    if end - start as usize > 64 << 20 {
        return Err(format!(
            "loadable bytes span {} MiB: a NOLOAD section is being loaded?",
            (end - start as usize) >> 20
        ));
    }
    let mut out = vec![0u8; end - start as usize];
    for (addr, bytes) in segments {
        let at = (addr - start) as usize;
        out[at..at + bytes.len()].copy_from_slice(bytes);
    }
    Ok((start, out, entry))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::process::Command;

    fn tmp(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("xtask-uimage-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d.join(name)
    }

    fn mkimage_list(path: &std::path::Path) -> (bool, String) {
        let out = Command::new("mkimage")
            .arg("-l")
            .arg(path)
            .output()
            .expect("mkimage (Debian u-boot-tools) is installed by `cargo xtask test`");
        let text = String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
        (out.status.success(), text)
    }

    #[test]
    fn header_fields_are_big_endian_at_their_offsets() {
        let data = b"hello world".to_vec();
        let h = legacy_header(&data, 0x0010_0040, 0x0010_0040, 0x1234_5678, "raytracer");
        assert_eq!(&h[0..4], &[0x27, 0x05, 0x19, 0x56]);
        assert_eq!(&h[8..12], &[0x12, 0x34, 0x56, 0x78]);
        assert_eq!(u32::from_be_bytes(h[12..16].try_into().unwrap()), 11);
        assert_eq!(u32::from_be_bytes(h[16..20].try_into().unwrap()), 0x0010_0040);
        assert_eq!(u32::from_be_bytes(h[24..28].try_into().unwrap()), crc32fast::hash(&data));
        assert_eq!(&h[28..32], &[17, 2, 1, 0]);
        assert_eq!(&h[32..41], b"raytracer");
        let mut zeroed = h;
        zeroed[4..8].fill(0);
        assert_eq!(u32::from_be_bytes(h[4..8].try_into().unwrap()), crc32fast::hash(&zeroed));
    }

    #[test]
    #[ignore = "needs Debian's mkimage (u-boot-tools); `cargo xtask test` installs it and runs these"]
    fn mkimage_lists_our_image_and_builds_the_same_header() {
        let data: Vec<u8> = (0..5000u32).map(|i| (i * 7 % 251) as u8).collect();
        let img = legacy_image(&data, 0x0010_0040, 0x0010_0040, 0, "raytracer test");
        let path = tmp("ours.img");
        std::fs::write(&path, &img).unwrap();
        let (ok, text) = mkimage_list(&path);
        assert!(ok, "mkimage -l rejected the image:\n{text}");
        assert!(text.contains("Image Name:   raytracer test"), "{text}");
        assert!(text.contains("ARM U-Boot Standalone Program (uncompressed)"), "{text}");
        assert!(text.contains("Data Size:    5000 Bytes"), "{text}");
        assert!(text.contains("Load Address: 00100040"), "{text}");
        assert!(text.contains("Entry Point:  00100040"), "{text}");

        // mkimage's own image of the same data: equal but for time and hcrc.
        let bin = tmp("data.bin");
        std::fs::write(&bin, &data).unwrap();
        let theirs = tmp("theirs.img");
        let st = Command::new("mkimage")
            .args([
                "-A",
                "arm",
                "-O",
                "u-boot",
                "-T",
                "standalone",
                "-C",
                "none",
                "-a",
                "0x00100040",
                "-e",
                "0x00100040",
                "-n",
                "raytracer test",
                "-d",
            ])
            .arg(&bin)
            .arg(&theirs)
            .output()
            .unwrap();
        assert!(st.status.success(), "{}", String::from_utf8_lossy(&st.stderr));
        let theirs = std::fs::read(&theirs).unwrap();
        assert_eq!(theirs.len(), img.len());
        assert_eq!(theirs[0..4], img[0..4], "magic");
        assert_eq!(theirs[12..], img[12..], "size, addresses, data CRC, codes, name, data");
        // With mkimage's time stamp our header CRC must equal mkimage's.
        let time = u32::from_be_bytes(theirs[8..12].try_into().unwrap());
        let again = legacy_header(&data, 0x0010_0040, 0x0010_0040, time, "raytracer test");
        assert_eq!(again[..], theirs[..64]);
    }

    #[test]
    #[ignore = "needs Debian's mkimage (u-boot-tools); `cargo xtask test` installs it and runs these"]
    fn mkimage_rejects_a_corrupted_payload() {
        let data = vec![0x5a; 256];
        let mut img = legacy_image(&data, 0x0010_0040, 0x0010_0040, 0, "raytracer");
        img[100] ^= 1;
        let path = tmp("bad.img");
        std::fs::write(&path, &img).unwrap();
        // mkimage verifies the data CRC; a legacy image failing it is not
        // listed as one (mkimage then tries other formats).
        let (_, text) = mkimage_list(&path);
        assert!(!text.contains("Image Name:   raytracer"), "corruption not detected:\n{text}");
        img[100] ^= 1;
        std::fs::write(&path, &img).unwrap();
        let (ok, text) = mkimage_list(&path);
        assert!(ok && text.contains("Image Name:   raytracer"), "restored image not listed:\n{text}");
    }

    #[test]
    fn elf_load_segments_become_a_flat_binary() {
        // A minimal ELF32 with two PT_LOAD segments (one with a gap) and a
        // NOLOAD-like segment with filesz 0.
        let mut elf = vec![0u8; 0x200];
        elf[0..4].copy_from_slice(b"\x7fELF");
        elf[4] = 1;
        elf[5] = 1;
        elf[24..28].copy_from_slice(&0x0010_0040u32.to_le_bytes());
        elf[28..32].copy_from_slice(&52u32.to_le_bytes());
        elf[42..44].copy_from_slice(&32u16.to_le_bytes());
        elf[44..46].copy_from_slice(&3u16.to_le_bytes());
        let ph = |elf: &mut Vec<u8>, i: usize, off: u32, paddr: u32, filesz: u32| {
            let p = 52 + i * 32;
            elf[p..p + 4].copy_from_slice(&1u32.to_le_bytes());
            elf[p + 4..p + 8].copy_from_slice(&off.to_le_bytes());
            elf[p + 8..p + 12].copy_from_slice(&(paddr + 0x1000).to_le_bytes()); // vaddr differs
            elf[p + 12..p + 16].copy_from_slice(&paddr.to_le_bytes());
            elf[p + 16..p + 20].copy_from_slice(&filesz.to_le_bytes());
        };
        ph(&mut elf, 0, 0x100, 0x0010_0040, 4);
        ph(&mut elf, 1, 0x180, 0x0010_0050, 2);
        ph(&mut elf, 2, 0x0, 0x0400_0000, 0);
        elf[0x100..0x104].copy_from_slice(&[1, 2, 3, 4]);
        elf[0x180..0x182].copy_from_slice(&[9, 8]);
        let (start, bin, entry) = elf32_to_binary(&elf).unwrap();
        assert_eq!(start, 0x0010_0040);
        assert_eq!(entry, 0x0010_0040);
        assert_eq!(bin, vec![1, 2, 3, 4, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 9, 8]);
        assert!(elf32_to_binary(b"not an elf").is_err());
    }
}
