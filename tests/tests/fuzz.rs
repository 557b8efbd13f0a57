//! Fuzzing the whole-body controller (issue 9): random sensor frames (near the home pose,
//! extreme, NaN, ±inf, random cycle counters) interleaved with random planner input (random
//! byte strings through `apply_bytes`, random — mostly invalid — `Command`s through `apply`,
//! and their encodings). Whatever arrives, `step` never panics and its output is always
//! guarded: every torque finite and within its effort limit, the platform velocity finite and
//! within its limit, the leg rates within theirs, the mode `Normal` exactly when no fault is
//! reported.
//!
//! The number of proptest cases comes from `FUZZ_CASES` (default [`DEFAULT_CASES`], ≈ 20 s in
//! the test profile); each case is a fresh controller and [`STEPS`] cycles. The long local run:
//! `FUZZ_CASES=200000 cargo test --release -p thesis-tests --test fuzz` (≥ 10 minutes).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    reason = "test code: a failure is a test failure"
)]

use fixtures::justin::{self, collision as jc, whole_body};
use hal::{JointSample, PlatformSample};
use kernel::controller::config::{
    ArmId, CartesianParameters, CollisionFieldParameters, Field, JointGroup, TaskKind, TaskSpec,
};
use kernel::controller::messages::{encode_command, Command, Pose};
use kernel::controller::{SensorFrame, PLATFORM_DOF};
use nalgebra::{convert, RealField};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use std::sync::atomic::{AtomicU64, Ordering};

const U: usize = justin::UPPER_DOF;
/// Cases when `FUZZ_CASES` is not set.
const DEFAULT_CASES: u32 = 2000;
/// Control cycles per case.
const STEPS: usize = 48;

/// Cycles served normally, cycles with a fault, commands accepted, commands rejected.
static COUNTS: [AtomicU64; 4] = [AtomicU64::new(0), AtomicU64::new(0), AtomicU64::new(0), AtomicU64::new(0)];

fn count(slot: usize) {
    if let Some(c) = COUNTS.get(slot) {
        c.fetch_add(1, Ordering::Relaxed);
    }
}

fn tally<E>(result: Result<(), E>) {
    count(if result.is_ok() { 2 } else { 3 });
}

use fixtures::justin::whole_body::JustinController as Justin;

fn cases() -> u32 {
    std::env::var("FUZZ_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(DEFAULT_CASES)
}

/// A sensor value: mostly plausible, sometimes extreme or not finite.
fn value() -> impl Strategy<Value = f64> + Clone {
    prop_oneof![
        6 => -1.0..1.0_f64,
        1 => prop_oneof![
            Just(f64::NAN),
            Just(f64::INFINITY),
            Just(f64::NEG_INFINITY),
            Just(f64::MAX),
            Just(-f64::MAX),
            Just(1e30),
            Just(-1e30),
            Just(f64::MIN_POSITIVE),
            Just(0.0),
        ],
        1 => any::<f64>(),
        1 => -1e6..1e6_f64,
    ]
}

/// How a frame's cycle counters relate to the last one.
#[derive(Clone, Copy, Debug)]
enum Cycle {
    Next,
    Repeat,
    Back(u64),
    Gap(u64),
    Random(u64),
    Split(u64),
}

fn cycle() -> impl Strategy<Value = Cycle> {
    prop_oneof![
        12 => Just(Cycle::Next),
        1 => Just(Cycle::Repeat),
        1 => (1..1000_u64).prop_map(Cycle::Back),
        1 => (2..20_u64).prop_map(Cycle::Gap),
        1 => any::<u64>().prop_map(Cycle::Random),
        1 => (1..5_u64).prop_map(Cycle::Split),
    ]
}

/// A frame: every value the home state plus `scale ×` a deviation; `overrides` replace single
/// values (signal, index, value).
#[derive(Clone, Debug)]
struct FrameSpec {
    deviation: Vec<f64>,
    scale: f64,
    overrides: Vec<(usize, usize, f64)>,
    cycle: Cycle,
}

const VALUES: usize = 3 * U + 3 + 3 + 4;

fn frame_spec() -> impl Strategy<Value = FrameSpec> {
    (
        prop::collection::vec(-1.0..1.0_f64, VALUES),
        prop_oneof![8 => Just(0.02), 2 => Just(0.3), 1 => Just(3.0), 1 => Just(1e3)],
        prop_oneof![3 => Just(Vec::new()), 1 => prop::collection::vec((0..6_usize, 0..U, value()), 1..4)],
        cycle(),
    )
        .prop_map(|(deviation, scale, overrides, cycle)| FrameSpec { deviation, scale, overrides, cycle })
}

/// Any joint group.
fn joint_group() -> impl Strategy<Value = JointGroup> {
    prop::sample::select(JointGroup::all::<2>().to_vec())
}

fn task_kind() -> impl Strategy<Value = TaskKind> {
    let hand = prop_oneof![Just(ArmId::RIGHT), Just(ArmId::LEFT)];
    (0..8_u8, hand, joint_group()).prop_map(|(k, hand, group)| match k {
        0 => TaskKind::CartesianImpedance(hand),
        1 => TaskKind::CollisionAvoidance(if hand == ArmId::RIGHT { Field::Strong } else { Field::Weak }),
        2 => TaskKind::SingularityAvoidance(hand),
        3 => TaskKind::EndStops,
        4 => TaskKind::TorsoWorkspace,
        5 => TaskKind::JointImpedance(group),
        _ => TaskKind::JointDamping(group),
    })
}

/// A planner parameter: mostly in a plausible range, sometimes negative or not finite.
fn parameter(max: f64) -> impl Strategy<Value = f64> + Clone {
    prop_oneof![6 => 0.0..max, 1 => value(), 1 => Just(f64::INFINITY), 1 => -max..0.0]
}

fn array<const K: usize>(s: impl Strategy<Value = f64> + Clone) -> impl Strategy<Value = [f64; K]> + Clone {
    prop::collection::vec(s, K).prop_map(|v| core::array::from_fn(|i| v[i]))
}

fn hand() -> impl Strategy<Value = ArmId> {
    prop_oneof![Just(ArmId::RIGHT), Just(ArmId::LEFT)]
}

/// Random commands, valid and invalid. Positions are offsets from the home TCPs (added when
/// applied), so that some goals are reachable.
fn command() -> impl Strategy<Value = Command<f64>> {
    let pose = (array::<3>(prop_oneof![4 => -0.3..0.3_f64, 1 => value()]), array::<4>(value()), any::<bool>())
        .prop_map(|(position, orientation, unit)| {
            let norm = orientation.iter().map(|x| x * x).sum::<f64>().sqrt();
            let orientation =
                if unit && norm.is_finite() && norm > 1e-6 { orientation.map(|x| x / norm) } else { orientation };
            Pose { position, orientation }
        });
    let cartesian = (
        array::<3>(parameter(2000.0)),
        array::<3>(parameter(300.0)),
        parameter(2.0),
        array::<6>(value()),
        array::<6>(value()),
    )
        .prop_map(|(t, r, d, lower, upper)| CartesianParameters {
            translational_stiffness: t,
            rotational_stiffness: r,
            damping_ratio: d,
            force_lower: lower.map(|x| -x.abs() * 100.0),
            force_upper: upper.map(|x| x * 100.0),
        });
    let field = (parameter(200.0), parameter(0.3), parameter(2.0), parameter(0.1), parameter(0.3)).prop_map(
        |(f, d, xi, a0, a1)| CollisionFieldParameters {
            max_force: f,
            influence_distance: d,
            damping_ratio: xi,
            activation_full: a0,
            activation_zero: a1,
        },
    );
    let group = joint_group();
    prop_oneof![
        prop::collection::vec((task_kind(), prop_oneof![8 => 0..4_u8, 1 => any::<u8>()]), 0..14).prop_map(|specs| {
            Command::SetHierarchy(specs.into_iter().map(|(kind, level)| TaskSpec { kind, level }).collect())
        }),
        (hand(), cartesian).prop_map(|(hand, parameters)| Command::SetCartesian { hand, parameters }),
        (any::<bool>(), field).prop_map(|(strong, parameters)| Command::SetCollisionField {
            field: if strong { Field::Strong } else { Field::Weak },
            parameters
        }),
        (hand(), pose.clone(), parameter(3.0)).prop_map(|(hand, pose, duration_s)| Command::TcpGoal {
            hand,
            pose,
            duration_s
        }),
        (hand(), pose, array::<3>(value()), array::<3>(value())).prop_map(
            |(hand, pose, linear_velocity, angular_velocity)| {
                Command::TcpSample { hand, pose, linear_velocity, angular_velocity }
            }
        ),
        (group, prop::collection::vec(prop_oneof![4 => -0.3..0.3_f64, 1 => value()], 0..20), parameter(3.0)).prop_map(
            |(group, values, duration_s)| Command::JointGoal {
                group,
                values: values.into_iter().collect(),
                duration_s
            }
        ),
    ]
}

/// Planner input between two cycles.
#[derive(Clone, Debug)]
enum Input {
    Nothing,
    Bytes(Vec<u8>),
    Command(Command<f64>),
    Encoded(Command<f64>),
}

fn input() -> impl Strategy<Value = Input> {
    prop_oneof![
        10 => Just(Input::Nothing),
        1 => prop::collection::vec(any::<u8>(), 0..96).prop_map(Input::Bytes),
        2 => command().prop_map(Input::Command),
        1 => command().prop_map(Input::Encoded),
    ]
}

fn case() -> impl Strategy<Value = Vec<(FrameSpec, Input)>> {
    prop::collection::vec((frame_spec(), input()), STEPS)
}

/// Floating-point type under test.
trait Float: RealField + Copy + serde::de::DeserializeOwned + serde::Serialize {
    /// The command in this type (`None` if it does not convert).
    fn command(command: &Command<f64>) -> Option<Command<Self>>;
}

impl Float for f64 {
    fn command(command: &Command<f64>) -> Option<Command<Self>> {
        Some(command.clone())
    }
}

impl Float for f32 {
    fn command(command: &Command<f64>) -> Option<Command<Self>> {
        // Through JSON: commands with non-finite values (written as `null`) do not convert.
        serde_json::from_str(&serde_json::to_string(command).ok()?).ok()
    }
}

fn controller<T: Float>() -> Box<Justin<T>> {
    let model = justin::model::<T>().unwrap();
    let collision = jc::collision_model(&model).unwrap();
    let config = whole_body::controller_config::<T>().unwrap();
    Box::new(Justin::<T>::try_new(model, collision, config, &whole_body::fig_6_3_hierarchy(ArmId::RIGHT)).unwrap())
}

fn build_frame<T: Float>(spec: &FrameSpec, last: &mut u64) -> SensorFrame<T, U> {
    let home = justin::home_configuration::<f64>();
    let d = |i: usize| spec.deviation[i] * spec.scale;
    let mut position: [f64; U] = core::array::from_fn(|i| home[i + PLATFORM_DOF] + d(i));
    let mut velocity: [f64; U] = core::array::from_fn(|i| d(U + i));
    let mut torque: [f64; U] = core::array::from_fn(|i| 20.0 * d(2 * U + i));
    let mut pose: [f64; 3] = core::array::from_fn(|i| home[i] + d(3 * U + i));
    let mut base: [f64; 3] = core::array::from_fn(|i| d(3 * U + 3 + i));
    let mut legs: [f64; 4] = core::array::from_fn(|i| justin::LEG_LENGTH_NOMINAL + 0.05 * d(3 * U + 6 + i));
    for (signal, index, value) in &spec.overrides {
        let slot = match signal {
            0 => position.get_mut(*index),
            1 => velocity.get_mut(*index),
            2 => torque.get_mut(*index),
            3 => pose.get_mut(index % 3),
            4 => base.get_mut(index % 3),
            _ => legs.get_mut(index % 4),
        };
        if let Some(slot) = slot {
            *slot = *value;
        }
    }
    let (joints, platform) = match spec.cycle {
        Cycle::Next => (*last + 1, *last + 1),
        Cycle::Repeat => (*last, *last),
        Cycle::Back(k) => (last.saturating_sub(k), last.saturating_sub(k)),
        Cycle::Gap(k) => (*last + k, *last + k),
        Cycle::Random(c) => (c, c),
        Cycle::Split(k) => (*last + 1, *last + 1 + k),
    };
    // Random counters may jump to the end of the range; keep room for the following cycles.
    *last = (*last).max(joints).min(u64::MAX / 2);
    let t = |a: &[f64]| -> Vec<T> { a.iter().map(|x| convert::<f64, T>(*x)).collect() };
    let arr = |a: &[f64]| -> [T; U] { core::array::from_fn(|i| t(a)[i]) };
    SensorFrame {
        joints: JointSample { position: arr(&position), velocity: arr(&velocity), torque: arr(&torque), cycle: joints },
        platform: PlatformSample {
            pose: pose.map(convert),
            velocity: base.map(convert),
            leg_lengths: legs.map(convert),
            cycle: platform,
        },
    }
}

/// Shifts a command's TCP positions from offsets to world positions near the home TCPs.
fn located(command: &Command<f64>) -> Command<f64> {
    let tcp = |hand: ArmId| if hand == ArmId::RIGHT { [0.6, -0.3, 1.0] } else { [0.6, 0.3, 1.0] };
    let mut command = command.clone();
    match &mut command {
        Command::TcpGoal { hand, pose, .. } | Command::TcpSample { hand, pose, .. } => {
            for (p, o) in pose.position.iter_mut().zip(tcp(*hand)) {
                *p += o;
            }
        }
        _ => {}
    }
    command
}

fn check<T: Float>(controller: &Justin<T>) -> Result<(), TestCaseError> {
    thesis_tests::contract::check_output(controller).map_err(TestCaseError::fail)
}

fn run<T: Float>(steps: &[(FrameSpec, Input)]) -> Result<(), TestCaseError> {
    let mut controller = controller::<T>();
    let mut last = 0;
    let mut buffer = [0_u8; 1024];
    for (spec, input) in steps {
        let frame = build_frame::<T>(spec, &mut last);
        controller.step(&frame);
        check(&controller)?;
        count(usize::from(controller.telemetry().fault.is_some()));
        match input {
            Input::Nothing => {}
            Input::Bytes(bytes) => tally(controller.apply_bytes(bytes)),
            Input::Command(command) => {
                if let Some(command) = T::command(&located(command)) {
                    tally(controller.apply(&command));
                }
            }
            Input::Encoded(command) => {
                if let Some(command) = T::command(&located(command)) {
                    if let Ok(bytes) = encode_command(&command, &mut buffer) {
                        let bytes = bytes.to_vec();
                        tally(controller.apply_bytes(&bytes));
                    }
                }
            }
        }
    }
    Ok(())
}

fn fuzz<T: Float>(cases: u32) {
    let config = Config { cases, max_shrink_iters: 200, failure_persistence: None, ..Config::default() };
    let mut runner = TestRunner::new(config);
    runner.run(&case(), |steps| run::<T>(&steps)).unwrap();
    let c = |i: usize| COUNTS.get(i).map_or(0, |c| c.load(Ordering::Relaxed));
    eprintln!(
        "fuzz ({cases} cases): {} normal cycles, {} faulty cycles, {} commands accepted, {} rejected",
        c(0),
        c(1),
        c(2),
        c(3)
    );
}

#[test]
fn random_frames_and_commands_never_break_the_guards_in_f64() {
    fuzz::<f64>(cases());
}

#[test]
fn random_frames_and_commands_never_break_the_guards_in_f32() {
    fuzz::<f32>(cases().div_ceil(4));
}
