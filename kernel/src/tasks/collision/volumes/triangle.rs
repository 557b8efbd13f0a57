//! Triangle cores (Sec. 3.1.1): the per-triangle quantities every test against a triangle
//! shares ([`TriangleFrame`]), and the closest points of a point, a segment or a triangle and a
//! triangle (see the table of [`super`]).

use nalgebra::{RealField, Vector3};

use super::segment::{closest_edge_edge, closest_on_edge, negligible};
use crate::math::sqrt;

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
pub(in crate::tasks::collision) struct TriangleFrame<T: RealField> {
    vertices: [Vector3<T>; 3],
    edges: [Vector3<T>; 3],
    edge_length2: [T; 3],
    planar: bool,
    normal: Vector3<T>,
    normal_length2: T,
    edge_normals: [Vector3<T>; 3],
}

impl<T: RealField + Copy> TriangleFrame<T> {
    /// The frame of the degenerate triangle at the origin.
    pub(in crate::tasks::collision) fn placeholder() -> Self {
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

    pub(super) fn new(t: &[Vector3<T>; 3]) -> Self {
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
    pub(super) fn height(&self, p: &Vector3<T>) -> T {
        let [a, _, _] = &self.vertices;
        self.normal.dot(&(p - a))
    }

    /// Broad phase against the triangle's plane: every point within `radius` of the triangle
    /// lies in the slab `|n̂ · (x − v₀)| ≤ radius`, every point of the ball `(center,
    /// ball_radius)` at least `|n̂ · (center − v₀)| − ball_radius` from the plane, so the
    /// difference is a lower bound of their distance. `Some(that bound)` if it exceeds `limit`
    /// (squared test first: one root and one division only then); `None` otherwise and without
    /// a plane.
    pub(in crate::tasks::collision) fn slab_gap(
        &self,
        radius: T,
        center: &Vector3<T>,
        ball_radius: T,
        limit: T,
    ) -> Option<T> {
        let reach = limit + radius + ball_radius;
        if !self.planar || reach <= T::zero() {
            return None;
        }
        let h = self.height(center);
        if h * h <= reach * reach * self.normal_length2 {
            return None;
        }
        let gap = h.abs() / sqrt(self.normal_length2) - radius - ball_radius;
        (gap > limit).then_some(gap)
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
    pub(super) fn closest_point(&self, p: &Vector3<T>, height: T) -> Vector3<T> {
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
pub(super) fn closest_on_triangle<T: RealField + Copy>(p: &Vector3<T>, t: &[Vector3<T>; 3]) -> Vector3<T> {
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
pub(super) fn closest_segment_triangle<T: RealField + Copy>(
    p: &Vector3<T>,
    q: &Vector3<T>,
    t: &[Vector3<T>; 3],
) -> (Vector3<T>, Vector3<T>) {
    closest_segment_framed(p, q, &TriangleFrame::new(t))
}

/// [`closest_segment_triangle`] against the triangle of `frame`.
pub(super) fn closest_segment_framed<T: RealField + Copy>(
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
pub(super) fn closest_triangle_triangle<T: RealField + Copy>(
    s: &[Vector3<T>; 3],
    t: &[Vector3<T>; 3],
) -> (Vector3<T>, Vector3<T>) {
    closest_triangles_framed(&TriangleFrame::new(s), &TriangleFrame::new(t))
}

/// [`closest_triangle_triangle`] of the triangles of the frames `fs` and `ft`.
pub(super) fn closest_triangles_framed<T: RealField + Copy>(
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
