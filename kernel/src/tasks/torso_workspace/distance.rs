//! Signed Euclidean distance from the torso centre point to one boundary curve of the
//! workspace (a circular arc or a straight line), with its gradient.
//!
//! Arcs are segments, not full circles: the full circle of a boundary arc can cross the inside
//! of the workspace (e.g. the circle of arc 6, `q_t2 + q_t3 = 0`, also carries the points with
//! `q_t2 = 0` when `l_t2 = l_t3`), so the distance is the one to the nearest point of the arc:
//! radial inside the arc's angular sector, to the nearer end point outside it. Both pieces
//! meet with equal value and gradient on the sector's edge rays (the distance is C¹).

use nalgebra::{RealField, Vector2};

use super::kinematics::{direction, Arc};
use crate::math::sqrt;

/// A boundary arc prepared for distance queries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ArcBoundary<T> {
    /// The arc.
    pub arc: Arc<T>,
    /// `e(θ_mid)`, the direction of the middle of the arc from its centre.
    mid: Vector2<T>,
    /// Cosine of half the arc's angle.
    cos_half: T,
    /// End points at `start` and `end`.
    ends: [Vector2<T>; 2],
    /// `true` if the feasible side is the inside of the circle.
    feasible_inside: bool,
}

impl<T: RealField + Copy> ArcBoundary<T> {
    /// Prepares `arc`; `feasible_inside` says on which side of the circle the allowed region
    /// lies (near the arc).
    pub fn new(arc: Arc<T>, feasible_inside: bool) -> Self {
        let half: T = (arc.end - arc.start) * nalgebra::convert::<f64, T>(0.5);
        Self {
            arc,
            mid: direction(arc.start + half),
            cos_half: half.cos(),
            ends: [arc.point(arc.start), arc.point(arc.end)],
            feasible_inside,
        }
    }

    /// Signed distance `d` (m; positive on the feasible side) from `p` to the arc, and
    /// `∂d/∂p`.
    ///
    /// In the arc's sector `d = ±(r − ρ)`, `ρ = |p − c|`, positive on the feasible side of the
    /// circle. Outside it `d = ±|p − p_end|` for the nearer end point. The sign is the verdict
    /// `feasible` of the joint-space side of the limit, which the radial side cannot tell far
    /// from the arc or where the joint map folds.
    /// `tiny` (m) guards the directions: at the centre or exactly on an end point the radial
    /// formula is used.
    pub fn signed_distance(&self, p: &Vector2<T>, feasible: bool, tiny: T) -> (T, Vector2<T>) {
        let v = p - self.arc.center;
        let rho = sqrt(v.norm_squared());
        let sign = if self.feasible_inside { T::one() } else { -T::one() };
        let radial = |rho: T| {
            let unit = if rho > tiny { v / rho } else { self.mid };
            (sign * (self.arc.radius - rho), -unit * sign)
        };
        if rho > tiny && v.dot(&self.mid) >= rho * self.cos_half {
            // The radial side agrees with the joint-space verdict except where the joint map
            // folds onto itself: `q_t3 < 0` lands on the same points as `q_t3 > 0` (arc 5).
            // There the joint verdict wins; the distance stays continuous through 0.
            let (d, g) = radial(rho);
            return if feasible == (d >= T::zero()) || d.abs() <= tiny { (d, g) } else { (-d, -g) };
        }
        let [a, b] = self.ends;
        let (wa, wb) = (p - a, p - b);
        let w = if wa.norm_squared() <= wb.norm_squared() { wa } else { wb };
        let dist = sqrt(w.norm_squared());
        if dist <= tiny {
            return radial(rho);
        }
        let side = if feasible { T::one() } else { -T::one() };
        (side * dist, w * (side / dist))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;

    /// Brute-force distance to a densely sampled arc.
    fn brute(arc: &Arc<f64>, p: &Vector2<f64>) -> f64 {
        (0..=200_000)
            .map(|k| (arc.point(arc.start + (arc.end - arc.start) * f64::from(k) / 200_000.0) - p).norm())
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn distance_matches_brute_force_and_gradient_matches_finite_differences() {
        let arc = Arc { center: Vector2::new(0.1, -0.2), radius: 0.3, start: -0.4, end: 1.9 };
        let boundary = ArcBoundary::new(arc, true);
        let mut state = 7_u64;
        let mut uniform = || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1_u64 << 53) as f64
        };
        for _ in 0..300 {
            let p = Vector2::new(uniform() - 0.4, uniform() - 0.7);
            let inside = (p - arc.center).norm() < arc.radius;
            let (d, grad) = boundary.signed_distance(&p, inside, 1e-12);
            assert!((d.abs() - brute(&arc, &p)).abs() < 2e-6, "{p:?}");
            let h = 1e-7;
            let fd = Vector2::new(
                boundary.signed_distance(&(p + Vector2::x() * h), inside, 1e-12).0
                    - boundary.signed_distance(&(p - Vector2::x() * h), inside, 1e-12).0,
                boundary.signed_distance(&(p + Vector2::y() * h), inside, 1e-12).0
                    - boundary.signed_distance(&(p - Vector2::y() * h), inside, 1e-12).0,
            ) / (2.0 * h);
            assert!((fd - grad).amax() < 1e-6, "{p:?}: {fd:?} vs {grad:?}");
            assert!((grad.norm() - 1.0).abs() < 1e-12);
        }
        // Exactly at the centre and at an end point: finite.
        let (d, g) = boundary.signed_distance(&arc.center, true, 1e-12);
        assert!((d - 0.3).abs() < 1e-15 && g.iter().all(|x| x.is_finite()));
        let (d, g) = boundary.signed_distance(&arc.point(arc.end), true, 1e-12);
        assert!(d.abs() < 1e-15 && (g.norm() - 1.0).abs() < 1e-12);
    }
}
