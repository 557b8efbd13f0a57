//! The command-side limit: the rigid-contact force the commanded torque produces along the
//! limited axes, kept inside the effective bounds (module docs of [`super`]: "Command-side
//! limit").

use nalgebra::{Cholesky, Const, RealField, SMatrix, SVector, Vector6};

use super::limiter::ForceLimiter;
use crate::dynamics::{InertiaFactor, TreeFactorization};
use crate::math::cholesky::{cholesky_in_place, solve_lower_in_place, solve_lower_transpose_in_place};

/// What the command-side limit did: the torque to add and the axes it acted on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandLimit<T, const N: usize> {
    /// `−J_Lᵀ e` (upper-body rows; zero without excess).
    pub torque: SVector<T, N>,
    /// Per hand and axis: the commanded contact force left its bounds.
    pub limited: [[bool; 6]; 2],
}

impl<T: RealField + Copy, const N: usize> ForceLimiter<T, N> {
    /// The command-side limit (module docs) for the projected task torque `τ = Σ_i N_i τ_i` of
    /// this cycle, after [`Self::update`]: `regularisation` is `μ` of the parameters, `factor`
    /// a factor of the closed-loop inertia ([`InertiaFactor`]: dense or tree-sparse), `damping`
    /// the Cartesian damping force of each hand (task axes). Returns the torque `−J_Lᵀ e` that
    /// moves every limited axis' rigid-contact force onto its bound (with the damping rule of
    /// the module docs). Zero without an enabled limit or if a solve fails.
    /// Cost: one substitution with `factor` per limited row plus one for `τ`
    /// (`reflected_dense`, `reflected_tree`), one 12 × 12 Cholesky.
    pub fn limit_command<'m>(
        &self,
        regularisation: T,
        task_torque: &SVector<T, N>,
        factor: impl Into<InertiaFactor<'m, T, N>>,
        damping: &[Vector6<T>; 2],
    ) -> CommandLimit<T, N> {
        let none = CommandLimit { torque: SVector::zeros(), limited: [[false; 6]; 2] };
        // The limited rows L: an axis of a hand with an enabled limit and a finite bound.
        let mut selected = [false; 12];
        for (h, bounds) in self.effective.iter().enumerate() {
            let Some((lower, upper)) = bounds else { continue };
            for (axis, (low, high)) in lower.iter().zip(upper.iter()).enumerate() {
                if let Some(s) = selected.get_mut(6 * h + axis) {
                    *s = low.is_finite() || high.is_finite();
                }
            }
        }
        if !selected.iter().any(|s| *s) {
            return none;
        }
        let (solved, mut reflected, mut force) = match factor.into() {
            InertiaFactor::Dense(factor) => self.reflected_dense(regularisation, task_torque, factor, &selected),
            InertiaFactor::Tree(factor) => self.reflected_tree(regularisation, task_torque, factor, &selected),
        };
        let solved = solved
            && cholesky_in_place(reflected.as_mut_slice(), 12)
            && solve_lower_in_place(reflected.as_slice(), force.as_mut_slice())
            && solve_lower_transpose_in_place(reflected.as_slice(), force.as_mut_slice());
        if !(solved && force.iter().all(|x| x.is_finite())) {
            return none;
        }
        let mut excess = SVector::<T, 12>::zeros();
        let mut limited = [[false; 6]; 2];
        for (h, ((bounds, flags), damping)) in
            self.effective.iter().zip(limited.iter_mut()).zip(damping.iter()).enumerate()
        {
            let Some((lower, upper)) = bounds else { continue };
            for (axis, flag) in flags.iter_mut().enumerate() {
                let row = 6 * h + axis;
                let get = |v: &Vector6<T>| v.get(axis).copied().unwrap_or_else(T::zero);
                let (Some(f), Some(e)) = (force.get(row), excess.get_mut(row)) else { continue };
                let d = get(damping);
                let (low, high) = (get(lower) + d.max(T::zero()), get(upper) + d.min(T::zero()));
                let over = *f - f.max(low).min(high);
                *e = over;
                *flag = over != T::zero();
            }
        }
        // −J_Lᵀ e: one dot product per column of the stacked Jacobian.
        let dot = |a: &[T], b: &[T]| a.iter().zip(b.iter()).fold(T::zero(), |s, (x, y)| s + *x * *y);
        let mut torque = SVector::<T, N>::zeros();
        for (t, column) in torque.iter_mut().zip(self.stacked.as_slice().chunks_exact(12)) {
            *t = -dot(column, excess.as_slice());
        }
        CommandLimit { torque, limited }
    }

    /// The reflected inertia `J_L M⁻¹ J_Lᵀ + μ I` of the limited rows (identity on the others;
    /// the lower triangle is written) and `J_L M⁻¹ τ` with the dense `M = L Lᵀ`:
    /// `Y = L⁻¹ J_Lᵀ` (forward substitution of the selected rows only, loops on the column-major
    /// factor) and `z = L⁻¹ τ`, then `Yᵀ Y` and `Yᵀ z`. `false` if a substitution failed.
    fn reflected_dense(
        &self,
        regularisation: T,
        task_torque: &SVector<T, N>,
        factor: &Cholesky<T, Const<N>>,
        selected: &[bool; 12],
    ) -> (bool, SMatrix<T, 12, 12>, SVector<T, 12>) {
        // With M = L Lᵀ: Y = L⁻¹ J_Lᵀ (forward substitution of the selected rows only) and
        // z = L⁻¹ τ; the reflected inertia J_L M⁻¹ J_Lᵀ = Yᵀ Y (identity on the other rows) and
        // J_L M⁻¹ τ = Yᵀ z.
        let l = factor.l_dirty().as_slice();
        let mut z = *task_torque;
        let mut reduced = SMatrix::<T, N, 12>::zeros();
        let mut solved = solve_lower_in_place(l, z.as_mut_slice());
        for (i, (column, s)) in reduced.as_mut_slice().chunks_exact_mut(N).zip(selected.iter()).enumerate() {
            if !s {
                continue;
            }
            for (y, j) in column.iter_mut().zip(self.stacked.as_slice().chunks_exact(12)) {
                *y = j.get(i).copied().unwrap_or_else(T::zero);
            }
            solved &= solve_lower_in_place(l, column);
        }
        let mut reflected = SMatrix::<T, 12, 12>::identity();
        let mut force = SVector::<T, 12>::zeros();
        let dot = |a: &[T], b: &[T]| a.iter().zip(b.iter()).fold(T::zero(), |s, (x, y)| s + *x * *y);
        for (i, ((yi, si), (r_column, f))) in reduced
            .as_slice()
            .chunks_exact(N)
            .zip(selected.iter())
            .zip(reflected.as_mut_slice().chunks_exact_mut(12).zip(force.iter_mut()))
            .enumerate()
        {
            if !si {
                continue;
            }
            *f = dot(yi, z.as_slice());
            // Column i, rows j ≥ i (the lower triangle the factorisation reads).
            for (j, ((yj, sj), x)) in
                reduced.as_slice().chunks_exact(N).zip(selected.iter()).zip(r_column.iter_mut()).enumerate().skip(i)
            {
                if *sj {
                    *x = dot(yi, yj) + if i == j { regularisation } else { T::zero() };
                }
            }
        }
        (solved, reflected, force)
    }

    /// [`Self::reflected_dense`] on the tree-sparse `M = Lᵀ L`: `X = S L⁻¹` for the stack `S`
    /// of the selected rows of `J_u` and `τᵀ` ([`TreeFactorization::right_solve_mut`]), then
    /// `J_L M⁻¹ J_Lᵀ = X_L X_Lᵀ` and `J_L M⁻¹ τ = X_L x_τᵀ` over the columns of `X`.
    fn reflected_tree(
        &self,
        regularisation: T,
        task_torque: &SVector<T, N>,
        factor: &TreeFactorization<T, N>,
        selected: &[bool; 12],
    ) -> (bool, SMatrix<T, 12, 12>, SVector<T, 12>) {
        let mut x = SMatrix::<T, 13, N>::zeros();
        for ((column, j), t) in x.data.0.iter_mut().zip(self.stacked.data.0.iter()).zip(task_torque.iter()) {
            for ((c, v), s) in column.iter_mut().zip(j.iter()).zip(selected.iter()) {
                if *s {
                    *c = *v;
                }
            }
            if let Some(c) = column.get_mut(12) {
                *c = *t;
            }
        }
        factor.right_solve_mut(&mut x);
        // The rows of X as contiguous columns: the Gram entries are dot products.
        let rows = x.transpose();
        let Some((torque_row, _)) = rows.data.0.split_last() else {
            return (false, SMatrix::identity(), SVector::zeros());
        };
        let dot = |a: &[T; N], b: &[T; N]| a.iter().zip(b.iter()).fold(T::zero(), |s, (x, y)| s + *x * *y);
        let mut reflected = SMatrix::<T, 12, 12>::identity();
        let mut force = SVector::<T, 12>::zeros();
        for (i, ((r_column, f), (x_i, si))) in
            reflected.data.0.iter_mut().zip(force.iter_mut()).zip(rows.data.0.iter().zip(selected.iter())).enumerate()
        {
            if !si {
                continue;
            }
            *f = dot(x_i, torque_row);
            // Column i, rows j ≥ i (the lower triangle the factorisation reads).
            for (j, ((r, x_j), sj)) in
                r_column.iter_mut().zip(rows.data.0.iter()).zip(selected.iter()).enumerate().skip(i)
            {
                if *sj {
                    *r = dot(x_i, x_j) + if i == j { regularisation } else { T::zero() };
                }
            }
        }
        (true, reflected, force)
    }
}
