//! Storage functions of the proof of stability (5.63)–(5.67), per level, for telemetry.

use nalgebra::{RealField, SVector};

use super::compliance_stack::ComplianceStack;
use super::config::{DynamicsTerms, MultilevelConfig};
use super::decomposition::Decomposition;
use super::error::MultilevelError;
use crate::math::sqrt;

/// Energy bookkeeping of one priority level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelStorage<T> {
    /// Kinetic energy of the level, `½ v_iᵀ Λ_i v_i` (J).
    pub kinetic: T,
    /// Potential `V_i` of the level's rows (J).
    pub potential: T,
    /// Storage function `S_i = ½ v_iᵀ Λ_i v_i + V_i` (5.64) (J).
    pub storage: T,
    /// Its rate along the closed loop with `F_ext = 0`, (5.65):
    /// `Ṡ_i = v_iᵀ Z_i J_iᵀ(−F_i) + (∂V_i/∂x_i) J_i q̇` (W). Exact for every state when the
    /// model is exact and `τ_μ` is applied (from (5.62) and `Λ̇_i = μ_ii + μ_iiᵀ`); `≤ 0` inside
    /// `A_{i−1}` (5.67). Assumes time-invariant potentials (constant equilibria).
    pub storage_rate: T,
    /// Static residual `√(gᵀ Λ_i⁻¹ g)` of the projected spring force `g = Z_i J_iᵀ (∂V_i/∂x_i)ᵀ`
    /// (√J/s): zero exactly where (5.68) holds, i.e. at the level's (constrained) minimum.
    /// Invariant to the basis of the level.
    pub static_residual: T,
    /// `(q, v) ∈ A_i` (5.63) within the tolerances of [`MultilevelConfig`]: this level and all
    /// levels above it are at rest (`kinetic ≤ kinetic_tolerance`) in their (constrained)
    /// equilibrium (`static_residual ≤ residual_tolerance`).
    pub in_set: bool,
}

impl<T: RealField + Copy> Default for LevelStorage<T> {
    fn default() -> Self {
        Self {
            kinetic: T::zero(),
            potential: T::zero(),
            storage: T::zero(),
            storage_rate: T::zero(),
            static_residual: T::zero(),
            in_set: false,
        }
    }
}

/// Storage functions `S_i` (5.64), their rates (5.65) and the set memberships `A_i` (5.63) of
/// every level, written to `out[..r]` (the other entries are reset). A planner reads
/// convergence (`S_i → 0`, or `in_set` with `V_i > 0` at a constrained minimum, i.e. a
/// conflict with the levels above) and the order in which the levels settle.
///
/// Per level `i`, with the task torque `τ_i = Σ_rows jᵀ f`, its spring part
/// `τ_i^s = Σ_rows jᵀ f_s` and the basis rows `z` of the level:
/// `S_i = ½ Σ λ v² + Σ V_row`, `Ṡ_i = Σ v (z τ_i) − Σ_rows f_s (j q̇)`,
/// residual² `= Σ (z τ_i^s)² / λ`.
///
/// Inputs: the stack and the decomposition made from it ([`super::decompose`]) and the same
/// model terms. Cost O(R N + N²). Errors: [`MultilevelError::InvalidConfig`], and
/// [`MultilevelError::StackMismatch`] if the stack has a different number of levels than the
/// decomposition (`out` unchanged).
///
/// ```
/// use kernel::hierarchy::multilevel::*;
/// use nalgebra::{Matrix2, RowVector2, Vector2};
/// let m = Matrix2::new(1.0, 0.0, 0.0, 4.0);
/// let factor = m.cholesky().unwrap();
/// let (c, g, qd) = (Matrix2::zeros(), Vector2::zeros(), Vector2::new(1.0, 0.0));
/// let dynamics = DynamicsTerms { mass_matrix: &m, mass_factor: &factor, coriolis: &c, gravity: &g, velocity: &qd };
/// // One level: a spring on x₁ stretched by 0.1 m with 100 N/m.
/// let mut stack = ComplianceStack::<f64, 2, 4>::new();
/// stack.push(0, ComplianceRow { jacobian: RowVector2::new(1.0, 0.0), jacobian_rate: RowVector2::zeros(),
///     stiffness_force: -10.0, damping_force: 0.0, potential: 0.5 }).unwrap();
/// let mut out = Decomposition::<f64, 2, 1>::default();
/// decompose(&MultilevelConfig::default(), &stack, &dynamics, &mut out).unwrap();
/// let mut storage = [LevelStorage::default(); 1];
/// storage_functions(&MultilevelConfig::default(), &out, &stack, &dynamics, &mut storage).unwrap();
/// // The single level holds all: S = ½ q̇ᵀ M q̇ + V = 0.5 + 0.5 J; no damping, so Ṡ = 0.
/// assert!((storage[0].storage - 1.0).abs() < 1e-12 && storage[0].storage_rate.abs() < 1e-12);
/// ```
pub fn storage_functions<T: RealField + Copy, const N: usize, const R: usize, const L: usize>(
    config: &MultilevelConfig<T>,
    decomposition: &Decomposition<T, N, L>,
    stack: &ComplianceStack<T, N, R>,
    dynamics: &DynamicsTerms<'_, T, N>,
    out: &mut [LevelStorage<T>; L],
) -> Result<(), MultilevelError> {
    config.validate()?;
    if stack.level_count() != decomposition.level_count() {
        return Err(MultilevelError::StackMismatch);
    }
    let half: T = nalgebra::convert(0.5);
    let mut inside = true;
    for (level, slot) in out.iter_mut().enumerate() {
        if level >= decomposition.level_count() {
            *slot = LevelStorage::default();
            continue;
        }
        let (mut torque, mut spring) = (SVector::<T, N>::zeros(), SVector::<T, N>::zeros());
        let (mut potential, mut potential_rate) = (T::zero(), T::zero());
        for row in stack.level(level) {
            torque += row.jacobian.transpose() * row.force();
            spring += row.jacobian.transpose() * row.stiffness_force;
            potential += row.potential;
            potential_rate -= row.stiffness_force * row.jacobian.dot(&dynamics.velocity.transpose());
        }
        let (mut kinetic, mut power, mut residual) = (T::zero(), T::zero(), T::zero());
        for row in decomposition.level_rows(level) {
            let static_force = row.basis.transpose().dot(&spring);
            kinetic += half * row.inertia * row.velocity * row.velocity;
            power += row.velocity * row.basis.transpose().dot(&torque);
            residual += static_force * static_force / row.inertia;
        }
        let static_residual = sqrt(residual);
        inside = inside && kinetic <= config.kinetic_tolerance && static_residual <= config.residual_tolerance;
        *slot = LevelStorage {
            kinetic,
            potential,
            storage: kinetic + potential,
            storage_rate: power + potential_rate,
            static_residual,
            in_set: inside,
        };
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::super::test_support::Fixture;
    use super::super::{coriolis_decoupling, ComplianceRow, ComplianceStack};
    use super::*;
    use crate::test_models::N;

    /// Along the closed loop (5.58) with the exact model, `Ṡ_i` of (5.65) is the true time
    /// derivative of `S_i`: compare with `d/dt S_i = v_iᵀ Λ_i v̇_i + ½ v_iᵀ Λ̇_i v_i + V̇_i`,
    /// `v̇ = J̄ q̈ + J̄̇ q̇`, `q̈ = M⁻¹(τ − C q̇ − g)` and `τ = Σ τ_i^p + τ_μ + g`.
    #[test]
    fn storage_rate_is_the_closed_loop_derivative() {
        for seed in 0..30 {
            let fixture = Fixture::new(seed, &[3, 2]);
            let terms = fixture.terms();
            let out = fixture.decompose().unwrap();
            let mut storage = [LevelStorage::default(); 4];
            storage_functions(&MultilevelConfig::default(), &out, &fixture.stack, &terms, &mut storage).unwrap();
            let mut tau = coriolis_decoupling(&out, &terms) + fixture.gravity;
            for level in 0..3 {
                let task: SVector<f64, N> =
                    fixture.stack.level(level).map(|r| r.jacobian.transpose() * r.force()).sum();
                for r in out.level_rows(level) {
                    tau += r.jacobian.transpose() * r.basis.transpose().dot(&task);
                }
            }
            let qdd = fixture.factor.solve(&(tau - fixture.coriolis * fixture.velocity - fixture.gravity));
            let jbar = out.extended_jacobian();
            let jbar_rate = -jbar * out.basis_rate().transpose() * jbar;
            let vdot = jbar * qdd + jbar_rate * fixture.velocity;
            for (level, level_storage) in storage.iter().enumerate().take(3) {
                let mut rate = 0.0;
                for (k, r) in out.rows().iter().enumerate().filter(|(_, r)| r.level == level) {
                    rate += r.velocity * r.inertia * vdot[k] + 0.5 * r.velocity * r.inertia_rate * r.velocity;
                }
                rate -= fixture
                    .stack
                    .level(level)
                    .map(|r| r.stiffness_force * r.jacobian.dot(&fixture.velocity.transpose()))
                    .sum::<f64>();
                let expected = level_storage.storage_rate;
                assert!(
                    (rate - expected).abs() < 1e-8 * (1.0 + expected.abs()),
                    "seed {seed} level {level}: {rate} vs {expected}"
                );
            }
        }
    }

    #[test]
    fn set_membership_is_nested_and_mismatched_stacks_are_refused() {
        let fixture = Fixture::new(2, &[3, 2]);
        let terms = fixture.terms();
        let out = fixture.decompose().unwrap();
        let mut storage = [LevelStorage::default(); 4];
        let loose = MultilevelConfig { kinetic_tolerance: 1e9, residual_tolerance: 1e9, ..MultilevelConfig::default() };
        storage_functions(&loose, &out, &fixture.stack, &terms, &mut storage).unwrap();
        assert_eq!(storage.map(|s| s.in_set), [true, true, true, false]);
        storage_functions(&MultilevelConfig::default(), &out, &fixture.stack, &terms, &mut storage).unwrap();
        assert!(storage.iter().all(|s| !s.in_set));
        assert!(storage[..3].iter().all(|s| s.kinetic > 0.0 && (s.storage - s.kinetic - s.potential).abs() < 1e-12));
        let mut other = ComplianceStack::<f64, N, 16>::new();
        let row: ComplianceRow<f64, N> = fixture.stack.rows()[0].1;
        other.push(0, row).unwrap();
        assert_eq!(
            storage_functions(&MultilevelConfig::default(), &out, &other, &terms, &mut storage),
            Err(MultilevelError::StackMismatch)
        );
    }
}
