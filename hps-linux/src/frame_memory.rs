//! The memory frame mode needs, looked for before the frame DMA is ever
//! considered ([`find`]): a buffer the kernel set aside, physically
//! contiguous, that the FPGA-to-SDRAM port can reach, large enough for
//! the board's ring. Under Linux that comes from the u-dma-buf module
//! (ikwzm/udmabuf: `/dev/udmabufN`, its `phys_addr` and `size` in
//! `/sys/class/u-dma-buf/udmabufN/`, README "Device file"; `u-dma-buf.c`
//! prints `phys_addr` as `%pad`, 0x and 8 hex digits for the A9's 32-bit
//! DMA addresses, and `size` as `%zu`; a `reserved-memory` region given
//! to it as its `memory-region` works the
//! same). Without one the program renders rows over the lightweight
//! bridge and says why ([`NoFrameMemory`]): a frame DMA started at an
//! address the kernel did not set aside would write over whatever memory
//! is there.
//!
//! A buffer found is mapped with the CPU cache off ([`DmaRing`]): opened
//! with `O_SYNC`, which u-dma-buf maps uncached under its default
//! `sync_mode` 1 (u-dma-buf README, "Disabling CPU cache": modes 1, 2, 3,
//! 5, 6, 7 give an uncached, write-combined or coherent mapping with
//! `O_SYNC`; 0 and 4 keep the cache on, which [`find`] refuses). So what
//! the FPGA writes behind the caches is what the program reads, with no
//! cache maintenance from user space. On 32-bit ARM the kernel's uncached
//! mapping (`pgprot_noncached`) is Strongly-ordered, where an unaligned
//! access is unpredictable: every access to the ring is an aligned word.
//! The ring's slots lie in the buffer, and the frame DMA is given their
//! physical addresses.

use std::fmt;
use std::fs::OpenOptions;
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};

use memmap2::{MmapOptions, MmapRaw};
use model::{FRAME_BYTES, ROW_BYTES};
use rt_services::FrameMemory;

/// The HPS's SDRAM that the FPGA-to-SDRAM port addresses: the DE1-SoC's
/// 1 GiB of DDR3 from address 0 (Terasic DE1-SoC User Manual, 2.1 "Layout
/// and Components": 1GB DDR3 SDRAM on the HPS; Cyclone V HPS TRM, "SDRAM
/// Controller Subsystem": the FPGA ports see SDRAM addresses).
pub const SDRAM_END: u64 = 0x4000_0000;

/// The ring frame mode fills: the board's slots (the services' and the
/// display's), whole frames.
pub const RING_BYTES: u64 = (crate::panel::RING_SLOTS * model::FRAME_BYTES) as u64;

/// FRAME_BASE holds an 8-byte aligned address (docs/frame-dma.md).
const FRAME_BASE_ALIGN: u64 = 8;

/// A u-dma-buf buffer fit for the ring.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DmaBuffer {
    /// Its device node.
    pub device: PathBuf,
    /// Its physical (bus) address.
    pub phys_addr: u64,
    /// Its length in bytes.
    pub size: u64,
}

/// Why frame mode cannot be used: each names what is missing.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum NoFrameMemory {
    /// No u-dma-buf device at all.
    NoBuffer {
        /// Where it was looked for.
        class: PathBuf,
    },
    /// Buffers, none usable; what is wrong with each.
    Unfit(Vec<String>),
}

impl fmt::Display for NoFrameMemory {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "frame mode without contiguous memory: ")?;
        match self {
            NoFrameMemory::NoBuffer { class } => write!(
                f,
                "no u-dma-buf buffer ({} is empty or absent; the older udmabuf driver's class is not read); the frame DMA needs one the kernel set aside",
                class.display()
            )?,
            NoFrameMemory::Unfit(why) => write!(f, "{}", why.join("; "))?,
        }
        write!(f, " (docs/linux.md, \"Frame mode\"); rendering rows over the lightweight bridge")
    }
}

/// The first u-dma-buf buffer in `sysfs` (its device in `dev`) of at
/// least `need` bytes inside [`SDRAM_END`], suitably aligned.
pub fn find(sysfs: &Path, dev: &Path, need: u64) -> Result<DmaBuffer, NoFrameMemory> {
    let class = sysfs.join("class/u-dma-buf");
    let mut names: Vec<String> = std::fs::read_dir(&class)
        .map(|d| d.flatten().map(|e| e.file_name().to_string_lossy().into_owned()).collect())
        .unwrap_or_default();
    names.sort();
    if names.is_empty() {
        return Err(NoFrameMemory::NoBuffer { class });
    }
    let mut unfit = Vec::new();
    for name in names {
        let attr = |a: &str| {
            let path = class.join(&name).join(a);
            let text = std::fs::read_to_string(&path).map_err(|e| format!("{name}: {}: {e}", path.display()))?;
            parse_number(text.trim()).ok_or(format!("{name}: {a} reads {:?}", text.trim()))
        };
        // Absent in older modules, whose O_SYNC mapping is uncached.
        let sync_mode = attr("sync_mode").ok();
        let checked =
            attr("phys_addr").and_then(|phys_addr| Ok((phys_addr, attr("size")?))).and_then(|(phys_addr, size)| {
                fits(phys_addr, size, need).map_err(|why| format!("{name} ({size} bytes at {phys_addr:#x}): {why}"))?;
                if let Some(mode @ (0 | 4)) = sync_mode {
                    return Err(format!(
                        "{name}: sync_mode {mode} keeps the CPU cache on even with O_SYNC, and the FPGA's writes \
                         would be read stale (write 1 to /sys/class/u-dma-buf/{name}/sync_mode)"
                    ));
                }
                Ok(DmaBuffer { device: dev.join(&name), phys_addr, size })
            });
        match checked {
            Ok(buffer) => return Ok(buffer),
            Err(why) => unfit.push(why),
        }
    }
    Err(NoFrameMemory::Unfit(unfit))
}

/// Whether `size` bytes at `phys_addr` hold `need` where the frame DMA
/// can write them.
fn fits(phys_addr: u64, size: u64, need: u64) -> Result<(), String> {
    if size < need {
        return Err(format!("smaller than the ring's {need} bytes"));
    }
    if phys_addr.saturating_add(need) > SDRAM_END {
        return Err(format!("past the SDRAM the FPGA-to-SDRAM port reaches (below {SDRAM_END:#x})"));
    }
    if !phys_addr.is_multiple_of(FRAME_BASE_ALIGN) {
        return Err(format!("not {FRAME_BASE_ALIGN}-byte aligned"));
    }
    Ok(())
}

/// The ring's slots in a u-dma-buf buffer, mapped non-cached (`O_SYNC`):
/// the [`FrameMemory`] frame mode renders into. The slots follow each
/// other from the buffer's start; the frame DMA is given their physical
/// addresses.
pub struct DmaRing {
    map: MmapRaw,
    phys_addr: u32,
    slots: usize,
    device: PathBuf,
}

impl fmt::Debug for DmaRing {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "DmaRing({}, {} slots at {:#x})", self.device.display(), self.slots, self.phys_addr)
    }
}

impl DmaRing {
    /// Map `slots` frame slots of `buffer` (found by [`find`], so it holds
    /// them inside [`SDRAM_END`]).
    pub fn open(buffer: &DmaBuffer, slots: usize) -> Result<DmaRing, String> {
        let len = slots * FRAME_BYTES;
        if (len as u64) > buffer.size {
            return Err(format!("{}: {} bytes, not enough for {slots} frames", buffer.device.display(), buffer.size));
        }
        let phys_addr = u32::try_from(buffer.phys_addr)
            .ok()
            .filter(|a| u64::from(*a) + len as u64 <= SDRAM_END)
            .ok_or(format!("{}: {:#x} is past the SDRAM", buffer.device.display(), buffer.phys_addr))?;
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(libc::O_SYNC)
            .open(&buffer.device)
            .map_err(|e| format!("{}: {e}", buffer.device.display()))?;
        let map = MmapOptions::new()
            .len(len)
            .map_raw(&file)
            .map_err(|e| format!("{}: mmap: {e}", buffer.device.display()))?;
        Ok(DmaRing { map, phys_addr, slots, device: buffer.device.clone() })
    }

    /// Where row `y` of `slot` starts plus `offset`, if `len` bytes from
    /// there lie in the mapping.
    fn at(&self, slot: usize, y: u16, offset: usize, len: usize) -> Option<*mut u8> {
        if slot >= self.slots || usize::from(y) >= model::HEIGHT || offset + len > ROW_BYTES {
            return None;
        }
        let start = slot * FRAME_BYTES + usize::from(y) * ROW_BYTES + offset;
        Some(self.map.as_mut_ptr().wrapping_add(start))
    }
}

/// Orders the loads after it after every load before it, as seen by the
/// whole system (`dmb sy`, not only the inner-shareable `dmb ish` that
/// `std::sync::atomic::fence` issues on ARMv7): the ring reads a row only
/// after the accelerator's ROWS_DONE register said it landed (ARM
/// Architecture Reference Manual ARMv7-A, A3.8.3 "Memory barriers", DMB).
/// Needed where the mapping is Normal non-cacheable (`sync_mode` 2, write
/// combining); harmless on a Strongly-ordered one.
fn read_barrier() {
    #[cfg(target_arch = "arm")]
    // SAFETY: a barrier instruction: no memory, register or flag changes.
    unsafe {
        core::arch::asm!("dmb sy", options(nostack, preserves_flags))
    };
    #[cfg(not(target_arch = "arm"))]
    std::sync::atomic::fence(std::sync::atomic::Ordering::SeqCst);
}

impl FrameMemory for DmaRing {
    fn slot_address(&self, slot: usize) -> u32 {
        // The frame DMA is given this address: never one past the buffer.
        assert!(slot < self.slots, "slot {slot} of a ring of {}", self.slots);
        self.phys_addr + (slot * FRAME_BYTES) as u32
    }

    fn read_row(&mut self, slot: usize, y: u16, offset: usize, out: &mut [u8]) {
        let Some(row) = self.at(slot, y, 0, ROW_BYTES) else { return };
        if offset + out.len() > ROW_BYTES {
            return;
        }
        read_barrier();
        // Whole aligned words only (module docs): those covering the bytes
        // asked for, then the bytes out of them.
        let (first, last) = (offset / 4, (offset + out.len()).div_ceil(4));
        let mut bytes = [0u8; ROW_BYTES];
        for w in first..last {
            // SAFETY: `at` checked the row lies in the mapping, which lives
            // as long as `self`; rows start 4-byte aligned (the mapping is
            // page aligned, frames and rows are multiples of 4 bytes), and
            // `w` is below the row's word count. The ring reads only rows
            // the DMA finished writing (its counter covered them).
            let word = unsafe { row.cast::<u32>().add(w).read_volatile() };
            bytes[w * 4..w * 4 + 4].copy_from_slice(&word.to_ne_bytes());
        }
        out.copy_from_slice(&bytes[offset..offset + out.len()]);
    }

    fn write_row(&mut self, slot: usize, y: u16, row: &[u8; ROW_BYTES]) {
        let Some(dst) = self.at(slot, y, 0, ROW_BYTES) else { return };
        for (w, chunk) in row.chunks_exact(4).enumerate() {
            let word = u32::from_ne_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
            // SAFETY: as in `read_row`: an aligned word of the row, in the
            // mapping; the ring gives a slot to one engine at a time (this
            // is only for an engine that writes rows itself, never while
            // the DMA has the slot).
            unsafe { dst.cast::<u32>().add(w).write_volatile(word) };
        }
    }
}

/// sysfs numbers: `0x`-prefixed hex (`phys_addr`) or decimal (`size`).
fn parse_number(text: &str) -> Option<u64> {
    match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => u64::from_str_radix(hex, 16).ok(),
        None => text.parse().ok(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sysfs_numbers_read_in_either_base() {
        assert_eq!(parse_number("0x000000003f000000"), Some(0x3f00_0000));
        assert_eq!(parse_number("8388608"), Some(8 << 20));
        assert_eq!(parse_number("lots"), None);
    }

    #[test]
    fn a_buffer_fits_only_whole_aligned_and_within_sdram() {
        assert_eq!(fits(0x3f00_0000, 8 << 20, 7 << 20), Ok(()));
        assert!(fits(0x3f00_0000, 1 << 20, 7 << 20).unwrap_err().contains("smaller"));
        assert!(fits(0x3ff0_0000, 8 << 20, 7 << 20).unwrap_err().contains("past the SDRAM"));
        assert!(fits(0x3f00_0004, 8 << 20, 7 << 20).unwrap_err().contains("aligned"));
    }
}
