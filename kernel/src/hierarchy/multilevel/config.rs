//! The multi-level controller's settings and the model terms it reads.

use nalgebra::{RealField, SMatrix, SVector};

use super::error::MultilevelError;
use crate::math::CholeskyFactor;

/// Settings of the multi-level controller. Validated by every entry point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MultilevelConfig<T> {
    /// Smallest admissible share `ρ = √(j M⁻¹ N jᵀ / j M⁻¹ jᵀ) ∈ (0, 1)` of a row that is still
    /// free after the rows above it (and of a null space axis on the last level). Below it the
    /// hierarchy counts as singular ([`MultilevelError::Singular`]). Default `1e-4`.
    pub singular_threshold: T,
    /// Whether [`multilevel_control`](super::multilevel_control) adds the Coriolis decoupling `τ_μ` (5.60) (switchable for
    /// experiments such as Fig. 5.23). Default `true`.
    pub coriolis_decoupling: bool,
    /// Tolerance on a level's kinetic energy `½ v_iᵀ Λ_i v_i` (J) for the set membership
    /// `(q, v) ∈ A_i` (5.63). Default `1e-4` J.
    pub kinetic_tolerance: T,
    /// Tolerance on a level's static residual ([`LevelStorage::static_residual`](super::LevelStorage::static_residual), √J/s) for
    /// the set membership. Default `0.1`: e.g. a 0.14 N spring force on a 2 kg TCP (0.12 mm
    /// at 1200 N/m), or 0.03 Nm on a joint direction of 0.1 kg m² (3 mrad at 10 Nm/rad).
    pub residual_tolerance: T,
}

impl<T: RealField + Copy> Default for MultilevelConfig<T> {
    fn default() -> Self {
        Self {
            singular_threshold: nalgebra::convert(1e-4),
            coriolis_decoupling: true,
            kinetic_tolerance: nalgebra::convert(1e-4),
            residual_tolerance: nalgebra::convert(0.1),
        }
    }
}

impl<T: RealField + Copy> MultilevelConfig<T> {
    pub(super) fn validate(&self) -> Result<(), MultilevelError> {
        let threshold_ok = self.singular_threshold.is_finite()
            && self.singular_threshold > T::zero()
            && self.singular_threshold < T::one();
        let tolerances_ok = self.kinetic_tolerance.is_finite()
            && self.kinetic_tolerance >= T::zero()
            && self.residual_tolerance.is_finite()
            && self.residual_tolerance >= T::zero();
        if threshold_ok && tolerances_ok {
            Ok(())
        } else {
            Err(MultilevelError::InvalidConfig)
        }
    }
}

/// The rigid-body terms of the controller's model at the current state `(q, q̇)`.
#[derive(Clone, Copy, Debug)]
pub struct DynamicsTerms<'a, T: RealField, const N: usize> {
    /// Mass matrix `M(q)` (kg, kg m²), e.g. `data.mass_matrix` after [`crate::dynamics::crba`].
    pub mass_matrix: &'a SMatrix<T, N, N>,
    /// Its Cholesky factor ([`crate::dynamics::mass_matrix_cholesky`]).
    pub mass_factor: &'a CholeskyFactor<T, N>,
    /// Coriolis matrix `C(q, q̇)` with `Ṁ = C + Cᵀ` (2.7) ([`crate::dynamics::coriolis_matrix`]).
    pub coriolis: &'a SMatrix<T, N, N>,
    /// Gravity torque `g(q)` (Nm), compensated in (5.58).
    pub gravity: &'a SVector<T, N>,
    /// Joint velocities `q̇` (rad/s, m/s).
    pub velocity: &'a SVector<T, N>,
}

impl<T: RealField + Copy, const N: usize> DynamicsTerms<'_, T, N> {
    pub(super) fn is_finite(&self) -> bool {
        crate::math::all_finite(self.mass_matrix)
            && crate::math::all_finite(self.coriolis)
            && crate::math::all_finite(self.gravity)
            && crate::math::all_finite(self.velocity)
    }

    /// `Ṁ = C + Cᵀ` (2.7).
    pub(super) fn mass_matrix_rate(&self) -> SMatrix<T, N, N> {
        self.coriolis + self.coriolis.transpose()
    }
}
