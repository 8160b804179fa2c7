//! The per-pixel tracer: camera ray, intersections, shading and the one
//! secondary ray. This is the computation each hardware lane pipelines.
//!
//! Per pixel, in the order of the four hardware stages:
//!
//! 1. **Camera ray** ([`camera_ray`]): an exact integer direction `d`, and
//!    its normalised form `n`.
//! 2. **Intersect**: the sphere ([`hit_sphere`] with `n`), else the plane if
//!    `d.y < 0` ([`hit_plane`] with the exact `d`), else the sky. The sphere
//!    stands on the plane and the eye is above it, so a sphere hit is always
//!    the nearer one.
//! 3. **Shade**: `intensity = AMBIENT + (1 - AMBIENT) * max(0, N . L)` with
//!    `L` the normalised vector to the light; the colour is
//!    `albedo * intensity` ([`crate::colour::shade`]).
//! 4. **Secondary ray**: on the plane, a shadow ray toward the light tested
//!    against the sphere (hit nearer than the light: ambient only). On the
//!    sphere, the mirror ray `R = n - 2 (n . N) N` looks up the plane (its
//!    unlit checker colour) or the sky, blended in by `REFLECTANCE`.

use crate::arith::{
    clamp_unit, fp_add, fp_div, fp_mul, fp_neg, fp_sqrt, fp_sub, normalize, vec3_add, vec3_cross, vec3_dot, vec3_scale,
    vec3_sub, Normalized, Vec3, WideVec3,
};
use crate::colour::{lerp, shade, Rgb};
use crate::light::Light;
use crate::scene::*;
use crate::word::{FRAC_BITS, Q};

/// Mask of the 9-bit pixel coordinates the hardware registers hold.
pub const COORD_MASK: u16 = 0x1ff;

/// The un-normalised camera ray direction through pixel `(x, y)`, exact.
///
/// With `xs = 2x - 479` and `ys = 359 - 2y` (pixel centres in half pixels,
/// screen up positive) and the integer camera basis of [`crate::scene`]:
/// `d = xs * right + ys * up + FOCAL_HALF_PIXELS * forward`, taken as raw
/// Q13.10 words. Only the direction matters. `x` and `y` are used as 9-bit
/// values (masked with [`COORD_MASK`]) exactly as the hardware's registers
/// and counters hold them, so rows and columns past the frame extrapolate the
/// same camera.
#[inline(always)]
pub const fn camera_ray(x: u16, y: u16) -> Vec3 {
    let xs = 2 * (x & COORD_MASK) as i32 - (WIDTH as i32 - 1);
    let ys = (HEIGHT as i32 - 1) - 2 * (y & COORD_MASK) as i32;
    Vec3::from_raw(
        CAMERA_RIGHT_X * xs,
        CAMERA_UP.0 * ys + CAMERA_FORWARD.0 * FOCAL_HALF_PIXELS,
        CAMERA_UP.1 * ys + CAMERA_FORWARD.1 * FOCAL_HALF_PIXELS,
    )
}

/// Distance along a unit ray from `origin` to the front of the unit sphere.
///
/// `oc = SPHERE_CENTRE - origin`, `b = oc . dir`, `p = oc x dir` (the
/// perpendicular offset of the centre from the ray), `d2 = p . p`. The ray
/// hits when `b > 0` and `d2 <= 1.0`; the distance is `b - sqrt(1.0 - d2)`.
/// The cross product keeps every intermediate small for origins near the
/// sphere and saturates harmlessly (to "miss") for far ones.
#[inline(always)]
pub fn hit_sphere(origin: Vec3, dir: Vec3) -> Option<Q> {
    let oc = vec3_sub(SPHERE_CENTRE, origin);
    let b = vec3_dot(oc, dir);
    if b.raw() <= 0 {
        return None;
    }
    let perp = vec3_cross(oc, dir);
    let d2 = vec3_dot(perp, perp);
    if d2 > Q::ONE {
        return None;
    }
    Some(fp_sub(b, fp_sqrt(fp_sub(Q::ONE, d2))))
}

/// Where a ray from `origin` (above the plane) along `dir` meets y = 0, as
/// `(x, z)`; `None` when `dir.y >= 0`.
///
/// Uses only ratios of `dir`, so `dir` need not be normalised:
/// `x = origin.x + (origin.y * dir.x) / (-dir.y)`, each step by
/// [`fp_mul`], [`fp_div`] and [`fp_add`] (far hits saturate).
#[inline(always)]
pub fn hit_plane(origin: Vec3, dir: Vec3) -> Option<(Q, Q)> {
    if dir.y.raw() >= 0 {
        return None;
    }
    let down = fp_neg(dir.y);
    let x = fp_add(origin.x, fp_div(fp_mul(origin.y, dir.x), down));
    let z = fp_add(origin.z, fp_div(fp_mul(origin.y, dir.z), down));
    Some((x, z))
}

/// The checkerboard colour at `(x, z)`: bit 10 (the units bit) of each raw
/// coordinate, XORed, so `floor(x) + floor(z)` odd gives [`CHECKER_ODD`].
#[inline(always)]
pub const fn checker(x: Q, z: Q) -> Rgb {
    if ((x.raw() ^ z.raw()) >> FRAC_BITS) & 1 == 1 {
        CHECKER_ODD
    } else {
        CHECKER_EVEN
    }
}

/// The sky colour for a unit direction's y component:
/// `lerp(SKY_HORIZON, SKY_ZENITH, clamp_unit(dir_y))`.
#[inline(always)]
pub fn sky(dir_y: Q) -> Rgb {
    lerp(SKY_HORIZON, SKY_ZENITH, clamp_unit(dir_y))
}

/// `AMBIENT + (1.0 - AMBIENT) * clamp_unit(cosine)`, at most 1.0.
#[inline(always)]
pub fn intensity(cosine: Q) -> Q {
    fp_add(AMBIENT, fp_mul(fp_sub(Q::ONE, AMBIENT), clamp_unit(cosine)))
}

/// Everything about a pixel that does not depend on the light: the primary
/// hit and, on the sphere, the mirror ray's colour (the reflection is unlit).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Primary {
    /// The ray misses everything: the final colour.
    Sky(Rgb),
    /// The ray meets the plane at `(x, 0, z)`.
    Plane {
        /// World x of the hit.
        x: Q,
        /// World z of the hit.
        z: Q,
    },
    /// The ray meets the sphere.
    Sphere {
        /// The hit point `EYE + t n`.
        p: Vec3,
        /// The surface normal `p - SPHERE_CENTRE`.
        normal: Vec3,
        /// What the mirror ray sees: plane checker or sky.
        mirrored: Rgb,
    },
}

/// The light-independent work for pixel `(x, y)` (9-bit coordinates, see
/// [`camera_ray`]): stages 1 and 2, and the sphere's mirror ray.
#[inline(always)]
pub fn primary(x: u16, y: u16) -> Primary {
    let d = camera_ray(x, y);
    let n = normalize(WideVec3::from_vec3(d)).dir;
    if let Some(t) = hit_sphere(EYE, n) {
        let p = vec3_add(EYE, vec3_scale(n, t));
        let normal = vec3_sub(p, SPHERE_CENTRE);
        // Mirror ray R = n - 2 (n . N) N.
        let k = vec3_dot(n, normal);
        let r = vec3_sub(n, vec3_scale(normal, fp_add(k, k)));
        let mirrored = match hit_plane(p, r) {
            Some((qx, qz)) => checker(qx, qz),
            None => sky(r.y),
        };
        Primary::Sphere { p, normal, mirrored }
    } else if let Some((x, z)) = hit_plane(EYE, d) {
        Primary::Plane { x, z }
    } else {
        Primary::Sky(sky(n.y))
    }
}

/// The normalised vector from a hit's surface point to the light (zero for
/// the sky, which ignores it).
#[inline(always)]
pub fn light_vector(hit: &Primary, light: &Light) -> Normalized {
    let l = light.position();
    match *hit {
        Primary::Sky(_) => Normalized::default(),
        Primary::Plane { x, z } => normalize(WideVec3 { x: l.x.raw() - x.raw(), y: l.y.raw(), z: l.z.raw() - z.raw() }),
        Primary::Sphere { p, .. } => normalize(WideVec3::sub(l, p)),
    }
}

/// The colour of a hit lit through `to_light` (its [`light_vector`]).
#[inline(always)]
pub fn shade_lit(hit: &Primary, to_light: &Normalized) -> Rgb {
    match *hit {
        Primary::Sky(colour) => colour,
        Primary::Plane { x, z } => {
            let p = Vec3::new(x, Q::ZERO, z);
            let cosine = to_light.dir.y;
            let lit = cosine.raw() > 0 && !shadowed(p, to_light);
            shade(checker(x, z), if lit { intensity(cosine) } else { AMBIENT })
        }
        Primary::Sphere { normal, mirrored, .. } => {
            let local = shade(SPHERE_BASE, intensity(vec3_dot(normal, to_light.dir)));
            lerp(local, mirrored, REFLECTANCE)
        }
    }
}

/// Trace one pixel. `x` and `y` are 9-bit coordinates (see [`camera_ray`]).
#[inline]
pub fn trace_pixel(x: u16, y: u16, light: &Light) -> Rgb {
    let hit = primary(x, y);
    shade_lit(&hit, &light_vector(&hit, light))
}

/// Whether the sphere blocks the segment from `p` to the light: the shadow
/// ray hits it at a distance shorter than the light's (`to_light.len`).
#[inline(always)]
fn shadowed(p: Vec3, to_light: &Normalized) -> bool {
    match hit_sphere(p, to_light.dir) {
        Some(t) => t < to_light.len,
        None => false,
    }
}

/// Trace row `y` into `out` as line-buffer words `0x00RRGGBB`, pixel `x` at
/// index `x`: exactly what the hardware leaves in its line buffer.
///
/// With the `std` feature the light-independent [`primary`] results of the
/// frame are computed once per process and reused, and the row's light
/// vectors are normalised in one pass before shading (independent square
/// roots and divisions overlap in the CPU): the same values, several times
/// less work per pixel.
pub fn render_row(y: u16, light: &Light, out: &mut [u32; WIDTH]) {
    #[cfg(feature = "std")]
    if let Some(row) = primary_cache::row(y) {
        let mut to_light = [Normalized::default(); WIDTH];
        for (l, hit) in to_light.iter_mut().zip(row) {
            *l = light_vector(hit, light);
        }
        for ((px, hit), l) in out.iter_mut().zip(row).zip(&to_light) {
            *px = shade_lit(hit, l).to_word();
        }
        return;
    }
    for (x, px) in (0u16..).zip(out.iter_mut()) {
        *px = trace_pixel(x, y, light).to_word();
    }
}

#[cfg(feature = "std")]
mod primary_cache {
    //! The frame's [`Primary`] hits, computed once (about 5.5 MB).
    use super::{primary, Primary};
    use crate::scene::{HEIGHT, WIDTH};
    use std::sync::OnceLock;

    static HITS: OnceLock<Vec<Primary>> = OnceLock::new();

    /// The hits of row `y`, or `None` past the frame.
    pub fn row(y: u16) -> Option<&'static [Primary]> {
        let y = usize::from(y);
        if y >= HEIGHT {
            return None;
        }
        let hits = HITS
            .get_or_init(|| (0..HEIGHT as u16).flat_map(|y| (0..WIDTH as u16).map(move |x| primary(x, y))).collect());
        hits.get(y * WIDTH..(y + 1) * WIDTH)
    }
}
