//! The exact shortcuts of the triangle and segment tests against the full evaluation: the
//! clamp before the division ([`clamped_ratio`]), the piercing tests skipped for a triangle
//! strictly on one side of the other's plane, and the edge–edge clamping order, on random
//! configurations with touching, penetrating, coplanar and parallel cases, in f64 and f32.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "tests")]

use nalgebra::{RealField, Vector3};

use super::segment::{clamped_ratio, closest_segment_segment, unit_clamp};
use super::tests::Rng;
use super::triangle::closest_triangle_triangle;
use super::{reference, Core};

/// `clamped_ratio(n, d)` is bit-identical to `unit_clamp(n / d)` for every finite `d > 0`: random
/// quotients inside, below and above `[0, 1]`, the boundaries `n = 0` and `n = d`, signed
/// zeros, tiny and huge magnitudes (underflowing and overflowing quotients), infinite and NaN
/// numerators.
fn clamped_ratio_is_the_clamped_quotient<T: RealField + Copy>() {
    let mut rng = Rng(0x5EED_C1A4);
    let cast = |x: f64| nalgebra::convert::<f64, T>(x);
    let mut values: Vec<T> = [0.0, -0.0, 1.0, -1.0, 1e-300, 1e300, 1e-40, 3e38, f64::MIN_POSITIVE, f64::NAN]
        .iter()
        .map(|&x| cast(x))
        .collect();
    for _ in 0..4000 {
        values.push(cast(rng.range(-2.0, 2.0) * 10f64.powf(rng.range(-8.0, 8.0))));
    }
    let mut checked = 0;
    for &d in values.iter().filter(|d| **d > T::zero() && d.is_finite()) {
        for &n in values.iter().take(40).chain([d, -d, d * cast(0.5)].iter()) {
            let (fast, plain) = (clamped_ratio(n, d), unit_clamp(n / d));
            assert!(
                fast == plain && fast.is_sign_negative() == plain.is_sign_negative(),
                "{n} / {d}: {fast} vs {plain}"
            );
            checked += 1;
        }
    }
    assert!(checked > 50_000, "{checked}");
}

#[test]
fn clamped_ratio_is_the_clamped_quotient_f64() {
    clamped_ratio_is_the_clamped_quotient::<f64>();
}

#[test]
fn clamped_ratio_is_the_clamped_quotient_f32() {
    clamped_ratio_is_the_clamped_quotient::<f32>();
}

/// A random triangle near the origin, then a second one placed by `case`: 0 strictly above the
/// first one's plane, 1 touching it (a vertex on the plane, exactly: the first triangle lies in
/// `z = 0`), 2 penetrating (vertices on both sides), 3 coplanar, 4 parallel above it, 5 general.
fn triangle_pair(rng: &mut Rng, case: usize) -> ([Vector3<f64>; 3], [Vector3<f64>; 3]) {
    let flat = |rng: &mut Rng| Vector3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 0.0);
    let s = [flat(rng), flat(rng), flat(rng)];
    let lifted = |rng: &mut Rng, lo: f64, hi: f64| {
        let mut p = rng.point();
        p.z = rng.range(lo, hi);
        p
    };
    let t = match case {
        0 => [lifted(rng, 0.01, 1.0), lifted(rng, 0.01, 1.0), lifted(rng, 0.01, 1.0)],
        1 => [flat(rng), lifted(rng, 0.01, 1.0), lifted(rng, 0.01, 1.0)],
        2 => [lifted(rng, -1.0, -0.01), lifted(rng, 0.01, 1.0), lifted(rng, -1.0, 1.0)],
        3 => [flat(rng), flat(rng), flat(rng)],
        4 => {
            let h = rng.range(0.0, 0.5);
            s.map(|v| v + Vector3::new(rng.range(-0.5, 0.5), rng.range(-0.5, 0.5), h))
        }
        _ => [rng.point(), rng.point(), rng.point()],
    };
    (s, t)
}

/// Triangle–triangle (with the piercing tests skipped for a triangle strictly on one side of
/// the other's plane) against the reference (six segment–triangle tests from scratch, every
/// piercing test run) in every case of [`triangle_pair`], both orders: the distances agree to
/// 1e-12 m (f64) and 2e-5 m (f32), the points to 1e-9 m (f64) wherever the reference pair is
/// unique (all but the coplanar and parallel cases); both branches of the skip are exercised.
#[test]
fn triangle_pairs_agree_with_the_full_evaluation() {
    let mut rng = Rng(0x7A1A_0007);
    let (mut skipped, mut tested, mut points_checked) = (0, 0, 0);
    let f32_of = |t: &[Vector3<f64>; 3]| t.map(|v| v.map(|x| x as f32));
    for case in 0..6 {
        for _ in 0..1500 {
            let (s0, t0) = triangle_pair(&mut rng, case);
            for (s, t) in [(s0, t0), (t0, s0)] {
                let one_side = |a: &[Vector3<f64>; 3], b: &[Vector3<f64>; 3]| {
                    let n = (b[1] - b[0]).cross(&(b[2] - b[0]));
                    let h = a.map(|v| n.dot(&(v - b[0])));
                    h.iter().all(|&x| x > 0.0) || h.iter().all(|&x| x < 0.0)
                };
                for side in [one_side(&s, &t), one_side(&t, &s)] {
                    if side {
                        skipped += 1;
                    } else {
                        tested += 1;
                    }
                }
                let (x, y) = closest_triangle_triangle(&s, &t);
                let (rx, ry) = reference::closest_triangle_triangle(&s, &t);
                let (fast, plain) = ((y - x).norm(), (ry - rx).norm());
                assert!((fast - plain).abs() <= 1e-12, "case {case}: {fast} vs {plain}: {s:?} {t:?}");
                if case != 3 && case != 4 {
                    points_checked += 1;
                    assert!((x - rx).norm() <= 1e-9 && (y - ry).norm() <= 1e-9, "case {case}: {s:?} {t:?}");
                }
                let (s32, t32) = (f32_of(&s), f32_of(&t));
                let (x, y) = closest_triangle_triangle(&s32, &t32);
                let (rx, ry) = reference::closest_triangle_triangle(&s32, &t32);
                assert!(((y - x).norm() - (ry - rx).norm()).abs() <= 2e-5, "f32 case {case}: {s:?} {t:?}");
            }
        }
    }
    assert!(skipped > 5000 && tested > 5000 && points_checked > 10_000, "{skipped} {tested} {points_checked}");
}

/// Segment–segment (the clamped `t` recomputes `s` only when `b s + f` leaves `[0, e]`, the
/// clamps compare before dividing) against the reference (quotients clamped after the
/// division): random segments in general position, sharing an end, meeting at a right angle
/// (`b s + f` exactly 0 or `e`), touching end to interior, crossing, parallel and collinear,
/// both orders. Distances agree to 1e-12 m (f64) and 2e-6 m (f32); the points are
/// bit-identical except where the pair is not unique (parallel) or `b s + f` lies exactly on
/// the boundary, and there agree to 1e-9 m (f64) outside the parallel case.
#[test]
fn segment_pairs_agree_with_the_full_evaluation() {
    let mut rng = Rng(0x5E65_0003);
    let (mut identical, mut cases) = (0, 0);
    for case in 0..7 {
        for _ in 0..3000 {
            let (p1, q1) = if case == 2 { axis_segment(&mut rng, 2) } else { (rng.point(), rng.point()) };
            let d = q1 - p1;
            let (p2, q2) = match case {
                0 => (rng.point(), rng.point()),
                1 => (p1, rng.point()),
                // Segments on the coordinate axes: exact zeros and boundary values in the products.
                2 => {
                    let axis = (rng.uniform() * 2.0) as usize;
                    axis_segment(&mut rng, axis)
                }
                3 => (p1 + d * rng.uniform(), rng.point()),
                4 => {
                    let x = p1 + d * rng.uniform();
                    let w = rng.point();
                    (x - w, x + w * rng.uniform())
                }
                5 => {
                    let shift = rng.point() * 0.3;
                    (p1 + shift + d * rng.range(-0.5, 0.5), q1 + shift + d * rng.range(-0.5, 0.5))
                }
                _ => (p1 + d * rng.range(-1.0, 2.0), p1 + d * rng.range(-1.0, 2.0)),
            };
            for (a, b) in [((p1, q1), (p2, q2)), ((p2, q2), (p1, q1))] {
                cases += 1;
                let (x, y) = closest_segment_segment(&a.0, &a.1, &b.0, &b.1);
                let (rx, ry) = reference::closest_points(&Core::Segment([a.0, a.1]), &Core::Segment([b.0, b.1]));
                assert!(((y - x).norm() - (ry - rx).norm()).abs() <= 1e-12, "case {case}: {a:?} {b:?}");
                identical += usize::from((x, y) == (rx, ry));
                if case < 5 {
                    assert!((x - rx).norm() <= 1e-9 && (y - ry).norm() <= 1e-9, "case {case}: {a:?} {b:?}");
                }
                let c = |v: &Vector3<f64>| v.map(|z| z as f32);
                let (x, y) = closest_segment_segment(&c(&a.0), &c(&a.1), &c(&b.0), &c(&b.1));
                let (rx, ry) =
                    reference::closest_points(&Core::Segment([c(&a.0), c(&a.1)]), &Core::Segment([c(&b.0), c(&b.1)]));
                assert!(((y - x).norm() - (ry - rx).norm()).abs() <= 2e-6, "f32 case {case}: {a:?} {b:?}");
            }
        }
    }
    assert!(identical * 10 >= cases * 9, "{identical} of {cases} bit-identical");
}

/// A segment on coordinate axis `axis` between two integers in `[-2, 2]` (distinct).
fn axis_segment(rng: &mut Rng, axis: usize) -> (Vector3<f64>, Vector3<f64>) {
    let k = (rng.uniform() * 4.0).floor() - 2.0;
    let (a, b) = (k, k + 1.0 + (rng.uniform() * 2.0).floor());
    let on_axis = |x: f64| Vector3::from_fn(|i, _| if i == axis { x } else { 0.0 });
    (on_axis(a), on_axis(b))
}
