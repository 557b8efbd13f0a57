//! The full controller step of the imported Franka Panda (`fixtures::robots::panda`, issue 15):
//! the fixed-base, single-arm controller of `tests/src/fixed_base.rs` with its collision model
//! (`fixtures/robots/panda/panda.collision`: 21 volumes, 80 pairs) and both collision fields in
//! the hierarchy, measured by the `wcet-step-panda` image like Justin's step.
//!
//! Frames: a nominal sequence (a posture with a small sinusoidal joint motion while the TCP goal
//! moves 5 cm along a cubic, from [`goal_command`]), then the capacity frames (both collision
//! fields widened by [`capacity_commands`] so that every one of the 80 pairs is evaluated
//! exactly and both fields fill their rows, over the postures of [`CAPACITY_POSTURES`] at 60 % of
//! the joint speed limits).

use fixtures::fixed_base::{self, FixedBaseGains};
use fixtures::robots::panda;
use hal::{JointSample, PlatformSample, LEGS};
use kernel::controller::config::*;
use kernel::controller::messages::{Command, Pose};
use kernel::controller::{Controller, SensorFrame};
use kernel::platform::{PlatformAxis, PlatformLayout};
use kernel::tasks::collision::CollisionModel;
use nalgebra::{ComplexField, SVector, UnitQuaternion, Vector3};

use crate::{c, S};

/// Collision volumes of `panda.collision`.
pub const VOLUMES: usize = panda::collision::VOLUMES;
/// Enabled pairs of `panda.collision` (every pair less the kernel's rules and the listed ones).
pub const PAIRS: usize = panda::collision::PAIRS;

/// The Panda's whole-body controller: N = U = 7 (fixed base), one arm, 21 volumes, 80 pairs.
pub type PandaController =
    Controller<S, { panda::N }, { panda::BODIES }, { panda::FRAMES }, { panda::N }, VOLUMES, PAIRS, 1>;
/// One sensor frame.
pub type PandaFrame = SensorFrame<S, { panda::N }>;

/// The arm.
const ARM: ArmId = ArmId(0);

/// The hierarchy of `tests/src/fixed_base.rs` with the two collision fields of Fig. 6.3: end stops
/// and the strong field over the Cartesian impedance over the weak field and the singularity
/// avoidance over the arm's joint damping.
pub const HIERARCHY: [TaskSpec; 6] = [
    TaskSpec { kind: TaskKind::EndStops, level: 0 },
    TaskSpec { kind: TaskKind::CollisionAvoidance(Field::Strong), level: 0 },
    TaskSpec { kind: TaskKind::CartesianImpedance(ARM), level: 1 },
    TaskSpec { kind: TaskKind::CollisionAvoidance(Field::Weak), level: 2 },
    TaskSpec { kind: TaskKind::SingularityAvoidance(ARM), level: 2 },
    TaskSpec { kind: TaskKind::JointDamping(JointGroup::Arm(ARM)), level: 3 },
];

/// The strong (5 cm, 150 N) and weak (15 cm, 25 N, Table 3.1) fields of Justin's configuration.
fn collision_fields() -> [CollisionFieldParameters<S>; 2] {
    let field = |max_force: f64, reach: f64, full: f64| CollisionFieldParameters {
        max_force: c(max_force),
        influence_distance: c(reach),
        damping_ratio: c(0.7),
        activation_full: c(full),
        activation_zero: c(reach),
    };
    [field(150.0, 0.05, 0.01), field(25.0, 0.15, 0.0)]
}

/// The gains of `tests/src/fixed_base.rs` (400 N/m, 30 Nm/rad at the TCP) in the fixed-base
/// configuration of [`fixtures::fixed_base`], with the collision fields of [`collision_fields`]
/// and the Cartesian force limits on (±20 N, Table 7.1's "Clean the mug!"), so that the
/// contact-force limiter runs in every frame as in Justin's measurement.
pub fn controller_config() -> Option<ControllerConfig<S, { panda::N }, 1>> {
    let cartesian = CartesianParameters {
        translational_stiffness: [c(400.0); 3],
        rotational_stiffness: [c(30.0); 3],
        damping_ratio: c(0.7),
        force_lower: [c(-20.0); 6],
        force_upper: [c(20.0); 6],
    };
    let layout = RobotLayout {
        tcp: panda::TCPS,
        platform: PlatformLayout::try_new::<{ panda::N }>([PlatformAxis::Absent; 3]).ok()?,
        torso: None,
        arms: [[true; panda::N]],
    };
    Some(fixed_base::controller_config(
        layout,
        FixedBaseGains {
            period_s: c(1e-3),
            cartesian: [cartesian],
            collision: collision_fields(),
            end_stops: EndStopParameters {
                margin: c(0.1),
                stiffness: SVector::repeat(c(50.0)),
                damping: SVector::repeat(c(2.0)),
            },
            joint_stiffness: SVector::repeat(c(20.0)),
            joint_damping: SVector::repeat(c(2.0)),
            force_limit: true,
        },
    ))
}

/// The Panda's collision model: `fixtures/robots/panda/panda.collision` as `fixtures/build.rs`
/// compiles it (the constructor the host-sim rig uses).
pub fn collision_model(model: &panda::RobotModel<S>) -> Option<CollisionModel<S, VOLUMES, PAIRS>> {
    panda::collision::collision_model(model).ok()
}

/// The controller with [`controller_config`] and [`HIERARCHY`]. Always inlined into the caller's
/// `init`, so that the controller is built in place there (as Justin's `new_controller`).
#[inline(always)]
pub fn new_controller() -> Option<PandaController> {
    let model = panda::model::<S>().ok()?;
    let collision = collision_model(&model)?;
    PandaController::try_new(model, collision, controller_config()?, &HIERARCHY).ok()
}

/// One full control cycle; returns the sum of the output torques (a checksum).
#[no_mangle]
#[inline(never)]
pub fn wcet_step_panda(controller: &mut PandaController, frame: &PandaFrame) -> S {
    let out = controller.step(frame);
    out.torque.iter().fold(c(0.0), |a, t| a + *t)
}

/// The posture of the nominal frames (rad): `tests/src/fixed_base.rs`'s first.
pub const HOME: [f64; panda::N] = [0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8];

/// Postures of the capacity frames (rad): [`HOME`], the other two of `tests/src/fixed_base.rs`,
/// the elbow folded to its stop with the hand turned toward the base, and the arm stretched
/// (elbow near its upper stop: near-singular) with joints 1, 3 and 5 at their stops.
pub const CAPACITY_POSTURES: [[f64; panda::N]; 5] = [
    HOME,
    [0.5, 0.2, -0.4, -1.6, 0.3, 1.5, -0.2],
    [-0.7, -0.5, 0.6, -2.3, -0.4, 2.2, 1.2],
    [0.0, 0.9, 0.0, -3.0, 0.0, 3.7, 0.0],
    [2.85, 1.7, -2.85, -0.08, 2.85, 0.0, 2.85],
];

/// Frames of the nominal sequence.
pub const NOMINAL_FRAMES: u32 = 24;
/// First capacity frame.
pub const CAPACITY_START: u32 = NOMINAL_FRAMES;
/// All frames: nominal, then every capacity posture once.
pub const STEP_FRAMES: u32 = CAPACITY_START + CAPACITY_POSTURES.len() as u32;

/// Influence distance (m) of both fields in the capacity frames: larger than any distance
/// between two of the Panda's volumes, so the broad phase skips none of the 80 pairs.
pub const CAPACITY_FIELD_M: f64 = 10.0;

/// Which input class frame `k` belongs to.
pub fn frame_class(k: u32) -> &'static str {
    if k < CAPACITY_START {
        "nominal"
    } else {
        "capacity"
    }
}

/// The moving goal, applied before frame 1 (after frame 0 set the target to the measured TCP):
/// the TCP goal 5 cm away along a 0.5 s cubic, so every nominal frame after it samples the
/// trajectory.
pub fn goal_command(controller: &PandaController, k: u32) -> Option<Command<S>> {
    if k != 1 {
        return None;
    }
    let target = controller.tcp_target(ARM)?.pose;
    let goal = target.translation.vector + Vector3::new(c(0.03), c(-0.04), c(0.0));
    let rotation = UnitQuaternion::from_rotation_matrix(&target.rotation);
    let pose = Pose { position: goal.into(), orientation: [rotation.w, rotation.i, rotation.j, rotation.k] };
    Some(Command::TcpGoal { hand: ARM, pose, duration_s: c(0.5) })
}

/// The commands widening both fields to [`CAPACITY_FIELD_M`], applied before [`CAPACITY_START`].
pub fn capacity_commands(k: u32) -> Option<[Command<S>; 2]> {
    if k != CAPACITY_START {
        return None;
    }
    Some([Field::Strong, Field::Weak].map(|field| {
        let mut parameters = collision_fields()[field.index()];
        parameters.influence_distance = c(CAPACITY_FIELD_M);
        parameters.activation_zero = c(CAPACITY_FIELD_M);
        Command::SetCollisionField { field, parameters }
    }))
}

/// Applies the planner commands of frame `k` ([`goal_command`], [`capacity_commands`]); `false`
/// if one is refused.
pub fn prepare(controller: &mut PandaController, k: u32) -> bool {
    goal_command(controller, k).is_none_or(|command| controller.apply(&command).is_ok())
        && capacity_commands(k).is_none_or(|commands| commands.iter().all(|command| controller.apply(command).is_ok()))
}

/// Frame `k` of the measured sequence (cycle counter `k + 1`), for `k < STEP_FRAMES`: nominal
/// frames move every joint by 0.05 rad at 0.5 Hz about [`HOME`] (a phase per joint); capacity
/// frames are at rest in position and move at 60 % of the joint speed limit `speed`, signs
/// alternating.
pub fn step_frame(k: u32, speed: &SVector<S, { panda::N }>) -> PandaFrame {
    let cycle = u64::from(k) + 1;
    let (q, v) = match CAPACITY_POSTURES.get(k.saturating_sub(CAPACITY_START) as usize) {
        Some(posture) if k >= CAPACITY_START => {
            let sign = |i: usize| if (i + k as usize).is_multiple_of(2) { c(1.0) } else { c(-1.0) };
            (posture.map(c), core::array::from_fn(|i| sign(i) * c(0.6) * speed[i]))
        }
        _ => {
            let t = c(f64::from(k) * 1e-3);
            let w = c(core::f64::consts::PI);
            let phase = |i: usize| w * t + c(i as f64);
            (
                core::array::from_fn(|i| c(HOME[i]) + c(0.05) * ComplexField::sin(phase(i))),
                core::array::from_fn(|i| c(0.05) * w * ComplexField::cos(phase(i))),
            )
        }
    };
    SensorFrame {
        joints: JointSample { position: q, velocity: v, torque: [c(0.0); panda::N], cycle },
        platform: PlatformSample { pose: [c(0.0); 3], velocity: [c(0.0); 3], leg_lengths: [c(0.4); LEGS], cycle },
    }
}
