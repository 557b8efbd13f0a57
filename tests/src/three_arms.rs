//! More than two arms: a synthetic fixed-base robot with three 3-DOF arms on a common torso
//! (a yaw joint), built with the kernel's model builder, under the same `Controller` as Justin
//! and the Panda with `A = 3`, in f64 and f32: each arm's Cartesian task torque is `Jᵀ f` of its
//! own rows, the contact-force limiter acts on the arm whose bounds are finite and on no other,
//! and the tasks and commands of parts the robot does not have are refused.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "test code")]

use fixtures::fixed_base::{self, FixedBaseGains};
use hal::{JointSample, PlatformSample, LEGS};
use kernel::controller::config::*;
use kernel::controller::error::CommandError;
use kernel::controller::messages::{Command, Pose};
use kernel::controller::{Controller, SensorFrame};
use kernel::dynamics::frame_jacobian;
use kernel::math::Placement;
use kernel::model::{FrameId, Inertia, JointDrive, JointKind, JointLimits, Model, ModelBuilder};
use kernel::platform::{PlatformAxis, PlatformLayout};
use kernel::tasks::collision::CollisionModelBuilder;
use nalgebra::{convert, Matrix3, RealField, SMatrix, SVector, Translation3, Unit, UnitQuaternion, Vector3};

/// Coordinates: the torso yaw, then three joints per arm.
const N: usize = 10;
/// Arms.
const A: usize = 3;
/// The robot's controller: fixed base (`U = N`), no collision volumes, three arms.
type ThreeArms<T> = Controller<T, N, N, A, N, 0, 0, A>;

/// Isotropic translational TCP stiffness (N/m); no rotational stiffness (a 3-DOF arm cannot
/// hold an orientation).
const STIFFNESS: f64 = 400.0;
/// The finite force bound of the last arm (N, every translational axis); the others are
/// unbounded.
const BOUND: f64 = 5.0;

fn c<T: RealField>(x: f64) -> T {
    convert(x)
}

fn placement<T: RealField + Copy>(xyz: [f64; 3], yaw: f64) -> Placement<T> {
    let p = Placement::<f64>::from_parts(
        Translation3::new(xyz[0], xyz[1], xyz[2]),
        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw).to_rotation_matrix(),
    );
    convert(p)
}

fn link<T: RealField + Copy>(mass: f64, length: f64) -> Inertia<T> {
    Inertia {
        mass: c(mass),
        com: Vector3::new(c(length / 2.0), T::zero(), T::zero()),
        rotational: Matrix3::<T>::identity() * c::<T>(0.01),
    }
}

/// A torso yawing about z (coordinate 0) with three arms 120° apart, each a shoulder yaw, a
/// shoulder pitch and an elbow pitch (coordinates `1 + 3 a ..`) with 0.3 m links, the TCP
/// (frame `a`) at the end of the forearm.
fn model<T: RealField + Copy>() -> Model<T, N, N, A> {
    let mut b = ModelBuilder::<T, N, N, A>::new(Vector3::new(T::zero(), T::zero(), c(-9.81)));
    let (z, y) = (Unit::new_normalize(Vector3::z()), Unit::new_normalize(Vector3::y()));
    let revolute =
        |axis: Unit<Vector3<f64>>| JointKind::Revolute { axis: Unit::new_unchecked(axis.into_inner().map(c)) };
    let torso = b
        .add_body(None, placement([0.0, 0.0, 0.5], 0.0), revolute(z), JointDrive::actuated(0), link(10.0, 0.0))
        .unwrap();
    for arm in 0..A {
        let angle = 2.0 * core::f64::consts::PI * arm as f64 / A as f64;
        let mount = placement([0.2 * angle.cos(), 0.2 * angle.sin(), 0.3], angle);
        // Shoulder yaw, shoulder pitch, elbow pitch: (placement in the parent, axis, link).
        let joints = [
            (mount, z, link(2.0, 0.0)),
            (placement([0.0, 0.0, 0.1], 0.0), y, link(1.5, 0.3)),
            (placement([0.3, 0.0, 0.0], 0.0), y, link(1.0, 0.3)),
        ];
        let mut parent = torso;
        for (k, (placement, axis, inertia)) in joints.into_iter().enumerate() {
            let drive = JointDrive::actuated(1 + 3 * arm + k);
            parent = b.add_body(Some(parent), placement, revolute(axis), drive, inertia).unwrap();
        }
        b.add_frame(Some(parent), placement([0.3, 0.0, 0.0], 0.0)).unwrap();
    }
    b.limits(JointLimits {
        position_lower: SVector::repeat(c(-2.5)),
        position_upper: SVector::repeat(c(2.5)),
        velocity: SVector::repeat(c(2.0)),
        effort: SVector::repeat(c(200.0)),
    });
    b.try_build().unwrap()
}

/// The coordinates of arm `a`.
fn arm_mask(arm: usize) -> [bool; N] {
    core::array::from_fn(|i| (1 + 3 * arm..4 + 3 * arm).contains(&i))
}

/// The hierarchy: end stops over one Cartesian impedance per arm, each on its own level, over
/// the damping of the upper body.
fn hierarchy() -> [TaskSpec; 5] {
    [
        TaskSpec { kind: TaskKind::EndStops, level: 0 },
        TaskSpec { kind: TaskKind::CartesianImpedance(ArmId(0)), level: 1 },
        TaskSpec { kind: TaskKind::CartesianImpedance(ArmId(1)), level: 2 },
        TaskSpec { kind: TaskKind::CartesianImpedance(ArmId(2)), level: 3 },
        TaskSpec { kind: TaskKind::JointDamping(JointGroup::UpperBody), level: 4 },
    ]
}

/// The fixed-base configuration with the last arm's translational force bounded by [`BOUND`]
/// and the contact-force limiter `enabled` or not.
fn config<T: RealField + Copy>(force_limit: bool) -> ControllerConfig<T, N, A> {
    let free = CartesianParameters {
        translational_stiffness: [c(STIFFNESS); 3],
        rotational_stiffness: [T::zero(); 3],
        damping_ratio: c(0.7),
        force_lower: [c(f64::NEG_INFINITY); 6],
        force_upper: [c(f64::INFINITY); 6],
    };
    let mut bounded = free;
    bounded.force_lower[..3].fill(c(-BOUND));
    bounded.force_upper[..3].fill(c(BOUND));
    let field = CollisionFieldParameters {
        max_force: c(20.0),
        influence_distance: c(0.1),
        damping_ratio: c(0.7),
        activation_full: c(0.0),
        activation_zero: c(0.1),
    };
    let layout = RobotLayout {
        tcp: [FrameId(0), FrameId(1), FrameId(2)],
        platform: PlatformLayout::try_new::<N>([PlatformAxis::Absent; 3]).unwrap(),
        torso: Some(core::array::from_fn(|i| i == 0)),
        arms: [arm_mask(0), arm_mask(1), arm_mask(2)],
    };
    let gains = FixedBaseGains {
        period_s: c(1e-3),
        cartesian: [free, free, bounded],
        collision: [field; 2],
        end_stops: EndStopParameters {
            margin: c(0.1),
            stiffness: SVector::repeat(c(50.0)),
            damping: SVector::repeat(c(2.0)),
        },
        joint_stiffness: SVector::repeat(c(20.0)),
        joint_damping: SVector::repeat(c(2.0)),
        force_limit,
    };
    fixed_base::controller_config(layout, gains)
}

fn controller<T: RealField + Copy>(force_limit: bool) -> Box<ThreeArms<T>> {
    let model = model::<T>();
    let collision = CollisionModelBuilder::<T, 0, 0>::new().try_build(&model, &[]).unwrap();
    Box::new(ThreeArms::<T>::try_new(model, collision, config(force_limit), &hierarchy()).unwrap())
}

/// A frame at `q` at rest.
fn frame<T: RealField + Copy>(q: &[f64; N], cycle: u64) -> SensorFrame<T, N> {
    SensorFrame {
        joints: JointSample { position: q.map(c), velocity: [T::zero(); N], torque: [T::zero(); N], cycle },
        platform: PlatformSample { pose: [T::zero(); 3], velocity: [T::zero(); 3], leg_lengths: [c(0.4); LEGS], cycle },
    }
}

/// Two postures inside the joint limits, away from the end-stop margins, no arm stretched.
const POSTURES: [[f64; N]; 2] =
    [[0.3, 0.2, 0.5, -1.0, -0.3, 0.4, -1.2, 0.1, 0.6, -0.9], [-0.4, -0.5, 0.7, -1.4, 0.6, 0.3, -0.8, -0.2, 0.9, -1.5]];

/// The TCP goal offset of arm `a` (m, world): a different pull per arm.
fn offset(arm: usize) -> Vector3<f64> {
    Vector3::new(0.03, -0.04, 0.0) + Vector3::new(-0.02, 0.01, 0.03) * arm as f64
}

/// Holds one cycle at `q`, then sends every arm a TCP goal [`offset`] away and steps again;
/// returns the controller after the second step and the goals.
fn pulled<T: RealField + Copy>(q: &[f64; N], force_limit: bool) -> (Box<ThreeArms<T>>, [Vector3<T>; A]) {
    let mut controller = controller::<T>(force_limit);
    controller.step(&frame(q, 1));
    assert!(controller.telemetry().fault.is_none(), "{:?}", controller.telemetry().fault);
    let goals: [Vector3<T>; A] = core::array::from_fn(|arm| {
        let target = controller.tcp_target(ArmId(arm as u8)).unwrap().pose;
        target.translation.vector + offset(arm).map(c)
    });
    for (arm, goal) in goals.iter().enumerate() {
        let pose = Pose { position: (*goal).into(), orientation: [T::one(), T::zero(), T::zero(), T::zero()] };
        let target = controller.tcp_target(ArmId(arm as u8)).unwrap().pose;
        let rotation = UnitQuaternion::from_rotation_matrix(&target.rotation);
        let pose = Pose { orientation: [rotation.w, rotation.i, rotation.j, rotation.k], ..pose };
        controller.apply(&Command::TcpGoal { hand: ArmId(arm as u8), pose, duration_s: T::zero() }).unwrap();
    }
    controller.step(&frame(q, 2));
    assert!(controller.telemetry().fault.is_none(), "{:?}", controller.telemetry().fault);
    (controller, goals)
}

/// Per arm and posture: the Cartesian task's torque before projection is `Jᵀ f` of the arm's own
/// TCP rows, `f = −K (p − p_des)` (zero velocity: no damping; the bounded arm's force clamped
/// to [`BOUND`] per axis of its desired frame), to `tolerance` relative; it moves no joint of
/// another arm.
fn each_arm_has_the_cartesian_torque_of_its_rows<T: RealField + Copy + Into<f64>>(tolerance: f64) {
    for q in POSTURES {
        let (controller, goals) = pulled::<T>(&q, false);
        let t = controller.telemetry();
        assert!(controller.telemetry().fault.is_none());
        let mut norms = [0.0; A];
        for (arm, goal) in goals.iter().enumerate() {
            let tcp = FrameId(arm);
            let mut jacobian = SMatrix::<T, 6, N>::zeros();
            frame_jacobian(controller.model(), controller.data(), tcp, &mut jacobian).unwrap();
            let position = controller.data().frame_placements[arm].translation.vector;
            let mut force = (position - goal) * c::<T>(-STIFFNESS);
            if arm == 2 {
                // The bounds hold in the axes of the desired frame.
                let axes = *controller.tcp_target(ArmId(2)).unwrap().pose.rotation.matrix();
                force = axes * (axes.transpose() * force).map(|f| f.max(c(-BOUND)).min(c(BOUND)));
            }
            let torque = jacobian.fixed_rows::<3>(0).transpose() * force;
            let others = (0..A).filter(|a| *a != arm).flat_map(|a| (0..N).filter(move |i| arm_mask(a)[*i]));
            assert!(others.clone().all(|i| torque[i] == T::zero()), "arm {arm} moves no other arm");
            let expected: f64 = torque.norm().into();
            let entry =
                t.tasks.iter().position(|k| *k == Some(TaskKind::CartesianImpedance(ArmId(arm as u8)))).unwrap();
            let actual: f64 = t.task_torque_norm[entry].into();
            assert!(expected > 0.5, "arm {arm}: ‖Jᵀ f‖ = {expected} Nm");
            assert!(
                (actual - expected).abs() <= tolerance * expected,
                "arm {arm}: ‖τ_cart‖ {actual} vs ‖Jᵀ f‖ {expected}"
            );
            norms[arm] = actual;
        }
        eprintln!("three arms, posture {q:?}: ‖τ_cart‖ per arm {norms:?} Nm");
    }
}

#[test]
fn each_of_three_arms_has_the_cartesian_torque_of_its_own_rows_in_f64() {
    each_arm_has_the_cartesian_torque_of_its_rows::<f64>(1e-9);
}

#[test]
fn each_of_three_arms_has_the_cartesian_torque_of_its_own_rows_in_f32() {
    each_arm_has_the_cartesian_torque_of_its_rows::<f32>(1e-3);
}

/// The contact-force limiter on the third arm only (the one with finite bounds): with the
/// limiter on, the output differs from the same step with it off by the command-side limit's
/// torque `−J_Lᵀ e` of the third arm's rows, which moves the torso and the third arm and not one
/// joint of the other two arms; only the third arm's force axes are flagged as limited.
fn the_force_limiter_acts_per_arm<T: RealField + Copy + Into<f64>>(tolerance: f64) {
    for q in POSTURES {
        let (limited, _) = pulled::<T>(&q, true);
        let (free, _) = pulled::<T>(&q, false);
        let difference = SVector::<T, N>::from(limited.output().torque) - SVector::<T, N>::from(free.output().torque);
        let scale: f64 = SVector::<T, N>::from(free.output().torque).amax().into();
        for arm in 0..A {
            let moved: f64 =
                (0..N).filter(|i| arm_mask(arm)[*i]).map(|i| difference[i].into().abs()).fold(0.0, f64::max);
            if arm == 2 {
                assert!(moved > 1e-3, "the limit moves the bounded arm ({moved} Nm)");
                eprintln!("three arms, posture {q:?}: the limit moves the bounded arm by up to {moved} Nm");
            } else {
                assert!(moved <= tolerance * scale, "arm {arm} moved by {moved} Nm");
            }
        }
        let flags = limited.telemetry().tcp_force_limited;
        assert!(flags[2][..3].iter().any(|f| *f), "{flags:?}");
        assert_eq!(flags[0], [false; 6]);
        assert_eq!(flags[1], [false; 6]);
        assert_eq!(limited.telemetry().contact_wrench.len(), A);
    }
}

#[test]
fn the_force_limiter_acts_per_arm_in_f64() {
    the_force_limiter_acts_per_arm::<f64>(1e-12);
}

#[test]
fn the_force_limiter_acts_per_arm_in_f32() {
    the_force_limiter_acts_per_arm::<f32>(1e-5);
}

/// The tasks of parts the robot does not have are refused (a platform's, a fourth arm's), the
/// commands for a fourth arm too; the torso's and the third arm's are accepted.
#[test]
fn three_arms_refuse_tasks_and_commands_of_parts_they_do_not_have() {
    let mut controller = controller::<f64>(false);
    let groups = controller.config().layout.groups();
    let arms = [0, 1, 2].map(|a| JointGroup::Arm(ArmId(a)));
    assert_eq!(groups.as_slice(), [[JointGroup::Torso].as_slice(), &arms, &[JointGroup::UpperBody]].concat());
    controller.step(&frame(&POSTURES[0], 1));
    for kind in [
        TaskKind::JointImpedance(JointGroup::Platform),
        TaskKind::JointDamping(JointGroup::Arm(ArmId(3))),
        TaskKind::CartesianImpedance(ArmId(3)),
        TaskKind::SingularityAvoidance(ArmId(3)),
    ] {
        let tasks = [TaskSpec { kind, level: 0 }].into_iter().collect();
        assert_eq!(controller.apply(&Command::SetHierarchy(tasks)), Err(CommandError::UnknownTask), "{kind:?}");
    }
    let pose = Pose { position: [0.3, 0.0, 0.5], orientation: [1.0, 0.0, 0.0, 0.0] };
    let out_of_range = Err(CommandError::OutOfRange { field: "hand" });
    assert_eq!(controller.apply(&Command::TcpGoal { hand: ArmId(3), pose, duration_s: 1.0 }), out_of_range);
    assert!(controller.tcp_target(ArmId(3)).is_none());
    let accepted = [
        TaskSpec { kind: TaskKind::JointImpedance(JointGroup::Torso), level: 0 },
        TaskSpec { kind: TaskKind::SingularityAvoidance(ArmId(2)), level: 1 },
        TaskSpec { kind: TaskKind::CartesianImpedance(ArmId(2)), level: 1 },
    ];
    assert_eq!(controller.apply(&Command::SetHierarchy(accepted.into_iter().collect())), Ok(()));
    controller.step(&frame(&POSTURES[0], 2));
    assert!(controller.telemetry().fault.is_none(), "{:?}", controller.telemetry().fault);
}
