//! `__aeabi_memcpy` and its aligned variants, with 32-byte `ldm`/`stm`
//! bursts.
//!
//! LLVM lowers every copy on this target to these AEABI routines (ARM
//! RTABI, IHI 0043, 4.3.4). The ones compiler-builtins provides copy a word
//! per load and store (`ldr`/`str` and a compare-and-branch: one
//! instruction per byte), and smoltcp copies every TCP payload byte through
//! them: about half a million instructions per frame. Here a copy between
//! buffers of the same word alignment moves eight words per `ldm`/`stm`
//! pair (about 0.1 instructions per byte); a copy between differently
//! aligned buffers goes a byte at a time (rare: the frame path keeps both
//! ends aligned, see dwmac's `TX_SKEW`). Hand-written in assembly so the
//! compiler cannot turn the loops back into calls to themselves.
//!
//! The link resolves the symbols to these definitions (`llvm-nm` on the
//! image shows them in the firmware's `.text`, compiler-builtins' copies
//! gone); the firmware's QEMU tests compare every streamed byte with the
//! model, which exercises them on every frame.

#[cfg(target_arch = "arm")]
core::arch::global_asm!(
    ".section .text.__aeabi_memcpy,\"ax\",%progbits",
    ".global __aeabi_memcpy",
    ".type __aeabi_memcpy,%function",
    ".arm",
    "__aeabi_memcpy:",
    // r0 = dst, r1 = src, r2 = n
    "    eor     r3, r0, r1",
    "    tst     r3, #3",
    "    bne     3f",
    // Same alignment: bytes up to a word boundary, then the word routine.
    "1:  tst     r0, #3",
    "    beq     __aeabi_memcpy4",
    "    cmp     r2, #0",
    "    bxeq    lr",
    "    ldrb    r3, [r1], #1",
    "    sub     r2, r2, #1",
    "    strb    r3, [r0], #1",
    "    b       1b",
    // Different alignments: bytes.
    "3:  cmp     r2, #0",
    "    bxeq    lr",
    "4:  ldrb    r3, [r1], #1",
    "    subs    r2, r2, #1",
    "    strb    r3, [r0], #1",
    "    bne     4b",
    "    bx      lr",
    ".size __aeabi_memcpy, . - __aeabi_memcpy",
    "",
    ".section .text.__aeabi_memcpy4,\"ax\",%progbits",
    ".global __aeabi_memcpy4",
    ".global __aeabi_memcpy8",
    ".type __aeabi_memcpy4,%function",
    ".type __aeabi_memcpy8,%function",
    ".arm",
    // Both pointers word aligned.
    "__aeabi_memcpy4:",
    "__aeabi_memcpy8:",
    "    subs    r2, r2, #32",
    "    blo     2f",
    "    push    {{r4-r11}}",
    "1:  ldm     r1!, {{r3-r10}}",
    "    subs    r2, r2, #32",
    "    stm     r0!, {{r3-r10}}",
    "    bhs     1b",
    "    pop     {{r4-r11}}",
    // 0..31 bytes left (r2 + 32): words, then bytes.
    "2:  add     r2, r2, #32",
    "3:  subs    r2, r2, #4",
    "    ldrhs   r3, [r1], #4",
    "    strhs   r3, [r0], #4",
    "    bhs     3b",
    "    adds    r2, r2, #4",
    "    bxeq    lr",
    "4:  ldrb    r3, [r1], #1",
    "    subs    r2, r2, #1",
    "    strb    r3, [r0], #1",
    "    bne     4b",
    "    bx      lr",
    ".size __aeabi_memcpy4, . - __aeabi_memcpy4",
);
