//! The whole-body controller of Ch. 6: one [`Controller::step`] per control cycle maps a
//! sensor frame (joint positions, velocities, torques; platform pose, velocity, leg lengths) to
//! an actuator frame (joint torques, platform velocity command, leg rates, brake request) plus
//! [`Telemetry`].
//!
//! ## The cycle
//! 1. **Validate** the frame ([`faults::validate_frame`]); on a fault go to the safe output.
//! 2. **Dynamics** at `y = (r, q)` (5.7): kinematics, `M`, `C`, `g`, the tree-sparse factor
//!    `M = Lᵀ L` ([`crate::dynamics::TreeFactorization`], the Cartesian damping design) and,
//!    decoupled from it, the factor of the closed-loop inertia (the platform block replaced by
//!    the admittance mass, [`crate::platform::storage::closed_loop_inertia`]): the inertia the
//!    controller shapes, read by the collision, torso, projection and force-limit stages.
//! 3. **Contact-force limiter** ([`force_limit`]), then the **stack**: the limiter estimates the
//!    contact wrench of each TCP from the momentum residual, tightens the Table 7.1 force bounds
//!    per axis where the estimate exceeds them and adds the reaction along the limited axes to
//!    the platform's virtual force; every task of the hierarchy ([`config::TaskSpec`], data, not
//!    code) emits its rows on its level; a task moving between levels, or fading in or out after
//!    a planner command, is blended with the cubic (4.68) over `transition_s`
//!    ([`crate::hierarchy::push_transitioning`], [`crate::hierarchy::push_scaled`]).
//! 4. **Projection** ([`crate::hierarchy::project`]): dynamically consistent (`W` = the
//!    closed-loop inertia) for free motion or statically consistent (`W = I`) for contact tasks
//!    ([`config::Consistency`]), continuous shaping; `τ = Σ_i N_i τ_i` (4.7).
//! 5. **Platform** (Sec. 5.1): the platform rows of `τ` are the virtual force of the admittance
//!    (5.1), (5.12) (with a force deadband, Sec. 6.2); its velocity is the reference of the ICR
//!    singularity avoidance with leg motion (Fig. 3.10), which commands `ṙ_des` and `λ̇`.
//! 6. **Upper body** (5.13): `τ_q = τ₀ + Σ_i N_i τ_i` with the compensation
//!    `τ₀ = M_qr r̈ + C_qr ṙ + g_q` (5.14) for the commanded platform acceleration, plus the
//!    limiter's command-side correction, which keeps the rigid-contact force of `Σ_i N_i τ_i`
//!    along the limited TCP axes inside the bounds ([`force_limit`]).
//! 7. **Guards** ([`guard`]): torque limits with priority-preserving scaling, a torque-rate limit that keeps the change's direction,
//!    platform velocity and acceleration limits, leg-rate limits.
//! 8. **Telemetry**: TCP errors, storage (potential) per level and its rate, activations and
//!    torque norms per task, collision distance, contact from the momentum residual
//!    ([`observer`]), energy, saturation, fault.
//!
//! The Cartesian damping acts on the upper-body velocities only ((5.11): "Damping is not applied
//! to the platform subsystem"); the admittance damps the platform.
//!
//! ## Run-time changes
//! The planner changes the hierarchy, gains and goals through [`command::Command`]s
//! ([`Controller::apply`]): validated completely, then applied, or rejected with a typed
//! [`error::CommandError`] and nothing changed.
//!
//! ## Where things are
//! | module | what |
//! | --- | --- |
//! | [`frames`] | the I/O of one cycle: [`SensorFrame`] in, [`ActuatorFrame`] out |
//! | [`config`] | [`config::ControllerConfig`] and its validation, the task kinds ([`config::TaskKind`]) and their parameters |
//! | [`layout`], [`capacity`] | arms, joint groups and the robot layout; the table sizes |
//! | `task_set` | the validated task objects of the configuration and the dispatch of a task kind to its rows |
//! | `active_hierarchy` | the running hierarchy and its transitions (4.68) |
//! | `cycle` | [`Controller::step`]: the stages above, the safe output |
//! | [`command`], [`messages`] | planner commands (decoding, [`Controller::apply`]); the wire messages |
//! | [`telemetry`] | [`Telemetry`] and its wire summary |
//! | [`error`] | [`ConfigError`], [`error::CommandError`] |
//! | [`faults`], [`recovery`], [`guard`], [`observer`], [`force_limit`], [`mod@speed_barrier`], [`trajectory`] | the algorithms of the stages |
//!
//! A [`Controller`] holds its settings (models, configuration, validated task objects; changed
//! only by commands), its state (what one cycle leaves for the next) and its workspace (what a
//! cycle computes in), each a struct of its own (`settings`, `state`).

pub mod capacity;
pub mod command;
pub mod config;
pub mod error;
pub mod faults;
pub mod force_limit;
pub mod frames;
pub mod guard;
pub mod layout;
pub mod messages;
pub mod observer;
pub mod recovery;
pub mod speed_barrier;
pub mod telemetry;
pub mod trajectory;

mod active_hierarchy;
mod cycle;
mod settings;
mod state;
mod task_set;

use nalgebra::RealField;
use serde::Deserialize;

pub use capacity::MAX_ACTIVE;
pub use error::ConfigError;
pub use frames::{ActuatorFrame, SensorFrame, PLATFORM_DOF};
pub use telemetry::Telemetry;

use command::{decode_command, Command, CommandTarget};
use config::{ArmId, ControllerConfig, TaskSpec, MAX_TASK_ROWS};
use cycle::Cycle;
use error::CommandError;
use settings::{ControllerSettings, Derived};
use state::{ControllerState, InertiaFactors, Workspace};

use crate::model::{Data, Model};
use crate::tasks::cartesian_impedance::CartesianTarget;
use crate::tasks::collision::{CollisionData, CollisionModel};

/// The whole-body controller for a robot with `N = 3 + U` coordinates (platform first) or
/// `N = U` (a fixed base, every platform axis absent), `B` bodies, `F` frames, `A` arms (one or
/// two, each with a TCP, [`layout`]), and a collision model of `V` volumes and `P` pairs. See the
/// module docs.
///
/// Its parts: the settings (models, configuration, validated task objects; changed only by
/// [`Controller::apply`]), the state one cycle leaves for the next, and the workspace each
/// cycle computes in.
///
/// # Example
/// A platform `(x, y, θ)` carrying two one-joint arms, each with a TCP and a collision sphere;
/// the hierarchy is the strong collision field over the upper-body joint impedance. The first
/// valid frame sets the targets at the measured state, so the arms at rest get exactly the
/// gravity compensation (5.14).
/// ```
/// use hal::{JointSample, PlatformSample, LEGS};
/// use kernel::controller::config::*;
/// use kernel::controller::faults::SafeOutput;
/// use kernel::controller::force_limit::ForceLimitParameters;
/// use kernel::controller::recovery::RecoveryParameters;
/// use kernel::controller::speed_barrier::SpeedBarrierParameters;
/// use kernel::controller::{Controller, SensorFrame};
/// use kernel::hierarchy::{Recursion, Shaping};
/// use kernel::model::{Inertia, JointDrive, JointKind, ModelBuilder, Placement};
/// use kernel::platform::admittance::AdmittanceConfig;
/// use kernel::platform::avoidance::AvoidanceConfig;
/// use kernel::platform::coupling_compensation::CompensationSwitch;
/// use kernel::platform::icr::IcrRepulsionConfig;
/// use kernel::platform::legs::{LegAdmittanceConfig, ReturnGains};
/// use kernel::platform::{PlatformAxis, PlatformLayout};
/// use kernel::tasks::cartesian_impedance::AxisMask;
/// use kernel::tasks::collision::{CollisionModelBuilder, SweptSphere};
/// use nalgebra::{SVector, Translation3, UnitQuaternion, Unit, Vector3, Vector6};
///
/// // The robot: N = 5 coordinates (x, y, θ, right arm, left arm), B = 5 bodies, F = 2 TCPs.
/// let mut b = ModelBuilder::<f64, 5, 5, 2>::new(Vector3::new(0.0, 0.0, -9.81));
/// let at = |x: f64, y: f64, z: f64| {
///     Placement::from_parts(Translation3::new(x, y, z), UnitQuaternion::identity().into())
/// };
/// let slide = |axis: Vector3<f64>| JointKind::Prismatic { axis: Unit::new_normalize(axis) };
/// let turn = |axis: Vector3<f64>| JointKind::Revolute { axis: Unit::new_normalize(axis) };
/// let base_x = b.add_body(None, at(0.0, 0.0, 0.0), slide(Vector3::x()), JointDrive::actuated(0),
///     Inertia::point_mass(10.0, Vector3::zeros())).unwrap();
/// let base_y = b.add_body(Some(base_x), at(0.0, 0.0, 0.0), slide(Vector3::y()), JointDrive::actuated(1),
///     Inertia::point_mass(10.0, Vector3::zeros())).unwrap();
/// let base = b.add_body(Some(base_y), at(0.0, 0.0, 0.0), turn(Vector3::z()), JointDrive::actuated(2),
///     Inertia::point_mass(40.0, Vector3::new(0.1, 0.0, 0.3))).unwrap();
/// let mut arm = |y: f64, coordinate: usize| {
///     // A horizontal 0.5 m arm about y, its 2 kg at 0.3 m from the shoulder.
///     let body = b.add_body(Some(base), at(0.0, y, 1.0), turn(Vector3::y()), JointDrive::actuated(coordinate),
///         Inertia::point_mass(2.0, Vector3::new(0.3, 0.0, 0.0))).unwrap();
///     (body, b.add_frame(Some(body), at(0.5, 0.0, 0.0)).unwrap())
/// };
/// let (right_arm, right_tcp) = arm(-0.2, 3);
/// let (left_arm, left_tcp) = arm(0.2, 4);
/// let model = b.try_build().unwrap();
/// let mut c = CollisionModelBuilder::<f64, 2, 1>::new();
/// c.add_volume(Some(right_arm), SweptSphere::sphere(Vector3::new(0.5, 0.0, 0.0), 0.05)).unwrap();
/// c.add_volume(Some(left_arm), SweptSphere::sphere(Vector3::new(0.5, 0.0, 0.0), 0.05)).unwrap();
/// let collision = c.try_build(&model, &[]).unwrap();
///
/// // The configuration: every gain and limit of the controller.
/// let cartesian = CartesianParameters {
///     translational_stiffness: [500.0; 3],
///     rotational_stiffness: [20.0; 3],
///     damping_ratio: 0.7,
///     force_lower: [f64::NEG_INFINITY; 6],
///     force_upper: [f64::INFINITY; 6],
/// };
/// let field = CollisionFieldParameters {
///     max_force: 20.0, influence_distance: 0.1, damping_ratio: 0.7, activation_full: 0.0, activation_zero: 0.1,
/// };
/// let avoidance = AvoidanceConfig {
///     repulsion: IcrRepulsionConfig {
///         leg_directions: [45.0_f64, 135.0, 225.0, 315.0].map(f64::to_radians),
///         max_extension: 0.12, extension_ratio: 0.4, max_force: 0.8, min_yaw_rate: 1e-3,
///     },
///     legs: LegAdmittanceConfig {
///         mass: 0.2, damping: 1.0, cubic_stiffness: 1e3, nominal_length: 0.4, min_length: 0.3, max_length: 0.5,
///     },
///     return_gains: ReturnGains::critically_damped(2.0, 0.05),
///     icr_avoidance: false,
///     leg_motion: false,
/// };
/// let config = ControllerConfig {
///     period_s: 1e-3,
///     layout: RobotLayout {
///         tcp: [right_tcp, left_tcp],
///         platform: PlatformLayout::try_new::<5>([0, 1, 2].map(PlatformAxis::Admitted)).unwrap(),
///         torso: None,
///         arms: [[false, false, false, true, false], [false, false, false, false, true]],
///     },
///     recursion: Recursion::Augmented,
///     consistency: Consistency::Dynamic,
///     shaping: Shaping::Continuous { singular_full: 0.05, singular_start: 0.15 },
///     transition_s: 1.0,
///     cartesian: [cartesian; 2],
///     cartesian_fallback_damping: Vector6::repeat(10.0),
///     collision: [field; 2],
///     singularity: SingularityParameters {
///         rows: AxisMask::new([false, false, true, false, false, false]), // one row per one-joint arm
///         threshold: 0.025, full_activation: 0.01, stiffness: 100.0, damping: 1.0,
///     },
///     end_stops: EndStopParameters { margin: 0.1, stiffness: SVector::repeat(10.0), damping: SVector::repeat(1.0) },
///     torso_workspace: None,
///     joint_stiffness: SVector::repeat(50.0),
///     joint_damping: SVector::repeat(5.0),
///     safe_damping: SVector::repeat(5.0),
///     joint_damping_loop_gain: 0.4,
///     platform: PlatformParameters {
///         admittance: AdmittanceConfig {
///             mass: Vector3::new(50.0, 50.0, 10.0),
///             damping: Vector3::new(200.0, 200.0, 40.0),
///             force_limit: Vector3::new(100.0, 100.0, 40.0),
///             free_axes: [true; 3],
///         },
///         avoidance,
///         compensation: CompensationSwitch::ON,
///         force_deadband: [0.0; 3],
///     },
///     output_limits: OutputLimits {
///         torque_rate: SVector::repeat(1e4),
///         base_velocity: Vector3::repeat(1.0),
///         base_acceleration: Vector3::repeat(2.0),
///         leg_rate: 0.2,
///     },
///     input_limits: InputLimits {
///         position_tolerance: 0.05, velocity_factor: 1.5, max_cycle_gap: 5, brake_after_cycles: 100,
///     },
///     observer: ObserverParameters { gain: 50.0, contact_threshold: 5.0 },
///     force_limit: ForceLimitParameters {
///         enabled: false, margin: 0.05, gain: 3.0, max_correction: 10.0, regularisation: 1e-4,
///     },
///     speed_barrier: SpeedBarrierParameters {
///         onset: 0.5, full: 0.9, braking_time_s: 0.002, max_torque_fraction: 0.25,
///     },
///     recovery: RecoveryParameters { valid_cycles: 10, margin: 0.2, blend_s: 0.1 },
/// };
/// let hierarchy = [
///     TaskSpec { kind: TaskKind::CollisionAvoidance(Field::Strong), level: 0 },
///     TaskSpec { kind: TaskKind::JointImpedance(JointGroup::UpperBody), level: 1 },
/// ];
/// let mut controller = Controller::<f64, 5, 5, 2, 2, 2, 1, 2>::try_new(model, collision, config, &hierarchy).unwrap();
///
/// // One cycle with the arms horizontal and everything at rest.
/// let frame = SensorFrame {
///     joints: JointSample { position: [0.0; 2], velocity: [0.0; 2], torque: [0.0; 2], cycle: 1 },
///     platform: PlatformSample { pose: [0.0; 3], velocity: [0.0; 3], leg_lengths: [0.4; LEGS], cycle: 1 },
/// };
/// let output = *controller.step(&frame);
/// assert_eq!(output.mode, SafeOutput::Normal);
/// assert_eq!(controller.telemetry().fault, None);
/// // The hands are 0.4 m apart: no collision row; the joint springs are at their targets.
/// assert_eq!(controller.telemetry().collision_rows, 0);
/// let gravity = controller.data().gravity_torque;
/// for (torque, g) in output.torque.iter().zip(gravity.iter().skip(3)) {
///     // 2 kg at 0.3 m: 5.9 Nm holds each arm up.
///     assert!((g.abs() - 2.0 * 9.81 * 0.3).abs() < 1e-9);
///     assert!((torque - g).abs() < 1e-9);
/// }
/// assert_eq!(output.platform.velocity, [0.0; 3]);
/// ```
#[derive(Clone, Debug)]
pub struct Controller<
    T: RealField,
    const N: usize,
    const B: usize,
    const F: usize,
    const U: usize,
    const V: usize,
    const P: usize,
    const A: usize,
> {
    settings: ControllerSettings<T, N, B, F, V, P, A>,
    state: ControllerState<T, N, U, A>,
    work: Workspace<T, N, B, F, V, P, A>,
    factors: InertiaFactors<T, N>,
}

impl<
        T: RealField + Copy,
        const N: usize,
        const B: usize,
        const F: usize,
        const U: usize,
        const V: usize,
        const P: usize,
        const A: usize,
    > Controller<T, N, B, F, U, V, P, A>
{
    /// Validates everything once: the configuration, every task's parameters and the initial
    /// hierarchy. The controller starts (targets at the measured poses) on its first valid
    /// frame.
    #[inline(always)]
    pub fn try_new(
        model: Model<T, N, B, F>,
        collision_model: CollisionModel<T, V, P>,
        config: ControllerConfig<T, N, A>,
        hierarchy: &[TaskSpec],
    ) -> Result<Self, ConfigError> {
        const {
            assert!(
                N == U + PLATFORM_DOF || N == U,
                "N must be U joints after the platform's 3 coordinates, or U joints on a fixed base"
            )
        };
        const { assert!(A >= 1 && A <= layout::MAX_ARMS, "one to MAX_ARMS arms (the task names and joint groups)") };
        const { assert!(N <= MAX_TASK_ROWS, "a joint-space task emits up to N rows") };
        // Everything fallible first, out of line, with a small result ([`Derived::try_new`]);
        // then the controller in one infallible expression of its final fields: no by-value
        // part of it is built before a branch that may return an error, so the caller's frame
        // (the firmware's `init`) holds the models, the configuration and at most one
        // controller, not copies of it beside the validation's temporaries.
        let Derived { tasks, tree, admittance, avoidance, hierarchy: active } =
            Derived::try_new(&model, &config, hierarchy, N - U)?;
        Ok(Self {
            work: Workspace::new(&model, &collision_model, tasks.broad_phase_distance()),
            factors: InertiaFactors::new(tree),
            state: ControllerState::new(&config, active, admittance, avoidance),
            settings: ControllerSettings { model, collision_model, config, tasks },
        })
    }

    /// The model.
    pub fn model(&self) -> &Model<T, N, B, F> {
        &self.settings.model
    }

    /// The current configuration (changed only by accepted commands).
    pub fn config(&self) -> &ControllerConfig<T, N, A> {
        &self.settings.config
    }

    /// The hierarchy as the planner last set it: `(task, level)` of every entry that is not
    /// fading out.
    pub fn hierarchy(&self) -> impl Iterator<Item = TaskSpec> + '_ {
        self.state.hierarchy.planned()
    }

    /// `true` while a task moves between levels or fades.
    pub fn in_transition(&self) -> bool {
        self.state.hierarchy.in_transition()
    }

    /// `true` once a valid frame has been processed (targets are set).
    pub fn started(&self) -> bool {
        self.state.started
    }

    /// The dynamics workspace of the last valid cycle. The step uses `C q̇`-type products only
    /// ([`crate::dynamics::coriolis_product`]): `coriolis` and the Coriolis composites are not computed.
    pub fn data(&self) -> &Data<T, N, B, F> {
        &self.work.data
    }

    /// The collision geometry of the last cycle with a collision task.
    pub fn collision_data(&self) -> &CollisionData<T, V, P> {
        &self.work.collision_data
    }

    /// The current TCP target of `arm`, `None` for an arm the robot does not have.
    pub fn tcp_target(&self, arm: ArmId) -> Option<CartesianTarget<T>> {
        arm.of(&self.state.hands).map(|trajectory| trajectory.sample())
    }

    /// The telemetry of the last cycle.
    pub fn telemetry(&self) -> &Telemetry<T, N, A> {
        &self.state.telemetry
    }

    /// The output of the last cycle.
    pub fn output(&self) -> &ActuatorFrame<T, U> {
        &self.state.output
    }

    /// One control cycle: never panics, always returns a checked output (the whole-body torque,
    /// or the safe output of [`faults`] with the fault in the telemetry).
    pub fn step(&mut self, frame: &SensorFrame<T, U>) -> &ActuatorFrame<T, U> {
        Cycle { settings: &self.settings, state: &mut self.state, work: &mut self.work }.step(frame, &mut self.factors);
        &self.state.output
    }

    /// Applies a planner command, all or nothing ([`command`]).
    pub fn apply(&mut self, command: &Command<T>) -> Result<(), CommandError> {
        CommandTarget { settings: &mut self.settings, state: &mut self.state, work: &mut self.work }.apply(command)
    }

    /// Decodes a command from postcard bytes and applies it.
    pub fn apply_bytes(&mut self, bytes: &[u8]) -> Result<(), CommandError>
    where
        T: for<'de> Deserialize<'de>,
    {
        let command = decode_command::<T>(bytes)?;
        self.apply(&command)
    }
}
