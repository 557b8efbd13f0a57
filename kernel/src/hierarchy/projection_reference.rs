//! The plain scalar-inverse projector recursion: the straightforward nalgebra form of
//! [`project`](super::project) it replaced (the rank-one updates of (4.13) with `W⁻¹` applied by
//! full Cholesky solves, every product a generic nalgebra one). Test builds only: it is the
//! reference the fast recursion is compared with (kernel unit tests on the small test models,
//! `thesis-tests` on the Justin model, which include this file by path).
//!
//! The including module provides the names it uses (`use super::*`): nalgebra's `RealField`,
//! `SMatrix`, `SVector`, the hierarchy's `HierarchyConfig`, `Recursion`, `Shaping`, `Stack`,
//! `Weighting`, `RowDiagnostics`, `LevelDiagnostics` and `transition_activation`.

use super::*;

/// Everything the reference projection produces (the outputs of `HierarchyData`).
#[derive(Clone, Debug)]
pub struct ReferenceOutput<T: RealField, const N: usize, const R: usize, const L: usize> {
    /// Accumulated projector after the last level.
    pub projector: SMatrix<T, N, N>,
    /// `τ = Σ_i N_i τ_i` (4.7).
    pub torque: SVector<T, N>,
    /// Per-row diagnostics, stack order processed level by level.
    pub rows: [RowDiagnostics<T>; R],
    /// Per-level diagnostics.
    pub levels: [LevelDiagnostics<T>; L],
    /// Projected torque of each level.
    pub level_torques: [SVector<T, N>; L],
    /// Number of levels.
    pub level_count: usize,
}

/// The reference recursion for a valid stack (at most `R` rows, levels below `L`; the caller
/// checks this, no validation here).
pub fn project_reference<T: RealField + Copy, const N: usize, const R: usize, const RS: usize, const L: usize>(
    config: &HierarchyConfig<'_, T, N>,
    stack: &Stack<T, N, RS>,
) -> ReferenceOutput<T, N, R, L> {
    let mut data = ReferenceOutput {
        projector: SMatrix::identity(),
        torque: SVector::zeros(),
        rows: [RowDiagnostics {
            level: 0,
            activation: T::zero(),
            projected_norm_ratio: T::zero(),
            transmission: T::zero(),
        }; R],
        levels: [LevelDiagnostics { torque_norm: T::zero(), projected_torque_norm: T::zero(), conflict: T::zero() }; L],
        level_torques: [SVector::zeros(); L],
        level_count: stack.level_count(),
    };
    let mut level_projector = SMatrix::<T, N, N>::identity();
    let level_count = stack.level_count();
    let mut diagnostics = data.rows.iter_mut();
    for (level, (level_diagnostics, level_torque)) in
        data.levels.iter_mut().zip(data.level_torques.iter_mut()).enumerate().take(level_count)
    {
        let on_level = || stack.rows().iter().filter(move |r| r.level == level);
        let input = data.projector;
        let torque: SVector<T, N> =
            on_level().fold(SVector::zeros(), |t, r| t + r.row.jacobian.transpose() * r.row.force);
        let projected = apply_projector(&config.weighting, &input, &torque);
        data.torque += projected;
        *level_torque = projected;
        *level_diagnostics = level_result(&torque, &projected);

        if config.recursion == Recursion::Successive {
            level_projector = SMatrix::identity();
        }
        let last = level + 1 == level_count;
        for stack_row in on_level() {
            if last && !config.diagnose_last_level {
                if let Some(slot) = diagnostics.next() {
                    *slot = RowDiagnostics {
                        level,
                        activation: stack_row.row.activation,
                        projected_norm_ratio: T::zero(),
                        transmission: transmission(&config.weighting, &input, &stack_row.row.jacobian.transpose()),
                    };
                }
                continue;
            }
            let working = match config.recursion {
                Recursion::Successive => &mut level_projector,
                Recursion::Augmented | Recursion::Unprojected => &mut data.projector,
            };
            let mut row =
                update_row(config, &input, working, stack_row.row.jacobian.transpose(), stack_row.row.activation);
            row.level = level;
            if let Some(slot) = diagnostics.next() {
                *slot = row;
            }
        }
        if config.recursion == Recursion::Successive {
            data.projector *= level_projector;
        }
    }
    data
}

fn update_row<T: RealField + Copy, const N: usize>(
    config: &HierarchyConfig<'_, T, N>,
    input: &SMatrix<T, N, N>,
    working: &mut SMatrix<T, N, N>,
    row: SVector<T, N>,
    task_activation: T,
) -> RowDiagnostics<T> {
    let transmission = transmission(&config.weighting, input, &row);
    let reference = row.dot(&metric_solve(&config.weighting, &row));
    let projected = *working * row;
    let w = metric_solve(&config.weighting, &projected);
    let s = projected.dot(&w);
    if !reference.is_finite() || reference <= T::zero() {
        return RowDiagnostics { level: 0, activation: T::zero(), projected_norm_ratio: T::zero(), transmission };
    }
    let ratio = (s.max(T::zero()) / reference).sqrt();
    let clamped = task_activation.max(T::zero()).min(T::one());
    let activation = match config.shaping {
        Shaping::Continuous { singular_full, singular_start } => {
            clamped * (T::one() - transition_activation(ratio, singular_full, singular_start))
        }
        Shaping::Discontinuous { singular_threshold } => {
            if clamped > T::zero() && ratio > singular_threshold {
                T::one()
            } else {
                T::zero()
            }
        }
    };
    if activation > T::zero() && s > T::zero() && config.recursion != Recursion::Unprojected {
        let u = *working * projected;
        *working -= u * (w.transpose() * (activation / s));
    }
    RowDiagnostics { level: 0, activation, projected_norm_ratio: ratio, transmission }
}

fn transmission<T: RealField + Copy, const N: usize>(
    weighting: &Weighting<'_, T, N>,
    input: &SMatrix<T, N, N>,
    row: &SVector<T, N>,
) -> T {
    let row_norm = row.norm();
    if row_norm > T::zero() {
        apply_projector(weighting, input, row).norm() / row_norm
    } else {
        T::one()
    }
}

fn metric_solve<T: RealField + Copy, const N: usize>(
    weighting: &Weighting<'_, T, N>,
    x: &SVector<T, N>,
) -> SVector<T, N> {
    match weighting {
        Weighting::Identity | Weighting::AccelerationBased(_) => *x,
        Weighting::Inertia(factor) | Weighting::Stiffness(factor) => factor.solve(x),
    }
}

fn apply_projector<T: RealField + Copy, const N: usize>(
    weighting: &Weighting<'_, T, N>,
    projector: &SMatrix<T, N, N>,
    torque: &SVector<T, N>,
) -> SVector<T, N> {
    match weighting {
        Weighting::AccelerationBased(mass) => {
            let l = mass.l();
            l * (l.transpose() * (projector * mass.solve(torque)))
        }
        _ => projector * torque,
    }
}

fn level_result<T: RealField + Copy, const N: usize>(
    torque: &SVector<T, N>,
    projected: &SVector<T, N>,
) -> LevelDiagnostics<T> {
    let (torque_norm, projected_torque_norm) = (torque.norm(), projected.norm());
    let conflict = if torque_norm > T::zero() {
        (T::one() - projected_torque_norm / torque_norm).max(T::zero()).min(T::one())
    } else {
        T::zero()
    };
    LevelDiagnostics { torque_norm, projected_torque_norm, conflict }
}
