//! The repulsive potentials' parameters and force law, shared by all pairs.

use nalgebra::{convert, RealField};

use crate::tasks::TaskError;

/// Parameters of the repulsive potentials, shared by all pairs (Table 3.1, Table 4.5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CollisionParameters<T> {
    max_force: T,
    influence_distance: T,
    damping_ratio: T,
    activation_full: T,
    activation_zero: T,
}

impl<T: RealField + Copy> CollisionParameters<T> {
    /// Validated parameters:
    /// - `max_force` `F_max > 0` (N): the repulsive force at contact, `d = 0` (3.8);
    /// - `influence_distance` `d0 > 0` (m): the potential vanishes for `d ≥ d0`;
    /// - `damping_ratio` `ξ ≥ 0` of every pair (3.23);
    /// - the activation band `0 ≤ ϑ1 < ϑ2` (m) of (4.68) for the hierarchy: a row's
    ///   activation is 1 for `d ≤ ϑ1`, 0 for `d ≥ ϑ2`, and `1 − (3s² − 2s³)`, `s = (d − ϑ1)/(ϑ2 − ϑ1)`
    ///   in between (Table 4.5: `N'max = 1.5/(ϑ2 − ϑ1)`).
    ///
    /// ```
    /// use kernel::tasks::collision::CollisionParameters;
    /// // Table 3.1: F_max = 25 N, d0 = 0.15 m, ξ = 0.7 (activation band [0, d0]).
    /// let p = CollisionParameters::try_new(25.0_f64, 0.15, 0.7, 0.0, 0.15).unwrap();
    /// assert_eq!(p.force(0.0), 25.0);
    /// assert!((p.stiffness(0.0) - 2.0 * 25.0 / 0.15).abs() < 1e-12); // 333 N/m
    /// assert_eq!(p.potential(0.2), 0.0);
    /// ```
    pub fn try_new(
        max_force: T,
        influence_distance: T,
        damping_ratio: T,
        activation_full: T,
        activation_zero: T,
    ) -> Result<Self, TaskError> {
        let finite = [max_force, influence_distance, damping_ratio, activation_full, activation_zero]
            .iter()
            .all(|x| x.is_finite());
        if !finite {
            return Err(TaskError::NonFinite);
        }
        let zero = T::zero();
        if max_force <= zero {
            return Err(TaskError::InvalidParameter { name: "max_force" });
        }
        if influence_distance <= zero {
            return Err(TaskError::InvalidParameter { name: "influence_distance" });
        }
        if damping_ratio < zero {
            return Err(TaskError::InvalidParameter { name: "damping_ratio" });
        }
        if activation_full < zero || activation_zero <= activation_full {
            return Err(TaskError::InvalidParameter { name: "activation band" });
        }
        Ok(Self { max_force, influence_distance, damping_ratio, activation_full, activation_zero })
    }

    /// `F_max` (N).
    pub fn max_force(&self) -> T {
        self.max_force
    }

    /// `d0` (m).
    pub fn influence_distance(&self) -> T {
        self.influence_distance
    }

    /// `ξ`.
    pub fn damping_ratio(&self) -> T {
        self.damping_ratio
    }

    /// The same parameters with damping ratio `ξ` (validated).
    pub fn with_damping_ratio(&self, damping_ratio: T) -> Result<Self, TaskError> {
        Self::try_new(
            self.max_force,
            self.influence_distance,
            damping_ratio,
            self.activation_full,
            self.activation_zero,
        )
    }

    /// Distance below which a pair emits a row: `max(d0, ϑ2)` (m).
    pub fn emit_distance(&self) -> T {
        self.influence_distance.max(self.activation_zero)
    }

    /// Potential `V(d)` (J), (3.8): `−F_max/(3 d0²) (d − d0)³` for `d ≤ d0`, else 0. For
    /// `d < 0` (overlapping volumes) the same cubic continues.
    pub fn potential(&self, d: T) -> T {
        let s = self.relative_offset(d);
        if s >= T::zero() {
            return T::zero();
        }
        -self.max_force * self.influence_distance / convert::<f64, T>(3.0) * s * s * s
    }

    /// Repulsive force `F_sca(d) = −∂V/∂d = F_max/d0² (d − d0)²` for `d ≤ d0`, else 0 (N),
    /// (3.10); `F_sca(0) = F_max`.
    pub fn force(&self, d: T) -> T {
        let s = self.relative_offset(d);
        if s >= T::zero() {
            return T::zero();
        }
        self.max_force * s * s
    }

    /// Local stiffness `k = ∂²V/∂d² = 2 F_max/d0² (d0 − d)` for `d ≤ d0`, else 0 (N/m), (3.22).
    pub fn stiffness(&self, d: T) -> T {
        // `(d0 − d) / d0 = −s` exactly (IEEE rounding is symmetric), so the division is the
        // one `force` and `potential` make (one division per row where they are inlined).
        let s = self.relative_offset(d);
        if s >= T::zero() {
            return T::zero();
        }
        convert::<f64, T>(2.0) * self.max_force / self.influence_distance * -s
    }

    /// `s = (d − d0) / d0` of the force law (3.10).
    #[inline]
    fn relative_offset(&self, d: T) -> T {
        (d - self.influence_distance) / self.influence_distance
    }

    /// Activation `a(d) = 1 − N_des(d)` with the cubic `N_des` of (4.68) on `[ϑ1, ϑ2]`.
    pub fn activation(&self, d: T) -> T {
        crate::math::switching::transition_activation(d, self.activation_full, self.activation_zero)
    }
}
