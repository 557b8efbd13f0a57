//! Forward dynamics through a Cholesky factorization of the mass matrix.

use nalgebra::{Cholesky, Const, RealField, SVector};

use super::crba::crba;
use super::error::DynamicsError;
use super::kernels::check_finite;
use super::rnea::rnea;
use crate::model::{Data, Model};

/// Cholesky factorization `M = L Lᵀ` of the mass matrix last written by [`crba`].
///
/// The only way the kernel "inverts" `M`: solves go through the factor, never through an
/// explicit inverse. Cost O(N³/3). Errors: [`DynamicsError::MassMatrixNotPositiveDefinite`].
pub fn mass_matrix_cholesky<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    data: &Data<T, N, B, F>,
) -> Result<Cholesky<T, Const<N>>, DynamicsError> {
    Cholesky::new(data.mass_matrix).ok_or(DynamicsError::MassMatrixNotPositiveDefinite)
}

/// Forward dynamics `q̈ = M(q)⁻¹ (τ − C(q, q̇) q̇ − g(q))` of (2.1).
///
/// Runs [`rnea`] with `q̈ = 0` for the bias `C q̇ + g`, [`crba`] for `M` and solves with its
/// Cholesky factor. Precondition: [`super::forward_kinematics`] at `(q, q̇)`.
/// Errors: non-finite `τ`, or `M` not positive definite (then nothing is returned).
pub fn forward_dynamics<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &mut Data<T, N, B, F>,
    tau: &SVector<T, N>,
) -> Result<SVector<T, N>, DynamicsError> {
    check_finite(tau, "tau")?;
    let bias = *rnea(model, data, &SVector::zeros())?;
    crba(model, data);
    let factor = mass_matrix_cholesky(data)?;
    Ok(factor.solve(&(tau - bias)))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::dynamics::forward_kinematics;
    use crate::test_models::{branched, state};

    #[test]
    fn forward_dynamics_inverts_rnea() {
        let model = branched::<f64>();
        let mut data = Data::new(&model);
        for seed in 0..50 {
            let (q, v, tau) = (state(seed, 2.0), state(seed + 1, 2.0), state(seed + 2, 20.0));
            forward_kinematics(&model, &mut data, &q, &v).unwrap();
            let qdd = forward_dynamics(&model, &mut data, &tau).unwrap();
            let back = *rnea(&model, &mut data, &qdd).unwrap();
            assert!((back - tau).amax() < 1e-10 * (1.0 + tau.amax()));
        }
    }

    #[test]
    fn non_finite_input_is_rejected() {
        let model = branched::<f64>();
        let mut data = Data::new(&model);
        let mut q = state(1, 1.0);
        q[2] = f64::NAN;
        let v = SVector::zeros();
        assert_eq!(forward_kinematics(&model, &mut data, &q, &v), Err(DynamicsError::NonFinite { input: "q" }));
        forward_kinematics(&model, &mut data, &state(1, 1.0), &v).unwrap();
        let mut tau = SVector::zeros();
        tau[0] = f64::INFINITY;
        assert_eq!(forward_dynamics(&model, &mut data, &tau), Err(DynamicsError::NonFinite { input: "tau" }));
    }
}
