//! Recursive Newton–Euler algorithm: inverse dynamics.

use nalgebra::{RealField, SVector, Vector3};

use super::{add_to_coordinates, check_finite, DynamicsError};
use crate::math::spatial::{force_cross, motion_cross, spatial};
use crate::model::{Data, Model};

/// Inverse dynamics `τ = M(q) q̈ + C(q, q̇) q̇ + g(q)` ((2.1) of the thesis) by the recursive
/// Newton–Euler algorithm in world coordinates.
///
/// Forward pass: `a_i = a_p + S_i q̈_i + (v_i × S_i) q̇_i` with the base accelerating at `−g` (gravity as
/// a fictitious acceleration); body force `f_i = I_i a_i + v_i ×* I_i v_i`. Backward pass:
/// `f_p += f_i`, `τ_tree,i = S_iᵀ f_i`, mapped to coordinates by the drive matrix.
///
/// Precondition: [`super::forward_kinematics`] at `(q, q̇)`. Writes `body_accelerations`,
/// `body_forces`, `tau` (returned). Cost O(B). Errors: [`DynamicsError::NonFinite`] for `q̈`.
pub fn rnea<'d, T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &'d mut Data<T, N, B, F>,
    qdd: &SVector<T, N>,
) -> Result<&'d SVector<T, N>, DynamicsError> {
    check_finite(qdd, "qdd")?;
    let base = spatial(&Vector3::zeros(), &(-model.gravity));
    for (i, body) in model.bodies().iter().enumerate() {
        let parent = body.parent.and_then(|p| data.body_accelerations.get(p.0)).copied().unwrap_or(base);
        let (Some(s), Some(v), Some(inertia)) =
            (data.motion_subspaces.get(i), data.body_velocities.get(i), data.body_inertias.get(i))
        else {
            continue;
        };
        let joint_rate = body.drive.evaluate(&data.v, false);
        let acceleration = parent + s * body.drive.evaluate(qdd, false) + motion_cross(v, s) * joint_rate;
        let force = inertia * acceleration + force_cross(v, &(inertia * v));
        if let (Some(a), Some(f)) = (data.body_accelerations.get_mut(i), data.body_forces.get_mut(i)) {
            *a = acceleration;
            *f = force;
        }
    }
    backward_project(model, data);
    Ok(&data.tau)
}

/// Backward pass shared by [`rnea`] and [`super::gravity`]: accumulates `body_forces` into
/// their parents and projects each onto its joint, writing `data.tau`.
pub(super) fn backward_project<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &mut Data<T, N, B, F>,
) {
    data.tau.fill(T::zero());
    for (i, body) in model.bodies().iter().enumerate().rev() {
        let (Some(f), Some(s)) = (data.body_forces.get(i).copied(), data.motion_subspaces.get(i)) else {
            continue;
        };
        add_to_coordinates(&mut data.tau, &body.drive, s.dot(&f));
        if let Some(parent) = body.parent.and_then(|p| data.body_forces.get_mut(p.0)) {
            *parent += f;
        }
    }
}
