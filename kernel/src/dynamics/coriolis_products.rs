//! Products with the Christoffel-consistent Coriolis matrix without forming it: `C(q, q̇) x`
//! and `Cᵀ(q, q̇) q̇`, each in one O(B) tree pass.

use nalgebra::{RealField, SVector, Vector6};

use super::kernels::{add6, add_scaled6, add_to_coordinates, dot6};
use super::rnea::force_cross;
use crate::model::{Data, Model};

/// `C(q, q̇) x` for any coordinate vector `x`, with the `C` of [`super::coriolis_matrix`]
/// ((2.1), `Ṁ = C + Cᵀ` (2.7)), by a Newton–Euler-style pass in world coordinates.
///
/// With `C = Σ_i J_iᵀ (I_i J̇_i + B_i J_i)` and `B_i = ½ İ_i + ½ (I_i v_i)×̄`: the forward
/// pass accumulates `u_i = J_i x = u_p + S_i x_i` and `w_i = J̇_i x = w_p + Ṡ_i x_i`
/// (`x_i` the joint's rate for `x` through the drive row), the body force is
/// `f_i = I_i w_i + ½ İ_i u_i + ½ u_i ×* (I_i v_i)`, and the backward pass sums the forces
/// into the parents and projects `S_iᵀ f^c_i`, mapped to coordinates as `Gᵀ τ_tree`.
/// For `x = q̇` this is RNEA's velocity-product term.
///
/// Precondition: [`super::forward_kinematics`] at `(q, q̇)`. Reads the motion subspaces,
/// their rates, the body velocities and the world inertias; writes nothing. Cost O(B).
pub fn coriolis_product<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    x: &SVector<T, N>,
) -> SVector<T, N> {
    let half = nalgebra::convert::<f64, T>(0.5);
    // Per body `(u_i, w_i)` in the forward pass, then its subtree force `f^c_i`.
    let mut motion = [(Vector6::<T>::zeros(), Vector6::<T>::zeros()); B];
    let mut forces = [Vector6::<T>::zeros(); B];
    let per_body = model
        .bodies()
        .iter()
        .zip(data.motion_subspaces.iter())
        .zip(data.subspace_rates.iter())
        .zip(data.body_velocities.iter())
        .zip(data.world_inertias.iter())
        .zip(forces.iter_mut())
        .enumerate();
    for (i, (((((body, s), s_dot), v), inertia), force)) in per_body {
        let (u_parent, w_parent) = body
            .parent
            .map(|p| p.0)
            .filter(|p| *p < i)
            .and_then(|p| motion.get(p))
            .copied()
            .unwrap_or((Vector6::zeros(), Vector6::zeros()));
        let rate = body.drive.evaluate(x, false);
        let u = add_scaled6(&u_parent, s, rate);
        let w = add_scaled6(&w_parent, s_dot, rate);
        let coriolis = add6(&inertia.rate(v).apply(&u), &force_cross(&u, &inertia.apply(v)));
        *force = add_scaled6(&inertia.apply(&w), &coriolis, half);
        if let Some(slot) = motion.get_mut(i) {
            *slot = (u, w);
        }
    }
    let mut out = SVector::zeros();
    for (i, body) in model.bodies().iter().enumerate().rev() {
        let (Some(f), Some(s)) = (forces.get(i).copied(), data.motion_subspaces.get(i)) else {
            continue;
        };
        add_to_coordinates(&mut out, &body.drive, dot6(s, &f));
        if let Some(parent) = body.parent.map(|p| p.0).filter(|p| *p < i).and_then(|p| forces.get_mut(p)) {
            *parent = add6(parent, &f);
        }
    }
    out
}

/// `Cᵀ(q, q̇) q̇ = Ṁ q̇ − C q̇` for the `C` of [`super::coriolis_matrix`] ((2.7); the term of
/// the momentum observer's `ṗ = τ + τ_ext + Cᵀ q̇ − g`).
///
/// Since `B_iᵀ v_i = ½ İ_i v_i − ½ v_i ×* I_i v_i = 0`, only the `J̇_iᵀ I_i v_i` part of
/// `Cᵀ = Σ_i (J̇_iᵀ I_i + J_iᵀ B_iᵀ) J_i` remains: the tree entry of joint `j` is
/// `Ṡ_jᵀ p^c_j` with the subtree momentum `p^c_j = Σ_{k ∈ subtree(j)} I_k v_k`, mapped to
/// coordinates as `Gᵀ τ_tree`.
///
/// Precondition: [`super::forward_kinematics`] at `(q, q̇)`. Reads the subspace rates, the
/// body velocities and the world inertias; writes nothing. Cost O(B).
pub fn coriolis_transpose_velocity<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
) -> SVector<T, N> {
    let mut momenta = [Vector6::<T>::zeros(); B];
    for ((p, inertia), v) in momenta.iter_mut().zip(data.world_inertias.iter()).zip(data.body_velocities.iter()) {
        *p = inertia.apply(v);
    }
    let mut out = SVector::zeros();
    for (i, body) in model.bodies().iter().enumerate().rev() {
        let (Some(p), Some(s_dot)) = (momenta.get(i).copied(), data.subspace_rates.get(i)) else {
            continue;
        };
        add_to_coordinates(&mut out, &body.drive, dot6(s_dot, &p));
        if let Some(parent) = body.parent.map(|p| p.0).filter(|p| *p < i).and_then(|p| momenta.get_mut(p)) {
            *parent = add6(parent, &p);
        }
    }
    out
}

/// `(C(q, q̇) q̇, Cᵀ(q, q̇) q̇)` for the `C` of [`super::coriolis_matrix`] ((2.1), (2.7)) in
/// one O(B) tree pass on the stored kinematics.
///
/// For `x = q̇` the pass of [`coriolis_product`] has `u_i = v_i` and `w_i = ζ_i` (the body
/// velocity and drift of forward kinematics), and `½ İ_i v_i = ½ v_i ×* (I_i v_i)`, so the body
/// force is RNEA's velocity product `f_i = I_i ζ_i + v_i ×* p_i` with the momentum
/// `p_i = I_i v_i`; the same momenta summed over the subtrees give
/// [`coriolis_transpose_velocity`]'s `Ṡ_jᵀ p^c_j`. Backward pass: `S_iᵀ f^c_i` and
/// `Ṡ_iᵀ p^c_i`, mapped to coordinates as `Gᵀ τ_tree`.
///
/// Precondition: [`super::kinematics`] at `(q, q̇)` at [`super::KinematicsLevel::Velocities`]
/// or above. Reads the motion subspaces, their rates, the body velocities and drifts and the
/// world inertias; writes nothing. Cost O(B).
pub fn coriolis_velocity_products<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
) -> (SVector<T, N>, SVector<T, N>) {
    // Per body its force `f_i` and momentum `p_i`, then their subtree sums.
    let mut forces = [(Vector6::<T>::zeros(), Vector6::<T>::zeros()); B];
    let per_body = forces
        .iter_mut()
        .zip(data.world_inertias.iter())
        .zip(data.body_velocities.iter())
        .zip(data.body_drift_accelerations.iter());
    for (((slot, inertia), v), drift) in per_body {
        let momentum = inertia.apply(v);
        *slot = (add6(&inertia.apply(drift), &force_cross(v, &momentum)), momentum);
    }
    let (mut product, mut transpose) = (SVector::zeros(), SVector::zeros());
    for (i, body) in model.bodies().iter().enumerate().rev() {
        let (Some((f, p)), Some(s), Some(s_dot)) =
            (forces.get(i).copied(), data.motion_subspaces.get(i), data.subspace_rates.get(i))
        else {
            continue;
        };
        add_to_coordinates(&mut product, &body.drive, dot6(s, &f));
        add_to_coordinates(&mut transpose, &body.drive, dot6(s_dot, &p));
        if let Some(parent) = body.parent.map(|p| p.0).filter(|p| *p < i).and_then(|p| forces.get_mut(p)) {
            *parent = (add6(&parent.0, &f), add6(&parent.1, &p));
        }
    }
    (product, transpose)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::dynamics::{coriolis_matrix, forward_kinematics};
    use crate::test_models::{branched, state, B, F, N};
    use nalgebra::SMatrix;
    use proptest::prelude::*;

    /// `(C x, Cᵀ q̇)` by the tree passes and by the matrix of [`coriolis_matrix`], cast to f64.
    fn products<T: RealField + Copy>(
        model: &Model<T, N, B, F>,
        q: &SVector<f64, N>,
        v: &SVector<f64, N>,
        x: &SVector<f64, N>,
    ) -> ([SVector<f64, N>; 2], [SVector<f64, N>; 2]) {
        let cast = |y: &SVector<f64, N>| y.map(|e| nalgebra::convert::<f64, T>(e));
        let back = |y: SVector<T, N>| y.map(|e| nalgebra::try_convert::<T, f64>(e).unwrap());
        let mut data = Data::new(model);
        forward_kinematics(model, &mut data, &cast(q), &cast(v)).unwrap();
        let fast = [back(coriolis_product(model, &data, &cast(x))), back(coriolis_transpose_velocity(model, &data))];
        let c: SMatrix<T, N, N> = *coriolis_matrix(model, &mut data);
        let matrix = [back(c * cast(x)), back(c.transpose() * cast(v))];
        (fast, matrix)
    }

    proptest! {
        /// On the branched model (prismatic root, skewed axes, a branch point, a coupled joint):
        /// the tree passes equal the products with the full matrix, f64 to rounding; f32 within
        /// single-precision rounding of the f64 matrix.
        #[test]
        fn products_equal_matrix_products(seed in any::<u64>()) {
            let (q, v, x) = (state(seed, 2.0), state(seed ^ 3, 2.0), state(seed ^ 11, 2.0));
            let (fast, matrix) = products(&branched::<f64>(), &q, &v, &x);
            for (a, b) in fast.iter().zip(matrix.iter()) {
                prop_assert!((a - b).amax() <= 1e-12 * (1.0 + b.amax()), "f64: {:e}", (a - b).amax());
            }
            let (fast32, _) = products(&branched::<f32>(), &q, &v, &x);
            for (a, b) in fast32.iter().zip(matrix.iter()) {
                prop_assert!((a - b).amax() <= 2e-5 * (1.0 + b.amax()), "f32: {:e}", (a - b).amax());
            }
        }

        /// The fused `(C q̇, Cᵀ q̇)` after the velocity-level kinematics pass equals the two
        /// separate passes after full forward kinematics and the products with the matrix of
        /// [`coriolis_matrix`] (f64 to rounding, f32 within single-precision rounding).
        #[test]
        fn fused_velocity_products_equal_separate_passes(seed in any::<u64>()) {
            let (q, v) = (state(seed, 2.0), state(seed ^ 3, 2.0));
            let (separate, matrix) = products(&branched::<f64>(), &q, &v, &v);
            let fused = |model: &Model<f64, N, B, F>| {
                let mut data = Data::new(model);
                crate::dynamics::kinematics(model, &mut data, &q, crate::dynamics::KinematicsLevel::Velocities(&v))
                    .unwrap();
                let (c_v, ct_v) = coriolis_velocity_products(model, &data);
                [c_v, ct_v]
            };
            for ((a, b), c) in fused(&branched::<f64>()).iter().zip(separate.iter()).zip(matrix.iter()) {
                prop_assert!((a - b).amax() <= 1e-12 * (1.0 + b.amax()), "f64 passes: {:e}", (a - b).amax());
                prop_assert!((a - c).amax() <= 1e-12 * (1.0 + c.amax()), "f64 matrix: {:e}", (a - c).amax());
            }
            let m32 = branched::<f32>();
            let mut data = Data::new(&m32);
            let (q32, v32) = (q.map(|x| x as f32), v.map(|x| x as f32));
            crate::dynamics::kinematics(&m32, &mut data, &q32, crate::dynamics::KinematicsLevel::Velocities(&v32))
                .unwrap();
            let (c_v, ct_v) = coriolis_velocity_products(&m32, &data);
            for (a, c) in [c_v, ct_v].iter().zip(matrix.iter()) {
                let a = a.map(f64::from);
                prop_assert!((a - c).amax() <= 2e-5 * (1.0 + c.amax()), "f32: {:e}", (a - c).amax());
            }
        }

        /// `C q̇` by the product is RNEA's velocity term and `C q̇ + Cᵀ q̇` is `Ṁ q̇`: the
        /// matrix-free products satisfy (2.7) on their own (no round trip through `C`).
        #[test]
        fn products_give_mass_matrix_rate(seed in any::<u64>()) {
            let model = branched::<f64>();
            let (q, v) = (state(seed, 2.0), state(seed ^ 7, 2.0));
            let mut data = Data::new(&model);
            forward_kinematics(&model, &mut data, &q, &v).unwrap();
            let c_v = coriolis_product(&model, &data, &v);
            let ct_v = coriolis_transpose_velocity(&model, &data);
            let bias = *crate::dynamics::rnea(&model, &mut data, &SVector::zeros()).unwrap();
            let g = *crate::dynamics::gravity(&model, &mut data);
            prop_assert!((c_v + g - bias).amax() < 1e-11 * (1.0 + bias.amax()));
            let mass = |q: &SVector<f64, N>| {
                let mut d = Data::new(&model);
                forward_kinematics(&model, &mut d, q, &SVector::zeros()).unwrap();
                *crate::dynamics::crba(&model, &mut d)
            };
            let h = 1e-5;
            let m_dot_v = (mass(&(q + v * h)) - mass(&(q - v * h))) / (2.0 * h) * v;
            prop_assert!((m_dot_v - c_v - ct_v).amax() < 1e-7 * (1.0 + m_dot_v.amax()));
        }
    }
}
