//! The simulated Rollin' Justin under the kernel's whole-body controller
//! ([`kernel::controller::Controller`]): the rig every `wbc_*` and service-task scenario uses.
//!
//! Per control cycle ([`Rig::cycle`]): read the joint and platform samples through the `hal`
//! traits, number the frame with the control-cycle counter (the simulator counts physics
//! steps), call the [`Driver`]'s `step` (the host controller in `f64` or `f32`, or the firmware
//! under QEMU), write the torques and the platform command back, and
//! record one row in the scenario convention of docs/OUTPUT.md (`t`, `q.*`, `dq.*`, `tau.*`, the
//! TCP errors `e0.*` (right) and `e1.*` (left), the storage `S<level>` per level, the activation
//! `a.<task>` per hierarchy entry, the controller's platform commands and diagnostics, the TCP
//! positions and the external forces on the TCPs).

use fixtures::justin::{self, collision, whole_body};
use hal::{JointTorqueInterface, PlatformVelocityInterface};
use kernel::controller::config::{ArmId, ControllerConfig, TaskKind, TaskSpec, MAX_LEVELS};
use kernel::controller::faults::SafeOutput;
use kernel::controller::messages::Command;
use kernel::controller::{ActuatorFrame, SensorFrame};
use kernel::tasks::cartesian_impedance::CartesianTarget;
use kernel::tasks::collision::SweptSphere;
use nalgebra::{RealField, SVector};

use crate::output::{Summary, TimeSeries};
use crate::pil::Firmware;
use crate::scalar::{F32Controller, Scalar};
use crate::scenarios::{RunOptions, PLANT_SEED};
use crate::sim::{
    run_loop, CycleInfo, JointStops, Physics, SimConfig, SimError, Simulator, StepReport, CONTROL_PERIOD_S,
};

/// Collision volumes: the robot's 28 plus up to four environment volumes (table, wall, …).
pub const VOLUMES: usize = collision::VOLUMES + MAX_ENVIRONMENT;
/// Most environment volumes (as many as the firmware's setup message carries).
pub const MAX_ENVIRONMENT: usize = link::setup::MAX_ENVIRONMENT_VOLUMES;
/// Pair capacity: the robot's pairs plus 27 per environment volume.
pub const PAIRS: usize = collision::PAIRS + 27 * MAX_ENVIRONMENT;

/// The Justin-like simulator.
pub type JustinSim = Simulator<{ justin::N }, { justin::BODIES }, { justin::FRAMES }, { justin::UPPER_DOF }>;
/// The whole-body controller of the Justin-like robot in `f64`, with room for the rig's environment
/// volumes (`fixtures::justin::whole_body::JustinController` has the robot's volumes only).
pub type RigController = justin::whole_body::WholeBodyController<f64, VOLUMES, PAIRS>;

/// Base velocity-loop lag of the simulated platform (s): an imperfect velocity loop, as in the
/// `mobile_impedance` scenarios.
pub const BASE_LAG_S: f64 = 0.05;

/// The simulator and the controller, wired.
pub struct Rig {
    /// The simulated robot.
    pub sim: JustinSim,
    /// The host controller in `f64`: it drives the robot with [`Driver::HostF64`], and runs
    /// alongside on the same frames otherwise (its telemetry fills the columns; its torques are
    /// the reference of [`Rig::torque_difference`]).
    pub controller: RigController,
    /// The controller whose output drives the robot.
    pub driver: Driver,
    /// Faults seen so far (cycles with a safe output).
    pub faulty_cycles: u64,
    /// Smallest collision distance seen (m) over all pairs.
    pub min_distance_m: f64,
    /// Largest joint-torque difference |τ_driver − τ_host f64| (Nm) over the first
    /// [`COMPARISON_S`], on the same frames (0 with [`Driver::HostF64`]).
    pub torque_difference: f64,
    /// The output applied in the last cycle.
    output: ActuatorFrame<f64, { justin::UPPER_DOF }>,
}

/// The controller that drives the rig's robot.
pub enum Driver {
    /// The rig's own host controller in `f64`.
    HostF64,
    /// The same controller in `f32` on the host ([`crate::scalar`]).
    HostF32(F32Controller),
    /// The firmware image under QEMU ([`crate::pil`]); boxed: its link buffers are large.
    Firmware(Box<Firmware>),
}

impl Driver {
    /// The driver the run's options ask for: the firmware when they name a PIL target (the
    /// image runs `f32`), else the host controller in their scalar.
    fn for_options(
        options: &RunOptions,
        environment: &[SweptSphere<f64>],
        changes: ConfigChanges,
        hierarchy: &[TaskSpec],
    ) -> Result<Self, String> {
        match (options.pil, options.scalar) {
            (Some(target), _) => {
                firmware_for(target, environment, changes, hierarchy).map(|f| Self::Firmware(Box::new(f)))
            }
            (None, Scalar::F32) => F32Controller::new(environment, changes, hierarchy).map(Self::HostF32),
            (None, Scalar::F64) => Ok(Self::HostF64),
        }
    }

    /// The firmware, when it drives the robot.
    pub fn firmware(&self) -> Option<&Firmware> {
        match self {
            Self::Firmware(firmware) => Some(firmware.as_ref()),
            Self::HostF64 | Self::HostF32(_) => None,
        }
    }

    /// What `summary.json` records as the controller.
    pub fn label(&self) -> String {
        match self {
            Self::HostF64 => "host f64".into(),
            Self::HostF32(_) => "host f32".into(),
            Self::Firmware(firmware) => firmware.target().label(),
        }
    }

    /// The output for `frame`, given the host `f64` controller's output `host` on it.
    fn step(
        &mut self,
        frame: &SensorFrame<f64, { justin::UPPER_DOF }>,
        host: ActuatorFrame<f64, { justin::UPPER_DOF }>,
    ) -> Result<ActuatorFrame<f64, { justin::UPPER_DOF }>, String> {
        match self {
            Self::HostF64 => Ok(host),
            Self::HostF32(controller) => controller.step(frame),
            Self::Firmware(firmware) => firmware.step(frame),
        }
    }

    /// Applies a planner command (the host `f64` controller has applied it already).
    fn apply(&mut self, command: &Command<f64>) -> Result<(), String> {
        match self {
            Self::HostF64 => Ok(()),
            Self::HostF32(controller) => controller.apply(command),
            Self::Firmware(firmware) => firmware.apply(command),
        }
    }
}

/// The span over which the driver's torques are compared with the host `f64` controller's (s).
pub const COMPARISON_S: f64 = 0.5;

/// What a scenario changes in the configuration of Ch. 6 ([`whole_body::controller_config`]):
/// the rig builds the configuration in each controller's scalar and applies these.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConfigChanges {
    /// Platform axes `(x, y, θ)` the admittance moves (Ch. 6: all three; `false` holds the
    /// base at rest like a braked platform).
    pub free_base_axes: [bool; 3],
}

impl ConfigChanges {
    /// The configuration of Ch. 6 unchanged.
    pub const NONE: Self = Self { free_base_axes: [true; 3] };

    /// [`whole_body::controller_config`] in `T` with these changes.
    pub fn config<T: RealField + Copy>(
        self,
    ) -> Result<ControllerConfig<T, { justin::N }, { whole_body::ARMS }>, String> {
        let mut config = whole_body::controller_config::<T>().map_err(|e| format!("config: {e}"))?;
        config.platform.admittance.free_axes = self.free_base_axes;
        Ok(config)
    }
}

/// The rig's whole-body controller in `T`: the collision model with `environment` volumes
/// (world frame), the configuration with `changes`, and `hierarchy`.
pub fn whole_body_controller<T: RealField + Copy>(
    environment: &[SweptSphere<T>],
    changes: ConfigChanges,
    hierarchy: &[TaskSpec],
) -> Result<justin::whole_body::WholeBodyController<T, VOLUMES, PAIRS>, String> {
    controller_with_config(environment, changes.config()?, hierarchy)
}

/// [`whole_body_controller`] with the configuration `config`.
fn controller_with_config<T: RealField + Copy>(
    environment: &[SweptSphere<T>],
    config: ControllerConfig<T, { justin::N }, { whole_body::ARMS }>,
    hierarchy: &[TaskSpec],
) -> Result<justin::whole_body::WholeBodyController<T, VOLUMES, PAIRS>, String> {
    if environment.len() > MAX_ENVIRONMENT {
        return Err(format!("at most {MAX_ENVIRONMENT} environment volumes"));
    }
    let model = justin::model::<T>().map_err(|e| format!("model: {e}"))?;
    let collision_model = collision::collision_model_with_environment::<T, VOLUMES, PAIRS>(&model, environment)
        .map_err(|e| format!("collision model: {e}"))?;
    justin::whole_body::WholeBodyController::try_new(model, collision_model, config, hierarchy)
        .map_err(|e| format!("controller: {e}"))
}

/// Builds the rig: the robot at `q0` at rest on the plant of `options`, the host `f64`
/// controller ([`whole_body_controller`]) and the [`Driver`] the options ask for.
pub fn rig(
    q0: &SVector<f64, { justin::N }>,
    environment: &[SweptSphere<f64>],
    changes: ConfigChanges,
    hierarchy: &[TaskSpec],
    options: &RunOptions,
) -> Result<Rig, String> {
    let model = justin::model::<f64>().map_err(|e| format!("model: {e}"))?;
    let config = above_sensor_noise(changes.config()?, &model, q0, options.plant_model(PLANT_SEED))?;
    let controller = controller_with_config(environment, config, hierarchy)?;
    let mut sim: JustinSim = options
        .simulator(model, SimConfig { base_lag_s: BASE_LAG_S, ..SimConfig::default() })
        .map_err(|e| format!("simulator: {e}"))?;
    sim.set_state(*q0, SVector::zeros()).map_err(|e| format!("initial state: {e}"))?;
    sim.set_joint_stops(Some(JointStops::JUSTIN)).map_err(|e| format!("joint stops: {e}"))?;
    let driver = Driver::for_options(options, environment, changes, hierarchy)?;
    let output = *controller.output();
    Ok(Rig { sim, controller, driver, faulty_cycles: 0, min_distance_m: f64::INFINITY, torque_difference: 0.0, output })
}

/// `config` with the observer's contact threshold raised by the noise floor of the sensors of
/// `plant` at `q0` ([`kernel::controller::observer::noise_floor`]: the velocity noise through
/// `K_O M q̇` and the torque-sensor offsets), unchanged on the ideal plant (`None`). On the
/// realistic plant ([`crate::plant::PlantModel::justin`]) the floor at Justin's home pose is
/// about 15 Nm (README `--plant`).
fn above_sensor_noise(
    mut config: ControllerConfig<f64, { justin::N }, { whole_body::ARMS }>,
    model: &kernel::model::Model<f64, { justin::N }, { justin::BODIES }, { justin::FRAMES }>,
    q0: &SVector<f64, { justin::N }>,
    plant: Option<crate::plant::PlantModel>,
) -> Result<ControllerConfig<f64, { justin::N }, { whole_body::ARMS }>, String> {
    let Some(plant) = plant else { return Ok(config) };
    let mut data = kernel::model::Data::new(model);
    kernel::dynamics::forward_kinematics(model, &mut data, q0, &SVector::zeros()).map_err(|e| e.to_string())?;
    let mass = kernel::dynamics::crba(model, &mut data);
    let observed = config.layout.coordinates(kernel::controller::config::JointGroup::UpperBody);
    let observer = &mut config.observer;
    observer.contact_threshold += kernel::controller::observer::noise_floor(
        mass,
        &observed,
        observer.gain,
        plant.velocity_noise_rad_s,
        plant.torque_offset_nm,
    );
    Ok(config)
}

/// Starts the firmware and configures its controller for the rig ([`crate::pil::rig_setup`]).
fn firmware_for(
    target: crate::pil::Target,
    environment: &[SweptSphere<f64>],
    changes: ConfigChanges,
    hierarchy: &[TaskSpec],
) -> Result<Firmware, String> {
    let mut firmware = Firmware::start(target)?;
    firmware.configure(&crate::pil::rig_setup(environment, changes.free_base_axes, hierarchy)?)?;
    Ok(firmware)
}

/// The default rig of Ch. 6: Justin at its home pose, the configuration of
/// [`whole_body::controller_config`] and the Fig. 6.3 hierarchy for `hand`.
pub fn chapter_6_rig(hand: ArmId, environment: &[SweptSphere<f64>], options: &RunOptions) -> Result<Rig, String> {
    rig(&justin::home_configuration(), environment, ConfigChanges::NONE, &whole_body::fig_6_3_hierarchy(hand), options)
}

/// The columns [`Rig::record`] writes, in order.
pub fn columns() -> Vec<String> {
    let mut columns = vec!["t".to_string()];
    columns.extend(crate::scenarios::joint_columns(&justin::JOINT_NAMES));
    columns.extend(crate::scenarios::pose_error_columns(0));
    columns.extend(crate::scenarios::pose_error_columns(1));
    columns.extend((0..MAX_LEVELS).map(|l| format!("S{l}")));
    columns.extend((0..MAX_LEVELS).map(|l| format!("dS{l}")));
    columns.extend(TaskKind::all::<{ whole_body::ARMS }>().iter().map(|k| format!("a.{}", k.name())));
    columns.extend(TaskKind::all::<{ whole_body::ARMS }>().iter().map(|k| format!("tn.{}", k.name())));
    columns.extend(
        [
            "vcmd.x",
            "vcmd.y",
            "vcmd.theta",
            "fvir.x",
            "fvir.y",
            "fvir.theta",
            "leg.0",
            "leg.1",
            "leg.2",
            "leg.3",
            "min_distance",
            "collision_rows",
            "tau_ext_norm",
            "contact",
            "kinetic_j",
            "potential_j",
            "mode",
            "saturated",
            "right_tcp.x",
            "right_tcp.y",
            "right_tcp.z",
            "left_tcp.x",
            "left_tcp.y",
            "left_tcp.z",
            "force.right.x",
            "force.right.y",
            "force.right.z",
            "force.left.x",
            "force.left.y",
            "force.left.z",
        ]
        .iter()
        .map(|s| s.to_string()),
    );
    columns
}

impl Rig {
    /// One control cycle: sense, step the host `f64` controller and the [`Driver`] on the same
    /// frame, actuate with the driver's output. Returns the output mode.
    pub fn cycle(&mut self, info: &CycleInfo) -> Result<SafeOutput, String> {
        let sim_error = |e: SimError| e.to_string();
        let mut joints = JointTorqueInterface::read(&mut self.sim).map_err(sim_error)?;
        let mut platform = PlatformVelocityInterface::read(&mut self.sim).map_err(sim_error)?;
        joints.cycle = info.cycle + 1;
        platform.cycle = info.cycle + 1;
        let frame = SensorFrame { joints, platform };
        let host = *self.controller.step(&frame);
        let output = self.driver.step(&frame, host)?;
        if info.time_s < COMPARISON_S {
            let difference = output.torque.iter().zip(host.torque.iter()).map(|(a, b)| (a - b).abs());
            self.torque_difference = difference.fold(self.torque_difference, f64::max);
        }
        self.output = output;
        self.sim.write_torque(&output.torque).map_err(sim_error)?;
        self.sim.write_velocity(&output.platform).map_err(sim_error)?;
        if output.mode != SafeOutput::Normal {
            self.faulty_cycles += 1;
        }
        if let Some(d) = self.controller.telemetry().min_collision_distance {
            self.min_distance_m = self.min_distance_m.min(d);
        }
        Ok(output.mode)
    }

    /// The row of [`columns`] for the cycle just run.
    pub fn record(&mut self, info: &CycleInfo) -> Result<Vec<f64>, SimError> {
        let t = self.controller.telemetry();
        let output = &self.output;
        let mut row = vec![info.time_s];
        row.extend(self.sim.q().iter());
        row.extend(self.sim.v().iter());
        row.extend([0.0; 3]);
        row.extend(output.torque.iter());
        row.extend(t.tcp_error.iter().flat_map(|e| e.iter().copied()));
        row.extend(t.level_storage.iter());
        row.extend(t.level_storage_rate.iter());
        let entry = |kind: TaskKind, values: &[f64]| {
            t.tasks
                .iter()
                .zip(values.iter())
                .take(t.task_count)
                .find(|(k, _)| **k == Some(kind))
                .map_or(0.0, |(_, v)| *v)
        };
        row.extend(TaskKind::all::<{ whole_body::ARMS }>().iter().map(|k| entry(*k, &t.task_activation)));
        row.extend(TaskKind::all::<{ whole_body::ARMS }>().iter().map(|k| entry(*k, &t.task_torque_norm)));
        row.extend(output.platform.velocity.iter());
        row.extend(t.virtual_force.iter());
        row.extend(output.platform.leg_rates.iter());
        row.push(t.min_collision_distance.unwrap_or(f64::NAN));
        #[allow(clippy::cast_precision_loss, reason = "a few hundred rows")]
        row.push(t.collision_rows as f64);
        row.push(t.external_torque.norm());
        row.push(f64::from(u8::from(t.contact)));
        row.push(t.kinetic_energy);
        row.push(t.potential_energy);
        row.push(match output.mode {
            SafeOutput::Normal => 0.0,
            SafeOutput::Hold => 1.0,
            SafeOutput::Brake => 2.0,
        });
        row.push(f64::from(u8::from(t.saturation.any())));
        let right = self.sim.frame_placement(justin::RIGHT_TCP)?.translation.vector;
        let left = self.sim.frame_placement(justin::LEFT_TCP)?.translation.vector;
        row.extend(right.iter().chain(left.iter()));
        for frame in [justin::RIGHT_TCP, justin::LEFT_TCP] {
            row.extend(self.external_force(frame, info.time_s)?.iter());
        }
        Ok(row)
    }

    /// The host controller's current TCP target of `arm`.
    pub fn tcp_target(&self, arm: ArmId) -> Result<CartesianTarget<f64>, String> {
        self.controller.tcp_target(arm).ok_or_else(|| format!("no arm {arm:?}"))
    }

    /// Applies a planner command to the host `f64` controller and to the driver.
    pub fn apply(&mut self, command: &Command<f64>) -> Result<(), String> {
        self.controller.apply(command).map_err(|e| e.to_string())?;
        self.driver.apply(command)
    }

    /// Records which controller drove the robot ([`Driver::label`]) and, unless it is the host
    /// `f64` controller, its torque difference to that one; with the firmware also its
    /// statistics and, with the counting plugin loaded, the instructions per step (max, median).
    pub fn describe_controller(&self, summary: &mut Summary) {
        summary.value("controller", self.driver.label());
        if !matches!(self.driver, Driver::HostF64) {
            summary.metric("torque_difference_to_host_f64_first_0_5_s_nm", self.torque_difference);
        }
        let Some(firmware) = self.driver.firmware() else { return };
        if let Some(stats) = firmware.stats {
            summary
                .value("firmware_cycles", stats.cycles)
                .value("firmware_deadline_misses", stats.deadline_misses)
                .value("firmware_worst_cycle_clock_cycles", stats.worst_cycle_cost)
                .value("firmware_link_faults", stats.link_faults);
        }
        match firmware.step_counts() {
            Ok(Some(counts)) => {
                summary
                    .value("firmware_step_instructions_max", counts.max)
                    .value("firmware_step_instructions_median", counts.median)
                    .value("firmware_steps_counted", counts.steps);
            }
            Ok(None) => {}
            Err(e) => eprintln!("pil: no instruction counts: {e}"),
        }
    }

    /// The force the environment applies to `frame` at time `t_s` (N, world frame): the pushes
    /// acting on it plus the contact forces of the surfaces it touches.
    fn external_force(&mut self, frame: kernel::FrameId, t_s: f64) -> Result<nalgebra::Vector3<f64>, SimError> {
        let mut force = self.sim.push_force(frame, t_s);
        for index in 0..self.sim.surfaces().len() {
            let touches = self.sim.surfaces().get(index).is_some_and(|s| s.frame == frame);
            if let Some(contact) = self.sim.surface_force(index)?.filter(|_| touches) {
                force += contact.force_world;
            }
        }
        Ok(force)
    }

    /// Runs `duration_s` of simulated time in the scenario loop ([`run_loop`]): per control
    /// cycle [`Rig::cycle`], [`Rig::record`] into a new time series, then `each` (goals, pushes,
    /// progress, checks), then the physics up to the next cycle. Stops at the first error.
    pub fn run<E>(&mut self, duration_s: f64, mut each: E) -> Result<TimeSeries, String>
    where
        E: FnMut(&mut Rig, &CycleInfo) -> Result<(), String>,
    {
        let mut series = TimeSeries::new(columns());
        run_loop(self, duration_s, CONTROL_PERIOD_S, |rig, info| {
            rig.cycle(info).map_err(|e| format!("cycle {}: {e}", info.cycle))?;
            series.push(rig.record(info)?)?;
            each(rig, info)
        })?;
        Ok(series)
    }
}

/// The rig's physics is its simulator's.
impl Physics for Rig {
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

/// The realistic plant's joint friction in the normal force of one contact (N).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrictionShare {
    /// The friction's share: the force the friction torque `τ_f` alone gives the contact,
    /// positive when it presses the TCP into it.
    pub share_n: f64,
    /// The largest share friction of the plant's magnitudes can give it at the current
    /// velocities: `Σ_j |W_ij| (τ_c,j + d_j |q̇_j|)` for the row `i` of the map `W` below.
    pub bound_n: f64,
}

/// The realistic plant's joint friction in the normal forces of the touched contacts, each
/// given by its TCP frame, the unit direction it presses along (world) and whether it is
/// touched. A joint torque `τ` gives rigid contacts along these directions the forces
/// `W τ = (J M_u⁻¹ Jᵀ)⁻¹ J M_u⁻¹ τ` (dynamically consistent), `J` the touched contacts' rows
/// `directionᵀ J_v` on the upper-body columns, `M_u` the upper-body block of `M` at the
/// simulator's state (the base is velocity controlled: joint torques do not move it). The
/// share is `W τ_f` of the friction torque ([`JustinSim::friction_torque`]), the bound the
/// largest over every sign of the friction magnitudes ([`JustinSim::friction_torque_bound`]).
/// Zero for an untouched contact and on the ideal plant. Errors: an unknown frame, a
/// non-finite state, a singular `J M_u⁻¹ Jᵀ`.
pub fn friction_contact_shares(
    sim: &JustinSim,
    contacts: &[(kernel::model::FrameId, nalgebra::Vector3<f64>, bool)],
) -> Result<Vec<FrictionShare>, String> {
    use kernel::dynamics::{crba, forward_kinematics, frame_jacobian};
    const U: usize = justin::UPPER_DOF;
    let (friction, magnitude) = (sim.friction_torque(), sim.friction_torque_bound());
    let touched: Vec<_> = contacts.iter().filter(|c| c.2).collect();
    if touched.is_empty() || magnitude.iter().all(|t| *t == 0.0) {
        return Ok(vec![FrictionShare::default(); contacts.len()]);
    }
    let model = sim.model();
    let mut data = kernel::model::Data::new(model);
    forward_kinematics(model, &mut data, sim.q(), sim.v()).map_err(|e| e.to_string())?;
    let base = justin::N - U;
    let mut rows = nalgebra::DMatrix::<f64>::zeros(touched.len(), U);
    for (mut row, (frame, direction, _)) in rows.row_iter_mut().zip(touched.iter()) {
        let mut jacobian = nalgebra::SMatrix::<f64, 6, { justin::N }>::zeros();
        frame_jacobian(model, &data, *frame, &mut jacobian).map_err(|e| e.to_string())?;
        row.copy_from(&(direction.transpose() * jacobian.fixed_view::<3, U>(0, base)));
    }
    let mass = crba(model, &mut data).fixed_view::<U, U>(base, base).into_owned();
    let factor = mass.cholesky().ok_or("the upper-body inertia is not positive definite")?;
    let mobility = factor.solve(&rows.transpose()); // M_u⁻¹ Jᵀ
    let reflected = (&rows * &mobility).cholesky().ok_or("J M⁻¹ Jᵀ is singular")?;
    let map = reflected.solve(&mobility.transpose()); // W
    let mut next = map
        .row_iter()
        .map(|w| FrictionShare { share_n: w.transpose().dot(&friction), bound_n: w.abs().transpose().dot(&magnitude) });
    Ok(contacts.iter().map(|c| if c.2 { next.next().unwrap_or_default() } else { FrictionShare::default() }).collect())
}
