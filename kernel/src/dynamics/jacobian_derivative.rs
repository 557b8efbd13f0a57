//! Configuration derivative of point and frame Jacobians, `Σ_k (∂J/∂q_k) u_k`, analytically
//! from the joint motion subspaces.

use nalgebra::{RealField, SMatrix, SVector, Vector3};

use super::error::DynamicsError;
use super::kernels::check_finite;
use crate::math::spatial::{angular, linear, linear_at_point, motion_cross, Motion};
use crate::model::{BodyId, Data, FrameId, Model};

/// Directional configuration derivative `J'(u) = Σ_k (∂J/∂q_k) u_k` of the Jacobian of a point
/// rigidly attached to `body` (the [`super::point_jacobian`] of `point`, world-aligned, linear
/// rows first, 6×N). With `u = e_k` it is the partial derivative `∂J/∂q_k`; with `u = q̇` it is
/// `J̇` (so `J'(q̇) q̇` equals [`super::point_drift`]).
///
/// Derivation (world coordinates at the world origin, angular first): a tree joint `i` moves
/// every descendant by the twist `S_i`, so `∂S_j/∂θ_i = S_i × S_j` if `i` is `j` or one of its
/// ancestors, and 0 otherwise; the point moves with its body, `∂p/∂θ_i = s_i,lin + s_i,ang × p`
/// for `i` on the path to `body`. With the tree rates `θ'_i = G_i u` of the drive map
/// (`q_tree = G q + offset`), define `W_j = Σ_{i ∈ support(j)} S_i θ'_i`. Then
/// `S'_j = W_j × S_j`, `p' = w_b,lin + w_b,ang × p` with `W_b` of the body, and the tree column
/// `(s_j,lin + s_j,ang × p; s_j,ang)` of (2.6) has derivative
/// `(s'_j,lin + s'_j,ang × p + s_j,ang × p'; s'_j,ang)`. As `J = J_tree G` with constant `G`,
/// `J'(u) = J'_tree(G u) G`: every tree column is added to the coordinates that drive it.
///
/// Inputs: `point` in world coordinates (m), `direction` `u` (N entries, unit of `q`).
/// Precondition: [`super::forward_kinematics`] was called at the current `q`.
/// Writes only `derivative`. Cost O(depth): two passes over the support path.
/// Errors: [`DynamicsError::UnknownBody`], [`DynamicsError::NonFinite`] for a non-finite
/// `direction` (the output is left unchanged).
pub fn point_jacobian_derivative<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    body: BodyId,
    point: &Vector3<T>,
    direction: &SVector<T, N>,
    derivative: &mut SMatrix<T, 6, N>,
) -> Result<(), DynamicsError> {
    model.body(body).ok_or(DynamicsError::UnknownBody)?;
    check_finite(direction, "direction")?;
    // W_b: spatial "velocity" of the body for joint rates u.
    let mut total = Motion::<T>::zeros();
    for id in model.support(body) {
        if let (Some(joint), Some(s)) = (model.body(id), data.motion_subspaces.get(id.0)) {
            total += s * joint.drive.evaluate(direction, false);
        }
    }
    let point_rate = linear_at_point(&total, point);
    *derivative = SMatrix::zeros();
    // Walking from the body to the root, `below` holds the joints between `body` and `j`, so
    // `total − below` is W_j (it includes S_j itself, which drops out of S_j × S_j = 0).
    let mut below = Motion::<T>::zeros();
    for id in model.support(body) {
        let (Some(joint), Some(s)) = (model.body(id), data.motion_subspaces.get(id.0)) else {
            continue;
        };
        let ds = motion_cross(&(total - below), s);
        below += s * joint.drive.evaluate(direction, false);
        let (ds_ang, s_ang) = (angular(&ds), angular(s));
        let lin = linear(&ds) + ds_ang.cross(point) + s_ang.cross(&point_rate);
        let column = [lin.x, lin.y, lin.z, ds_ang.x, ds_ang.y, ds_ang.z];
        for term in joint.drive.terms() {
            // Column-major storage: column `k` is entries `6k..6k + 6` (O(1), no panic path).
            let start = term.coordinate.saturating_mul(6);
            if let Some(c) = derivative.as_mut_slice().get_mut(start..start.saturating_add(6)) {
                for (x, v) in c.iter_mut().zip(column.iter()) {
                    *x += *v * term.coefficient;
                }
            }
        }
    }
    Ok(())
}

/// Directional configuration derivative `Σ_k (∂J/∂q_k) u_k` of the [`super::frame_jacobian`]
/// of `frame` (its origin moves with its body); see [`point_jacobian_derivative`]. Zero for a
/// world-fixed frame.
///
/// The plain reference of the manipulability gradient (3.55)–(3.57),
/// `∂m/∂q_k = m tr((J Jᵀ)⁻¹ (∂J/∂q_k) Jᵀ)` with `u = e_k` (the task itself evaluates all `k` in
/// one walk, see [`crate::tasks::manipulability::manipulability`]).
///
/// ```
/// # use kernel::model::{Data, Inertia, JointDrive, JointKind, ModelBuilder, Placement};
/// # use kernel::dynamics::{forward_kinematics, frame_jacobian_derivative};
/// # use nalgebra::{SMatrix, SVector, Unit, Vector3};
/// // A 1 m pendulum about y: J_x = −cos q, so ∂J_x/∂q = sin q.
/// let mut b = ModelBuilder::<f64, 1, 1, 1>::new(Vector3::new(0.0, 0.0, -9.81));
/// let link = b.add_body(None, Placement::identity(),
///     JointKind::Revolute { axis: Unit::new_normalize(Vector3::y()) }, JointDrive::actuated(0),
///     Inertia::point_mass(1.0, Vector3::new(0.0, 0.0, -1.0))).unwrap();
/// let tip = b.add_frame(Some(link), Placement::translation(0.0, 0.0, -1.0)).unwrap();
/// let model = b.try_build().unwrap();
/// let mut data = Data::new(&model);
/// let q = SVector::<f64, 1>::new(0.3);
/// forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
/// let mut dj = SMatrix::<f64, 6, 1>::zeros();
/// frame_jacobian_derivative(&model, &data, tip, &SVector::repeat(1.0), &mut dj).unwrap();
/// assert!((dj[0] - 0.3_f64.sin()).abs() < 1e-15);
/// ```
pub fn frame_jacobian_derivative<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    frame: FrameId,
    direction: &SVector<T, N>,
    derivative: &mut SMatrix<T, 6, N>,
) -> Result<(), DynamicsError> {
    let f = model.frame(frame).ok_or(DynamicsError::UnknownFrame)?;
    let origin = data.frame_placements.get(frame.0).ok_or(DynamicsError::UnknownFrame)?.translation.vector;
    match f.parent {
        Some(body) => point_jacobian_derivative(model, data, body, &origin, direction, derivative),
        None => {
            check_finite(direction, "direction")?;
            *derivative = SMatrix::zeros();
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::dynamics::{forward_kinematics, frame_drift, frame_jacobian};
    use crate::test_models::{branched, state, N, TCP, WRIST};
    use proptest::prelude::*;

    fn jacobian_at(
        model: &crate::test_models::Branched<f64>,
        frame: FrameId,
        q: &SVector<f64, N>,
    ) -> SMatrix<f64, 6, N> {
        let mut data = Data::new(model);
        forward_kinematics(model, &mut data, q, &SVector::zeros()).unwrap();
        let mut j = SMatrix::zeros();
        frame_jacobian(model, &data, frame, &mut j).unwrap();
        j
    }

    proptest! {
        /// Every partial derivative ∂J/∂q_k (both branches, the coupled joint included) equals
        /// the central difference (J(q + h e_k) − J(q − h e_k)) / 2h.
        #[test]
        fn partial_derivatives_match_finite_differences(seed in any::<u64>()) {
            let model = branched::<f64>();
            let mut data = Data::new(&model);
            let q = state(seed, 2.0);
            forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
            let h = 1e-5;
            for frame in [TCP, WRIST] {
                for k in 0..N {
                    let e = SVector::<f64, N>::from_fn(|r, _| if r == k { 1.0 } else { 0.0 });
                    let mut dj = SMatrix::<f64, 6, N>::zeros();
                    frame_jacobian_derivative(&model, &data, frame, &e, &mut dj).unwrap();
                    let fd = (jacobian_at(&model, frame, &(q + e * h)) - jacobian_at(&model, frame, &(q - e * h))) / (2.0 * h);
                    prop_assert!((fd - dj).amax() < 1e-6, "frame {:?} k {}: {}", frame, k, (fd - dj).amax());
                }
            }
        }

        /// Along u = q̇ the derivative is J̇, so J'(q̇) q̇ equals the independent drift algorithm.
        #[test]
        fn derivative_along_velocity_gives_the_drift(seed in any::<u64>()) {
            let model = branched::<f64>();
            let mut data = Data::new(&model);
            let (q, v) = (state(seed, 2.0), state(seed ^ 11, 1.5));
            forward_kinematics(&model, &mut data, &q, &v).unwrap();
            for frame in [TCP, WRIST] {
                let mut dj = SMatrix::<f64, 6, N>::zeros();
                frame_jacobian_derivative(&model, &data, frame, &v, &mut dj).unwrap();
                let drift = frame_drift(&model, &data, frame).unwrap();
                prop_assert!((dj * v - drift).amax() < 1e-12 * (1.0 + drift.amax()));
            }
        }
    }

    #[test]
    fn f32_matches_f64() {
        let (m64, m32) = (branched::<f64>(), branched::<f32>());
        let (mut d64, mut d32) = (Data::new(&m64), Data::new(&m32));
        let (q, u) = (state(7, 2.0), state(8, 1.0));
        forward_kinematics(&m64, &mut d64, &q, &SVector::zeros()).unwrap();
        forward_kinematics(&m32, &mut d32, &q.cast(), &SVector::zeros()).unwrap();
        let (mut j64, mut j32) = (SMatrix::<f64, 6, N>::zeros(), SMatrix::<f32, 6, N>::zeros());
        frame_jacobian_derivative(&m64, &d64, TCP, &u, &mut j64).unwrap();
        frame_jacobian_derivative(&m32, &d32, TCP, &u.cast(), &mut j32).unwrap();
        assert!((j32.cast::<f64>() - j64).amax() < 1e-5, "{}", (j32.cast::<f64>() - j64).amax());
    }

    #[test]
    fn bad_input_is_an_error_and_leaves_output() {
        let model = branched::<f64>();
        let data = Data::new(&model);
        let mut dj = SMatrix::<f64, 6, N>::repeat(3.0);
        let mut u = SVector::<f64, N>::zeros();
        assert_eq!(frame_jacobian_derivative(&model, &data, FrameId(9), &u, &mut dj), Err(DynamicsError::UnknownFrame));
        u[1] = f64::NAN;
        assert_eq!(
            frame_jacobian_derivative(&model, &data, TCP, &u, &mut dj),
            Err(DynamicsError::NonFinite { input: "direction" })
        );
        assert!(dj.iter().all(|&x| x == 3.0));
    }
}
