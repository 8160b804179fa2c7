//! An `f64` reference renderer of the same scene, for judging the fixed-point
//! model's precision. It follows the same formulas as [`crate::trace`] with
//! real arithmetic and rounds each channel once at the end.

use crate::colour::Rgb;
use crate::frame::FRAME_BYTES;
use crate::scene::*;
use crate::trace::camera_ray;
use crate::word::Q;

type V = [f64; 3];

fn v(q: crate::arith::Vec3) -> V {
    [q.x.to_f64(), q.y.to_f64(), q.z.to_f64()]
}
fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn add(a: V, b: V) -> V {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn scale(a: V, s: f64) -> V {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V, b: V) -> V {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn unit(a: V) -> (V, f64) {
    let len = dot(a, a).sqrt();
    if len == 0.0 {
        ([0.0; 3], 0.0)
    } else {
        (scale(a, 1.0 / len), len)
    }
}
fn rgb(c: Rgb) -> V {
    [c.r as f64, c.g as f64, c.b as f64]
}
fn lerp(a: V, b: V, t: f64) -> V {
    add(a, scale(sub(b, a), t))
}
fn q(x: Q) -> f64 {
    x.to_f64()
}

fn hit_sphere(origin: V, dir: V) -> Option<f64> {
    let oc = sub(v(SPHERE_CENTRE), origin);
    let b = dot(oc, dir);
    if b <= 0.0 {
        return None;
    }
    let p = cross(oc, dir);
    let d2 = dot(p, p);
    (d2 <= 1.0).then(|| b - (1.0 - d2).sqrt())
}

fn hit_plane(origin: V, dir: V) -> Option<(f64, f64)> {
    (dir[1] < 0.0).then(|| {
        let s = origin[1] / -dir[1];
        (origin[0] + s * dir[0], origin[2] + s * dir[2])
    })
}

fn checker(x: f64, z: f64) -> V {
    let odd = (x.floor() as i64 + z.floor() as i64).rem_euclid(2) == 1;
    rgb(if odd { CHECKER_ODD } else { CHECKER_EVEN })
}

fn sky(dir_y: f64) -> V {
    lerp(rgb(SKY_HORIZON), rgb(SKY_ZENITH), dir_y.clamp(0.0, 1.0))
}

fn intensity(cosine: f64) -> f64 {
    q(AMBIENT) + (1.0 - q(AMBIENT)) * cosine.clamp(0.0, 1.0)
}

/// The exact (unrounded) colour of pixel `(x, y)` for a light at `light`.
pub fn trace_pixel_f64(x: u16, y: u16, light: V) -> V {
    let eye = v(EYE);
    let d = v(camera_ray(x, y));
    let (n, _) = unit(d);
    if let Some(t) = hit_sphere(eye, n) {
        let p = add(eye, scale(n, t));
        let normal = sub(p, v(SPHERE_CENTRE));
        let (l, _) = unit(sub(light, p));
        let local = scale(rgb(SPHERE_BASE), intensity(dot(normal, l)));
        let r = sub(n, scale(normal, 2.0 * dot(n, normal)));
        let mirrored = match hit_plane(p, r) {
            Some((qx, qz)) => checker(qx, qz),
            None => sky(r[1]),
        };
        lerp(local, mirrored, q(REFLECTANCE))
    } else if let Some((px, pz)) = hit_plane(eye, d) {
        let p = [px, 0.0, pz];
        let (l, dist) = unit(sub(light, p));
        let shadowed = matches!(hit_sphere(p, l), Some(t) if t < dist);
        let lit = l[1] > 0.0 && !shadowed;
        scale(checker(px, pz), if lit { intensity(l[1]) } else { q(AMBIENT) })
    } else {
        sky(n[1])
    }
}

/// Round a real colour to RGB888 (half up, clamped).
pub fn quantize(c: V) -> [u8; 3] {
    c.map(|ch| (ch + 0.5).floor().clamp(0.0, 255.0) as u8)
}

/// Render a whole frame in the 518,400-byte wire format with `f64`
/// arithmetic, the light given in world units.
pub fn render_frame_f64(light: V) -> Vec<u8> {
    let mut out = Vec::with_capacity(FRAME_BYTES);
    for y in 0..HEIGHT as u16 {
        for x in 0..WIDTH as u16 {
            out.extend_from_slice(&quantize(trace_pixel_f64(x, y, light)));
        }
    }
    out
}
