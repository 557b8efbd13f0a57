//! Models used by the kernel's unit tests (test builds only).
//!
//! `branched` exercises everything the algorithms must handle: a prismatic root (like the
//! mobile base), revolute joints about skewed axes with offset placements, a branch point,
//! a coupled joint driven by two coordinates (like Justin's q_t4, (3.41)) and bodies with full
//! rotational inertia and off-axis centres of mass.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, reason = "test support")]

use nalgebra::{Matrix3, RealField, SVector, Translation3, Unit, UnitQuaternion, Vector3};

use crate::math::spatial::Placement;
use crate::model::{FrameId, Inertia, JointDrive, JointKind, Model, ModelBuilder};

/// Coordinates, bodies and frames of [`branched`].
pub const N: usize = 6;
/// Bodies of [`branched`].
pub const B: usize = 7;
/// Frames of [`branched`].
pub const F: usize = 2;
/// The test model type.
pub type Branched<T> = Model<T, N, B, F>;

fn c<T: RealField + Copy>(x: f64) -> T {
    nalgebra::convert(x)
}

fn placement<T: RealField + Copy>(xyz: [f64; 3], rpy: [f64; 3]) -> Placement<T> {
    let r = UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]).to_rotation_matrix();
    let p = Placement::<f64>::from_parts(Translation3::new(xyz[0], xyz[1], xyz[2]), r);
    nalgebra::convert(p)
}

fn inertia<T: RealField + Copy>(mass: f64, com: [f64; 3], diag: [f64; 3], off: f64) -> Inertia<T> {
    let rot = Matrix3::new(diag[0], off, 0.0, off, diag[1], -off, 0.0, -off, diag[2]);
    Inertia { mass: c(mass), com: Vector3::new(c(com[0]), c(com[1]), c(com[2])), rotational: rot.map(c) }
}

fn revolute<T: RealField + Copy>(axis: [f64; 3]) -> JointKind<T> {
    JointKind::Revolute { axis: Unit::new_normalize(Vector3::new(c(axis[0]), c(axis[1]), c(axis[2]))) }
}

/// The branched test tree; frame 0 is a TCP on the coupled branch, frame 1 on the other branch.
pub fn branched<T: RealField + Copy>() -> Branched<T> {
    let mut b = ModelBuilder::<T, N, B, F>::new(Vector3::new(T::zero(), T::zero(), c(-9.81)));
    let x = Unit::new_normalize(Vector3::new(c(1.0), c(0.2), c(0.0)));
    let base = b
        .add_body(
            None,
            placement([0.1, 0.0, 0.2], [0.0, 0.0, 0.3]),
            JointKind::Prismatic { axis: x },
            JointDrive::actuated(0),
            inertia(5.0, [0.1, 0.0, 0.05], [0.4, 0.5, 0.6], 0.01),
        )
        .unwrap();
    let yaw = b
        .add_body(
            Some(base),
            placement([0.0, 0.1, 0.3], [0.1, 0.0, 0.0]),
            revolute([0.0, 0.1, 1.0]),
            JointDrive::actuated(1),
            inertia(3.0, [0.0, 0.05, 0.1], [0.1, 0.12, 0.08], 0.005),
        )
        .unwrap();
    let pitch = b
        .add_body(
            Some(yaw),
            placement([0.0, 0.0, 0.25], [0.0, 0.2, 0.0]),
            revolute([0.0, 1.0, 0.0]),
            JointDrive::actuated(2),
            inertia(2.0, [0.15, 0.0, 0.0], [0.02, 0.05, 0.05], 0.002),
        )
        .unwrap();
    // Coupled joint: q_tree = −(q2 + q3) + 0.1, like (3.41) with an offset.
    let elbow = b
        .add_body(
            Some(pitch),
            placement([0.3, 0.0, 0.0], [0.0, 0.0, 0.1]),
            revolute([0.0, 1.0, 0.2]),
            JointDrive::actuated(3),
            inertia(1.5, [0.12, 0.01, 0.0], [0.01, 0.03, 0.03], 0.001),
        )
        .unwrap();
    let passive = b
        .add_body(
            Some(elbow),
            placement([0.28, 0.0, 0.0], [0.0, 0.0, 0.0]),
            revolute([0.0, 1.0, 0.0]),
            JointDrive::coupled(&[(2, c(-1.0)), (3, c(-1.0))], c(0.1)).unwrap(),
            inertia(0.8, [0.05, 0.0, 0.02], [0.004, 0.006, 0.005], 0.0),
        )
        .unwrap();
    let prism = b
        .add_body(
            Some(yaw),
            placement([0.0, 0.2, 0.1], [0.3, 0.0, 0.0]),
            JointKind::Prismatic { axis: Unit::new_normalize(Vector3::new(c(0.0), c(0.3), c(1.0))) },
            JointDrive::actuated(4),
            inertia(1.0, [0.0, 0.0, 0.1], [0.01, 0.01, 0.002], 0.0),
        )
        .unwrap();
    let wrist = b
        .add_body(
            Some(prism),
            placement([0.0, 0.0, 0.2], [0.0, 0.0, 0.5]),
            revolute([1.0, 0.0, 0.3]),
            JointDrive::actuated(5),
            inertia(0.6, [0.03, 0.02, 0.05], [0.003, 0.002, 0.004], 0.0005),
        )
        .unwrap();
    b.add_frame(Some(passive), placement([0.1, 0.02, -0.03], [0.2, 0.1, 0.0])).unwrap();
    b.add_frame(Some(wrist), placement([0.0, 0.05, 0.12], [0.0, 0.0, 0.0])).unwrap();
    b.try_build().unwrap()
}

/// Frame on the coupled branch of [`branched`].
pub const TCP: FrameId = FrameId(0);
/// Frame on the prismatic branch of [`branched`].
pub const WRIST: FrameId = FrameId(1);

/// A deterministic pseudo-random state (xorshift), entries in `[-scale, scale]`.
pub fn state(seed: u64, scale: f64) -> SVector<f64, N> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    SVector::from_fn(|_, _| {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        ((s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * scale
    })
}
