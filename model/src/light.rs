//! The validated light position.

use core::fmt;

use crate::arith::Vec3;
use crate::word::{OutOfRange, Q};

/// A point light position in world units, every component a valid Q13.10 word.
///
/// Any position in the word range is accepted, up to +-8191 units: the tracer
/// range-reduces light vectors ([`crate::arith::normalize`]), so a far light
/// acts like a directional light instead of overflowing.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Hash)]
pub struct Light {
    pos: Vec3,
}

/// Which component of a light was rejected.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Axis {
    /// x component.
    X,
    /// y component.
    Y,
    /// z component.
    Z,
}

/// A light component outside `[-2^23, 2^23)` raw (or not a finite number).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct LightError {
    /// The offending component.
    pub axis: Axis,
    /// Why it was rejected.
    pub source: OutOfRange,
}

impl fmt::Display for LightError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "light {:?}: {}", self.axis, self.source)
    }
}

impl core::error::Error for LightError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        Some(&self.source)
    }
}

/// Why a text `"X,Y,Z"` is not a light.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum ParseLightError {
    /// Not exactly three comma-separated components.
    ComponentCount,
    /// A component is not a number.
    NotANumber,
    /// The position is outside the word range.
    Range(LightError),
}

impl fmt::Display for ParseLightError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParseLightError::ComponentCount => f.write_str("expected three numbers X,Y,Z"),
            ParseLightError::NotANumber => f.write_str("a component of X,Y,Z is not a number"),
            ParseLightError::Range(e) => fmt::Display::fmt(e, f),
        }
    }
}

impl core::error::Error for ParseLightError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            ParseLightError::Range(e) => Some(e),
            _ => None,
        }
    }
}

impl core::str::FromStr for Light {
    type Err = ParseLightError;

    /// A light from `"X,Y,Z"` in world units (`"3,4,-2"`), as
    /// [`Light::from_world`].
    fn from_str(s: &str) -> Result<Light, ParseLightError> {
        let mut xyz = [0f64; 3];
        let mut parts = s.split(',');
        for c in &mut xyz {
            let part = parts.next().ok_or(ParseLightError::ComponentCount)?;
            *c = part.trim().parse().map_err(|_| ParseLightError::NotANumber)?;
        }
        if parts.next().is_some() {
            return Err(ParseLightError::ComponentCount);
        }
        Light::from_world(xyz[0], xyz[1], xyz[2]).map_err(ParseLightError::Range)
    }
}

fn component(axis: Axis, r: Result<Q, OutOfRange>) -> Result<Q, LightError> {
    r.map_err(|source| LightError { axis, source })
}

impl Light {
    /// A light from raw Q13.10 components; values outside `[-2^23, 2^23)`
    /// are rejected, never wrapped.
    pub fn from_raw(x: i32, y: i32, z: i32) -> Result<Light, LightError> {
        Ok(Light {
            pos: Vec3::new(
                component(Axis::X, Q::from_raw(x as i64))?,
                component(Axis::Y, Q::from_raw(y as i64))?,
                component(Axis::Z, Q::from_raw(z as i64))?,
            ),
        })
    }

    /// A light from world units, rounded to the nearest Q13.10 word.
    pub fn from_world(x: f64, y: f64, z: f64) -> Result<Light, LightError> {
        Ok(Light {
            pos: Vec3::new(
                component(Axis::X, Q::checked_from_f64(x))?,
                component(Axis::Y, Q::checked_from_f64(y))?,
                component(Axis::Z, Q::checked_from_f64(z))?,
            ),
        })
    }

    /// The position as words.
    pub const fn position(&self) -> Vec3 {
        self.pos
    }

    /// The raw components `(x, y, z)`, each in `[-2^23, 2^23)`.
    pub const fn raw(&self) -> [i32; 3] {
        [self.pos.x.raw(), self.pos.y.raw(), self.pos.z.raw()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_is_checked_not_wrapped() {
        assert!(Light::from_raw(-(1 << 23), (1 << 23) - 1, 0).is_ok());
        let e = Light::from_raw(0, 1 << 23, 0).unwrap_err();
        assert_eq!(e.axis, Axis::Y);
        assert_eq!(Light::from_raw(0, 0, -(1 << 23) - 1).unwrap_err().axis, Axis::Z);
        assert_eq!(Light::from_raw(i32::MIN, 0, 0).unwrap_err().axis, Axis::X);
        assert!(Light::from_world(8192.0, 0.0, 0.0).is_err());
        assert!(Light::from_world(0.0, f64::INFINITY, 0.0).is_err());
    }

    #[test]
    fn parses_world_units() {
        assert_eq!("3, 4,-2".parse::<Light>().map(|l| l.raw()), Ok([3072, 4096, -2048]));
        assert_eq!("1,2".parse::<Light>(), Err(ParseLightError::ComponentCount));
        assert_eq!("1,2,3,4".parse::<Light>(), Err(ParseLightError::ComponentCount));
        assert_eq!("1,x,3".parse::<Light>(), Err(ParseLightError::NotANumber));
        assert!(matches!("9000,0,0".parse::<Light>(), Err(ParseLightError::Range(_))));
    }
}
