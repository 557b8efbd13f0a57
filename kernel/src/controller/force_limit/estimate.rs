//! The estimate of the contact wrenches from the momentum residual (module docs of
//! [`super`]: "Estimate of the contact wrench").

use nalgebra::{Matrix3, RealField, SMatrix, SVector, Vector6};

use super::limiter::{ForceLimitParameters, ForceLimiter, HandLimits};
use crate::controller::layout::RobotLayout;
use crate::dynamics::{frame_jacobian, DynamicsError};
use crate::math::cholesky::{cholesky_in_place, solve_lower_in_place, solve_lower_transpose_in_place};
use crate::model::{Data, Model};

impl<T: RealField + Copy, const N: usize> ForceLimiter<T, N> {
    /// One period `dt`: estimates the wrenches from `residual` (`τ̂_ext`, [`crate::controller::observer`]) at
    /// the kinematics of `data` (after `forward_kinematics`), then advances the governor of each
    /// hand with `Some` limits (a hand with `None` is reset). If the 12 × 12 solve fails (a
    /// non-finite input), the estimate is zero and the corrections are held. Cost two frame
    /// Jacobians, the 12 × 12 Gram matrix as N rank-one updates and one 12 × 12 Cholesky, all
    /// as loops over the column-major storage.
    /// Errors: [`DynamicsError::UnknownFrame`] for a TCP frame outside the model.
    #[allow(clippy::too_many_arguments, reason = "the controller's pieces, each used once")]
    pub fn update<const B: usize, const F: usize>(
        &mut self,
        parameters: &ForceLimitParameters<T>,
        model: &Model<T, N, B, F>,
        data: &Data<T, N, B, F>,
        layout: &RobotLayout<N>,
        residual: &SVector<T, N>,
        hands: &[Option<HandLimits<T>>; 2],
        dt: T,
    ) -> Result<(), DynamicsError> {
        // J_h = blockdiag(A_hᵀ, A_hᵀ) J_h,world column by column; J_u (platform columns zero)
        // stacked for both hands into the 12 × N matrix, one 12-entry column per coordinate.
        let mut full = [SMatrix::<T, 6, N>::zeros(); 2];
        let mut stacked = SMatrix::<T, 12, N>::zeros();
        for (h, ((tcp, limits), jacobian)) in layout.tcp.iter().zip(hands.iter()).zip(full.iter_mut()).enumerate() {
            let axes = limits.map_or_else(Matrix3::identity, |l| l.axes);
            frame_jacobian(model, data, *tcp, jacobian)?;
            for (k, (column, target)) in
                jacobian.as_mut_slice().chunks_exact_mut(6).zip(stacked.as_mut_slice().chunks_exact_mut(12)).enumerate()
            {
                for half in column.chunks_exact_mut(3) {
                    let world = [
                        half.first().copied().unwrap_or_else(T::zero),
                        half.get(1).copied().unwrap_or_else(T::zero),
                        half.get(2).copied().unwrap_or_else(T::zero),
                    ];
                    // (Aᵀ x)_i = column i of A · x.
                    for (x, a) in half.iter_mut().zip(axes.as_slice().chunks_exact(3)) {
                        *x = a.iter().zip(world.iter()).fold(T::zero(), |s, (a, w)| s + *a * *w);
                    }
                }
                if layout.platform.is_platform(k) {
                    continue;
                }
                if let Some(rows) = target.get_mut(6 * h..6 * h + 6) {
                    rows.copy_from_slice(column);
                }
            }
        }
        // Gram matrix J_u J_uᵀ + μ I as a sum of rank-one terms over the columns, and J_u τ̂_ext.
        let mut gram = SMatrix::<T, 12, 12>::identity() * parameters.regularisation;
        let mut projected = SVector::<T, 12>::zeros();
        for (column, r) in stacked.as_slice().chunks_exact(12).zip(residual.iter()) {
            for (g_column, c_j) in gram.as_mut_slice().chunks_exact_mut(12).zip(column.iter()) {
                if *c_j != T::zero() {
                    for (g, c_i) in g_column.iter_mut().zip(column.iter()) {
                        *g += *c_i * *c_j;
                    }
                }
            }
            for (p, c) in projected.iter_mut().zip(column.iter()) {
                *p += *c * *r;
            }
        }
        self.stacked = stacked;
        self.effective = [None; 2];
        let mut external = projected;
        let solved = cholesky_in_place(gram.as_mut_slice(), 12)
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
