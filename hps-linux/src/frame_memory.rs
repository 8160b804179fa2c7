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
//! Serving frames from such a buffer (mapping it non-cached, the boot
//! self-test's frame half on it, the ring in it) is not built yet: a
//! buffer found is reported, and rows are rendered still.

use std::fmt;
use std::path::{Path, PathBuf};

/// The HPS's SDRAM that the FPGA-to-SDRAM port addresses: the DE1-SoC's
/// 1 GiB of DDR3 from address 0 (Terasic DE1-SoC User Manual, 2.1 "Layout
/// and Components": 1GB DDR3 SDRAM on the HPS; Cyclone V HPS TRM, "SDRAM
/// Controller Subsystem": the FPGA ports see SDRAM addresses).
pub const SDRAM_END: u64 = 0x4000_0000;

/// The ring frame mode would fill: the board's slots, whole frames.
pub const RING_BYTES: u64 = (hps_sim::board::BOARD_SLOTS * model::FRAME_BYTES) as u64;

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
        let checked =
            attr("phys_addr").and_then(|phys_addr| Ok((phys_addr, attr("size")?))).and_then(|(phys_addr, size)| {
                fits(phys_addr, size, need).map_err(|why| format!("{name} ({size} bytes at {phys_addr:#x}): {why}"))?;
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
