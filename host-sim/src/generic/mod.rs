//! The generic rig: a robot (`--robot <name>`: every imported robot, or `justin`) simulated by
//! [`Simulator`] under the kernel's whole-body controller for its layout (issue 15, item 4).
//!
//! The import registers each robot: the index `fixtures/robots/mod.rs` lists them in
//! `fixtures::for_each_imported_robot!`, from which [`RobotName`] and [`simulate`]'s dispatch are
//! built, and each robot's module carries its scenario start posture `HOME` and its `ELBOW`
//! (`host-sim/src/import/`); Justin is added by hand.
//!
//! An imported robot (`fixtures::robots::<name>`) has its generated layout: a fixed base
//! (`U = N`, every platform axis absent) or, imported with `--base planar`, the admitted
//! platform (`U = N − 3`, its generated `JOINTS`), one arm per TCP of the import, and its torso
//! coordinates if it has any (TIAGo++'s lift), and its imported collision model
//! (`fixtures::robots::<name>::collision`, compiled from `<name>.collision`). Justin (`fixtures::justin`) runs with its full controller: the
//! platform admittance (`U = N − 3`, the platform's velocity command written to the simulator),
//! the torso, both arms (arm 0 the right one, the scenarios' TCP) and its own collision model.
//!
//! Every gain, limit and the hierarchy come from the robot's compiled configuration file
//! (`fixtures/robots/<name>/config.toml`: `controller_config()` and the file's
//! `[hierarchy.fig_6_3]`; Justin's `whole_body::controller_config` and `fig_6_3_hierarchy`): the import writes its gains by one rule from the model
//! (`host-sim/src/import/config.rs`: the heaviest TCP direction at 1.5 Hz, `ξ = 0.7`, joint
//! damping and end stops from the diagonal inertia); a value edited in the file changes the run
//! after a rebuild, with no Rust edit. The hierarchy is the file's Fig. 6.3 for arm 0: the
//! Cartesian impedance of arm 0 with the strong collision avoidance over the weak collision avoidance, arm 0's singularity avoidance, the end stops, the joint
//! impedance of the torso and the other arms and the upper body's damping.
//!
//! [`GenericRig::cycle`] reads the sensors through the `hal` traits, steps the controller in the
//! run's scalar (`f64` or `f32`: the frame narrowed, the torque widened) and writes the torques.

pub mod limits;
pub mod nearest_posture;
pub mod posture_push;
pub mod reach;
pub mod self_collision;

use fixtures::justin::{self, whole_body};
use hal::{JointTorqueInterface, PlatformVelocityInterface};
use kernel::controller::config::*;
use kernel::controller::faults::SafeOutput;
use kernel::controller::messages::{Command, Pose};
use kernel::controller::{Controller, SensorFrame};
use kernel::model::{FrameId, Model};
use kernel::tasks::collision::CollisionModel;
use nalgebra::{convert, RealField, SVector, Vector3};

use crate::output::TimeSeries;
use crate::scalar::Scalar;
use crate::scenarios::{Outcome, RunOptions};
use crate::sim::{CycleInfo, JointStops, Physics, SimConfig, SimError, Simulator, StepReport};

/// What the generic rig needs of an imported robot besides its model.
#[derive(Clone, Copy, Debug)]
pub struct RobotSpec<const N: usize, const A: usize> {
    /// The robot's name (`--robot`).
    pub name: &'static str,
    /// The TCP frame of each arm.
    pub tcps: [FrameId; A],
    /// The home posture (rad, m): inside the limits, away from the end-stop margins.
    pub home: fn() -> [f64; N],
    /// A mid-chain frame of arm 0 (the elbow) where `posture_push` pushes.
    pub elbow: FrameId,
    /// URDF joint of each coordinate.
    pub joint_names: [&'static str; N],
    /// The name of collision volume `i` of [`RigParts::plant_collision`] (its `VOLUME_SPECS`).
    pub volume_name: fn(usize) -> Option<&'static str>,
}

/// The spec of an imported robot: its generated `HOME` and `ELBOW` (`host-sim/src/import/`).
macro_rules! imported_spec {
    ($robot:ident) => {
        RobotSpec {
            name: stringify!($robot),
            tcps: fixtures::robots::$robot::TCPS,
            home: || fixtures::robots::$robot::HOME,
            elbow: fixtures::robots::$robot::ELBOW,
            joint_names: fixtures::robots::$robot::JOINT_NAMES,
            volume_name: |i| fixtures::robots::$robot::collision::VOLUME_SPECS.get(i).map(|v| v.name),
        }
    };
}

/// Justin: arm 0 the right arm (TCP `right_tcp`), arm 1 the left; its home pose
/// (`justin::home_configuration`); the elbow frame `right_arm_link4`.
pub const JUSTIN: RobotSpec<{ justin::N }, { whole_body::ARMS }> = RobotSpec {
    name: "justin",
    tcps: [justin::RIGHT_TCP, justin::LEFT_TCP],
    home: || justin::home_configuration::<f64>().into(),
    elbow: justin::RIGHT_ARM_LINK4,
    joint_names: justin::JOINT_NAMES,
    volume_name: |i| justin::collision::VOLUME_SPECS.get(i).map(|v| v.name),
};

/// A generic scenario: one function over the robot's sizes and the controller's scalar.
pub trait Scenario {
    /// Runs the scenario on `spec` with the controller in `T` built of `parts()` (called once per
    /// simulated run).
    fn simulate<
        T,
        const N: usize,
        const B: usize,
        const F: usize,
        const U: usize,
        const V: usize,
        const P: usize,
        const A: usize,
    >(
        spec: &RobotSpec<N, A>,
        parts: &dyn Fn() -> Result<RigParts<T, N, B, F, U, V, P, A>, String>,
        options: &RunOptions,
    ) -> Result<Outcome, String>
    where
        T: RealField + Copy + Into<f64>;
}

/// What the rig is built of: the controller's pieces in `T` (the robot's model, collision model,
/// compiled configuration and Fig. 6.3 hierarchy, which a scenario may adjust before
/// [`GenericRig::new`] builds the controller of them), the simulated plant's model and collision
/// model in `f64` and the simulator's settings.
pub struct RigParts<
    T: RealField + Copy,
    const N: usize,
    const B: usize,
    const F: usize,
    const U: usize,
    const V: usize,
    const P: usize,
    const A: usize,
> {
    /// The controller's model of the robot.
    pub model: Model<T, N, B, F>,
    /// The controller's collision model (the imported robot's table, Justin's
    /// `fixtures::justin::collision` without environment volumes).
    pub collision: CollisionModel<T, V, P>,
    /// The controller's configuration (the robot's compiled `config.toml`).
    pub config: ControllerConfig<T, N, A>,
    /// The controller's hierarchy (the file's Fig. 6.3 for arm 0).
    pub hierarchy: Vec<TaskSpec>,
    /// The simulated robot's model.
    pub plant: Model<f64, N, B, F>,
    /// The controller's collision model in `f64` on the simulated robot's model, where a
    /// scenario measures the pair distances.
    pub plant_collision: CollisionModel<f64, V, P>,
    /// The simulator's settings.
    pub sim_config: SimConfig,
}

/// The parts of an imported robot: its models and its compiled configuration, in `T`.
macro_rules! imported {
    ($robot:ident, $t:ty) => {{
        use fixtures::robots::$robot;
        let error = |e: kernel::model::ModelError| format!("model: {e}");
        let model = $robot::model::<$t>().map_err(error)?;
        let collision = $robot::collision::collision_model(&model).map_err(|e| format!("collision model: {e}"))?;
        let plant = $robot::model::<f64>().map_err(error)?;
        let config = $robot::controller_config::<$t>().map_err(|e| format!("{}: {e:?}", stringify!($robot)))?;
        RigParts::<
            $t,
            { $robot::N },
            { $robot::BODIES },
            { $robot::FRAMES },
            { $robot::JOINTS },
            { $robot::collision::VOLUMES },
            { $robot::collision::PAIRS },
            { $robot::ARMS },
        > {
            model,
            collision,
            config,
            hierarchy: $robot::config::hierarchy::fig_6_3::LEVELS.to_vec(),
            plant_collision: $robot::collision::collision_model(&plant).map_err(|e| format!("collision model: {e}"))?,
            plant,
            sim_config: SimConfig::default(),
        }
    }};
}

/// Justin's parts in `T`: the pieces of the controller of `crate::wbc` (its model, its collision
/// model without environment volumes, its configuration) with the Fig. 6.3 hierarchy for the
/// right TCP, the simulator with the base's lag.
fn justin_parts<T: RealField + Copy>() -> Result<
    RigParts<
        T,
        { justin::N },
        { justin::BODIES },
        { justin::FRAMES },
        { justin::UPPER_DOF },
        { crate::wbc::VOLUMES },
        { crate::wbc::PAIRS },
        { whole_body::ARMS },
    >,
    String,
> {
    let model = justin::model::<T>().map_err(|e| format!("model: {e}"))?;
    let plant = justin::model::<f64>().map_err(|e| format!("model: {e}"))?;
    Ok(RigParts {
        collision: justin::collision::collision_model_with_environment(&model, &[])
            .map_err(|e| format!("collision model: {e}"))?,
        model,
        config: crate::wbc::ConfigChanges::NONE.config()?,
        hierarchy: whole_body::fig_6_3_hierarchy(ArmId::RIGHT).to_vec(),
        plant_collision: justin::collision::collision_model_with_environment(&plant, &[])
            .map_err(|e| format!("collision model: {e}"))?,
        plant,
        sim_config: SimConfig { base_lag_s: crate::wbc::BASE_LAG_S, ..SimConfig::default() },
    })
}

/// The robots a generic scenario runs on: every imported robot of `fixtures/robots/` (listed
/// by the index's `fixtures::for_each_imported_robot!`, so an import registers its robot, and
/// `--robot <name>` takes it after a rebuild) and Justin, by hand.
macro_rules! robot_names {
    ($($module:ident $variant:ident),*) => {
        /// A generic scenario's robot (`--robot`): the imported robots by their module name,
        /// `justin`; the default is the Panda.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
        pub enum RobotName {
            $(
                #[doc = concat!("`fixtures::robots::", stringify!($module), "`, imported.")]
                #[value(name = stringify!($module))]
                $variant,
            )*
            /// The Justin-like robot (`fixtures::justin`): platform, torso and two 7-DOF arms.
            Justin,
        }

        impl RobotName {
            /// The option's value on the command line.
            pub fn name(self) -> &'static str {
                match self {
                    $(Self::$variant => stringify!($module),)*
                    Self::Justin => "justin",
                }
            }
        }

        /// Runs scenario `S` on the robot and in the scalar the options name.
        pub fn simulate<S: Scenario>(options: &RunOptions) -> Result<Outcome, String> {
            match (options.robot.unwrap_or(RobotName::Panda), options.scalar) {
                $(
                    (RobotName::$variant, Scalar::F64) => S::simulate(&imported_spec!($module), &|| Ok(imported!($module, f64)), options),
                    (RobotName::$variant, Scalar::F32) => S::simulate(&imported_spec!($module), &|| Ok(imported!($module, f32)), options),
                )*
                (RobotName::Justin, Scalar::F64) => S::simulate(&JUSTIN, &justin_parts::<f64>, options),
                (RobotName::Justin, Scalar::F32) => S::simulate(&JUSTIN, &justin_parts::<f32>, options),
            }
        }
    };
}
fixtures::for_each_imported_robot!(robot_names);

fn c<T: RealField>(x: f64) -> T {
    convert(x)
}

/// The simulated robot and its controller, wired.
pub struct GenericRig<
    T: RealField + Copy,
    const N: usize,
    const B: usize,
    const F: usize,
    const U: usize,
    const V: usize,
    const P: usize,
    const A: usize,
> {
    /// The simulated robot (always `f64`).
    pub sim: Simulator<N, B, F, U>,
    /// The controller in the run's scalar; boxed: it is large.
    pub controller: Box<Controller<T, N, B, F, U, V, P, A>>,
    /// Cycles with a safe output instead of the whole-body torque.
    pub faulty_cycles: u64,
    /// Cycles with a non-finite torque or TCP error.
    pub non_finite_cycles: u64,
}

impl<
        T,
        const N: usize,
        const B: usize,
        const F: usize,
        const U: usize,
        const V: usize,
        const P: usize,
        const A: usize,
    > GenericRig<T, N, B, F, U, V, P, A>
where
    T: RealField + Copy + Into<f64>,
{
    /// The robot at its home posture at rest on the plant of `options`, the controller built of
    /// `parts` (its model, collision model, configuration and hierarchy).
    pub fn new(
        spec: &RobotSpec<N, A>,
        parts: RigParts<T, N, B, F, U, V, P, A>,
        options: &RunOptions,
    ) -> Result<Self, String> {
        let RigParts { model, collision, config, hierarchy, plant, sim_config, .. } = parts;
        let controller = Box::new(
            Controller::try_new(model, collision, config, &hierarchy).map_err(|e| format!("controller: {e}"))?,
        );
        let mut sim = options.simulator(plant, sim_config)?;
        sim.set_state(SVector::from((spec.home)()), SVector::zeros())?;
        sim.set_joint_stops(Some(JointStops::JUSTIN))?;
        Ok(Self { sim, controller, faulty_cycles: 0, non_finite_cycles: 0 })
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
        let torque: [f64; U] = output.torque.map(Into::into);
        let platform = hal::PlatformCommand {
            velocity: output.platform.velocity.map(Into::into),
            leg_rates: output.platform.leg_rates.map(Into::into),
        };
        if output.mode != SafeOutput::Normal {
            self.faulty_cycles += 1;
        }
        let errors_finite = self.controller.telemetry().tcp_error.iter().all(|e| e.iter().all(|x| x.is_finite()));
        if !(errors_finite && torque.iter().all(|x| x.is_finite())) {
            self.non_finite_cycles += 1;
        }
        JointTorqueInterface::write_torque(&mut self.sim, &torque)?;
        PlatformVelocityInterface::write_velocity(&mut self.sim, &platform)?;
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

    /// The translational stiffness of `arm`'s Cartesian impedance along world `z` (N/m, the
    /// configuration's).
    pub fn translational_stiffness(&self, arm: usize) -> Result<f64, String> {
        let cartesian = self.controller.config().cartesian.get(arm).ok_or("no such arm")?;
        Ok(cartesian.translational_stiffness[2].into())
    }

    /// The TCP position error of `arm` (m): `‖p − p_des‖` from the telemetry.
    pub fn tcp_error(&self, arm: usize) -> f64 {
        let telemetry = self.controller.telemetry();
        telemetry.tcp_error.get(arm).map_or(f64::NAN, |e| e.fixed_rows::<3>(0).norm().into())
    }
}

/// The columns of [`record`]: `t`, the coordinates' `q.*`, `dq.*`, the `U` actuated joints'
/// `tau.*`, then per arm `a` the TCP error norm `e<a>` (m) and the TCP position `tcp<a>.x/y/z`
/// (m, world).
pub fn columns<const N: usize, const U: usize, const A: usize>(spec: &RobotSpec<N, A>) -> Vec<String> {
    let mut columns = vec!["t".to_string()];
    let joints = spec.joint_names.get(N - U..).unwrap_or_default();
    columns.extend(spec.joint_names.iter().map(|n| format!("q.{n}")));
    columns.extend(spec.joint_names.iter().map(|n| format!("dq.{n}")));
    columns.extend(joints.iter().map(|n| format!("tau.{n}")));
    for arm in 0..A {
        columns.push(format!("e{arm}"));
        columns.extend(["x", "y", "z"].iter().map(|axis| format!("tcp{arm}.{axis}")));
    }
    columns
}

/// Appends the rig's state at `time_s` to `series` (the columns of [`columns`]).
pub fn record<
    T,
    const N: usize,
    const B: usize,
    const F: usize,
    const U: usize,
    const V: usize,
    const P: usize,
    const A: usize,
>(
    rig: &mut GenericRig<T, N, B, F, U, V, P, A>,
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

impl<
        T,
        const N: usize,
        const B: usize,
        const F: usize,
        const U: usize,
        const V: usize,
        const P: usize,
        const A: usize,
    > Physics for GenericRig<T, N, B, F, U, V, P, A>
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
