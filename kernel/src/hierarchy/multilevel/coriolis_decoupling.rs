//! The task-level Coriolis matrix `μ` (5.57) and the power-conserving decoupling `τ_μ` (5.60).

use nalgebra::{RealField, SMatrix, SVector};

use super::config::DynamicsTerms;
use super::decomposition::Decomposition;

/// Task-level Coriolis/centrifugal matrix `μ = Λ(J̄ M⁻¹ C − J̄̇) J̄⁻¹` (5.57), evaluated as
/// `μ = Z (C Zᵀ + M Żᵀ)`: with `q̇ = Zᵀ v` (5.52)–(5.53), `q̈ = Zᵀ v̇ + Żᵀ v`, and
/// `Z (M q̈ + C q̇) = Λ v̇ + μ v` because `Z = J̄⁻ᵀ`. Both forms agree since
/// `J̄̇ = −J̄ Żᵀ J̄` and `Λ J̄ = Z M`. It satisfies `Λ̇ = μ + μᵀ`, and as `Λ` is block-diagonal
/// for every `q`, its off-diagonal blocks are skew: `μ_ij = −μ_jiᵀ` (`i ≠ j`).
///
/// Inputs: a decomposition of the current state ([`super::decompose`]) and the same model
/// terms. Returns `μ` (N×N) in the decomposition's row order. Cost O(N³) (three products):
/// meant for analysis and tests; the controller needs only `τ_μ` ([`coriolis_decoupling`]).
/// An empty decomposition gives zero.
///
/// ```
/// use kernel::hierarchy::multilevel::*;
/// use nalgebra::{Matrix2, RowVector2, Vector2};
/// // Constant inertia and rows: Ż = 0, C = 0, hence μ = 0.
/// let m = Matrix2::new(1.0, 0.0, 0.0, 4.0);
/// let factor = m.cholesky().unwrap();
/// let (c, g, qd) = (Matrix2::zeros(), Vector2::zeros(), Vector2::new(0.3, -0.1));
/// let dynamics = DynamicsTerms { mass_matrix: &m, mass_factor: &factor, coriolis: &c, gravity: &g, velocity: &qd };
/// let mut stack = ComplianceStack::<f64, 2, 4>::new();
/// stack.push(0, ComplianceRow { jacobian: RowVector2::new(1.0, 1.0), jacobian_rate: RowVector2::zeros(),
///     stiffness_force: 0.0, damping_force: 0.0, potential: 0.0 }).unwrap();
/// let mut out = Decomposition::<f64, 2, 2>::default();
/// stack.push(1, ComplianceRow { jacobian: RowVector2::new(0.0, 1.0), ..stack.rows()[0].1 }).unwrap();
/// decompose(&MultilevelConfig::default(), &stack, &dynamics, &mut out).unwrap();
/// assert_eq!(task_space_coriolis(&out, &dynamics).amax(), 0.0);
/// ```
pub fn task_space_coriolis<T: RealField + Copy, const N: usize, const L: usize>(
    decomposition: &Decomposition<T, N, L>,
    dynamics: &DynamicsTerms<'_, T, N>,
) -> SMatrix<T, N, N> {
    let z = decomposition.basis();
    let z_rate = decomposition.basis_rate();
    z * (dynamics.coriolis * z.transpose() + dynamics.mass_matrix * z_rate.transpose())
}

/// Power-conserving cancellation of the Coriolis/centrifugal couplings between the levels
/// (5.60): `τ_μ = Σ_i J̄_iᵀ Σ_{j≠i} μ_ij v_j`, so that the closed loop of every level is
/// `Λ_i v̇_i + μ_ii v_i + Z_i J_iᵀ F_i = F_i,ext` (5.62). Its power `τ_μᵀ q̇ = vᵀ μ_off v`
/// vanishes because the off-diagonal blocks `μ_off` are skew (`μ_ij = −μ_jiᵀ`); this holds for
/// any model error, as it only needs `Λ̇ = μ + μᵀ` of the controller's own model.
///
/// Evaluated without forming `μ`: with `Ż_iᵀ v_i` and `Z_iᵀ v_i` (the level's share of `q̇`),
/// the coupling force of a basis row `z` of level `i` is
/// `(μ_off v)_row = z (M Σ_{j≠i} Ż_jᵀ v_j + C Σ_{j≠i} Z_jᵀ v_j)`. Cost O(L N²).
///
/// Inputs: a decomposition of the current state ([`super::decompose`]) and the same model
/// terms. Returns `τ_μ` (Nm); zero for fewer than two levels.
///
/// ```
/// use kernel::hierarchy::multilevel::*;
/// use nalgebra::{Matrix2, RowVector2, Vector2};
/// // A velocity-dependent C couples the levels; τ_μ does no work: τ_μᵀ q̇ = 0.
/// let m = Matrix2::new(2.0, 0.3, 0.3, 1.0);
/// let factor = m.cholesky().unwrap();
/// let (c, g, qd) = (Matrix2::new(0.1, -0.4, 0.2, 0.05), Vector2::zeros(), Vector2::new(0.7, -0.2));
/// let dynamics = DynamicsTerms { mass_matrix: &m, mass_factor: &factor, coriolis: &c, gravity: &g, velocity: &qd };
/// let row = |j: RowVector2<f64>| ComplianceRow { jacobian: j, jacobian_rate: RowVector2::new(0.1, 0.0),
///     stiffness_force: 0.0, damping_force: 0.0, potential: 0.0 };
/// let mut stack = ComplianceStack::<f64, 2, 4>::new();
/// stack.push(0, row(RowVector2::new(1.0, 0.5))).unwrap();
/// stack.push(1, row(RowVector2::new(0.0, 1.0))).unwrap();
/// let mut out = Decomposition::<f64, 2, 2>::default();
/// decompose(&MultilevelConfig::default(), &stack, &dynamics, &mut out).unwrap();
/// let tau_mu = coriolis_decoupling(&out, &dynamics);
/// assert!(tau_mu.amax() > 1e-3 && tau_mu.dot(&qd).abs() < 1e-14);
/// ```
pub fn coriolis_decoupling<T: RealField + Copy, const N: usize, const L: usize>(
    decomposition: &Decomposition<T, N, L>,
    dynamics: &DynamicsTerms<'_, T, N>,
) -> SVector<T, N> {
    let share = |level: usize| {
        decomposition
            .level_rows(level)
            .iter()
            .fold((SVector::<T, N>::zeros(), SVector::<T, N>::zeros()), |(a, qd), r| {
                (a + r.basis_rate.transpose() * r.velocity, qd + r.basis.transpose() * r.velocity)
            })
    };
    let rate_all: SVector<T, N> =
        decomposition.rows().iter().fold(SVector::zeros(), |a, r| a + r.basis_rate.transpose() * r.velocity);
    let all = dynamics.mass_matrix * rate_all + dynamics.coriolis * dynamics.velocity;
    let mut torque = SVector::zeros();
    for level in 0..decomposition.level_count() {
        let (rate_own, velocity_own) = share(level);
        let coupling = all - (dynamics.mass_matrix * rate_own + dynamics.coriolis * velocity_own);
        for row in decomposition.level_rows(level) {
            torque += row.jacobian.transpose() * row.basis.transpose().dot(&coupling);
        }
    }
    torque
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::super::test_support::Fixture;
    use super::super::{decompose, ComplianceStack, Decomposition, MultilevelConfig};
    use super::*;
    use crate::test_models::N;

    fn blocks(out: &Decomposition<f64, N, 4>) -> std::vec::Vec<std::ops::Range<usize>> {
        out.levels().iter().map(|s| s.start..s.start + s.len).collect()
    }

    /// `Λ̇ = μ + μᵀ` (diagonal, from the recursion's `λ̇`), hence skew off-diagonal blocks,
    /// `μ_ij = −μ_jiᵀ`; and `τ_μ = J̄ᵀ μ_off v` with zero power `τ_μᵀ q̇`.
    #[test]
    fn skew_couplings_and_zero_power() {
        for seed in 0..50 {
            let fixture = Fixture::new(seed, &[3, 2]);
            let terms = fixture.terms();
            let out = fixture.decompose().unwrap();
            let mu = task_space_coriolis(&out, &terms);
            let sum = mu + mu.transpose();
            let scale = 1.0 + mu.amax();
            assert!((sum - SMatrix::from_diagonal(&out.inertia_rate())).amax() < 1e-9 * scale, "seed {seed}");
            let ranges = blocks(&out);
            let mut off = mu;
            for r in &ranges {
                off.view_mut((r.start, r.start), (r.len(), r.len())).fill(0.0);
            }
            assert!((off + off.transpose()).amax() < 1e-9 * scale, "μ_ij = −μ_jiᵀ, seed {seed}");
            let tau = coriolis_decoupling(&out, &terms);
            let expected = out.extended_jacobian().transpose() * off * out.velocity();
            assert!((tau - expected).amax() < 1e-9 * (1.0 + expected.amax()), "seed {seed}");
            let power = tau.dot(&fixture.velocity);
            assert!(power.abs() < 1e-10 * (1.0 + tau.amax() * fixture.velocity.amax()), "seed {seed}: power {power}");
        }
    }

    /// (5.57) literally: `μ = Λ (J̄ M⁻¹ C − J̄̇) J̄⁻¹` with `J̄̇` from a central difference of `J̄`
    /// along the motion (the task levels' rows; the last level's basis is fixed by pivoting).
    #[test]
    fn matches_the_thesis_form_with_a_finite_difference_jbar_rate() {
        for seed in 0..20 {
            let fixture = Fixture::new(seed, &[3, 2]);
            let terms = fixture.terms();
            let out = fixture.decompose().unwrap();
            let h = 1e-6;
            let jbar_at = |s: f64| {
                Fixture::at(&(fixture.q + fixture.velocity * s), &fixture.velocity, &[3, 2])
                    .decompose()
                    .unwrap()
                    .extended_jacobian()
            };
            let jbar_rate = (jbar_at(h) - jbar_at(-h)) / (2.0 * h);
            let jbar = out.extended_jacobian();
            let analytic_rate = -jbar * out.basis_rate().transpose() * jbar;
            let lambda = SMatrix::from_diagonal(&out.inertia());
            let thesis =
                lambda * (jbar * fixture.factor.solve(&fixture.coriolis) - jbar_rate) * out.basis().transpose();
            let mu = task_space_coriolis(&out, &terms);
            let scale = 1.0 + mu.amax();
            // Compare the task-level rows (0..5); the FD of the last row mixes in the pivot basis.
            assert!((thesis.rows(0, 5) - mu.rows(0, 5)).amax() < 1e-5 * scale, "seed {seed}");
            assert!(
                (analytic_rate.rows(0, 5) - jbar_rate.rows(0, 5)).amax() < 1e-5 * (1.0 + jbar_rate.amax()),
                "seed {seed}"
            );
        }
    }

    /// `τ_μ` does not depend on the basis chosen inside a level: reversing the order of the
    /// level-0 rows changes `Z₀` (another M-orthogonal basis of the same space) but not `τ_μ`.
    #[test]
    fn invariant_to_the_basis_within_a_level() {
        for seed in 0..20 {
            let fixture = Fixture::new(seed, &[3, 2]);
            let terms = fixture.terms();
            let out = fixture.decompose().unwrap();
            let mut reversed = ComplianceStack::<f64, N, 16>::new();
            let rows = fixture.stack.rows();
            for (level, row) in rows.iter().filter(|(l, _)| *l == 0).rev().chain(rows.iter().filter(|(l, _)| *l != 0)) {
                reversed.push(*level, *row).unwrap();
            }
            let mut other = Decomposition::<f64, N, 4>::default();
            decompose(&MultilevelConfig::default(), &reversed, &terms, &mut other).unwrap();
            assert!((other.basis().row(0) - out.basis().row(0)).amax() > 1e-6, "the basis did change");
            let (a, b) = (coriolis_decoupling(&out, &terms), coriolis_decoupling(&other, &terms));
            assert!((a - b).amax() < 1e-9 * (1.0 + a.amax()), "seed {seed}");
        }
    }

    #[test]
    fn f32_agrees_with_f64() {
        let fixture = Fixture::new(21, &[3, 2]);
        let out = fixture.decompose().unwrap();
        let tau = coriolis_decoupling(&out, &fixture.terms());
        let f32_fixture = fixture.cast_f32();
        let out32 = f32_fixture.decompose().unwrap();
        let tau32 = coriolis_decoupling(&out32, &f32_fixture.terms()).cast::<f64>();
        assert!((tau - tau32).amax() < 2e-3 * (1.0 + tau.amax()), "{} vs {}", tau, tau32);
    }
}
