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

mod segment;
mod triangle;

#[cfg(test)]
use segment::closest_segment_segment;
use segment::{closest_edge_edge_inline, closest_on_edge, closest_on_segment};
pub(super) use triangle::TriangleFrame;
use triangle::{closest_on_triangle, closest_segment_framed, closest_triangles_framed};
#[cfg(test)]
use triangle::{closest_segment_triangle, closest_triangle_triangle};

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
    /// The frame of the core: a triangle's [`TriangleFrame`], a segment's start and direction
    /// ([`TriangleFrame::set_segment`] on the placeholder), a point's
    /// [`TriangleFrame::placeholder`] (never read).
    #[inline]
    pub(in crate::tasks::collision) fn triangle_frame(&self) -> TriangleFrame<T> {
        let mut frame = match self {
            Self::Triangle(t) => return TriangleFrame::new(t),
            _ => TriangleFrame::placeholder(),
        };
        self.update_frame(&mut frame);
        frame
    }

    /// Writes the core's part of `frame` ([`Self::triangle_frame`]): all of it for a triangle,
    /// the start and direction for a segment, nothing for a point.
    #[inline]
    pub(in crate::tasks::collision) fn update_frame(&self, frame: &mut TriangleFrame<T>) {
        match self {
            Self::Triangle(t) => *frame = TriangleFrame::new(t),
            Self::Segment([p, q]) => frame.set_segment(p, q),
            Self::Point(_) => {}
        }
    }

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
    let (fa, fb) = (a.core.triangle_frame(), b.core.triangle_frame());
    proximity_framed(a, &fa, b, &fb)
}

/// [`proximity`] with the triangle frames of both cores given ([`Core::triangle_frame`], computed
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
    // One reciprocal for the three components (3.5).
    let direction = if core_distance > direction_threshold() {
        Some(Unit::new_unchecked(delta * (T::one() / core_distance)))
    } else {
        None
    };
    Proximity { distance: core_distance - a.radius - b.radius, core_first, core_second, direction }
}

/// Closest points `(on a, on b)` of two cores in the same frame. Cost: bounded per kind, at most six
/// piercing tests, six vertex projections and nine edge–edge tests (triangle–triangle).
pub fn closest_points<T: RealField + Copy>(a: &Core<T>, b: &Core<T>) -> (Vector3<T>, Vector3<T>) {
    closest_points_framed(a, &a.triangle_frame(), b, &b.triangle_frame())
}

/// [`closest_points`] with the cores' frames `fa`, `fb` ([`Core::triangle_frame`]; read for a
/// triangle or a segment core): the same operations as from the cores alone.
fn closest_points_framed<T: RealField + Copy>(
    a: &Core<T>,
    fa: &TriangleFrame<T>,
    b: &Core<T>,
    fb: &TriangleFrame<T>,
) -> (Vector3<T>, Vector3<T>) {
    let swap = |(x, y): (Vector3<T>, Vector3<T>)| (y, x);
    match (a, b) {
        (Core::Point(p), Core::Point(q)) => (*p, *q),
        (Core::Point(p), Core::Segment(_)) => (*p, on_segment(p, fb)),
        (Core::Segment(_), Core::Point(p)) => (on_segment(p, fa), *p),
        (Core::Point(p), Core::Triangle(_)) => (*p, fb.closest_point(p, fb.height(p))),
        (Core::Triangle(_), Core::Point(p)) => (fa.closest_point(p, fa.height(p)), *p),
        (Core::Segment(_), Core::Segment(_)) => {
            let ((p1, d1, a1), (p2, d2, a2)) = (fa.first_edge(), fb.first_edge());
            closest_edge_edge_inline(p1, d1, a1, p2, d2, a2)
        }
        (Core::Segment([p, q]), Core::Triangle(_)) => {
            let (_, d, a) = fa.first_edge();
            closest_segment_framed(p, q, d, a, fb)
        }
        (Core::Triangle(_), Core::Segment([p, q])) => {
            let (_, d, a) = fb.first_edge();
            swap(closest_segment_framed(p, q, d, a, fa))
        }
        (Core::Triangle(_), Core::Triangle(_)) => closest_triangles_framed(fa, fb),
    }
}

/// Closest point to `p` on the segment of the frame `f` ([`TriangleFrame::set_segment`]).
#[inline]
fn on_segment<T: RealField + Copy>(p: &Vector3<T>, f: &TriangleFrame<T>) -> Vector3<T> {
    let (a, d, length2) = f.first_edge();
    closest_on_edge(p, a, d, length2)
}

#[cfg(test)]
mod reference;

#[cfg(test)]
mod pruning_tests;

#[cfg(test)]
mod tests;
