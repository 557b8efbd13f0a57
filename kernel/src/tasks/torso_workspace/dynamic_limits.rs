//! Load-dependent dynamic limits of the torso workspace (Sec. 3.3.3, (3.44)–(3.52), App. A.2):
//! the torques a load at the torso centre point needs, and the boundaries in the torso plane
//! where they reach the actuator limits.
//!
//! - Joint 2 (3.48): `τ_t2 / F_t,load = −x sin α − z cos α = −e(α)·p_t`, so each torque limit is
//!   a straight line with normal `e(α)`, parallel to the load direction.
//! - Joint 3 (3.49): `τ_t3 = −F_t,load l_t3 cos(q_t2 + q_t3 − α)` depends on the angle sum
//!   only; a torque limit `τ` is reached at `q_t2 + q_t3 = α ± arccos(−τ / (F_t,load l_t3))`,
//!   half circles of radius `l_t2` around `l_t3 e(α ± arccos(…))` in the torso plane
//!   ((3.50)–(3.52), Table A.2). Each limit excludes a band of angle sums between its two
//!   circles; it exists only if `F_t,load l_t3 > |τ|`.

use nalgebra::{RealField, Vector2};

use super::kinematics::{direction, Range, TorsoGeometry};
use crate::tasks::TaskError;

/// The load at the torso centre point (3.44): `F_t = F_t,load (cos α, −sin α)` in the torso
/// plane. `α = 90°` is a vertical, downward load (weight).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TorsoLoad<T> {
    /// Magnitude `F_t,load ≥ 0` (N).
    pub force: T,
    /// Direction `α` (rad), about the Y axis.
    pub angle: T,
}

impl<T: RealField + Copy> TorsoLoad<T> {
    /// A load of `force` N at `angle_deg` degrees.
    pub fn from_degrees(force: f64, angle_deg: f64) -> Self {
        Self { force: nalgebra::convert(force), angle: nalgebra::convert(angle_deg.to_radians()) }
    }

    /// The force vector `F_t = F_t,load (cos α, −sin α)` (N) of (3.44).
    #[inline]
    pub fn vector(&self) -> Vector2<T> {
        let (s, c) = self.angle.sin_cos();
        Vector2::new(c, -s) * self.force
    }

    /// Finite `F_t,load ≥ 0` and finite `α`.
    pub fn validate(&self) -> Result<(), TaskError> {
        if !(self.force.is_finite() && self.force >= T::zero() && self.angle.is_finite()) {
            return Err(TaskError::InvalidParameter { name: "load" });
        }
        Ok(())
    }
}

/// Actuator torque ranges of the two driven pitch joints ((3.46), (3.47)), Nm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TorqueLimits<T> {
    /// `[τ_t2,min, τ_t2,max]` (Nm).
    pub joint2: Range<T>,
    /// `[τ_t3,min, τ_t3,max]` (Nm).
    pub joint3: Range<T>,
}

impl<T: RealField + Copy> TorqueLimits<T> {
    /// `±limit` Nm on both joints (Fig. 3.16: ±230 Nm; experiment 3.3.5: ±140 Nm).
    pub fn symmetric(limit: f64) -> Self {
        let l: T = nalgebra::convert(limit);
        Self { joint2: Range::new(-l, l), joint3: Range::new(-l, l) }
    }

    /// `true` if both torques are within their ranges.
    #[inline]
    pub fn contains(&self, torque: &Vector2<T>) -> bool {
        self.joint2.contains(torque.x) && self.joint3.contains(torque.y)
    }

    /// Finite limits with `τ_min < 0 < τ_max` (holding no load must be feasible).
    pub fn validate(&self) -> Result<(), TaskError> {
        let ok = |r: &Range<T>| r.is_proper() && r.min < T::zero() && r.max > T::zero();
        if !(ok(&self.joint2) && ok(&self.joint3)) {
            return Err(TaskError::InvalidParameter { name: "torque limits" });
        }
        Ok(())
    }
}

/// The motor torques `τ_t = −J_tᵀ F_t` (Nm) that hold the load at the torso centre point,
/// (3.45): `τ_t2 = −F (l_t3 cos(q_t2 + q_t3 − α) + l_t2 cos(q_t2 − α))`,
/// `τ_t3 = −F l_t3 cos(q_t2 + q_t3 − α)`.
///
/// ```
/// use kernel::tasks::torso_workspace::{load_torque, TorsoGeometry, TorsoLoad};
/// // Torso leaning forward horizontally (q_t2 = 90°, q_t3 = 0) under 800 N of weight:
/// // both links are lever arms, τ_t2 = −800·0.6 = −480 Nm, τ_t3 = −800·0.3 = −240 Nm.
/// let geometry = TorsoGeometry::<f64>::from_degrees([0.3, 0.3], [-90.0, 90.0], [0.0, 135.0], [0.0, 135.0]);
/// let tau = load_torque(&geometry, &TorsoLoad::from_degrees(800.0, 90.0), core::f64::consts::FRAC_PI_2, 0.0);
/// assert!((tau.x + 480.0).abs() < 1e-9 && (tau.y + 240.0).abs() < 1e-9);
/// ```
#[inline]
pub fn load_torque<T: RealField + Copy>(geometry: &TorsoGeometry<T>, load: &TorsoLoad<T>, q2: T, q3: T) -> Vector2<T> {
    -geometry.jacobian(q2, q3).transpose() * load.vector()
}

/// A joint-2 torque limit as a line (3.48): the points with `normal·p + offset = 0`, feasible
/// where `normal·p + offset ≥ 0`; `normal` is a unit vector, so the left side is the signed
/// distance (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TorqueLine<T> {
    /// Unit normal, pointing to the feasible side.
    pub normal: Vector2<T>,
    /// Offset (m).
    pub offset: T,
}

/// The joint-2 lines for `τ_t2,min` and `τ_t2,max`, in that order: `τ_t2 ≥ τ_min ⟺
/// −e(α)·p − τ_min/F ≥ 0` and `τ_t2 ≤ τ_max ⟺ e(α)·p + τ_max/F ≥ 0`. `None` without load.
pub fn joint2_lines<T: RealField + Copy>(load: &TorsoLoad<T>, limits: &Range<T>) -> Option<[TorqueLine<T>; 2]> {
    if load.force <= T::zero() {
        return None;
    }
    let n = direction(load.angle);
    Some([
        TorqueLine { normal: -n, offset: -limits.min / load.force },
        TorqueLine { normal: n, offset: limits.max / load.force },
    ])
}

/// One joint-3 torque limit `τ` as an excluded band of angle sums `q_t2 + q_t3` (3.49):
/// the sums with `|q_t2 + q_t3 − center| < half_width` (mod 2π) need a torque beyond `τ`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TorqueBand<T> {
    /// Middle of the band (rad): `α` for `τ_min < 0`, `α + π` for `τ_max > 0`.
    pub center: T,
    /// Half width (rad), in `(0, π/2)`.
    pub half_width: T,
}

impl<T: RealField + Copy> TorqueBand<T> {
    /// The band of torque limit `limit` (Nm, nonzero) under `load`, or `None` if the limit can
    /// hold the load everywhere (`F_t,load l_t3 ≤ |τ|`, (3.49) has no solution, Fig. 3.16d).
    ///
    /// `τ_t3 = −F l_t3 cos ψ`, `ψ = q_t2 + q_t3 − α`. For `τ_min < 0`: `τ_t3 < τ_min ⟺
    /// cos ψ > −τ_min/(F l_t3)`, a band around `ψ = 0` of half width `arccos(−τ_min/(F l_t3))`.
    /// For `τ_max > 0`: `τ_t3 > τ_max ⟺ cos ψ < −τ_max/(F l_t3)`, a band around `ψ = π` of half
    /// width `arccos(τ_max/(F l_t3))`.
    pub fn new(link3: T, load: &TorsoLoad<T>, limit: T) -> Option<Self> {
        let capacity = load.force * link3;
        // NaN-safe: only a capacity strictly above the limit gives a band.
        if capacity.partial_cmp(&limit.abs()) != Some(core::cmp::Ordering::Greater) {
            return None;
        }
        let ratio = limit.abs() / capacity;
        let center = if limit < T::zero() { load.angle } else { load.angle + T::pi() };
        Some(Self { center, half_width: ratio.acos() })
    }

    /// The two boundary sums `center ∓ half_width` (rad), lower first. They are the two
    /// solutions `α ± arccos(−τ/(F l_t3))` of (3.49) up to multiples of 2π.
    #[inline]
    pub fn boundaries(&self) -> [T; 2] {
        [self.center - self.half_width, self.center + self.half_width]
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::tasks::torso_workspace::tests::test_geometry;

    #[test]
    fn joint2_lines_are_where_the_joint2_torque_hits_its_limits() {
        let g = test_geometry::<f64>();
        for (force, angle) in [(800.0, 90.0), (800.0, 70.0), (1200.0, 90.0), (550.0, 20.0)] {
            let load = TorsoLoad::from_degrees(force, angle);
            let limits = TorqueLimits::symmetric(230.0);
            let lines = joint2_lines(&load, &limits.joint2).unwrap();
            for (q2, q3) in [(0.3, 0.4), (-1.2, 2.0), (1.5, 0.1), (0.9, 0.6)] {
                let p = g.center(q2, q3);
                let tau2 = load_torque(&g, &load, q2, q3).x;
                // (3.48): τ_t2 / F = −x sin α − z cos α.
                let a = load.angle;
                assert!((tau2 / force + p.x * a.sin() + p.y * a.cos()).abs() < 1e-12);
                // signed distances = torque margins / F.
                assert!((lines[0].normal.dot(&p) + lines[0].offset - (tau2 + 230.0) / force).abs() < 1e-12);
                assert!((lines[1].normal.dot(&p) + lines[1].offset - (230.0 - tau2) / force).abs() < 1e-12);
            }
            // The lines are parallel to the load direction (Sec. 3.3.3).
            assert!(lines[0].normal.dot(&load.vector()).abs() < 1e-9);
        }
        assert!(joint2_lines(&TorsoLoad::<f64>::from_degrees(0.0, 90.0), &Range::new(-1.0, 1.0)).is_none());
    }

    /// Points on the joint-3 circles need exactly the limit torque (Table A.2, (3.49)–(3.52)).
    #[test]
    fn joint3_bands_have_the_limit_torque_on_their_circles() {
        let g = test_geometry::<f64>();
        let load = TorsoLoad::from_degrees(1200.0, 80.0);
        for limit in [-230.0, 230.0] {
            let band = TorqueBand::new(g.link3, &load, limit).unwrap();
            for phi in band.boundaries() {
                // the circle of (3.51)/(3.52) for this sum, parametrised by q2.
                let center = direction(phi) * g.link3;
                for q2 in [-2.0, -1.0, 0.0, 0.5] {
                    let q3 = phi - q2;
                    let p = g.center(q2, q3);
                    assert!(((p - center).norm() - g.link2).abs() < 1e-12);
                    assert!((load_torque(&g, &load, q2, q3).y - limit).abs() < 1e-9, "{limit} {phi}");
                }
                // Table A.2: φ = α ± arccos(−τ/(F l_t3)) modulo 2π.
                let acos = (-limit / (1200.0 * 0.3_f64)).acos();
                let matches = [load.angle + acos, load.angle - acos].iter().any(|s| {
                    let d = super::super::kinematics::wrap_to_pi(s - phi);
                    d.abs() < 1e-12
                });
                assert!(matches, "{limit} {phi}");
            }
        }
        // 550 N · 0.3 m = 165 Nm < 230 Nm: no joint-3 constraint (Fig. 3.16d).
        assert!(TorqueBand::new(0.3, &TorsoLoad::<f64>::from_degrees(550.0, 90.0), -230.0).is_none());
    }

    /// "In case of τ_t2,min = τ_t3,min = −τ_t2,max = −τ_t3,max, the centers even lie on the
    /// straight τ_t2,min and τ_t2,max boundaries" (Sec. 3.3.3).
    #[test]
    fn circle_centres_lie_on_the_joint2_lines_for_symmetric_limits() {
        let g = test_geometry::<f64>();
        let load = TorsoLoad::from_degrees(800.0, 70.0);
        let limits = TorqueLimits::symmetric(230.0);
        let lines = joint2_lines(&load, &limits.joint2).unwrap();
        let low = TorqueBand::new(g.link3, &load, limits.joint3.min).unwrap();
        let high = TorqueBand::new(g.link3, &load, limits.joint3.max).unwrap();
        for phi in low.boundaries() {
            let c = direction(phi) * g.link3;
            assert!((lines[0].normal.dot(&c) + lines[0].offset).abs() < 1e-12);
        }
        for phi in high.boundaries() {
            let c = direction(phi) * g.link3;
            assert!((lines[1].normal.dot(&c) + lines[1].offset).abs() < 1e-12);
        }
    }

    #[test]
    fn validation() {
        assert!(TorqueLimits::<f64>::symmetric(230.0).validate().is_ok());
        assert!(TorqueLimits::<f64>::symmetric(-1.0).validate().is_err());
        assert!(TorsoLoad::<f64>::from_degrees(-1.0, 0.0).validate().is_err());
        assert!(TorsoLoad { force: 1.0, angle: f64::NAN }.validate().is_err());
    }
}
