//! Swept-sphere volumes and their closest points (Sec. 3.1.1).
//!
//! A swept-sphere volume is the set of points within `radius` of a convex **core**: a point
//! (sphere), a segment (capsule, "rounded cylinder") or a triangle (a sphere "unrolled on a
//! triangle"). The distance of two volumes is the distance of their cores minus both radii, and
//! the closest surface points lie on the line through the closest core points. The thesis uses
//! GJK on these spherically extended convex hulls (\[GJK88\], \[TBF11\]); here every core pair has
//! an exact closed-form solution, so the cost is bounded per pair kind (no iteration):
//!
//! | cores | method |
//! | --- | --- |
//! | point–point | difference |
//! | point–segment | clamped projection |
//! | segment–segment | minimum of the convex quadratic `‖p₁ + s d₁ − p₂ − t d₂‖²` over `[0,1]²`: line solution, clamp `s`, best `t`, clamp, best `s` |
//! | point–triangle | projection onto the plane if it falls inside, else the nearest of the edges it lies outside of |
//! | segment–triangle | crossing point if the segment pierces the triangle, else the nearest of {the endpoints that project inside, the segment vs each edge an endpoint lies outside of} |
//! | triangle–triangle | the nearest of the six edge–triangle pairs, each edge–edge pair at most once |
//!
//! The last two rest on a property of convex polytopes: if neither closest point is on the
//! relative boundary of its feature, the features are parallel and a boundary pair is as close.
//!
//! **Uniqueness and continuity.** The distance is a 1-Lipschitz function of the core points, so
//! it is continuous in the configuration. The closest points are unique, and continuous, unless
//! two flat features are parallel: parallel segments whose projections overlap, a segment
//! parallel to a triangle above its interior, parallel triangles above each other. There the set
//! of closest pairs is a segment or polygon, and the chosen pair jumps as the features tilt
//! through parallel. Parallel overlapping segments take the midpoint of the overlap; the other
//! cases take the first candidate in the fixed order above. Degenerate cores (zero-length
//! segments, zero-area triangles) are handled as the point or segment they are.

use nalgebra::{convert, RealField, Unit, Vector3};

use crate::math::spatial::Placement;
use crate::math::sqrt;

/// The convex set a sphere is swept over, in some frame (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Core<T: RealField> {
    /// A single point: the volume is a sphere.
    Point(Vector3<T>),
    /// A segment between two points: the volume is a capsule.
    Segment([Vector3<T>; 2]),
    /// A triangle: the volume is a sphere swept over the triangle.
    Triangle([Vector3<T>; 3]),
}

impl<T: RealField + Copy> Core<T> {
    /// The core mapped through `placement` (body frame → world frame).
    pub fn transformed(&self, placement: &Placement<T>) -> Self {
        let map = |p: &Vector3<T>| placement.rotation * p + placement.translation.vector;
        match self {
            Self::Point(p) => Self::Point(map(p)),
            Self::Segment(s) => Self::Segment(s.each_ref().map(map)),
            Self::Triangle(t) => Self::Triangle(t.each_ref().map(map)),
        }
    }

    /// The defining points (1, 2 or 3).
    pub fn points(&self) -> &[Vector3<T>] {
        match self {
            Self::Point(p) => core::slice::from_ref(p),
            Self::Segment(s) => s,
            Self::Triangle(t) => t,
        }
    }

    /// `true` if every coordinate is finite.
    pub fn is_finite(&self) -> bool {
        self.points().iter().all(|p| p.iter().all(|x| x.is_finite()))
    }

    /// The point of the core closest to `p`.
    pub fn closest_point_to(&self, p: &Vector3<T>) -> Vector3<T> {
        match self {
            Self::Point(c) => *c,
            Self::Segment([a, b]) => closest_on_segment(p, a, b),
            Self::Triangle(t) => closest_on_triangle(p, t),
        }
    }
}

/// A swept-sphere volume: every point within `radius` (m) of `core`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SweptSphere<T: RealField> {
    /// The core.
    pub core: Core<T>,
    /// Radius of the swept sphere (m), `≥ 0`.
    pub radius: T,
}

impl<T: RealField + Copy> SweptSphere<T> {
    /// A sphere of radius `radius` about `center`.
    pub fn sphere(center: Vector3<T>, radius: T) -> Self {
        Self { core: Core::Point(center), radius }
    }

    /// A capsule: the sphere swept from `a` to `b`.
    pub fn capsule(a: Vector3<T>, b: Vector3<T>, radius: T) -> Self {
        Self { core: Core::Segment([a, b]), radius }
    }

    /// The sphere swept over the triangle `(a, b, c)`.
    pub fn swept_triangle(a: Vector3<T>, b: Vector3<T>, c: Vector3<T>, radius: T) -> Self {
        Self { core: Core::Triangle([a, b, c]), radius }
    }

    /// The volume mapped through `placement`.
    pub fn transformed(&self, placement: &Placement<T>) -> Self {
        Self { core: self.core.transformed(placement), radius: self.radius }
    }

    /// A sphere `(center, radius)` enclosing the volume: the centroid of the core's points and
    /// the largest distance to them plus the swept radius (m).
    pub fn bounding_sphere(&self) -> (Vector3<T>, T) {
        let points = self.core.points();
        let count: T = convert(points.len().max(1) as f64);
        let center = points.iter().fold(Vector3::zeros(), |c, p| c + p) / count;
        // The largest squared distance, then one square root (the same value: sqrt is monotone).
        let reach2 = points.iter().map(|p| (p - center).norm_squared()).fold(T::zero(), |m, d| m.max(d));
        (center, sqrt(reach2) + self.radius)
    }

    /// Signed distance of the point `p` to the surface (negative inside).
    pub fn signed_distance_to(&self, p: &Vector3<T>) -> T {
        sqrt((p - self.core.closest_point_to(p)).norm_squared()) - self.radius
    }
}

/// Closest points of two swept-sphere volumes `a` (first, index `i` of the pair) and `b`
/// (second, `j`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Proximity<T: RealField> {
    /// Signed surface distance `d = ‖c_b − c_a‖ − r_a − r_b` (m), (3.4); negative when the
    /// volumes overlap.
    pub distance: T,
    /// Closest point of `a`'s core (world frame, m).
    pub core_first: Vector3<T>,
    /// Closest point of `b`'s core (world frame, m).
    pub core_second: Vector3<T>,
    /// Unit collision direction `e_i` from `a` towards `b`, (3.5). `None` if the cores touch
    /// (closer than [`direction_threshold`]), where it is undefined.
    pub direction: Option<Unit<Vector3<T>>>,
}

impl<T: RealField + Copy> Proximity<T> {
    /// The closest surface points `(x_i, x_j) = (c_a + r_a e, c_b − r_b e)` (world frame, m), or
    /// `None` without a direction. With overlap (`d < 0`) `x_j` lies before `x_i` along `e`.
    pub fn surface_points(&self, radius_first: T, radius_second: T) -> Option<(Vector3<T>, Vector3<T>)> {
        let e = self.direction?.into_inner();
        Some((self.core_first + e * radius_first, self.core_second - e * radius_second))
    }
}

/// Core distance below which the collision direction is undefined (m): `1000 ε`
/// (2.2e-13 m in `f64`, 1.2e-4 m in `f32`). The cores meet only after the surfaces have
/// penetrated by the sum of the radii.
pub fn direction_threshold<T: RealField + Copy>() -> T {
    convert::<f64, T>(1e3) * T::default_epsilon()
}

/// Distance and closest points of two swept-sphere volumes given in the same frame.
///
/// ```
/// use kernel::tasks::collision::{proximity, SweptSphere};
/// use nalgebra::Vector3;
/// // Two crossing capsules 0.5 m apart (cores), radii 0.1 and 0.05: d = 0.35 m.
/// let a = SweptSphere::<f64>::capsule(Vector3::new(-1.0, 0.0, 0.0), Vector3::new(1.0, 0.0, 0.0), 0.1);
/// let b = SweptSphere::capsule(Vector3::new(0.3, -1.0, 0.5), Vector3::new(0.3, 1.0, 0.5), 0.05);
/// let p = proximity(&a, &b);
/// assert!((p.distance - 0.35).abs() < 1e-15);
/// assert!((p.direction.unwrap().into_inner() - Vector3::z()).norm() < 1e-15);
/// ```
pub fn proximity<T: RealField + Copy>(a: &SweptSphere<T>, b: &SweptSphere<T>) -> Proximity<T> {
    let (fa, fb) = (TriangleFrame::of(&a.core), TriangleFrame::of(&b.core));
    proximity_framed(a, &fa, b, &fb)
}

/// [`proximity`] with the triangle frames of both cores given ([`TriangleFrame::of`], computed
/// once per volume and cycle and shared by all its pairs): the same operations, so the same
/// result.
pub(super) fn proximity_framed<T: RealField + Copy>(
    a: &SweptSphere<T>,
    fa: &TriangleFrame<T>,
    b: &SweptSphere<T>,
    fb: &TriangleFrame<T>,
) -> Proximity<T> {
    let (core_first, core_second) = closest_points_framed(&a.core, fa, &b.core, fb);
    let delta = core_second - core_first;
    let core_distance = sqrt(delta.norm_squared());
    let direction =
        if core_distance > direction_threshold() { Some(Unit::new_unchecked(delta / core_distance)) } else { None };
    Proximity { distance: core_distance - a.radius - b.radius, core_first, core_second, direction }
}

/// Closest points `(on a, on b)` of two cores in the same frame. Cost: bounded per kind, at most six
/// piercing tests, six vertex projections and nine edge–edge tests (triangle–triangle).
pub fn closest_points<T: RealField + Copy>(a: &Core<T>, b: &Core<T>) -> (Vector3<T>, Vector3<T>) {
    closest_points_framed(a, &TriangleFrame::of(a), b, &TriangleFrame::of(b))
}

/// [`closest_points`] with the cores' triangle frames `fa`, `fb` ([`TriangleFrame::of`]; read
/// only for a triangle core).
fn closest_points_framed<T: RealField + Copy>(
    a: &Core<T>,
    fa: &TriangleFrame<T>,
    b: &Core<T>,
    fb: &TriangleFrame<T>,
) -> (Vector3<T>, Vector3<T>) {
    let swap = |(x, y): (Vector3<T>, Vector3<T>)| (y, x);
    match (a, b) {
        (Core::Point(p), Core::Point(q)) => (*p, *q),
        (Core::Point(p), Core::Segment([x, y])) => (*p, closest_on_segment(p, x, y)),
        (Core::Segment([x, y]), Core::Point(p)) => (closest_on_segment(p, x, y), *p),
        (Core::Point(p), Core::Triangle(_)) => (*p, fb.closest_point(p, fb.height(p))),
        (Core::Triangle(_), Core::Point(p)) => (fa.closest_point(p, fa.height(p)), *p),
        (Core::Segment([p1, q1]), Core::Segment([p2, q2])) => closest_segment_segment(p1, q1, p2, q2),
        (Core::Segment([p, q]), Core::Triangle(_)) => closest_segment_framed(p, q, fb),
        (Core::Triangle(_), Core::Segment([p, q])) => swap(closest_segment_framed(p, q, fa)),
        (Core::Triangle(_), Core::Triangle(_)) => closest_triangles_framed(fa, fb),
    }
}

/// A positive scalar far below any meaningful squared length (m²): `ε⁴` (5e-63 in `f64`,
/// 2e-28 in `f32`, both representable). Guards the divisions by squared lengths.
#[inline]
fn negligible<T: RealField + Copy>() -> T {
    let e = T::default_epsilon();
    e * e * e * e
}

/// `value` clamped to `[0, 1]` (NaN maps to 0).
#[inline]
fn unit_clamp<T: RealField + Copy>(value: T) -> T {
    if value > T::one() {
        T::one()
    } else if value > T::zero() {
        value
    } else {
        T::zero()
    }
}

/// Closest point to `p` on the segment `[a, b]`.
fn closest_on_segment<T: RealField + Copy>(p: &Vector3<T>, a: &Vector3<T>, b: &Vector3<T>) -> Vector3<T> {
    closest_on_edge(p, a, &(b - a), (b - a).norm_squared())
}

/// Closest point to `p` on the segment from `a` along `d` with `length2 = ‖d‖²`.
#[inline]
fn closest_on_edge<T: RealField + Copy>(p: &Vector3<T>, a: &Vector3<T>, d: &Vector3<T>, length2: T) -> Vector3<T> {
    if length2 <= negligible::<T>() {
        return *a;
    }
    a + d * unit_clamp((p - a).dot(d) / length2)
}

/// Closest points of the segments `[p1, q1]` and `[p2, q2]`.
///
/// Minimises `f(s, t) = ‖p1 + s d1 − p2 − t d2‖²` over `[0, 1]²`: the infinite lines' solution
/// for `s`, clamped; the best `t` for it, clamped; the best `s` for that `t`, clamped (exact for
/// this convex quadratic). Parallel segments (`a e − b² ≤ ε a e`) take the midpoint of the
/// overlap of the projections (or the nearest end), zero-length ones the point.
fn closest_segment_segment<T: RealField + Copy>(
    p1: &Vector3<T>,
    q1: &Vector3<T>,
    p2: &Vector3<T>,
    q2: &Vector3<T>,
) -> (Vector3<T>, Vector3<T>) {
    let (d1, d2) = (q1 - p1, q2 - p2);
    let (a, e) = (d1.norm_squared(), d2.norm_squared());
    closest_edge_edge(p1, &d1, a, p2, &d2, e)
}

/// [`closest_segment_segment`] of the segments from `p1` along `d1` and from `p2` along `d2`,
/// with `a = ‖d1‖²` and `e = ‖d2‖²` given by the caller (computed once per edge).
fn closest_edge_edge<T: RealField + Copy>(
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
        (true, false) => return (*p1, point2(unit_clamp(f / e))),
        (false, true) => return (point1(unit_clamp(-d1.dot(&r) / a)), *p2),
        (false, false) => {}
    }
    let (b, c) = (d1.dot(d2), d1.dot(&r));
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
fn triangle_normal<T: RealField + Copy>([a, b, c]: &[Vector3<T>; 3]) -> Option<Vector3<T>> {
    let (ab, ac) = (b - a, c - a);
    let n = ab.cross(&ac);
    let eps = T::default_epsilon();
    let scale = ab.norm_squared() + ac.norm_squared();
    (n.norm_squared() > eps * eps * scale * scale + negligible::<T>()).then_some(n)
}

/// A triangle `(v₀, v₁, v₂)` with the quantities every distance test against it shares: the
/// edges `e_k = v_{k+1} − v_k` and `‖e_k‖²`; if it is not degenerate (`planar`), its normal `n`
/// ([`triangle_normal`]), `‖n‖²` and the in-plane edge normals `n × e_k` that point into the
/// triangle (zeros and one for a degenerate triangle, which has no plane).
#[derive(Clone, Copy, Debug)]
pub(super) struct TriangleFrame<T: RealField> {
    vertices: [Vector3<T>; 3],
    edges: [Vector3<T>; 3],
    edge_length2: [T; 3],
    planar: bool,
    normal: Vector3<T>,
    normal_length2: T,
    edge_normals: [Vector3<T>; 3],
}

impl<T: RealField + Copy> TriangleFrame<T> {
    /// The frame of `core` if it is a triangle, else [`Self::placeholder`] (never read: only a
    /// triangle core's frame is).
    #[inline]
    pub(super) fn of(core: &Core<T>) -> Self {
        match core {
            Core::Triangle(t) => Self::new(t),
            _ => Self::placeholder(),
        }
    }

    /// The frame of the degenerate triangle at the origin.
    pub(super) fn placeholder() -> Self {
        let zero = Vector3::zeros();
        Self {
            vertices: [zero; 3],
            edges: [zero; 3],
            edge_length2: [T::zero(); 3],
            planar: false,
            normal: zero,
            normal_length2: T::one(),
            edge_normals: [zero; 3],
        }
    }

    fn new(t: &[Vector3<T>; 3]) -> Self {
        let [a, b, c] = t;
        let edges = [b - a, c - b, a - c];
        let edge_length2 = edges.each_ref().map(|e| e.norm_squared());
        match triangle_normal(t) {
            Some(normal) => Self {
                vertices: *t,
                edges,
                edge_length2,
                planar: true,
                normal,
                normal_length2: normal.norm_squared(),
                edge_normals: edges.each_ref().map(|e| normal.cross(e)),
            },
            None => Self {
                vertices: *t,
                edges,
                edge_length2,
                planar: false,
                normal: Vector3::zeros(),
                normal_length2: T::one(),
                edge_normals: [Vector3::zeros(); 3],
            },
        }
    }

    /// Signed height `n · (p − v₀)` of `p` above the plane (unnormalised; zero without a plane).
    #[inline]
    fn height(&self, p: &Vector3<T>) -> T {
        let [a, _, _] = &self.vertices;
        self.normal.dot(&(p - a))
    }

    /// A lower bound of the squared distance of any point of the triangle's plane to the
    /// segment whose ends have the heights `hp`, `hq`, as `(min(hp², hq²), ‖n‖²)` (the bound is
    /// their quotient): zero unless both ends are strictly on one side of a plane.
    #[inline]
    fn clearance(&self, hp: T, hq: T) -> (T, T) {
        if self.planar && hp * hq > T::zero() {
            ((hp * hp).min(hq * hq), self.normal_length2)
        } else {
            (T::zero(), T::one())
        }
    }

    /// For each edge `k`, `true` if `x` lies on its inner side, `(n × e_k) · (x − v_k) ≥ 0`
    /// (the triple products `n · (e_k × (x − v_k))` of [`closest_on_triangle`]'s test,
    /// regrouped): all `true` if the projection of `x` onto the plane lies inside or on the
    /// triangle; all `false` for a degenerate triangle.
    #[inline]
    fn sides(&self, x: &Vector3<T>) -> [bool; 3] {
        if !self.planar {
            return [false; 3];
        }
        let zero = T::zero();
        let [m0, m1, m2] = &self.edge_normals;
        let [a, b, c] = &self.vertices;
        [m0.dot(&(x - a)) >= zero, m1.dot(&(x - b)) >= zero, m2.dot(&(x - c)) >= zero]
    }

    /// The projection of `x` (height `height`) onto the plane if `sides` (its [`Self::sides`])
    /// puts it inside or on the triangle.
    #[inline]
    fn projection(&self, x: &Vector3<T>, height: T, sides: [bool; 3]) -> Option<Vector3<T>> {
        (sides == [true; 3]).then(|| x - self.normal * (height / self.normal_length2))
    }

    /// Closest point to `p` on the triangle, with `height = self.height(p)`: the projection onto
    /// the plane if it falls inside, else the nearest point of the edges `p` lies outside of
    /// (the closest point of a triangle to an outside point is on such an edge; all three
    /// edges for a degenerate triangle).
    fn closest_point(&self, p: &Vector3<T>, height: T) -> Vector3<T> {
        let sides = self.sides(p);
        if let Some(x) = self.projection(p, height, sides) {
            return x;
        }
        let mut nearest = Nearest::new();
        for (((v, e), &length2), inner) in self.vertices.iter().zip(&self.edges).zip(&self.edge_length2).zip(sides) {
            if !inner {
                nearest.offer(p, &closest_on_edge(p, v, e, length2));
            }
        }
        nearest.pair.1
    }

    /// The point where the segment `[p, q]` pierces the triangle, given the heights `dp`, `dq`
    /// of its ends, if it does.
    #[inline]
    fn piercing(&self, p: &Vector3<T>, q: &Vector3<T>, dp: T, dq: T) -> Option<Vector3<T>> {
        let zero = T::zero();
        let crosses = (dp <= zero && dq >= zero) || (dp >= zero && dq <= zero);
        if self.planar && crosses && dp != dq {
            let x = p + (q - p) * (dp / (dp - dq));
            if self.sides(&x) == [true; 3] {
                return Some(x);
            }
        }
        None
    }
}

/// The running nearest of candidate pairs (the first wins ties).
struct Nearest<T: RealField> {
    pair: (Vector3<T>, Vector3<T>),
    distance2: T,
    empty: bool,
}

impl<T: RealField + Copy> Nearest<T> {
    #[inline]
    fn new() -> Self {
        Self { pair: (Vector3::zeros(), Vector3::zeros()), distance2: T::zero(), empty: true }
    }

    /// `true` if no pair at a squared distance of at least the [`TriangleFrame::clearance`]
    /// `(h2, n2)` (that is `h2 / n2`) can beat the nearest so far.
    #[inline]
    fn excludes(&self, (h2, n2): (T, T)) -> bool {
        !self.empty && h2 >= self.distance2 * n2
    }

    #[inline]
    fn offer(&mut self, x: &Vector3<T>, y: &Vector3<T>) {
        let d = (y - x).norm_squared();
        if self.empty || d < self.distance2 {
            self.pair = (*x, *y);
            self.distance2 = d;
            self.empty = false;
        }
    }
}

/// Closest point to `p` on the triangle `t`: its projection onto the plane if that falls
/// inside, else the nearest point of the edges.
fn closest_on_triangle<T: RealField + Copy>(p: &Vector3<T>, t: &[Vector3<T>; 3]) -> Vector3<T> {
    let frame = TriangleFrame::new(t);
    frame.closest_point(p, frame.height(p))
}

/// Closest points of the segment `[p, q]` and the triangle `t` (segment point first).
///
/// The crossing point if the segment pierces the triangle; else the nearest of the ends whose
/// projection falls inside the triangle (with that projection) and of the segment against each
/// edge that an end lies outside of. The candidates left out cannot be closer: the closest
/// pair `(x, y)` has `x − y` in the normal cone of the triangle at `y`, so with `y` on edge `k`
/// either `x` lies outside edge `k` (then an end does) or `x` lies above `y` at the distance of
/// an end that projects inside; an end outside the triangle is no closer than the segment
/// against an edge it lies outside of. The edges are skipped when the segment's distance from
/// the plane is no less than the nearest end's.
#[cfg(test)]
fn closest_segment_triangle<T: RealField + Copy>(
    p: &Vector3<T>,
    q: &Vector3<T>,
    t: &[Vector3<T>; 3],
) -> (Vector3<T>, Vector3<T>) {
    closest_segment_framed(p, q, &TriangleFrame::new(t))
}

/// [`closest_segment_triangle`] against the triangle of `frame`.
fn closest_segment_framed<T: RealField + Copy>(
    p: &Vector3<T>,
    q: &Vector3<T>,
    frame: &TriangleFrame<T>,
) -> (Vector3<T>, Vector3<T>) {
    let (hp, hq) = (frame.height(p), frame.height(q));
    if let Some(x) = frame.piercing(p, q, hp, hq) {
        return (x, x);
    }
    let (sp, sq) = (frame.sides(p), frame.sides(q));
    let mut nearest = Nearest::new();
    for (x, end) in [(p, frame.projection(p, hp, sp)), (q, frame.projection(q, hq, sq))] {
        if let Some(y) = end {
            nearest.offer(x, &y);
        }
    }
    if nearest.excludes(frame.clearance(hp, hq)) {
        return nearest.pair;
    }
    let d = q - p;
    let a = d.norm_squared();
    for (((v, e), &length2), (inner_p, inner_q)) in
        frame.vertices.iter().zip(&frame.edges).zip(&frame.edge_length2).zip(sp.into_iter().zip(sq))
    {
        if !(inner_p && inner_q) {
            let (x, y) = closest_edge_edge(p, &d, a, v, e, length2);
            nearest.offer(&x, &y);
        }
    }
    nearest.pair
}

/// Closest points of two triangles: the nearest of the candidates of the six edge–triangle
/// pairs of [`closest_segment_triangle`] (edges of `s` against `t`, then edges of `t` against
/// `s`). The first piercing edge gives a crossing point; else the vertices that project inside
/// the other triangle, then each edge–edge pair once, if an end of either edge lies outside the
/// other edge and neither edge's distance from the other triangle's plane rules it out. Each
/// plane, vertex height, side and projection is computed once.
#[cfg(test)]
fn closest_triangle_triangle<T: RealField + Copy>(
    s: &[Vector3<T>; 3],
    t: &[Vector3<T>; 3],
) -> (Vector3<T>, Vector3<T>) {
    closest_triangles_framed(&TriangleFrame::new(s), &TriangleFrame::new(t))
}

/// [`closest_triangle_triangle`] of the triangles of the frames `fs` and `ft`.
fn closest_triangles_framed<T: RealField + Copy>(
    fs: &TriangleFrame<T>,
    ft: &TriangleFrame<T>,
) -> (Vector3<T>, Vector3<T>) {
    let (s, t) = (&fs.vertices, &ft.vertices);
    let [a, b, c] = s;
    let [d, e, f] = t;
    let [ha, hb, hc] = s.each_ref().map(|v| ft.height(v));
    let [hd, he, hf] = t.each_ref().map(|v| fs.height(v));
    let edges_s = [(a, b, ha, hb), (b, c, hb, hc), (c, a, hc, ha)];
    let edges_t = [(d, e, hd, he), (e, f, he, hf), (f, d, hf, hd)];
    for (p, q, hp, hq) in edges_s {
        if let Some(x) = ft.piercing(p, q, hp, hq) {
            return (x, x);
        }
    }
    for (p, q, hp, hq) in edges_t {
        if let Some(x) = fs.piercing(p, q, hp, hq) {
            return (x, x);
        }
    }
    let [sa, sb, sc] = s.each_ref().map(|v| ft.sides(v));
    let [sd, se, sf] = t.each_ref().map(|v| fs.sides(v));
    let mut nearest = Nearest::new();
    for (v, h, side) in [(a, ha, sa), (b, hb, sb), (c, hc, sc)] {
        if let Some(y) = ft.projection(v, h, side) {
            nearest.offer(v, &y);
        }
    }
    for (v, h, side) in [(d, hd, sd), (e, he, se), (f, hf, sf)] {
        if let Some(x) = fs.projection(v, h, side) {
            nearest.offer(&x, v);
        }
    }
    // Edge k of t has an end outside edge j of s: `outer_t[k][j]`; the bound of edge k of t.
    let outer = |[x0, x1, x2]: [bool; 3], [y0, y1, y2]: [bool; 3]| [!(x0 && y0), !(x1 && y1), !(x2 && y2)];
    let outer_t = [outer(sd, se), outer(se, sf), outer(sf, sd)];
    let bounds_t = edges_t.map(|(_, _, hp, hq)| fs.clearance(hp, hq));
    let sides_s = [(sa, sb), (sb, sc), (sc, sa)];
    for (j, (((p, _, hp, hq), (sp, sq)), (edge, &length2))) in
        edges_s.into_iter().zip(sides_s).zip(fs.edges.iter().zip(&fs.edge_length2)).enumerate()
    {
        let bound_s = ft.clearance(hp, hq);
        if nearest.excludes(bound_s) {
            continue;
        }
        let outer_s = outer(sp, sq);
        let edges = ft.vertices.iter().zip(&ft.edges).zip(&ft.edge_length2);
        for ((((v, e), &e2), out_s), (out_t, bound_t)) in edges.zip(outer_s).zip(outer_t.iter().zip(&bounds_t)) {
            if (out_s || out_t.get(j).copied().unwrap_or(true)) && !nearest.excludes(*bound_t) {
                let (x, y) = closest_edge_edge(p, edge, length2, v, e, e2);
                nearest.offer(&x, &y);
            }
        }
    }
    nearest.pair
}

#[cfg(test)]
#[path = "reference.rs"]
mod reference;

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "tests")]
    use super::*;

    /// Fast and reference closest points of `a` and `b`: the core distances agree within
    /// `tol_distance`; returns whether the closest points also agree within `tol_point` (they
    /// need not where the closest pair is not unique) and whether they are bit-identical.
    fn compare_with_reference<T: RealField + Copy>(
        a: &Core<T>,
        b: &Core<T>,
        tol_distance: T,
        tol_point: T,
    ) -> (bool, bool) {
        let (fa, fb) = closest_points(a, b);
        let (ra, rb) = reference::closest_points(a, b);
        let (fast, plain) = ((fb - fa).norm(), (rb - ra).norm());
        assert!((fast - plain).abs() <= tol_distance, "distance {fast} vs reference {plain}: {a:?} {b:?}");
        let close = (fa - ra).norm() <= tol_point && (fb - rb).norm() <= tol_point;
        (close, (fa, fb) == (ra, rb))
    }

    fn to_f32(core: &Core<f64>) -> Core<f32> {
        let cast = |p: &Vector3<f64>| p.map(|x| x as f32);
        match core {
            Core::Point(p) => Core::Point(cast(p)),
            Core::Segment(s) => Core::Segment(s.each_ref().map(cast)),
            Core::Triangle(t) => Core::Triangle(t.each_ref().map(cast)),
        }
    }

    /// The closest points agree with the plain reference (every candidate from scratch,
    /// triangle–triangle as six segment–triangle tests) on random cores of every kind pair in
    /// both orders, one in eight degenerate and one in eight parallel to the other core: f64
    /// to 1e-12 m in distance and 1e-9 m in the points, f32 to 2e-5 m and 1e-3 m. Where the
    /// points differ (closest pairs not unique) the fast pair is on the cores and certified
    /// optimal (f64), and that happens in at most 2 % of the cases (the parallel ones).
    #[test]
    fn closest_points_agree_with_the_reference() {
        let mut rng = Rng(0x7A1A_0002);
        let (mut cases, mut moved64, mut moved32, mut identical, mut pierced) = (0, 0, 0, 0, 0);
        for ka in 0..3 {
            for kb in 0..3 {
                for _ in 0..4000 {
                    let a = random_core(&mut rng, ka, None);
                    let b = random_core(&mut rng, kb, Some(&a));
                    cases += 1;
                    let (close, same) = compare_with_reference(&a, &b, 1e-12, 1e-9);
                    identical += usize::from(same);
                    if !close {
                        moved64 += 1;
                        let (pa, pb) = closest_points(&a, &b);
                        assert!(on_core(&a, &pa) && on_core(&b, &pb), "{a:?} {b:?}");
                        assert!(certified(&a, &b, &pa, &pb), "not optimal: {a:?} {b:?}");
                    }
                    let (pa, pb) = closest_points(&a, &b);
                    pierced += usize::from(ka + kb >= 3 && pa == pb);
                    let (close32, _) = compare_with_reference(&to_f32(&a), &to_f32(&b), 2e-5, 1e-3);
                    moved32 += usize::from(!close32);
                }
            }
        }
        println!("{cases} cases: {identical} bit-identical, points differ in {moved64} (f64) and {moved32} (f32); {pierced} piercing");
        assert!(moved64 * 50 <= cases && moved32 * 50 <= cases, "{moved64} / {moved32} of {cases}");
        assert!(pierced > 500, "{pierced} piercing pairs");
    }

    /// The degenerate configurations against the reference: parallel and zero-length
    /// segments against triangles, coplanar, touching (vertex on a face, edge on an edge) and
    /// penetrating triangles, points on edges and vertices, collinear triangles.
    #[test]
    fn degenerate_cases_agree_with_the_reference() {
        let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
        let tri = Core::Triangle([v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)]);
        let cores = [
            // Points on an edge, on a vertex, inside, above an edge.
            Core::Point(v(0.5, 0.0, 0.0)),
            Core::Point(v(1.0, 0.0, 0.0)),
            Core::Point(v(0.2, 0.3, 0.0)),
            Core::Point(v(0.5, 0.5, 0.7)),
            // Zero-length segments on the face and above it.
            Core::Segment([v(0.2, 0.2, 0.0), v(0.2, 0.2, 0.0)]),
            Core::Segment([v(0.2, 0.2, 0.4), v(0.2, 0.2, 0.4)]),
            // Segments parallel to an edge (above it, in the plane, collinear), parallel to the
            // face above it, in the plane crossing an edge, ending on the face.
            Core::Segment([v(0.2, 0.0, 0.3), v(0.8, 0.0, 0.3)]),
            Core::Segment([v(0.2, -0.3, 0.0), v(0.8, -0.3, 0.0)]),
            Core::Segment([v(-0.5, 0.0, 0.0), v(0.5, 0.0, 0.0)]),
            Core::Segment([v(0.1, 0.1, 0.5), v(0.3, 0.2, 0.5)]),
            Core::Segment([v(0.2, -0.5, 0.0), v(0.2, 0.5, 0.0)]),
            Core::Segment([v(0.2, 0.2, 0.0), v(0.2, 0.2, 1.0)]),
            // Triangles: coplanar overlapping, coplanar disjoint, parallel above, touching with
            // a vertex on the face, sharing an edge, penetrating, collinear (degenerate), a point.
            Core::Triangle([v(0.2, 0.2, 0.0), v(1.2, 0.2, 0.0), v(0.2, 1.2, 0.0)]),
            Core::Triangle([v(2.0, 0.0, 0.0), v(3.0, 0.0, 0.0), v(2.0, 1.0, 0.0)]),
            Core::Triangle([v(0.3, 0.3, 0.25), v(1.3, 0.3, 0.25), v(0.3, 1.3, 0.25)]),
            Core::Triangle([v(0.2, 0.2, 0.0), v(0.5, 0.5, 1.0), v(0.0, 0.5, 1.0)]),
            Core::Triangle([v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.5, -0.5, 0.5)]),
            Core::Triangle([v(0.2, 0.2, -0.5), v(0.3, 0.1, 0.5), v(0.9, 0.9, 0.5)]),
            Core::Triangle([v(0.0, 0.0, 0.5), v(2.0, 0.0, 0.5), v(1.0, 0.0, 0.5)]),
            Core::Triangle([v(0.3, 0.3, 0.3), v(0.3, 0.3, 0.3), v(0.3, 0.3, 0.3)]),
        ];
        for core in &cores {
            for (a, b) in [(&tri, core), (core, &tri)] {
                let (close, _) = compare_with_reference(a, b, 1e-15, 1e-15);
                let (pa, pb) = closest_points(a, b);
                // Where the closest pair is not unique, another optimal pair.
                assert!(close || (on_core(a, &pa) && on_core(b, &pb) && certified(a, b, &pa, &pb)), "{a:?} {b:?}");
                compare_with_reference(&to_f32(a), &to_f32(b), 1e-6, 1e-6);
            }
        }
    }

    /// xorshift64*, uniform in [0, 1).
    pub(super) struct Rng(pub u64);

    impl Rng {
        pub fn uniform(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
        }
        pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.uniform()
        }
        pub fn point(&mut self) -> Vector3<f64> {
            Vector3::new(self.range(-1.0, 1.0), self.range(-1.0, 1.0), self.range(-1.0, 1.0))
        }
    }

    /// A random core of `kind` (0 point, 1 segment, 2 triangle). One in eight is degenerate
    /// (zero length, collinear or coincident vertices), one in eight is made parallel to
    /// `other` (shifted copy of a feature), to exercise the special cases.
    fn random_core(rng: &mut Rng, kind: usize, other: Option<&Core<f64>>) -> Core<f64> {
        let special = rng.uniform();
        let a = rng.point();
        match kind {
            0 => Core::Point(a),
            1 => {
                let mut b = rng.point();
                if special < 0.125 {
                    b = a;
                } else if special < 0.25 {
                    if let Some(o) = other {
                        let (p, q) = match o {
                            Core::Segment([p, q]) => (*p, *q),
                            Core::Triangle([p, q, _]) => (*p, *q),
                            Core::Point(p) => (*p, *p + Vector3::x()),
                        };
                        let shift = rng.point() * 0.5;
                        let s = rng.range(-0.5, 1.0);
                        return Core::Segment([
                            p + shift + (q - p) * s,
                            p + shift + (q - p) * (s + rng.range(0.2, 1.5)),
                        ]);
                    }
                }
                Core::Segment([a, b])
            }
            _ => {
                let (b, mut c) = (rng.point(), rng.point());
                if special < 0.125 {
                    c = a + (b - a) * rng.range(-0.5, 1.5);
                } else if special < 0.25 {
                    if let Some(Core::Triangle(t)) = other {
                        let shift = rng.point() * 0.5;
                        return Core::Triangle(t.map(|p| p + shift));
                    }
                    if let Some(Core::Segment([p, q])) = other {
                        // A triangle whose plane contains a shifted copy of the segment direction.
                        let shift = rng.point() * 0.5;
                        return Core::Triangle([*p + shift, *q + shift, *p + shift + rng.point()]);
                    }
                }
                Core::Triangle([a, b, c])
            }
        }
    }

    /// Parameters of a core point: none, `s`, or barycentric `(u, v)`.
    fn point_at(core: &Core<f64>, u: f64, v: f64) -> Vector3<f64> {
        match core {
            Core::Point(p) => *p,
            Core::Segment([a, b]) => a + (b - a) * u,
            Core::Triangle([a, b, c]) => a + (b - a) * u + (c - a) * v,
        }
    }

    fn dimension(core: &Core<f64>) -> usize {
        match core {
            Core::Point(_) => 0,
            Core::Segment(_) => 1,
            Core::Triangle(_) => 2,
        }
    }

    /// Grid of parameters with spacing `h` around `center` (within `±reach·h`), clipped to
    /// the core's parameter domain.
    fn grid(core: &Core<f64>, center: (f64, f64), h: f64, reach: i32) -> Vec<(f64, f64)> {
        let steps = |c: f64| (-reach..=reach).map(move |k| c + f64::from(k) * h);
        match dimension(core) {
            0 => vec![(0.0, 0.0)],
            1 => steps(center.0).filter(|s| (0.0..=1.0).contains(s)).map(|s| (s, 0.0)).collect(),
            _ => steps(center.0)
                .flat_map(|u| steps(center.1).map(move |v| (u, v)))
                .filter(|&(u, v)| u >= 0.0 && v >= 0.0 && u + v <= 1.0 + 1e-12)
                .collect(),
        }
    }

    /// Brute-force reference: the smallest distance over a parameter grid of both cores
    /// (`n` cells per unit parameter), then eight grids zoomed by 4 around the best sample.
    fn sampled_distance(a: &Core<f64>, b: &Core<f64>, n: i32) -> f64 {
        let h = 1.0 / f64::from(n);
        let mut best = (f64::INFINITY, (0.0, 0.0), (0.0, 0.0));
        let search = |ga: &[(f64, f64)], gb: &[(f64, f64)], best: &mut (f64, (f64, f64), (f64, f64))| {
            let pb: Vec<_> = gb.iter().map(|&(u, v)| ((u, v), point_at(b, u, v))).collect();
            for &(u, v) in ga {
                let x = point_at(a, u, v);
                for (pv, y) in &pb {
                    let d = (y - x).norm();
                    if d < best.0 {
                        *best = (d, (u, v), *pv);
                    }
                }
            }
        };
        let (full_a, full_b) = (grid(a, (0.0, 0.0), h, n), grid(b, (0.0, 0.0), h, n));
        search(&full_a, &full_b, &mut best);
        let mut step = h;
        for _ in 0..8 {
            let reach = 4;
            let next = step / f64::from(reach);
            let (ga, gb) = (grid(a, best.1, next, 3 * reach), grid(b, best.2, next, 3 * reach));
            search(&ga, &gb, &mut best);
            step = next;
        }
        best.0
    }

    /// `true` if `x` lies on the core (within 1e-9 m): solves for its segment or barycentric
    /// parameters by least squares and checks the residual and the parameter domain.
    fn on_core(core: &Core<f64>, x: &Vector3<f64>) -> bool {
        let on_segment = |a: &Vector3<f64>, b: &Vector3<f64>| {
            let d = b - a;
            let s = if d.norm_squared() > 0.0 { (x - a).dot(&d) / d.norm_squared() } else { 0.0 };
            (-1e-9..=1.0 + 1e-9).contains(&s) && (a + d * s - x).norm() < 1e-9
        };
        match core {
            Core::Point(p) => (p - x).norm() < 1e-9,
            Core::Segment([a, b]) => on_segment(a, b),
            Core::Triangle([a, b, c]) => {
                let m = nalgebra::Matrix3x2::from_columns(&[b - a, c - a]);
                let normal = m.transpose() * m;
                if normal.determinant() > 1e-10 * normal.norm_squared() {
                    let uv = normal.try_inverse().unwrap() * m.transpose() * (x - a);
                    let inside = uv.x >= -1e-9 && uv.y >= -1e-9 && uv.x + uv.y <= 1.0 + 1e-9;
                    if inside && (a + m * uv - x).norm() < 1e-9 {
                        return true;
                    }
                }
                on_segment(a, b) || on_segment(b, c) || on_segment(c, a)
            }
        }
    }

    /// Largest distance from a point of the core to the nearest sample of its coarse grid
    /// with `n` cells per unit parameter.
    fn covering_radius(core: &Core<f64>, n: i32) -> f64 {
        let n = f64::from(n);
        match core {
            Core::Point(_) => 0.0,
            Core::Segment([a, b]) => (b - a).norm() / (2.0 * n),
            Core::Triangle([a, b, c]) => ((b - a).norm() + (c - a).norm()) / n,
        }
    }

    /// Optimality certificate of a closest pair `(p, q)` of convex polytopes: with
    /// `w = q − p`, every vertex `x` of `a` has `w·x ≤ w·p` and every vertex `y` of `b` has
    /// `w·y ≥ w·q`. Then `‖y − x‖ ≥ (y − x)·w/‖w‖ ≥ ‖w‖` for all `x ∈ a`, `y ∈ b`.
    fn certified(a: &Core<f64>, b: &Core<f64>, p: &Vector3<f64>, q: &Vector3<f64>) -> bool {
        let w = q - p;
        let tolerance = 1e-12 * (1.0 + w.norm());
        a.points().iter().all(|x| w.dot(&(x - p)) <= tolerance)
            && b.points().iter().all(|y| w.dot(&(y - q)) >= -tolerance)
    }

    #[test]
    fn core_distances_agree_with_brute_force_sampling() {
        let mut rng = Rng(0x5EED_0001);
        let mut worst = [0.0_f64; 6];
        let mut errors = Vec::new();
        let cases = [
            (0, 0, 1000, 1),
            (0, 1, 2000, 200),
            (1, 1, 2000, 100),
            (0, 2, 2000, 40),
            (1, 2, 1000, 60),
            (2, 2, 300, 24),
        ];
        for (case, &(ka, kb, count, n)) in cases.iter().enumerate() {
            for _ in 0..count {
                let a = random_core(&mut rng, ka, None);
                let b = random_core(&mut rng, kb, Some(&a));
                let (pa, pb) = closest_points(&a, &b);
                let (qb, qa) = closest_points(&b, &a);
                let analytic = (pb - pa).norm();
                // Symmetric in the arguments.
                assert!(((qa - qb).norm() - analytic).abs() < 1e-12, "{a:?} {b:?}");
                // The closest points lie on their cores and are certified optimal.
                assert!(on_core(&a, &pa) && on_core(&b, &pb), "{a:?} {b:?}");
                assert!(certified(&a, &b, &pa, &pb), "not optimal: {a:?} {b:?}");
                let sampled = sampled_distance(&a, &b, n);
                // The closed form is never worse than any sample, and the samples agree to
                // within the grid resolution.
                assert!(analytic <= sampled + 1e-12, "closed form {analytic} > sampled {sampled}: {a:?} {b:?}");
                let error = sampled - analytic;
                let bound = covering_radius(&a, n) + covering_radius(&b, n) + 1e-12;
                assert!(error <= bound, "sampled {sampled} vs {analytic} (bound {bound}): {a:?} {b:?}");
                worst[case] = worst[case].max(error);
                errors.push(error);
            }
        }
        errors.sort_by(f64::total_cmp);
        println!(
            "sampled − closed-form distance over {} pairs: median {:.1e} m, 99th percentile {:.1e} m; largest per case (pp, ps, ss, pt, st, tt): {:?}",
            errors.len(),
            errors[errors.len() / 2],
            errors[errors.len() * 99 / 100],
            worst.map(|w| format!("{w:.1e}"))
        );
    }

    #[test]
    fn parallel_and_degenerate_cases() {
        let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
        // Parallel overlapping segments: the midpoint of the overlap, distance 0.3.
        let (p, q) =
            closest_segment_segment(&v(0.0, 0.0, 0.0), &v(1.0, 0.0, 0.0), &v(0.5, 0.3, 0.0), &v(2.0, 0.3, 0.0));
        assert!((p - v(0.75, 0.0, 0.0)).norm() < 1e-15 && (q - v(0.75, 0.3, 0.0)).norm() < 1e-15);
        // Anti-parallel, disjoint along the line: nearest ends.
        let (p, q) =
            closest_segment_segment(&v(0.0, 0.0, 0.0), &v(1.0, 0.0, 0.0), &v(3.0, 0.3, 0.0), &v(1.5, 0.3, 0.0));
        assert!((p - v(1.0, 0.0, 0.0)).norm() < 1e-15 && (q - v(1.5, 0.3, 0.0)).norm() < 1e-15);
        // Collinear overlapping: distance 0.
        let (p, q) =
            closest_segment_segment(&v(0.0, 0.0, 0.0), &v(1.0, 0.0, 0.0), &v(0.5, 0.0, 0.0), &v(2.0, 0.0, 0.0));
        assert!((p - q).norm() < 1e-15);
        // Zero-length segments.
        let (p, q) =
            closest_segment_segment(&v(0.2, 1.0, 0.0), &v(0.2, 1.0, 0.0), &v(0.0, 0.0, 0.0), &v(1.0, 0.0, 0.0));
        assert!((p - v(0.2, 1.0, 0.0)).norm() < 1e-15 && (q - v(0.2, 0.0, 0.0)).norm() < 1e-15);
        let (p, q) =
            closest_segment_segment(&v(0.0, 0.0, 0.0), &v(0.0, 0.0, 0.0), &v(1.0, 1.0, 1.0), &v(1.0, 1.0, 1.0));
        assert_eq!((p, q), (v(0.0, 0.0, 0.0), v(1.0, 1.0, 1.0)));
        // Crossing segments.
        let (p, q) =
            closest_segment_segment(&v(-1.0, 0.0, 0.0), &v(1.0, 0.0, 0.0), &v(0.3, -1.0, 0.0), &v(0.3, 1.0, 0.0));
        assert!((p - v(0.3, 0.0, 0.0)).norm() < 1e-15 && (q - p).norm() < 1e-15);

        let tri = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)];
        // A segment piercing the triangle: the crossing point.
        let (p, q) = closest_segment_triangle(&v(0.2, 0.2, -1.0), &v(0.2, 0.2, 1.0), &tri);
        assert!((p - v(0.2, 0.2, 0.0)).norm() < 1e-15 && (q - p).norm() < 1e-15);
        // Coplanar segment inside: distance 0.
        let (p, q) = closest_segment_triangle(&v(0.1, 0.1, 0.0), &v(0.3, 0.2, 0.0), &tri);
        assert!((p - q).norm() < 1e-15);
        // Segment parallel above the interior: distance 0.5 (one of the equidistant pairs).
        let (p, q) = closest_segment_triangle(&v(0.1, 0.1, 0.5), &v(0.3, 0.2, 0.5), &tri);
        assert!(((p - q).norm() - 0.5).abs() < 1e-15);
        // Point above an edge's Voronoi region.
        assert!((closest_on_triangle(&v(0.5, -1.0, 2.0), &tri) - v(0.5, 0.0, 0.0)).norm() < 1e-15);
        // Degenerate (collinear) triangle behaves as its longest edge.
        let flat = [v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
        assert!((closest_on_triangle(&v(1.5, 1.0, 0.0), &flat) - v(1.5, 0.0, 0.0)).norm() < 1e-15);
        // Interpenetrating triangles: distance 0.
        let other = [v(0.2, 0.2, -0.5), v(0.3, 0.1, 0.5), v(0.9, 0.9, 0.5)];
        let (p, q) = closest_triangle_triangle(&tri, &other);
        assert!((p - q).norm() < 1e-14);
        // Parallel triangles above each other: the gap.
        let above = tri.map(|x| x + v(0.3, 0.3, 0.25));
        let (p, q) = closest_triangle_triangle(&tri, &above);
        assert!(((q - p).norm() - 0.25).abs() < 1e-15);
    }

    #[test]
    fn swept_sphere_distance_and_surface_points() {
        let a = SweptSphere::<f64>::sphere(Vector3::new(0.0, 0.0, 0.0), 0.1);
        let b = SweptSphere::swept_triangle(
            Vector3::new(-1.0, -1.0, 0.5),
            Vector3::new(2.0, -1.0, 0.5),
            Vector3::new(-1.0, 2.0, 0.5),
            0.2,
        );
        let p = proximity(&a, &b);
        assert!((p.distance - 0.2).abs() < 1e-15);
        let (xi, xj) = p.surface_points(0.1, 0.2).unwrap();
        assert!((xi - Vector3::new(0.0, 0.0, 0.1)).norm() < 1e-15 && (xj - Vector3::new(0.0, 0.0, 0.3)).norm() < 1e-15);
        assert!(b.signed_distance_to(&xj).abs() < 1e-15 && a.signed_distance_to(&xi).abs() < 1e-15);
        // Overlap: negative distance; concentric cores: no direction.
        let c = SweptSphere::<f64>::capsule(Vector3::new(0.0, 0.0, -1.0), Vector3::new(0.0, 0.0, 1.0), 0.05);
        let p = proximity(&a, &c);
        assert!((p.distance + 0.15).abs() < 1e-15 && p.direction.is_none() && p.surface_points(0.1, 0.05).is_none());
        // f32.
        let a32 = SweptSphere::<f32>::capsule(Vector3::new(-1.0, 0.0, 0.0), Vector3::new(1.0, 0.0, 0.0), 0.1);
        let b32 = SweptSphere::<f32>::sphere(Vector3::new(0.4, 0.0, 0.6), 0.1);
        assert!((proximity(&a32, &b32).distance - 0.4).abs() < 1e-6);
    }

    /// Under small rigid motions the distance vector `c_b − c_a` (hence `d` and `e`) moves at
    /// most twice as far as the fastest core point: it is the point of the convex Minkowski
    /// difference nearest to the origin, which is unique. The closest points themselves move
    /// by O(step) except where features are parallel; there they jump *together* (both by
    /// nearly the same vector) — checked by counting such slides and requiring they happen
    /// only in near-parallel configurations for segment pairs.
    #[test]
    fn distance_and_closest_points_are_continuous() {
        let mut rng = Rng(0xC0_471E);
        let mut slides = 0;
        for case in 0..600 {
            let (ka, kb) = [(1, 1), (1, 2), (2, 2), (0, 2), (0, 1)][case % 5];
            let a = random_core(&mut rng, ka, None);
            let b0 = random_core(&mut rng, kb, Some(&a));
            let axis = Unit::new_normalize(rng.point());
            let pivot = rng.point();
            let step = 1e-4;
            let moved = |k: f64| {
                let r = nalgebra::Rotation3::from_axis_angle(&axis, k * step);
                let placement = Placement::from_parts((pivot - r * pivot).into(), r);
                b0.transformed(&placement)
            };
            let mut previous = closest_points(&a, &b0);
            for k in 1..200 {
                let b = moved(f64::from(k));
                let current = closest_points(&a, &b);
                // Core points move at most |pivot - p| · step ≤ 2√3 · step.
                let bound = 2.0 * 2.0 * 3f64.sqrt() * step + 1e-12;
                let (dv0, dv1) = (previous.1 - previous.0, current.1 - current.0);
                assert!((dv1 - dv0).norm() <= bound, "distance vector jumped: {a:?} {b:?}");
                let jump = (current.0 - previous.0).norm().max((current.1 - previous.1).norm());
                if jump > 1e3 * step {
                    slides += 1;
                    if let (Core::Segment([p, q]), Core::Segment([r, s])) = (&a, &b) {
                        let sine = (q - p).normalize().cross(&(s - r).normalize()).norm();
                        assert!(sine < 0.05, "segments jumped while not parallel (sin {sine})");
                    }
                }
                previous = current;
            }
        }
        println!("closest-point slides along parallel features: {slides}");
    }
}
