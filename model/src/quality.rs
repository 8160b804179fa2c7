//! How close the fixed-point model comes to the `f64` reference.

use crate::light::Light;
use crate::reference::render_frame_f64;

/// Largest per-channel difference that still counts as "close".
pub const CLOSE_TOLERANCE: u8 = 8;

/// Agreement between two RGB888 images of the same size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quality {
    /// Peak signal-to-noise ratio over all channels, in dB (infinite when equal).
    pub psnr_db: f64,
    /// Share of pixels whose three channels all differ by at most
    /// [`CLOSE_TOLERANCE`], in `[0, 1]`.
    pub within_tolerance: f64,
    /// Largest channel difference seen.
    pub max_diff: u8,
}

/// Compare two RGB888 images byte for byte (`a` and `b` the same length, a
/// multiple of 3).
pub fn compare(a: &[u8], b: &[u8]) -> Quality {
    assert_eq!(a.len(), b.len(), "images differ in size");
    let mut sq = 0u64;
    let mut close = 0usize;
    let mut max_diff = 0u8;
    for (pa, pb) in a.chunks_exact(3).zip(b.chunks_exact(3)) {
        let mut pixel_max = 0u8;
        for (ca, cb) in pa.iter().zip(pb) {
            let d = ca.abs_diff(*cb);
            sq += u64::from(d) * u64::from(d);
            pixel_max = pixel_max.max(d);
        }
        close += usize::from(pixel_max <= CLOSE_TOLERANCE);
        max_diff = max_diff.max(pixel_max);
    }
    let mse = sq as f64 / a.len() as f64;
    let psnr_db = if mse == 0.0 { f64::INFINITY } else { 10.0 * (255.0 * 255.0 / mse).log10() };
    Quality { psnr_db, within_tolerance: close as f64 / (a.len() / 3) as f64, max_diff }
}

/// The light positions of the quality report (world units): around the orbit
/// above the sphere's top (y = 2), below it, near the plane, and far away.
pub const REPORT_LIGHTS: [(&str, [f64; 3]); 10] = [
    ("front-right high", [3.0, 4.0, -2.0]),
    ("orbit 0 deg", [3.0, 3.0, 0.0]),
    ("orbit 90 deg", [0.0, 3.0, 3.0]),
    ("orbit 180 deg", [-3.0, 3.0, 0.0]),
    ("orbit 270 deg", [0.0, 3.0, -3.0]),
    ("low left-back, below the top", [-2.5, 1.5, 1.5]),
    ("low right-front, below the top", [2.0, 1.0, -2.5]),
    ("grazing, near the plane", [4.0, 0.25, 1.0]),
    ("far, same direction as (3,4,-2)", [1500.0, 2000.0, -1000.0]),
    ("far overhead", [-100.0, 8000.0, 300.0]),
];

/// Render `light` with the model and the reference and compare them.
pub fn measure(light: [f64; 3]) -> Result<Quality, crate::light::LightError> {
    let l = Light::from_world(light[0], light[1], light[2])?;
    let fixed = crate::frame::render_frame(&l);
    // The reference sees the light exactly where the model does (rounded to Q13.10).
    let p = l.position();
    let reference = render_frame_f64([p.x.to_f64(), p.y.to_f64(), p.z.to_f64()]);
    Ok(compare(&fixed, &reference))
}
