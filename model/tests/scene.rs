//! The traced picture: layout of the frame, the wire format, and the scene's
//! content for the acceptance light (3, 4, -2).

use model::arith::Vec3;
use model::colour::shade;
use model::scene::*;
use model::trace::camera_ray;
use model::*;

fn light(x: f64, y: f64, z: f64) -> Light {
    Light::from_world(x, y, z).expect("test light in range")
}

fn frame(l: &Light) -> Vec<u8> {
    render_frame(l)
}

fn px(f: &[u8], x: usize, y: usize) -> Rgb {
    let i = (y * WIDTH + x) * 3;
    Rgb::new(f[i], f[i + 1], f[i + 2])
}

#[test]
fn camera_ray_is_exact_integer_basis() {
    // Top-left pixel: xs = -479, ys = 359.
    assert_eq!(camera_ray(0, 0), Vec3::from_raw(61 * -479, 60 * 359 - 11 * 800, 11 * 359 + 60 * 800));
    // Coordinates are 9-bit like the hardware registers.
    assert_eq!(camera_ray(512 + 7, 1024 + 9), camera_ray(7, 9));
    // Left and right halves mirror each other exactly.
    let (l, r) = (camera_ray(10, 100), camera_ray(469, 100));
    assert_eq!((l.x.raw(), l.y, l.z), (-r.x.raw(), r.y, r.z));
}

/// `render_row` (which reuses light-independent work and batches the light
/// vectors on the host) equals `trace_pixel` (computed directly) everywhere.
#[test]
fn render_row_is_trace_pixel_packed() {
    let lights = [
        light(3.0, 4.0, -2.0),
        light(-2.5, 1.5, 1.5),
        light(2.5, 0.5, 0.0),
        Light::from_raw(0, model::word::RAW_MIN, 0).unwrap(),
    ];
    for l in &lights {
        for y in 0..HEIGHT as u16 {
            let mut row = [0u32; WIDTH];
            render_row(y, l, &mut row);
            for (x, word) in row.iter().enumerate() {
                assert_eq!(*word, trace_pixel(x as u16, y, l).to_word(), "pixel ({x}, {y}) for {l:?}");
                assert_eq!(word >> 24, 0, "bits 31:24 are zero");
            }
        }
    }
}

#[test]
fn wire_frame_is_row_major_top_first_rgb() {
    let l = light(-1.0, 3.0, 2.0);
    let f = frame(&l);
    assert_eq!(f.len(), 518_400);
    for y in [0u16, 1, 200, 359] {
        let mut row = [0u32; WIDTH];
        render_row(y, &l, &mut row);
        let mut bytes = [0u8; ROW_BYTES];
        row_to_rgb888(&row, &mut bytes);
        assert_eq!(&f[y as usize * ROW_BYTES..][..ROW_BYTES], &bytes[..], "row {y}");
        let c = Rgb::from_word(row[17]);
        assert_eq!(&bytes[17 * 3..17 * 3 + 3], &[c.r, c.g, c.b], "R, G, B order");
    }
}

#[test]
fn rows_past_the_frame_extrapolate_without_panicking() {
    let l = light(3.0, 4.0, -2.0);
    let mut row = [0u32; WIDTH];
    render_row(511, &l, &mut row);
    assert_eq!(trace_pixel(u16::MAX, u16::MAX, &l), trace_pixel(511, 511, &l));
}

/// The acceptance picture: sky on top, blue sphere in the centre with the
/// checkerboard mirrored in its lower half, the checkerboard plane, and the
/// shadow on the side away from the light (the light is to the right, +x).
#[test]
fn acceptance_picture_content() {
    let f = frame(&light(3.0, 4.0, -2.0));

    // Sky: every pixel of the top rows is the pale-to-deep blue gradient.
    for y in 0..40 {
        for x in 0..WIDTH {
            let c = px(&f, x, y);
            assert!(c.b > 180 && c.b > c.r && c.b > c.g, "sky at ({x}, {y}) is {c:?}");
        }
    }
    // Sky gets deeper toward the top.
    assert!(px(&f, 240, 0).r < px(&f, 240, 100).r);

    // Sphere: blue-dominated in the centre of the upper half.
    for (x, y) in [(240, 140), (215, 150), (265, 150)] {
        let c = px(&f, x, y);
        assert!(c.b > c.r.saturating_mul(2) && c.b > c.g + 60, "sphere at ({x}, {y}) is {c:?}");
    }

    // Mirrored checkerboard: sharp green-channel edges (red squares have
    // little green, white ones much) between horizontal
    // neighbours inside the sphere's lower half, none in its upper half
    // (which mirrors the smooth sky).
    let edges = |rows: std::ops::Range<usize>| {
        rows.flat_map(|y| (205..275).map(move |x| (x, y)))
            .filter(|&(x, y)| px(&f, x, y).g.abs_diff(px(&f, x + 1, y).g) > 40)
            .count()
    };
    assert!(edges(185..225) > 40, "lower half mirrors the checkerboard: {}", edges(185..225));
    assert_eq!(edges(120..160), 0, "upper half mirrors the sky");

    // Plane: both checker colours in the bottom row, fully lit or ambient.
    let bottom: Vec<Rgb> = (0..WIDTH).map(|x| px(&f, x, HEIGHT - 1)).collect();
    assert!(bottom.iter().any(|c| c.r > 150 && c.g < 60), "red squares");
    assert!(bottom.iter().any(|c| c.r > 150 && c.g > 150 && c.b > 150), "white squares");

    // Shadow: plane pixels lit by ambient only, exactly, left of the sphere
    // and nowhere right of it.
    let ambient = [shade(CHECKER_EVEN, AMBIENT), shade(CHECKER_ODD, AMBIENT)];
    let shadowed = |xs: std::ops::Range<usize>| {
        (190..260)
            .flat_map(|y| xs.clone().map(move |x| (x, y)))
            .filter(|&(x, y)| ambient.contains(&px(&f, x, y)))
            .count()
    };
    assert!(shadowed(0..200) > 1000, "shadow left of the sphere: {}", shadowed(0..200));
    assert_eq!(shadowed(280..WIDTH), 0, "no shadow on the lit side");
}

#[test]
fn light_below_the_plane_leaves_it_ambient() {
    let f = frame(&Light::from_raw(0, model::word::RAW_MIN, 0).expect("in range"));
    let ambient = [shade(CHECKER_EVEN, AMBIENT), shade(CHECKER_ODD, AMBIENT)];
    for x in 0..WIDTH {
        assert!(ambient.contains(&px(&f, x, HEIGHT - 1)), "pixel {x} of the bottom row");
    }
}

#[test]
fn extreme_lights_render_a_sane_frame() {
    use model::word::{RAW_MAX, RAW_MIN};
    let usual = frame(&light(3.0, 4.0, -2.0));
    let sky_rows = 0..40 * ROW_BYTES;
    for x in [RAW_MIN, 0, RAW_MAX] {
        for y in [RAW_MIN, 0, RAW_MAX] {
            for z in [RAW_MIN, RAW_MAX] {
                let f = frame(&Light::from_raw(x, y, z).expect("in range"));
                // The sky never depends on the light, and the sphere stays blue.
                assert_eq!(f[sky_rows.clone()], usual[sky_rows.clone()]);
                let c = px(&f, 240, 140);
                assert!(c.b > c.r && c.b > c.g, "light ({x}, {y}, {z}): sphere {c:?}");
            }
        }
    }
}

/// A light far away acts as a directional light: moving it ten times farther
/// in the same direction barely changes the frame.
#[test]
fn far_light_matches_nearer_light_in_same_direction() {
    let near = frame(&light(600.0, 800.0, -400.0));
    let far = frame(&light(6000.0, 8000.0, -4000.0));
    let q = model::quality::compare(&near, &far);
    // What differs is the far plane near the horizon, which is as far from
    // the scene's centre as the nearer light (measured 98.999%).
    assert!(q.within_tolerance > 0.985, "{q:?}");
    assert!(q.psnr_db > 35.0, "{q:?}");
    // And both differ clearly from a light in another direction.
    let other = frame(&light(-8000.0, 2000.0, 6000.0));
    assert!(model::quality::compare(&far, &other).within_tolerance < 0.9);
}

/// The shadow ray counts the sphere only if it is nearer than the light: a
/// light between a plane point and the sphere lights that point.
#[test]
fn sphere_beyond_the_light_casts_no_shadow() {
    use model::trace::{light_vector, shade_lit, Primary};
    let l = light(2.5, 0.5, 0.0);
    let lit = |x: f64| {
        let hit = Primary::Plane { x: Q::checked_from_f64(x).unwrap(), z: Q::ZERO };
        let colour = shade_lit(&hit, &light_vector(&hit, &l));
        ![shade(CHECKER_EVEN, AMBIENT), shade(CHECKER_ODD, AMBIENT)].contains(&colour)
    };
    // Light, then sphere, behind the point at x = 4: lit.
    assert!(lit(4.0), "the sphere beyond the light must not shadow");
    // The sphere between the point at x = -2.5 and the light: shadowed.
    assert!(!lit(-2.5), "the sphere between point and light shadows");
}
