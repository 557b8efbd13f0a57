//! Rigid-body dynamics of the kinematic tree (Sec. 2.1 of the thesis; Featherstone's
//! algorithms), one algorithm per file.
//!
//! Call [`forward_kinematics`] once per state (or [`kinematics`] at the [`KinematicsLevel`]
//! the caller needs: [`placement_kinematics`] for CRBA, gravity and Jacobians, velocities
//! without the 6×6 inertias for the controller; [`support_kinematics`] for the Jacobians of
//! one body); the other algorithms read the kinematics it stored in
//! [`crate::model::Data`] and write their own outputs there:
//!
//! | algorithm | computes | cost |
//! | --- | --- | --- |
//! | [`forward_kinematics`] | placements, motion subspaces, body velocities and drifts | O(B) |
//! | [`kinematics`] | the same up to a [`KinematicsLevel`] (placements; velocities; all) | O(B) |
//! | [`placement_kinematics`] | placements, motion subspaces, world inertias (for CRBA, gravity, Jacobians) | O(B) |
//! | [`support_kinematics`] | placements and motion subspaces of one support path (for its Jacobians) | O(depth) |
//! | [`frame_jacobian`], [`point_jacobian`] | 6×N Jacobian, world-aligned, linear rows first | O(depth) |
//! | [`frame_drift`], [`point_drift`] | `J̇(q, q̇) q̇` | O(1) |
//! | [`rnea`] | `M q̈ + C q̇ + g` | O(B) |
//! | [`gravity`] | `g(q)` | O(B) |
//! | [`crba`] | `M(q)` | O(B·depth) |
//! | [`composite_inertia_matrices`] | the 6×6 `I^c` of [`crba`] | O(B) |
//! | [`coriolis_matrix`] | `C(q, q̇)` with `Ṁ = C + Cᵀ` (2.7) | O(B·depth) |
//! | [`composite_coriolis_operators`] | the 6×6 `B^c` of [`coriolis_matrix`] | O(B) |
//! | [`coriolis_product`], [`coriolis_transpose_velocity`] | `C x`, `Cᵀ q̇` without forming `C` | O(B) |
//! | [`coriolis_velocity_products`] | `C q̇` and `Cᵀ q̇` in one pass | O(B) |
//! | [`mass_matrix_cholesky`], [`forward_dynamics`] | `M = L Lᵀ`, `q̈ = M⁻¹(τ − C q̇ − g)` | O(N³) |
//! | [`TreeFactorization`] | `M = Lᵀ L` over the branch-induced sparsity, solves | O(Σ depth²) |
//! | [`kinetic_energy`], [`potential_energy`] | `½ q̇ᵀ M q̇`, `−Σ m_i gᵀ c_i` | O(B) |
//!
//! With coupled joints the tree quantities are mapped through the constant drive matrix `G`
//! (`q_tree = G q + offset`): `M = Gᵀ M_tree G`, `C = Gᵀ C_tree G`, `τ = Gᵀ τ_tree`,
//! `J = J_tree G`; see [`crate::model::JointDrive`].

mod coriolis_matrix;
mod coriolis_products;
mod crba;
mod energy;
mod error;
mod forward_dynamics;
mod forward_kinematics;
mod frame_drift;
mod frame_jacobian;
mod gravity;
mod jacobian_derivative;
mod kernels;
mod rnea;
mod tree_copy;
mod tree_factorization;
mod tree_kernels;

pub use coriolis_matrix::{composite_coriolis_operators, coriolis_matrix};
pub use coriolis_products::{coriolis_product, coriolis_transpose_velocity, coriolis_velocity_products};
pub use crba::{composite_inertia_matrices, crba};
pub use energy::{kinetic_energy, potential_energy};
pub use error::DynamicsError;
pub use forward_dynamics::{forward_dynamics, mass_matrix_cholesky};
pub use forward_kinematics::{
    forward_kinematics, kinematics, placement_kinematics, support_kinematics, KinematicsLevel,
};
pub use frame_drift::{frame_drift, point_drift};
pub use frame_jacobian::{frame_jacobian, point_jacobian};
pub use gravity::gravity;
pub use jacobian_derivative::{frame_jacobian_derivative, point_jacobian_derivative};
pub use rnea::rnea;
pub use tree_factorization::{InertiaFactor, TreeFactorization, TreeStructure};

/// The plain reference algorithms (test-only; also included by the `thesis-tests` crate).
#[cfg(test)]
#[allow(clippy::indexing_slicing, dead_code, reason = "test reference")]
pub(crate) mod reference {
    use crate as kernel;
    include!("reference.rs");
}

#[cfg(test)]
mod reference_tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    //! The fast algorithms against [`super::reference`] on the branched test model (prismatic
    //! root, skewed axes, a branch point, a coupled joint) at random states.
    use super::*;
    use crate::model::{BodyId, Data, Model};
    use crate::test_models::{branched, state, B, F, N};
    use nalgebra::{RealField, SMatrix, SVector};
    use proptest::prelude::*;

    /// Largest absolute difference of two equally long sequences.
    fn diff<'a>(a: impl IntoIterator<Item = &'a f64>, b: impl IntoIterator<Item = &'a f64>) -> f64 {
        a.into_iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
    }

    /// Every output of the fast algorithms, cast to f64.
    struct Outputs {
        m: SMatrix<f64, N, N>,
        ic: [SMatrix<f64, 6, 6>; B],
        c: SMatrix<f64, N, N>,
        bc: [SMatrix<f64, 6, 6>; B],
        g: SVector<f64, N>,
        tau: SVector<f64, N>,
        jacobians: [SMatrix<f64, 6, N>; 2],
        kinematics: std::vec::Vec<f64>,
    }

    fn fast<T: RealField + Copy>(
        model: &Model<T, N, B, F>,
        q: &SVector<f64, N>,
        v: &SVector<f64, N>,
        a: &SVector<f64, N>,
    ) -> Outputs {
        let cast = |x: &SVector<f64, N>| x.map(|e| nalgebra::convert::<f64, T>(e));
        let mut data = Data::new(model);
        forward_kinematics(model, &mut data, &cast(q), &cast(v)).unwrap();
        let m = crba(model, &mut data).map(|e| nalgebra::try_convert(e).unwrap());
        let ic = composite_inertia_matrices(&mut data).map(|x| x.map(|e| nalgebra::try_convert(e).unwrap()));
        let c = coriolis_matrix(model, &mut data).map(|e| nalgebra::try_convert(e).unwrap());
        let bc = composite_coriolis_operators(&mut data).map(|x| x.map(|e| nalgebra::try_convert(e).unwrap()));
        let g = gravity(model, &mut data).map(|e| nalgebra::try_convert(e).unwrap());
        let tau = rnea(model, &mut data, &cast(a)).unwrap().map(|e| nalgebra::try_convert(e).unwrap());
        let mut jacobians = [SMatrix::zeros(); 2];
        for (k, out) in jacobians.iter_mut().enumerate() {
            let mut j = SMatrix::<T, 6, N>::zeros();
            frame_jacobian(model, &data, crate::model::FrameId(k), &mut j).unwrap();
            *out = j.map(|e| nalgebra::try_convert(e).unwrap());
        }
        Outputs { m, ic, c, bc, g, tau, jacobians, kinematics: kinematics(&data) }
    }

    fn reference_outputs(
        model: &Model<f64, N, B, F>,
        q: &SVector<f64, N>,
        v: &SVector<f64, N>,
        a: &SVector<f64, N>,
    ) -> Outputs {
        let mut data = Data::new(model);
        reference::forward_kinematics(model, &mut data, q, v);
        let (c, bc) = reference::coriolis(model, &data);
        // g(q) = RNEA(q, 0, 0).
        let mut at_rest = Data::new(model);
        reference::forward_kinematics(model, &mut at_rest, q, &SVector::zeros());
        let mut jacobians = [SMatrix::zeros(); 2];
        for (k, out) in jacobians.iter_mut().enumerate() {
            let frame = &model.frames()[k];
            let p = data.frame_placements[k].translation.vector;
            *out = reference::point_jacobian(model, &data, frame.parent.unwrap_or(BodyId(0)), &p);
        }
        Outputs {
            m: reference::crba(model, &data),
            ic: reference::composites(model, &data.body_inertias),
            c,
            bc,
            g: reference::rnea(model, &at_rest, &SVector::zeros()),
            tau: reference::rnea(model, &data, a),
            jacobians,
            kinematics: kinematics(&data),
        }
    }

    /// Placements, subspaces, velocities, drifts, 6×6 inertias and frame placements, flattened.
    fn kinematics<T: RealField + Copy>(data: &Data<T, N, B, F>) -> std::vec::Vec<f64> {
        let mut out = std::vec::Vec::new();
        let mut push = |x: &[T]| out.extend(x.iter().map(|e| nalgebra::try_convert::<T, f64>(*e).unwrap()));
        for i in 0..B {
            push(data.body_placements[i].to_homogeneous().as_slice());
            push(data.motion_subspaces[i].as_slice());
            push(data.body_velocities[i].as_slice());
            push(data.body_drift_accelerations[i].as_slice());
            push(data.body_inertias[i].as_slice());
        }
        for f in &data.frame_placements {
            push(f.to_homogeneous().as_slice());
        }
        out
    }

    /// `fast` within `tol · (1 + max |reference|)` of `reference`, output by output.
    fn check(fast: &Outputs, reference: &Outputs, tol: f64) -> Result<(), TestCaseError> {
        let close = |name: &str, a: &[f64], b: &[f64]| -> Result<(), TestCaseError> {
            let scale = 1.0 + b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let d = diff(a, b);
            prop_assert!(d <= tol * scale, "{name}: difference {d:e} (scale {scale:e})");
            Ok(())
        };
        close("kinematics", &fast.kinematics, &reference.kinematics)?;
        close("M", fast.m.as_slice(), reference.m.as_slice())?;
        for (a, b) in fast.ic.iter().zip(reference.ic.iter()) {
            close("I^c", a.as_slice(), b.as_slice())?;
        }
        close("C", fast.c.as_slice(), reference.c.as_slice())?;
        for (a, b) in fast.bc.iter().zip(reference.bc.iter()) {
            close("B^c", a.as_slice(), b.as_slice())?;
        }
        close("g", fast.g.as_slice(), reference.g.as_slice())?;
        close("rnea", fast.tau.as_slice(), reference.tau.as_slice())?;
        for (a, b) in fast.jacobians.iter().zip(reference.jacobians.iter()) {
            close("J", a.as_slice(), b.as_slice())?;
        }
        Ok(())
    }

    /// `M`, `g` and both frame Jacobians after the position-only passes on fresh workspaces
    /// (`placement_kinematics` for all of them, then `support_kinematics` of each frame's body
    /// alone for its Jacobian), cast to f64.
    fn positions_only<T: RealField + Copy>(model: &Model<T, N, B, F>, q: &SVector<f64, N>) -> std::vec::Vec<f64> {
        let q = q.map(|e| nalgebra::convert::<f64, T>(e));
        let mut out = std::vec::Vec::new();
        let mut push = |x: &[T]| out.extend(x.iter().map(|e| nalgebra::try_convert::<T, f64>(*e).unwrap()));
        let mut data = Data::new(model);
        placement_kinematics(model, &mut data, &q).unwrap();
        push(crba(model, &mut data).as_slice());
        push(gravity(model, &mut data).as_slice());
        for k in 0..2 {
            let mut j = SMatrix::<T, 6, N>::zeros();
            frame_jacobian(model, &data, crate::model::FrameId(k), &mut j).unwrap();
            push(j.as_slice());
            let mut support = Data::new(model);
            let body = model.frames()[k].parent.unwrap();
            support_kinematics(model, &mut support, &q, body).unwrap();
            let mut j = SMatrix::<T, 6, N>::from_element(T::one());
            frame_jacobian(model, &support, crate::model::FrameId(k), &mut j).unwrap();
            push(j.as_slice());
        }
        out
    }

    /// The reference values in the order of [`positions_only`].
    fn reference_positions_only(model: &Model<f64, N, B, F>, q: &SVector<f64, N>) -> std::vec::Vec<f64> {
        let zero = SVector::zeros();
        let r = reference_outputs(model, q, &zero, &zero);
        let mut out = std::vec::Vec::new();
        out.extend_from_slice(r.m.as_slice());
        out.extend_from_slice(r.g.as_slice());
        for j in &r.jacobians {
            out.extend_from_slice(j.as_slice());
            out.extend_from_slice(j.as_slice());
        }
        out
    }

    proptest! {
        /// The position-only passes give the reference `M`, `g` and frame Jacobians: f64 to
        /// rounding, f32 within single-precision rounding.
        #[test]
        fn position_kinematics_equal_reference(seed in any::<u64>()) {
            let (m64, m32) = (branched::<f64>(), branched::<f32>());
            let q = state(seed, 2.0);
            let reference = reference_positions_only(&m64, &q);
            let scale = 1.0 + reference.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let d64 = diff(&positions_only(&m64, &q), &reference);
            prop_assert!(d64 <= 1e-12 * scale, "f64: difference {d64:e}");
            let d32 = diff(&positions_only(&m32, &q), &reference);
            prop_assert!(d32 <= 2e-5 * scale, "f32: difference {d32:e}");
        }

        /// An unknown body is an error of `support_kinematics`, a non-finite `q` of both passes.
        #[test]
        fn position_kinematics_reject_bad_input(seed in any::<u64>()) {
            let model = branched::<f64>();
            let mut data = Data::new(&model);
            let mut q = state(seed, 2.0);
            prop_assert_eq!(support_kinematics(&model, &mut data, &q, BodyId(B)), Err(DynamicsError::UnknownBody));
            q[0] = f64::NAN;
            prop_assert!(placement_kinematics(&model, &mut data, &q).is_err());
            prop_assert!(support_kinematics(&model, &mut data, &q, BodyId(0)).is_err());
        }

        /// f64: the fast FK, CRBA, Coriolis matrix (and `B^c`), gravity, RNEA and frame
        /// Jacobians equal the reference to rounding.
        #[test]
        fn fast_equals_reference_f64(seed in any::<u64>()) {
            let model = branched::<f64>();
            let (q, v, a) = (state(seed, 2.0), state(seed ^ 5, 2.0), state(seed ^ 9, 3.0));
            check(&fast(&model, &q, &v, &a), &reference_outputs(&model, &q, &v, &a), 1e-12)?;
        }

        /// f32: the fast algorithms in single precision stay within f32 rounding of the f64
        /// reference.
        #[test]
        fn fast_f32_is_within_tolerance_of_reference_f64(seed in any::<u64>()) {
            let (m64, m32) = (branched::<f64>(), branched::<f32>());
            let (q, v, a) = (state(seed, 2.0), state(seed ^ 5, 2.0), state(seed ^ 9, 3.0));
            check(&fast(&m32, &q, &v, &a), &reference_outputs(&m64, &q, &v, &a), 2e-5)?;
        }
    }
}
