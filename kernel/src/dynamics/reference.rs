// Plain reference implementations of the rigid-body algorithms (the kernel's original,
// matrix-based code: 6×6 spatial inertias, nalgebra products, `Model::support` walks), kept
// to test the fast implementations against. Test-only: included by the kernel's
// `dynamics::reference_tests` and by the `thesis-tests` crate (`include!`, with the path
// `kernel` naming the kernel crate), so it uses only public kernel items.

use kernel::math::spatial::{
    force_bar_matrix, force_cross, force_cross_matrix, motion_cross, motion_cross_matrix, spatial, Motion,
    Placement, SpatialMatrix,
};
use kernel::model::{BodyId, Data, JointDrive, JointKind, Model};
use nalgebra::{RealField, SMatrix, SVector, Vector3, Vector6};

/// `m += value · g_rowᵀ g_col` through the drive rows of two joints.
fn add_coupled<T: RealField + Copy, const N: usize>(
    m: &mut SMatrix<T, N, N>,
    row: &JointDrive<T>,
    col: &JointDrive<T>,
    value: T,
) {
    for r in row.terms() {
        for c in col.terms() {
            m[(r.coordinate, c.coordinate)] += r.coefficient * c.coefficient * value;
        }
    }
}

/// Forward kinematics: writes `body_placements`, `motion_subspaces`, `body_velocities`,
/// `body_drift_accelerations`, `body_inertias` (6×6) and `frame_placements` of `data`.
pub fn forward_kinematics<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &mut Data<T, N, B, F>,
    q: &SVector<T, N>,
    v: &SVector<T, N>,
) {
    data.q = *q;
    data.v = *v;
    for (i, body) in model.bodies().iter().enumerate() {
        let parent = body.parent.map(|p| p.0);
        let parent_placement = parent.map_or_else(Placement::identity, |p| data.body_placements[p]);
        let parent_velocity = parent.map_or_else(Motion::zeros, |p| data.body_velocities[p]);
        let parent_drift = parent.map_or_else(Motion::zeros, |p| data.body_drift_accelerations[p]);
        let joint_frame = parent_placement * body.joint_placement;
        let placement = joint_frame * body.joint.motion(body.drive.evaluate(q, true));
        let axis = joint_frame.rotation * body.joint.axis().into_inner();
        let subspace = match body.joint {
            JointKind::Revolute { .. } => spatial(&axis, &placement.translation.vector.cross(&axis)),
            JointKind::Prismatic { .. } => spatial(&Vector3::zeros(), &axis),
        };
        let rate = body.drive.evaluate(v, false);
        let velocity = parent_velocity + subspace * rate;
        data.body_placements[i] = placement;
        data.motion_subspaces[i] = subspace;
        data.body_velocities[i] = velocity;
        data.body_drift_accelerations[i] = parent_drift + motion_cross(&velocity, &subspace) * rate;
        data.body_inertias[i] = body.inertia.spatial_matrix(&placement);
    }
    for (frame, slot) in model.frames().iter().zip(data.frame_placements.iter_mut()) {
        let parent = frame.parent.map_or_else(Placement::identity, |p| data.body_placements[p.0]);
        *slot = parent * frame.placement;
    }
}

/// Subtree sums of 6×6 per-body operators (with the body inertias: the composite inertias).
pub fn composites<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    per_body: &[SpatialMatrix<T>; B],
) -> [SpatialMatrix<T>; B] {
    let mut out = *per_body;
    for (i, body) in model.bodies().iter().enumerate().rev() {
        if let Some(p) = body.parent {
            let own = out[i];
            out[p.0] += own;
        }
    }
    out
}

/// `M(q)` by the composite rigid-body algorithm on 6×6 inertias (after the reference
/// `forward_kinematics`).
pub fn crba<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
) -> SMatrix<T, N, N> {
    let composite = composites(model, &data.body_inertias);
    let mut m = SMatrix::zeros();
    for (i, body) in model.bodies().iter().enumerate() {
        let force = composite[i] * data.motion_subspaces[i];
        for j in model.support(BodyId(i)) {
            let value = data.motion_subspaces[j.0].dot(&force);
            add_coupled(&mut m, &model.bodies()[j.0].drive, &body.drive, value);
            if j.0 != i {
                add_coupled(&mut m, &body.drive, &model.bodies()[j.0].drive, value);
            }
        }
    }
    m
}

/// `C(q, q̇)` and the composite operators `B^c` from 6×6 matrix products (after the reference
/// `forward_kinematics`).
pub fn coriolis<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
) -> (SMatrix<T, N, N>, [SpatialMatrix<T>; B]) {
    let half = nalgebra::convert::<f64, T>(0.5);
    let mut per_body = [SpatialMatrix::zeros(); B];
    for ((b, inertia), v) in per_body.iter_mut().zip(data.body_inertias.iter()).zip(data.body_velocities.iter()) {
        let momentum = inertia * v;
        *b = (force_cross_matrix(v) * inertia + force_bar_matrix(&momentum) - inertia * motion_cross_matrix(v)) * half;
    }
    let bc_all = composites(model, &per_body);
    let ic_all = composites(model, &data.body_inertias);
    let mut c = SMatrix::zeros();
    for (j, body) in model.bodies().iter().enumerate() {
        let (ic, bc, s_j) = (ic_all[j], bc_all[j], data.motion_subspaces[j]);
        let s_dot_j = motion_cross(&data.body_velocities[j], &s_j);
        let column_force = ic * s_dot_j + bc * s_j;
        let row_inertia = ic * s_j;
        let row_coriolis = bc.transpose() * s_j;
        for a in model.support(BodyId(j)) {
            let (ancestor, s_a) = (&model.bodies()[a.0], data.motion_subspaces[a.0]);
            add_coupled(&mut c, &ancestor.drive, &body.drive, s_a.dot(&column_force));
            if a.0 != j {
                let s_dot_a = motion_cross(&data.body_velocities[a.0], &s_a);
                add_coupled(&mut c, &body.drive, &ancestor.drive, row_inertia.dot(&s_dot_a) + row_coriolis.dot(&s_a));
            }
        }
    }
    (c, bc_all)
}

/// Inverse dynamics `M q̈ + C q̇ + g` by RNEA on 6×6 inertias (after the reference
/// `forward_kinematics`).
pub fn rnea<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    qdd: &SVector<T, N>,
) -> SVector<T, N> {
    let base = spatial(&Vector3::zeros(), &(-model.gravity));
    let mut acc = [Vector6::zeros(); B];
    let mut forces = [Vector6::zeros(); B];
    for (i, body) in model.bodies().iter().enumerate() {
        let parent = body.parent.map_or(base, |p| acc[p.0]);
        let (s, v, inertia) = (data.motion_subspaces[i], data.body_velocities[i], data.body_inertias[i]);
        acc[i] = parent
            + s * body.drive.evaluate(qdd, false)
            + motion_cross(&v, &s) * body.drive.evaluate(&data.v, false);
        forces[i] = inertia * acc[i] + force_cross(&v, &(inertia * v));
    }
    let mut tau = SVector::zeros();
    for (i, body) in model.bodies().iter().enumerate().rev() {
        let value = data.motion_subspaces[i].dot(&forces[i]);
        for t in body.drive.terms() {
            tau[t.coordinate] += t.coefficient * value;
        }
        if let Some(p) = body.parent {
            let f = forces[i];
            forces[p.0] += f;
        }
    }
    tau
}

/// Jacobian of `point` (world) on `body`, linear rows first (after the reference
/// `forward_kinematics`).
pub fn point_jacobian<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    body: BodyId,
    point: &Vector3<T>,
) -> SMatrix<T, 6, N> {
    let mut j = SMatrix::<T, 6, N>::zeros();
    for id in model.support(body) {
        let s = data.motion_subspaces[id.0];
        let w = Vector3::new(s[0], s[1], s[2]);
        let lin = Vector3::new(s[3], s[4], s[5]) + w.cross(point);
        let column = Vector6::new(lin.x, lin.y, lin.z, w.x, w.y, w.z);
        for t in model.bodies()[id.0].drive.terms() {
            for r in 0..6 {
                j[(r, t.coordinate)] += column[r] * t.coefficient;
            }
        }
    }
    j
}
