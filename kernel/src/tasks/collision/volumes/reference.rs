//! The plain closed-form core distances (the test reference of the functions in
//! [`super`]): each candidate of Sec. 3.1.1's swept-sphere distance computed from scratch,
//! triangle–triangle as the nearest of six segment–triangle tests.
#![allow(dead_code, reason = "test reference")]

use nalgebra::{convert, RealField, Vector3};

use super::Core;

/// Closest points `(on a, on b)` of two cores in the same frame.
pub fn closest_points<T: RealField + Copy>(a: &Core<T>, b: &Core<T>) -> (Vector3<T>, Vector3<T>) {
    let swap = |(x, y): (Vector3<T>, Vector3<T>)| (y, x);
    let closest_point_to = |core: &Core<T>, p: &Vector3<T>| match core {
        Core::Point(c) => *c,
        Core::Segment([a, b]) => closest_on_segment(p, a, b),
        Core::Triangle(t) => closest_on_triangle(p, t),
    };
    match (a, b) {
        (Core::Point(p), Core::Point(q)) => (*p, *q),
        (Core::Point(p), other) => (*p, closest_point_to(other, p)),
        (other, Core::Point(p)) => (closest_point_to(other, p), *p),
        (Core::Segment([p1, q1]), Core::Segment([p2, q2])) => closest_segment_segment(p1, q1, p2, q2),
        (Core::Segment([p, q]), Core::Triangle(t)) => closest_segment_triangle(p, q, t),
        (Core::Triangle(t), Core::Segment([p, q])) => swap(closest_segment_triangle(p, q, t)),
        (Core::Triangle(s), Core::Triangle(t)) => closest_triangle_triangle(s, t),
    }
}

/// A positive scalar far below any meaningful squared length (m²): `ε⁴` (5e-63 in `f64`,
/// 2e-28 in `f32`, both representable). Guards the divisions by squared lengths.
#[inline]
pub fn negligible<T: RealField + Copy>() -> T {
    let e = T::default_epsilon();
    e * e * e * e
}

/// `value` clamped to `[0, 1]` (NaN maps to 0).
#[inline]
pub fn unit_clamp<T: RealField + Copy>(value: T) -> T {
    if value > T::one() {
        T::one()
    } else if value > T::zero() {
        value
    } else {
        T::zero()
    }
}

/// Closest point to `p` on the segment `[a, b]`.
pub fn closest_on_segment<T: RealField + Copy>(p: &Vector3<T>, a: &Vector3<T>, b: &Vector3<T>) -> Vector3<T> {
    let d = b - a;
    let length2 = d.norm_squared();
    if length2 <= negligible::<T>() {
        return *a;
    }
    a + d * unit_clamp((p - a).dot(&d) / length2)
}

/// Closest points of the segments `[p1, q1]` and `[p2, q2]`.
///
/// Minimises `f(s, t) = ‖p1 + s d1 − p2 − t d2‖²` over `[0, 1]²`: the infinite lines' solution
/// for `s`, clamped; the best `t` for it, clamped; the best `s` for that `t`, clamped (exact for
/// this convex quadratic). Parallel segments (`a e − b² ≤ ε a e`) take the midpoint of the
/// overlap of the projections (or the nearest end), zero-length ones the point.
pub fn closest_segment_segment<T: RealField + Copy>(
    p1: &Vector3<T>,
    q1: &Vector3<T>,
    p2: &Vector3<T>,
    q2: &Vector3<T>,
) -> (Vector3<T>, Vector3<T>) {
    let (d1, d2, r) = (q1 - p1, q2 - p2, p1 - p2);
    let (a, e, f) = (d1.norm_squared(), d2.norm_squared(), d2.dot(&r));
    let eps = T::default_epsilon();
    let tiny = eps * eps * (a + e + r.norm_squared()) + negligible::<T>();
    let point1 = |s: T| p1 + d1 * s;
    let point2 = |t: T| p2 + d2 * t;
    match (a <= tiny, e <= tiny) {
        (true, true) => return (*p1, *p2),
        (true, false) => return (*p1, point2(unit_clamp(f / e))),
        (false, true) => return (point1(unit_clamp(-d1.dot(&r) / a)), *p2),
        (false, false) => {}
    }
    let (b, c) = (d1.dot(&d2), d1.dot(&r));
    let denominator = a * e - b * b;
    let mut s = if denominator > eps * a * e {
        unit_clamp((b * f - c * e) / denominator)
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
    let t_free = (b * s + f) / e;
    let t = unit_clamp(t_free);
    if t != t_free {
        s = unit_clamp((b * t - c) / a);
    }
    (point1(s), point2(t))
}

/// Normal `(b − a) × (c − a)` of a triangle if its area is not negligible against its size.
pub fn triangle_normal<T: RealField + Copy>([a, b, c]: &[Vector3<T>; 3]) -> Option<Vector3<T>> {
    let (ab, ac) = (b - a, c - a);
    let n = ab.cross(&ac);
    let eps = T::default_epsilon();
    let scale = ab.norm_squared() + ac.norm_squared();
    (n.norm_squared() > eps * eps * scale * scale + negligible::<T>()).then_some(n)
}

/// `true` if `x` (in the triangle's plane) lies inside or on the triangle with normal `n`.
pub fn inside_triangle<T: RealField + Copy>(x: &Vector3<T>, [a, b, c]: &[Vector3<T>; 3], n: &Vector3<T>) -> bool {
    let zero = T::zero();
    n.dot(&(b - a).cross(&(x - a))) >= zero
        && n.dot(&(c - b).cross(&(x - b))) >= zero
        && n.dot(&(a - c).cross(&(x - c))) >= zero
}

/// The pair with the smallest distance among `candidates` (first wins ties).
pub fn nearest_pair<T: RealField + Copy, const K: usize>(
    candidates: [(Vector3<T>, Vector3<T>); K],
) -> (Vector3<T>, Vector3<T>) {
    let mut best = (Vector3::zeros(), Vector3::zeros());
    let mut best_distance: Option<T> = None;
    for (x, y) in candidates {
        let d = (y - x).norm_squared();
        if best_distance.is_none_or(|b| d < b) {
            best = (x, y);
            best_distance = Some(d);
        }
    }
    best
}

/// Closest point to `p` on the triangle `t`.
pub fn closest_on_triangle<T: RealField + Copy>(p: &Vector3<T>, t: &[Vector3<T>; 3]) -> Vector3<T> {
    closest_on_triangle_with_normal(p, t, triangle_normal(t).as_ref())
}

/// [`closest_on_triangle`] with the triangle's [`triangle_normal`] computed by the caller (once
/// per triangle when several points are tested against it; the same operations).
pub fn closest_on_triangle_with_normal<T: RealField + Copy>(
    p: &Vector3<T>,
    t: &[Vector3<T>; 3],
    normal: Option<&Vector3<T>>,
) -> Vector3<T> {
    let [a, b, c] = t;
    if let Some(n) = normal {
        let projection = p - n * (n.dot(&(p - a)) / n.norm_squared());
        if inside_triangle(&projection, t, n) {
            return projection;
        }
    }
    nearest_pair([
        (*p, closest_on_segment(p, a, b)),
        (*p, closest_on_segment(p, b, c)),
        (*p, closest_on_segment(p, c, a)),
    ])
    .1
}

/// Closest points of the segment `[p, q]` and the triangle `t` (segment point first).
pub fn closest_segment_triangle<T: RealField + Copy>(
    p: &Vector3<T>,
    q: &Vector3<T>,
    t: &[Vector3<T>; 3],
) -> (Vector3<T>, Vector3<T>) {
    let normal = triangle_normal(t);
    let n = normal.as_ref();
    if let Some(x) = segment_piercing(p, q, t, n) {
        return (x, x);
    }
    let ends = [closest_on_triangle_with_normal(p, t, n), closest_on_triangle_with_normal(q, t, n)];
    closest_segment_triangle_boundary(p, q, t, ends)
}

/// The point where the segment `[p, q]` pierces the triangle `t` with normal `normal` (its
/// [`triangle_normal`]), if it does.
pub fn segment_piercing<T: RealField + Copy>(
    p: &Vector3<T>,
    q: &Vector3<T>,
    t: &[Vector3<T>; 3],
    normal: Option<&Vector3<T>>,
) -> Option<Vector3<T>> {
    let n = normal?;
    let [a, _, _] = t;
    let (dp, dq) = (n.dot(&(p - a)), n.dot(&(q - a)));
    let zero = T::zero();
    let crosses = (dp <= zero && dq >= zero) || (dp >= zero && dq <= zero);
    if crosses && dp != dq {
        let x = p + (q - p) * (dp / (dp - dq));
        if inside_triangle(&x, t, n) {
            return Some(x);
        }
    }
    None
}

/// The boundary candidates of [`closest_segment_triangle`] for a segment that does not pierce
/// the triangle: both endpoints against the triangle (`ends`, the closest points of the triangle
/// to `p` and `q`, computed by the caller) and the segment against the three edges.
pub fn closest_segment_triangle_boundary<T: RealField + Copy>(
    p: &Vector3<T>,
    q: &Vector3<T>,
    [a, b, c]: &[Vector3<T>; 3],
    [closest_p, closest_q]: [Vector3<T>; 2],
) -> (Vector3<T>, Vector3<T>) {
    nearest_pair([
        (*p, closest_p),
        (*q, closest_q),
        closest_segment_segment(p, q, a, b),
        closest_segment_segment(p, q, b, c),
        closest_segment_segment(p, q, c, a),
    ])
}

/// Closest points of two triangles: the nearest of the six edge–triangle pairs, each computed
/// from scratch.
pub fn closest_triangle_triangle<T: RealField + Copy>(
    s: &[Vector3<T>; 3],
    t: &[Vector3<T>; 3],
) -> (Vector3<T>, Vector3<T>) {
    let [a, b, c] = s;
    let [d, e, f] = t;
    let swap = |(x, y): (Vector3<T>, Vector3<T>)| (y, x);
    nearest_pair([
        closest_segment_triangle(a, b, t),
        closest_segment_triangle(b, c, t),
        closest_segment_triangle(c, a, t),
        swap(closest_segment_triangle(d, e, s)),
        swap(closest_segment_triangle(e, f, s)),
        swap(closest_segment_triangle(f, d, s)),
    ])
}
