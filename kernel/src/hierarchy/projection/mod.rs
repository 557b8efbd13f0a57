//! The scalar-inverse projector recursion.

mod kernels;

use nalgebra::{RealField, SMatrix, SVector};

use super::config::{HierarchyConfig, Recursion, Shaping, Weighting};
use super::error::HierarchyError;
use super::stack::Stack;
use crate::math::sqrt;
use kernels::{
    cholesky_inverse, column_norms_of, dot, mat_vec, mat_vec_dot, norm_squared, projected_norm_squared_adding,
    quadratic_form, rank_one_update,
};
#[cfg(test)]
use {
    super::transition::push_transitioning,
    crate::tasks::{TaskRow, TaskRows},
    nalgebra::RowSVector,
};

/// What the recursion did with one row (stack order).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowDiagnostics<T> {
    /// Priority level of the row.
    pub level: usize,
    /// Activation used in the projector update: task activation × singularity shaping.
    pub activation: T,
    /// Projected-row norm ratio `ρ = √(j̄W⁻¹j̄ᵀ / jW⁻¹jᵀ)`: 1 = independent of the rows above,
    /// 0 = fully dependent (algorithmic singularity). 0 for a zero row.
    pub projected_norm_ratio: T,
    /// `‖N_in jᵀ‖ / ‖jᵀ‖`: the share of the row's torque direction its level's input projector
    /// passes (as `r₂` in Fig. 4.17). 1 on the first level. `None` for the rows of the last
    /// level without diagnostics ([`HierarchyConfig::diagnose_last_level`]), which do not form it.
    pub transmission: Option<T>,
}

/// Per-level result of the projection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelDiagnostics<T> {
    /// `‖τ_i‖`: norm of the level's task torque before projection (Nm).
    pub torque_norm: T,
    /// `‖τ_i^p‖`: after projection (Nm).
    pub projected_torque_norm: T,
    /// Conflict with the levels above, `1 − ‖τ_i^p‖/‖τ_i‖ ∈ [0, 1]` (0 if `τ_i = 0`).
    pub conflict: T,
}

/// Workspace and outputs of [`project`] for `N` coordinates, `R` rows, `L` levels.
#[derive(Clone, Debug)]
pub struct HierarchyData<T: RealField, const N: usize, const R: usize, const L: usize> {
    /// Accumulated projector after the last level (torque space; `N^s` of the static
    /// recursion for the acceleration-based weighting).
    pub projector: SMatrix<T, N, N>,
    /// The projector of the current level alone (successive recursion).
    level_projector: SMatrix<T, N, N>,
    /// The resulting torque `τ = Σ_i N_i τ_i` (4.7).
    pub torque: SVector<T, N>,
    /// Diagnostics per row, stack order (the first `stack.rows().len()` are valid).
    pub rows: [RowDiagnostics<T>; R],
    /// Diagnostics per level (the first `level_count` are valid).
    pub levels: [LevelDiagnostics<T>; L],
    /// Projected torque `N_i τ_i` of each level (the first `level_count` are valid; they sum to
    /// [`Self::torque`]). Used to saturate with priority (lower levels are scaled first).
    pub level_torques: [SVector<T, N>; L],
    /// Number of levels of the last projection.
    pub level_count: usize,
}

impl<T: RealField + Copy, const N: usize, const R: usize, const L: usize> Default for HierarchyData<T, N, R, L> {
    fn default() -> Self {
        Self {
            projector: SMatrix::identity(),
            level_projector: SMatrix::identity(),
            torque: SVector::zeros(),
            rows: [RowDiagnostics {
                level: 0,
                activation: T::zero(),
                projected_norm_ratio: T::zero(),
                transmission: None,
            }; R],
            levels: [LevelDiagnostics { torque_norm: T::zero(), projected_torque_norm: T::zero(), conflict: T::zero() };
                L],
            level_torques: [SVector::zeros(); L],
            level_count: 0,
        }
    }
}

/// Projects the stack into one torque `τ = Σ_i N_i τ_i` (4.7), `τ_i = Σ_{rows on i} jᵀ f`.
///
/// Levels are processed from 0 (highest priority) upwards. All rows of level `i` share the
/// input projector `N_i` (successive: product of the level projectors above (4.4)–(4.6);
/// augmented: the accumulated projector (4.9)–(4.13)). Then, row by row in stack order, the
/// projected row `j̄ᵀ = N jᵀ` (augmented: the accumulated `N`; successive: the projector of
/// this level's earlier rows) and `w = W⁻¹ j̄ᵀ` give the scalar `s = j̄ w`, and
/// `N ← N − a (N j̄ᵀ) wᵀ / s` — the only inversion is `1/s`. With [`Weighting::AccelerationBased`]
/// the recursion is the static one and the level torque is mapped as `M N (M⁻¹ τ_i)`
/// (4.38)–(4.42).
///
/// With `W = L Lᵀ` (the Cholesky factor of [`Weighting::Inertia`] or [`Weighting::Stiffness`])
/// `W⁻¹ = L⁻ᵀL⁻¹` is formed once per projection (about `N³/2` multiply-adds, only if some row
/// updates the projector) from the factor's column-major storage, and each row applies it by
/// two mat-vecs: `jW⁻¹jᵀ = j (W⁻¹jᵀ)` and `w = W⁻¹j̄ᵀ`. All mat-vecs run column by column over
/// the column-major storage and skip the zero entries of the vector (task rows are sparse, and
/// projected rows keep zeros where the projector does not couple); the rank-one update works in
/// place on the projector's columns. The transmissions of a level's rows are computed against
/// its input projector before its first update, so no copy of the projector is made, and while
/// the input projector is still exactly `I` (the first level) the level torque and the
/// transmissions need no mat-vec at all. Below it, a row with a single nonzero entry `b` (a
/// joint row) adds its one product to the task torque and transmits the column norm
/// `‖N_in e_b‖`; the `N` column norms are formed once per level. The rows of the last level
/// without diagnostics only add their torque (no transmission). A given `W⁻¹`
/// ([`Weighting::InverseInertia`]) is used in place, and a row that carries its `jW⁻¹jᵀ`
/// ([`super::StackRow::metric_norm_squared`], computed by its task over the factor this
/// `W⁻¹` inverts) skips the quadratic form; the caller guarantees that the carried value
/// belongs to the given `W⁻¹`.
///
/// A row's activation `a` is its task activation times the shaping of its norm ratio `ρ`
/// ([`Shaping`]); with the continuous shaping, `a → 0` before `s → 0`, so `1/s` is only formed
/// for `s ≥ ρ₁² jW⁻¹jᵀ > 0`, and the torque is continuous through rank changes. A zero row
/// neither acts nor locks. The task force `f` is applied unscaled: unilateral tasks fade their
/// own force with their potential.
///
/// Writes `data` and returns the torque. Cost: at most `5 N²` multiply-adds per row that updates
/// the projector (`4 N²` for one that does not lock), the row's nonzero entries per row of the
/// last level without diagnostics, and `N²` once per level for the level torque.
/// Errors (nothing written): a level `≥ L`, more rows than `R`, an invalid shaping band (a
/// non-finite row cannot be on the stack: [`Stack::push`] refuses it).
pub fn project<'d, T: RealField + Copy, const N: usize, const R: usize, const RS: usize, const L: usize>(
    config: &HierarchyConfig<'_, T, N>,
    stack: &Stack<T, N, RS>,
    data: &'d mut HierarchyData<T, N, R, L>,
) -> Result<&'d SVector<T, N>, HierarchyError> {
    validate(config, stack, R, L)?;
    let level_count = stack.level_count();
    let HierarchyData { projector, level_projector, torque, rows, levels, level_torques, level_count: count } = data;
    *projector = SMatrix::identity();
    *torque = SVector::zeros();
    *count = level_count;
    let mut scratch = Scratch::<T, N>::default();
    // W⁻¹ once for all rows that update the projector: L⁻ᵀL⁻¹ from a Cholesky factor, or given.
    let updates = level_count > 1 || config.diagnose_last_level;
    let factor_inverse = match config.weighting {
        Weighting::Inertia(factor) | Weighting::Stiffness(factor) if updates => {
            Some(cholesky_inverse::<T, N>(factor.l_dirty().as_slice()))
        }
        _ => None,
    };
    let metric_inverse = match config.weighting {
        Weighting::InverseInertia(inverse) if updates => Some(inverse),
        _ => factor_inverse.as_ref(),
    };
    let mut first_slot = 0;
    let mut identity = true;
    // The working projector is still exactly `I` (no rank-one update applied to it yet).
    let mut working_identity = true;
    for (level, (level_diagnostics, level_torque)) in
        levels.iter_mut().zip(level_torques.iter_mut()).enumerate().take(level_count)
    {
        let on_level = || stack.rows().iter().filter(move |r| r.level == level);
        // The input projector is still exactly `I` (the first level, or no projection): then
        // `N τ = τ` and every transmission is 1 without a mat-vec.
        let accelerated = matches!(config.weighting, Weighting::AccelerationBased(_));
        let identity_input = identity && !accelerated;

        // The task torque `τ_i = Σ jᵀ f` and the diagnostics against the level's input
        // projector, before any row of the level updates it. A row with one nonzero entry `b`
        // (joint rows `e_bᵀ`) adds its one product to `τ_i` and transmits `‖N_in e_b‖`: the
        // column norms of `N_in` are formed once per level, when the first such row appears.
        let mut task_torque = SVector::<T, N>::zeros();
        let mut level_rows = 0;
        let mut column_norms: Option<[T; N]> = None;
        // Nothing lies below the last level: without diagnostics its rows lock nothing and
        // form no transmission (they keep their task activation, ρ = 0).
        let last = level + 1 == level_count;
        let diagnosed = !last || config.diagnose_last_level;
        for (slot, r) in rows.iter_mut().skip(first_slot).zip(on_level()) {
            let row = r.row.jacobian.as_slice();
            let force = r.row.force;
            let single = if identity_input || accelerated || !diagnosed { None } else { single_entry(row) };
            let transmission = match single.and_then(|b| task_torque.get_mut(b).zip(row.get(b)).map(|tj| (b, tj))) {
                Some((b, (t, &j))) => {
                    *t += j * force;
                    Some(
                        column_norms
                            .get_or_insert_with(|| column_norms_of::<T, N>(projector.as_slice()))
                            .get(b)
                            .copied()
                            .unwrap_or_else(T::one),
                    )
                }
                None if identity_input || !diagnosed => {
                    // A row over some columns adds over those only (the other terms are `±0`:
                    // the same sums).
                    let torque = task_torque.as_mut_slice();
                    match r.support {
                        (0, end) if end >= N => add_scaled(torque, row, force),
                        (first, end) => add_scaled(
                            torque.get_mut(first..end).unwrap_or_default(),
                            row.get(first..end).unwrap_or_default(),
                            force,
                        ),
                    }
                    diagnosed.then_some(T::one())
                }
                None => Some(transmission(&config.weighting, projector, row, force, &mut task_torque, &mut scratch.u)),
            };
            *slot =
                RowDiagnostics { level, activation: r.row.activation, projected_norm_ratio: T::zero(), transmission };
            level_rows += 1;
        }
        if identity_input {
            *level_torque = task_torque;
        } else {
            apply_projector(&config.weighting, projector, task_torque.as_slice(), level_torque);
        }
        for (t, &p) in torque.as_mut_slice().iter_mut().zip(level_torque.as_slice()) {
            *t += p;
        }
        *level_diagnostics = level_result(&task_torque, level_torque);

        if diagnosed {
            if config.recursion == Recursion::Successive {
                *level_projector = SMatrix::identity();
                working_identity = true;
            }
            for (slot, r) in rows.iter_mut().skip(first_slot).zip(on_level()) {
                let working = match config.recursion {
                    Recursion::Successive => &mut *level_projector,
                    Recursion::Augmented | Recursion::Unprojected => &mut *projector,
                };
                // A carried `j W⁻¹ jᵀ` is one of the step's inverse inertia.
                let carried = match config.weighting {
                    Weighting::InverseInertia(_) => r.metric_norm_squared,
                    _ => None,
                };
                let (activation, ratio, updated) = update_row(
                    config,
                    metric_inverse,
                    working,
                    working_identity,
                    r.row.jacobian.as_slice(),
                    r.row.activation,
                    carried,
                    &mut scratch,
                );
                working_identity &= !updated;
                slot.activation = activation;
                slot.projected_norm_ratio = ratio;
            }
            if config.recursion == Recursion::Successive {
                *projector *= *level_projector;
            }
            identity &= config.recursion == Recursion::Unprojected;
        }
        first_slot += level_rows;
    }
    Ok(&data.torque)
}

/// Vectors of one row's update.
struct Scratch<T: RealField, const N: usize> {
    /// `j̄ᵀ = N jᵀ`.
    projected: SVector<T, N>,
    /// `W⁻¹ jᵀ`, then `w = W⁻¹ j̄ᵀ` (metric weightings only).
    w: SVector<T, N>,
    /// `N j̄ᵀ` (and the transmission's `N_in jᵀ`).
    u: SVector<T, N>,
}

impl<T: RealField + Copy, const N: usize> Default for Scratch<T, N> {
    fn default() -> Self {
        Self { projected: SVector::zeros(), w: SVector::zeros(), u: SVector::zeros() }
    }
}

/// The rank-one update `N ← N − a (N j̄ᵀ) wᵀ / s` of one row (the remark after Table 4.3,
/// (4.13) with (4.70)–(4.72)); returns its activation `a`, norm ratio `ρ` and whether the
/// projector was updated. While `working` is exactly `I` (`identity`), `j̄ᵀ = N jᵀ = jᵀ`,
/// `N j̄ᵀ = jᵀ`, `W⁻¹j̄ᵀ = W⁻¹jᵀ` and `s = jW⁻¹jᵀ` are taken without their mat-vecs. Below
/// that, a `carried` `jW⁻¹jᵀ` (the row's [`StackRow::metric_norm_squared`](super::StackRow)
/// with the inverse-inertia weighting) replaces the quadratic form.
#[allow(clippy::too_many_arguments, reason = "the row, its carried metric and the recursion's state")]
fn update_row<T: RealField + Copy, const N: usize>(
    config: &HierarchyConfig<'_, T, N>,
    metric_inverse: Option<&SMatrix<T, N, N>>,
    working: &mut SMatrix<T, N, N>,
    identity: bool,
    row: &[T],
    task_activation: T,
    carried: Option<T>,
    scratch: &mut Scratch<T, N>,
) -> (T, T, bool) {
    // jW⁻¹jᵀ (or |j|²); W⁻¹jᵀ skips the zero entries of the row and is kept only while the
    // working projector is `I` (then it is also `w`).
    let reference = match (metric_inverse, carried) {
        (Some(inverse), _) if identity => {
            mat_vec::<T, N>(inverse.as_slice(), row, scratch.w.as_mut_slice());
            dot(row, scratch.w.as_slice())
        }
        (Some(_), Some(carried)) => carried,
        (Some(inverse), None) => quadratic_form::<T, N>(inverse.as_slice(), row),
        (None, _) => norm_squared(row),
    };
    if !reference.is_finite() || reference <= T::zero() {
        return (T::zero(), T::zero(), false);
    }
    // w = W⁻¹j̄ᵀ, s = j̄ w (or w = j̄ᵀ, s = |j̄|²).
    let s = if identity {
        // W⁻¹jᵀ is already in `scratch.w`.
        for (p, &j) in scratch.projected.as_mut_slice().iter_mut().zip(row) {
            *p = j;
        }
        reference
    } else {
        mat_vec::<T, N>(working.as_slice(), row, scratch.projected.as_mut_slice());
        match metric_inverse {
            Some(inverse) => {
                mat_vec_dot::<T, N>(inverse.as_slice(), scratch.projected.as_slice(), scratch.w.as_mut_slice())
            }
            None => norm_squared(scratch.projected.as_slice()),
        }
    };
    let ratio = sqrt(s.max(T::zero()) / reference);
    let activation = config.shaping.row_activation(task_activation, ratio);
    let updated = activation > T::zero() && s > T::zero() && config.recursion != Recursion::Unprojected;
    if updated {
        let u = if identity {
            scratch.projected.as_slice()
        } else {
            mat_vec::<T, N>(working.as_slice(), scratch.projected.as_slice(), scratch.u.as_mut_slice());
            scratch.u.as_slice()
        };
        let w = match metric_inverse {
            Some(_) => scratch.w.as_slice(),
            None => scratch.projected.as_slice(),
        };
        rank_one_update::<T, N>(working.as_mut_slice(), u, w, activation / s);
    }
    (activation, ratio, updated)
}

/// `‖N_in jᵀ‖ / ‖jᵀ‖` (the acceleration-based projector: `‖M N M⁻¹ jᵀ‖ / ‖jᵀ‖`), 1 for a zero
/// row; adds `jᵀ f` to `task_torque`. `tmp` receives the projected row (acceleration-based
/// projector only; the others form both norms and the torque in one pass over the nonzero
/// entries of the row, [`projected_norm_squared_adding`]).
fn transmission<T: RealField + Copy, const N: usize>(
    weighting: &Weighting<'_, T, N>,
    input: &SMatrix<T, N, N>,
    row: &[T],
    force: T,
    task_torque: &mut SVector<T, N>,
    tmp: &mut SVector<T, N>,
) -> T {
    let (row_squared, projected_squared) = match weighting {
        Weighting::AccelerationBased(_) => {
            add_scaled(task_torque.as_mut_slice(), row, force);
            let row_squared = norm_squared(row);
            if row_squared > T::zero() {
                apply_projector(weighting, input, row, tmp);
            }
            (row_squared, norm_squared(tmp.as_slice()))
        }
        _ => projected_norm_squared_adding::<T, N>(input.as_slice(), row, force, task_torque.as_mut_slice()),
    };
    if row_squared > T::zero() {
        sqrt(projected_squared / row_squared)
    } else {
        T::one()
    }
}

/// `t ← t + x f`.
fn add_scaled<T: RealField + Copy>(t: &mut [T], x: &[T], f: T) {
    for (t, &x) in t.iter_mut().zip(x) {
        *t += x * f;
    }
}

/// The index of the only nonzero entry of `row`; `None` for a zero row or several nonzero
/// entries.
fn single_entry<T: RealField + Copy>(row: &[T]) -> Option<usize> {
    let mut nonzero = row.iter().enumerate().filter(|(_, &x)| x != T::zero());
    match (nonzero.next(), nonzero.next()) {
        (Some((b, _)), None) => Some(b),
        _ => None,
    }
}

/// `out = N τ`, or `M N M⁻¹ τ` for the acceleration-based projector (4.38).
fn apply_projector<T: RealField + Copy, const N: usize>(
    weighting: &Weighting<'_, T, N>,
    projector: &SMatrix<T, N, N>,
    torque: &[T],
    out: &mut SVector<T, N>,
) {
    match weighting {
        Weighting::AccelerationBased(mass) => {
            let l = mass.l();
            *out = l * (l.transpose() * (projector * mass.solve(&SVector::from_iterator(torque.iter().copied()))));
        }
        _ => mat_vec::<T, N>(projector.as_slice(), torque, out.as_mut_slice()),
    }
}

fn level_result<T: RealField + Copy, const N: usize>(
    torque: &SVector<T, N>,
    projected: &SVector<T, N>,
) -> LevelDiagnostics<T> {
    let (torque_norm, projected_torque_norm) = (sqrt(torque.norm_squared()), sqrt(projected.norm_squared()));
    let conflict = if torque_norm > T::zero() {
        (T::one() - projected_torque_norm / torque_norm).max(T::zero()).min(T::one())
    } else {
        T::zero()
    };
    LevelDiagnostics { torque_norm, projected_torque_norm, conflict }
}

fn validate<T: RealField + Copy, const N: usize, const RS: usize>(
    config: &HierarchyConfig<'_, T, N>,
    stack: &Stack<T, N, RS>,
    row_capacity: usize,
    level_capacity: usize,
) -> Result<(), HierarchyError> {
    if stack.rows().len() > row_capacity {
        return Err(HierarchyError::Capacity { capacity: row_capacity });
    }
    if stack.level_count() > level_capacity {
        return Err(HierarchyError::TooManyLevels { capacity: level_capacity });
    }
    // The rows are finite: the stack refuses others.
    let band_ok = match config.shaping {
        Shaping::Continuous { singular_full, singular_start } => {
            singular_full.is_finite()
                && singular_start.is_finite()
                && T::zero() < singular_full
                && singular_full < singular_start
        }
        Shaping::Discontinuous { singular_threshold } => {
            singular_threshold.is_finite() && singular_threshold >= T::zero()
        }
    };
    if band_ok {
        Ok(())
    } else {
        Err(HierarchyError::InvalidShaping)
    }
}

#[cfg(test)]
#[path = "../projection_reference.rs"]
mod reference;

#[cfg(test)]
mod tests;
