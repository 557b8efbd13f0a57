//! Forward kinematics: placements, motion subspaces, velocities and velocity-product
//! accelerations of every body, and frame placements, by one pass whose level says what it
//! computes ([`KinematicsLevel`]: placements only for CRBA and gravity, velocities for the
//! controller, everything); and the placements of one support path, on the same step.

use nalgebra::{ArrayStorage, Matrix3, RealField, Rotation3, SVector, Translation3, Vector3, Vector6};

use super::error::DynamicsError;
use super::kernels::{add_scaled6, check_finite};
use crate::math::spatial::{Motion, Placement};
use crate::model::{Body, BodyId, Data, Inertia, JointKind, Model, WorldInertia};

/// What one kinematics pass ([`kinematics`]) computes, each level including the one before.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum KinematicsLevel<'a, T: RealField, const N: usize> {
    /// Placements `⁰X_i`, motion subspaces `S_i` and ten-parameter world inertias `I_i` of every
    /// body: what [`super::crba`], [`super::gravity`] and the body-point Jacobians read
    /// (Pinocchio's `crba(q)` computes the same before its backward pass). `q̇` is not read.
    Placements,
    /// And, at `q̇`, the body velocities `v_i`, subspace rates `Ṡ_i`, drifts `ζ_i` and the frame
    /// placements: everything the velocity-dependent algorithms and the controller read; no 6×6
    /// inertias.
    Velocities(&'a SVector<T, N>),
    /// And the 6×6 world inertias `body_inertias` ([`super::kinetic_energy`]).
    Full(&'a SVector<T, N>),
}

/// Forward kinematics at state `(q, q̇)`: [`kinematics`] at [`KinematicsLevel::Full`].
///
/// For each body `i` with parent `p` (world placements `⁰X`), the placement pass
/// `joint_step`: `⁰X_i = ⁰X_p · X_J(placement) · X(q_i)`, motion subspace `S_i = (a; p_i × a)`
/// for a revolute joint with world axis `a` through the body origin `p_i`, `S_i = (0; a)` for a
/// prismatic one; then velocity `v_i = v_p + S_i q̇_i`, subspace rate `Ṡ_i = v_i × S_i`, drift
/// `ζ_i = ζ_p + Ṡ_i q̇_i`, world spatial inertia `I_i` (Featherstone (2.63), as a 6×6 matrix and
/// in ten-parameter form); then every frame placement. `q_i`, `q̇_i` are joint values through
/// the drive (coupling) map.
///
/// Writes `q, v, body_placements, motion_subspaces, subspace_rates, body_velocities,
/// body_drift_accelerations, body_inertias, world_inertias, frame_placements`. Cost O(B + F).
/// Errors: [`DynamicsError::NonFinite`] if `q` or `q̇` has NaN/inf (nothing written).
pub fn forward_kinematics<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &mut Data<T, N, B, F>,
    q: &SVector<T, N>,
    v: &SVector<T, N>,
) -> Result<(), DynamicsError> {
    kinematics(model, data, q, KinematicsLevel::Full(v))
}

/// Position kinematics at `q` for the joint-space inertia matrix and gravity: [`kinematics`] at
/// [`KinematicsLevel::Placements`] (placements `⁰X_i`, motion subspaces `S_i` and world inertias
/// `I_i` in ten-parameter form, Featherstone (2.63); no velocities, drifts, 6×6 inertias or
/// frame placements).
///
/// Writes `q, body_placements, motion_subspaces, world_inertias`: enough for
/// [`super::crba`], [`super::gravity`] and the body-point Jacobians
/// ([`super::point_jacobian`], [`super::frame_jacobian`]). Cost O(B).
/// Errors: [`DynamicsError::NonFinite`] if `q` has NaN/inf (nothing written).
pub fn placement_kinematics<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &mut Data<T, N, B, F>,
    q: &SVector<T, N>,
) -> Result<(), DynamicsError> {
    kinematics(model, data, q, KinematicsLevel::Placements)
}

/// The kinematics pass at `q` (and the `q̇` of the level) up to `level`: per body, in tree
/// order, the placement step `joint_step` and the ten-parameter world inertia `I_i`
/// (Featherstone (2.63)); from [`KinematicsLevel::Velocities`] on also `v_i = v_p + S_i q̇_i`,
/// `Ṡ_i = v_i × S_i`, `ζ_i = ζ_p + Ṡ_i q̇_i` and, after the bodies, every frame placement; at
/// [`KinematicsLevel::Full`] also the 6×6 `I_i`.
///
/// Writes `q, body_placements, motion_subspaces, world_inertias`, from `Velocities` on also
/// `v, body_velocities, subspace_rates, body_drift_accelerations, frame_placements`, at `Full`
/// also `body_inertias`. Cost O(B) (+ O(F) from `Velocities` on). Errors:
/// [`DynamicsError::NonFinite`] if `q` or the level's `q̇` has NaN/inf (nothing written).
#[inline(always)]
pub fn kinematics<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &mut Data<T, N, B, F>,
    q: &SVector<T, N>,
    level: KinematicsLevel<'_, T, N>,
) -> Result<(), DynamicsError> {
    check_finite(q, "q")?;
    let (velocity, full) = match level {
        KinematicsLevel::Placements => (None, false),
        KinematicsLevel::Velocities(v) => (Some(v), false),
        KinematicsLevel::Full(v) => (Some(v), true),
    };
    if let Some(v) = velocity {
        check_finite(v, "v")?;
        data.v = *v;
    }
    data.q = *q;
    for (i, body) in model.bodies().iter().enumerate() {
        let parent = body.parent.map(|p| p.0);
        let (r, t, subspace) = joint_step(body, parent.and_then(|p| data.body_placements.get(p)), q);
        let world_inertia = world_inertia(&body.inertia, &r, &t);
        let placement = from_columns(r, t);
        if let Some(v) = velocity {
            let (parent_velocity, parent_drift) = match (
                parent.and_then(|p| data.body_velocities.get(p)),
                parent.and_then(|p| data.body_drift_accelerations.get(p)),
            ) {
                (Some(v), Some(z)) => (*v, *z),
                _ => (Motion::zeros(), Motion::zeros()),
            };
            let rate = body.drive.evaluate(v, false);
            let velocity = add_scaled6(&parent_velocity, &subspace, rate);
            let subspace_rate = cross_motion(&velocity, &subspace);
            let drift = add_scaled6(&parent_drift, &subspace_rate, rate);
            let slots = (
                data.subspace_rates.get_mut(i),
                data.body_velocities.get_mut(i),
                data.body_drift_accelerations.get_mut(i),
            );
            if let (Some(sd), Some(vel), Some(z)) = slots {
                *sd = subspace_rate;
                *vel = velocity;
                *z = drift;
            }
        }
        if full {
            if let Some(inertia) = data.body_inertias.get_mut(i) {
                *inertia = world_inertia.matrix();
            }
        }
        let slots = (data.body_placements.get_mut(i), data.motion_subspaces.get_mut(i), data.world_inertias.get_mut(i));
        if let (Some(x), Some(s), Some(wi)) = slots {
            *x = placement;
            *s = subspace;
            *wi = world_inertia;
        }
    }
    if velocity.is_some() {
        for (frame, slot) in model.frames().iter().zip(data.frame_placements.iter_mut()) {
            *slot = match frame.parent.and_then(|p| data.body_placements.get(p.0)) {
                Some(parent) => compose(parent, &frame.placement),
                None => frame.placement,
            };
        }
    }
    Ok(())
}

/// Position kinematics at `q` along one support path: the placement pass of
/// [`forward_kinematics`] (`joint_step`) for `body` and its ancestors only, root first
/// (Pinocchio's `computeFrameJacobian(q)` walks the same joints).
///
/// Writes `q` and the `body_placements` and `motion_subspaces` of the support of `body`:
/// enough for [`super::point_jacobian`] on `body` and [`super::frame_jacobian`] of a frame
/// attached to it. Cost O(depth). Errors: [`DynamicsError::NonFinite`] if `q` has NaN/inf,
/// [`DynamicsError::UnknownBody`] (nothing written in either case).
pub fn support_kinematics<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &mut Data<T, N, B, F>,
    q: &SVector<T, N>,
    body: BodyId,
) -> Result<(), DynamicsError> {
    check_finite(q, "q")?;
    let bodies = model.bodies();
    bodies.get(body.0).ok_or(DynamicsError::UnknownBody)?;
    // The support, leaf first (parents have smaller indices, so at most B entries).
    let mut path = [0usize; B];
    let mut len = 0;
    let mut next = Some(body);
    while let (Some(id), Some(slot)) = (next, path.get_mut(len)) {
        let Some(b) = bodies.get(id.0) else { break };
        *slot = id.0;
        len += 1;
        next = b.parent.filter(|p| p.0 < id.0);
    }
    data.q = *q;
    for &i in path.get(..len).unwrap_or(&[]).iter().rev() {
        let Some(b) = bodies.get(i) else { continue };
        let parent = b.parent.and_then(|p| data.body_placements.get(p.0));
        let (r, t, subspace) = joint_step(b, parent, q);
        if let (Some(x), Some(s)) = (data.body_placements.get_mut(i), data.motion_subspaces.get_mut(i)) {
            *x = from_columns(r, t);
            *s = subspace;
        }
    }
    Ok(())
}

/// The placement step of one body (every kinematics pass shares it): from the parent's world
/// placement (`None`: the world), `⁰X_i = ⁰X_p · X_J(placement) · X(q_i)` with the joint value
/// `q_i` through the drive map, as rotation columns and translation, and the world motion
/// subspace `S_i = (a; p_i × a)` (revolute, world axis `a` through the body origin `p_i`) or
/// `(0; a)` (prismatic). About a coordinate axis the world axis is a column of the joint frame's
/// rotation (no product). The placement products are written out on 3×3 arrays (no generic
/// matrix iteration).
#[inline(always)]
fn joint_step<T: RealField + Copy, const N: usize>(
    body: &Body<T>,
    parent: Option<&Placement<T>>,
    q: &SVector<T, N>,
) -> (Columns<T>, [T; 3], Motion<T>) {
    let joint_frame = match parent {
        Some(parent_placement) => compose(parent_placement, &body.joint_placement),
        None => body.joint_placement,
    };
    let r = columns(&joint_frame);
    let [t0, t1, t2] = joint_frame.translation.vector.data.0[0];
    // One drive term (every joint but a coupled one): `offset + g q_c` without the term loop.
    let value = match body.drive.terms() {
        [t] => body.drive.offset() + t.coefficient * q.get(t.coordinate).copied().unwrap_or_else(T::zero),
        _ => body.drive.evaluate(q, true),
    };
    let a = body.joint.axis().into_inner();
    match body.joint {
        JointKind::Revolute { .. } => {
            let (rotated, [a0, a1, a2]) = rotate(&r, &[a.x, a.y, a.z], value);
            let lin = [t1 * a2 - t2 * a1, t2 * a0 - t0 * a2, t0 * a1 - t1 * a0];
            (rotated, [t0, t1, t2], Vector6::new(a0, a1, a2, lin[0], lin[1], lin[2]))
        }
        JointKind::Prismatic { .. } => {
            let [a0, a1, a2] = mul3(&r, &[a.x, a.y, a.z]);
            let z = T::zero();
            (r, [t0 + a0 * value, t1 + a1 * value, t2 + a2 * value], Vector6::new(z, z, z, a0, a1, a2))
        }
    }
}

/// Ten-parameter world inertia (Featherstone (2.63)) of a body with inertia `inertia` (body
/// frame) whose frame has world rotation columns `r` and origin `t`: `c = R c_b + t`,
/// `h = m c`, `Ī = R I_c Rᵀ + m (|c|² 1 − c cᵀ)`, with `R I_c Rᵀ = Σ_l (R I_c)_l r_lᵀ` over the
/// columns (a diagonal `I_c`, principal body axes, scales the columns: `(R I_c)_l = I_ll r_l`)
/// and the parallel-axis term from `h` (`m (c_y² + c_z²) = h_y c_y + h_z c_z`, …). The same
/// inertia as [`WorldInertia::from_body`]; the lower triangle of `I_c` is read.
#[inline(always)]
fn world_inertia<T: RealField + Copy>(inertia: &Inertia<T>, r: &Columns<T>, t: &[T; 3]) -> WorldInertia<T> {
    let z = T::zero();
    let [r0, r1, r2] = r;
    let [[i00, i10, i20], [_, i11, i21], [_, _, i22]] = inertia.rotational.data.0;
    let scale = |x: &[T; 3], k: T| [x[0] * k, x[1] * k, x[2] * k];
    let p = if i10 == z && i20 == z && i21 == z {
        [scale(r0, i00), scale(r1, i11), scale(r2, i22)]
    } else {
        [mul3(r, &[i00, i10, i20]), mul3(r, &[i10, i11, i21]), mul3(r, &[i20, i21, i22])]
    };
    // (R I_c Rᵀ)_ij = Σ_l (R I_c)_il R_jl.
    let [[a0, a1, a2], [b0, b1, b2], [d0, d1, d2]] = p;
    let ([x0, x1, x2], [y0, y1, y2], [w0, w1, w2]) = (*r0, *r1, *r2);
    let [cb0, cb1, cb2] = inertia.com.data.0[0];
    let [u0, u1, u2] = mul3(r, &[cb0, cb1, cb2]);
    let (c0, c1, c2) = (u0 + t[0], u1 + t[1], u2 + t[2]);
    let m = inertia.mass;
    let (h0, h1, h2) = (m * c0, m * c1, m * c2);
    WorldInertia {
        mass: m,
        first_moment: [h0, h1, h2],
        rotational: [
            (a0 * x0 + b0 * y0 + d0 * w0) + (h1 * c1 + h2 * c2),
            (a1 * x1 + b1 * y1 + d1 * w1) + (h0 * c0 + h2 * c2),
            (a2 * x2 + b2 * y2 + d2 * w2) + (h0 * c0 + h1 * c1),
            (a0 * x1 + b0 * y1 + d0 * w1) - h0 * c1,
            (a0 * x2 + b0 * y2 + d0 * w2) - h0 * c2,
            (a1 * x2 + b1 * y2 + d1 * w2) - h1 * c2,
        ],
    }
}

/// `X p` for a placement `X = (R, t)` and a point `p`: `R p + t` (the translation of
/// `X · (1, p)`, the same operations as [`compose`]).
#[inline]
pub(super) fn transform_point<T: RealField + Copy>(x: &Placement<T>, p: &Vector3<T>) -> Vector3<T> {
    let ta = x.translation.vector;
    let [a, b, c] = mul3(&columns(x), &[p.x, p.y, p.z]);
    Vector3::new(a + ta.x, b + ta.y, c + ta.z)
}

/// Columns of a 3×3 matrix (nalgebra's storage order).
type Columns<T> = [[T; 3]; 3];

/// The rotation of a placement as columns.
#[inline]
fn columns<T: RealField + Copy>(p: &Placement<T>) -> Columns<T> {
    p.rotation.matrix().data.0
}

/// A placement from rotation columns and a translation.
#[inline]
fn from_columns<T: RealField + Copy>(r: Columns<T>, t: [T; 3]) -> Placement<T> {
    let [t0, t1, t2] = t;
    Placement::from_parts(
        Translation3::new(t0, t1, t2),
        Rotation3::from_matrix_unchecked(Matrix3::from_data(ArrayStorage(r))),
    )
}

/// `R x` for `R` given by columns.
#[inline]
fn mul3<T: RealField + Copy>(r: &Columns<T>, x: &[T; 3]) -> [T; 3] {
    let [c0, c1, c2] = r;
    let [x0, x1, x2] = *x;
    [c0[0] * x0 + c1[0] * x1 + c2[0] * x2, c0[1] * x0 + c1[1] * x1 + c2[1] * x2, c0[2] * x0 + c1[2] * x1 + c2[2] * x2]
}

/// `A B` for matrices given by columns.
#[inline]
fn mul33<T: RealField + Copy>(a: &Columns<T>, b: &Columns<T>) -> Columns<T> {
    let [b0, b1, b2] = b;
    [mul3(a, b0), mul3(a, b1), mul3(a, b2)]
}

/// `a · b` for placements: `(R_a R_b, R_a t_b + t_a)`.
#[inline]
fn compose<T: RealField + Copy>(a: &Placement<T>, b: &Placement<T>) -> Placement<T> {
    let t = transform_point(a, &b.translation.vector);
    from_columns(mul33(&columns(a), &columns(b)), [t.x, t.y, t.z])
}

/// `R · Rot(a, angle)` for `R` given by columns and the unit axis `a`, and the rotated axis
/// `R a` (the same in both frames). About a coordinate axis the product touches two columns of
/// `R` (e.g. about `z`: `(c r₀ + s r₁, c r₁ − s r₀, r₂)`) and `R a` is the third column; about
/// any other axis it is the product with [`axis_angle`].
#[inline(always)]
fn rotate<T: RealField + Copy>(r: &Columns<T>, a: &[T; 3], angle: T) -> (Columns<T>, [T; 3]) {
    let (z, o) = (T::zero(), T::one());
    let [r0, r1, r2] = *r;
    let turn = |x: &[T; 3], y: &[T; 3], s: T, c: T| -> ([T; 3], [T; 3]) {
        // (c x + s y, c y − s x): the plane of `x`, `y` turned by the angle.
        (
            [c * x[0] + s * y[0], c * x[1] + s * y[1], c * x[2] + s * y[2]],
            [c * y[0] - s * x[0], c * y[1] - s * x[1], c * y[2] - s * x[2]],
        )
    };
    match *a {
        [x, y, w] if x == z && y == z && w == o => {
            let (s, c) = angle.sin_cos();
            let (n0, n1) = turn(&r0, &r1, s, c);
            ([n0, n1, r2], r2)
        }
        [x, y, w] if x == o && y == z && w == z => {
            let (s, c) = angle.sin_cos();
            let (n1, n2) = turn(&r1, &r2, s, c);
            ([r0, n1, n2], r0)
        }
        [x, y, w] if x == z && y == o && w == z => {
            let (s, c) = angle.sin_cos();
            let (n2, n0) = turn(&r2, &r0, s, c);
            ([n0, r1, n2], r1)
        }
        _ => (mul33(r, &axis_angle(a, angle)), mul3(r, a)),
    }
}

/// Rotation by `angle` about the unit axis `a` (Rodrigues): `cos θ 1 + sin θ [a]× + (1 − cos θ) a aᵀ`,
/// as columns.
#[inline]
fn axis_angle<T: RealField + Copy>(a: &[T; 3], angle: T) -> Columns<T> {
    let (s, c) = angle.sin_cos();
    let k = T::one() - c;
    let [x, y, z] = *a;
    let (kx, ky, kz) = (k * x, k * y, k * z);
    let (sx, sy, sz) = (s * x, s * y, s * z);
    [
        [kx * x + c, kx * y + sz, kx * z - sy],
        [kx * y - sz, ky * y + c, ky * z + sx],
        [kx * z + sy, ky * z - sx, kz * z + c],
    ]
}

/// Motion cross product `m × u = (ω×ω_u; ω×v_u + v×ω_u)` written out on the six entries.
#[inline]
pub(super) fn cross_motion<T: RealField + Copy>(m: &Motion<T>, u: &Motion<T>) -> Motion<T> {
    let [w0, w1, w2, v0, v1, v2] = m.data.0[0];
    let [a0, a1, a2, b0, b1, b2] = u.data.0[0];
    Vector6::new(
        w1 * a2 - w2 * a1,
        w2 * a0 - w0 * a2,
        w0 * a1 - w1 * a0,
        w1 * b2 - w2 * b1 + v1 * a2 - v2 * a1,
        w2 * b0 - w0 * b2 + v2 * a0 - v0 * a2,
        w0 * b1 - w1 * b0 + v0 * a1 - v1 * a0,
    )
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::test_models::{branched, state};
    use nalgebra::{UnitQuaternion, Vector3};

    /// The ten parameters as an array (mass, first moment, rotational), cast to f64.
    fn params<T: RealField + Copy>(w: &WorldInertia<T>) -> [f64; 10] {
        let f = |x: T| nalgebra::try_convert::<T, f64>(x).unwrap();
        let [h0, h1, h2] = w.first_moment;
        let [a, b, c, d, e, g] = w.rotational;
        [f(w.mass), f(h0), f(h1), f(h2), f(a), f(b), f(c), f(d), f(e), f(g)]
    }

    /// `world_inertia` (column form, diagonal fast path) against the reference
    /// `WorldInertia::from_body` for the inertias of the branched test model (full and diagonal
    /// `I_c`) and of Justin-like principal-axis bodies, at random placements far from and near the
    /// origin: f64 to rounding, f32 within single-precision rounding of the f64 reference.
    fn check<T: RealField + Copy>(tol: f64) {
        let model = branched::<f64>();
        let mut inertias: std::vec::Vec<Inertia<f64>> = model.bodies().iter().map(|b| b.inertia).collect();
        inertias.push(Inertia {
            mass: 3.0,
            com: Vector3::new(0.0, 0.0, 0.15),
            rotational: nalgebra::Matrix3::from_diagonal(&Vector3::new(0.0273, 0.0273, 0.0096)),
        });
        inertias.push(Inertia::point_mass(1.4, Vector3::new(0.02, -0.01, 0.3)));
        let diagonal = inertias
            .iter()
            .filter(|i| i.rotational == nalgebra::Matrix3::from_diagonal(&i.rotational.diagonal()))
            .count();
        assert!(diagonal >= 3 && diagonal < inertias.len(), "both paths are exercised");
        for seed in 0..200u64 {
            let s = state(seed, 3.0);
            let reach = if seed % 2 == 0 { 1.0 } else { 40.0 };
            let rotation = UnitQuaternion::from_euler_angles(s[0], s[1], s[2]).to_rotation_matrix();
            let x = Placement::from_parts(Translation3::new(s[3] * reach, s[4] * reach, s[5] * reach), rotation);
            let xt: Placement<T> = nalgebra::convert(x);
            for inertia in &inertias {
                let reference = params(&WorldInertia::from_body(inertia, &x));
                let it: Inertia<T> = Inertia {
                    mass: nalgebra::convert(inertia.mass),
                    com: inertia.com.map(nalgebra::convert),
                    rotational: inertia.rotational.map(nalgebra::convert),
                };
                let fast = params(&world_inertia(&it, &columns(&xt), &xt.translation.vector.data.0[0]));
                let scale = 1.0 + reference.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                for (a, b) in fast.iter().zip(reference.iter()) {
                    assert!((a - b).abs() <= tol * scale, "seed {seed}: {fast:?} vs {reference:?}");
                }
            }
        }
    }

    #[test]
    fn world_inertia_equals_from_body_f64() {
        check::<f64>(1e-14);
    }

    #[test]
    fn world_inertia_equals_from_body_f32() {
        check::<f32>(2e-6);
    }
}
