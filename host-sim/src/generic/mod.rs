//! The generic rig: an imported robot (`--robot panda|tiago_dual`, `fixtures::robots`) simulated
//! by [`Simulator`] under the kernel's whole-body controller for its layout (issue 15, item 4).
//!
//! The layout is the robot's (`fixtures::robots::<name>::layout`): a fixed base (`U = N`, every
//! platform axis absent), one arm per TCP of the import, and the robot's torso coordinates if it
//! has any (TIAGo++'s lift). Collision avoidance has no volumes yet: the import writes the
//! swept-sphere model as a text file (`fixtures/robots/<name>/<name>.collision`) without a Rust
//! constructor.
//!
//! Every gain, limit and the hierarchy come from the robot's compiled configuration file
//! (`fixtures/robots/<name>/config.toml`, `fixtures::robots::<name>::controller_config` and
//! `config::hierarchy::fig_6_3::LEVELS`): the import writes its gains by one rule from the model
//! (`host-sim/src/import/config.rs`: the heaviest TCP direction at 1.5 Hz, `ξ = 0.7`, joint
//! damping and end stops from the diagonal inertia); a value edited in the file changes the run
//! after a rebuild, with no Rust edit. The hierarchy is the file's Fig. 6.3 for arm 0: the
//! Cartesian impedance of arm 0 (with the strong collision avoidance, which has no volumes yet)
//! over the weak collision avoidance, arm 0's singularity avoidance, the end stops, the joint
//! impedance of the torso and the other arms and the upper body's damping.
//!
//! [`GenericRig::cycle`] reads the sensors through the `hal` traits, steps the controller in the
//! run's scalar (`f64` or `f32`: the frame narrowed, the torque widened) and writes the torques.

pub mod posture_push;
pub mod reach;

use fixtures::robots::{panda, tiago_dual};
use hal::{JointTorqueInterface, PlatformVelocityInterface};
use kernel::controller::config::*;
use kernel::controller::faults::SafeOutput;
use kernel::controller::messages::{Command, Pose};
use kernel::controller::{Controller, SensorFrame};
use kernel::model::{FrameId, Model};
use kernel::tasks::collision::CollisionModelBuilder;
use nalgebra::{convert, RealField, SVector, Vector3};

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

/// What the generic rig needs of an imported robot besides its model.
#[derive(Clone, Copy, Debug)]
pub struct RobotSpec<const N: usize, const A: usize> {
    /// The robot's name (`--robot`).
    pub name: &'static str,
    /// The TCP frame of each arm.
    pub tcps: [FrameId; A],
    /// The home posture (rad, m): inside the limits, away from the end-stop margins.
    pub home: [f64; N],
    /// A mid-chain frame of arm 0 (the elbow) where `posture_push` pushes.
    pub elbow: FrameId,
    /// URDF joint of each coordinate.
    pub joint_names: [&'static str; N],
}

/// The Panda: one arm of all seven joints; the home posture of `tests/src/fixed_base.rs`.
pub const PANDA: RobotSpec<{ panda::N }, 1> = RobotSpec {
    name: "panda",
    tcps: panda::TCPS,
    home: [0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8],
    elbow: panda::PANDA_LINK4,
    joint_names: panda::JOINT_NAMES,
};

/// TIAGo++: the lift (coordinate 0) as the torso, the left arm (1–7, TCP 0) and the right arm
/// (8–14, TCP 1); home: the lift at 0.15 m, each arm's shoulder forward and out, elbow bent
/// 1.5 rad.
pub const TIAGO_DUAL: RobotSpec<{ tiago_dual::N }, 2> = RobotSpec {
    name: "tiago_dual",
    tcps: tiago_dual::TCPS,
    home: [0.15, 0.4, 0.3, 0.0, 1.5, 0.0, 0.5, 0.0, 0.4, 0.3, 0.0, 1.5, 0.0, 0.5, 0.0],
    elbow: tiago_dual::ARM_LEFT_4_LINK,
    joint_names: tiago_dual::JOINT_NAMES,
};

/// A generic scenario: one function over the robot's sizes and the controller's scalar.
pub trait Scenario {
    /// Runs the scenario on `spec` with the controller in `T` made of `parts`.
    fn simulate<T, const N: usize, const B: usize, const F: usize, const A: usize>(
        spec: &RobotSpec<N, A>,
        parts: RigParts<T, N, B, F, A>,
        options: &RunOptions,
    ) -> Result<Outcome, String>
    where
        T: RealField + Copy + Into<f64>;
}

/// What the rig is built of: the controller's model in `T`, the simulated plant's in `f64`, the
/// robot's compiled configuration and its Fig. 6.3 hierarchy.
pub struct RigParts<T: RealField + Copy, const N: usize, const B: usize, const F: usize, const A: usize> {
    /// The controller's model.
    pub model: Model<T, N, B, F>,
    /// The simulated robot's model.
    pub plant: Model<f64, N, B, F>,
    /// The controller's configuration: the robot's `config.toml`.
    pub config: ControllerConfig<T, N, A>,
    /// The hierarchy: the file's `[hierarchy.fig_6_3]`.
    pub hierarchy: &'static [TaskSpec],
}

/// The parts of a robot: its models and its compiled configuration, in `T`.
macro_rules! parts {
    ($robot:ident, $t:ty) => {{
        let error = |e: kernel::model::ModelError| format!("model: {e}");
        RigParts::<$t, { $robot::N }, { $robot::BODIES }, { $robot::FRAMES }, { $robot::ARMS }> {
            model: $robot::model::<$t>().map_err(error)?,
            plant: $robot::model::<f64>().map_err(error)?,
            config: $robot::controller_config::<$t>().map_err(|e| format!("{}: {e:?}", stringify!($robot)))?,
            hierarchy: &$robot::config::hierarchy::fig_6_3::LEVELS,
        }
    }};
}

/// Runs scenario `S` on the robot and in the scalar the options name.
pub fn simulate<S: Scenario>(options: &RunOptions) -> Result<Outcome, String> {
    match (options.robot.unwrap_or_default(), options.scalar) {
        (RobotName::Panda, Scalar::F64) => S::simulate(&PANDA, parts!(panda, f64), options),
        (RobotName::Panda, Scalar::F32) => S::simulate(&PANDA, parts!(panda, f32), options),
        (RobotName::TiagoDual, Scalar::F64) => S::simulate(&TIAGO_DUAL, parts!(tiago_dual, f64), options),
        (RobotName::TiagoDual, Scalar::F32) => S::simulate(&TIAGO_DUAL, parts!(tiago_dual, f32), options),
    }
}

fn c<T: RealField>(x: f64) -> T {
    convert(x)
}

/// The controller of an imported robot: `U = N` (fixed base), no collision volumes, `A` arms.
pub type GenericController<T, const N: usize, const B: usize, const F: usize, const A: usize> =
    Controller<T, N, B, F, N, 0, 0, A>;

/// The simulated imported robot and its controller, wired.
pub struct GenericRig<T: RealField + Copy, const N: usize, const B: usize, const F: usize, const A: usize> {
    /// The simulated robot (always `f64`).
    pub sim: Simulator<N, B, F, N>,
    /// The controller in the run's scalar; boxed: it is large.
    pub controller: Box<GenericController<T, N, B, F, A>>,
    /// Its configuration (the robot's `config.toml`).
    pub config: ControllerConfig<T, N, A>,
    /// Cycles with a safe output instead of the whole-body torque.
    pub faulty_cycles: u64,
    /// Cycles with a non-finite torque or TCP error.
    pub non_finite_cycles: u64,
}

impl<T, const N: usize, const B: usize, const F: usize, const A: usize> GenericRig<T, N, B, F, A>
where
    T: RealField + Copy + Into<f64>,
{
    /// The robot at its home posture at rest on the plant of `options`, the controller made of
    /// `parts`.
    pub fn new(spec: &RobotSpec<N, A>, parts: RigParts<T, N, B, F, A>, options: &RunOptions) -> Result<Self, String> {
        let RigParts { model, plant, config, hierarchy } = parts;
        let collision = CollisionModelBuilder::<T, 0, 0>::new()
            .try_build(&model, &[])
            .map_err(|e| format!("collision model: {e}"))?;
        let controller =
            GenericController::try_new(model, collision, config, hierarchy).map_err(|e| format!("controller: {e}"))?;
        let mut sim = options.simulator(plant, SimConfig::default())?;
        sim.set_state(SVector::from(spec.home), SVector::zeros())?;
        sim.set_joint_stops(Some(JointStops::JUSTIN))?;
        Ok(Self { sim, controller: Box::new(controller), config, faulty_cycles: 0, non_finite_cycles: 0 })
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
        let id = *ArmId::all::<A>().get(arm).ok_or("no such arm")?;
        let target = self.controller.tcp_target(id).ok_or("no TCP target")?.pose;
        let rotation = nalgebra::UnitQuaternion::from_rotation_matrix(&target.rotation);
        let goal = target.translation.vector + offset.map(c::<T>);
        let pose = Pose { position: goal.into(), orientation: [rotation.w, rotation.i, rotation.j, rotation.k] };
        self.controller
            .apply(&Command::TcpGoal { hand: id, pose, duration_s: T::zero() })
            .map_err(|e| format!("TcpGoal: {e}"))
    }

    /// The translational stiffness of `arm`'s Cartesian impedance along world `x` (N/m, the
    /// configuration's).
    pub fn translational_stiffness(&self, arm: usize) -> Result<f64, String> {
        let cartesian = self.config.cartesian.get(arm).ok_or("no such arm")?;
        Ok(cartesian.translational_stiffness[0].into())
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
