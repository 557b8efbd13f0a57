//! The generic rig: an imported robot (`--robot panda|tiago_dual`, `fixtures::robots`) simulated
//! by [`Simulator`] under the kernel's whole-body controller for its layout (issue 15, item 4).
//!
//! The layout is a fixed base (`U = N`, every platform axis absent), one arm per TCP of the
//! import (`A = TCPS.len()`), and the robot's torso coordinates if it has any (TIAGo++'s lift).
//! The hierarchy ([`hierarchy`]): end stops over the Cartesian impedance of every arm with the
//! strong self-collision avoidance (Fig. 6.3's top level) over each arm's singularity avoidance
//! with the weak collision avoidance (Fig. 6.3's null-space level) over the joint damping of the
//! upper body. The collision model is the robot's imported one
//! (`fixtures::robots::<name>::collision`, from `<name>.collision`) in the capacities
//! [`COLLISION_VOLUMES`] and [`COLLISION_PAIRS`] of the largest robot; the two fields are the
//! robot's `config.toml` (`[collision.strong]`, `[collision.weak]`).
//!
//! Every gain follows from the model by one rule, [`gains`]: the Cartesian stiffness per arm is
//! `K = λ ω_c²` with `λ` the largest eigenvalue of the translational reflected inertia
//! `(J_p M⁻¹ J_pᵀ)⁻¹` at the home posture and the rotational one `λ_r ω_c²` likewise, so the
//! heaviest direction has the natural frequency `ω_c` ([`CARTESIAN_FREQUENCY_RAD_S`]); the
//! kernel damps it with the thesis' `ξ = 0.7` (double diagonalisation). The joint damping is
//! `D_i = 2 ξ ω_j M_ii` and the end stops `K = ω_j² max M_ii`, `D = 2 ξ ω_j max M_ii`
//! ([`JOINT_FREQUENCY_RAD_S`]). A robot's configuration file will replace this function.
//!
//! [`GenericRig::cycle`] reads the sensors through the `hal` traits, steps the controller in the
//! run's scalar (`f64` or `f32`: the frame narrowed, the torque widened) and writes the torques.

pub mod posture_push;
pub mod reach;
pub mod self_collision;

use fixtures::collision_table::{self, VolumeSpec};
use fixtures::fixed_base::{self, FixedBaseGains};
use fixtures::robots::{panda, tiago_dual};
use hal::{JointTorqueInterface, PlatformVelocityInterface};
use kernel::controller::config::*;
use kernel::controller::faults::SafeOutput;
use kernel::controller::messages::{Command, Pose};
use kernel::controller::{Controller, SensorFrame};
use kernel::dynamics::{crba, forward_kinematics, frame_jacobian};
use kernel::model::{Data, FrameId, Model};
use kernel::platform::{PlatformAxis, PlatformLayout};
use kernel::tasks::collision::VolumeId;
use nalgebra::{convert, RealField, SMatrix, SVector, Vector3};

use crate::output::TimeSeries;
use crate::scalar::Scalar;
use crate::scenarios::{Outcome, RunOptions};
use crate::sim::{CycleInfo, JointStops, Physics, SimConfig, SimError, Simulator, StepReport};

/// The imported robots a generic scenario runs on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum RobotName {
    /// The Franka Panda (`fixtures::robots::panda`): fixed base, one 7-DOF arm.
    #[default]
    Panda,
    /// TIAGo++ (`fixtures::robots::tiago_dual`): fixed base, the torso lift and two 7-DOF arms.
    #[value(name = "tiago_dual")]
    TiagoDual,
}

impl RobotName {
    /// The option's value on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Panda => "panda",
            Self::TiagoDual => "tiago_dual",
        }
    }
}

/// Damping ratio of every gain rule (the thesis' `ξ = 0.7`, Ch. 6).
pub const DAMPING_RATIO: f64 = 0.7;
/// Natural frequency of the Cartesian impedance along the heaviest direction (rad/s): 1.5 Hz.
pub const CARTESIAN_FREQUENCY_RAD_S: f64 = 3.0 * core::f64::consts::PI;
/// Natural frequency of the joint damping and the end stops (rad/s): 3 Hz.
pub const JOINT_FREQUENCY_RAD_S: f64 = 6.0 * core::f64::consts::PI;

/// What the generic rig needs of an imported robot besides its model.
#[derive(Clone, Copy, Debug)]
pub struct RobotSpec<const N: usize, const A: usize> {
    /// The robot's name (`--robot`).
    pub name: &'static str,
    /// The TCP frame of each arm.
    pub tcps: [FrameId; A],
    /// The coordinates of each arm.
    pub arms: [[bool; N]; A],
    /// The torso coordinates, if the robot has a torso.
    pub torso: Option<[bool; N]>,
    /// The home posture (rad, m): inside the limits, away from the end-stop margins.
    pub home: [f64; N],
    /// A mid-chain frame of arm 0 (the elbow) where `posture_push` pushes.
    pub elbow: FrameId,
    /// URDF joint of each coordinate.
    pub joint_names: [&'static str; N],
    /// The collision volumes (`fixtures::robots::<name>::collision::VOLUME_SPECS`).
    pub collision_volumes: &'static [VolumeSpec],
    /// The pairs the collision file excludes (`…::collision::EXCLUDED`).
    pub collision_excluded: &'static [(VolumeId, VolumeId)],
    /// The strong and the weak collision field (the robot's `config.toml`).
    pub collision_fields: [CollisionFieldParameters<f64>; 2],
}

/// Volume capacity of the rig's collision model: the largest imported robot's.
pub const COLLISION_VOLUMES: usize = larger(panda::collision::VOLUMES, tiago_dual::collision::VOLUMES);
/// Pair capacity of the rig's collision model: the largest imported robot's.
pub const COLLISION_PAIRS: usize = larger(panda::collision::PAIRS, tiago_dual::collision::PAIRS);

const fn larger(a: usize, b: usize) -> usize {
    if a > b {
        a
    } else {
        b
    }
}

/// A collision field from the module of a compiled `config.toml` table (`[collision.strong]`).
macro_rules! collision_field {
    ($($table:ident)::+) => {
        CollisionFieldParameters {
            max_force: $($table)::+::MAX_FORCE,
            influence_distance: $($table)::+::INFLUENCE_DISTANCE,
            damping_ratio: $($table)::+::DAMPING_RATIO,
            activation_full: $($table)::+::ACTIVATION_FULL,
            activation_zero: $($table)::+::ACTIVATION_ZERO,
        }
    };
}

/// The Panda: one arm of all seven joints; the home posture of `tests/src/fixed_base.rs`.
pub const PANDA: RobotSpec<{ panda::N }, 1> = RobotSpec {
    name: "panda",
    tcps: panda::TCPS,
    arms: [[true; panda::N]],
    torso: None,
    home: [0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8],
    elbow: panda::PANDA_LINK4,
    joint_names: panda::JOINT_NAMES,
    collision_volumes: &panda::collision::VOLUME_SPECS,
    collision_excluded: &panda::collision::EXCLUDED,
    collision_fields: [
        collision_field!(panda::config::collision::strong),
        collision_field!(panda::config::collision::weak),
    ],
};

/// TIAGo++: the lift (coordinate 0) as the torso, the left arm (1–7, TCP 0) and the right arm
/// (8–14, TCP 1); home: the lift at 0.15 m, each arm's shoulder forward and out, elbow bent
/// 1.5 rad.
pub const TIAGO_DUAL: RobotSpec<{ tiago_dual::N }, 2> = RobotSpec {
    name: "tiago_dual",
    tcps: tiago_dual::TCPS,
    arms: [[O, I, I, I, I, I, I, I, O, O, O, O, O, O, O], [O, O, O, O, O, O, O, O, I, I, I, I, I, I, I]],
    torso: Some([I, O, O, O, O, O, O, O, O, O, O, O, O, O, O]),
    home: [0.15, 0.4, 0.3, 0.0, 1.5, 0.0, 0.5, 0.0, 0.4, 0.3, 0.0, 1.5, 0.0, 0.5, 0.0],
    elbow: tiago_dual::ARM_LEFT_4_LINK,
    joint_names: tiago_dual::JOINT_NAMES,
    collision_volumes: &tiago_dual::collision::VOLUME_SPECS,
    collision_excluded: &tiago_dual::collision::EXCLUDED,
    collision_fields: [
        collision_field!(tiago_dual::config::collision::strong),
        collision_field!(tiago_dual::config::collision::weak),
    ],
};

/// A coordinate in a mask (`I`) or not (`O`), for the masks above.
const I: bool = true;
const O: bool = false;

/// A generic scenario: one function over the robot's sizes and the controller's scalar.
pub trait Scenario {
    /// Runs the scenario on `spec` with the controller in `T` built on `model`.
    fn simulate<T, const N: usize, const B: usize, const F: usize, const A: usize>(
        spec: &RobotSpec<N, A>,
        model: Model<T, N, B, F>,
        plant: Model<f64, N, B, F>,
        options: &RunOptions,
    ) -> Result<Outcome, String>
    where
        T: RealField + Copy + Into<f64>;
}

/// Runs scenario `S` on the robot and in the scalar the options name.
pub fn simulate<S: Scenario>(options: &RunOptions) -> Result<Outcome, String> {
    let error = |e: kernel::model::ModelError| format!("model: {e}");
    match (options.robot.unwrap_or_default(), options.scalar) {
        (RobotName::Panda, Scalar::F64) => {
            S::simulate(&PANDA, panda::model::<f64>().map_err(error)?, panda::model().map_err(error)?, options)
        }
        (RobotName::Panda, Scalar::F32) => {
            S::simulate(&PANDA, panda::model::<f32>().map_err(error)?, panda::model().map_err(error)?, options)
        }
        (RobotName::TiagoDual, Scalar::F64) => S::simulate(
            &TIAGO_DUAL,
            tiago_dual::model::<f64>().map_err(error)?,
            tiago_dual::model().map_err(error)?,
            options,
        ),
        (RobotName::TiagoDual, Scalar::F32) => S::simulate(
            &TIAGO_DUAL,
            tiago_dual::model::<f32>().map_err(error)?,
            tiago_dual::model().map_err(error)?,
            options,
        ),
    }
}

fn c<T: RealField>(x: f64) -> T {
    convert(x)
}

/// The gains of [`gains`], in `f64`.
#[derive(Clone, Debug, PartialEq)]
pub struct Gains<const N: usize, const A: usize> {
    /// Isotropic translational stiffness per arm (N/m).
    pub translational_stiffness: [f64; A],
    /// Isotropic rotational stiffness per arm (Nm/rad).
    pub rotational_stiffness: [f64; A],
    /// Joint damping per coordinate (Nms/rad or Ns/m).
    pub joint_damping: [f64; N],
    /// End-stop stiffness (Nm/rad) and damping (Nms/rad), one for every joint.
    pub end_stop: (f64, f64),
}

/// The gain rule (module docs) from the model at the robot's home posture.
pub fn gains<const N: usize, const B: usize, const F: usize, const A: usize>(
    spec: &RobotSpec<N, A>,
    model: &Model<f64, N, B, F>,
) -> Result<Gains<N, A>, String> {
    let mut data = Data::new(model);
    let q = SVector::from(spec.home);
    forward_kinematics(model, &mut data, &q, &SVector::zeros()).map_err(|e| format!("home posture: {e}"))?;
    let mass = *crba(model, &mut data);
    let inverse = mass.try_inverse().ok_or("the mass matrix at the home posture is singular")?;
    let mut translational_stiffness = [0.0; A];
    let mut rotational_stiffness = [0.0; A];
    for (arm, tcp) in spec.tcps.iter().enumerate() {
        let mut jacobian = SMatrix::<f64, 6, N>::zeros();
        frame_jacobian(model, &data, *tcp, &mut jacobian).map_err(|e| format!("TCP Jacobian: {e}"))?;
        let heaviest = |rows: usize| -> Result<f64, String> {
            let j = jacobian.fixed_rows::<3>(rows);
            let reflected = (j * inverse * j.transpose()).try_inverse().ok_or("the TCP is singular at home")?;
            Ok(reflected.symmetric_eigenvalues().max())
        };
        let w2 = CARTESIAN_FREQUENCY_RAD_S * CARTESIAN_FREQUENCY_RAD_S;
        if let (Some(t), Some(r)) = (translational_stiffness.get_mut(arm), rotational_stiffness.get_mut(arm)) {
            *t = heaviest(0)? * w2;
            *r = heaviest(3)? * w2;
        }
    }
    let joint_damping = mass.diagonal().map(|m| 2.0 * DAMPING_RATIO * JOINT_FREQUENCY_RAD_S * m).into();
    let heaviest_joint = mass.diagonal().max();
    let end_stop = (
        JOINT_FREQUENCY_RAD_S * JOINT_FREQUENCY_RAD_S * heaviest_joint,
        2.0 * DAMPING_RATIO * JOINT_FREQUENCY_RAD_S * heaviest_joint,
    );
    Ok(Gains { translational_stiffness, rotational_stiffness, joint_damping, end_stop })
}

/// The hierarchy: end stops; the Cartesian impedance of every arm with the strong collision
/// avoidance; each arm's singularity avoidance with the weak collision avoidance; the upper
/// body's joint damping (the collision tasks at the levels of Fig. 6.3).
pub fn hierarchy<const A: usize>() -> Vec<TaskSpec> {
    let arms = ArmId::all::<A>();
    let mut tasks = vec![TaskSpec { kind: TaskKind::EndStops, level: 0 }];
    tasks.push(TaskSpec { kind: TaskKind::CollisionAvoidance(Field::Strong), level: 1 });
    tasks.extend(arms.iter().map(|arm| TaskSpec { kind: TaskKind::CartesianImpedance(*arm), level: 1 }));
    tasks.push(TaskSpec { kind: TaskKind::CollisionAvoidance(Field::Weak), level: 2 });
    tasks.extend(arms.iter().map(|arm| TaskSpec { kind: TaskKind::SingularityAvoidance(*arm), level: 2 }));
    tasks.push(TaskSpec { kind: TaskKind::JointDamping(JointGroup::UpperBody), level: 3 });
    tasks
}

/// The controller's configuration for `spec` with `gains`, in `T`: a fixed base (the platform
/// parameters are valid but drive nothing), no force limit, the Ch. 6 guards.
fn config<T: RealField + Copy, const N: usize, const A: usize>(
    spec: &RobotSpec<N, A>,
    gains: &Gains<N, A>,
) -> Result<ControllerConfig<T, N, A>, String> {
    let cartesian = core::array::from_fn(|arm| CartesianParameters {
        translational_stiffness: [c(gains.translational_stiffness.get(arm).copied().unwrap_or(0.0)); 3],
        rotational_stiffness: [c(gains.rotational_stiffness.get(arm).copied().unwrap_or(0.0)); 3],
        damping_ratio: c(DAMPING_RATIO),
        force_lower: [c(f64::NEG_INFINITY); 6],
        force_upper: [c(f64::INFINITY); 6],
    });
    let field = |f: &CollisionFieldParameters<f64>| CollisionFieldParameters {
        max_force: c(f.max_force),
        influence_distance: c(f.influence_distance),
        damping_ratio: c(f.damping_ratio),
        activation_full: c(f.activation_full),
        activation_zero: c(f.activation_zero),
    };
    let layout = RobotLayout {
        tcp: spec.tcps,
        platform: PlatformLayout::try_new::<N>([PlatformAxis::Absent; 3]).map_err(|e| format!("layout: {e}"))?,
        torso: spec.torso,
        arms: spec.arms,
    };
    Ok(fixed_base::controller_config(
        layout,
        FixedBaseGains {
            period_s: c(crate::sim::CONTROL_PERIOD_S),
            cartesian,
            collision: spec.collision_fields.each_ref().map(field),
            end_stops: EndStopParameters {
                margin: c(0.1),
                stiffness: c(gains.end_stop.0),
                damping: c(gains.end_stop.1),
            },
            joint_stiffness: SVector::zeros(),
            joint_damping: SVector::from(gains.joint_damping.map(c)),
            force_limit: false,
        },
    ))
}

/// The controller of an imported robot: `U = N` (fixed base), the rig's collision capacities,
/// `A` arms.
pub type GenericController<T, const N: usize, const B: usize, const F: usize, const A: usize> =
    Controller<T, N, B, F, N, COLLISION_VOLUMES, COLLISION_PAIRS, A>;

/// The simulated imported robot and its controller, wired.
pub struct GenericRig<T: RealField + Copy, const N: usize, const B: usize, const F: usize, const A: usize> {
    /// The simulated robot (always `f64`).
    pub sim: Simulator<N, B, F, N>,
    /// The controller in the run's scalar; boxed: it is large.
    pub controller: Box<GenericController<T, N, B, F, A>>,
    /// The gains of [`gains`].
    pub gains: Gains<N, A>,
    /// Cycles with a safe output instead of the whole-body torque.
    pub faulty_cycles: u64,
    /// Cycles with a non-finite torque or TCP error.
    pub non_finite_cycles: u64,
}

impl<T, const N: usize, const B: usize, const F: usize, const A: usize> GenericRig<T, N, B, F, A>
where
    T: RealField + Copy + Into<f64>,
{
    /// The robot at its home posture at rest on the plant of `options`, the controller on `model`
    /// with the rig's [`hierarchy`].
    pub fn new(
        spec: &RobotSpec<N, A>,
        model: Model<T, N, B, F>,
        plant: Model<f64, N, B, F>,
        options: &RunOptions,
    ) -> Result<Self, String> {
        Self::with_hierarchy(spec, model, plant, options, &hierarchy::<A>())
    }

    /// [`Self::new`] with the hierarchy `tasks` instead of the rig's.
    pub fn with_hierarchy(
        spec: &RobotSpec<N, A>,
        model: Model<T, N, B, F>,
        plant: Model<f64, N, B, F>,
        options: &RunOptions,
        tasks: &[TaskSpec],
    ) -> Result<Self, String> {
        let gains = gains(spec, &plant)?;
        let collision = collision_table::build(&model, spec.collision_volumes, spec.collision_excluded)
            .map_err(|e| format!("collision model: {e}"))?;
        let controller = GenericController::try_new(model, collision, config(spec, &gains)?, tasks)
            .map_err(|e| format!("controller: {e}"))?;
        let mut sim = options.simulator(plant, SimConfig::default())?;
        sim.set_state(SVector::from(spec.home), SVector::zeros())?;
        sim.set_joint_stops(Some(JointStops::JUSTIN))?;
        Ok(Self { sim, controller: Box::new(controller), gains, faulty_cycles: 0, non_finite_cycles: 0 })
    }

    /// One control cycle: sense, step the controller on the frame in `T`, write the torques.
    pub fn cycle(&mut self, info: &CycleInfo) -> Result<(), String> {
        let mut joints = JointTorqueInterface::read(&mut self.sim)?;
        let mut platform = PlatformVelocityInterface::read(&mut self.sim)?;
        joints.cycle = info.cycle + 1;
        platform.cycle = info.cycle + 1;
        let frame = SensorFrame {
            joints: hal::JointSample {
                position: joints.position.map(c),
                velocity: joints.velocity.map(c),
                torque: joints.torque.map(c),
                cycle: joints.cycle,
            },
            platform: hal::PlatformSample {
                pose: platform.pose.map(c),
                velocity: platform.velocity.map(c),
                leg_lengths: platform.leg_lengths.map(c),
                cycle: platform.cycle,
            },
        };
        let output = self.controller.step(&frame);
        let torque: [f64; N] = output.torque.map(Into::into);
        if output.mode != SafeOutput::Normal {
            self.faulty_cycles += 1;
        }
        let errors_finite = self.controller.telemetry().tcp_error.iter().all(|e| e.iter().all(|x| x.is_finite()));
        if !(errors_finite && torque.iter().all(|x| x.is_finite())) {
            self.non_finite_cycles += 1;
        }
        JointTorqueInterface::write_torque(&mut self.sim, &torque)?;
        Ok(())
    }

    /// The TCP position of `arm` in the simulator (m, world).
    pub fn tcp_position(&mut self, spec: &RobotSpec<N, A>, arm: usize) -> Result<Vector3<f64>, String> {
        let frame = *spec.tcps.get(arm).ok_or("no such arm")?;
        Ok(self.sim.frame_placement(frame)?.translation.vector)
    }

    /// Moves the goal of `arm` by `offset` (m, world) from its current target, as a step.
    pub fn step_goal(&mut self, arm: usize, offset: Vector3<f64>) -> Result<(), String> {
        self.move_goal(arm, offset, 0.0)
    }

    /// Moves the goal of `arm` by `offset` (m, world) from its current target along the kernel's
    /// cubic of `duration_s` (0: a step), keeping the orientation.
    pub fn move_goal(&mut self, arm: usize, offset: Vector3<f64>, duration_s: f64) -> Result<(), String> {
        let id = *ArmId::all::<A>().get(arm).ok_or("no such arm")?;
        let target = self.controller.tcp_target(id).ok_or("no TCP target")?.pose;
        let rotation = nalgebra::UnitQuaternion::from_rotation_matrix(&target.rotation);
        let goal = target.translation.vector + offset.map(c::<T>);
        let pose = Pose { position: goal.into(), orientation: [rotation.w, rotation.i, rotation.j, rotation.k] };
        self.controller
            .apply(&Command::TcpGoal { hand: id, pose, duration_s: c(duration_s) })
            .map_err(|e| format!("TcpGoal: {e}"))
    }

    /// The TCP position error of `arm` (m): `‖p − p_des‖` from the telemetry.
    pub fn tcp_error(&self, arm: usize) -> f64 {
        let telemetry = self.controller.telemetry();
        telemetry.tcp_error.get(arm).map_or(f64::NAN, |e| e.fixed_rows::<3>(0).norm().into())
    }
}

/// The columns of [`record`]: `t`, the joints' `q.*`, `dq.*`, `tau.*`, then per arm `a` the TCP
/// error norm `e<a>` (m) and the TCP position `tcp<a>.x/y/z` (m, world).
pub fn columns<const N: usize, const A: usize>(spec: &RobotSpec<N, A>) -> Vec<String> {
    let mut columns = vec!["t".to_string()];
    columns.extend(crate::scenarios::joint_columns(&spec.joint_names));
    for arm in 0..A {
        columns.push(format!("e{arm}"));
        columns.extend(["x", "y", "z"].iter().map(|axis| format!("tcp{arm}.{axis}")));
    }
    columns
}

/// Appends the rig's state at `time_s` to `series` (the columns of [`columns`]).
pub fn record<T, const N: usize, const B: usize, const F: usize, const A: usize>(
    rig: &mut GenericRig<T, N, B, F, A>,
    spec: &RobotSpec<N, A>,
    time_s: f64,
    series: &mut TimeSeries,
) -> Result<(), String>
where
    T: RealField + Copy + Into<f64>,
{
    let mut row = vec![time_s];
    row.extend(rig.sim.q().iter());
    row.extend(rig.sim.v().iter());
    row.extend(rig.sim.applied_torque().iter());
    for arm in 0..A {
        row.push(rig.tcp_error(arm));
        row.extend(rig.tcp_position(spec, arm)?.iter());
    }
    series.push(row)
}

impl<T, const N: usize, const B: usize, const F: usize, const A: usize> Physics for GenericRig<T, N, B, F, A>
where
    T: RealField + Copy,
{
    fn time_s(&self) -> f64 {
        self.sim.time_s()
    }

    fn physics_step_s(&self) -> f64 {
        self.sim.config().physics_step_s
    }

    fn step_physics(&mut self) -> Result<StepReport, SimError> {
        self.sim.step()
    }
}
