//! Arithmetic primitives, defined exactly as the hardware computes them.
//!
//! Conventions shared by every primitive (the RTL in `fpga/` implements these
//! words bit for bit):
//!
//! * Operands are 24-bit two's-complement Q13.10 words ([`Q`]).
//! * Products are formed at full width (24 x 24 -> 48 bits) and sums of
//!   products are accumulated at full width before any rounding.
//! * **Rounding** of a full-width Q26.20 value back to Q13.10 is
//!   *round half up*: `(p + 2^9) >> 10` with an arithmetic (flooring) shift.
//!   -0.5 LSB rounds to 0, +0.5 LSB rounds to +1 LSB.
//! * **Saturation**: a result outside `[-2^23, 2^23 - 1]` is clamped to the
//!   nearest end. Nothing wraps.
//! * Division truncates toward zero; square roots floor. Both have a defined
//!   result for every input (division by zero, negative radicands).

use crate::word::{FRAC_BITS, Q};

/// `2^9`: half an LSB of a Q13.10 word at Q26.20 scale, the rounding bias.
const HALF_LSB_WIDE: i64 = 1 << (FRAC_BITS - 1);

/// Round a full-width Q26.20 value to a word: `(p + 2^9) >> 10`, then saturate.
#[inline(always)]
const fn round_wide(p: i64) -> Q {
    Q::saturate((p + HALF_LSB_WIDE) >> FRAC_BITS)
}

/// Saturating addition: `sat(a + b)`. Exact when the sum is in range.
#[inline(always)]
pub const fn fp_add(a: Q, b: Q) -> Q {
    Q::saturate(a.raw() as i64 + b.raw() as i64)
}

/// Saturating subtraction: `sat(a - b)`. Exact when the difference is in range.
#[inline(always)]
pub const fn fp_sub(a: Q, b: Q) -> Q {
    Q::saturate(a.raw() as i64 - b.raw() as i64)
}

/// Saturating negation: `sat(-a)`; `-MIN` gives `MAX`.
#[inline(always)]
pub const fn fp_neg(a: Q) -> Q {
    Q::saturate(-(a.raw() as i64))
}

/// Multiplication: `sat((a_raw * b_raw + 2^9) >> 10)`.
///
/// The 48-bit product is exact; it is rounded half up (arithmetic shift, so
/// toward +infinity on ties for either sign) and saturated. Examples:
/// `1.0 * x = x` exactly; `MAX * MAX = MAX`; `MIN * MIN = MAX`;
/// `MIN * -1.0 = MAX`; raw `1 * 512 = 1` (0.5 LSB rounds up);
/// raw `-1 * 512 = 0` (-0.5 LSB rounds up to 0).
#[inline(always)]
pub const fn fp_mul(a: Q, b: Q) -> Q {
    round_wide(a.raw() as i64 * b.raw() as i64)
}

/// Division: `sat(trunc((a_raw * 2^10) / b_raw))`, truncating toward zero.
///
/// The hardware divides magnitudes (`|a| << 10` by `|b|`, a 34-bit by 24-bit
/// unsigned restoring division whose integer quotient is the floor) and
/// negates the quotient when the signs differ, so the result truncates toward
/// zero. A quotient beyond the word range saturates (`MIN / -1.0 = MAX`).
///
/// Division by zero: `MAX` when `a >= 0`, `MIN` when `a < 0` (the limit of a
/// tiny positive divisor), so `0 / 0 = MAX`.
#[inline(always)]
pub fn fp_div(a: Q, b: Q) -> Q {
    if b.raw() == 0 {
        return if a.raw() >= 0 { Q::MAX } else { Q::MIN };
    }
    Q::saturate(div_trunc((a.raw() as i64) << FRAC_BITS, b.raw() as i64))
}

/// `n / d` truncated toward zero, for `|n| <= 2^33` and `0 < |d| < 2^24`, exact
/// wherever the caller's saturation at `2^23` does not hide the difference.
#[inline(always)]
fn div_trunc(n: i64, d: i64) -> i64 {
    #[cfg(feature = "std")]
    {
        // Faster than a 64-bit integer divide on x86, and exact: both operands
        // are exact doubles, a non-integer quotient lies at least 1/|d| >=
        // 2^-24 from an integer, more than an ulp of any quotient below 2^24,
        // so truncating the correctly rounded quotient gives the integer one
        // (larger quotients saturate either way). Property-tested both ways.
        (n as f64 / d as f64) as i64
    }
    #[cfg(not(feature = "std"))]
    {
        n / d
    }
}

/// Square root: `floor(sqrt(a_raw * 2^10))` for `a >= 0`, and `0` for `a < 0`.
///
/// The radicand `a_raw << 10` is a 33-bit unsigned integer; the hardware's
/// (restoring, one result bit per step) integer square root gives its floor,
/// a 17-bit result that always fits a word. `sqrt(MAX)` is raw 92681
/// (90.509...). Negative inputs give zero, never a fault.
#[inline(always)]
pub fn fp_sqrt(a: Q) -> Q {
    if a.raw() <= 0 {
        return Q::ZERO;
    }
    Q::saturate(isqrt((a.raw() as u64) << FRAC_BITS) as i64)
}

/// Integer square root: the largest `r` with `r * r <= n`.
///
/// This is the function the hardware's restoring square root computes (one
/// result bit per step).
#[inline(always)]
pub fn isqrt(n: u64) -> u64 {
    #[cfg(feature = "std")]
    {
        // `u64::isqrt` is exact but slow in software; the hardware square root
        // of the FPU plus a one-step integer correction is exact too, because
        // every radicand here is below 2^53 and so the estimate is off by at
        // most one.
        let mut r = (n as f64).sqrt() as u64;
        if r * r > n {
            r -= 1;
        } else if (r + 1) * (r + 1) <= n {
            r += 1;
        }
        r
    }
    #[cfg(not(feature = "std"))]
    {
        n.isqrt()
    }
}

/// A vector of three words (a point, a direction, a normal).
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default, Hash)]
pub struct Vec3 {
    /// World x (screen right).
    pub x: Q,
    /// World y (up).
    pub y: Q,
    /// World z (away from the camera).
    pub z: Q,
}

impl Vec3 {
    /// A vector from three words.
    pub const fn new(x: Q, y: Q, z: Q) -> Vec3 {
        Vec3 { x, y, z }
    }

    /// A vector from three raw words (saturated into range).
    pub const fn from_raw(x: i32, y: i32, z: i32) -> Vec3 {
        Vec3::new(Q::from_raw_unchecked(x), Q::from_raw_unchecked(y), Q::from_raw_unchecked(z))
    }
}

/// Component-wise [`fp_add`].
#[inline(always)]
pub const fn vec3_add(a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(fp_add(a.x, b.x), fp_add(a.y, b.y), fp_add(a.z, b.z))
}

/// Component-wise [`fp_sub`].
#[inline(always)]
pub const fn vec3_sub(a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(fp_sub(a.x, b.x), fp_sub(a.y, b.y), fp_sub(a.z, b.z))
}

/// Each component times one word, each by [`fp_mul`].
#[inline(always)]
pub const fn vec3_scale(v: Vec3, s: Q) -> Vec3 {
    Vec3::new(fp_mul(v.x, s), fp_mul(v.y, s), fp_mul(v.z, s))
}

/// Dot product with a single rounding:
/// `sat((ax*bx + ay*by + az*bz + 2^9) >> 10)`.
///
/// The three 48-bit products are summed exactly (50 bits) and rounded half up
/// once, then saturated. This is *not* the sum of three [`fp_mul`]s.
#[inline(always)]
pub const fn vec3_dot(a: Vec3, b: Vec3) -> Q {
    round_wide(
        a.x.raw() as i64 * b.x.raw() as i64 + a.y.raw() as i64 * b.y.raw() as i64 + a.z.raw() as i64 * b.z.raw() as i64,
    )
}

/// Cross product, each component a difference of two exact products rounded
/// once: `c.x = sat((ay*bz - az*by + 2^9) >> 10)`, and cyclically for y, z.
#[inline(always)]
pub const fn vec3_cross(a: Vec3, b: Vec3) -> Vec3 {
    let (ax, ay, az) = (a.x.raw() as i64, a.y.raw() as i64, a.z.raw() as i64);
    let (bx, by, bz) = (b.x.raw() as i64, b.y.raw() as i64, b.z.raw() as i64);
    Vec3::new(round_wide(ay * bz - az * by), round_wide(az * bx - ax * bz), round_wide(ax * by - ay * bx))
}

/// A vector of raw Q13.10 values too wide for a word: the exact difference of
/// two word vectors needs 25 bits. [`normalize`] accepts any `i32` components.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default, Hash)]
pub struct WideVec3 {
    /// Raw x (value `x / 1024`).
    pub x: i32,
    /// Raw y.
    pub y: i32,
    /// Raw z.
    pub z: i32,
}

impl WideVec3 {
    /// The exact difference `a - b` (25 bits per component, no saturation).
    #[inline(always)]
    pub const fn sub(a: Vec3, b: Vec3) -> WideVec3 {
        WideVec3 { x: a.x.raw() - b.x.raw(), y: a.y.raw() - b.y.raw(), z: a.z.raw() - b.z.raw() }
    }

    /// A word vector, widened (exact).
    #[inline(always)]
    pub const fn from_vec3(v: Vec3) -> WideVec3 {
        WideVec3 { x: v.x.raw(), y: v.y.raw(), z: v.z.raw() }
    }
}

/// The result of [`normalize`]: a unit direction and the input's length.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct Normalized {
    /// The unit vector, components in Q13.10 (about +-1.0).
    pub dir: Vec3,
    /// The input's Euclidean length in Q13.10, saturated at `MAX`.
    pub len: Q,
}

/// Magnitude that [`normalize`] scales the largest component into:
/// `[2^13, 2^14]` raw after range reduction.
pub const NORMALIZE_TOP_BIT: u32 = 13;
/// Numerator exponent of the reciprocal in [`normalize`]: `recip = 2^33 / len_w`.
pub const NORMALIZE_RECIP_NUM_BITS: u32 = 33;
/// Shift that brings `w * recip` back to Q13.10: `33 - 10`.
pub const NORMALIZE_RECIP_SHIFT: u32 = NORMALIZE_RECIP_NUM_BITS - FRAC_BITS;

/// Normalise a vector by power-of-two range reduction, one integer square
/// root, one reciprocal and three multiplies. Defined for every `i32`
/// component, so a far light (components near 8192) or the 25-bit difference
/// of two words never overflows.
///
/// Exact definition (all integers, `>>` is an arithmetic, flooring shift):
///
/// 1. `m = max(|v.x|, |v.y|, |v.z|)`. If `m == 0`, the result is the zero
///    vector with length 0.
/// 2. `k` = bit length of `m` (`m < 2^k`, `m >= 2^(k-1)`); `s = k - 14`.
///    Range reduction: `w = v >> s` if `s >= 0`, else `w = v << -s`. Now the
///    largest `|w|` lies in `[2^13, 2^14]`.
/// 3. `q = w.x^2 + w.y^2 + w.z^2` (exact, `< 2^30`);
///    `len_w = isqrt(q)` (floor; in `[2^13, 28378]`).
/// 4. `recip = floor(2^33 / len_w)` (unsigned; in `[302_705, 2^20]`).
/// 5. `dir.c = (w.c * recip + 2^22) >> 23` for each component `c`
///    (round half up), so `|dir| ~ 1.0` with raw components near 1024.
/// 6. `len = sat(len_w << s)` if `s >= 0`, else `len_w >> -s` (floor): the
///    length of `v` in Q13.10.
///
/// `dir` may exceed 1.0 by an LSB because `len_w` is a floor; users clamp
/// where that matters.
#[inline(always)]
pub fn normalize(v: WideVec3) -> Normalized {
    let (ax, ay, az) = (v.x.unsigned_abs(), v.y.unsigned_abs(), v.z.unsigned_abs());
    let m = max3(ax, ay, az);
    if m == 0 {
        return Normalized { dir: Vec3::from_raw(0, 0, 0), len: Q::ZERO };
    }
    let bit_len = 32 - m.leading_zeros() as i32;
    let s = bit_len - (NORMALIZE_TOP_BIT as i32 + 1);
    let (wx, wy, wz) = if s >= 0 {
        ((v.x >> s) as i64, (v.y >> s) as i64, (v.z >> s) as i64)
    } else {
        let l = -s;
        ((v.x << l) as i64, (v.y << l) as i64, (v.z << l) as i64)
    };
    let q = (wx * wx + wy * wy + wz * wz) as u64;
    let len_w = isqrt(q);
    // len_w >= 2^13, so the quotient is below 2^21: `div_trunc` is exact.
    let recip = div_trunc(1i64 << NORMALIZE_RECIP_NUM_BITS, len_w as i64);
    let round = 1i64 << (NORMALIZE_RECIP_SHIFT - 1);
    let dir = Vec3::new(
        Q::saturate((wx * recip + round) >> NORMALIZE_RECIP_SHIFT),
        Q::saturate((wy * recip + round) >> NORMALIZE_RECIP_SHIFT),
        Q::saturate((wz * recip + round) >> NORMALIZE_RECIP_SHIFT),
    );
    let len = if s >= 0 { Q::saturate((len_w as i64) << s) } else { Q::saturate((len_w >> -s) as i64) };
    Normalized { dir, len }
}

#[inline(always)]
const fn max3(a: u32, b: u32, c: u32) -> u32 {
    let ab = if a > b { a } else { b };
    if ab > c {
        ab
    } else {
        c
    }
}

/// Clamp a word to `[0, 1.0]` (raw `[0, 1024]`): used for cosines and blend
/// factors before they scale 8-bit colours.
#[inline(always)]
pub const fn clamp_unit(a: Q) -> Q {
    if a.raw() < 0 {
        Q::ZERO
    } else if a.raw() > Q::ONE.raw() {
        Q::ONE
    } else {
        a
    }
}
