//! Geometric Jacobians of body points and frames.

use nalgebra::{RealField, SMatrix, Vector3};

use super::error::DynamicsError;
use super::forward_kinematics::transform_point;
use crate::model::{BodyId, Data, FrameId, Model};

/// Jacobian of the point `point` (world coordinates, m) rigidly attached to body `body`:
/// `[ṗ; ω] = J q̇`, world-aligned, **linear rows first**, 6×N.
///
/// Column `k` sums, over the joints `j` on the path from the root to `body`, the coupling
/// coefficient `G_jk` times `(s_j,lin + s_j,ang × p; s_j,ang)` where `S_j` is the joint's world
/// motion subspace. This is the standard `J_i` of (2.6)/(3.18) mapped through the drive matrix.
///
/// Precondition: [`super::forward_kinematics`] was called for the current state.
/// Writes only `jacobian`. Cost O(depth). Errors: [`DynamicsError::UnknownBody`].
pub fn point_jacobian<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    body: BodyId,
    point: &Vector3<T>,
    jacobian: &mut SMatrix<T, 6, N>,
) -> Result<(), DynamicsError> {
    let bodies = model.bodies();
    let mut next = Some(body);
    bodies.get(body.0).ok_or(DynamicsError::UnknownBody)?;
    let out = jacobian.as_mut_slice();
    out.fill(T::zero());
    let [p0, p1, p2] = [point.x, point.y, point.z];
    while let Some(id) = next {
        let (Some(joint), Some(s)) = (bodies.get(id.0), data.motion_subspaces.get(id.0)) else {
            break;
        };
        // (s_lin + s_ang × p; s_ang): linear velocity of the point, then angular velocity.
        let [w0, w1, w2, v0, v1, v2] = s.data.0[0];
        let column = [v0 + w1 * p2 - w2 * p1, v1 + w2 * p0 - w0 * p2, v2 + w0 * p1 - w1 * p0, w0, w1, w2];
        for term in joint.drive.terms() {
            // Column-major storage: column `k` is entries `6k..6k + 6` (O(1), no panic path).
            let start = term.coordinate.saturating_mul(6);
            if let Some(c) = out.get_mut(start..start.saturating_add(6)) {
                for (x, v) in c.iter_mut().zip(column.iter()) {
                    *x += *v * term.coefficient;
                }
            }
        }
        next = joint.parent.filter(|p| p.0 < id.0);
    }
    Ok(())
}

/// Jacobian of the origin of frame `frame`, world-aligned, linear rows first, 6×N
/// (Pinocchio's `LOCAL_WORLD_ALIGNED` frame Jacobian). A world-fixed frame has `J = 0`.
///
/// Precondition: the placements and subspaces of the frame's support, from
/// [`super::forward_kinematics`], [`super::placement_kinematics`] or
/// [`super::support_kinematics`] on the frame's body (the frame origin is computed from the
/// body placement). Writes only `jacobian`. Cost O(depth).
///
/// ```
/// # use kernel::model::{Data, Inertia, JointDrive, JointKind, ModelBuilder, Placement};
/// # use kernel::dynamics::{forward_kinematics, frame_jacobian};
/// # use nalgebra::{SMatrix, SVector, Unit, Vector3};
/// // A 1 m pendulum about y hanging along −z: at q = 0 the tip moves along −x... (ω × r).
/// let mut b = ModelBuilder::<f64, 1, 1, 1>::new(Vector3::new(0.0, 0.0, -9.81));
/// let link = b.add_body(None, Placement::identity(),
///     JointKind::Revolute { axis: Unit::new_normalize(Vector3::y()) }, JointDrive::actuated(0),
///     Inertia::point_mass(1.0, Vector3::new(0.0, 0.0, -1.0))).unwrap();
/// let tip = b.add_frame(Some(link), Placement::translation(0.0, 0.0, -1.0)).unwrap();
/// let model = b.try_build().unwrap();
/// let mut data = Data::new(&model);
/// forward_kinematics(&model, &mut data, &SVector::zeros(), &SVector::zeros()).unwrap();
/// let mut j = SMatrix::<f64, 6, 1>::zeros();
/// frame_jacobian(&model, &data, tip, &mut j).unwrap();
/// // ẋ = (e_y × (0, 0, −1)) q̇ = −q̇, ω_y = q̇.
/// assert!((j[0] + 1.0).abs() < 1e-15 && (j[4] - 1.0).abs() < 1e-15);
/// ```
pub fn frame_jacobian<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    frame: FrameId,
    jacobian: &mut SMatrix<T, 6, N>,
) -> Result<(), DynamicsError> {
    let f = model.frame(frame).ok_or(DynamicsError::UnknownFrame)?;
    match f.parent {
        Some(body) => {
            // The frame origin `⁰X_body · p_frame` (what `forward_kinematics` stores in
            // `frame_placements`), from the body placement alone.
            let parent = data.body_placements.get(body.0).ok_or(DynamicsError::UnknownBody)?;
            let origin = transform_point(parent, &f.placement.translation.vector);
            point_jacobian(model, data, body, &origin, jacobian)
        }
        None => {
            jacobian.as_mut_slice().fill(T::zero());
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::dynamics::forward_kinematics;
    use crate::test_models::{branched, state, N, TCP, WRIST};
    use nalgebra::SVector;
    use proptest::prelude::*;

    proptest! {
        /// J q̇ equals the central-difference velocity of the frame: linear rows the origin's
        /// velocity, angular rows the world angular velocity (from R(q+hq̇) R(q−hq̇)ᵀ).
        #[test]
        fn jacobian_matches_finite_differences(seed in any::<u64>()) {
            let model = branched::<f64>();
            let mut data = Data::new(&model);
            let (q, v) = (state(seed, 2.0), state(seed ^ 3, 1.0));
            for frame in [TCP, WRIST] {
                forward_kinematics(&model, &mut data, &q, &v).unwrap();
                let mut j = SMatrix::<f64, 6, N>::zeros();
                frame_jacobian(&model, &data, frame, &mut j).unwrap();
                let twist = j * v;
                let h = 1e-6;
                let mut at = |q: SVector<f64, N>| {
                    forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
                    data.frame_placements[frame.0]
                };
                let (plus, minus) = (at(q + v * h), at(q - v * h));
                let lin = (plus.translation.vector - minus.translation.vector) / (2.0 * h);
                // vee of the skew part of R₊R₋ᵀ ≈ exp(2h[ω]×) (acos-based angles are
                // ill-conditioned at such small angles).
                let r = (plus.rotation * minus.rotation.inverse()).into_inner();
                let ang = nalgebra::Vector3::new(r[(2, 1)] - r[(1, 2)], r[(0, 2)] - r[(2, 0)], r[(1, 0)] - r[(0, 1)])
                    / (4.0 * h);
                prop_assert!((twist.fixed_rows::<3>(0) - lin).amax() < 1e-7);
                prop_assert!((twist.fixed_rows::<3>(3) - ang).amax() < 1e-7);
            }
        }
    }

    #[test]
    fn unknown_frame_is_an_error_and_leaves_output() {
        let model = branched::<f64>();
        let data = Data::new(&model);
        let mut j = SMatrix::<f64, 6, N>::repeat(7.0);
        assert_eq!(frame_jacobian(&model, &data, FrameId(99), &mut j), Err(DynamicsError::UnknownFrame));
        assert!(j.iter().all(|&x| x == 7.0));
    }
}
