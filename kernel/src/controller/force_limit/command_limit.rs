//! The command-side limit: the rigid-contact force the commanded torque produces along the
//! limited axes, kept inside the effective bounds (module docs of [`super`]: "Command-side
//! limit").

use nalgebra::{Cholesky, Const, RealField, SMatrix, SVector, Vector6};

use super::limiter::{ForceLimiter, Stacked};
use crate::controller::layout::MAX_ARMS;
use crate::dynamics::{InertiaFactor, TreeFactorization};
use crate::math::cholesky::{cholesky_in_place, solve_lower_in_place, solve_lower_transpose_in_place};

/// What the command-side limit did: the torque to add and the axes it acted on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandLimit<T, const N: usize, const A: usize> {
    /// `−J_Lᵀ e` (upper-body rows; zero without excess).
    pub torque: SVector<T, N>,
    /// Per hand and axis: the commanded contact force left its bounds.
    pub limited: [[bool; 6]; A],
}

impl<T: RealField + Copy, const N: usize, const A: usize> ForceLimiter<T, N, A> {
    /// The command-side limit (module docs) for the projected task torque `τ = Σ_i N_i τ_i` of
    /// this cycle, after [`Self::update`]: `regularisation` is `μ` of the parameters, `factor`
    /// a factor of the closed-loop inertia ([`InertiaFactor`]: dense or tree-sparse), `damping`
    /// the Cartesian damping force of each hand (task axes). Returns the torque `−J_Lᵀ e` that
    /// moves every limited axis' rigid-contact force onto its bound (with the damping rule of
    /// the module docs). Zero without an enabled limit or if a solve fails.
    /// The `k` limited rows are packed: one substitution with `factor` per limited row plus
    /// one for `τ` (`reflected_dense`, `reflected_tree`; on the tree factor four rows at once
    /// while `k ≤ 3`, 13 while `k ≤ 12`, the `6 MAX_ARMS + 1` of every arm beyond), one `k × k`
    /// Cholesky.
    pub fn limit_command<'m>(
        &self,
        regularisation: T,
        task_torque: &SVector<T, N>,
        factor: impl Into<InertiaFactor<'m, T, N>>,
        damping: &[Vector6<T>; A],
    ) -> CommandLimit<T, N, A> {
        let none = CommandLimit { torque: SVector::zeros(), limited: [[false; 6]; A] };
        // The limited rows L (indices into the stacked J_u, ascending): an axis of a hand with
        // an enabled limit and a finite bound.
        let mut packed: Stacked<usize, A> = [[0; 6]; A];
        let rows = packed.as_flattened_mut();
        let mut count = 0;
        for (h, bounds) in self.effective.iter().enumerate() {
            let Some((lower, upper)) = bounds else { continue };
            for (axis, (low, high)) in lower.iter().zip(upper.iter()).enumerate() {
                if let (true, Some(r)) = (low.is_finite() || high.is_finite(), rows.get_mut(count)) {
                    *r = 6 * h + axis;
                    count += 1;
                }
            }
        }
        let Some(rows) = rows.get(..count).filter(|r| !r.is_empty()) else {
            return none;
        };
        // J_L M⁻¹ J_Lᵀ + μ I (count × count, column-major, lower triangle) and J_L M⁻¹ τ.
        let mut reflected_storage = [[[[T::zero(); 6]; A]; 6]; A];
        let reflected = reflected_storage.as_flattened_mut().as_flattened_mut().as_flattened_mut();
        let mut force_storage: Stacked<T, A> = [[T::zero(); 6]; A];
        let force = force_storage.as_flattened_mut();
        let solved = match factor.into() {
            InertiaFactor::Dense(factor) => {
                self.reflected_dense(regularisation, task_torque, factor, rows, reflected, force)
            }
            InertiaFactor::Tree(factor) if count < 4 => {
                self.reflected_tree::<4>(regularisation, task_torque, factor, rows, reflected, force)
            }
            InertiaFactor::Tree(factor) if A <= 2 || count < 13 => {
                self.reflected_tree::<13>(regularisation, task_torque, factor, rows, reflected, force)
            }
            InertiaFactor::Tree(factor) => {
                self.reflected_tree::<{ 6 * MAX_ARMS + 1 }>(regularisation, task_torque, factor, rows, reflected, force)
            }
        };
        let (Some(reflected), Some(force)) = (reflected.get_mut(..count * count), force.get_mut(..count)) else {
            return none;
        };
        let solved = solved
            && cholesky_in_place(reflected, count)
            && solve_lower_in_place(reflected, force)
            && solve_lower_transpose_in_place(reflected, force);
        if !(solved && force.iter().all(|x| x.is_finite())) {
            return none;
        }
        let mut excess_storage: Stacked<T, A> = [[T::zero(); 6]; A];
        let excess = excess_storage.as_flattened_mut();
        let mut limited = [[false; 6]; A];
        for ((row, f), e) in rows.iter().zip(force.iter()).zip(excess.iter_mut()) {
            let (h, axis) = (row / 6, row % 6);
            let (Some(Some((lower, upper))), Some(damping), Some(flags)) =
                (self.effective.get(h), damping.get(h), limited.get_mut(h))
            else {
                continue;
            };
            let (Some(low), Some(high), Some(d), Some(flag)) =
                (lower.get(axis), upper.get(axis), damping.get(axis), flags.get_mut(axis))
            else {
                continue;
            };
            let (low, high) = (*low + d.max(T::zero()), *high + d.min(T::zero()));
            let over = *f - f.max(low).min(high);
            *e = over;
            *flag = over != T::zero();
        }
        // −J_Lᵀ e: one dot product over the limited rows per column of the stacked Jacobian.
        let mut torque = SVector::<T, N>::zeros();
        for (t, column) in torque.as_mut_slice().iter_mut().zip(self.stacked.iter()) {
            let column = column.as_flattened();
            *t = -rows
                .iter()
                .zip(excess.iter())
                .fold(T::zero(), |s, (r, e)| s + column.get(*r).copied().unwrap_or_else(T::zero) * *e);
        }
        CommandLimit { torque, limited }
    }

    /// The reflected inertia `J_L M⁻¹ J_Lᵀ + μ I` of the limited `rows` (packed `k × k`
    /// column-major into `reflected`, the lower triangle is written) and `J_L M⁻¹ τ` (into
    /// `force`) with the dense `M = L Lᵀ`: `Y = L⁻¹ J_Lᵀ` (forward substitution, loops on the
    /// column-major factor) and `z = L⁻¹ τ`, then `Yᵀ Y` and `Yᵀ z`. `false` if a substitution
    /// failed.
    fn reflected_dense(
        &self,
        regularisation: T,
        task_torque: &SVector<T, N>,
        factor: &Cholesky<T, Const<N>>,
        rows: &[usize],
        reflected: &mut [T],
        force: &mut [T],
    ) -> bool {
        let count = rows.len();
        let l = factor.l_dirty().as_slice();
        let mut z = *task_torque;
        let mut reduced_storage: Stacked<[T; N], A> = [[[T::zero(); N]; 6]; A];
        let reduced = reduced_storage.as_flattened_mut();
        let mut solved = solve_lower_in_place(l, z.as_mut_slice());
        for (column, r) in reduced.iter_mut().zip(rows.iter()) {
            for (y, j) in column.iter_mut().zip(self.stacked.iter()) {
                *y = j.as_flattened().get(*r).copied().unwrap_or_else(T::zero);
            }
            solved &= solve_lower_in_place(l, column);
        }
        let dot = |a: &[T], b: &[T]| a.iter().zip(b.iter()).fold(T::zero(), |s, (x, y)| s + *x * *y);
        for (i, (yi, (r_column, f))) in
            reduced.iter().zip(reflected.chunks_exact_mut(count.max(1)).zip(force.iter_mut())).take(count).enumerate()
        {
            *f = dot(yi, z.as_slice());
            // Column i, rows j ≥ i (the lower triangle the factorisation reads).
            for (j, (yj, x)) in reduced.iter().zip(r_column.iter_mut()).enumerate().skip(i) {
                *x = dot(yi, yj) + if i == j { regularisation } else { T::zero() };
            }
        }
        solved
    }

    /// [`Self::reflected_dense`] on the tree-sparse `M = Lᵀ L`: `X = S L⁻¹` for the stack `S`
    /// of the limited rows of `J_u` and `τᵀ` packed into `R > rows.len()` rows
    /// ([`TreeFactorization::right_solve_mut`]), then `J_L M⁻¹ J_Lᵀ = X_L X_Lᵀ` and
    /// `J_L M⁻¹ τ = X_L x_τᵀ` as rank-one updates over the columns of `X`. `false` if `R` is
    /// too small.
    fn reflected_tree<const R: usize>(
        &self,
        regularisation: T,
        task_torque: &SVector<T, N>,
        factor: &TreeFactorization<T, N>,
        rows: &[usize],
        reflected: &mut [T],
        force: &mut [T],
    ) -> bool {
        let count = rows.len();
        if count >= R || count == 0 {
            return false;
        }
        let mut x = SMatrix::<T, R, N>::zeros();
        for ((column, j), t) in x.data.0.iter_mut().zip(self.stacked.iter()).zip(task_torque.iter()) {
            let j = j.as_flattened();
            for (c, r) in column.iter_mut().zip(rows.iter()) {
                *c = j.get(*r).copied().unwrap_or_else(T::zero);
            }
            if let Some(c) = column.get_mut(count) {
                *c = *t;
            }
        }
        factor.right_solve_mut(&mut x);
        // The lower triangle of the R × R Gram matrix of the packed rows, as rank-one updates
        // over the columns of X (fixed trip counts): `X_L X_Lᵀ` in its leading `k × k` block,
        // `X_L x_τᵀ` in its row `k`.
        let mut gram = [[T::zero(); R]; R];
        for column in x.data.0.iter() {
            for (j, (g, x_j)) in gram.iter_mut().zip(column.iter()).enumerate() {
                for i in j..R {
                    if let (Some(g), Some(x_i)) = (g.get_mut(i), column.get(i)) {
                        *g += *x_i * *x_j;
                    }
                }
            }
        }
        for (j, ((target, g), f)) in
            reflected.chunks_exact_mut(count.max(1)).zip(gram.iter()).zip(force.iter_mut()).take(count).enumerate()
        {
            *f = g.get(count).copied().unwrap_or_else(T::zero);
            for (i, (t, value)) in target.iter_mut().zip(g.iter()).enumerate().skip(j) {
                *t = if i == j { *value + regularisation } else { *value };
            }
        }
        true
    }
}
