//! The measured kernel stages and their inputs, shared by the Cortex-M images
//! (`firmware/src/bin/{wcet,wcet_step,wcet_step_panda,panic_check}.rs`) and the host callgrind
//! bench (`wcet/host`); the imported Panda's step is in `panda` (feature `panda`). See `wcet/measure.sh`. The
//! scalar is `f32`, or `f64` with the `wcet-f64` feature.
#![no_std]

#[cfg(feature = "panda")]
pub mod panda;

use fixtures::justin;
use fixtures::justin::collision::JustinCollisionModel;
use fixtures::justin::whole_body;
use fixtures::justin::JustinModel;
use hal::{JointSample, PlatformSample};
use kernel::controller::config::{ArmId, Field, TaskKind, TaskSpec};
use kernel::controller::messages::Command;
use kernel::controller::SensorFrame;
use kernel::dynamics::{coriolis_matrix, crba, forward_kinematics, frame_jacobian, gravity, mass_matrix_cholesky};
use kernel::hierarchy::{project, HierarchyConfig, HierarchyData, Stack};
use kernel::math::CholeskyFactor;
use kernel::tasks::collision::{self_collision_rows, CollisionData, CollisionParameters, CollisionReport};
use kernel::tasks::{TaskRow, TaskRows};
use kernel::{Data, FrameId};
use nalgebra::{ComplexField, RowSVector, SMatrix, SVector};

#[cfg(not(feature = "wcet-f64"))]
pub type S = f32;
#[cfg(feature = "wcet-f64")]
pub type S = f64;

pub const N: usize = justin::N;
/// Input cases: the home pose, then seeded perturbations.
pub const CASES: u32 = 10;
pub const COLLISION_ROWS: usize = 64;
pub const ROWS: usize = 40;
pub const LEVELS: usize = 4;

pub type JustinData = Data<S, N, { justin::BODIES }, { justin::FRAMES }>;
pub type Rows = TaskRows<S, N, COLLISION_ROWS>;
pub type Hierarchy = HierarchyData<S, N, ROWS, LEVELS>;

pub fn c(x: f64) -> S {
    nalgebra::convert::<f64, S>(x)
}

// --- the measured stages --------------------------------------------------------------------

/// Stage 0: the dynamics terms the controller needs every cycle.
#[no_mangle]
#[inline(never)]
pub fn wcet_dynamics(
    model: &JustinModel<S>,
    data: &mut JustinData,
    q: &SVector<S, N>,
    v: &SVector<S, N>,
    jacobian: &mut SMatrix<S, 6, N>,
) -> Option<CholeskyFactor<S, N>> {
    forward_kinematics(model, data, q, v).ok()?;
    crba(model, data);
    coriolis_matrix(model, data);
    gravity(model, data);
    let factor = mass_matrix_cholesky(data).ok()?;
    frame_jacobian(model, data, justin::RIGHT_TCP, jacobian).ok()?;
    Some(factor)
}

/// Stage 1: self-collision avoidance rows of the 214 pairs.
#[no_mangle]
#[inline(never)]
pub fn wcet_self_collision(
    collision: &JustinCollisionModel<S>,
    collision_data: &mut CollisionData<S, { justin::collision::VOLUMES }, { justin::collision::PAIRS }>,
    model: &JustinModel<S>,
    data: &JustinData,
    factor: &CholeskyFactor<S, N>,
    parameters: &CollisionParameters<S>,
    rows: &mut Rows,
) -> Option<CollisionReport<S>> {
    self_collision_rows(collision, collision_data, model, data, factor, parameters, rows).ok()
}

/// Stage 2: the hierarchical projection.
#[no_mangle]
#[inline(never)]
pub fn wcet_projection(config: &HierarchyConfig<'_, S, N>, stack: &Stack<S, N, ROWS>, out: &mut Hierarchy) -> S {
    project(config, stack, out).map_or(S::NAN, |t| t.sum())
}

// --- inputs ---------------------------------------------------------------------------------

struct XorShift(u32);
impl XorShift {
    /// Uniform in [-1, 1).
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 17;
        self.0 ^= self.0 << 5;
        f64::from(self.0) / f64::from(u32::MAX / 2 + 1) - 1.0
    }
}

fn push_frame_rows(
    stack: &mut Stack<S, N, ROWS>,
    data: &JustinData,
    model: &JustinModel<S>,
    level: usize,
    frame: FrameId,
    rows: &[usize],
) -> Option<()> {
    let mut j = SMatrix::<S, 6, N>::zeros();
    frame_jacobian(model, data, frame, &mut j).ok()?;
    for r in rows {
        let k = stack.rows().len();
        let force = c(5.0) * ComplexField::cos(c(0.7) * c(k as f64));
        stack
            .push(level, TaskRow { jacobian: j.row(*r).into_owned(), force, potential: c(0.0), activation: c(1.0) })
            .ok()?;
    }
    Some(())
}

/// The 40-row stack of `host-sim/benches/hierarchy.rs` at the current pose.
pub fn build_stack(stack: &mut Stack<S, N, ROWS>, data: &JustinData, model: &JustinModel<S>) -> Option<()> {
    *stack = Stack::new();
    push_frame_rows(stack, data, model, 0, justin::RIGHT_TCP, &[0, 1, 2, 3, 4, 5])?;
    push_frame_rows(stack, data, model, 0, justin::LEFT_TCP, &[0, 1, 2, 3])?;
    push_frame_rows(stack, data, model, 1, justin::LEFT_TCP, &[4, 5])?;
    push_frame_rows(stack, data, model, 1, justin::RIGHT_HAND, &[0, 1, 2, 3, 4, 5])?;
    push_frame_rows(stack, data, model, 1, justin::TORSO_TOP, &[0, 1])?;
    for (level, joints) in [(2, 3..13), (3, 10..20)] {
        for joint in joints {
            let k = stack.rows().len();
            let jacobian = RowSVector::<S, N>::from_fn(|_, col| if col == joint { c(1.0) } else { c(0.0) });
            let force = c(5.0) * ComplexField::cos(c(0.7) * c(k as f64));
            stack.push(level, TaskRow { jacobian, force, potential: c(0.0), activation: c(1.0) }).ok()?;
        }
    }
    Some(())
}

/// Case 0 is the home pose with q̇ = 0.3 rad/s; the others perturb q by up to ±0.3 rad and
/// q̇ by ±0.5 rad/s (xorshift seeded with the case number).
pub fn case_input(case: u32) -> (SVector<S, N>, SVector<S, N>) {
    let mut rng = XorShift(0x9E37_79B9 ^ case.wrapping_mul(0x85EB_CA6B));
    let scale = if case == 0 { 0.0 } else { 1.0 };
    let q = justin::home_configuration::<S>() + SVector::<S, N>::from_fn(|_, _| c(0.3 * scale * rng.next()));
    let v = SVector::<S, N>::from_fn(|_, _| c(0.3 + 0.5 * scale * rng.next()));
    (q, v)
}

// --- the full controller step (issue 8) -----------------------------------------------------

/// Upper-body joints of the Justin-like robot.
pub const U: usize = justin::UPPER_DOF;
/// The whole-body controller of Fig. 6.3 for the right hand, every one of the 214 pairs enabled.
pub type JustinController = whole_body::JustinController<S>;
/// One sensor frame.
pub type Frame = SensorFrame<S, U>;

/// The controller with `whole_body::controller_config` and `fig_6_3_hierarchy(ArmId::RIGHT)`,
/// both TCPs with the force limits of Table 7.1's "Clean the mug!" (±20 N on every tool axis):
/// the contact-force limiter's command-side limit (12 solves with the inertia factor, one
/// 12 × 12 Cholesky) runs in every valid frame. The return from the safe output is immediate
/// (one valid cycle, no blend) so that the frames after the fault frame output the whole-body
/// torque and their checksums compare the full computation (a waiting or blending cycle runs
/// the same computation, so its cost is the same).
///
/// Always inlined into the caller's `init`, so that the controller is built in place there: a
/// separate frame returning it by value made LTO keep up to three copies on the stack (270 KB
/// in f32, more than the RAM above the statics in f64).
#[inline(always)]
pub fn new_controller() -> Option<JustinController> {
    let model = justin::model::<S>().ok()?;
    let collision = justin::collision::collision_model(&model).ok()?;
    let mut config = whole_body::controller_config::<S>().ok()?;
    let limits = whole_body::CLEAN_MUG.cartesian::<S>();
    for hand in config.cartesian.iter_mut() {
        hand.force_lower = limits.force_lower;
        hand.force_upper = limits.force_upper;
    }
    config.recovery.valid_cycles = 1;
    config.recovery.blend_s = 0.0;
    JustinController::try_new(model, collision, config, &whole_body::fig_6_3_hierarchy(ArmId::RIGHT)).ok()
}

/// One full control cycle; returns the sum of the output torques (a checksum).
#[no_mangle]
#[inline(never)]
pub fn wcet_step(controller: &mut JustinController, frame: &Frame) -> S {
    let out = controller.step(frame);
    out.torque.iter().fold(c(0.0), |a, t| a + *t)
}

/// Frames of the nominal sequence: the home pose with a small sinusoidal motion.
pub const NOMINAL_FRAMES: u32 = 24;
/// Adversarial configurations (see [`ADVERSARIAL`]).
pub const ADVERSARIAL_FRAMES: u32 = ADVERSARIAL.len() as u32;
/// First capacity frame (see [`capacity_commands`]).
pub const CAPACITY_START: u32 = NOMINAL_FRAMES + ADVERSARIAL_FRAMES + 2;
/// Capacity frames: every adversarial configuration and the home pose again, with both
/// collision fields widened by [`capacity_commands`].
pub const CAPACITY_FRAMES: u32 = ADVERSARIAL_FRAMES + 1;
/// First frame of the hierarchy transition (see [`transition_command`]): the capacity frames
/// again, with a task moving between the levels.
pub const TRANSITION_START: u32 = CAPACITY_START + CAPACITY_FRAMES;
/// Transition frames: every capacity configuration once more, while [`transition_command`]'s
/// hierarchy change is in progress (they are capacity frames: class `capacity`).
pub const TRANSITION_FRAMES: u32 = CAPACITY_FRAMES;
/// All frames: nominal, adversarial, one faulty (NaN) frame, one valid frame after it, the
/// capacity frames, then the capacity frames during a hierarchy transition.
pub const STEP_FRAMES: u32 = TRANSITION_START + TRANSITION_FRAMES;

/// Influence distance (m) of both collision fields in the capacity frames: larger than any
/// distance between two of Justin's volumes, so the broad phase skips no pair, all 214 pairs are
/// evaluated exactly in every capacity frame, and both fields fill their 32 rows and drop the
/// rest (the drop path over all 214 candidates).
pub const CAPACITY_FIELD_M: f64 = 10.0;

/// The planner commands applied before frame `k` (the capacity frames start by widening both
/// collision fields to [`CAPACITY_FIELD_M`]; the hierarchy, the tasks and every other parameter
/// stay those of [`new_controller`]).
pub fn capacity_commands(k: u32) -> Option<[Command<S>; 2]> {
    if k != CAPACITY_START {
        return None;
    }
    let config = whole_body::controller_config::<S>().ok()?;
    let widened = |field: Field| {
        let mut parameters = *config.collision.get(field.index())?;
        parameters.influence_distance = c(CAPACITY_FIELD_M);
        parameters.activation_zero = c(CAPACITY_FIELD_M);
        Some(Command::SetCollisionField { field, parameters })
    };
    Some([widened(Field::Strong)?, widened(Field::Weak)?])
}

/// The task that [`transition_command`] moves: the right arm's singularity avoidance (one row),
/// from level 1 to level 0.
pub const TRANSITION_TASK: TaskKind = TaskKind::SingularityAvoidance(ArmId::RIGHT);

/// The planner command applied before frame `k`: at [`TRANSITION_START`], the Fig. 6.3 hierarchy
/// with [`TRANSITION_TASK`] moved from level 1 to level 0. During the transition (`transition_s`,
/// 1 s, so through every transition frame) the task's rows are on both levels, scaled by the
/// cubic (4.68): one more row updates the level-0 projector and one more row is on the last
/// level, the most the row capacity allows at capacity (the capacity frames hold 127 of
/// `MAX_ROWS = 128` rows; moving a task of `k` rows needs `k` more, so only a one-row task can
/// move while both collision fields are full).
pub fn transition_command(k: u32) -> Option<Command<S>> {
    if k != TRANSITION_START {
        return None;
    }
    let mut command = Command::SetHierarchy(Default::default());
    if let Command::SetHierarchy(tasks) = &mut command {
        for spec in whole_body::fig_6_3_hierarchy(ArmId::RIGHT) {
            let level = if spec.kind == TRANSITION_TASK { 0 } else { spec.level };
            tasks.push(TaskSpec { level, ..spec }).ok()?;
        }
    }
    Some(command)
}

/// Applies the planner commands of frame `k` ([`capacity_commands`], [`transition_command`]);
/// `false` if one is refused.
pub fn prepare(controller: &mut JustinController, k: u32) -> bool {
    capacity_commands(k).is_none_or(|commands| commands.iter().all(|command| controller.apply(command).is_ok()))
        && transition_command(k).is_none_or(|command| controller.apply(&command).is_ok())
}

/// Which input class frame `k` belongs to.
pub fn frame_class(k: u32) -> &'static str {
    if k < NOMINAL_FRAMES {
        "nominal"
    } else if k < NOMINAL_FRAMES + ADVERSARIAL_FRAMES {
        "adversarial"
    } else if k == NOMINAL_FRAMES + ADVERSARIAL_FRAMES {
        "fault"
    } else if k < CAPACITY_START {
        "recovery"
    } else {
        "capacity"
    }
}

/// Adversarial upper-body configurations (q of coordinates 3..20, rad) and the velocity scale
/// (fraction of the joint speed limit, signs alternate): found by a seeded random search
/// (`wcet-host search`) maximising the pairs inside the strong (5 cm) and weak (15 cm) collision
/// fields, with joints at their end stops, the torso bent to its workspace boundary and an arm
/// stretched near its singularity; see BENCHMARKS.md.
pub const ADVERSARIAL: &[[f64; U]] = &[
    // Found by `wcet-host search 3000` (score = 3·strong + weak + joints near a stop):
    // strong 29, weak 44, joints near a stop 6
    [
        3.424, 0.326, 1.018, -0.505, 1.618, -1.034, 1.376, 0.960, -0.532, -2.084, 1.289, 0.706, 2.957, -2.084, -2.914,
        -1.335, 1.949,
    ],
    // strong 27, weak 46, 5
    [
        -2.419, 0.336, 1.649, 1.737, -0.668, 2.702, 1.892, -0.391, 1.910, 2.018, -0.839, 2.013, 2.604, -2.058, -1.073,
        0.114, -0.004,
    ],
    // strong 26, weak 59, 7
    [
        3.439, 0.896, 2.306, -0.505, 1.355, 0.199, -2.084, 2.957, -1.165, -2.012, 0.881, 1.279, -2.896, -1.886, 2.679,
        -2.055, 1.788,
    ],
    // strong 26, weak 57, 6
    [
        -1.233, 1.053, 1.735, 2.954, 1.957, -1.644, -1.189, -2.066, 1.965, 2.084, 2.957, 1.988, -2.311, -0.016, -1.553,
        -1.784, -0.018,
    ],
    // strong 26, weak 36, 5
    [
        3.481, -1.561, 0.838, 2.782, -2.084, 0.500, 1.239, -2.267, -2.084, 1.532, -2.626, -0.775, -2.666, 1.332,
        -1.527, 0.768, -1.232,
    ],
    // strong 24, weak 39, 7
    [
        -2.334, -1.272, 1.715, -2.863, 1.972, -1.185, -2.084, -1.285, -0.468, -1.553, 2.600, -2.084, -0.872, -2.084,
        -2.789, 0.406, -1.134,
    ],
    // Hand-made: torso bent to its workspace boundary (q_t2, q_t3 at their stops), right arm
    // stretched (elbow at 0.02 rad: near-singular), left arm at home.
    [0.0, 1.55, 2.33, 0.0, 1.0, 0.0, 0.02, 0.0, 0.0, 0.0, 0.5, 0.5, 0.5, 1.5, -0.5, -0.5, -0.2],
    // Hand-made: torso at the other stops, both arms stretched down (near-singular), wrists at stops.
    [-2.42, -1.55, 0.02, 0.0, 0.02, 0.0, 0.02, 0.0, 2.07, 2.07, 0.0, 0.02, 0.0, 0.02, 0.0, -2.07, -2.07],
];

fn frame(cycle: u64, q: &SVector<S, N>, v: &SVector<S, N>) -> Frame {
    let upper = |x: &SVector<S, N>| core::array::from_fn(|i| x[i + justin::BASE_DOF]);
    Frame {
        joints: JointSample { position: upper(q), velocity: upper(v), torque: [c(0.0); U], cycle },
        platform: PlatformSample {
            pose: [q[0], q[1], q[2]],
            velocity: [v[0], v[1], v[2]],
            leg_lengths: [c(justin::LEG_LENGTH_NOMINAL); 4],
            cycle,
        },
    }
}

/// Frame `k` of the measured sequence (cycle counter `k + 1`), for `k < STEP_FRAMES`.
pub fn step_frame(k: u32, speed: &SVector<S, N>) -> Frame {
    let cycle = u64::from(k) + 1;
    let home = justin::home_configuration::<S>();
    if k < NOMINAL_FRAMES {
        // 0.05 rad amplitude, 0.5 Hz, a phase per joint; the platform drifts at 0.1 m/s.
        let t = c(f64::from(k) * 1e-3);
        let w = c(core::f64::consts::PI);
        let q = home + SVector::<S, N>::from_fn(|i, _| c(0.05) * ComplexField::sin(w * t + c(i as f64)));
        let mut v = SVector::<S, N>::from_fn(|i, _| c(0.05) * w * ComplexField::cos(w * t + c(i as f64)));
        v[0] = c(0.1);
        return frame(cycle, &q, &v);
    }
    // Capacity and transition frames repeat the adversarial configurations (then the home pose).
    let a = if k >= TRANSITION_START {
        k - TRANSITION_START
    } else if k >= CAPACITY_START {
        k - CAPACITY_START
    } else {
        k - NOMINAL_FRAMES
    };
    if k >= CAPACITY_START && a == ADVERSARIAL_FRAMES {
        return frame(cycle, &home, &SVector::zeros());
    }
    let Some(upper) = ADVERSARIAL.get(a as usize) else {
        let mut f = frame(cycle, &home, &SVector::zeros());
        if a == ADVERSARIAL_FRAMES {
            f.joints.position[4] = S::NAN;
        }
        return f;
    };
    let mut q = home;
    for (i, x) in upper.iter().enumerate() {
        q[i + justin::BASE_DOF] = c(*x);
    }
    // Nonzero velocities: 60 % of the joint speed limit, alternating signs; platform moving.
    let v = SVector::<S, N>::from_fn(|i, _| {
        let sign = if (i + a as usize).is_multiple_of(2) { c(1.0) } else { c(-1.0) };
        if i < justin::BASE_DOF {
            sign * c(0.3)
        } else {
            sign * c(0.6) * speed[i]
        }
    });
    frame(cycle, &q, &v)
}
