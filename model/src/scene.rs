//! Every constant of the scene, defined once. The tracer, the `f64`
//! reference renderer and the RTL parameters all read them from here.
//!
//! World y is up, the plane is y = 0 with a checkerboard of unit squares, the
//! sphere has centre (0, 1, 0) and radius 1. The camera stands at (0, 2, -6)
//! on the -z side and looks toward +z, tilted down by `asin(11/61)` (about
//! 10.4 degrees) so the sphere sits near the centre with sky in the top rows.

use crate::arith::Vec3;
use crate::colour::Rgb;
use crate::word::Q;

/// Frame width in pixels.
pub const WIDTH: usize = 480;
/// Frame height in pixels.
pub const HEIGHT: usize = 360;

/// Camera position (0, 2, -6), exact in Q13.10.
pub const EYE: Vec3 = Vec3::from_raw(0, 2 << 10, -6 << 10);
/// Sphere centre (0, 1, 0); the radius is 1.0 (implicit in the tracer).
pub const SPHERE_CENTRE: Vec3 = Vec3::from_raw(0, 1 << 10, 0);

/// Camera basis as small integers, scaled by 61 so the tilt is exact: right
/// = (61, 0, 0), up = (0, 60, 11), forward = (0, -11, 60), an orthogonal
/// basis of length 61 (11^2 + 60^2 = 61^2).
pub const CAMERA_RIGHT_X: i32 = 61;
/// Up vector y and z components (see [`CAMERA_RIGHT_X`]).
pub const CAMERA_UP: (i32, i32) = (60, 11);
/// Forward vector y and z components (see [`CAMERA_RIGHT_X`]).
pub const CAMERA_FORWARD: (i32, i32) = (-11, 60);
/// Focal length in half pixels (400 pixels: a 62 degree horizontal view).
pub const FOCAL_HALF_PIXELS: i32 = 800;

/// Sky colour at the horizon (ray direction y = 0).
pub const SKY_HORIZON: Rgb = Rgb::new(200, 222, 250);
/// Sky colour at the zenith (ray direction y = 1).
pub const SKY_ZENITH: Rgb = Rgb::new(40, 90, 190);
/// Checkerboard colour where `floor(x) + floor(z)` is even.
pub const CHECKER_EVEN: Rgb = Rgb::new(230, 230, 230);
/// Checkerboard colour where `floor(x) + floor(z)` is odd.
pub const CHECKER_ODD: Rgb = Rgb::new(200, 30, 30);
/// Solid base colour of the sphere.
pub const SPHERE_BASE: Rgb = Rgb::new(30, 70, 230);

/// Ambient light: the intensity of a surface facing away from the light or
/// in shadow (0.25).
pub const AMBIENT: Q = Q::from_raw_unchecked(256);
/// Share of the mirror reflection in the sphere's colour (0.375).
pub const REFLECTANCE: Q = Q::from_raw_unchecked(384);
