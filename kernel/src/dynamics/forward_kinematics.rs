//! Forward kinematics: placements, motion subspaces, velocities and velocity-product
//! accelerations of every body, and frame placements.

use nalgebra::{RealField, SVector, Vector3};

use super::{check_finite, DynamicsError};
use crate::math::spatial::{motion_cross, spatial, Motion, Placement};
use crate::model::{Data, JointKind, Model};

/// Forward kinematics at state `(q, q̇)`.
///
/// For each body `i` with parent `p` (world placements `⁰X`):
/// `⁰X_i = ⁰X_p · X_J(placement) · X(q_i)`, motion subspace `S_i = (a; p_i × a)` for a revolute
/// joint with world axis `a` through the body origin `p_i`, `S_i = (0; a)` for a prismatic one,
/// velocity `v_i = v_p + S_i q̇_i`, drift `ζ_i = ζ_p + (v_i × S_i) q̇_i`, world spatial
/// inertia `I_i`; then every frame placement. `q_i`, `q̇_i` are joint values through the drive
/// (coupling) map.
///
/// Writes `q, v, body_placements, motion_subspaces, body_velocities,
/// body_drift_accelerations, body_inertias, frame_placements`. Cost O(B + F).
/// Errors: [`DynamicsError::NonFinite`] if `q` or `q̇` has NaN/inf (nothing written).
pub fn forward_kinematics<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &mut Data<T, N, B, F>,
    q: &SVector<T, N>,
    v: &SVector<T, N>,
) -> Result<(), DynamicsError> {
    check_finite(q, "q")?;
    check_finite(v, "v")?;
    data.q = *q;
    data.v = *v;
    for (i, body) in model.bodies().iter().enumerate() {
        let parent = body.parent.map(|p| p.0);
        let parent_placement = parent_entry(&data.body_placements, parent).unwrap_or_else(Placement::identity);
        let parent_velocity = parent_entry(&data.body_velocities, parent).unwrap_or_else(Motion::zeros);
        let parent_drift = parent_entry(&data.body_drift_accelerations, parent).unwrap_or_else(Motion::zeros);

        let joint_frame = parent_placement * body.joint_placement;
        let placement = joint_frame * body.joint.motion(body.drive.evaluate(q, true));
        let axis = joint_frame.rotation * body.joint.axis().into_inner();
        let subspace = match body.joint {
            JointKind::Revolute { .. } => spatial(&axis, &placement.translation.vector.cross(&axis)),
            JointKind::Prismatic { .. } => spatial(&Vector3::zeros(), &axis),
        };
        let rate = body.drive.evaluate(v, false);
        let velocity = parent_velocity + subspace * rate;
        let drift = parent_drift + motion_cross(&velocity, &subspace) * rate;

        let slots = (
            data.body_placements.get_mut(i),
            data.motion_subspaces.get_mut(i),
            data.body_velocities.get_mut(i),
            data.body_drift_accelerations.get_mut(i),
            data.body_inertias.get_mut(i),
        );
        if let (Some(x), Some(s), Some(vel), Some(z), Some(inertia)) = slots {
            *x = placement;
            *s = subspace;
            *vel = velocity;
            *z = drift;
            *inertia = body.inertia.spatial_matrix(&placement);
        }
    }
    for (frame, slot) in model.frames().iter().zip(data.frame_placements.iter_mut()) {
        let parent = frame.parent.and_then(|p| data.body_placements.get(p.0)).copied();
        *slot = parent.unwrap_or_else(Placement::identity) * frame.placement;
    }
    Ok(())
}

/// The parent's entry of a per-body array; `None` for a root body.
fn parent_entry<X: Copy>(per_body: &[X], parent: Option<usize>) -> Option<X> {
    parent.and_then(|p| per_body.get(p).copied())
}
