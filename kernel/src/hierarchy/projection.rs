//! The scalar-inverse projector recursion.

use nalgebra::{RealField, SMatrix, SVector};

use super::{HierarchyConfig, HierarchyError, Recursion, Shaping, Stack, Weighting};
use crate::math::sqrt;
#[cfg(test)]
use {
    super::push_transitioning,
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
    /// passes (as `r₂` in Fig. 4.17). 1 on the first level.
    pub transmission: T,
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
                transmission: T::zero(),
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
/// transmissions need no mat-vec at all. A row with a single nonzero entry `b` (a joint row)
/// transmits the column norm `‖N_in e_b‖`; the `N` column norms are formed once per level.
///
/// A row's activation `a` is its task activation times the shaping of its norm ratio `ρ`
/// ([`Shaping`]); with the continuous shaping, `a → 0` before `s → 0`, so `1/s` is only formed
/// for `s ≥ ρ₁² jW⁻¹jᵀ > 0`, and the torque is continuous through rank changes. A zero row
/// neither acts nor locks. The task force `f` is applied unscaled: unilateral tasks fade their
/// own force with their potential.
///
/// Writes `data` and returns the torque. Cost: at most `5 N²` multiply-adds per row that updates
/// the projector (`4 N²` for one that does not lock), `N²` (less for sparse rows, none on the
/// first level, a lookup for a joint row after `N²` once per level) per row of the last level
/// without diagnostics.
/// Errors (nothing written): a level `≥ L`, more rows than `R`, a non-finite row, an invalid
/// shaping band.
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
    let metric_inverse = match config.weighting {
        Weighting::Inertia(factor) | Weighting::Stiffness(factor) if updates => {
            Some(cholesky_inverse::<T, N>(factor.l_dirty().as_slice()))
        }
        Weighting::InverseInertia(inverse) if updates => Some(*inverse),
        _ => None,
    };
    let mut first_slot = 0;
    let mut identity = true;
    // The working projector is still exactly `I` (no rank-one update applied to it yet).
    let mut working_identity = true;
    for (level, (level_diagnostics, level_torque)) in
        levels.iter_mut().zip(level_torques.iter_mut()).enumerate().take(level_count)
    {
        let on_level = || stack.rows().iter().filter(move |r| r.level == level);
        let mut task_torque = SVector::<T, N>::zeros();
        for r in on_level() {
            let force = r.row.force;
            for (t, &j) in task_torque.as_mut_slice().iter_mut().zip(r.row.jacobian.as_slice()) {
                *t += j * force;
            }
        }
        // The input projector is still exactly `I` (the first level, or no projection): then
        // `N τ = τ` and every transmission is 1 without a mat-vec.
        let identity_input = identity && !matches!(config.weighting, Weighting::AccelerationBased(_));
        if identity_input {
            *level_torque = task_torque;
        } else {
            apply_projector(&config.weighting, projector, task_torque.as_slice(), level_torque);
        }
        for (t, &p) in torque.as_mut_slice().iter_mut().zip(level_torque.as_slice()) {
            *t += p;
        }
        *level_diagnostics = level_result(&task_torque, level_torque);

        // Diagnostics against the level's input projector, before any row of the level updates it.
        // A row with one nonzero entry `b` (joint rows `e_bᵀ`) transmits `‖N_in e_b‖`: the
        // column norms of `N_in` are formed once per level, when the first such row appears.
        let mut level_rows = 0;
        let mut column_norms: Option<[T; N]> = None;
        let accelerated = matches!(config.weighting, Weighting::AccelerationBased(_));
        for (slot, r) in rows.iter_mut().skip(first_slot).zip(on_level()) {
            let row = r.row.jacobian.as_slice();
            let single = if identity_input || accelerated { None } else { single_entry(row) };
            let transmission = match single {
                _ if identity_input => T::one(),
                Some(b) => column_norms
                    .get_or_insert_with(|| column_norms_of::<T, N>(projector.as_slice()))
                    .get(b)
                    .copied()
                    .unwrap_or_else(T::one),
                None => transmission(&config.weighting, projector, row, &mut scratch.u),
            };
            *slot =
                RowDiagnostics { level, activation: r.row.activation, projected_norm_ratio: T::zero(), transmission };
            level_rows += 1;
        }
        // Nothing lies below the last level: without diagnostics its rows lock nothing (the
        // skipped rows keep their task activation, ρ = 0 and their transmission).
        let last = level + 1 == level_count;
        if !last || config.diagnose_last_level {
            if config.recursion == Recursion::Successive {
                *level_projector = SMatrix::identity();
                working_identity = true;
            }
            for (slot, r) in rows.iter_mut().skip(first_slot).zip(on_level()) {
                let working = match config.recursion {
                    Recursion::Successive => &mut *level_projector,
                    Recursion::Augmented | Recursion::Unprojected => &mut *projector,
                };
                let (activation, ratio, updated) = update_row(
                    config,
                    metric_inverse.as_ref(),
                    working,
                    working_identity,
                    r.row.jacobian.as_slice(),
                    r.row.activation,
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
/// `N j̄ᵀ = jᵀ`, `W⁻¹j̄ᵀ = W⁻¹jᵀ` and `s = jW⁻¹jᵀ` are taken without their mat-vecs.
fn update_row<T: RealField + Copy, const N: usize>(
    config: &HierarchyConfig<'_, T, N>,
    metric_inverse: Option<&SMatrix<T, N, N>>,
    working: &mut SMatrix<T, N, N>,
    identity: bool,
    row: &[T],
    task_activation: T,
    scratch: &mut Scratch<T, N>,
) -> (T, T, bool) {
    // jW⁻¹jᵀ (or |j|²); W⁻¹jᵀ skips the zero entries of the row and is kept only while the
    // working projector is `I` (then it is also `w`).
    let reference = match metric_inverse {
        Some(inverse) if identity => {
            mat_vec::<T, N>(inverse.as_slice(), row, scratch.w.as_mut_slice());
            dot(row, scratch.w.as_slice())
        }
        Some(inverse) => quadratic_form::<T, N>(inverse.as_slice(), row),
        None => norm_squared(row),
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
    let ratio = (s.max(T::zero()) / reference).sqrt();
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
/// row. `tmp` receives the projected row (acceleration-based projector only; the others form
/// both norms in one pass, [`projected_norm_squared`]).
fn transmission<T: RealField + Copy, const N: usize>(
    weighting: &Weighting<'_, T, N>,
    input: &SMatrix<T, N, N>,
    row: &[T],
    tmp: &mut SVector<T, N>,
) -> T {
    let (row_squared, projected_squared) = match weighting {
        Weighting::AccelerationBased(_) => {
            let row_squared = norm_squared(row);
            if row_squared > T::zero() {
                apply_projector(weighting, input, row, tmp);
            }
            (row_squared, norm_squared(tmp.as_slice()))
        }
        _ => projected_norm_squared::<T, N>(input.as_slice(), row),
    };
    if row_squared > T::zero() {
        sqrt(projected_squared / row_squared)
    } else {
        T::one()
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

/// `‖A e_b‖` for every column `b` of the column-major `N × N` matrix `a`: the transmission
/// `‖A jᵀ‖ / ‖jᵀ‖` of every row `j = α e_bᵀ`.
fn column_norms_of<T: RealField + Copy, const N: usize>(a: &[T]) -> [T; N] {
    let mut norms = [T::zero(); N];
    for (norm, column) in norms.iter_mut().zip(a.chunks_exact(N.max(1))) {
        *norm = sqrt(norm_squared(column));
    }
    norms
}

/// `xᵀ A x` for the column-major `N × N` matrix `a`: `A x` over the nonzero entries of `x`,
/// accumulated in registers as in [`mat_vec`] and never stored, then dotted with `x` (bit for
/// bit the sums of [`mat_vec`] and [`dot`]).
fn quadratic_form<T: RealField + Copy, const N: usize>(a: &[T], x: &[T]) -> T {
    let mut sum = [T::zero(); N];
    for (column, &xc) in a.chunks_exact(N.max(1)).zip(x) {
        if xc != T::zero() {
            for (v, &aic) in sum.iter_mut().zip(column) {
                *v += aic * xc;
            }
        }
    }
    dot(x, &sum)
}

/// `(‖x‖², ‖A x‖²)` for the column-major `N × N` matrix `a` in one pass over the nonzero entries
/// of `x`: `A x` is accumulated in registers as in [`mat_vec`] and never stored. The sums equal
/// those of [`norm_squared`] and [`mat_vec`] bit for bit (the skipped terms are `+0`).
fn projected_norm_squared<T: RealField + Copy, const N: usize>(a: &[T], x: &[T]) -> (T, T) {
    let mut sum = [T::zero(); N];
    let mut x_squared = T::zero();
    for (column, &xc) in a.chunks_exact(N.max(1)).zip(x) {
        if xc != T::zero() {
            x_squared += xc * xc;
            for (v, &aic) in sum.iter_mut().zip(column) {
                *v += aic * xc;
            }
        }
    }
    (x_squared, norm_squared(&sum))
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

/// `Σ xᵢ yᵢ`.
fn dot<T: RealField + Copy>(x: &[T], y: &[T]) -> T {
    x.iter().zip(y).fold(T::zero(), |acc, (&a, &b)| acc + a * b)
}

/// `Σ xᵢ²`.
fn norm_squared<T: RealField + Copy>(x: &[T]) -> T {
    x.iter().fold(T::zero(), |acc, &v| acc + v * v)
}

/// `y = A x` for the column-major `N × N` matrix `a`, column by column, accumulated in
/// registers; zero entries of `x` are skipped (task rows are sparse, projected rows often too).
fn mat_vec<T: RealField + Copy, const N: usize>(a: &[T], x: &[T], y: &mut [T]) {
    // Accumulated in a local array the optimiser keeps in registers.
    let mut sum = [T::zero(); N];
    for (column, &xc) in a.chunks_exact(N.max(1)).zip(x) {
        if xc != T::zero() {
            for (v, &aic) in sum.iter_mut().zip(column) {
                *v += aic * xc;
            }
        }
    }
    for (v, s) in y.iter_mut().zip(sum) {
        *v = s;
    }
}

/// `y = A x` as [`mat_vec`], returning `x · y` formed from the registers (bit for bit
/// [`dot`]`(x, y)`).
fn mat_vec_dot<T: RealField + Copy, const N: usize>(a: &[T], x: &[T], y: &mut [T]) -> T {
    let mut sum = [T::zero(); N];
    for (column, &xc) in a.chunks_exact(N.max(1)).zip(x) {
        if xc != T::zero() {
            for (v, &aic) in sum.iter_mut().zip(column) {
                *v += aic * xc;
            }
        }
    }
    for (v, s) in y.iter_mut().zip(sum) {
        *v = s;
    }
    dot(x, &sum)
}

/// `A ← A − u (c w)ᵀ` in place on the column-major `N × N` matrix `a`.
fn rank_one_update<T: RealField + Copy, const N: usize>(a: &mut [T], u: &[T], w: &[T], c: T) {
    for (column, &wc) in a.chunks_exact_mut(N.max(1)).zip(w) {
        let coefficient = wc * c;
        for (aic, &ui) in column.iter_mut().zip(u) {
            *aic -= ui * coefficient;
        }
    }
}

/// `(L Lᵀ)⁻¹ = L⁻ᵀ L⁻¹` from the column-major storage of the lower-triangular `L` (only its
/// lower triangle is read). The rows of `X = L⁻¹` by forward substitution,
/// `X_i = (e_iᵀ − Σ_{k<i} L_ik X_k) / L_ii`, kept as the columns `y_i = X_iᵀ` of `Y = Xᵀ`;
/// then column `b` of `XᵀX` is `Σ_{k ≥ b} X_kb y_k`. Every inner loop runs over a whole column
/// (length `N`, accumulated in registers): about `N³/2` multiply-adds, most of them on zeros
/// of the triangles, but without the loop overhead of triangular index ranges.
fn cholesky_inverse<T: RealField + Copy, const N: usize>(l: &[T]) -> SMatrix<T, N, N> {
    let n = N.max(1);
    let mut y = SMatrix::<T, N, N>::zeros();
    for i in 0..N {
        let Some(&diagonal) = l.get(i * n + i) else {
            break;
        };
        // Σ_{k<i} L_ik y_k accumulated with `+` (the same roundings as `−` from 0, by symmetry);
        // y_k[i] = 0 for k < i, so entry i is `1 − (±0)`.
        let mut sum = [T::zero(); N];
        for (yk, lk) in y.as_slice().chunks_exact(n).zip(l.chunks_exact(n)).take(i) {
            let lik = lk.get(i).copied().unwrap_or_else(T::zero);
            if lik != T::zero() {
                for (v, &ykj) in sum.iter_mut().zip(yk) {
                    *v += lik * ykj;
                }
            }
        }
        let Some(column) = y.as_mut_slice().chunks_exact_mut(n).nth(i) else {
            break;
        };
        for (j, (yi, v)) in column.iter_mut().zip(sum).enumerate() {
            let unit = if j == i { T::one() } else { T::zero() };
            *yi = (unit - v) / diagonal;
        }
    }
    let mut inverse = SMatrix::<T, N, N>::zeros();
    for (b, out) in inverse.as_mut_slice().chunks_exact_mut(n).enumerate() {
        let mut sum = [T::zero(); N];
        for yk in y.as_slice().chunks_exact(n).skip(b) {
            let xkb = yk.get(b).copied().unwrap_or_else(T::zero);
            if xkb != T::zero() {
                for (v, &ykj) in sum.iter_mut().zip(yk) {
                    *v += xkb * ykj;
                }
            }
        }
        for (o, v) in out.iter_mut().zip(sum) {
            *o = v;
        }
    }
    inverse
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
    // `x · 0` is ±0 for a finite `x` and NaN otherwise, and NaN propagates through the sum: one
    // multiply-add per entry instead of a test and a branch.
    let finite = stack.rows().iter().all(|r| {
        let zero = T::zero();
        let probe = r
            .row
            .jacobian
            .as_slice()
            .iter()
            .fold(r.row.force * zero + r.row.activation * zero, |sum, &x| sum + x * zero);
        probe == zero
    });
    if !finite {
        return Err(HierarchyError::NonFinite);
    }
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
#[path = "projection_reference.rs"]
mod reference;

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::dynamics::{crba, forward_kinematics, mass_matrix_cholesky};
    use crate::hierarchy::{push_transitioning, Stack};
    use crate::math::CholeskyFactor;
    use crate::tasks::{TaskRow, TaskRows};
    use crate::test_models::{branched, state, N};
    use crate::Data;
    use nalgebra::{DMatrix, RowSVector};

    const CONTINUOUS: Shaping<f64> = Shaping::Continuous { singular_full: 0.05, singular_start: 0.15 };

    fn row(j: RowSVector<f64, N>, f: f64) -> TaskRow<f64, N> {
        TaskRow { jacobian: j, force: f, potential: 0.0, activation: 1.0 }
    }

    fn random_stack(seed: u64, levels: &[usize]) -> Stack<f64, N, 8> {
        let mut stack = Stack::new();
        for (k, &level) in levels.iter().enumerate() {
            let j = state(seed * 31 + k as u64, 1.0).transpose();
            stack.push(level, row(j, 10.0 * state(seed + 99, 1.0)[k % N])).unwrap();
        }
        stack
    }

    fn mass_factor(seed: u64) -> CholeskyFactor<f64, N> {
        let model = branched::<f64>();
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &state(seed, 2.0), &SVector::zeros()).unwrap();
        crba(&model, &mut data);
        mass_matrix_cholesky(&data).unwrap()
    }

    /// Direct augmented projector I − Jₐᵀ (Jₐ W⁻¹ Jₐᵀ)⁺ Jₐ W⁻¹ (4.9), (4.15) by SVD.
    fn direct_projector(rows: &[RowSVector<f64, N>], w_inv: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
        if rows.is_empty() {
            return SMatrix::identity();
        }
        let ja = DMatrix::from_fn(rows.len(), N, |r, c| rows[r][c]);
        let w = DMatrix::from_fn(N, N, |r, c| w_inv[(r, c)]);
        let inner = (&ja * &w * ja.transpose()).pseudo_inverse(1e-12).unwrap();
        let p = DMatrix::identity(N, N) - ja.transpose() * inner * &ja * &w;
        SMatrix::from_fn(|r, c| p[(r, c)])
    }

    fn config<'a>(recursion: Recursion, weighting: Weighting<'a, f64, N>) -> HierarchyConfig<'a, f64, N> {
        HierarchyConfig { recursion, weighting, shaping: CONTINUOUS, diagnose_last_level: true }
    }

    #[test]
    fn scalar_recursion_equals_the_direct_augmented_projector() {
        let mut checked = 0;
        for seed in 1..30 {
            let factor = mass_factor(seed);
            let m_inv = factor.inverse();
            let stack = random_stack(seed, &[0, 0, 1, 2, 2]);
            for (weighting, w_inv) in [(Weighting::Identity, SMatrix::identity()), (Weighting::Inertia(&factor), m_inv)]
            {
                let mut data = HierarchyData::<f64, N, 8, 4>::default();
                let tau = *project(&config(Recursion::Augmented, weighting), &stack, &mut data).unwrap();
                // Equality holds when no row is near singular: every ρ above the shaping band,
                // so every activation is exactly 1.
                let min_ratio =
                    data.rows[..stack.rows().len()].iter().map(|r| r.projected_norm_ratio).fold(f64::MAX, f64::min);
                if min_ratio < 0.15 {
                    continue;
                }
                checked += 1;
                let mut expected = SVector::<f64, N>::zeros();
                let mut above = std::vec::Vec::new();
                for level in 0..3 {
                    let n = direct_projector(&above, &w_inv);
                    for r in stack.rows().iter().filter(|r| r.level == level) {
                        expected += n * r.row.jacobian.transpose() * r.row.force;
                    }
                    above.extend(stack.rows().iter().filter(|r| r.level == level).map(|r| r.row.jacobian));
                }
                assert!(
                    (tau - expected).amax() < 1e-9 * (1.0 + expected.amax()),
                    "seed {seed}: {}",
                    (tau - expected).amax()
                );
                assert!((data.projector - direct_projector(&above, &w_inv)).amax() < 1e-9, "seed {seed}");
            }
        }
        assert!(checked >= 30, "only {checked} of 58 cases were non-singular");
    }

    #[test]
    fn table_4_3_strictness_and_idempotence() {
        let factor = mass_factor(7);
        let m_inv = factor.inverse();
        let stack = random_stack(3, &[0, 1, 1]);
        let level0: SVector<f64, N> = stack.rows()[0].row.jacobian.transpose();
        for (weighting, dynamic) in [
            (Weighting::Identity, false),
            (Weighting::Inertia(&factor), true),
            (Weighting::AccelerationBased(&factor), true),
        ] {
            let mut data = HierarchyData::<f64, N, 8, 4>::default();
            project(&config(Recursion::Augmented, weighting), &stack, &mut data).unwrap();
            let n = data.projector;
            // Static strictness N_j J_iᵀ = 0 (W = I, W = M); dynamic J_i M⁻¹ N_j = 0 (W = M, accel).
            match weighting {
                Weighting::AccelerationBased(_) => {
                    let full = factor.l() * factor.l().transpose() * n * m_inv;
                    assert!((level0.transpose() * m_inv * full).amax() < 1e-10);
                }
                _ => {
                    assert!((n * level0).amax() < 1e-10);
                    if dynamic {
                        assert!((level0.transpose() * m_inv * n).amax() < 1e-10);
                    }
                }
            }
            assert!((n * n - n).amax() < 1e-10, "augmented projectors are idempotent");
        }
        // Successive projectors (two non-orthogonal rows on consecutive levels) are not.
        let mut data = HierarchyData::<f64, N, 8, 4>::default();
        project(&config(Recursion::Successive, Weighting::Identity), &random_stack(3, &[0, 1, 2]), &mut data).unwrap();
        assert!((data.projector * data.projector - data.projector).amax() > 1e-3);
    }

    #[test]
    fn invariance_4_77_only_the_critical_direction_is_touched() {
        let j = RowSVector::<f64, N>::from_fn(|_, c| [1.0, -2.0, 0.5, 0.0, 1.5, 0.3][c]);
        for activation in [0.0, 0.3, 1.0] {
            let mut stack = Stack::<f64, N, 8>::new();
            stack.push(0, TaskRow { activation, ..row(j, 1.0) }).unwrap();
            let mut data = HierarchyData::<f64, N, 8, 4>::default();
            project(&config(Recursion::Augmented, Weighting::Identity), &stack, &mut data).unwrap();
            let n = data.projector;
            assert!((n * j.transpose() - j.transpose() * (1.0 - activation)).amax() < 1e-12);
            let v = SVector::<f64, N>::from_fn(|r, _| [2.0, 1.0, 0.0, 3.0, 0.0, 0.0][r]);
            assert!(j.dot(&v.transpose()).abs() < 1e-15);
            assert!((n * v - v).amax() < 1e-12, "directions orthogonal to the row are untouched");
        }
    }

    /// Two rows on levels 0 and 1 that become parallel as `t → 0`: an algorithmic
    /// singularity. Returns the level-2 torque as a function of `t`.
    fn torque_near_singularity(t: f64, shaping: Shaping<f64>) -> SVector<f64, N> {
        let a = RowSVector::<f64, N>::from_fn(|_, c| [1.0, 0.0, 0.0, 0.0, 0.0, 0.0][c]);
        let b = RowSVector::<f64, N>::from_fn(|_, c| [1.0, t, 0.0, 0.0, 0.0, 0.0][c]);
        let mut stack = Stack::<f64, N, 8>::new();
        stack.push(0, row(a, 1.0)).unwrap();
        stack.push(1, row(b, 1.0)).unwrap();
        stack.push(2, row(RowSVector::from_fn(|_, c| [0.3, 1.0, 0.2, 0.0, 0.0, 0.0][c]), 5.0)).unwrap();
        let mut data = HierarchyData::<f64, N, 8, 4>::default();
        let cfg = HierarchyConfig {
            recursion: Recursion::Augmented,
            weighting: Weighting::Identity,
            shaping,
            diagnose_last_level: true,
        };
        *project(&cfg, &stack, &mut data).unwrap()
    }

    #[test]
    fn continuous_through_an_algorithmic_singularity_classical_jumps() {
        let classical = Shaping::Discontinuous { singular_threshold: 1e-3 };
        let (mut worst_continuous, mut worst_classical) = (0.0_f64, 0.0_f64);
        let steps = 4000;
        for k in 0..steps {
            let t0 = 0.4 * k as f64 / steps as f64;
            let t1 = 0.4 * (k + 1) as f64 / steps as f64;
            worst_continuous = worst_continuous
                .max((torque_near_singularity(t1, CONTINUOUS) - torque_near_singularity(t0, CONTINUOUS)).amax());
            worst_classical = worst_classical
                .max((torque_near_singularity(t1, classical) - torque_near_singularity(t0, classical)).amax());
        }
        // Step 1e-4 in t: a continuous torque changes by O(1e-3); the classical one jumps by
        // the full blocked component (5 · 1.0 of the level-2 force along the unlocked axis).
        assert!(worst_continuous < 1e-2, "continuous shaping jumped by {worst_continuous}");
        assert!(worst_classical > 1.0, "classical projector should jump, max step {worst_classical}");
    }

    #[test]
    fn level_transition_is_continuous_and_exact_at_the_ends() {
        let mut task = TaskRows::<f64, N, 2>::new();
        task.push(row(RowSVector::from_fn(|_, c| [0.0, 1.0, 0.5, 0.0, 0.0, 0.0][c]), 4.0)).unwrap();
        let other = row(RowSVector::from_fn(|_, c| [0.2, 1.0, 0.0, 0.0, 0.0, 0.0][c]), -3.0);
        let torque = |progress: f64| {
            let mut stack = Stack::<f64, N, 8>::new();
            stack.push(1, other).unwrap();
            push_transitioning(&mut stack, &task, 2, 0, progress).unwrap();
            let mut data = HierarchyData::<f64, N, 8, 4>::default();
            *project(&config(Recursion::Augmented, Weighting::Identity), &stack, &mut data).unwrap()
        };
        let on = |level: usize| {
            let mut stack = Stack::<f64, N, 8>::new();
            stack.push(1, other).unwrap();
            stack.push_rows(level, &task).unwrap();
            let mut data = HierarchyData::<f64, N, 8, 4>::default();
            *project(&config(Recursion::Augmented, Weighting::Identity), &stack, &mut data).unwrap()
        };
        assert!((torque(0.0) - on(2)).amax() < 1e-12 && (torque(1.0) - on(0)).amax() < 1e-12);
        let mut worst = 0.0_f64;
        for k in 0..1000 {
            worst = worst.max((torque((k + 1) as f64 / 1000.0) - torque(k as f64 / 1000.0)).amax());
        }
        assert!(worst < 0.05, "max torque step {worst} for a progress step of 1e-3");
    }

    #[test]
    fn bad_input_is_rejected_without_output() {
        let mut stack = random_stack(1, &[0, 5]);
        let mut data = HierarchyData::<f64, N, 8, 4> { torque: SVector::repeat(7.0), ..Default::default() };
        let cfg = config(Recursion::Augmented, Weighting::Identity);
        assert_eq!(project(&cfg, &stack, &mut data), Err(HierarchyError::TooManyLevels { capacity: 4 }));
        stack.clear();
        stack.push(0, TaskRow { force: f64::NAN, ..row(RowSVector::zeros(), 0.0) }).unwrap();
        assert_eq!(project(&cfg, &stack, &mut data), Err(HierarchyError::NonFinite));
        for (entry, value) in [(0, f64::INFINITY), (N - 1, f64::NEG_INFINITY), (2, f64::NAN)] {
            let mut j = RowSVector::<f64, N>::from_element(1e300);
            j[entry] = value;
            stack.clear();
            stack.push(0, row(j, 1.0)).unwrap();
            assert_eq!(project(&cfg, &stack, &mut data), Err(HierarchyError::NonFinite), "entry {entry}");
        }
        stack.clear();
        stack.push(0, TaskRow { activation: f64::NEG_INFINITY, ..row(RowSVector::from_element(1.0), 0.0) }).unwrap();
        assert_eq!(project(&cfg, &stack, &mut data), Err(HierarchyError::NonFinite));
        assert_eq!(data.torque, SVector::<f64, N>::repeat(7.0));
        let bad = HierarchyConfig { shaping: Shaping::Continuous { singular_full: 0.2, singular_start: 0.1 }, ..cfg };
        assert_eq!(project(&bad, &Stack::<f64, N, 8>::new(), &mut data), Err(HierarchyError::InvalidShaping));
    }

    /// Fast [`project`] against the plain reference recursion on random stacks (every
    /// recursion × weighting × shaping, with and without last-level diagnostics), on the
    /// branched test model (its mass matrix at random states, a random SPD stiffness).
    #[test]
    fn fast_recursion_equals_the_reference_on_the_test_model() {
        let (mut worst64, mut worst32) = (0.0_f64, 0.0_f64);
        for seed in 0..40 {
            let mut rng = reference::TestRng::new(seed);
            let mass = mass_factor(seed + 1);
            let mass = mass.l() * mass.l().transpose();
            let stiffness = reference::random_spd::<N>(&mut rng);
            let stack = reference::random_stack::<N, 16>(&mut rng, 2 + seed as usize % 3);
            worst64 = worst64.max(reference::compare_f64::<N, 16, 16, 4>(&stack, &mass, &stiffness, 1e-9));
            worst32 = worst32.max(reference::compare_f32::<N, 16, 16, 4>(&stack, &mass, &stiffness, 4.0, 1e-6));
        }
        // The comparison is not vacuous: rounding differs (other summation order).
        assert!(worst64 > 0.0 && worst32 > 0.0, "{worst64} {worst32}");
    }

    /// The same on a Justin-size system (`N = 20`, random SPD mass and stiffness matrices,
    /// up to four levels).
    #[test]
    fn fast_recursion_equals_the_reference_for_20_coordinates() {
        for seed in 0..20 {
            let mut rng = reference::TestRng::new(1000 + seed);
            let mass = reference::random_spd::<20>(&mut rng);
            let stiffness = reference::random_spd::<20>(&mut rng);
            let stack = reference::random_stack::<20, 24>(&mut rng, 2 + seed as usize % 3);
            reference::compare_f64::<20, 24, 24, 4>(&stack, &mass, &stiffness, 1e-9);
            reference::compare_f32::<20, 24, 24, 4>(&stack, &mass, &stiffness, 4.0, 1e-6);
        }
    }

    /// [`quadratic_form`], [`mat_vec_dot`] and [`projected_norm_squared`] (one pass) give bit for
    /// bit the sums of the plain [`mat_vec`], [`dot`] and [`norm_squared`] they replace, in f64
    /// and f32, on random matrices and sparse random vectors (including the zero vector).
    #[test]
    fn fused_norms_equal_the_plain_mat_vec_bit_for_bit() {
        fn check<T: RealField + Copy, const M: usize>(a: &SMatrix<T, M, M>, x: &SVector<T, M>) {
            let mut ax = SVector::<T, M>::zeros();
            mat_vec::<T, M>(a.as_slice(), x.as_slice(), ax.as_mut_slice());
            let quadratic = quadratic_form::<T, M>(a.as_slice(), x.as_slice());
            assert_eq!(quadratic, dot(x.as_slice(), ax.as_slice()));
            let mut fused = SVector::<T, M>::zeros();
            assert_eq!(mat_vec_dot::<T, M>(a.as_slice(), x.as_slice(), fused.as_mut_slice()), quadratic);
            assert_eq!(fused, ax);
            let (x_squared, ax_squared) = projected_norm_squared::<T, M>(a.as_slice(), x.as_slice());
            assert_eq!(x_squared, norm_squared(x.as_slice()));
            assert_eq!(ax_squared, norm_squared(ax.as_slice()));
            // Not vacuous: the plain mat-vec agrees with nalgebra's product to rounding.
            let expected = a * x;
            assert!((ax - expected).amax() <= T::from_f64(1e-5).unwrap() * (T::one() + expected.amax()));
        }
        let mut rng = reference::TestRng::new(77);
        for case in 0..200 {
            let density = [0.0, 0.2, 0.5, 1.0][case % 4];
            let a = SMatrix::<f64, 20, 20>::from_fn(|_, _| rng.symmetric());
            let x = SVector::<f64, 20>::from_fn(|_, _| if rng.unit() < density { rng.symmetric() } else { 0.0 });
            check(&a, &x);
            check(&a.cast::<f32>(), &x.cast::<f32>());
            let a = reference::random_spd::<N>(&mut rng);
            let x = SVector::<f64, N>::from_fn(|_, _| if rng.unit() < density { rng.symmetric() } else { 0.0 });
            check(&a, &x);
            check(&a.cast::<f32>(), &x.cast::<f32>());
        }
    }

    /// Joint rows `α e_bᵀ` below a projecting level take their transmission from the input
    /// projector's column norms: equal to the general `‖N_in jᵀ‖ / ‖jᵀ‖` for every weighting
    /// (the acceleration-based one keeps the general form).
    #[test]
    fn joint_row_transmissions_are_the_input_projector_column_norms() {
        let factor = mass_factor(4);
        for seed in 0..10 {
            let level0 = random_stack(seed, &[0, 0, 0]);
            let mut stack = Stack::<f64, N, 16>::new();
            for r in level0.rows() {
                stack.push(r.level, r.row).unwrap();
            }
            for b in 0..N {
                let alpha = [2.0, -0.5, 1.0][b % 3];
                stack.push(1, row(RowSVector::from_fn(|_, c| if c == b { alpha } else { 0.0 }), 1.0)).unwrap();
            }
            for weighting in [Weighting::Identity, Weighting::Inertia(&factor), Weighting::AccelerationBased(&factor)] {
                for diagnose_last_level in [false, true] {
                    let cfg = HierarchyConfig { diagnose_last_level, ..config(Recursion::Augmented, weighting) };
                    let mut data = HierarchyData::<f64, N, 16, 4>::default();
                    project(&cfg, &stack, &mut data).unwrap();
                    let mut input = HierarchyData::<f64, N, 8, 4>::default();
                    project(&config(Recursion::Augmented, weighting), &level0, &mut input).unwrap();
                    let mut smallest = 1.0_f64;
                    for (b, diagnostics) in data.rows[3..3 + N].iter().enumerate() {
                        let j = stack.rows()[3 + b].row.jacobian;
                        let mut tmp = SVector::zeros();
                        let general = transmission(&weighting, &input.projector, j.as_slice(), &mut tmp);
                        assert!((diagnostics.transmission - general).abs() < 1e-12, "seed {seed} column {b}");
                        smallest = smallest.min(general);
                    }
                    // Not vacuous: the static and dynamic projectors (norm ≤ 1 per column
                    // direction) pass less than all of some joint direction.
                    let accelerated = matches!(weighting, Weighting::AccelerationBased(_));
                    assert!(accelerated || smallest < 0.99, "level 0 projects no joint direction: {smallest}");
                }
            }
        }
    }

    #[test]
    fn f32_agrees_with_f64() {
        let stack = random_stack(5, &[0, 0, 1, 2]);
        let mut stack32 = Stack::<f32, N, 8>::new();
        for r in stack.rows() {
            stack32
                .push(
                    r.level,
                    TaskRow {
                        jacobian: r.row.jacobian.cast(),
                        force: r.row.force as f32,
                        potential: 0.0,
                        activation: 1.0,
                    },
                )
                .unwrap();
        }
        let mut d64 = HierarchyData::<f64, N, 8, 4>::default();
        let mut d32 = HierarchyData::<f32, N, 8, 4>::default();
        let t64 = *project(&config(Recursion::Augmented, Weighting::Identity), &stack, &mut d64).unwrap();
        let cfg32 = HierarchyConfig {
            recursion: Recursion::Augmented,
            weighting: Weighting::Identity,
            shaping: Shaping::Continuous { singular_full: 0.05_f32, singular_start: 0.15 },
            diagnose_last_level: true,
        };
        let t32 = project(&cfg32, &stack32, &mut d32).unwrap().cast::<f64>();
        assert!((t64 - t32).amax() < 1e-4 * (1.0 + t64.amax()));
    }
}
