//! The Q13.10 word: the one number format of the hardware.
//!
//! A word is a signed 24-bit two's-complement integer `raw` standing for
//! `raw / 1024`. Its range is `[-8192, 8192 - 2^-10]`, raw `[-2^23, 2^23 - 1]`.
//! The value is stored in the `fixed` crate's `I22F10` (an `i32` with ten
//! fractional bits); the invariant of [`Q`] is that the bits always fit in 24.

use core::fmt;
use fixed::types::I22F10;

/// Number of fractional bits of a word.
pub const FRAC_BITS: u32 = 10;
/// Width of a word in bits.
pub const WORD_BITS: u32 = 24;
/// Smallest raw value of a word, `-2^23` (value -8192).
pub const RAW_MIN: i32 = -(1 << (WORD_BITS - 1));
/// Largest raw value of a word, `2^23 - 1` (value 8191.999).
pub const RAW_MAX: i32 = (1 << (WORD_BITS - 1)) - 1;

/// A signed Q13.10 fixed-point word (24 bits, 10 of them fractional).
///
/// Every constructor keeps the bits inside 24; arithmetic on words lives in
/// [`crate::arith`] and saturates there.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[repr(transparent)]
pub struct Q(I22F10);

/// A raw value that does not fit in a 24-bit word.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OutOfRange {
    /// The rejected raw value.
    pub raw: i64,
}

impl fmt::Display for OutOfRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "raw value {} is outside the Q13.10 word range [{}, {}]", self.raw, RAW_MIN, RAW_MAX)
    }
}

impl core::error::Error for OutOfRange {}

impl Q {
    /// 0.0
    pub const ZERO: Q = Q::from_raw_unchecked(0);
    /// 1.0 (raw 1024)
    pub const ONE: Q = Q::from_raw_unchecked(1 << FRAC_BITS);
    /// The most negative word, -8192.0 (raw -2^23).
    pub const MIN: Q = Q::from_raw_unchecked(RAW_MIN);
    /// The most positive word, 8191.999 (raw 2^23 - 1).
    pub const MAX: Q = Q::from_raw_unchecked(RAW_MAX);

    /// Word from raw bits known to be in range (constants only).
    ///
    /// In range is checked at compile time for constants; at run time an out of
    /// range value is saturated rather than trusted.
    pub const fn from_raw_unchecked(raw: i32) -> Q {
        Q::saturate(raw as i64)
    }

    /// Word from raw bits, rejecting anything outside `[-2^23, 2^23)`.
    pub const fn from_raw(raw: i64) -> Result<Q, OutOfRange> {
        if raw < RAW_MIN as i64 || raw > RAW_MAX as i64 {
            Err(OutOfRange { raw })
        } else {
            Ok(Q(I22F10::from_bits(raw as i32)))
        }
    }

    /// Word from a wide integer, clamped to `[RAW_MIN, RAW_MAX]`: the
    /// saturation every primitive applies to its result.
    #[inline(always)]
    pub const fn saturate(raw: i64) -> Q {
        let clamped = if raw < RAW_MIN as i64 {
            RAW_MIN
        } else if raw > RAW_MAX as i64 {
            RAW_MAX
        } else {
            raw as i32
        };
        Q(I22F10::from_bits(clamped))
    }

    /// Word from an integer number of units (`n * 1024` raw), saturated.
    pub const fn from_int(n: i32) -> Q {
        Q::saturate((n as i64) << FRAC_BITS)
    }

    /// The raw 24-bit value, sign-extended into an `i32`.
    #[inline(always)]
    pub const fn raw(self) -> i32 {
        self.0.to_bits()
    }

    /// The word as the `fixed` crate's `I22F10`.
    pub const fn to_fixed(self) -> I22F10 {
        self.0
    }

    /// The nearest word to `value` (ties away from zero), or an error if it
    /// falls outside the word range. NaN is out of range.
    pub fn checked_from_f64(value: f64) -> Result<Q, OutOfRange> {
        match I22F10::checked_from_num(value) {
            Some(v) => Q::from_raw(v.to_bits() as i64),
            // Beyond i32 raw: report a representative raw value.
            None => Err(OutOfRange { raw: if value < 0.0 { i64::MIN } else { i64::MAX } }),
        }
    }

    /// The exact value as an `f64`.
    pub fn to_f64(self) -> f64 {
        self.0.to_num::<f64>()
    }
}

impl fmt::Debug for Q {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Q({} = raw {})", self.0, self.raw())
    }
}

impl fmt::Display for Q {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.0, f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_limits() {
        assert_eq!(Q::MIN.raw(), -8_388_608);
        assert_eq!(Q::MAX.raw(), 8_388_607);
        assert!(Q::from_raw(RAW_MAX as i64 + 1).is_err());
        assert!(Q::from_raw(RAW_MIN as i64 - 1).is_err());
        assert_eq!(Q::from_raw(-1).map(Q::raw), Ok(-1));
        assert_eq!(Q::saturate(1 << 40), Q::MAX);
        assert_eq!(Q::saturate(-(1 << 40)), Q::MIN);
    }

    #[test]
    fn f64_conversion_rounds_and_rejects() {
        assert_eq!(Q::checked_from_f64(1.5).map(Q::raw), Ok(1536));
        assert_eq!(Q::checked_from_f64(-2.0).map(Q::raw), Ok(-2048));
        assert!(Q::checked_from_f64(8192.0).is_err());
        assert_eq!(Q::checked_from_f64(-8192.0), Ok(Q::MIN));
        assert!(Q::checked_from_f64(f64::NAN).is_err());
        assert!(Q::checked_from_f64(1e30).is_err());
        assert_eq!(Q::from_int(3).to_f64(), 3.0);
    }
}
