//! The estimate of the contact wrenches from the momentum residual (module docs of
//! [`super`]: "Estimate of the contact wrench").

use nalgebra::{Matrix3, RealField, SMatrix, SVector, Vector6};

use super::limiter::{ForceLimitParameters, ForceLimiter, HandLimits, Stacked};
use crate::controller::layout::RobotLayout;
use crate::dynamics::{frame_jacobian, DynamicsError};
use crate::math::cholesky::{cholesky_blocks, solve_lower_in_place, solve_lower_transpose_in_place};
use crate::model::{Data, Model};

impl<T: RealField + Copy, const N: usize, const A: usize> ForceLimiter<T, N, A> {
    /// One period `dt`: estimates the wrenches from `residual` (`τ̂_ext`, [`crate::controller::observer`]) at
    /// the kinematics of `data` (after `forward_kinematics`), then advances the governor of each
    /// hand with `Some` limits (a hand with `None` is reset). If the `6 A × 6 A` solve fails (a
    /// non-finite input), the estimate is zero and the corrections are held. Cost `A` frame
    /// Jacobians (the columns off a TCP's support path are zero and skipped), the lower
    /// triangle of the `6 A × 6 A` Gram matrix as N rank-one updates restricted to the hands a
    /// column moves (21 multiply-adds for an arm joint, 78 for one shared by two hands) and one
    /// `6 A × 6 A` Cholesky, all as loops over the column-major storage.
    /// Errors: [`DynamicsError::UnknownFrame`] for a TCP frame outside the model.
    #[allow(clippy::too_many_arguments, reason = "the controller's pieces, each used once")]
    pub fn update<const B: usize, const F: usize>(
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

    /// [`Self::update`] that leaves the world-aligned TCP Jacobians `(J_v; J_ω)` of every hand
    /// (what [`frame_jacobian`] writes for `layout.tcp`) in `world`, for the Cartesian tasks of
    /// the same cycle.
    #[allow(clippy::too_many_arguments, reason = "the controller's pieces, each used once")]
    pub fn update_with_jacobians<const B: usize, const F: usize>(
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
        // stacked for every hand into the 6A × N matrix, one 6A-entry column per coordinate,
        // written in place (every entry of `self.stacked` is written).
        let mut full = [SMatrix::<T, 6, N>::zeros(); A];
        for (h, (((tcp, limits), jacobian), world)) in
            layout.tcp.iter().zip(hands.iter()).zip(full.iter_mut()).zip(world.iter_mut()).enumerate()
        {
            let [a0, a1, a2] = limits.map_or_else(Matrix3::identity, |l| l.axes).data.0;
            frame_jacobian(model, data, *tcp, world)?;
            for (k, ((column, source), target)) in
                jacobian.data.0.iter_mut().zip(world.data.0.iter()).zip(self.stacked.iter_mut()).enumerate()
            {
                let Some(rows) = target.get_mut(h) else { continue };
                if source.iter().all(|x| *x == T::zero()) {
                    // Off the TCP's support path: zero in every frame.
                    *rows = [T::zero(); 6];
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
                *rows = if layout.platform.is_platform(k) { [T::zero(); 6] } else { *column };
            }
        }
        // Gram matrix J_u J_uᵀ + μ I (lower triangle, the one the factorisation reads; column
        // block `b` of hand `b`, row block `a`) as a sum of rank-one terms over the columns, and
        // J_u τ̂_ext. A column of one hand only (an arm joint) adds to that hand's 6 × 6
        // diagonal block; one shared by hands (torso) to the blocks of every pair of them.
        let mut gram = [[[[T::zero(); 6]; A]; 6]; A];
        for (b, block) in gram.iter_mut().enumerate() {
            for (j, column) in block.iter_mut().enumerate() {
                if let Some(g) = column.get_mut(b).and_then(|rows| rows.get_mut(j)) {
                    *g = parameters.regularisation;
                }
            }
        }
        let mut projected: Stacked<T, A> = [[T::zero(); 6]; A];
        for (column, r) in self.stacked.iter().zip(residual.as_slice().iter()) {
            let moves = column.map(|half| half.iter().any(|x| *x != T::zero()));
            // Index loops with fixed trip counts: they unroll for the layout's `A`.
            for b in 0..A {
                let (Some(y), Some(true), Some(block), Some(p)) =
                    (column.get(b), moves.get(b).copied(), gram.get_mut(b), projected.get_mut(b))
                else {
                    continue;
                };
                for a in b..A {
                    if let (Some(x), Some(true)) = (column.get(a), moves.get(a).copied()) {
                        add_outer(block, a, x, y, a == b);
                    }
                }
                for (p, x) in p.iter_mut().zip(y.iter()) {
                    *p += *x * *r;
                }
            }
        }
        self.effective = [None; A];
        let mut external = projected;
        let factored = cholesky_blocks(&mut gram);
        let (factor, rhs) =
            (gram.as_flattened_mut().as_flattened_mut().as_flattened_mut(), external.as_flattened_mut());
        let solved = factored && solve_lower_in_place(factor, rhs) && solve_lower_transpose_in_place(factor, rhs);
        if !(solved && rhs.iter().all(|x| x.is_finite())) {
            self.applied = [Vector6::zeros(); A];
            self.relief = SVector::zeros();
            return Ok(());
        }
        self.govern(parameters, layout, hands, &full, &external, dt);
        Ok(())
    }
}

/// `G_ij += x_i y_j` for the six columns `j` of `columns` (one hand's column block) and the six
/// rows `i` of row block `block`; on a diagonal block (`x = y`, `diagonal`) only the rows
/// `i ≥ j`, the lower triangle. Fixed trip counts: the loops unroll into straight multiply-adds.
/// Out of line, so that the loops over the hands that call it stay small (M7 f32: Justin's step
/// 93 instructions above the two-hand code it replaced, 1 036 with it inlined).
#[inline(never)]
fn add_outer<T: RealField + Copy, const A: usize>(
    columns: &mut [Stacked<T, A>; 6],
    block: usize,
    x: &[T; 6],
    y: &[T; 6],
    diagonal: bool,
) {
    for (j, (column, y_j)) in columns.iter_mut().zip(y.iter()).enumerate() {
        let Some(rows) = column.get_mut(block) else { continue };
        let first = if diagonal { j } else { 0 };
        for i in first..6 {
            if let (Some(g), Some(x_i)) = (rows.get_mut(i), x.get(i)) {
                *g += *x_i * *y_j;
            }
        }
    }
}
