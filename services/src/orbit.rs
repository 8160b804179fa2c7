//! The light orbiting the sphere, as `rt-client orbit` moves it: a circle of
//! radius `radius` around the y axis at height `height`, starting on +x and
//! turning towards +z. Light `k` of an `n`-frame orbit is at angle `k / n`
//! turn ([`Orbit::frame_light`]); a stream's light at time `t` is at angle
//! `t / period` turn ([`Orbit::light_at`]).
//!
//! rt-client computes the same path with `std`'s `cos` and `sin`; this crate
//! has no `libm`, so [`sin_cos_turns`] evaluates them by a quarter-turn
//! reduction and Taylor series to full `f64` precision. A host test checks
//! that every light of rt-client's orbits (up to 400 frames, several radii
//! and heights) comes out identical, word for word.

use core::time::Duration;

use model::{Light, LightError};

/// Orbit radius in world units (`rt-client orbit --radius`'s default).
pub const DEFAULT_RADIUS: f64 = 3.0;

/// Light height in world units (`rt-client orbit --height`'s default).
pub const DEFAULT_HEIGHT: f64 = 4.0;

/// Time for one turn: 2 s, as the GIF `rt-client orbit` writes plays its 48
/// frames (at 24 frames per second).
pub const DEFAULT_PERIOD: Duration = Duration::from_secs(2);

/// The shortest period accepted (1 ms).
pub const MIN_PERIOD: Duration = Duration::from_millis(1);

/// The longest period accepted (one day).
pub const MAX_PERIOD: Duration = Duration::from_secs(86_400);

/// Why an orbit was rejected.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum OrbitError {
    /// Some light of the circle is outside the word range (or a value is not
    /// a finite number).
    Light(LightError),
    /// The period is outside [`MIN_PERIOD`]`..=`[`MAX_PERIOD`].
    Period,
}

impl core::fmt::Display for OrbitError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            OrbitError::Light(e) => write!(f, "orbit leaves the light range: {e}"),
            OrbitError::Period => f.write_str("orbit period outside 1 ms ..= 1 day"),
        }
    }
}

/// A validated circular light path: every light on it is in range.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct Orbit {
    radius: f64,
    height: f64,
    period: Duration,
    /// The light at angle 0 (on +x), valid by construction.
    start: Light,
}

impl Orbit {
    /// An orbit of `radius` around the y axis at `height` (world units),
    /// one turn per `period`; rejected if any light of it is out of range.
    pub fn new(radius: f64, height: f64, period: Duration) -> Result<Orbit, OrbitError> {
        if !(MIN_PERIOD..=MAX_PERIOD).contains(&period) {
            return Err(OrbitError::Period);
        }
        // |r cos| and |r sin| never exceed |r| (the series below stay within
        // [-1, 1]), so the two extreme corners bound the whole circle.
        Light::from_world(-radius, height, -radius).map_err(OrbitError::Light)?;
        let start = Light::from_world(radius, height, radius).map_err(OrbitError::Light)?;
        let start = Light::from_world(radius, height, 0.0).unwrap_or(start);
        Ok(Orbit { radius, height, period, start })
    }

    /// rt-client orbit's defaults: radius 3, height 4, [`DEFAULT_PERIOD`].
    pub fn default_orbit() -> Result<Orbit, OrbitError> {
        Orbit::new(DEFAULT_RADIUS, DEFAULT_HEIGHT, DEFAULT_PERIOD)
    }

    /// The radius, world units.
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The height, world units.
    pub fn height(&self) -> f64 {
        self.height
    }

    /// The time of one turn.
    pub fn period(&self) -> Duration {
        self.period
    }

    /// The light `turns` of a turn from +x towards +z (any finite value;
    /// whole turns are dropped).
    pub fn light_at_turns(&self, turns: f64) -> Light {
        let (sin, cos) = sin_cos_turns(turns);
        Light::from_world(self.radius * cos, self.height, self.radius * sin).unwrap_or(self.start)
    }

    /// The light `t` after the start (on +x): angle `t / period` turn.
    pub fn light_at(&self, t: Duration) -> Light {
        let period = self.period.as_nanos().max(1);
        let turns = (t.as_nanos() % period) as f64 / period as f64;
        self.light_at_turns(turns)
    }

    /// Light `k` of an orbit of `frames` evenly spaced lights, as
    /// rt-client's `OrbitPath::light` gives it (angle `k / frames` turn).
    pub fn frame_light(&self, k: usize, frames: usize) -> Light {
        self.light_at_turns(k as f64 / frames.max(1) as f64)
    }
}

/// Sine and cosine of `turns` full turns (2 pi each), to about one unit in
/// the last place: the nearest quarter turn is taken out exactly, the rest
/// (at most an eighth of a turn) goes through Taylor series to the 17th and
/// 18th power. Non-finite input gives `(0, 1)`.
pub fn sin_cos_turns(turns: f64) -> (f64, f64) {
    if !turns.is_finite() {
        return (0.0, 1.0);
    }
    // Quarter turns; beyond 2^52 quarter turns every f64 is a whole one.
    let q = turns * 4.0;
    if q.abs() >= 4_503_599_627_370_496.0 {
        return (0.0, 1.0);
    }
    // The nearest whole quarter (exact: |q| < 2^52), and the rest in [-1/2, 1/2].
    let whole = round_half_away(q);
    let rest = q - whole;
    let quadrant = (whole as i64).rem_euclid(4);
    let x = rest * core::f64::consts::FRAC_PI_2;
    let x2 = x * x;
    // Horner form of the Taylor series: the term after x^(2m+1)/(2m+1)! is
    // -x^2 / ((2m+2)(2m+3)) times it.
    let mut s = 1.0;
    let mut c = 1.0;
    for m in (1..=8).rev() {
        let m = f64::from(m);
        s = 1.0 - x2 / ((2.0 * m) * (2.0 * m + 1.0)) * s;
        c = 1.0 - x2 / ((2.0 * m - 1.0) * (2.0 * m)) * c;
    }
    let s = x * s;
    match quadrant {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// `v` rounded to the nearest integer, halves away from zero, for `|v| < 2^52`
/// (`f64::round` needs `std`).
fn round_half_away(v: f64) -> f64 {
    let t = v as i64 as f64; // truncated toward zero, exact for |v| < 2^63
    let frac = v - t;
    if frac >= 0.5 {
        t + 1.0
    } else if frac <= -0.5 {
        t - 1.0
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// rt-client's `OrbitPath::light` (client/src/orbit.rs), verbatim but
    /// for the struct: the path this module must reproduce.
    fn rt_client_light(frames: usize, radius: f64, height: f64, k: usize) -> Result<Light, LightError> {
        let angle = TAU * k as f64 / frames.max(1) as f64;
        Light::from_world(radius * angle.cos(), height, radius * angle.sin())
    }

    #[test]
    fn every_light_of_rt_client_orbits_is_the_same() {
        let mut compared = 0;
        for (radius, height) in [(3.0, 4.0), (1.5, 2.0), (7.25, -1.0), (100.0, 4.0), (4095.5, 0.0)] {
            let orbit = Orbit::new(radius, height, DEFAULT_PERIOD).unwrap();
            for frames in 1..=400 {
                for k in 0..frames {
                    let want = rt_client_light(frames, radius, height, k).unwrap();
                    assert_eq!(orbit.frame_light(k, frames), want, "r {radius} h {height}: light {k} of {frames}");
                    compared += 1;
                }
            }
        }
        assert!(compared > 400_000);
    }

    #[test]
    fn sin_cos_matches_std() {
        for k in 0..100_000u32 {
            let turns = f64::from(k) / 100_000.0 * 3.0 - 1.0;
            let (s, c) = sin_cos_turns(turns);
            let a = turns * TAU;
            // Within the rounding of `turns * TAU` itself (an ulp of 2 pi).
            assert!((s - a.sin()).abs() < 2e-15 && (c - a.cos()).abs() < 2e-15, "{turns}: {s} {c}");
            assert!(s.abs() <= 1.0 && c.abs() <= 1.0);
        }
        assert_eq!(sin_cos_turns(0.25), (1.0, -0.0));
        assert_eq!(sin_cos_turns(f64::NAN), (0.0, 1.0));
        assert_eq!(sin_cos_turns(1e300), (0.0, 1.0));
    }

    #[test]
    fn a_stream_turns_once_per_period() {
        let o = Orbit::default_orbit().unwrap();
        let raw = |ms| o.light_at(Duration::from_millis(ms)).raw();
        assert_eq!(raw(0), [3072, 4096, 0]);
        assert_eq!(raw(500), [0, 4096, 3072]);
        assert_eq!(raw(1000), [-3072, 4096, 0]);
        assert_eq!(raw(1500), [0, 4096, -3072]);
        assert_eq!(raw(2000), raw(0));
        assert_eq!(raw(2_000_000_250), raw(250), "whole turns drop out exactly");
        // 48 frames at 24 per second: rt-client's GIF, frame by frame.
        for k in 0..48 {
            let t = Duration::from_secs(k) / 24;
            assert_eq!(o.light_at(t), rt_client_light(48, 3.0, 4.0, k as usize).unwrap(), "frame {k}");
        }
    }

    #[test]
    fn orbits_leaving_the_range_are_rejected() {
        assert!(matches!(Orbit::new(9000.0, 4.0, DEFAULT_PERIOD), Err(OrbitError::Light(_))));
        assert!(matches!(Orbit::new(3.0, -9000.0, DEFAULT_PERIOD), Err(OrbitError::Light(_))));
        assert!(matches!(Orbit::new(f64::NAN, 4.0, DEFAULT_PERIOD), Err(OrbitError::Light(_))));
        assert_eq!(Orbit::new(3.0, 4.0, Duration::ZERO), Err(OrbitError::Period));
        assert_eq!(Orbit::new(3.0, 4.0, MAX_PERIOD + Duration::from_millis(1)), Err(OrbitError::Period));
        // The largest radius in range: every light of it is valid.
        let o = Orbit::new(8191.0, 0.0, DEFAULT_PERIOD).unwrap();
        for k in 0..1000 {
            let l = o.frame_light(k, 1000);
            assert_eq!(Some(l), rt_client_light(1000, 8191.0, 0.0, k).ok());
        }
    }
}
