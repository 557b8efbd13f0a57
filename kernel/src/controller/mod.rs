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
//! 7. **Guards** ([`guard`]): torque and torque-rate limits with priority-preserving scaling,
//!    platform velocity and acceleration limits, leg-rate limits.
//! 8. **Telemetry**: TCP errors, storage (potential) per level and its rate, activations and
//!    torque norms per task, collision distance, contact from the momentum residual
//!    ([`observer`]), energy, saturation, fault.
//!
//! The Cartesian damping acts on the upper-body velocities only ((5.11): "Damping is not applied
//! to the platform subsystem"); the admittance damps the platform.
//!
//! ## Run-time changes
//! The planner changes the hierarchy, gains and goals through [`messages::Command`]s
//! ([`Controller::apply`]): validated completely, then applied, or rejected with a typed
//! [`messages::CommandError`] and nothing changed.

pub mod config;
pub mod faults;
pub mod force_limit;
pub mod guard;
pub mod messages;
pub mod observer;
pub mod recovery;
pub mod speed_barrier;
pub mod trajectory;

use heapless::Vec;
use nalgebra::{convert, Matrix3, RealField, SVector, Vector3, Vector6};

use hal::{JointSample, PlatformCommand, PlatformSample, LEGS};

use crate::dynamics::{
    coriolis_matrix, crba, forward_kinematics, gravity, DynamicsError, TreeFactorization, TreeStructure,
};
use crate::hierarchy::{
    project, push_scaled, push_transitioning, transition_weight, HierarchyConfig, HierarchyData, Stack, Weighting,
};
use crate::math::sqrt;
use crate::math::Placement;
use crate::model::{Data, Model};
use crate::platform::admittance::Admittance;
use crate::platform::avoidance::{PlatformAvoidance, PlatformReference};
use crate::platform::coupling_compensation::coupling_compensation;
use crate::platform::storage::closed_loop_inertia;
use crate::platform::PlatformError;
use crate::tasks::cartesian_impedance::{
    cartesian_impedance_factored, AxisMask, CartesianImpedance, CartesianImpedanceConfig, CartesianTarget,
    StiffnessFrame,
};
use crate::tasks::collision::{
    collision_rows_shared, CollisionData, CollisionModel, CollisionParameters, PairRowCache,
};
use crate::tasks::end_stops::{end_stops, EndStop, EndStopConfig};
use crate::tasks::joint_impedance::{joint_impedance, JointImpedance, JointImpedanceConfig, JointTarget};
use crate::tasks::manipulability::{manipulability_avoidance, Manipulability, ManipulabilityConfig};
use crate::tasks::torso_workspace::{torso_workspace, TorsoWorkspace};
use crate::tasks::{TaskError, TaskRows};

use config::{
    CartesianParameters, CollisionFieldParameters, Consistency, ControllerConfig, Hand, JointGroup, TaskKind, TaskSpec,
    MAX_LEVELS, MAX_ROWS, MAX_TASKS, MAX_TASK_ROWS,
};
use faults::{validate_frame, Fault, SafeOutput};
use force_limit::{ForceLimiter, HandLimits};
use guard::{limit_base_velocity, limit_leg_rates, rate_exceeded, saturate_with_priority, torque_box, Saturation};
use observer::MomentumObserver;
use recovery::Recovery;
use speed_barrier::{joint_mobility, speed_barrier, JointLimits};
use trajectory::{JointTrajectory, PoseTrajectory};

/// Number of platform coordinates `r = (x, y, θ)`; they come first in `q`.
pub const PLATFORM_DOF: usize = 3;

/// Most hierarchy entries at once: the tasks of the current hierarchy plus those fading out.
pub const MAX_ACTIVE: usize = 2 * MAX_TASKS;

/// One cycle's sensor input: the upper body's `U` joints and the platform.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorFrame<T, const U: usize> {
    /// Joint positions, velocities and torques of coordinates `3..3+U`.
    pub joints: JointSample<T, U>,
    /// Platform pose `(x, y, θ)` (coordinates `0..3`), velocity and leg lengths.
    pub platform: PlatformSample<T>,
}

/// One cycle's output.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ActuatorFrame<T, const U: usize> {
    /// Joint torques (Nm, N), within the effort and rate limits.
    pub torque: [T; U],
    /// Platform velocity command and leg rates.
    pub platform: PlatformCommand<T>,
    /// `true` requests the brakes (a persistent fault).
    pub brake: bool,
    /// Which output this is.
    pub mode: SafeOutput,
}

/// What the controller found in its last cycle (Sec. 7.2: "information about task execution").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Telemetry<T: RealField, const N: usize> {
    /// Cycle counter of the frame.
    pub cycle: u64,
    /// Controller time since the first valid frame (s).
    pub time_s: T,
    /// The fault of this cycle, if any.
    pub fault: Option<Fault>,
    /// Consecutive faulty cycles.
    pub fault_cycles: u32,
    /// Changes of the output mode since the first cycle ([`recovery`]).
    pub mode_changes: u32,
    /// TCP error `(p − p_des, 2ε)` in the desired frame's axes (m, rad-like), right then left;
    /// zero for a TCP without Cartesian task.
    pub tcp_error: [Vector6<T>; 2],
    /// Where the Cartesian force limits (Table 7.1) acted: the task clamped its spring force,
    /// or the command-side limit the commanded contact force ([`force_limit`]).
    pub tcp_force_limited: [[bool; 6]; 2],
    /// Estimated wrench each TCP applies on its environment (N, Nm), desired-frame axes, right
    /// then left: `−(J_u J_uᵀ + μ I)⁻¹ J_u τ̂_ext` ([`force_limit`]).
    pub contact_wrench: [Vector6<T>; 2],
    /// Contact-force governor correction per hand and axis (N, Nm): positive lowers the
    /// upper force bound, negative raises the lower one ([`force_limit`]).
    pub force_limit_correction: [Vector6<T>; 2],
    /// Number of levels in the last projection.
    pub level_count: usize,
    /// Potential energy of each level's springs (J): the level's storage function.
    pub level_storage: [T; MAX_LEVELS],
    /// Its rate, backward difference (W).
    pub level_storage_rate: [T; MAX_LEVELS],
    /// `‖N_i τ_i‖` per level (Nm).
    pub level_torque_norm: [T; MAX_LEVELS],
    /// Conflict of each level with the ones above, `1 − ‖N_i τ_i‖/‖τ_i‖`.
    pub level_conflict: [T; MAX_LEVELS],
    /// Hierarchy entries of the last cycle, in hierarchy order (the first `task_count`).
    pub tasks: [Option<TaskKind>; MAX_ACTIVE],
    /// Number of entries in `tasks`.
    pub task_count: usize,
    /// Largest row activation of each entry.
    pub task_activation: [T; MAX_ACTIVE],
    /// `‖τ_task‖` of each entry before projection (Nm), as in Fig. 6.5.
    pub task_torque_norm: [T; MAX_ACTIVE],
    /// Smallest distance over all collision pairs (m), `None` without a collision task; exact
    /// up to the broad-phase distance (the larger emit distance of the two fields), a lower
    /// bound beyond it.
    pub min_collision_distance: Option<T>,
    /// Collision rows on the stack.
    pub collision_rows: usize,
    /// Manipulability of each arm (when its task runs).
    pub manipulability: [T; 2],
    /// Estimated external joint torque (momentum residual, Nm).
    pub external_torque: SVector<T, N>,
    /// `‖external_torque‖` above the threshold.
    pub contact: bool,
    /// `½ ẏᵀ M_cl ẏ` with the closed-loop inertia (J).
    pub kinetic_energy: T,
    /// Sum of the task potentials (J).
    pub potential_energy: T,
    /// Virtual force on the platform after the deadband (N, N, Nm).
    pub virtual_force: Vector3<T>,
    /// Commanded platform velocity (m/s, m/s, rad/s).
    pub base_velocity: Vector3<T>,
    /// Commanded platform acceleration used in the compensation (m/s², rad/s²).
    pub base_acceleration: Vector3<T>,
    /// `true` while the ICR repulsion acts.
    pub icr_repelling: bool,
    /// What the output guards changed.
    pub saturation: Saturation<T>,
}

/// Why [`Controller::try_new`] refused its inputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConfigError {
    /// A task refused its parameters.
    Task(TaskError),
    /// A platform component refused its parameters.
    Platform(PlatformError),
    /// A controller parameter is out of range.
    InvalidParameter {
        /// Which one.
        name: &'static str,
    },
    /// The initial hierarchy is invalid.
    Hierarchy(messages::CommandError),
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Task(e) => write!(f, "task: {e}"),
            Self::Platform(e) => write!(f, "platform: {e}"),
            Self::InvalidParameter { name } => write!(f, "invalid parameter {name}"),
            Self::Hierarchy(e) => write!(f, "hierarchy: {e}"),
        }
    }
}

impl core::error::Error for ConfigError {}

/// The platform commands of one cycle, after the guards.
#[derive(Clone, Copy, Debug, PartialEq)]
struct PlatformStep<T> {
    /// `ṙ_des` (m/s, m/s, rad/s).
    velocity: Vector3<T>,
    /// Commanded `r̈` (the change of `ṙ_des` over the period), for (5.14).
    acceleration: Vector3<T>,
    /// `λ̇` (m/s).
    leg_rates: [T; LEGS],
}

/// A hierarchy entry, possibly moving: on `from` with weight `1 − σ` and on `to` with `σ`,
/// `σ = transition_weight(progress)`; `None` is "not in the hierarchy".
#[derive(Clone, Copy, Debug, PartialEq)]
struct ActiveTask<T> {
    kind: TaskKind,
    from: Option<u8>,
    to: Option<u8>,
    progress: T,
}

/// Validated task objects built from the configuration.
#[derive(Clone, Debug)]
struct TaskSet<T: RealField, const N: usize> {
    cartesian: [CartesianImpedance<T>; 2],
    collision: [CollisionParameters<T>; 2],
    singularity: [Manipulability<T, N>; 2],
    end_stops: Vec<EndStop<T, N>, MAX_TASK_ROWS>,
    torso: Option<TorsoWorkspace<T, N>>,
    /// Per [`JointGroup`] (see [`group_index`]): impedance, then pure damping.
    joint: [[JointImpedance<T, N>; 5]; 2],
}

fn cartesian_task<T: RealField + Copy, const N: usize>(
    config: &ControllerConfig<T, N>,
    hand: Hand,
    parameters: &CartesianParameters<T>,
) -> Result<CartesianImpedance<T>, TaskError> {
    let frame = config.layout.tcp.get(hand.index()).copied().ok_or(TaskError::InvalidParameter { name: "tcp" })?;
    CartesianImpedance::try_new(CartesianImpedanceConfig {
        frame,
        axes: AxisMask::ALL,
        stiffness_frame: StiffnessFrame::Desired,
        translational_stiffness: Matrix3::from_diagonal(&Vector3::from(parameters.translational_stiffness)),
        rotational_stiffness: Matrix3::from_diagonal(&Vector3::from(parameters.rotational_stiffness)),
        damping_ratio: parameters.damping_ratio,
        force_lower: Vector6::from(parameters.force_lower),
        force_upper: Vector6::from(parameters.force_upper),
        fallback_damping: config.cartesian_fallback_damping,
    })
}

fn collision_parameters<T: RealField + Copy>(
    p: &CollisionFieldParameters<T>,
) -> Result<CollisionParameters<T>, TaskError> {
    CollisionParameters::try_new(
        p.max_force,
        p.influence_distance,
        p.damping_ratio,
        p.activation_full,
        p.activation_zero,
    )
}

impl<T: RealField + Copy, const N: usize> TaskSet<T, N> {
    /// The distance below which both collision fields need exact pair distances (their larger
    /// emit distance): the broad phase of the geometry update skips the pairs beyond it.
    fn broad_phase_distance(&self) -> T {
        self.collision.iter().map(CollisionParameters::emit_distance).fold(T::zero(), |m, d| m.max(d))
    }

    fn try_new<const B: usize, const F: usize>(
        model: &Model<T, N, B, F>,
        config: &ControllerConfig<T, N>,
    ) -> Result<Self, ConfigError> {
        let [right, left] = config.cartesian;
        let cartesian = [
            cartesian_task(config, Hand::Right, &right).map_err(ConfigError::Task)?,
            cartesian_task(config, Hand::Left, &left).map_err(ConfigError::Task)?,
        ];
        let [strong, weak] = config.collision;
        let collision = [
            collision_parameters(&strong).map_err(ConfigError::Task)?,
            collision_parameters(&weak).map_err(ConfigError::Task)?,
        ];
        let s = &config.singularity;
        let arm = |hand: Hand| {
            let frame =
                config.layout.tcp.get(hand.index()).copied().ok_or(TaskError::InvalidParameter { name: "tcp" })?;
            Manipulability::try_new(ManipulabilityConfig {
                frame,
                rows: s.rows,
                coordinates: config.layout.coordinates(JointGroup::Arm(hand)),
                threshold: s.threshold,
                full_activation: s.full_activation,
                stiffness: s.stiffness,
                damping: s.damping,
            })
        };
        let singularity = [arm(Hand::Right).map_err(ConfigError::Task)?, arm(Hand::Left).map_err(ConfigError::Task)?];
        let mut stops = Vec::new();
        let limits = &model.limits;
        let e = &config.end_stops;
        for i in (0..N).filter(|i| !config.layout.platform.is_platform(*i)) {
            let (Some(&lower), Some(&upper)) = (limits.position_lower.get(i), limits.position_upper.get(i)) else {
                continue;
            };
            let span = upper - lower;
            if !(span.is_finite() && span > e.margin + e.margin) {
                continue;
            }
            let stop = EndStop::try_new(EndStopConfig::coordinate(i, lower, upper, e.margin, e.stiffness, e.damping))
                .map_err(ConfigError::Task)?;
            stops
                .push(stop)
                .map_err(|_| ConfigError::InvalidParameter { name: "end stops: more than MAX_TASK_ROWS" })?;
        }
        let torso = config.torso_workspace.map(TorsoWorkspace::try_new).transpose().map_err(ConfigError::Task)?;
        let joint_task = |group: JointGroup, stiffness: SVector<T, N>, damping: SVector<T, N>| {
            JointImpedance::try_new(JointImpedanceConfig {
                selected: config.layout.coordinates(group),
                stiffness,
                damping,
            })
            .map_err(ConfigError::Task)
        };
        let mut joint = [[joint_task(JointGroup::Platform, SVector::zeros(), SVector::zeros())?; 5]; 2];
        let [impedance, damping] = &mut joint;
        for ((group, imp), damp) in JointGroup::ALL.iter().zip(impedance.iter_mut()).zip(damping.iter_mut()) {
            *imp = joint_task(*group, config.joint_stiffness, config.joint_damping)?;
            *damp = joint_task(*group, SVector::zeros(), config.safe_damping)?;
        }
        Ok(Self { cartesian, collision, singularity, end_stops: stops, torso, joint })
    }
}

/// The whole-body controller for a robot with `N = 3 + U` coordinates (platform first), `B`
/// bodies, `F` frames, and a collision model of `V` volumes and `P` pairs. See the module docs.
#[derive(Clone, Debug)]
pub struct Controller<
    T: RealField,
    const N: usize,
    const B: usize,
    const F: usize,
    const U: usize,
    const V: usize,
    const P: usize,
> {
    model: Model<T, N, B, F>,
    collision_model: CollisionModel<T, V, P>,
    config: ControllerConfig<T, N>,
    tasks: TaskSet<T, N>,
    hierarchy: Vec<ActiveTask<T>, MAX_ACTIVE>,
    hands: [PoseTrajectory<T>; 2],
    joint_goal: JointTrajectory<T, N>,
    admittance: Admittance<T>,
    avoidance: PlatformAvoidance<T>,
    reference_pose: Vector3<T>,
    observer: MomentumObserver<T, N>,
    force_limiter: ForceLimiter<T, N>,
    /// The Cartesian damping force of each hand this cycle (task axes), outside the force limits.
    cartesian_damping: [Vector6<T>; 2],
    data: Data<T, N, B, F>,
    /// The elimination tree of the model's inertia ([`TreeFactorization`]).
    tree: TreeStructure<N>,
    collision_data: CollisionData<T, V, P>,
    stack: Stack<T, N, MAX_ROWS>,
    projection: HierarchyData<T, N, MAX_ROWS, MAX_LEVELS>,
    rows: TaskRows<T, N, MAX_TASK_ROWS>,
    started: bool,
    recovery: Recovery<T>,
    last_cycle: Option<u64>,
    hold_gravity: SVector<T, N>,
    previous_torque: SVector<T, N>,
    previous_base_velocity: Vector3<T>,
    telemetry: Telemetry<T, N>,
    output: ActuatorFrame<T, U>,
}

impl<
        T: RealField + Copy,
        const N: usize,
        const B: usize,
        const F: usize,
        const U: usize,
        const V: usize,
        const P: usize,
    > Controller<T, N, B, F, U, V, P>
{
    /// Validates everything once: the configuration, every task's parameters and the initial
    /// hierarchy. The controller starts (targets at the measured poses) on its first valid
    /// frame.
    pub fn try_new(
        model: Model<T, N, B, F>,
        collision_model: CollisionModel<T, V, P>,
        config: ControllerConfig<T, N>,
        hierarchy: &[TaskSpec],
    ) -> Result<Self, ConfigError> {
        const { assert!(N == U + PLATFORM_DOF, "N must be the platform's 3 coordinates plus U joints") };
        const { assert!(N <= MAX_TASK_ROWS, "a joint-space task emits up to N rows") };
        validate_config(&config)?;
        let tasks = TaskSet::try_new(&model, &config)?;
        let admittance = Admittance::try_new(config.platform.admittance).map_err(ConfigError::Platform)?;
        let avoidance = PlatformAvoidance::try_new(config.platform.avoidance).map_err(ConfigError::Platform)?;
        let active = messages::initial_hierarchy(hierarchy).map_err(ConfigError::Hierarchy)?;
        let data = Data::new(&model);
        let tree = TreeStructure::new(&model);
        let mut collision_data = CollisionData::new(&collision_model);
        collision_data.exact_within = Some(tasks.broad_phase_distance());
        Ok(Self {
            observer: MomentumObserver::new(config.observer.gain),
            force_limiter: ForceLimiter::new(),
            cartesian_damping: [Vector6::zeros(); 2],
            hands: [PoseTrajectory::hold(Placement::identity()); 2],
            joint_goal: JointTrajectory::hold(SVector::zeros()),
            model,
            collision_model,
            config,
            tasks,
            hierarchy: active,
            admittance,
            avoidance,
            reference_pose: Vector3::zeros(),
            data,
            tree,
            collision_data,
            stack: Stack::new(),
            projection: HierarchyData::default(),
            rows: TaskRows::new(),
            started: false,
            recovery: Recovery::Normal,
            last_cycle: None,
            hold_gravity: SVector::zeros(),
            previous_torque: SVector::zeros(),
            previous_base_velocity: Vector3::zeros(),
            telemetry: empty_telemetry(),
            output: ActuatorFrame {
                torque: [T::zero(); U],
                platform: PlatformCommand { velocity: [T::zero(); 3], leg_rates: [T::zero(); LEGS] },
                brake: false,
                mode: SafeOutput::Hold,
            },
        })
    }

    /// The model.
    pub fn model(&self) -> &Model<T, N, B, F> {
        &self.model
    }

    /// The current configuration (changed only by accepted commands).
    pub fn config(&self) -> &ControllerConfig<T, N> {
        &self.config
    }

    /// The hierarchy as the planner last set it: `(task, level)` of every entry that is not
    /// fading out.
    pub fn hierarchy(&self) -> impl Iterator<Item = TaskSpec> + '_ {
        self.hierarchy.iter().filter_map(|a| a.to.map(|level| TaskSpec { kind: a.kind, level }))
    }

    /// `true` while a task moves between levels or fades.
    pub fn in_transition(&self) -> bool {
        self.hierarchy.iter().any(|a| a.from != a.to)
    }

    /// `true` once a valid frame has been processed (targets are set).
    pub fn started(&self) -> bool {
        self.started
    }

    /// The dynamics workspace of the last valid cycle.
    pub fn data(&self) -> &Data<T, N, B, F> {
        &self.data
    }

    /// The collision geometry of the last cycle with a collision task.
    pub fn collision_data(&self) -> &CollisionData<T, V, P> {
        &self.collision_data
    }

    /// The current TCP target of `hand`.
    pub fn tcp_target(&self, hand: Hand) -> CartesianTarget<T> {
        self.hands
            .get(hand.index())
            .map_or_else(|| CartesianTarget::at_rest(Placement::identity()), PoseTrajectory::sample)
    }

    /// The telemetry of the last cycle.
    pub fn telemetry(&self) -> &Telemetry<T, N> {
        &self.telemetry
    }

    /// The output of the last cycle.
    pub fn output(&self) -> &ActuatorFrame<T, U> {
        &self.output
    }

    /// One control cycle: never panics, always returns a checked output (the whole-body torque,
    /// or the safe output of [`faults`] with the fault in the telemetry).
    pub fn step(&mut self, frame: &SensorFrame<T, U>) -> &ActuatorFrame<T, U> {
        self.telemetry.cycle = frame.joints.cycle;
        match self.control(frame) {
            Ok(()) => {
                self.telemetry.fault = self.recovery.output().1;
                self.telemetry.fault_cycles = 0;
                self.recovery.valid_cycle(&self.config.recovery, self.config.period_s);
            }
            Err(fault) => {
                self.recovery.fault(fault);
                self.safe_output(frame, fault);
            }
        }
        if self.last_cycle.is_none_or(|last| frame.joints.cycle > last) {
            self.last_cycle = Some(frame.joints.cycle);
        }
        &self.output
    }

    /// `y = (r, q)` and `ẏ` from a frame.
    fn state(frame: &SensorFrame<T, U>) -> (SVector<T, N>, SVector<T, N>) {
        let mut q = SVector::<T, N>::zeros();
        let mut v = SVector::<T, N>::zeros();
        let positions = frame.platform.pose.iter().chain(frame.joints.position.iter());
        let velocities = frame.platform.velocity.iter().chain(frame.joints.velocity.iter());
        for ((qi, vi), (p, r)) in q.iter_mut().zip(v.iter_mut()).zip(positions.zip(velocities)) {
            *qi = *p;
            *vi = *r;
        }
        (q, v)
    }

    fn control(&mut self, frame: &SensorFrame<T, U>) -> Result<(), Fault> {
        let input_limits = self.recovery.input_limits(&self.config.input_limits, &self.config.recovery);
        validate_frame(&self.model, &input_limits, frame, PLATFORM_DOF, self.last_cycle)?;
        let dt = self.config.period_s;
        let (q, v) = Self::state(frame);
        let (model, data) = (&self.model, &mut self.data);
        forward_kinematics(model, data, &q, &v).map_err(Fault::Dynamics)?;
        crba(model, data);
        coriolis_matrix(model, data);
        gravity(model, data);
        let layout = self.config.layout.platform;
        let closed_loop = closed_loop_inertia(&data.mass_matrix, &layout, &self.config.platform.admittance.mass);
        // The plain `M = Lᵀ L` for the Cartesian damping design, shared by both hands (`None`:
        // not positive definite, the tasks fall back to their configured damping).
        let mut mass = TreeFactorization::from_structure(self.tree);
        let mass_factored = mass.factorize(&self.data.mass_matrix).is_ok();
        // The closed-loop inertia's tree factor, the one factor of every consumer of `M̃⁻¹`
        // (collision, torso, projection, force limit): the platform rows and columns decoupled
        // from the factor of `M` (or factored anew when `M` is not positive definite). Fails
        // with `MassMatrixNotPositiveDefinite` when `M̃` is not positive definite.
        let mut inertia = mass.clone();
        let mut decoupled = [false; N];
        for c in layout.axes().iter().filter_map(|a| a.coordinate()) {
            if let Some(flag) = decoupled.get_mut(c) {
                *flag = true;
            }
        }
        if mass_factored { inertia.decouple(&decoupled, &closed_loop) } else { inertia.factorize(&closed_loop) }
            .map_err(Fault::Dynamics)?;
        let mass = mass_factored.then_some(&mass);
        if !self.started {
            self.start(&q, frame)?;
        }
        self.advance_targets(dt);
        self.limit_contact_forces(dt)?;
        self.build_stack(mass, &inertia)?;

        let inverse;
        let weighting = match self.config.consistency {
            Consistency::Static => Weighting::Identity,
            Consistency::Dynamic => {
                inverse = inertia.inverse();
                Weighting::InverseInertia(&inverse)
            }
        };
        let config = HierarchyConfig {
            recursion: self.config.recursion,
            weighting,
            shaping: self.config.shaping,
            diagnose_last_level: false,
        };
        project(&config, &self.stack, &mut self.projection).map_err(Fault::Hierarchy)?;

        let platform = self.platform_command(frame, dt)?;
        let terms = coupling_compensation(&self.data, &layout, &platform.acceleration).map_err(Fault::Platform)?;
        let compensation = terms.torque(self.config.platform.compensation) + self.speed_barrier(&v, &inertia);
        let compensation = self.blend_from_hold(&compensation, &v);
        let torque = self.guard_torque(&compensation, &inertia, dt);
        self.commit(frame, &torque, &platform, &closed_loop, dt)
    }

    /// Sets every target to the measured state (first valid frame).
    fn start(&mut self, q: &SVector<T, N>, frame: &SensorFrame<T, U>) -> Result<(), Fault> {
        for (trajectory, frame_id) in self.hands.iter_mut().zip(self.config.layout.tcp.iter()) {
            let pose = self
                .data
                .frame_placements
                .get(frame_id.0)
                .copied()
                .ok_or(Fault::Dynamics(DynamicsError::UnknownFrame))?;
            *trajectory = PoseTrajectory::hold(pose);
        }
        self.joint_goal = JointTrajectory::hold(*q);
        self.reference_pose = Vector3::from(frame.platform.pose);
        self.admittance.reset(&Vector3::zeros()).map_err(Fault::Platform)?;
        self.avoidance.reset(&Vector3::zeros(), &frame.platform.leg_lengths).map_err(Fault::Platform)?;
        self.previous_torque = self.data.gravity_torque;
        self.started = true;
        self.telemetry.time_s = T::zero();
        Ok(())
    }

    fn advance_targets(&mut self, dt: T) {
        for hand in self.hands.iter_mut() {
            hand.advance(dt);
        }
        self.joint_goal.advance(dt);
        let step = dt / self.config.transition_s;
        for task in self.hierarchy.iter_mut().filter(|t| t.from != t.to) {
            task.progress = (task.progress + step).min(T::one());
            if task.progress >= T::one() {
                task.from = task.to;
            }
        }
        self.hierarchy.retain(|t| t.to.is_some());
        self.telemetry.time_s += dt;
    }

    /// The contact-force limiter ([`force_limit`]) on the last cycle's observer estimate, for the
    /// hands whose Cartesian task is in the hierarchy with at least one finite force bound.
    fn limit_contact_forces(&mut self, dt: T) -> Result<(), Fault> {
        let hands = Hand::BOTH.map(|hand| {
            let running = self.hierarchy.iter().any(|a| a.kind == TaskKind::CartesianImpedance(hand));
            let parameters = self.config.cartesian.get(hand.index())?;
            let (lower, upper) = (Vector6::from(parameters.force_lower), Vector6::from(parameters.force_upper));
            let limited = lower.iter().chain(upper.iter()).any(|x| x.is_finite());
            let axes = *self.hands.get(hand.index())?.sample().pose.rotation.matrix();
            (running && limited).then_some(HandLimits { axes, lower, upper })
        });
        let residual = *self.observer.residual();
        self.force_limiter
            .update(&self.config.force_limit, &self.model, &self.data, &self.config.layout, &residual, &hands, dt)
            .map_err(Fault::Dynamics)?;
        self.telemetry.contact_wrench = self.force_limiter.applied();
        self.telemetry.force_limit_correction = self.force_limiter.correction();
        Ok(())
    }

    /// Evaluates every hierarchy entry onto the stack; fills the per-task telemetry.
    fn build_stack(
        &mut self,
        mass: Option<&TreeFactorization<T, N>>,
        inertia: &TreeFactorization<T, N>,
    ) -> Result<(), Fault> {
        self.stack.clear();
        let t = &mut self.telemetry;
        t.tcp_error = [Vector6::zeros(); 2];
        t.tcp_force_limited = [[false; 6]; 2];
        t.min_collision_distance = None;
        t.collision_rows = 0;
        t.manipulability = [T::zero(); 2];
        t.tasks = [None; MAX_ACTIVE];
        t.task_count = self.hierarchy.len();
        let mut scratch = Scratch {
            collision: &mut self.collision_data,
            geometry_current: false,
            pair_rows: PairRowCache::default(),
            cartesian_damping: [Vector6::zeros(); 2],
        };
        for (index, entry) in self.hierarchy.iter().enumerate() {
            self.rows.clear();
            evaluate(
                entry.kind,
                &EvaluationContext {
                    model: &self.model,
                    collision_model: &self.collision_model,
                    config: &self.config,
                    tasks: &self.tasks,
                    hands: &self.hands,
                    joint_goal: &self.joint_goal,
                    mass,
                    inertia,
                },
                &mut self.data,
                &mut scratch,
                &mut self.rows,
                &mut self.telemetry,
            )?;
            let sigma = transition_weight(entry.progress);
            match (entry.from, entry.to) {
                (Some(from), Some(to)) if from != to => {
                    push_transitioning(&mut self.stack, &self.rows, from.into(), to.into(), entry.progress)
                }
                (_, Some(to)) if entry.from.is_none() => push_scaled(&mut self.stack, &self.rows, to.into(), sigma),
                (Some(from), None) => push_scaled(&mut self.stack, &self.rows, from.into(), T::one() - sigma),
                (_, Some(to)) => push_scaled(&mut self.stack, &self.rows, to.into(), T::one()),
                (None, None) => Ok(()),
            }
            .map_err(Fault::Hierarchy)?;
            let t = &mut self.telemetry;
            if let (Some(kind), Some(activation), Some(norm)) =
                (t.tasks.get_mut(index), t.task_activation.get_mut(index), t.task_torque_norm.get_mut(index))
            {
                *kind = Some(entry.kind);
                *activation = self.rows.rows().iter().fold(T::zero(), |a, r| a.max(r.activation));
                *norm = sqrt(self.rows.torque().norm_squared());
            }
        }
        self.cartesian_damping = scratch.cartesian_damping;
        Ok(())
    }

    /// Admittance (5.1) driven by the platform rows of `τ`, then the ICR avoidance loop.
    /// Returns `ṙ_des`, the commanded `r̈` and the leg rates, all limited.
    fn platform_command(&mut self, frame: &SensorFrame<T, U>, dt: T) -> Result<PlatformStep<T>, Fault> {
        let platform = &self.config.platform;
        let mut force = Vector3::zeros();
        for ((axis, f), deadband) in
            self.config.layout.platform.axes().iter().zip(force.iter_mut()).zip(platform.force_deadband.iter())
        {
            if let Some(c) = axis.coordinate().filter(|_| axis.is_admitted()) {
                // The contact-force limiter's platform relief: the estimated reaction along the
                // limited axes ([`force_limit`]).
                let relief = self.force_limiter.platform_relief().get(c).copied().unwrap_or_else(T::zero);
                let raw = self.projection.torque.get(c).copied().unwrap_or_else(T::zero) + relief;
                // Deadband with a continuous output: F − sign(F) F₀ outside, 0 inside.
                *f = if raw > *deadband {
                    raw - *deadband
                } else if raw < -*deadband {
                    raw + *deadband
                } else {
                    T::zero()
                };
            }
        }
        let admitted = self.admittance.step(&force, &Vector3::zeros(), dt).map_err(Fault::Platform)?;
        self.reference_pose += admitted.velocity * dt;
        let reference = PlatformReference {
            pose: self.reference_pose,
            velocity: admitted.velocity,
            acceleration: admitted.acceleration,
        };
        let pose = Vector3::from(frame.platform.pose);
        let measured = Vector3::from(frame.platform.velocity);
        let avoidance = self.avoidance.step(&reference, &pose, &measured, dt).map_err(Fault::Platform)?;
        let limits = &self.config.output_limits;
        let mut limited = [false; 3];
        let velocity = limit_base_velocity(
            &avoidance.velocity,
            &self.previous_base_velocity,
            &limits.base_velocity,
            &limits.base_acceleration,
            dt,
            &mut limited,
        );
        let mut legs = avoidance.leg_rates;
        let t = &mut self.telemetry;
        t.saturation = Saturation::none();
        t.saturation.base_limited = limited;
        t.saturation.leg_rate_limited = limit_leg_rates(&mut legs, limits.leg_rate);
        t.virtual_force = force;
        t.icr_repelling = avoidance.repelling;
        let acceleration = (velocity - self.previous_base_velocity) / dt;
        t.base_acceleration = acceleration;
        Ok(PlatformStep { velocity, acceleration, leg_rates: legs })
    }

    /// The joint speed barrier ([`speed_barrier`]) on the upper body, from the measured `v`
    /// and the factor of the closed-loop inertia `M̃`.
    fn speed_barrier(&self, v: &SVector<T, N>, inertia: &TreeFactorization<T, N>) -> SVector<T, N> {
        let active = self.config.layout.coordinates(JointGroup::UpperBody);
        let limits = JointLimits { speed: &self.model.limits.velocity, effort: &self.model.limits.effort };
        speed_barrier(&self.config.speed_barrier, v, limits, |i| joint_mobility(inertia, i), &active)
    }

    /// While returning from the safe output ([`recovery`]): the levels' torques scaled by the
    /// weight `β` and the compensation moved towards the hold torque `g − D_safe q̇`, so that
    /// the guard receives `(1 − β) τ_hold + β (τ₀ + Σ τ_i^p)`. `compensation` itself in normal
    /// operation.
    fn blend_from_hold(&mut self, compensation: &SVector<T, N>, v: &SVector<T, N>) -> SVector<T, N> {
        let weight = self.recovery.weight();
        if weight >= T::one() {
            return *compensation;
        }
        let count = self.projection.level_count.min(MAX_LEVELS);
        for level in self.projection.level_torques.iter_mut().take(count) {
            *level *= weight;
        }
        let hold = self.data.gravity_torque - self.config.safe_damping.component_mul(v);
        compensation + (hold - compensation) * (T::one() - weight)
    }

    /// The upper-body torque `τ₀ + Σ N_i τ_i` with the command-side contact-force limit
    /// ([`force_limit`]) through the priority-preserving guard. The limit's torque joins `τ₀`:
    /// the guard scales the task levels, never the bound on the contact force.
    fn guard_torque(&mut self, compensation: &SVector<T, N>, factor: &TreeFactorization<T, N>, dt: T) -> SVector<T, N> {
        let count = self.projection.level_count.min(MAX_LEVELS);
        let levels = self.projection.level_torques.get(..count).unwrap_or(&[]);
        let tasks = levels.iter().fold(SVector::<T, N>::zeros(), |t, l| t + l);
        let limit = self.force_limiter.limit_command(
            self.config.force_limit.regularisation,
            &tasks,
            factor,
            &self.cartesian_damping,
        );
        for (flags, limited) in self.telemetry.tcp_force_limited.iter_mut().zip(limit.limited.iter()) {
            for (flag, l) in flags.iter_mut().zip(limited.iter()) {
                *flag |= *l;
            }
        }
        let compensation = &(compensation + limit.torque);
        let desired = compensation + tasks;
        let active = self.config.layout.coordinates(JointGroup::UpperBody);
        let rate = &self.config.output_limits.torque_rate;
        self.telemetry.saturation.torque_rate_limited =
            rate_exceeded(&desired, &self.previous_torque, rate, dt, &active);
        let mut saturation = self.telemetry.saturation;
        let torque = self.guarded(compensation, levels, dt, &mut saturation);
        self.telemetry.saturation = saturation;
        torque
    }

    /// `compensation + Σ levels` through the effort and rate box of the upper body with
    /// priority-preserving scaling ([`guard`]); zero on the platform coordinates.
    fn guarded(
        &self,
        compensation: &SVector<T, N>,
        levels: &[SVector<T, N>],
        dt: T,
        saturation: &mut Saturation<T>,
    ) -> SVector<T, N> {
        let active = self.config.layout.coordinates(JointGroup::UpperBody);
        let rate = &self.config.output_limits.torque_rate;
        let (lower, upper) = torque_box(&self.model.limits.effort, rate, &self.previous_torque, dt, &active);
        let mut torque = saturate_with_priority(compensation, levels, &lower, &upper, &active, saturation);
        for (t, a) in torque.iter_mut().zip(active.iter()) {
            if !a {
                *t = T::zero();
            }
        }
        torque
    }

    /// Writes the actuator frame and remembers the torque and platform command for the rate
    /// limits of the next cycle.
    fn write_output(&mut self, torque: &SVector<T, N>, platform: PlatformCommand<T>, mode: SafeOutput) {
        if self.last_cycle.is_some() && mode != self.output.mode {
            self.telemetry.mode_changes = self.telemetry.mode_changes.saturating_add(1);
        }
        self.previous_torque = *torque;
        self.previous_base_velocity = Vector3::from(platform.velocity);
        let out = &mut self.output;
        for (o, t) in out.torque.iter_mut().zip(torque.iter().skip(PLATFORM_DOF)) {
            *o = *t;
        }
        out.platform = platform;
        out.brake = mode == SafeOutput::Brake;
        out.mode = mode;
    }

    /// Checks the commands, updates the observer and the telemetry, writes the output.
    fn commit(
        &mut self,
        frame: &SensorFrame<T, U>,
        torque: &SVector<T, N>,
        platform: &PlatformStep<T>,
        closed_loop: &nalgebra::SMatrix<T, N, N>,
        dt: T,
    ) -> Result<(), Fault> {
        let (velocity, leg_rates) = (&platform.velocity, &platform.leg_rates);
        let finite = crate::math::all_finite(torque)
            && crate::math::all_finite(velocity)
            && leg_rates.iter().all(|x| x.is_finite());
        if !finite {
            return Err(Fault::NonFiniteOutput);
        }
        let mut measured = SVector::<T, N>::zeros();
        for (m, t) in measured.iter_mut().skip(PLATFORM_DOF).zip(frame.joints.torque.iter()) {
            *m = *t;
        }
        let observed = self.config.layout.coordinates(JointGroup::UpperBody);
        let residual = *self.observer.update(&self.data, &measured, &observed, dt);
        let t = &mut self.telemetry;
        t.external_torque = residual;
        t.contact = sqrt(residual.norm_squared()) > self.config.observer.contact_threshold;
        t.level_count = self.projection.level_count;
        // The stored energy of every level in one pass over the stack (each level's sum in stack
        // order).
        let mut storages = [T::zero(); MAX_LEVELS];
        for r in self.stack.rows() {
            if let Some(s) = storages.get_mut(r.level) {
                *s += r.row.potential;
            }
        }
        let mut potential = T::zero();
        for (level, &storage) in storages.iter().enumerate() {
            potential += storage;
            let diagnostics = self.projection.levels.get(level).filter(|_| level < self.projection.level_count);
            if let (Some(s), Some(rate), Some(norm), Some(conflict)) = (
                t.level_storage.get_mut(level),
                t.level_storage_rate.get_mut(level),
                t.level_torque_norm.get_mut(level),
                t.level_conflict.get_mut(level),
            ) {
                *rate = (storage - *s) / dt;
                *s = storage;
                *norm = diagnostics.map_or(T::zero(), |d| d.projected_torque_norm);
                *conflict = diagnostics.map_or(T::zero(), |d| d.conflict);
            }
        }
        t.potential_energy = potential;
        let half: T = convert(0.5);
        t.kinetic_energy = half * self.data.v.dot(&(closed_loop * self.data.v));
        t.base_velocity = *velocity;

        self.hold_gravity = self.data.gravity_torque;
        self.write_output(
            torque,
            PlatformCommand { velocity: (*velocity).into(), leg_rates: *leg_rates },
            self.recovery.output().0,
        );
        Ok(())
    }

    /// The safe output of [`faults`]: gravity compensation with joint damping through the
    /// guards, the platform ramped to rest, the legs stopped; the brakes after
    /// `brake_after_cycles` faulty cycles. The platform loop restarts from rest afterwards.
    fn safe_output(&mut self, frame: &SensorFrame<T, U>, fault: Fault) {
        let t = &mut self.telemetry;
        t.fault = Some(fault);
        t.fault_cycles = t.fault_cycles.saturating_add(1);
        let brake = t.fault_cycles >= self.config.input_limits.brake_after_cycles;
        let dt = self.config.period_s;
        let (q, v) = Self::state(frame);
        let positions_valid = crate::math::all_finite(&q)
            && forward_kinematics(&self.model, &mut self.data, &q, &SVector::zeros()).is_ok();
        let gravity_torque = if positions_valid { *gravity(&self.model, &mut self.data) } else { self.hold_gravity };
        let velocity = if crate::math::all_finite(&v) { v } else { SVector::zeros() };
        let hold = gravity_torque - self.config.safe_damping.component_mul(&velocity);
        let mut saturation = Saturation::none();
        let mut torque = self.guarded(&hold, &[], dt, &mut saturation);
        if !crate::math::all_finite(&torque) {
            torque = self.previous_torque;
        }
        let limits = &self.config.output_limits;
        let mut limited = [false; 3];
        let base = limit_base_velocity(
            &Vector3::zeros(),
            &self.previous_base_velocity,
            &limits.base_velocity,
            &limits.base_acceleration,
            dt,
            &mut limited,
        );
        saturation.base_limited = limited;
        self.telemetry.saturation = saturation;
        self.telemetry.base_velocity = base;
        // The platform loop restarts from the commanded (decaying) velocity.
        let _ = self.admittance.reset(&Vector3::zeros());
        let _ =
            self.avoidance.reset(&base, &frame.platform.leg_lengths.map(|l| if l.is_finite() { l } else { T::zero() }));
        let pose = Vector3::from(frame.platform.pose);
        if crate::math::all_finite(&pose) {
            self.reference_pose = pose;
        }
        self.observer.reset();
        self.force_limiter.reset();
        let mode = if brake { SafeOutput::Brake } else { SafeOutput::Hold };
        self.write_output(&torque, PlatformCommand { velocity: base.into(), leg_rates: [T::zero(); LEGS] }, mode);
    }
}

/// What the task evaluations of one cycle share: the collision geometry and whether it is
/// current (updated this cycle), the pair rows the collision fields evaluated (the strong
/// field's pairs are mostly among the weak field's), and the Cartesian damping force of each
/// hand (task axes) for the command-side force limit ([`force_limit`]).
struct Scratch<'a, T: RealField, const N: usize, const V: usize, const P: usize> {
    collision: &'a mut CollisionData<T, V, P>,
    geometry_current: bool,
    pair_rows: PairRowCache<T, N, P, MAX_TASK_ROWS>,
    cartesian_damping: [Vector6<T>; 2],
}

/// Read-only inputs of a task evaluation.
struct EvaluationContext<
    'a,
    T: RealField,
    const N: usize,
    const B: usize,
    const F: usize,
    const V: usize,
    const P: usize,
> {
    model: &'a Model<T, N, B, F>,
    collision_model: &'a CollisionModel<T, V, P>,
    config: &'a ControllerConfig<T, N>,
    tasks: &'a TaskSet<T, N>,
    hands: &'a [PoseTrajectory<T>; 2],
    joint_goal: &'a JointTrajectory<T, N>,
    /// The tree-sparse factor of the plain `M` (Cartesian damping design), `None` if `M` is not
    /// positive definite.
    mass: Option<&'a TreeFactorization<T, N>>,
    /// The tree-sparse factor of the closed-loop inertia (5.17) (collision and torso rows).
    inertia: &'a TreeFactorization<T, N>,
}

/// Appends the rows of one task to `rows` and records its telemetry.
fn evaluate<T: RealField + Copy, const N: usize, const B: usize, const F: usize, const V: usize, const P: usize>(
    kind: TaskKind,
    cx: &EvaluationContext<'_, T, N, B, F, V, P>,
    data: &mut Data<T, N, B, F>,
    scratch: &mut Scratch<'_, T, N, V, P>,
    rows: &mut TaskRows<T, N, MAX_TASK_ROWS>,
    telemetry: &mut Telemetry<T, N>,
) -> Result<(), Fault> {
    match kind {
        TaskKind::CartesianImpedance(hand) => {
            let (Some(task), Some(trajectory)) = (cx.tasks.cartesian.get(hand.index()), cx.hands.get(hand.index()))
            else {
                return Ok(());
            };
            // (5.11): no Cartesian damping on the platform coordinates.
            let velocity = data.v;
            for (i, x) in data.v.iter_mut().enumerate() {
                if cx.config.layout.platform.is_platform(i) {
                    *x = T::zero();
                }
            }
            let report = cartesian_impedance_factored(cx.model, data, cx.mass, task, &trajectory.sample(), rows);
            data.v = velocity;
            let report = report.map_err(Fault::Task)?;
            if let (Some(e), Some(s), Some(d)) = (
                telemetry.tcp_error.get_mut(hand.index()),
                telemetry.tcp_force_limited.get_mut(hand.index()),
                scratch.cartesian_damping.get_mut(hand.index()),
            ) {
                *e = report.error;
                *s = report.saturated;
                *d = report.damping_force;
            }
        }
        TaskKind::CollisionAvoidance(field) => {
            let Some(parameters) = cx.tasks.collision.get(field.index()) else { return Ok(()) };
            // The geometry (volumes in the world, all pair distances) and the pair rows' Jacobians
            // and reflected masses depend only on this cycle's kinematics and inertia: the first
            // collision entry of the cycle updates the geometry, the later ones (the other field)
            // reuse it and the rows already evaluated. Same rows as evaluating each field alone.
            let (model, data_ref, factor, collision_model) = (cx.model, &*data, cx.inertia, cx.collision_model);
            if !scratch.geometry_current {
                collision_model.update(data_ref, scratch.collision);
                scratch.pair_rows.clear();
                scratch.geometry_current = true;
            }
            let report = collision_rows_shared(
                collision_model,
                scratch.collision,
                model,
                data_ref,
                factor,
                parameters,
                &mut scratch.pair_rows,
                rows,
            );
            let report = report.map_err(Fault::Task)?;
            telemetry.min_collision_distance = report.min_distance;
            telemetry.collision_rows += report.rows;
        }
        TaskKind::SingularityAvoidance(hand) => {
            let Some(task) = cx.tasks.singularity.get(hand.index()) else { return Ok(()) };
            let report = manipulability_avoidance(cx.model, data, task, rows).map_err(Fault::Task)?;
            if let Some(m) = telemetry.manipulability.get_mut(hand.index()) {
                *m = report.manipulability;
            }
        }
        TaskKind::EndStops => end_stops(&cx.tasks.end_stops, &data.q, &data.v, rows).map_err(Fault::Task)?,
        TaskKind::TorsoWorkspace => {
            if let Some(task) = &cx.tasks.torso {
                torso_workspace(task, &data.q, &data.v, cx.inertia, rows).map_err(Fault::Task)?;
            }
        }
        TaskKind::JointImpedance(group) | TaskKind::JointDamping(group) => {
            let damping_only = matches!(kind, TaskKind::JointDamping(_));
            let Some(task) = cx.tasks.joint.get(usize::from(damping_only)).and_then(|t| t.get(group.index())) else {
                return Ok(());
            };
            let (position, velocity) = cx.joint_goal.sample();
            let target = if damping_only { JointTarget::at_rest(data.q) } else { JointTarget { position, velocity } };
            joint_impedance(task, &data.q, &data.v, &target, rows).map_err(Fault::Task)?;
        }
    }
    Ok(())
}

fn validate_config<T: RealField + Copy, const N: usize>(config: &ControllerConfig<T, N>) -> Result<(), ConfigError> {
    let positive = |x: T| x.is_finite() && x > T::zero();
    let non_negative = |v: &SVector<T, N>| v.iter().all(|x| x.is_finite() && *x >= T::zero());
    let limits = &config.output_limits;
    let force_limit = &config.force_limit;
    let checks: [(bool, &'static str); 15] = [
        (config.speed_barrier.is_valid(), "speed_barrier"),
        (config.recovery.is_valid(), "recovery"),
        (positive(config.period_s), "period_s"),
        (positive(config.transition_s), "transition_s"),
        (non_negative(&config.joint_stiffness), "joint_stiffness"),
        (non_negative(&config.joint_damping), "joint_damping"),
        (non_negative(&config.safe_damping), "safe_damping"),
        (limits.torque_rate.iter().all(|x| positive(*x)), "torque_rate"),
        (limits.base_velocity.iter().chain(limits.base_acceleration.iter()).all(|x| positive(*x)), "base limits"),
        (positive(limits.leg_rate), "leg_rate"),
        (
            config.input_limits.position_tolerance.is_finite() && config.input_limits.position_tolerance >= T::zero(),
            "position_tolerance",
        ),
        (
            config.input_limits.velocity_factor.is_finite()
                && config.input_limits.velocity_factor >= T::one()
                && config.input_limits.max_cycle_gap >= 1
                && config.input_limits.brake_after_cycles >= 1,
            "input limits",
        ),
        (positive(config.observer.gain) && positive(config.observer.contact_threshold), "observer"),
        (config.platform.force_deadband.iter().all(|x| x.is_finite() && *x >= T::zero()), "force_deadband"),
        (
            positive(force_limit.gain)
                && positive(force_limit.regularisation)
                && force_limit.margin >= T::zero()
                && force_limit.margin < T::one()
                && force_limit.max_correction.is_finite()
                && force_limit.max_correction >= T::zero(),
            "force_limit",
        ),
    ];
    match checks.iter().find(|(ok, _)| !ok) {
        Some((_, name)) => Err(ConfigError::InvalidParameter { name }),
        None => Ok(()),
    }
}

fn empty_telemetry<T: RealField + Copy, const N: usize>() -> Telemetry<T, N> {
    Telemetry {
        cycle: 0,
        time_s: T::zero(),
        fault: None,
        fault_cycles: 0,
        mode_changes: 0,
        tcp_error: [Vector6::zeros(); 2],
        tcp_force_limited: [[false; 6]; 2],
        contact_wrench: [Vector6::zeros(); 2],
        force_limit_correction: [Vector6::zeros(); 2],
        level_count: 0,
        level_storage: [T::zero(); MAX_LEVELS],
        level_storage_rate: [T::zero(); MAX_LEVELS],
        level_torque_norm: [T::zero(); MAX_LEVELS],
        level_conflict: [T::zero(); MAX_LEVELS],
        tasks: [None; MAX_ACTIVE],
        task_count: 0,
        task_activation: [T::zero(); MAX_ACTIVE],
        task_torque_norm: [T::zero(); MAX_ACTIVE],
        min_collision_distance: None,
        collision_rows: 0,
        manipulability: [T::zero(); 2],
        external_torque: SVector::zeros(),
        contact: false,
        kinetic_energy: T::zero(),
        potential_energy: T::zero(),
        virtual_force: Vector3::zeros(),
        base_velocity: Vector3::zeros(),
        base_acceleration: Vector3::zeros(),
        icr_repelling: false,
        saturation: Saturation::none(),
    }
}
