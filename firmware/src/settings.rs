//! The board's settings as boot.cmd hands them over: `raytracer.txt` from
//! the card's FAT partition, copied by U-Boot to the hand-off area
//! (memory.x, `HANDOFF`): the word `RTCF` (0x4643_5452, little-endian), the
//! text's length in bytes, then the text. QEMU's tests put the same bytes
//! there with `-device loader`. Nothing there (no file, no boot.cmd, a
//! cold start with stale memory that lacks the word) means the defaults:
//! DHCP, then link-local; the name `raytracer`; the board's MAC.

use core::fmt::Write;

use rt_services::address::settings::Settings;

/// The hand-off area's size (memory.x): the header and the text.
pub const HANDOFF_BYTES: usize = 4096;

/// "RTCF" as boot.cmd's `mw.l` writes it.
pub const MAGIC: u32 = u32::from_le_bytes(*b"RTCF");

unsafe extern "C" {
    /// The hand-off area (memory.x): memory no section of the image
    /// covers, which U-Boot (or QEMU's loader) wrote before the firmware
    /// started.
    static __handoff: u8;
}

/// The settings text handed over and the file's length, if the header is
/// there: the text as far as the area holds it (boot.cmd loads at most
/// that much, and writes the file's whole length).
fn handed_over(area: &mut [u8; HANDOFF_BYTES]) -> Option<(&[u8], usize)> {
    let base = &raw const __handoff;
    for (i, byte) in area.iter_mut().enumerate() {
        // SAFETY: within the 4 KiB memory.x reserves at `__handoff`, mapped
        // cacheable RAM; volatile because the bytes were put there by the
        // boot loader, outside this program.
        *byte = unsafe { core::ptr::read_volatile(base.add(i)) };
    }
    let word = |at: usize| u32::from_le_bytes([area[at], area[at + 1], area[at + 2], area[at + 3]]);
    if word(0) != MAGIC {
        return None;
    }
    let len = usize::try_from(word(4)).unwrap_or(usize::MAX);
    Some((&area[8..8 + len.min(HANDOFF_BYTES - 8)], len))
}

/// Read and log the settings (and every line that could not be used).
pub fn load(log: &mut impl Write) -> Settings {
    let mut area = [0u8; HANDOFF_BYTES];
    let Some((text, length)) = handed_over(&mut area) else {
        let _ = writeln!(
            log,
            "settings: none handed over (raytracer.txt): DHCP, then link-local; name {}",
            rt_services::DEFAULT_HOST_NAME
        );
        return Settings::default();
    };
    let settings = Settings::parse_handed(text, length);
    let _ = writeln!(log, "settings: raytracer.txt, {length} bytes");
    for p in &settings.problems {
        let _ = writeln!(log, "settings: raytracer.txt {p}: ignored");
    }
    let more = usize::from(settings.problem_count).saturating_sub(settings.problems.len());
    if more > 0 {
        let _ = writeln!(log, "settings: {more} more lines ignored");
    }
    settings
}
