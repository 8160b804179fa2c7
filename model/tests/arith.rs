//! The arithmetic primitives against plain-integer reference definitions
//! (i128, no shifts where a division says it more plainly), plus edge cases.

use model::arith::*;
use model::word::{Q, RAW_MAX, RAW_MIN};
use proptest::prelude::*;

fn sat(v: i128) -> i32 {
    v.clamp(RAW_MIN as i128, RAW_MAX as i128) as i32
}

/// Round half up of `v / 1024`: floor((v + 512) / 1024).
fn round_q(v: i128) -> i128 {
    (v + 512).div_euclid(1024)
}

fn ref_mul(a: i32, b: i32) -> i32 {
    sat(round_q(a as i128 * b as i128))
}

fn ref_div(a: i32, b: i32) -> i32 {
    if b == 0 {
        return if a >= 0 { RAW_MAX } else { RAW_MIN };
    }
    // Rust's `/` on integers truncates toward zero.
    sat(a as i128 * 1024 / b as i128)
}

/// Largest r with r * r <= n, by bisection.
fn ref_isqrt(n: u128) -> u128 {
    let (mut lo, mut hi) = (0u128, 1u128 << 64);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if mid * mid <= n {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

fn ref_sqrt(a: i32) -> i32 {
    if a <= 0 {
        0
    } else {
        sat(ref_isqrt(a as u128 * 1024) as i128)
    }
}

fn q(raw: i32) -> Q {
    Q::from_raw(raw as i64).expect("test word in range")
}

fn v(x: i32, y: i32, z: i32) -> Vec3 {
    Vec3::new(q(x), q(y), q(z))
}

fn word() -> impl Strategy<Value = i32> {
    prop_oneof![
        RAW_MIN..=RAW_MAX,
        -4096..=4096i32,
        Just(RAW_MIN),
        Just(RAW_MAX),
        Just(0),
        Just(-1),
        Just(1),
        Just(1024),
        Just(-1024),
        // Half-LSB products (odd x 512) exercise the rounding ties.
        Just(512),
        Just(-512),
        (-4096..4096i32).prop_map(|v| v | 1),
    ]
}

/// The plain definition of `normalize`, step by step from its rustdoc.
fn ref_normalize(c: [i32; 3]) -> ([i32; 3], i32) {
    let m = c.iter().map(|x| (*x as i128).abs()).max().unwrap_or(0);
    if m == 0 {
        return ([0; 3], 0);
    }
    let mut bit_len = 0;
    while (1i128 << bit_len) <= m {
        bit_len += 1;
    }
    let s = bit_len - 14;
    let w: Vec<i128> =
        c.iter().map(|&x| if s >= 0 { (x as i128).div_euclid(1 << s) } else { x as i128 * (1 << -s) }).collect();
    let len_w = ref_isqrt(w.iter().map(|x| (x * x) as u128).sum());
    let recip = (1u128 << 33) / len_w;
    let dir = [0, 1, 2].map(|i| sat((w[i] * recip as i128 + (1 << 22)).div_euclid(1 << 23)));
    let len = if s >= 0 { sat((len_w as i128) << s) } else { sat((len_w >> -s) as i128) };
    (dir, len)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4096))]

    #[test]
    fn add_sub_neg_match(a in word(), b in word()) {
        prop_assert_eq!(fp_add(q(a), q(b)).raw(), sat(a as i128 + b as i128));
        prop_assert_eq!(fp_sub(q(a), q(b)).raw(), sat(a as i128 - b as i128));
        prop_assert_eq!(fp_neg(q(a)).raw(), sat(-(a as i128)));
    }

    #[test]
    fn mul_matches(a in word(), b in word()) {
        prop_assert_eq!(fp_mul(q(a), q(b)).raw(), ref_mul(a, b));
    }

    #[test]
    fn div_matches(a in word(), b in word()) {
        prop_assert_eq!(fp_div(q(a), q(b)).raw(), ref_div(a, b));
    }

    #[test]
    fn sqrt_matches(a in word()) {
        prop_assert_eq!(fp_sqrt(q(a)).raw(), ref_sqrt(a));
    }

    #[test]
    fn isqrt_matches(n in 0u64..(1u64 << 53)) {
        prop_assert_eq!(isqrt(n) as u128, ref_isqrt(n as u128));
    }

    #[test]
    fn dot_and_cross_match(a in prop::array::uniform3(word()), b in prop::array::uniform3(word())) {
        let (va, vb) = (v(a[0], a[1], a[2]), v(b[0], b[1], b[2]));
        let p = |i: usize, j: usize| a[i] as i128 * b[j] as i128;
        prop_assert_eq!(vec3_dot(va, vb).raw(), sat(round_q(p(0, 0) + p(1, 1) + p(2, 2))));
        let c = vec3_cross(va, vb);
        prop_assert_eq!(c.x.raw(), sat(round_q(p(1, 2) - p(2, 1))));
        prop_assert_eq!(c.y.raw(), sat(round_q(p(2, 0) - p(0, 2))));
        prop_assert_eq!(c.z.raw(), sat(round_q(p(0, 1) - p(1, 0))));
    }

    #[test]
    fn normalize_matches_definition(c in prop::array::uniform3(prop_oneof![
        any::<i32>(), -(1i32 << 25)..(1 << 25), -64i32..64,
    ])) {
        let n = normalize(WideVec3 { x: c[0], y: c[1], z: c[2] });
        let (dir, len) = ref_normalize(c);
        prop_assert_eq!([n.dir.x.raw(), n.dir.y.raw(), n.dir.z.raw()], dir);
        prop_assert_eq!(n.len.raw(), len);
    }

    #[test]
    fn normalize_gives_unit_vectors(c in prop::array::uniform3(-(1i32 << 25)..(1 << 25))) {
        prop_assume!(c != [0, 0, 0]);
        let n = normalize(WideVec3 { x: c[0], y: c[1], z: c[2] });
        let d = [n.dir.x.raw() as f64, n.dir.y.raw() as f64, n.dir.z.raw() as f64];
        let norm = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() / 1024.0;
        prop_assert!((norm - 1.0).abs() < 2e-3, "|dir| = {norm}");
        let true_len = (c.iter().map(|x| (*x as f64).powi(2)).sum::<f64>()).sqrt() / 1024.0;
        let want = true_len.min(RAW_MAX as f64 / 1024.0);
        // Range reduction truncates each component by under one unit of w and
        // the square root floors (under one more), against len_w >= 2^13:
        // relative error below (sqrt(3) + 1) / 2^13 = 3.4e-4. Tiny inputs are
        // exact to an LSB.
        prop_assert!((n.len.to_f64() - want).abs() <= want * 3.4e-4 + 2.0 / 1024.0,
            "len {} want {}", n.len.to_f64(), want);
    }
}

#[test]
fn mul_edges() {
    let one = Q::ONE.raw();
    assert_eq!(fp_mul(Q::ONE, q(-1)).raw(), -1, "1.0 * -1 LSB is exact");
    assert_eq!(fp_mul(Q::MAX, Q::MAX), Q::MAX, "overflow saturates high");
    assert_eq!(fp_mul(Q::MIN, Q::MIN), Q::MAX, "MIN * MIN saturates high");
    assert_eq!(fp_mul(Q::MIN, q(-one)), Q::MAX, "MIN * -1.0 saturates");
    assert_eq!(fp_mul(Q::MIN, Q::ONE), Q::MIN, "MIN * 1.0 is exact");
    assert_eq!(fp_mul(Q::MAX, q(-2 * one)), Q::MIN, "negative overflow saturates low");
    assert_eq!(fp_mul(q(1), q(512)).raw(), 1, "+0.5 LSB rounds up");
    assert_eq!(fp_mul(q(-1), q(512)).raw(), 0, "-0.5 LSB rounds up to zero");
    assert_eq!(fp_mul(q(-1), q(513)).raw(), -1, "just below -0.5 LSB rounds down");
    assert_eq!(fp_mul(q(1), q(511)).raw(), 0);
    assert_eq!(fp_mul(Q::ZERO, Q::MIN), Q::ZERO);
}

#[test]
fn div_edges() {
    let one = Q::ONE.raw();
    assert_eq!(fp_div(q(3 * one), Q::ZERO), Q::MAX, "x / 0 with x > 0");
    assert_eq!(fp_div(Q::ZERO, Q::ZERO), Q::MAX, "0 / 0");
    assert_eq!(fp_div(q(-1), Q::ZERO), Q::MIN, "x / 0 with x < 0");
    assert_eq!(fp_div(Q::MIN, q(-one)), Q::MAX, "MIN / -1.0 saturates");
    assert_eq!(fp_div(Q::MIN, Q::ONE), Q::MIN);
    assert_eq!(fp_div(Q::MAX, q(1)), Q::MAX, "overflow saturates");
    assert_eq!(fp_div(Q::MAX, q(-1)), Q::MIN);
    assert_eq!(fp_div(q(-1), q(3 * one)).raw(), 0, "truncates toward zero");
    assert_eq!(fp_div(q(-7 * one), q(2 * one)).raw(), -3584, "-3.5 exact");
    assert_eq!(fp_div(q(1), q(3)).raw(), 341, "1/3 LSB quotient: 1024/3 truncated");
    assert_eq!(fp_div(q(-1), q(3)).raw(), -341);
}

#[test]
fn sqrt_edges() {
    assert_eq!(fp_sqrt(Q::ZERO), Q::ZERO);
    assert_eq!(fp_sqrt(q(-1)), Q::ZERO, "negative radicand gives zero");
    assert_eq!(fp_sqrt(Q::MIN), Q::ZERO);
    assert_eq!(fp_sqrt(q(1)).raw(), 32, "sqrt(2^-10) = 2^-5");
    assert_eq!(fp_sqrt(q(4 * 1024)).raw(), 2048);
    assert_eq!(fp_sqrt(q(2 * 1024)).raw(), 1448, "sqrt 2 floored");
    assert_eq!(fp_sqrt(Q::MAX).raw(), 92681);
}

#[test]
fn dot_rounds_once() {
    // Three products of 0.25 LSB each: one rounding gives 1 LSB (0.75 -> 1),
    // three separate fp_muls would give 0.
    let a = v(16, 16, 16);
    let b = v(16, 16, 16); // 16*16 = 256 = 0.25 LSB at Q26.20
    assert_eq!(vec3_dot(a, b).raw(), 1);
    assert_eq!(fp_mul(q(16), q(16)).raw(), 0);
    assert_eq!(vec3_dot(v(RAW_MAX, RAW_MAX, RAW_MAX), v(RAW_MAX, RAW_MAX, RAW_MAX)), Q::MAX);
    assert_eq!(vec3_dot(v(RAW_MIN, 0, 0), v(RAW_MAX, 0, 0)), Q::MIN);
}

#[test]
fn normalize_edges() {
    let zero = normalize(WideVec3::default());
    assert_eq!(zero.dir, Vec3::default());
    assert_eq!(zero.len, Q::ZERO);
    let x = normalize(WideVec3 { x: -1, y: 0, z: 0 });
    assert_eq!((x.dir.x.raw(), x.len.raw()), (-1024, 1), "-1 LSB normalises to -1.0");
    let far = normalize(WideVec3 { x: i32::MIN, y: i32::MAX, z: 0 });
    assert_eq!(far.len, Q::MAX, "length saturates");
    assert_eq!((far.dir.x.raw(), far.dir.y.raw()), (-724, 724), "45 degrees survives");
    let axis = normalize(WideVec3 { x: 0, y: 3 << 10, z: 0 });
    assert_eq!((axis.dir.y.raw(), axis.len.raw()), (1024, 3 << 10));
}

#[test]
fn clamp_unit_edges() {
    assert_eq!(clamp_unit(q(-1)), Q::ZERO);
    assert_eq!(clamp_unit(q(1025)), Q::ONE);
    assert_eq!(clamp_unit(q(1023)).raw(), 1023);
}
