//! Copying rows out of the frame ring with multi-word loads.
//!
//! Each row is read once, right after its lines were invalidated, so every
//! line comes from DRAM. An `ldm` of four words is one access (ARM ARM DDI
//! 0406C A3.5.5: a multi-word load to Normal memory may be one access) and
//! four times fewer load instructions than compiler-builtins' word-by-word
//! `memcpy` for this target, hence this hand-written loop.

/// Copy `dst.len()` bytes from `src` into `dst`: bytes up to a word
/// boundary of `src`, then 16-byte `ldm` bursts (stored with `stm` when
/// `dst` is word aligned too, else with four `str`, which may be unaligned
/// to Normal memory with SCTLR.A clear), then the tail.
///
/// # Safety
///
/// `src..src + dst.len()` is readable memory that nothing writes meanwhile.
pub unsafe fn burst_copy(dst: &mut [u8], src: *const u8) {
    let len = dst.len();
    let d = dst.as_mut_ptr();
    // SAFETY (all pointer arithmetic below): offsets stay below `len`,
    // within `dst` and, by the caller's promise, within the source.
    let head = (src as usize).wrapping_neg() & 3;
    let head = head.min(len);
    for i in 0..head {
        // SAFETY: see above.
        unsafe { *d.add(i) = src.add(i).read_volatile() };
    }
    let words = (len - head) / 16 * 16;
    // SAFETY: see above; `src + head` is word aligned.
    unsafe { burst(d.add(head), src.add(head), words) };
    for i in head + words..len {
        // SAFETY: see above.
        unsafe { *d.add(i) = src.add(i).read_volatile() };
    }
}

/// `bytes` (a multiple of 16) from word-aligned `src` to `dst`.
///
/// # Safety
///
/// As [`burst_copy`], for `bytes` bytes.
#[cfg(target_arch = "arm")]
unsafe fn burst(dst: *mut u8, src: *const u8, bytes: usize) {
    if bytes == 0 {
        return;
    }
    let groups = bytes / 16;
    if (dst as usize).is_multiple_of(4) {
        // SAFETY: the caller's ranges; only the named registers change.
        unsafe {
            core::arch::asm!(
                "2:",
                "ldm {s}!, {{r3, r4, r5, r8}}",
                "stm {d}!, {{r3, r4, r5, r8}}",
                "subs {n}, {n}, #1",
                "bne 2b",
                s = inout(reg) src => _, d = inout(reg) dst => _, n = inout(reg) groups => _,
                out("r3") _, out("r4") _, out("r5") _, out("r8") _,
                options(nostack),
            );
        }
    } else {
        // SAFETY: as above; `str` to Normal memory may be unaligned.
        unsafe {
            core::arch::asm!(
                "2:",
                "ldm {s}!, {{r3, r4, r5, r8}}",
                "str r3, [{d}], #4",
                "str r4, [{d}], #4",
                "str r5, [{d}], #4",
                "str r8, [{d}], #4",
                "subs {n}, {n}, #1",
                "bne 2b",
                s = inout(reg) src => _, d = inout(reg) dst => _, n = inout(reg) groups => _,
                out("r3") _, out("r4") _, out("r5") _, out("r8") _,
                options(nostack),
            );
        }
    }
}

/// Host builds of the crate's type-checks (the firmware only runs on Arm).
#[cfg(not(target_arch = "arm"))]
unsafe fn burst(dst: *mut u8, src: *const u8, bytes: usize) {
    // SAFETY: forwarded to the caller.
    unsafe { core::ptr::copy_nonoverlapping(src, dst, bytes) }
}
