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

mod compliance_stack;
mod config;
mod control;
mod coriolis_decoupling;
mod decomposition;
mod error;
mod storage;

pub use compliance_stack::{ComplianceRow, ComplianceStack};
pub use config::{DynamicsTerms, MultilevelConfig};
pub use control::{multilevel_control, MultilevelData};
pub use coriolis_decoupling::{coriolis_decoupling, task_space_coriolis};
pub use decomposition::{decompose, BasisRow, Decomposition, LevelSpan};
pub use error::MultilevelError;
pub use storage::{storage_functions, LevelStorage};

#[cfg(test)]
mod test_support;
