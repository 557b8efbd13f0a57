//! The layout is data: the whole-body controller on a fixed-base, single-arm robot, the imported
//! Franka Panda (`fixtures::robots::panda`, N = 7, one TCP): `A = 1`, no platform, no torso, a
//! hierarchy of end stops, Cartesian impedance, singularity avoidance and joint damping, in f64
//! and f32. The same `Controller` type and code path as Justin's.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "test code")]

use fixtures::fixed_base::{self, FixedBaseGains};
use fixtures::robots::panda;
use hal::{JointSample, PlatformSample, LEGS};
use kernel::controller::config::*;
use kernel::controller::error::CommandError;
use kernel::controller::messages::{Command, Pose};
use kernel::controller::{Controller, SensorFrame};
use kernel::dynamics::frame_jacobian;
use kernel::platform::coupling_compensation::CompensationSwitch;
use kernel::platform::{PlatformAxis, PlatformLayout};
use kernel::tasks::collision::CollisionModelBuilder;
use nalgebra::{convert, RealField, SMatrix, SVector, Vector3};

/// The Panda's controller: N = U = 7 (fixed base), no collision volumes, one arm.
type Panda<T> = Controller<T, { panda::N }, { panda::BODIES }, { panda::FRAMES }, { panda::N }, 0, 0, 1>;

/// Isotropic translational TCP stiffness (N/m): the spring force in the world is `−K e`.
const STIFFNESS: f64 = 400.0;

fn c<T: RealField>(x: f64) -> T {
    convert(x)
}

/// The hierarchy: end stops over the Cartesian impedance over the singularity avoidance over the
/// arm's joint damping.
fn hierarchy() -> [TaskSpec; 4] {
    let arm = ArmId(0);
    [
        TaskSpec { kind: TaskKind::EndStops, level: 0 },
        TaskSpec { kind: TaskKind::CartesianImpedance(arm), level: 1 },
        TaskSpec { kind: TaskKind::SingularityAvoidance(arm), level: 2 },
        TaskSpec { kind: TaskKind::JointDamping(JointGroup::Arm(arm)), level: 3 },
    ]
}

/// Every gain of the Panda's controller: a fixed base (every platform axis absent; the platform
/// parameters are valid but drive nothing, the leg motion on so that a running platform loop
/// would show), one arm of all seven joints, no torso.
/// The fixed-base configuration ([`fixtures::fixed_base`]) of the Panda, with the platform's
/// admittance, ICR avoidance, leg motion and coupling compensation all switched on: the test
/// `a_controller_without_a_platform_runs_no_admittance` checks that a fixed base runs none of them anyway.
fn config<T: RealField + Copy>() -> ControllerConfig<T, { panda::N }, 1> {
    let cartesian = CartesianParameters {
        translational_stiffness: [c(STIFFNESS); 3],
        rotational_stiffness: [c(30.0); 3],
        damping_ratio: c(0.7),
        force_lower: [c(f64::NEG_INFINITY); 6],
        force_upper: [c(f64::INFINITY); 6],
    };
    let field = CollisionFieldParameters {
        max_force: c(20.0),
        influence_distance: c(0.1),
        damping_ratio: c(0.7),
        activation_full: c(0.0),
        activation_zero: c(0.1),
    };
    let layout = RobotLayout {
        tcp: panda::TCPS,
        platform: PlatformLayout::try_new::<{ panda::N }>([PlatformAxis::Absent; 3]).unwrap(),
        torso: None,
        arms: [[true; panda::N]],
    };
    let gains = FixedBaseGains {
        period_s: c(1e-3),
        cartesian: [cartesian],
        collision: [field; 2],
        end_stops: EndStopParameters {
            margin: c(0.1),
            stiffness: SVector::repeat(c(50.0)),
            damping: SVector::repeat(c(2.0)),
        },
        joint_stiffness: SVector::repeat(c(20.0)),
        joint_damping: SVector::repeat(c(2.0)),
        force_limit: false,
    };
    // Every platform switch on: with every axis absent the step must still run no admittance
    // and no leg loop, which the test below checks.
    let mut config = fixed_base::controller_config(layout, gains);
    config.platform.admittance.free_axes = [true; 3];
    config.platform.avoidance.icr_avoidance = true;
    config.platform.avoidance.leg_motion = true;
    config.platform.compensation = CompensationSwitch::ON;
    config
}

fn controller<T: RealField + Copy>() -> Box<Panda<T>> {
    let model = panda::model::<T>().unwrap();
    let collision = CollisionModelBuilder::<T, 0, 0>::new().try_build(&model, &[]).unwrap();
    Box::new(Panda::<T>::try_new(model, collision, config(), &hierarchy()).unwrap())
}

/// A frame at `q` at rest; the platform sample is ignored on a fixed base, its legs far from
/// their nominal length (a running leg loop would move them).
fn frame<T: RealField + Copy>(q: &[f64; panda::N], cycle: u64) -> SensorFrame<T, { panda::N }> {
    SensorFrame {
        joints: JointSample {
            position: q.map(c),
            velocity: [T::zero(); panda::N],
            torque: [T::zero(); panda::N],
            cycle,
        },
        platform: PlatformSample {
            pose: [T::zero(); 3],
            velocity: [T::zero(); 3],
            leg_lengths: [c(0.45); LEGS],
            cycle,
        },
    }
}

/// Three postures inside the joint limits (rad), away from the end-stop margins.
const POSTURES: [[f64; panda::N]; 3] = [
    [0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8],
    [0.5, 0.2, -0.4, -1.6, 0.3, 1.5, -0.2],
    [-0.7, -0.5, 0.6, -2.3, -0.4, 2.2, 1.2],
];

/// On each posture: the first cycle holds (targets at the measured TCP), then a TCP goal 5 cm
/// away pulls. The output torque is finite and differs from the holding torque; the Cartesian
/// task's torque before projection is `Jᵀ f` of its own rows, `f = −K (p − p_des)` with the
/// isotropic `K` (zero velocity: no damping), to 1e-9 (f64) / 1e-3 (f32) relative (observed
/// 9.6 to 15.0 Nm, equal to 1e-15 in f64). The TCP error is the 5 cm offset.
fn steps_with_the_cartesian_torque_of_its_rows<T: RealField + Copy + Into<f64>>(tolerance: f64) {
    let offset = Vector3::new(0.03, -0.04, 0.0);
    for q in POSTURES {
        let mut controller = controller::<T>();
        let hold: SVector<T, { panda::N }> = SVector::from(controller.step(&frame(&q, 1)).torque);
        assert!(controller.telemetry().fault.is_none(), "{:?}", controller.telemetry().fault);
        let target = controller.tcp_target(ArmId(0)).unwrap().pose;
        let goal = target.translation.vector + offset.map(c);
        let rotation = nalgebra::UnitQuaternion::from_rotation_matrix(&target.rotation);
        let pose = Pose { position: goal.into(), orientation: [rotation.w, rotation.i, rotation.j, rotation.k] };
        controller.apply(&Command::TcpGoal { hand: ArmId(0), pose, duration_s: T::zero() }).unwrap();
        let torque: SVector<T, { panda::N }> = SVector::from(controller.step(&frame(&q, 2)).torque);
        let t = controller.telemetry();
        assert!(t.fault.is_none(), "{:?}", t.fault);
        assert!(torque.iter().all(|x| x.is_finite()));
        let change: f64 = ((torque - hold).norm()).into();
        assert!(change > 0.1, "the goal changes the torque by {change} Nm");

        let data = controller.data();
        let mut jacobian = SMatrix::<T, 6, { panda::N }>::zeros();
        frame_jacobian(controller.model(), data, panda::TCPS[0], &mut jacobian).unwrap();
        let position = data.frame_placements[panda::TCPS[0].0].translation.vector;
        let force = (position - goal) * c::<T>(-STIFFNESS);
        let expected: f64 = ((jacobian.fixed_rows::<3>(0).transpose() * force).norm()).into();
        let entry = t.tasks.iter().position(|k| *k == Some(TaskKind::CartesianImpedance(ArmId(0)))).unwrap();
        let actual: f64 = (t.task_torque_norm[entry]).into();
        assert!(expected > 1.0, "‖Jᵀ f‖ = {expected} Nm");
        assert!((actual - expected).abs() <= tolerance * expected, "‖τ_cart‖ {actual} vs ‖Jᵀ f‖ {expected}");
        let error: f64 = (t.tcp_error[0].fixed_rows::<3>(0).norm()).into();
        assert!((error - offset.norm()).abs() < 0.1 * tolerance, "TCP error {error} m");
    }
}

#[test]
fn a_fixed_base_panda_steps_with_the_cartesian_torque_of_its_rows_in_f64() {
    steps_with_the_cartesian_torque_of_its_rows::<f64>(1e-9);
}

#[test]
fn a_fixed_base_panda_steps_with_the_cartesian_torque_of_its_rows_in_f32() {
    steps_with_the_cartesian_torque_of_its_rows::<f32>(1e-3);
}

/// No platform: no admittance and no leg loop run, the platform command stays zero although the
/// legs are off their nominal length and the Cartesian task pulls; the telemetry's virtual force
/// is zero.
#[test]
fn a_controller_without_a_platform_runs_no_admittance() {
    let mut controller = controller::<f64>();
    let q = POSTURES[1];
    controller.step(&frame(&q, 1));
    let target = controller.tcp_target(ArmId(0)).unwrap().pose;
    let pose = Pose {
        position: (target.translation.vector + Vector3::new(0.1, 0.1, 0.0)).into(),
        orientation: [1.0, 0.0, 0.0, 0.0],
    };
    controller.apply(&Command::TcpGoal { hand: ArmId(0), pose, duration_s: 0.0 }).unwrap();
    for cycle in 2..50 {
        let output = *controller.step(&frame(&q, cycle));
        assert_eq!(output.platform.velocity, [0.0; 3], "cycle {cycle}");
        assert_eq!(output.platform.leg_rates, [0.0; LEGS], "cycle {cycle}");
        assert_eq!(controller.telemetry().virtual_force, Vector3::zeros());
        assert!(controller.telemetry().fault.is_none());
    }
}

/// What a one-armed robot without torso and platform refuses: a joint task on an empty group
/// and any command for a second arm; its own groups are the arm and the upper body.
#[test]
fn a_single_arm_refuses_tasks_and_commands_of_parts_it_does_not_have() {
    let mut controller = controller::<f64>();
    assert_eq!(controller.config().layout.groups().as_slice(), [JointGroup::Arm(ArmId(0)), JointGroup::UpperBody]);
    controller.step(&frame(&POSTURES[0], 1));
    for kind in [
        TaskKind::JointImpedance(JointGroup::Torso),
        TaskKind::JointDamping(JointGroup::Platform),
        TaskKind::JointImpedance(JointGroup::Arm(ArmId(1))),
        TaskKind::CartesianImpedance(ArmId(1)),
        TaskKind::SingularityAvoidance(ArmId(1)),
        TaskKind::TorsoWorkspace,
    ] {
        let tasks = [TaskSpec { kind, level: 0 }].into_iter().collect();
        assert_eq!(controller.apply(&Command::SetHierarchy(tasks)), Err(CommandError::UnknownTask), "{kind:?}");
    }
    let pose = Pose { position: [0.3, 0.0, 0.5], orientation: [1.0, 0.0, 0.0, 0.0] };
    let out_of_range = Err(CommandError::OutOfRange { field: "hand" });
    assert_eq!(controller.apply(&Command::TcpGoal { hand: ArmId(1), pose, duration_s: 1.0 }), out_of_range);
    let parameters = controller.config().cartesian[0];
    assert_eq!(controller.apply(&Command::SetCartesian { hand: ArmId(1), parameters }), out_of_range);
    let values = [0.0; panda::N].into_iter().collect();
    let goal = Command::JointGoal { group: JointGroup::Arm(ArmId(1)), values, duration_s: 1.0 };
    assert_eq!(controller.apply(&goal), out_of_range);
    let kept: Vec<TaskSpec> = controller.hierarchy().collect();
    assert_eq!(kept, hierarchy());
}
