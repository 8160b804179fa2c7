//! 8-bit colours and the integer colour arithmetic of the shading stage.

use crate::word::{FRAC_BITS, Q};

/// An RGB888 colour.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default, Hash)]
pub struct Rgb {
    /// Red.
    pub r: u8,
    /// Green.
    pub g: u8,
    /// Blue.
    pub b: u8,
}

impl Rgb {
    /// A colour from its channels.
    pub const fn new(r: u8, g: u8, b: u8) -> Rgb {
        Rgb { r, g, b }
    }

    /// The line-buffer word `0x00RRGGBB`.
    pub const fn to_word(self) -> u32 {
        (self.r as u32) << 16 | (self.g as u32) << 8 | self.b as u32
    }

    /// The colour of a line-buffer word; bits 31:24 are ignored.
    pub const fn from_word(w: u32) -> Rgb {
        Rgb::new((w >> 16) as u8, (w >> 8) as u8, w as u8)
    }

    /// Combine two colours channel by channel.
    #[inline(always)]
    fn zip_with(a: Rgb, b: Rgb, f: impl Fn(u8, u8) -> u8) -> Rgb {
        Rgb::new(f(a.r, b.r), f(a.g, b.g), f(a.b, b.b))
    }
}

/// `2^9`, the rounding bias of a product of a channel and a Q13.10 factor.
const HALF: i32 = 1 << (FRAC_BITS - 1);

fn lerp_channel(a: u8, b: u8, t: i32) -> u8 {
    // (b - a) * t is at most 255 * 1024 in magnitude; the shift floors.
    (a as i32 + (((b as i32 - a as i32) * t + HALF) >> FRAC_BITS)) as u8
}

fn scale_channel(a: u8, t: i32) -> u8 {
    ((a as i32 * t + HALF) >> FRAC_BITS) as u8
}

/// Linear blend `a + round((b - a) * t)` per channel, `t` in `[0, 1.0]`:
/// `c = a + (((b - a) * t_raw + 2^9) >> 10)`. The caller clamps `t`
/// ([`crate::arith::clamp_unit`]); then the result lies between `a` and `b`.
pub fn lerp(a: Rgb, b: Rgb, t: Q) -> Rgb {
    Rgb::zip_with(a, b, |ca, cb| lerp_channel(ca, cb, t.raw()))
}

/// Scale a colour by an intensity `i` in `[0, 1.0]`:
/// `c = (a * i_raw + 2^9) >> 10` per channel.
pub fn shade(albedo: Rgb, intensity: Q) -> Rgb {
    Rgb::zip_with(albedo, albedo, |c, _| scale_channel(c, intensity.raw()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn word_packing() {
        let c = Rgb::new(0x12, 0x34, 0x56);
        assert_eq!(c.to_word(), 0x0012_3456);
        assert_eq!(Rgb::from_word(0xff12_3456), c);
    }

    #[test]
    fn lerp_and_shade_endpoints() {
        let a = Rgb::new(10, 200, 0);
        let b = Rgb::new(250, 0, 255);
        assert_eq!(lerp(a, b, Q::ZERO), a);
        assert_eq!(lerp(a, b, Q::ONE), b);
        assert_eq!(lerp(a, b, Q::from_raw_unchecked(512)), Rgb::new(130, 100, 128));
        assert_eq!(shade(b, Q::ONE), b);
        assert_eq!(shade(b, Q::ZERO), Rgb::new(0, 0, 0));
        assert_eq!(shade(Rgb::new(255, 1, 3), Q::from_raw_unchecked(512)), Rgb::new(128, 1, 2));
    }
}
