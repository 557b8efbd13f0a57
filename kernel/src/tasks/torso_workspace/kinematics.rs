//! Kinematics of the tendon-coupled torso in its X-Z plane: the coupling (3.41), the torso
//! centre point (3.42), its Jacobian (3.43), the joint ranges of Table 3.2 and the arcs of
//! Table A.1 that bound the kinematic workspace.
//!
//! **Plane and angles.** `x` and `z` are the coordinates of the torso centre point `p_t` (the
//! axis of the passive joint `q_t4`) relative to the axis of `q_t2`, in the torso's sagittal
//! plane after the vertical joint `q_t1`: `z` along the vertical `q_t1` axis (up), `x`
//! horizontal, forward (the direction a positive `q_t2` leans the torso to). An angle `θ` in
//! this plane is measured from +Z towards +X like the pitch joints, i.e. the unit vector at `θ`
//! is `e(θ) = (sin θ, cos θ)` ([`direction`]); then (3.42) reads
//! `p_t = l_t2 e(q_t2) + l_t3 e(q_t2 + q_t3)`.

use nalgebra::{Matrix2, RealField, Vector2};

use crate::math::sqrt;
use crate::tasks::TaskError;

/// The unit vector `e(θ) = (sin θ, cos θ)` of the torso plane, `θ` measured from +Z towards +X.
///
/// ```
/// use kernel::tasks::torso_workspace::direction;
/// let e = direction(core::f64::consts::FRAC_PI_2);
/// assert!((e.x - 1.0).abs() < 1e-15 && e.y.abs() < 1e-15);
/// ```
#[inline]
pub fn direction<T: RealField + Copy>(theta: T) -> Vector2<T> {
    let (s, c) = theta.sin_cos();
    Vector2::new(s, c)
}

/// A closed interval `[min, max]` of a joint coordinate or of a torque (rad, Nm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range<T> {
    /// Lower bound.
    pub min: T,
    /// Upper bound.
    pub max: T,
}

impl<T: RealField + Copy> Range<T> {
    /// `[min, max]`.
    pub const fn new(min: T, max: T) -> Self {
        Self { min, max }
    }

    /// `true` if `min ≤ value ≤ max`.
    #[inline]
    pub fn contains(&self, value: T) -> bool {
        self.min <= value && value <= self.max
    }

    /// Finite bounds with `min < max`.
    pub(super) fn is_proper(&self) -> bool {
        self.min.is_finite() && self.max.is_finite() && self.min < self.max
    }
}

/// Link lengths and joint ranges of the tendon-coupled torso (Sec. 3.3.1, Table 3.2).
///
/// **Plane.** `x`, `z` are the coordinates of the torso centre point `p_t` (the axis of the
/// passive joint `q_t4`) relative to the axis of `q_t2`, in the torso's sagittal plane after
/// the vertical joint `q_t1` (Fig. 3.15): `z` up along the `q_t1` axis, `x` horizontal and
/// forward, the direction a positive `q_t2` leans the torso to. Angles in the plane are
/// measured from +Z towards +X like the pitch joints ([`direction`]), so (3.42) is
/// `p_t = l_t2 e(q_t2) + l_t3 e(q_t2 + q_t3)`.
///
/// The joint ranges are the three bounds of Table 3.2 written as intervals: `q_t2` itself,
/// `q_t3` itself, and the angle sum `q_t2 + q_t3 = −q_t4` (the passive joint, (3.41)), which
/// gives Table 3.2's `max(0°, −q_t2) ≤ q_t3 ≤ min(135°, 135° − q_t2)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TorsoGeometry<T> {
    /// `l_t2` (m): distance from the `q_t2` axis to the `q_t3` axis.
    pub link2: T,
    /// `l_t3` (m): distance from the `q_t3` axis to the `q_t4` axis (the torso centre point).
    pub link3: T,
    /// Range of `q_t2` (rad); Table 3.2: −90° … 90°.
    pub joint2: Range<T>,
    /// Range of `q_t3` (rad); Table 3.2: 0° … 135°. `q_t3 ≥ 0` selects the branch of the
    /// inverse kinematics (Sec. 3.3.3: "`q_t3 ≥ 0` always holds").
    pub joint3: Range<T>,
    /// Range of `q_t2 + q_t3` (rad); Table 3.2: 0° … 135°.
    pub sum: Range<T>,
}

/// The six kinematic limits as lines in the joint plane `(q_t2, q_t3)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum JointLine<T> {
    /// `q_t2 = value`.
    Joint2(T),
    /// `q_t3 = value`.
    Joint3(T),
    /// `q_t2 + q_t3 = value`.
    Sum(T),
}

impl<T: RealField + Copy> JointLine<T> {
    /// `coordinate − value` at `(q_t2, q_t3)` (rad): positive above the line.
    #[inline]
    pub fn offset(&self, q2: T, q3: T) -> T {
        match *self {
            Self::Joint2(v) => q2 - v,
            Self::Joint3(v) => q3 - v,
            Self::Sum(v) => q2 + q3 - v,
        }
    }
}

/// A circular arc of the torso plane: the points `center + radius · e(θ)`, `θ ∈ [start, end]`
/// (rad, [`direction`] convention), `end − start ∈ [0, π]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Arc<T> {
    /// Centre `(x, z)` (m).
    pub center: Vector2<T>,
    /// Radius (m).
    pub radius: T,
    /// First angle (rad).
    pub start: T,
    /// Last angle (rad).
    pub end: T,
}

impl<T: RealField + Copy> Arc<T> {
    /// The point at angle `theta` (m): `center + radius · e(θ)`.
    #[inline]
    pub fn point(&self, theta: T) -> Vector2<T> {
        self.center + direction(theta) * self.radius
    }
}

impl<T: RealField + Copy> TorsoGeometry<T> {
    /// A torso of links `(l_t2, l_t3)` (m) with the ranges of `q_t2`, `q_t3` and `q_t2 + q_t3`
    /// (degrees, `[min, max]`), as Table 3.2 gives them. Check it with [`Self::validate`].
    pub fn from_degrees(links: [f64; 2], joint2: [f64; 2], joint3: [f64; 2], sum: [f64; 2]) -> Self {
        let deg = |d: f64| nalgebra::convert::<f64, T>(d.to_radians());
        let range = |[min, max]: [f64; 2]| Range::new(deg(min), deg(max));
        let [link2, link3] = links.map(nalgebra::convert::<f64, T>);
        Self { link2, link3, joint2: range(joint2), joint3: range(joint3), sum: range(sum) }
    }

    /// Checks the geometry once: finite positive link lengths; proper ranges; `0 ≤ q_t3 < π`
    /// (the elbow branch, and `q_t3 = π` would fold the torso onto its base axis); `q_t2` and
    /// sum ranges at most π wide (every boundary arc then spans at most a half circle); a
    /// joint-space polygon with interior.
    pub fn validate(&self) -> Result<(), TaskError> {
        let invalid = |name| Err(TaskError::InvalidParameter { name });
        let positive = |x: T| x.is_finite() && x > T::zero();
        if !(positive(self.link2) && positive(self.link3)) {
            return invalid("link lengths");
        }
        let pi = T::pi();
        if !(self.joint2.is_proper() && self.joint2.max - self.joint2.min <= pi) {
            return invalid("joint2 range");
        }
        if !(self.joint3.is_proper() && self.joint3.min >= T::zero() && self.joint3.max < pi) {
            return invalid("joint3 range");
        }
        if !(self.sum.is_proper() && self.sum.max - self.sum.min <= pi) {
            return invalid("sum range");
        }
        // Non-empty interior: some q2 in its range with [q2 + q3min, q2 + q3max] meeting the
        // sum range, i.e. q2 ∈ [sum.min − q3max, sum.max − q3min].
        let low = self.joint2.min.max(self.sum.min - self.joint3.max);
        let high = self.joint2.max.min(self.sum.max - self.joint3.min);
        if low >= high {
            return invalid("empty workspace");
        }
        Ok(())
    }

    /// The torso centre point `p_t = (x, z)` (m) of (3.42):
    /// `x = l_t2 sin q_t2 + l_t3 sin(q_t2 + q_t3)`, `z = l_t2 cos q_t2 + l_t3 cos(q_t2 + q_t3)`.
    ///
    /// ```
    /// use kernel::tasks::torso_workspace::TorsoGeometry;
    /// let g = TorsoGeometry::<f64>::from_degrees([0.3, 0.3], [-90.0, 90.0], [0.0, 135.0], [0.0, 135.0]);
    /// let p = g.center(0.0, 0.0);
    /// assert!(p.x.abs() < 1e-15 && (p.y - 0.6).abs() < 1e-15); // upright: 0.6 m above q_t2
    /// ```
    #[inline]
    pub fn center(&self, q2: T, q3: T) -> Vector2<T> {
        direction(q2) * self.link2 + direction(q2 + q3) * self.link3
    }

    /// The Jacobian `J_t = ∂p_t/∂(q_t2, q_t3)` (m/rad) of (3.43).
    #[inline]
    pub fn jacobian(&self, q2: T, q3: T) -> Matrix2<T> {
        let (s2, c2) = q2.sin_cos();
        let (s23, c23) = (q2 + q3).sin_cos();
        let (l2, l3) = (self.link2, self.link3);
        Matrix2::new(l2 * c2 + l3 * c23, l3 * c23, -l2 * s2 - l3 * s23, -l3 * s23)
    }

    /// The passive joint `q_t4 = −(q_t2 + q_t3)` (rad) of (3.41) with the constant zero
    /// (upright chest).
    #[inline]
    pub fn passive_joint(q2: T, q3: T) -> T {
        -(q2 + q3)
    }

    /// `(q_t2, q_t3)` (rad) that put the torso centre point at `p = (x, z)`, on the branch
    /// `q_t3 ∈ [0, π]` (the one Table 3.2 allows), with `q_t2 ∈ [−π, π)`; `None` if `p` is out
    /// of reach (`|p| ∉ [|l_t2 − l_t3|, l_t2 + l_t3]`) or not finite. The result may still
    /// violate Table 3.2: check it with [`TorsoGeometry::contains`].
    ///
    /// ```
    /// use kernel::tasks::torso_workspace::TorsoGeometry;
    /// let g = TorsoGeometry::<f64>::from_degrees([0.3, 0.3], [-90.0, 90.0], [0.0, 135.0], [0.0, 135.0]);
    /// let [q2, q3] = g.inverse_kinematics(&g.center(-0.3, 0.9)).unwrap();
    /// assert!((q2 + 0.3).abs() < 1e-12 && (q3 - 0.9).abs() < 1e-12);
    /// ```
    pub fn inverse_kinematics(&self, p: &Vector2<T>) -> Option<[T; 2]> {
        let (l2, l3) = (self.link2, self.link3);
        let two: T = nalgebra::convert(2.0);
        let cos_q3 = (p.norm_squared() - l2 * l2 - l3 * l3) / (two * l2 * l3);
        // Points on the reach circles may round slightly beyond ±1.
        let slack = T::default_epsilon() * nalgebra::convert::<f64, T>(64.0);
        if !cos_q3.is_finite() || cos_q3.abs() > T::one() + slack {
            return None;
        }
        let cos_q3 = cos_q3.clamp(-T::one(), T::one());
        let q3 = cos_q3.acos();
        // p = R(q2) (l2 e(0) + l3 e(q3)): the angle of p is q2 plus the angle of the folded arm.
        let folded = q3.sin() * l3;
        let reach = l2 + l3 * cos_q3;
        let q2 = wrap_to_pi(p.x.atan2(p.y) - folded.atan2(reach));
        Some([q2, q3])
    }

    /// `true` if `(q_t2, q_t3)` lies in the ranges of Table 3.2 (closed).
    #[inline]
    pub fn contains(&self, q2: T, q3: T) -> bool {
        self.joint2.contains(q2) && self.joint3.contains(q3) && self.sum.contains(q2 + q3)
    }

    /// The six range limits bounding the kinematic workspace, in the order of Table A.1's arcs
    /// 1–6: `q_t2 = min`, `q_t3 = max`, `q_t2 + q_t3 = max`, `q_t2 = max`, `q_t3 = min`,
    /// `q_t2 + q_t3 = min`.
    pub fn arc_lines(&self) -> [JointLine<T>; 6] {
        [
            JointLine::Joint2(self.joint2.min),
            JointLine::Joint3(self.joint3.max),
            JointLine::Sum(self.sum.max),
            JointLine::Joint2(self.joint2.max),
            JointLine::Joint3(self.joint3.min),
            JointLine::Sum(self.sum.min),
        ]
    }

    /// The part of the joint-plane line `line` that lies in the joint ranges, mapped to the
    /// torso plane by (3.42): a circular arc (Table A.1 for the six range limits, Table A.2
    /// for `q_t2 + q_t3 = const`). `None` if the line misses the ranges.
    ///
    /// - `q_t2 = v`: centre `l_t2 e(v)`, radius `l_t3`, angle `θ = q_t2 + q_t3`.
    /// - `q_t3 = v`: centre 0, radius `√(l_t2² + l_t3² + 2 l_t2 l_t3 cos v)`, angle
    ///   `θ = q_t2 + atan2(l_t3 sin v, l_t2 + l_t3 cos v)`.
    /// - `q_t2 + q_t3 = v`: centre `l_t3 e(v)`, radius `l_t2`, angle `θ = q_t2`.
    pub fn arc(&self, line: JointLine<T>) -> Option<Arc<T>> {
        let (l2, l3) = (self.link2, self.link3);
        let (j2, j3, sum) = (self.joint2, self.joint3, self.sum);
        let (center, radius, start, end) = match line {
            JointLine::Joint2(v) => {
                if !j2.contains(v) {
                    return None;
                }
                let start = sum.min.max(v + j3.min);
                let end = sum.max.min(v + j3.max);
                (direction(v) * l2, l3, start, end)
            }
            JointLine::Joint3(v) => {
                if !j3.contains(v) {
                    return None;
                }
                let (s, c) = v.sin_cos();
                let offset = (l3 * s).atan2(l2 + l3 * c);
                let two: T = nalgebra::convert(2.0);
                let radius = sqrt((l2 * l2 + l3 * l3 + two * l2 * l3 * c).max(T::zero()));
                let start = j2.min.max(sum.min - v);
                let end = j2.max.min(sum.max - v);
                (Vector2::zeros(), radius, start + offset, end + offset)
            }
            JointLine::Sum(v) => {
                if !sum.contains(v) {
                    return None;
                }
                let start = j2.min.max(v - j3.max);
                let end = j2.max.min(v - j3.min);
                (direction(v) * l3, l2, start, end)
            }
        };
        (start <= end).then_some(Arc { center, radius, start, end })
    }
}

/// `x` wrapped into `[−π, π)`.
#[inline]
pub(super) fn wrap_to_pi<T: RealField + Copy>(x: T) -> T {
    let two_pi = T::two_pi();
    x - two_pi * ((x + T::pi()) / two_pi).floor()
}

/// `x` wrapped into `[from, from + 2π)`.
#[inline]
pub(super) fn wrap_from<T: RealField + Copy>(x: T, from: T) -> T {
    let two_pi = T::two_pi();
    x - two_pi * ((x - from) / two_pi).floor()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::tasks::torso_workspace::tests::test_geometry;
    use core::f64::consts::{FRAC_1_SQRT_2, PI, SQRT_2};

    fn deg(d: f64) -> f64 {
        d.to_radians()
    }

    #[test]
    fn jacobian_matches_finite_differences_and_ik_inverts_fk() {
        let g = test_geometry::<f64>();
        for (q2, q3) in [(0.3, 0.4), (-1.2, 2.0), (1.5, 0.1), (-0.2, 0.6)] {
            let h = 1e-6;
            let fd = Matrix2::from_columns(&[
                (g.center(q2 + h, q3) - g.center(q2 - h, q3)) / (2.0 * h),
                (g.center(q2, q3 + h) - g.center(q2, q3 - h)) / (2.0 * h),
            ]);
            assert!((fd - g.jacobian(q2, q3)).amax() < 1e-9);
            let [a, b] = g.inverse_kinematics(&g.center(q2, q3)).unwrap();
            assert!((a - q2).abs() < 1e-12 && (b - q3).abs() < 1e-12, "{q2} {q3}: {a} {b}");
        }
        assert_eq!(g.inverse_kinematics(&Vector2::new(0.7, 0.0)), None);
        assert_eq!(g.inverse_kinematics(&Vector2::new(f64::NAN, 0.0)), None);
    }

    /// Table A.1: centres and radii of arcs 1–6 for general `l_t2 ≠ l_t3`, and the angular
    /// ranges implied by Table 3.2.
    #[test]
    fn arcs_are_those_of_table_a1() {
        let (l2, l3) = (0.27, 0.33);
        let g = TorsoGeometry { link2: l2, link3: l3, ..test_geometry() };
        let table: [(JointLine<f64>, [f64; 2], f64); 6] = [
            (JointLine::Joint2(deg(-90.0)), [-l2, 0.0], l3),
            (JointLine::Joint3(deg(135.0)), [0.0, 0.0], (l2 * l2 + l3 * l3 - SQRT_2 * l2 * l3).sqrt()),
            (JointLine::Sum(deg(135.0)), [l3 * FRAC_1_SQRT_2, -l3 * FRAC_1_SQRT_2], l2),
            (JointLine::Joint2(deg(90.0)), [l2, 0.0], l3),
            (JointLine::Joint3(0.0), [0.0, 0.0], l2 + l3),
            (JointLine::Sum(0.0), [0.0, l3], l2),
        ];
        for (line, center, radius) in table {
            let arc = g.arc(line).unwrap();
            assert!((arc.center - Vector2::from(center)).amax() < 1e-15, "{line:?}");
            assert!((arc.radius - radius).abs() < 1e-15, "{line:?}");
        }
        // Angular extents: arc 1 spans q23 ∈ [0°, 45°], arc 4 q23 ∈ [90°, 135°], arc 6 q2 ∈ [−90°, 0°].
        let a1 = g.arc(JointLine::Joint2(deg(-90.0))).unwrap();
        assert!((a1.start - 0.0).abs() < 1e-15 && (a1.end - deg(45.0)).abs() < 1e-15);
        let a4 = g.arc(JointLine::Joint2(deg(90.0))).unwrap();
        assert!((a4.start - deg(90.0)).abs() < 1e-15 && (a4.end - deg(135.0)).abs() < 1e-15);
        let a6 = g.arc(JointLine::Sum(0.0)).unwrap();
        assert!((a6.start + deg(90.0)).abs() < 1e-15 && a6.end.abs() < 1e-15);
        // A line outside the ranges has no arc.
        assert_eq!(g.arc(JointLine::Sum(deg(140.0))), None);
    }

    /// Every point of every arc is on its joint line (equality) and inside the other ranges.
    #[test]
    fn arc_points_satisfy_their_limit_with_equality() {
        let g = test_geometry::<f64>();
        for line in g.arc_lines() {
            let arc = g.arc(line).unwrap();
            assert!(arc.end - arc.start <= PI + 1e-12);
            for k in 0..=20 {
                let theta = arc.start + (arc.end - arc.start) * f64::from(k) / 20.0;
                let [q2, q3] = g.inverse_kinematics(&arc.point(theta)).unwrap();
                assert!(line.offset(q2, q3).abs() < 1e-7, "{line:?} at {theta}: {q2} {q3}");
                let slack = 1e-7;
                assert!(q2 >= g.joint2.min - slack && q2 <= g.joint2.max + slack);
                assert!(q3 >= g.joint3.min - slack && q3 <= g.joint3.max + slack);
                assert!(q2 + q3 >= g.sum.min - slack && q2 + q3 <= g.sum.max + slack);
            }
        }
    }

    #[test]
    fn validation_rejects_bad_geometry() {
        let g = test_geometry::<f64>();
        assert_eq!(g.validate(), Ok(()));
        let bad = [
            TorsoGeometry { link2: 0.0, ..g },
            TorsoGeometry { joint3: Range::new(-0.1, 2.0), ..g },
            TorsoGeometry { joint3: Range::new(0.0, PI), ..g },
            TorsoGeometry { joint2: Range::new(-2.0, 2.0), ..g },
            TorsoGeometry { sum: Range::new(4.0, 4.1), ..g },
            TorsoGeometry { link3: f64::NAN, ..g },
        ];
        for b in bad {
            assert!(matches!(b.validate(), Err(TaskError::InvalidParameter { .. })), "{b:?}");
        }
    }

    #[test]
    fn wrapping() {
        assert!((wrap_to_pi(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-15);
        assert!((wrap_to_pi(-PI) + PI).abs() < 1e-15);
        assert!((wrap_from(-0.5, 0.0) - (2.0 * PI - 0.5)).abs() < 1e-15);
        assert!((wrap_from(0.5_f64, 0.0) - 0.5).abs() < 1e-15);
    }
}
