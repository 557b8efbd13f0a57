//! Multi-objective compliance control with proven stability (Sec. 5.2, (5.40)–(5.68)): the
//! hierarchical dynamics representation, the control law (5.58)–(5.60) and the storage
//! functions of the proof.
//!
//! # What is computed
//! The joint velocities are expressed by task-level velocities `v = J̄ q̇` (5.40)–(5.41),
//! `v = (v₁, …, v_r)`, with the extended Jacobian `J̄` whose inverse is the stacked null space
//! bases, `J̄⁻¹ = Zᵀ = (Z₁ᵀ, …, Z_rᵀ)` (5.52). In these coordinates the inertia is
//! block-diagonal, `Λ = Z M Zᵀ = diag(Λ_i)` (5.55)–(5.56), and the Coriolis matrix is
//! `μ = Λ(J̄ M⁻¹ C − J̄̇) Zᵀ = Z (C Zᵀ + M Żᵀ)` (5.57) (the second form follows from
//! `q̇ = Zᵀ v`). The control law (5.58) is
//! `τ = Σ_i τ_i^p + τ_μ + g(q)` with the projected compliance
//! `τ_i^p = −J̄_iᵀ Z_i J_iᵀ F_i` (5.59), `F_i = (∂V_i/∂x_i)ᵀ + D_i ẋ_i` (with the row forces
//! `f = −F` of [`crate::tasks`], `−J_iᵀ F_i = Σ_rows jᵀ f` is the level's task torque) and the
//! power-conserving Coriolis decoupling
//! `τ_μ = Σ_i J̄_iᵀ Σ_{j≠i} μ_ij v_j` (5.60). Telemetry: the storage functions
//! `S_i = ½ v_iᵀ Λ_i v_i + V_i` (5.64), their rates (5.65) and the nested sets `A_i` (5.63).
//!
//! # How: the scalar-inverse row recursion
//! The bases are built by the row-wise recursion of [`super::project`] with `W = M`: the rows
//! of the levels `1 … r−1` are processed in order, each row a sub-level. With the accumulated
//! dynamically consistent torque projector `N` (identity at the start), a row `j` gives
//! `p = N jᵀ`, `w = M⁻¹ p` (a Cholesky solve), `s = pᵀ w` and
//! - `z = wᵀ = j M⁻¹ N` (5.51), the basis row; `λ = z M zᵀ = s` (5.56);
//! - `J̄_row = (z M zᵀ)⁻¹ z M = pᵀ / s` (5.44), the only inversion being `1/s`;
//! - `N ← N − p wᵀ / s = N − J̄_rowᵀ z` (the rank-one update of [`super::project`]).
//!
//! The basis of a level is therefore `Z_i' = T_i Z_i` with the thesis' `Z_i = J_i M⁻¹ N_i`
//! and a unit lower-triangular `T_i` (a later row of the level is projected by the earlier
//! ones): an M-orthogonal basis of the same space, so `Λ` is even diagonal. Every level
//! quantity is invariant under such a change of basis `Z_i' = T_i Z_i`
//! (`J̄_i' = T_i⁻ᵀ J̄_i`, `v_i' = T_i⁻ᵀ v_i`, `Λ_i' = T_i Λ_i T_iᵀ`): the torque
//! `J̄_i'ᵀ Z_i' = J̄_iᵀ Z_i`, the kinetic energy `v_i'ᵀ Λ_i' v_i'`, the storage rate and,
//! because `T` is block-diagonal, `τ_μ` (the off-diagonal blocks transform as
//! `μ_ij' = T_i μ_ij T_jᵀ`; the term `T Λ Ṫᵀ` is block-diagonal). Only the level-1
//! velocity differs from the thesis' `v₁ = ẋ₁` (there `Z₁ = Λ₁ J₁ M⁻¹` gives `J̄₁ = J₁`):
//! here `v₁' = T₁⁻ᵀ ẋ₁`.
//!
//! The last level takes the complete remaining null space, `Z_r = Y_{r−1}` (5.51), of
//! dimension `N − Σ_{i<r} m_i`, whatever its own number of rows. It is spanned by projecting
//! coordinate axes through the same recursion (`j = e_kᵀ`), picking at each step the axis
//! with the largest share `ρ_k² = (M⁻¹N)_kk / (M⁻¹)_kk` still free (a pivoted Gram–Schmidt in
//! the metric `M`), so near-dependent candidates are never used. Then `J̄ Zᵀ = I`: the
//! extended Jacobian's inverse is `Zᵀ` (5.52) without any matrix inversion.
//!
//! # Time derivative
//! `μ` needs `Ż` (equivalently `J̄̇ = −J̄ Żᵀ J̄`). It is computed exactly, by propagating the
//! tangents of the recursion along `q̇` (forward-mode differentiation): with `Ṁ = C + Cᵀ`
//! (2.7) and the row rates `j̇` supplied by the tasks,
//! `ṗ = Ṅ jᵀ + N j̇ᵀ`, `ẇ = M⁻¹(ṗ − Ṁ w)`, `ṡ = ṗᵀw + pᵀẇ`, `ż = ẇᵀ`,
//! `Ṅ ← Ṅ − (ṗ wᵀ + p ẇᵀ)/s + p wᵀ ṡ/s²`. The only error is rounding; no finite difference
//! and no extra model evaluation is involved. The pivot choice of the last level is piecewise
//! constant; where it switches, the basis `Z_r` jumps, but by the invariance above no level
//! quantity (torque, `S_r`, `τ_μ`) does.
//!
//! # Scope
//! The thesis' setting: a fixed hierarchy of bilateral tasks whose Jacobians keep full row rank
//! (Proposition 5.1). Rows are not faded (no activations); a row that becomes dependent on the
//! rows above (ρ below [`MultilevelConfig::singular_threshold`]) is an error, and the
//! controller must fall back to its safe output. Unilateral constraints and continuous
//! transitions are the business of [`super::project`] (Sec. 4.4).
//!
//! # Modules
//! - [`decompose`]: `Z`, `Ż`, `J̄`, `Λ`, `Λ̇`, `v` ((5.40)–(5.56)).
//! - [`coriolis_decoupling`], [`task_space_coriolis`]: `τ_μ` (5.60) in `O(L N²)`, and the full
//!   `μ` (5.57) in `O(N³)` for analysis.
//! - [`storage_functions`]: `S_i`, `Ṡ_i`, `A_i` ((5.63)–(5.67)).
//! - [`multilevel_control`]: the whole control law (5.58) with telemetry.

mod control;
mod coriolis_decoupling;
mod decomposition;
mod storage;

pub use control::{multilevel_control, MultilevelData};
pub use coriolis_decoupling::{coriolis_decoupling, task_space_coriolis};
pub use decomposition::{decompose, BasisRow, Decomposition, LevelSpan};
pub use storage::{storage_functions, LevelStorage};

use core::fmt;

use heapless::Vec;
use nalgebra::{RealField, RowSVector, SMatrix, SVector};

use crate::math::CholeskyFactor;
use crate::tasks::TaskRow;

/// One task row of a compliance level, with what the multi-level controller needs beyond a
/// [`TaskRow`]: the row's time derivative (for `Ż`) and its force split into the spring and
/// the damper part (for the storage rate (5.65) and the sets (5.63)).
///
/// Sign convention of [`crate::tasks`]: the forces act along the row, `f = −∂V/∂x − d ẋ`
/// with `ẋ = j q̇`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ComplianceRow<T, const N: usize> {
    /// Jacobian row `j` (1×N).
    pub jacobian: RowSVector<T, N>,
    /// Its time derivative `j̇ = Σ_k (∂j/∂q_k) q̇_k` (1×N), e.g. from
    /// [`crate::dynamics::frame_jacobian_derivative`] with direction `q̇`; zero for joint rows.
    pub jacobian_rate: RowSVector<T, N>,
    /// Spring part `−∂V/∂x` of the row force (N or Nm).
    pub stiffness_force: T,
    /// Damper part `−(D ẋ)` of the row force (N or Nm).
    pub damping_force: T,
    /// The row's share of the level's potential `V_i` (J).
    pub potential: T,
}

impl<T: RealField + Copy, const N: usize> ComplianceRow<T, N> {
    /// A row from a task row, its rate and the spring part of its force; the damper part is
    /// the rest, `f − stiffness_force`.
    pub fn from_task_row(row: &TaskRow<T, N>, jacobian_rate: RowSVector<T, N>, stiffness_force: T) -> Self {
        Self {
            jacobian: row.jacobian,
            jacobian_rate,
            stiffness_force,
            damping_force: row.force - stiffness_force,
            potential: row.potential,
        }
    }

    /// Total row force `f = stiffness_force + damping_force`.
    pub fn force(&self) -> T {
        self.stiffness_force + self.damping_force
    }

    fn is_finite(&self) -> bool {
        self.stiffness_force.is_finite()
            && self.damping_force.is_finite()
            && self.potential.is_finite()
            && crate::math::all_finite(&self.jacobian)
            && crate::math::all_finite(&self.jacobian_rate)
    }
}

/// The compliance rows of all levels (capacity `R`), each tagged with its priority level
/// (0 = highest). Within a level, rows are used in insertion order.
#[derive(Clone, Debug, PartialEq)]
pub struct ComplianceStack<T, const N: usize, const R: usize> {
    rows: Vec<(usize, ComplianceRow<T, N>), R>,
}

impl<T: RealField + Copy, const N: usize, const R: usize> Default for ComplianceStack<T, N, R> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: RealField + Copy, const N: usize, const R: usize> ComplianceStack<T, N, R> {
    /// An empty stack.
    pub const fn new() -> Self {
        Self { rows: Vec::new() }
    }

    /// Removes every row.
    pub fn clear(&mut self) {
        self.rows.clear();
    }

    /// Appends one row on `level`. Errors: the stack is full.
    pub fn push(&mut self, level: usize, row: ComplianceRow<T, N>) -> Result<(), MultilevelError> {
        self.rows.push((level, row)).map_err(|_| MultilevelError::Capacity { capacity: R })
    }

    /// The rows `(level, row)` in insertion order.
    pub fn rows(&self) -> &[(usize, ComplianceRow<T, N>)] {
        &self.rows
    }

    /// The rows of one level, in insertion order.
    pub fn level(&self, level: usize) -> impl Iterator<Item = &ComplianceRow<T, N>> + '_ {
        self.rows.iter().filter(move |(l, _)| *l == level).map(|(_, row)| row)
    }

    /// Number of levels in use (highest level + 1; 0 when empty).
    pub fn level_count(&self) -> usize {
        self.rows.iter().map(|(level, _)| level + 1).max().unwrap_or(0)
    }
}

/// Settings of the multi-level controller. Validated by every entry point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MultilevelConfig<T> {
    /// Smallest admissible share `ρ = √(j M⁻¹ N jᵀ / j M⁻¹ jᵀ) ∈ (0, 1)` of a row that is still
    /// free after the rows above it (and of a null space axis on the last level). Below it the
    /// hierarchy counts as singular ([`MultilevelError::Singular`]). Default `1e-4`.
    pub singular_threshold: T,
    /// Whether [`multilevel_control`] adds the Coriolis decoupling `τ_μ` (5.60) (switchable for
    /// experiments such as Fig. 5.23). Default `true`.
    pub coriolis_decoupling: bool,
    /// Tolerance on a level's kinetic energy `½ v_iᵀ Λ_i v_i` (J) for the set membership
    /// `(q, v) ∈ A_i` (5.63). Default `1e-4` J.
    pub kinetic_tolerance: T,
    /// Tolerance on a level's static residual ([`LevelStorage::static_residual`], √J/s) for
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
    fn validate(&self) -> Result<(), MultilevelError> {
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
    fn is_finite(&self) -> bool {
        crate::math::all_finite(self.mass_matrix)
            && crate::math::all_finite(self.coriolis)
            && crate::math::all_finite(self.gravity)
            && crate::math::all_finite(self.velocity)
    }

    /// `Ṁ = C + Cᵀ` (2.7).
    fn mass_matrix_rate(&self) -> SMatrix<T, N, N> {
        self.coriolis + self.coriolis.transpose()
    }
}

/// Why the multi-level decomposition or control law refused its input. Outputs are left
/// unchanged.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MultilevelError {
    /// More rows than the stack's capacity.
    Capacity {
        /// The capacity `R`.
        capacity: usize,
    },
    /// A row names a level `≥ L`.
    TooManyLevels {
        /// The capacity `L`.
        capacity: usize,
    },
    /// The levels above the last one have more rows than the robot has coordinates, so they
    /// cannot all be independent.
    TooManyConstraints {
        /// Rows on the levels `1 … r−1`.
        rows: usize,
    },
    /// A row, a dynamics term or the state is NaN or infinite.
    NonFinite,
    /// A row of `level` is (numerically) dependent on the rows above it or zero: the
    /// hierarchy is singular (Proposition 5.1 requires full row rank).
    Singular {
        /// The level (0 = highest).
        level: usize,
    },
    /// The remaining null space of the last level could not be spanned (rounding broke the
    /// rank count).
    NullSpaceDeficient,
    /// A setting of [`MultilevelConfig`] is out of range.
    InvalidConfig,
    /// The stack has another number of levels than the decomposition it is used with.
    StackMismatch,
}

impl fmt::Display for MultilevelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Capacity { capacity } => write!(f, "more than {capacity} compliance rows"),
            Self::TooManyLevels { capacity } => write!(f, "more than {capacity} priority levels"),
            Self::TooManyConstraints { rows } => write!(f, "{rows} rows above the last level exceed the coordinates"),
            Self::NonFinite => f.write_str("non-finite row, dynamics term or state"),
            Self::Singular { level } => write!(f, "singular hierarchy: a row of level {level} is dependent"),
            Self::NullSpaceDeficient => f.write_str("the remaining null space could not be spanned"),
            Self::InvalidConfig => f.write_str("invalid multi-level configuration"),
            Self::StackMismatch => f.write_str("stack and decomposition have different levels"),
        }
    }
}

impl core::error::Error for MultilevelError {}

#[cfg(test)]
mod test_support;
