//! Recursive Newton–Euler algorithm: inverse dynamics.

use nalgebra::{RealField, SVector, Vector6};

use super::error::DynamicsError;
use super::kernels::{add6, add_scaled6, add_to_coordinates, check_finite, dot6};
use crate::model::{Data, Model};

/// Inverse dynamics `τ = M(q) q̈ + C(q, q̇) q̇ + g(q)` ((2.1) of the thesis) by the recursive
/// Newton–Euler algorithm in world coordinates.
///
/// Forward pass: `a_i = a_p + S_i q̈_i + Ṡ_i q̇_i` (with `Ṡ_i = v_i × S_i` from forward
/// kinematics) with the base accelerating at `−g` (gravity as a fictitious acceleration); body
/// force `f_i = I_i a_i + v_i ×* I_i v_i` (ten-parameter inertias). Backward pass:
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
    let base = gravity_acceleration(model);
    for (i, body) in model.bodies().iter().enumerate() {
        let parent = body.parent.and_then(|p| data.body_accelerations.get(p.0)).copied().unwrap_or(base);
        let (Some(s), Some(s_dot), Some(v), Some(inertia)) = (
            data.motion_subspaces.get(i),
            data.subspace_rates.get(i),
            data.body_velocities.get(i),
            data.world_inertias.get(i),
        ) else {
            continue;
        };
        let joint_rate = body.drive.evaluate(&data.v, false);
        let acceleration = add_scaled6(&add_scaled6(&parent, s, body.drive.evaluate(qdd, false)), s_dot, joint_rate);
        let force = add6(&inertia.apply(&acceleration), &force_cross(v, &inertia.apply(v)));
        if let (Some(a), Some(f)) = (data.body_accelerations.get_mut(i), data.body_forces.get_mut(i)) {
            *a = acceleration;
            *f = force;
        }
    }
    backward_project(model, data);
    Ok(&data.tau)
}

/// The fictitious base acceleration `(0; −g)` that stands for gravity.
#[inline]
pub(super) fn gravity_acceleration<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
) -> Vector6<T> {
    let g = model.gravity;
    let z = T::zero();
    Vector6::new(z, z, z, -g.x, -g.y, -g.z)
}

/// Force cross product `m ×* f = (ω×n + v×f; ω×f)`, written out on the six entries.
#[inline(always)]
pub(super) fn force_cross<T: RealField + Copy>(m: &Vector6<T>, f: &Vector6<T>) -> Vector6<T> {
    let [w0, w1, w2, v0, v1, v2] = m.data.0[0];
    let [n0, n1, n2, f0, f1, f2] = f.data.0[0];
    Vector6::new(
        w1 * n2 - w2 * n1 + v1 * f2 - v2 * f1,
        w2 * n0 - w0 * n2 + v2 * f0 - v0 * f2,
        w0 * n1 - w1 * n0 + v0 * f1 - v1 * f0,
        w1 * f2 - w2 * f1,
        w2 * f0 - w0 * f2,
        w0 * f1 - w1 * f0,
    )
}

/// Backward pass shared by [`rnea`] and [`super::gravity`]: accumulates `body_forces` into
/// their parents and projects each onto its joint, writing `data.tau`.
pub(super) fn backward_project<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &mut Data<T, N, B, F>,
) {
    data.tau.as_mut_slice().fill(T::zero());
    for (i, body) in model.bodies().iter().enumerate().rev() {
        let (Some(f), Some(s)) = (data.body_forces.get(i).copied(), data.motion_subspaces.get(i)) else {
            continue;
        };
        add_to_coordinates(&mut data.tau, &body.drive, dot6(s, &f));
        if let Some(parent) = body.parent.and_then(|p| data.body_forces.get_mut(p.0)) {
            *parent = add6(parent, &f);
        }
    }
}
