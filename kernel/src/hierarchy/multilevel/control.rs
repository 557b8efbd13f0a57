//! The multi-level compliance control law (5.58)–(5.60) with its telemetry.

use nalgebra::{RealField, SVector};

use super::compliance_stack::ComplianceStack;
use super::config::{DynamicsTerms, MultilevelConfig};
use super::coriolis_decoupling::coriolis_decoupling;
use super::decomposition::{decompose, Decomposition};
use super::error::MultilevelError;
use super::storage::{storage_functions, LevelStorage};

/// Workspace and outputs of [`multilevel_control`] for `N` coordinates and `L` levels.
#[derive(Clone, Debug, PartialEq)]
pub struct MultilevelData<T, const N: usize, const L: usize> {
    /// The hierarchical dynamics representation of the last call ([`decompose`]).
    pub decomposition: Decomposition<T, N, L>,
    /// Projected compliance torque of each level, `τ_i^p = −J̄_iᵀ Z_i J_iᵀ F_i` (5.59) (Nm); the
    /// first `level_count` entries are valid.
    pub level_torques: [SVector<T, N>; L],
    /// Coriolis decoupling `τ_μ` (5.60) (Nm); zero when switched off.
    pub coriolis_torque: SVector<T, N>,
    /// The command `τ = Σ_i τ_i^p + τ_μ + g(q)` (5.58) (Nm).
    pub torque: SVector<T, N>,
    /// Storage functions, rates and set memberships per level ([`storage_functions`]).
    pub storage: [LevelStorage<T>; L],
}

impl<T: RealField + Copy, const N: usize, const L: usize> Default for MultilevelData<T, N, L> {
    fn default() -> Self {
        Self {
            decomposition: Decomposition::default(),
            level_torques: [SVector::zeros(); L],
            coriolis_torque: SVector::zeros(),
            torque: SVector::zeros(),
            storage: [LevelStorage::default(); L],
        }
    }
}

/// Multi-objective compliance control (5.58): `τ = Σ_i τ_i^p + τ_μ + g(q)` with the projected
/// compliances `τ_i^p = J̄_iᵀ Z_i τ_i` (5.59), `τ_i = Σ_rows jᵀ f = −J_iᵀ((∂V_i/∂x_i)ᵀ + D_i ẋ_i)`,
/// and, if [`MultilevelConfig::coriolis_decoupling`] is set, the power-conserving Coriolis
/// decoupling `τ_μ` (5.60). By `J̄ Zᵀ = I`, `Z_j τ_i^p = 0` for `j ≠ i`: each level's torque
/// acts only on its own dynamics (5.62), and `J̄_iᵀ Z_i J_iᵀ = N_i J_iᵀ` (5.50) makes it the
/// dynamically consistent projection of Chapter 4. With the exact model, gravity compensation
/// and `τ_μ`, the equilibrium (the hierarchy-consistent constrained minimum) is asymptotically
/// stable (Proposition 5.1).
///
/// Runs [`decompose`], [`coriolis_decoupling`] and [`storage_functions`] and writes every
/// output of `data`. Inputs: the rows of all levels and the controller's model terms at
/// `(q, q̇)`, `g(q)` included. Cost O(m N² + N³ + L N²) (`m` rows above the last level).
/// Errors: those of [`decompose`]; `data.torque` is then left as it was, so the caller can hold
/// or replace it with its safe output.
///
/// ```
/// use kernel::hierarchy::multilevel::*;
/// use nalgebra::{Matrix2, RowVector2, Vector2};
/// // M = diag(1, 4); level 0 pushes x₁ + x₂ with 2 N, level 1 pushes x₁ with 3 N.
/// let m = Matrix2::new(1.0, 0.0, 0.0, 4.0);
/// let factor = m.cholesky().unwrap();
/// let (c, g, qd) = (Matrix2::zeros(), Vector2::zeros(), Vector2::zeros());
/// let dynamics = DynamicsTerms { mass_matrix: &m, mass_factor: &factor, coriolis: &c, gravity: &g, velocity: &qd };
/// let row = |j: RowVector2<f64>, f: f64| ComplianceRow { jacobian: j, jacobian_rate: RowVector2::zeros(),
///     stiffness_force: f, damping_force: 0.0, potential: 0.0 };
/// let mut stack = ComplianceStack::<f64, 2, 4>::new();
/// stack.push(0, row(RowVector2::new(1.0, 1.0), 2.0)).unwrap();
/// stack.push(1, row(RowVector2::new(1.0, 0.0), 3.0)).unwrap();
/// let mut data = MultilevelData::<f64, 2, 2>::default();
/// let tau = *multilevel_control(&MultilevelConfig::default(), &stack, &dynamics, &mut data).unwrap();
/// // Level 1 is projected into the null space of level 0: N₂ (3, 0) = (0.6, −2.4).
/// assert!((tau - Vector2::new(2.6, -0.4)).amax() < 1e-12);
/// // It does not accelerate level 0: j₀ M⁻¹ τ₁ᵖ = 0.
/// assert!((RowVector2::new(1.0, 0.25) * data.level_torques[1])[0].abs() < 1e-12);
/// ```
pub fn multilevel_control<'d, T: RealField + Copy, const N: usize, const R: usize, const L: usize>(
    config: &MultilevelConfig<T>,
    stack: &ComplianceStack<T, N, R>,
    dynamics: &DynamicsTerms<'_, T, N>,
    data: &'d mut MultilevelData<T, N, L>,
) -> Result<&'d SVector<T, N>, MultilevelError> {
    decompose(config, stack, dynamics, &mut data.decomposition)?;
    let decomposition = &data.decomposition;
    let mut torque = *dynamics.gravity;
    for (level, slot) in data.level_torques.iter_mut().enumerate() {
        let task: SVector<T, N> =
            stack.level(level).fold(SVector::zeros(), |t, r| t + r.jacobian.transpose() * r.force());
        *slot = decomposition
            .level_rows(level)
            .iter()
            .fold(SVector::zeros(), |t, r| t + r.jacobian.transpose() * r.basis.transpose().dot(&task));
        torque += *slot;
    }
    data.coriolis_torque =
        if config.coriolis_decoupling { coriolis_decoupling(decomposition, dynamics) } else { SVector::zeros() };
    torque += data.coriolis_torque;
    storage_functions(config, decomposition, stack, dynamics, &mut data.storage)?;
    data.torque = torque;
    Ok(&data.torque)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::super::test_support::Fixture;
    use super::*;
    use crate::hierarchy::{project, HierarchyConfig, HierarchyData, Recursion, Shaping, Stack, Weighting};
    use crate::tasks::TaskRow;
    use crate::test_models::N;

    /// Without `τ_μ`, the control law equals the augmented, dynamically consistent projection
    /// of Chapter 4 (`Σ N_i τ_i + g`, [`project`]) whenever the last level's rows are a full
    /// basis of the remaining null space — here the joint impedance on all coordinates.
    #[test]
    fn equals_the_chapter_4_projection_plus_decoupling() {
        for seed in 0..30 {
            let fixture = Fixture::new(seed, &[3, 2]);
            let terms = fixture.terms();
            let mut stack = Stack::<f64, N, 16>::new();
            for (level, row) in fixture.stack.rows() {
                stack
                    .push(
                        *level,
                        TaskRow { jacobian: row.jacobian, force: row.force(), potential: 0.0, activation: 1.0 },
                    )
                    .unwrap();
            }
            let config = HierarchyConfig {
                recursion: Recursion::Augmented,
                weighting: Weighting::Inertia(&fixture.factor),
                shaping: Shaping::Continuous { singular_full: 1e-6, singular_start: 2e-6 },
                diagnose_last_level: true,
            };
            let mut projection = HierarchyData::<f64, N, 16, 4>::default();
            let expected = project(&config, &stack, &mut projection).unwrap() + fixture.gravity;
            let mut data = MultilevelData::<f64, N, 4>::default();
            let off = MultilevelConfig { coriolis_decoupling: false, ..MultilevelConfig::default() };
            let tau = *multilevel_control(&off, &fixture.stack, &terms, &mut data).unwrap();
            assert!((tau - expected).amax() < 1e-9 * (1.0 + expected.amax()), "seed {seed}");
            assert_eq!(data.coriolis_torque, SVector::<f64, N>::zeros());
            let on = *multilevel_control(&MultilevelConfig::default(), &fixture.stack, &terms, &mut data).unwrap();
            assert!((on - tau - data.coriolis_torque).amax() < 1e-12 * (1.0 + on.amax()));
            // Level torques do not reach the other levels: Z_j τ_i^p = 0 (j ≠ i).
            let z = data.decomposition.basis();
            for (level, t) in data.level_torques.iter().enumerate().take(3) {
                let projected = z * t;
                for (k, r) in data.decomposition.rows().iter().enumerate() {
                    if r.level != level {
                        assert!(projected[k].abs() < 1e-9 * (1.0 + t.amax()), "seed {seed}");
                    }
                }
            }
        }
    }

    #[test]
    fn errors_leave_the_torque() {
        let fixture = Fixture::new(1, &[3, 2]);
        let mut data = MultilevelData::<f64, N, 4> { torque: SVector::repeat(7.0), ..Default::default() };
        let bad = MultilevelConfig { singular_threshold: 0.0, ..MultilevelConfig::default() };
        assert_eq!(
            multilevel_control(&bad, &fixture.stack, &fixture.terms(), &mut data),
            Err(MultilevelError::InvalidConfig)
        );
        assert_eq!(data.torque, SVector::<f64, N>::repeat(7.0));
    }

    #[test]
    fn f32_agrees_with_f64() {
        let fixture = Fixture::new(8, &[3, 2]);
        let mut data = MultilevelData::<f64, N, 4>::default();
        let tau =
            *multilevel_control(&MultilevelConfig::default(), &fixture.stack, &fixture.terms(), &mut data).unwrap();
        let f32_fixture = fixture.cast_f32();
        let mut data32 = MultilevelData::<f32, N, 4>::default();
        let tau32 =
            multilevel_control(&MultilevelConfig::default(), &f32_fixture.stack, &f32_fixture.terms(), &mut data32)
                .unwrap()
                .cast::<f64>();
        assert!((tau - tau32).amax() < 1e-3 * (1.0 + tau.amax()), "{tau} vs {tau32}");
        for level in 0..3 {
            let (a, b) = (data.storage[level].storage, f64::from(data32.storage[level].storage));
            assert!((a - b).abs() < 1e-3 * (1.0 + a.abs()), "level {level}: {a} vs {b}");
        }
    }
}
