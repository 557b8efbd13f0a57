//! The estimate of the contact wrenches from the momentum residual (module docs of
//! [`super`]: "Estimate of the contact wrench").

use nalgebra::{Matrix3, RealField, SMatrix, SVector, Vector6};

use super::limiter::{ForceLimitParameters, ForceLimiter, HandLimits};
use crate::controller::layout::RobotLayout;
use crate::dynamics::{frame_jacobian, DynamicsError};
use crate::math::cholesky::{cholesky_fixed, solve_lower_in_place, solve_lower_transpose_in_place};
use crate::model::{Data, Model};

impl<T: RealField + Copy, const N: usize> ForceLimiter<T, N> {
    /// One period `dt`: estimates the wrenches from `residual` (`τ̂_ext`, [`crate::controller::observer`]) at
    /// the kinematics of `data` (after `forward_kinematics`), then advances the governor of each
    /// hand with `Some` limits (a hand with `None` is reset). If the 12 × 12 solve fails (a
    /// non-finite input), the estimate is zero and the corrections are held. Cost two frame
    /// Jacobians (the columns off a TCP's support path are zero and skipped), the lower
    /// triangle of the 12 × 12 Gram matrix as N rank-one updates restricted to the hands a
    /// column moves (21 multiply-adds for an arm joint, 78 for a shared one) and one 12 × 12
    /// Cholesky, all as loops over the column-major storage.
    /// Errors: [`DynamicsError::UnknownFrame`] for a TCP frame outside the model.
    #[allow(clippy::too_many_arguments, reason = "the controller's pieces, each used once")]
    pub fn update<const B: usize, const F: usize, const A: usize>(
        &mut self,
        parameters: &ForceLimitParameters<T>,
        model: &Model<T, N, B, F>,
        data: &Data<T, N, B, F>,
        layout: &RobotLayout<N, A>,
        residual: &SVector<T, N>,
        hands: &[Option<HandLimits<T>>; A],
        dt: T,
    ) -> Result<(), DynamicsError> {
        let mut world = [SMatrix::<T, 6, N>::zeros(); A];
        self.update_with_jacobians(parameters, model, data, layout, residual, hands, dt, &mut world)
    }

    /// [`Self::update`] that leaves the world-aligned TCP Jacobians `(J_v; J_ω)` of both hands
    /// (what [`frame_jacobian`] writes for `layout.tcp`) in `world`, for the Cartesian tasks of
    /// the same cycle.
    #[allow(clippy::too_many_arguments, reason = "the controller's pieces, each used once")]
    pub fn update_with_jacobians<const B: usize, const F: usize, const A: usize>(
        &mut self,
        parameters: &ForceLimitParameters<T>,
        model: &Model<T, N, B, F>,
        data: &Data<T, N, B, F>,
        layout: &RobotLayout<N, A>,
        residual: &SVector<T, N>,
        hands: &[Option<HandLimits<T>>; A],
        dt: T,
        world: &mut [SMatrix<T, 6, N>; A],
    ) -> Result<(), DynamicsError> {
        // J_h = blockdiag(A_hᵀ, A_hᵀ) J_h,world column by column; J_u (platform columns zero)
        // stacked for both hands into the 12 × N matrix, one 12-entry column per coordinate,
        // written in place (every entry of `self.stacked` is written).
        let mut full = [SMatrix::<T, 6, N>::zeros(); 2];
        for (h, (((tcp, limits), jacobian), world)) in
            layout.tcp.iter().zip(hands.iter()).zip(full.iter_mut()).zip(world.iter_mut()).enumerate()
        {
            let [a0, a1, a2] = limits.map_or_else(Matrix3::identity, |l| l.axes).data.0;
            frame_jacobian(model, data, *tcp, world)?;
            for (k, ((column, source), target)) in jacobian
                .data
                .0
                .iter_mut()
                .zip(world.data.0.iter())
                .zip(self.stacked.as_mut_slice().chunks_exact_mut(12))
                .enumerate()
            {
                let Some(rows) = target.get_mut(6 * h..6 * h + 6) else { continue };
                if source.iter().all(|x| *x == T::zero()) {
                    // Off the TCP's support path: zero in every frame.
                    rows.fill(T::zero());
                    continue;
                }
                // (Aᵀ x)_i = column i of A · x, for the linear and the angular half.
                let [x0, x1, x2, x3, x4, x5] = *source;
                let rotate = |[a, b, c]: &[T; 3], x: T, y: T, z: T| *a * x + *b * y + *c * z;
                *column = [
                    rotate(&a0, x0, x1, x2),
                    rotate(&a1, x0, x1, x2),
                    rotate(&a2, x0, x1, x2),
                    rotate(&a0, x3, x4, x5),
                    rotate(&a1, x3, x4, x5),
                    rotate(&a2, x3, x4, x5),
                ];
                if layout.platform.is_platform(k) {
                    rows.fill(T::zero());
                } else {
                    rows.copy_from_slice(column);
                }
            }
        }
        // Gram matrix J_u J_uᵀ + μ I (lower triangle, the one the factorisation reads) as a sum
        // of rank-one terms over the columns, and J_u τ̂_ext. A column of one hand only (an arm
        // joint) adds to that hand's 6 × 6 diagonal block; a shared one (torso) to all three
        // blocks.
        let mut gram = SMatrix::<T, 12, 12>::zeros();
        for g in gram.as_mut_slice().iter_mut().step_by(13) {
            *g = parameters.regularisation;
        }
        let mut projected = SVector::<T, 12>::zeros();
        for (column, r) in self.stacked.data.0.iter().zip(residual.as_slice().iter()) {
            let [a0, a1, a2, a3, a4, a5, b0, b1, b2, b3, b4, b5] = *column;
            let (first, second) = ([a0, a1, a2, a3, a4, a5], [b0, b1, b2, b3, b4, b5]);
            let moves = |half: &[T; 6]| half.iter().any(|x| *x != T::zero());
            let (first_moves, second_moves) = (moves(&first), moves(&second));
            let (left, right) = gram.data.0.split_at_mut(6);
            if first_moves {
                add_outer(left, 0, &first, &first, true);
                if second_moves {
                    add_outer(left, 6, &second, &first, false);
                }
                for (p, x) in projected.as_mut_slice().iter_mut().zip(first.iter()) {
                    *p += *x * *r;
                }
            }
            if second_moves {
                add_outer(right, 6, &second, &second, true);
                for (p, x) in projected.as_mut_slice().iter_mut().skip(6).zip(second.iter()) {
                    *p += *x * *r;
                }
            }
        }
        self.effective = [None; 2];
        let mut external = projected;
        let solved = cholesky_fixed(&mut gram.data.0)
            && solve_lower_in_place(gram.as_slice(), external.as_mut_slice())
            && solve_lower_transpose_in_place(gram.as_slice(), external.as_mut_slice());
        if !solved {
            self.applied = [Vector6::zeros(); 2];
            self.relief = SVector::zeros();
            return Ok(());
        }
        if !crate::math::all_finite(&external) {
            self.applied = [Vector6::zeros(); 2];
            self.relief = SVector::zeros();
            return Ok(());
        }
        self.govern(parameters, layout, hands, &full, &external, dt);
        Ok(())
    }
}

/// `G_ij += x_{i−offset} y_j` for the six columns `j` of `columns` and the rows
/// `i ∈ [offset, offset + 6)`; on a diagonal block (`x = y`, columns `offset..offset + 6` of the
/// matrix, `diagonal`) only the rows `i ≥ j + offset`, the lower triangle. Fixed trip counts:
/// the loops unroll into straight multiply-adds.
#[inline(always)]
fn add_outer<T: RealField + Copy>(columns: &mut [[T; 12]], offset: usize, x: &[T; 6], y: &[T; 6], diagonal: bool) {
    for (j, (column, y_j)) in columns.iter_mut().zip(y.iter()).enumerate() {
        let first = if diagonal { j } else { 0 };
        for i in first..6 {
            if let (Some(g), Some(x_i)) = (column.get_mut(offset + i), x.get(i)) {
                *g += *x_i * *y_j;
            }
        }
    }
}
