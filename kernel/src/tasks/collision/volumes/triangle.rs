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
/// ([`triangle_normal`]), `‖n‖²`, the plane offset `n · v₀`, the in-plane edge normals
/// `m_k = n × e_k` that point into the triangle and their offsets `m_k · v_k` (zeros and one for
/// a degenerate triangle, which has no plane). A height or side test against the triangle is
/// then one dot product and a subtraction. The frame of a segment core holds only its start,
/// direction and squared length, as the first vertex and edge ([`Self::set_segment`]).
#[derive(Clone, Copy, Debug)]
pub(in crate::tasks::collision) struct TriangleFrame<T: RealField> {
    vertices: [Vector3<T>; 3],
    edges: [Vector3<T>; 3],
    edge_length2: [T; 3],
    planar: bool,
    normal: Vector3<T>,
    normal_length2: T,
    offset: T,
    edge_normals: [Vector3<T>; 3],
    edge_offsets: [T; 3],
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
            offset: T::zero(),
            edge_normals: [zero; 3],
            edge_offsets: [T::zero(); 3],
        }
    }

    /// The frame of the segment `[p, q]`: its start and first edge (`p`, `q − p`, `‖q − p‖²`,
    /// read by [`Self::first_edge`]); the rest as in `self` (unread for a segment core).
    #[inline]
    pub(in crate::tasks::collision) fn set_segment(&mut self, p: &Vector3<T>, q: &Vector3<T>) {
        let d = q - p;
        if let (Some(v), Some(e), Some(l)) =
            (self.vertices.first_mut(), self.edges.first_mut(), self.edge_length2.first_mut())
        {
            (*v, *e, *l) = (*p, d, d.norm_squared());
        }
    }

    /// The first vertex, the first edge `v₁ − v₀` and its squared length: of a segment core's
    /// frame ([`Self::set_segment`]), the segment's start, direction and squared length.
    #[inline]
    pub(super) fn first_edge(&self) -> (&Vector3<T>, &Vector3<T>, T) {
        let [v, ..] = &self.vertices;
        let [e, ..] = &self.edges;
        let [l, ..] = self.edge_length2;
        (v, e, l)
    }

    pub(super) fn new(t: &[Vector3<T>; 3]) -> Self {
        let [a, b, c] = t;
        let edges = [b - a, c - b, a - c];
        let edge_length2 = edges.each_ref().map(|e| e.norm_squared());
        match triangle_normal(t) {
            Some(normal) => {
                let edge_normals = edges.each_ref().map(|e| normal.cross(e));
                let [m0, m1, m2] = &edge_normals;
                Self {
                    vertices: *t,
                    edges,
                    edge_length2,
                    planar: true,
                    normal,
                    normal_length2: normal.norm_squared(),
                    offset: normal.dot(a),
                    edge_normals,
                    edge_offsets: [m0.dot(a), m1.dot(b), m2.dot(c)],
                }
            }
            None => Self {
                vertices: *t,
                edges,
                edge_length2,
                planar: false,
                normal: Vector3::zeros(),
                normal_length2: T::one(),
                offset: T::zero(),
                edge_normals: [Vector3::zeros(); 3],
                edge_offsets: [T::zero(); 3],
            },
        }
    }

    /// Signed height `n · p − n · v₀` of `p` above the plane (unnormalised; zero without a plane).
    #[inline]
    pub(super) fn height(&self, p: &Vector3<T>) -> T {
        self.normal.dot(p) - self.offset
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

    /// Bit `k` set if `x` lies on the inner side of edge `k`, `m_k · x ≥ m_k · v_k` with
    /// `m_k = n × e_k` (the triple products `n · (e_k × (x − v_k))` of the reference's test,
    /// regrouped):
    /// [`INSIDE`] (all three bits) if the projection of `x` onto the plane lies inside or on the
    /// triangle; no bit for a degenerate triangle.
    #[inline]
    fn sides(&self, x: &Vector3<T>) -> u8 {
        if !self.planar {
            return 0;
        }
        let [m0, m1, m2] = &self.edge_normals;
        let [o0, o1, o2] = self.edge_offsets;
        u8::from(m0.dot(x) >= o0) | u8::from(m1.dot(x) >= o1) << 1 | u8::from(m2.dot(x) >= o2) << 2
    }

    /// The projection of `x` (height `height`) onto the plane if `sides` (its [`Self::sides`])
    /// puts it inside or on the triangle.
    #[inline]
    fn projection(&self, x: &Vector3<T>, height: T, sides: u8) -> Option<Vector3<T>> {
        (sides == INSIDE).then(|| x - self.normal * (height / self.normal_length2))
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
        let mut bit = 1;
        for ((v, e), &length2) in self.vertices.iter().zip(&self.edges).zip(&self.edge_length2) {
            if sides & bit == 0 {
                nearest.offer(p, &closest_on_edge(p, v, e, length2));
            }
            bit <<= 1;
        }
        nearest.pair.1
    }

    /// The point where the segment `[p, q]` pierces the triangle, given the heights `dp`, `dq`
    /// of its ends, if it does: the sign test here, the crossing point in [`Self::crossing`].
    #[inline(always)]
    fn piercing(&self, p: &Vector3<T>, q: &Vector3<T>, dp: T, dq: T) -> Option<Vector3<T>> {
        let zero = T::zero();
        let crosses = (dp <= zero && dq >= zero) || (dp >= zero && dq <= zero);
        if self.planar && crosses && dp != dq {
            self.crossing(p, q, dp, dq)
        } else {
            None
        }
    }

    /// The point where the segment `[p, q]` with end heights `dp`, `dq` of opposite signs meets
    /// the plane, if it lies inside or on the triangle.
    #[inline(never)]
    fn crossing(&self, p: &Vector3<T>, q: &Vector3<T>, dp: T, dq: T) -> Option<Vector3<T>> {
        let x = p + (q - p) * (dp / (dp - dq));
        (self.sides(&x) == INSIDE).then_some(x)
    }
}

/// [`TriangleFrame::sides`] of a point whose projection lies inside or on the triangle.
const INSIDE: u8 = 0b111;

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
    let d = q - p;
    closest_segment_framed(p, q, &d, d.norm_squared(), &TriangleFrame::new(t))
}

/// `closest_segment_triangle` (its test entry point, which documents the method) against the
/// triangle of `frame`, with the segment's direction `d = q − p` and `a = ‖d‖²` given by the
/// caller (computed once per segment). Inlined into the pair loop.
#[inline(always)]
pub(super) fn closest_segment_framed<T: RealField + Copy>(
    p: &Vector3<T>,
    q: &Vector3<T>,
    d: &Vector3<T>,
    a: T,
    frame: &TriangleFrame<T>,
) -> (Vector3<T>, Vector3<T>) {
    let (hp, hq) = (frame.height(p), frame.height(q));
    if let Some(x) = frame.piercing(p, q, hp, hq) {
        return (x, x);
    }
    let (sp, sq) = (frame.sides(p), frame.sides(q));
    let mut nearest = Nearest::new();
    if let Some(y) = frame.projection(p, hp, sp) {
        nearest.offer(p, &y);
    }
    if let Some(y) = frame.projection(q, hq, sq) {
        nearest.offer(q, &y);
    }
    if nearest.excludes(frame.clearance(hp, hq)) {
        return nearest.pair;
    }
    // Bit k: both ends lie on the inner side of edge k (then edge k is skipped).
    let inner = sp & sq;
    let mut bit = 1;
    for ((v, e), &length2) in frame.vertices.iter().zip(&frame.edges).zip(&frame.edge_length2) {
        if inner & bit == 0 {
            let (x, y) = closest_edge_edge(p, d, a, v, e, length2);
            nearest.offer(&x, &y);
        }
        bit <<= 1;
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

/// `closest_triangle_triangle` (its test entry point, which documents the method) of the
/// triangles of the frames `fs` and `ft`. Out of line: the longest of the pair tests, kept out
/// of the per-pair loop that calls it.
#[inline(never)]
pub(super) fn closest_triangles_framed<T: RealField + Copy>(
    fs: &TriangleFrame<T>,
    ft: &TriangleFrame<T>,
) -> (Vector3<T>, Vector3<T>) {
    let (s, t) = (&fs.vertices, &ft.vertices);
    let hs = s.each_ref().map(|v| ft.height(v));
    let ht = t.each_ref().map(|v| fs.height(v));
    let ([a, b, c], [d, e, f]) = (s, t);
    let ([ha, hb, hc], [hd, he, hf]) = (hs, ht);
    // An edge pierces the other triangle only if its ends are not strictly on one side of that
    // triangle's plane: with all three vertices on one side, none of the three does.
    if straddles(hs) {
        for (p, q, hp, hq) in [(a, b, ha, hb), (b, c, hb, hc), (c, a, hc, ha)] {
            if let Some(x) = ft.piercing(p, q, hp, hq) {
                return (x, x);
            }
        }
    }
    if straddles(ht) {
        for (p, q, hp, hq) in [(d, e, hd, he), (e, f, he, hf), (f, d, hf, hd)] {
            if let Some(x) = fs.piercing(p, q, hp, hq) {
                return (x, x);
            }
        }
    }
    let ss = s.each_ref().map(|v| ft.sides(v));
    let st = t.each_ref().map(|v| fs.sides(v));
    let mut nearest = Nearest::new();
    for ((v, &h), &side) in s.iter().zip(&hs).zip(&ss) {
        if let Some(y) = ft.projection(v, h, side) {
            nearest.offer(v, &y);
        }
    }
    for ((v, &h), &side) in t.iter().zip(&ht).zip(&st) {
        if let Some(x) = fs.projection(v, h, side) {
            nearest.offer(&x, v);
        }
    }
    // Bit k of `inner_s[j]`: both ends of edge j of s lie on the inner side of edge k of t; bit
    // j of `inner_t[k]`: both ends of edge k of t on the inner side of edge j of s. The pair
    // (j, k) is tested unless both hold, or a plane clearance rules out either edge.
    let ([sa, sb, sc], [sd, se, sf]) = (ss, st);
    let inner_s = [sa & sb, sb & sc, sc & sa];
    let inner_t = [sd & se, se & sf, sf & sd];
    let ([is0, is1, is2], [it0, it1, it2]) = (inner_s, inner_t);
    let ([cs0, cs1, cs2], [ct0, ct1, ct2]) = (
        [ft.clearance(ha, hb), ft.clearance(hb, hc), ft.clearance(hc, ha)],
        [fs.clearance(hd, he), fs.clearance(he, hf), fs.clearance(hf, hd)],
    );
    let ([es0, es1, es2], [ls0, ls1, ls2]) = (&fs.edges, fs.edge_length2);
    let ([et0, et1, et2], [lt0, lt1, lt2]) = (&ft.edges, ft.edge_length2);
    // Each edge with its start, squared length, inner mask, clearance and bit.
    let edges_s = [(a, es0, ls0, is0, cs0, 1u8), (b, es1, ls1, is1, cs1, 2), (c, es2, ls2, is2, cs2, 4)];
    let edges_t = [(d, et0, lt0, it0, ct0, 1u8), (e, et1, lt1, it1, ct1, 2), (f, et2, lt2, it2, ct2, 4)];
    for &(p, edge, length2, inner_j, bound_s, bit_j) in &edges_s {
        if nearest.excludes(bound_s) {
            continue;
        }
        for &(v, other, other2, inner_k, bound_t, bit_k) in &edges_t {
            if (inner_j & bit_k == 0 || inner_k & bit_j == 0) && !nearest.excludes(bound_t) {
                let (x, y) = closest_edge_edge(p, edge, length2, v, other, other2);
                nearest.offer(&x, &y);
            }
        }
    }
    nearest.pair
}

/// `false` if the heights are all strictly positive or all strictly negative (the points lie
/// strictly on one side of a plane).
#[inline]
fn straddles<T: RealField + Copy>([h0, h1, h2]: [T; 3]) -> bool {
    let zero = T::zero();
    !((h0 > zero && h1 > zero && h2 > zero) || (h0 < zero && h1 < zero && h2 < zero))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::indexing_slicing, reason = "tests")]
    use nalgebra::{convert, convert_unchecked, RealField, Vector3};

    use super::super::tests::Rng;
    use super::TriangleFrame;

    /// The height `n · p − n · v₀` and the sides `m_k · x ≥ m_k · v_k` (offsets stored in the
    /// frame) against the vertex-relative forms `n · (p − v₀)` and `m_k · (x − v_k) ≥ 0`, on random
    /// triangles at up to `reach` m from the origin and points near them (in the plane, on an
    /// edge's line, on a vertex, off the plane): the heights agree to `tol · ‖n‖ (‖p‖ + ‖v₀‖)`,
    /// and a side bit differs only where the vertex-relative product is within that rounding
    /// of zero. Returns (bits compared, bits that differ).
    fn offsets_match_the_vertex_relative_forms<T: RealField + Copy>(reach: f64, tol: f64) -> (usize, usize) {
        let mut rng = Rng(0x0FF5_E7A5 ^ reach.to_bits());
        let cast = |p: Vector3<f64>| p.map(|x| convert::<f64, T>(x));
        let (mut compared, mut differ) = (0, 0);
        for case in 0..20_000 {
            let center = rng.point() * reach;
            let t = [rng.point(), rng.point(), rng.point()].map(|v| cast(center + v));
            let frame = TriangleFrame::new(&t);
            if !frame.planar {
                continue;
            }
            let (u, w) = (convert::<f64, T>(rng.uniform()), convert::<f64, T>(rng.range(-0.5, 1.5)));
            let x = match case % 4 {
                0 => t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * (w * (T::one() - u)),
                1 => t[1] + (t[2] - t[1]) * w,
                2 => t[2],
                _ => t[0] + cast(rng.point()),
            };
            let size = |v: &Vector3<T>| convert_unchecked::<T, f64>(v.norm());
            let scale = tol * size(&frame.normal) * (size(&x) + size(&t[0]) + size(&(x - t[0])));
            let plain = convert_unchecked::<T, f64>(frame.normal.dot(&(x - t[0])));
            assert!((convert_unchecked::<T, f64>(frame.height(&x)) - plain).abs() <= scale, "height: {t:?} {x:?}");
            let sides = frame.sides(&x);
            for (k, (m, v)) in frame.edge_normals.iter().zip(&t).enumerate() {
                let product = convert_unchecked::<T, f64>(m.dot(&(x - v)));
                let bound = tol * size(m) * (size(&x) + size(v) + size(&(x - v)));
                compared += 1;
                if (sides >> k & 1 == 1) != (product >= 0.0) {
                    differ += 1;
                    assert!(product.abs() <= bound, "side {k}: {product} beyond {bound}: {t:?} {x:?}");
                }
            }
        }
        (compared, differ)
    }

    #[test]
    fn offsets_match_the_vertex_relative_forms_f64() {
        for reach in [0.0, 2.0, 100.0] {
            let (compared, differ) = offsets_match_the_vertex_relative_forms::<f64>(reach, 1e-14);
            assert!(compared > 40_000 && differ * 4 < compared, "{compared} {differ}");
        }
    }

    #[test]
    fn offsets_match_the_vertex_relative_forms_f32() {
        for reach in [0.0, 2.0, 100.0] {
            let (compared, differ) = offsets_match_the_vertex_relative_forms::<f32>(reach, 1e-5);
            assert!(compared > 40_000 && differ * 4 < compared, "{compared} {differ}");
        }
    }
}
