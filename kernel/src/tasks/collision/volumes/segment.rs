//! Point–segment and segment–segment closest points, and the scalar guards the volume tests share.

use nalgebra::{convert, RealField, Vector3};

/// A positive scalar far below any meaningful squared length (m²): `ε⁴` (5e-63 in `f64`,
/// 2e-28 in `f32`, both representable). Guards the divisions by squared lengths.
#[inline]
pub(super) fn negligible<T: RealField + Copy>() -> T {
    let e = T::default_epsilon();
    e * e * e * e
}

/// `value` clamped to `[0, 1]` (NaN maps to 0).
#[inline]
pub(super) fn unit_clamp<T: RealField + Copy>(value: T) -> T {
    if value > T::one() {
        T::one()
    } else if value > T::zero() {
        value
    } else {
        T::zero()
    }
}

/// `numerator / denominator` clamped to `[0, 1]` for a finite `denominator > 0` (NaN maps to 0): the
/// same value as [`unit_clamp`] of the quotient, dividing only when it lies inside.
#[inline]
pub(super) fn clamped_ratio<T: RealField + Copy>(numerator: T, denominator: T) -> T {
    if numerator > T::zero() {
        if numerator < denominator {
            numerator / denominator
        } else {
            T::one()
        }
    } else {
        T::zero()
    }
}

/// Closest point to `p` on the segment `[a, b]`.
pub(super) fn closest_on_segment<T: RealField + Copy>(p: &Vector3<T>, a: &Vector3<T>, b: &Vector3<T>) -> Vector3<T> {
    closest_on_edge(p, a, &(b - a), (b - a).norm_squared())
}

/// Closest point to `p` on the segment from `a` along `d` with `length2 = ‖d‖²`.
#[inline]
pub(super) fn closest_on_edge<T: RealField + Copy>(
    p: &Vector3<T>,
    a: &Vector3<T>,
    d: &Vector3<T>,
    length2: T,
) -> Vector3<T> {
    if length2 <= negligible::<T>() {
        return *a;
    }
    a + d * clamped_ratio((p - a).dot(d), length2)
}

/// Closest points of the segments `[p1, q1]` and `[p2, q2]`: [`closest_edge_edge`] of their
/// directions (the volume tests take the directions from the segments' frames).
#[cfg(test)]
pub(super) fn closest_segment_segment<T: RealField + Copy>(
    p1: &Vector3<T>,
    q1: &Vector3<T>,
    p2: &Vector3<T>,
    q2: &Vector3<T>,
) -> (Vector3<T>, Vector3<T>) {
    let (d1, d2) = (q1 - p1, q2 - p2);
    let (a, e) = (d1.norm_squared(), d2.norm_squared());
    closest_edge_edge(p1, &d1, a, p2, &d2, e)
}

/// Closest points of the segments from `p1` along `d1` and from `p2` along `d2`, with
/// `a = ‖d1‖²` and `e = ‖d2‖²` given by the caller (computed once per edge or segment).
///
/// Minimises `f(s, t) = ‖p1 + s d1 − p2 − t d2‖²` over `[0, 1]²`: the infinite lines' solution
/// for `s`, clamped; the best `t` for it, clamped; the best `s` for that `t`, clamped (exact for
/// this convex quadratic). Parallel segments (`a e − b² ≤ ε a e`) take the midpoint of the
/// overlap of the projections (or the nearest end), zero-length ones the point.
pub(super) fn closest_edge_edge<T: RealField + Copy>(
    p1: &Vector3<T>,
    d1: &Vector3<T>,
    a: T,
    p2: &Vector3<T>,
    d2: &Vector3<T>,
    e: T,
) -> (Vector3<T>, Vector3<T>) {
    closest_edge_edge_inline(p1, d1, a, p2, d2, e)
}

/// [`closest_edge_edge`] inlined into its caller (the segment–segment pairs, which call nothing
/// else).
#[inline(always)]
pub(super) fn closest_edge_edge_inline<T: RealField + Copy>(
    p1: &Vector3<T>,
    d1: &Vector3<T>,
    a: T,
    p2: &Vector3<T>,
    d2: &Vector3<T>,
    e: T,
) -> (Vector3<T>, Vector3<T>) {
    let r = p1 - p2;
    let f = d2.dot(&r);
    let eps = T::default_epsilon();
    let tiny = eps * eps * (a + e + r.norm_squared()) + negligible::<T>();
    let point1 = |s: T| p1 + d1 * s;
    let point2 = |t: T| p2 + d2 * t;
    match (a <= tiny, e <= tiny) {
        (true, true) => return (*p1, *p2),
        (true, false) => return (*p1, point2(clamped_ratio(f, e))),
        (false, true) => return (point1(clamped_ratio(-d1.dot(&r), a)), *p2),
        (false, false) => {}
    }
    let (b, c) = (d1.dot(d2), d1.dot(&r));
    let denominator = a * e - b * b;
    let mut s = if denominator > eps * a * e {
        clamped_ratio(b * f - c * e, denominator)
    } else {
        // Parallel: parameters of p2 and q2 projected onto the first segment.
        let (sa, sb) = (-c / a, (b - c) / a);
        let (lo, hi) = (sa.min(sb).max(T::zero()), sa.max(sb).min(T::one()));
        if lo <= hi {
            (lo + hi) * convert::<f64, T>(0.5)
        } else {
            unit_clamp(sa.min(sb))
        }
    };
    // The best t for s; if it is clamped, the best s for the clamped t.
    let t_numerator = b * s + f;
    let t = if t_numerator >= T::zero() && t_numerator <= e {
        t_numerator / e
    } else {
        let t = if t_numerator > e { T::one() } else { T::zero() };
        s = clamped_ratio(b * t - c, a);
        t
    };
    (point1(s), point2(t))
}
