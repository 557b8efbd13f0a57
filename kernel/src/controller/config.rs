//! The controller's configuration: the robot layout, the task hierarchy as data and every gain,
//! validated once by [`super::Controller::try_new`] and changed at run time only through
//! validated planner commands ([`super::command`]). [`ControllerConfig::validate`] checks the
//! controller's own parameters; the task objects check theirs when the controller builds them.

use nalgebra::{RealField, SVector, Vector3, Vector6};

use super::error::ConfigError;
use super::force_limit::ForceLimitParameters;
use super::recovery::RecoveryParameters;
use super::speed_barrier::SpeedBarrierParameters;
use crate::hierarchy::{Recursion, Shaping};
use crate::platform::admittance::AdmittanceConfig;
use crate::platform::avoidance::AvoidanceConfig;
use crate::platform::coupling_compensation::CompensationSwitch;
use crate::tasks::cartesian_impedance::AxisMask;
use crate::tasks::torso_workspace::TorsoWorkspaceConfig;

pub use super::capacity::{MAX_LEVELS, MAX_ROWS, MAX_TASKS, MAX_TASK_ROWS};
pub use super::faults::InputLimits;
use super::layout::collect_truncated;
pub use super::layout::{ArmId, JointGroup, PerArm, RobotLayout, MAX_ARMS};

/// The two collision-avoidance fields of Fig. 6.3.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(serde::Serialize, serde::Deserialize)]
pub enum Field {
    /// Tight and very strong repulsion, on the level of the task execution.
    Strong,
    /// Weaker, largely extended repulsion, on a lower level.
    Weak,
}

impl Field {
    /// `0` for the strong field, `1` for the weak one.
    pub const fn index(self) -> usize {
        match self {
            Field::Strong => 0,
            Field::Weak => 1,
        }
    }
}

/// The control tasks the controller knows (Ch. 3), as the planner names them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(serde::Serialize, serde::Deserialize)]
pub enum TaskKind {
    /// Cartesian impedance of a TCP with force limits (Sec. 3.4.1, Table 7.1), six rows.
    CartesianImpedance(ArmId),
    /// Self-collision and platform–environment collision avoidance (Sec. 3.1) with one field.
    CollisionAvoidance(Field),
    /// Arm singularity avoidance by the manipulability (Sec. 3.4.2), one row.
    SingularityAvoidance(ArmId),
    /// Avoidance of the mechanical end stops of every limited joint (Sec. 3.4.3).
    EndStops,
    /// Torso workspace of the tendon-coupled torso (Sec. 3.3), twelve boundary rows.
    TorsoWorkspace,
    /// Joint impedance towards the joint goal (the torso impedance of Fig. 6.3, the joint
    /// impedance of Table 7.1, a platform goal), one row per coordinate of the group.
    JointImpedance(JointGroup),
    /// Joint damping `−D q̇` on a group, one row per coordinate.
    JointDamping(JointGroup),
}

/// Most task kinds of a layout: `4 A + 10` with [`MAX_ARMS`] arms (Cartesian impedance and
/// singularity avoidance per arm, two collision fields, end stops, torso workspace, joint
/// impedance and damping per group).
pub const MAX_TASK_KINDS: usize = 4 * MAX_ARMS + 10;

/// The names of the per-arm task kinds, per arm ([`ArmId::name`]).
const ARM_TASK_NAMES: [[&str; MAX_ARMS]; 4] = [
    ["cartesian_right", "cartesian_left", "cartesian_arm_2", "cartesian_arm_3"],
    ["singularity_right", "singularity_left", "singularity_arm_2", "singularity_arm_3"],
    ["joint_impedance_right_arm", "joint_impedance_left_arm", "joint_impedance_arm_2", "joint_impedance_arm_3"],
    ["joint_damping_right_arm", "joint_damping_left_arm", "joint_damping_arm_2", "joint_damping_arm_3"],
];

impl TaskKind {
    /// Every task kind of a robot with `A` arms, in a fixed order (the telemetry columns of
    /// host-sim follow it): Cartesian impedance per arm, the collision fields, singularity
    /// avoidance per arm, end stops, torso workspace, joint impedance and joint damping per
    /// group of [`JointGroup::all`]. `4 A + 10` kinds, 18 for Justin.
    pub fn all<const A: usize>() -> heapless::Vec<TaskKind, MAX_TASK_KINDS> {
        let arms = || ArmId::all::<A>().into_iter().take(MAX_ARMS);
        // By reference: the drop of heapless' `IntoIter` indexes a slice (a panic path).
        let all_groups = JointGroup::all::<A>();
        let groups = || all_groups.iter().copied();
        collect_truncated(
            arms()
                .map(TaskKind::CartesianImpedance)
                .chain([Field::Strong, Field::Weak].map(TaskKind::CollisionAvoidance))
                .chain(arms().map(TaskKind::SingularityAvoidance))
                .chain([TaskKind::EndStops, TaskKind::TorsoWorkspace])
                .chain(groups().map(TaskKind::JointImpedance))
                .chain(groups().map(TaskKind::JointDamping)),
        )
    }

    /// `true` for a joint impedance or a joint damping (the tasks whose damping is bounded by
    /// the sampled loop, [`crate::tasks::joint_impedance::sampled_damping`]).
    pub fn is_joint_task(self) -> bool {
        matches!(self, TaskKind::JointImpedance(_) | TaskKind::JointDamping(_))
    }

    /// A short name for logs, column headers and configuration files, e.g. `cartesian_right`,
    /// `joint_impedance_left_arm` (arms named by [`ArmId::name`]).
    pub fn name(self) -> &'static str {
        use JointGroup::{Arm, Platform, Torso, UpperBody};
        let per_arm = |table: usize, arm: ArmId| {
            ARM_TASK_NAMES.get(table).and_then(|names| names.get(arm.index())).copied().unwrap_or("unknown_arm")
        };
        match self {
            TaskKind::CartesianImpedance(arm) => per_arm(0, arm),
            TaskKind::CollisionAvoidance(Field::Strong) => "collision_strong",
            TaskKind::CollisionAvoidance(Field::Weak) => "collision_weak",
            TaskKind::SingularityAvoidance(arm) => per_arm(1, arm),
            TaskKind::EndStops => "end_stops",
            TaskKind::TorsoWorkspace => "torso_workspace",
            TaskKind::JointImpedance(Platform) => "joint_impedance_platform",
            TaskKind::JointImpedance(Torso) => "joint_impedance_torso",
            TaskKind::JointImpedance(Arm(arm)) => per_arm(2, arm),
            TaskKind::JointImpedance(UpperBody) => "joint_impedance_upper_body",
            TaskKind::JointDamping(Platform) => "joint_damping_platform",
            TaskKind::JointDamping(Torso) => "joint_damping_torso",
            TaskKind::JointDamping(Arm(arm)) => per_arm(3, arm),
            TaskKind::JointDamping(UpperBody) => "joint_damping_upper_body",
        }
    }
}

/// One entry of the hierarchy: a task on a priority level (0 = highest).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(serde::Serialize, serde::Deserialize)]
pub struct TaskSpec {
    /// The task.
    pub kind: TaskKind,
    /// Its priority level, `< MAX_LEVELS`.
    pub level: u8,
}

/// The consistency of the null space projections (Sec. 4.2, Table 4.3), i.e. the weighting
/// `W` of the generalized inverse.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(serde::Serialize, serde::Deserialize)]
pub enum Consistency {
    /// `W = I` (Def. 4.1): lower levels cause no task force in a static equilibrium — the choice
    /// for contact tasks whose force limits must bound the contact force (Table 7.1).
    Static,
    /// `W` = the closed-loop inertia (Def. 4.2): lower levels cause no task acceleration — the
    /// choice for free motion (Fig. 6.3).
    Dynamic,
}

/// Parameters of a TCP's Cartesian impedance as the planner sets them (Table 7.1): diagonal
/// stiffnesses and force limits in the axes of the desired tool frame.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CartesianParameters<T> {
    /// `(k_x, k_y, k_z)` (N/m), `≥ 0`.
    pub translational_stiffness: [T; 3],
    /// `(k_rx, k_ry, k_rz)` (Nm/rad), `≥ 0`.
    pub rotational_stiffness: [T; 3],
    /// Damping ratio `ξ ≥ 0` of the double-diagonalisation damping (0.7 in Ch. 6).
    pub damping_ratio: T,
    /// Lower force limits `(x, y, z, rx, ry, rz)` (N, Nm), `≤ 0`, may be `−∞`.
    pub force_lower: [T; 6],
    /// Upper force limits (N, Nm), `≥ 0`, may be `+∞` (Table 7.1: wiper `+10 N` in x).
    pub force_upper: [T; 6],
}

/// Parameters of one collision-avoidance field (Sec. 3.1, (3.8), (3.23), (4.68)).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CollisionFieldParameters<T> {
    /// Repulsive force at contact `F_max > 0` (N).
    pub max_force: T,
    /// Influence distance `d₀ > 0` (m).
    pub influence_distance: T,
    /// Damping ratio `ξ ≥ 0` of every pair.
    pub damping_ratio: T,
    /// Distance (m) at and below which a pair's row locks the lower levels completely.
    pub activation_full: T,
    /// Distance (m) at and above which a pair's row no longer locks the lower levels.
    pub activation_zero: T,
}

/// Parameters of the arm singularity avoidance (3.55)–(3.57), shared by every arm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SingularityParameters<T> {
    /// Rows of the TCP Jacobian whose manipulability is kept (e.g. the translational ones).
    pub rows: AxisMask,
    /// Threshold `m_kin,0 > 0` below which the potential acts.
    pub threshold: T,
    /// Manipulability at which the row locks the lower levels completely, `< threshold`.
    pub full_activation: T,
    /// Gain `k_msa ≥ 0`.
    pub stiffness: T,
    /// Damping `≥ 0` along the row.
    pub damping: T,
}

/// Parameters of the end stops (3.58)–(3.59): one margin for every limited joint, the gains per
/// coordinate (a joint's stop acts on its own inertia, which differs by orders of magnitude
/// between a shoulder and a wrist; platform entries unused).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EndStopParameters<T, const N: usize> {
    /// Distance from each stop at which the potential starts (rad, m), `> 0`.
    pub margin: T,
    /// `k_mes ≥ 0` of (3.58) per coordinate (J/rad², J/m²).
    pub stiffness: SVector<T, N>,
    /// Damping `≥ 0` of (3.59) per coordinate (Nms/rad, Ns/m).
    pub damping: SVector<T, N>,
}

/// The platform: admittance (5.1) and the ICR avoidance loop (Fig. 3.10).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlatformParameters<T> {
    /// The admittance (5.1)–(5.5).
    pub admittance: AdmittanceConfig<T>,
    /// The ICR singularity avoidance with leg motion; its reference is the admittance output.
    pub avoidance: AvoidanceConfig<T>,
    /// Which parts of the coupling compensation (5.14) are applied.
    pub compensation: CompensationSwitch,
    /// Virtual force magnitude below which the platform is not driven (N, N, Nm), `≥ 0`: "the
    /// mobile base is designed to move only if a force threshold is exceeded" (Sec. 6.2).
    pub force_deadband: [T; 3],
}

/// Limits the output guards enforce ([`super::guard`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutputLimits<T, const N: usize> {
    /// Joint torque rate limit (Nm/s) per coordinate (platform entries unused), `> 0`.
    pub torque_rate: SVector<T, N>,
    /// Platform velocity limit `(ẋ, ẏ, θ̇)` (m/s, m/s, rad/s), `> 0`.
    pub base_velocity: Vector3<T>,
    /// Platform acceleration limit (m/s², m/s², rad/s²), `> 0`.
    pub base_acceleration: Vector3<T>,
    /// Leg rate limit `|λ̇|` (m/s), `> 0`.
    pub leg_rate: T,
}

/// The generalized-momentum observer that detects contacts ((2.1) with `Ṁ = C + Cᵀ`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObserverParameters<T> {
    /// Observer gain `K_O > 0` (1/s): the residual is `τ_ext` low-passed with this bandwidth.
    pub gain: T,
    /// Residual norm above which a contact is reported (Nm), `> 0`.
    pub contact_threshold: T,
}

/// Everything [`super::Controller`] needs besides the model and the collision model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControllerConfig<T: RealField, const N: usize, const A: usize> {
    /// Control period (s), `> 0` (1 ms on Rollin' Justin).
    pub period_s: T,
    /// Which frames and coordinates are which.
    pub layout: RobotLayout<N, A>,
    /// Successive or augmented projections (Sec. 4.1).
    pub recursion: Recursion,
    /// Static or dynamic consistency of the projections.
    pub consistency: Consistency,
    /// Continuous transition shaping of algorithmic singularities (Sec. 4.4).
    pub shaping: Shaping<T>,
    /// Duration of a task's move between levels, fade-in or fade-out (s), `> 0`.
    pub transition_s: T,
    /// Cartesian impedance of each TCP, per arm ([`ArmId`]).
    pub cartesian: PerArm<CartesianParameters<T>, A>,
    /// Task-space damping used when the double diagonalisation is impossible (Ns/m, Nms/rad).
    pub cartesian_fallback_damping: Vector6<T>,
    /// The strong and the weak collision field.
    pub collision: [CollisionFieldParameters<T>; 2],
    /// Arm singularity avoidance.
    pub singularity: SingularityParameters<T>,
    /// End stops.
    pub end_stops: EndStopParameters<T, N>,
    /// Torso workspace (`None` if the robot has no coupled torso).
    pub torso_workspace: Option<TorsoWorkspaceConfig<T>>,
    /// Joint impedance stiffness per coordinate (Nm/rad, N/m), `≥ 0`.
    pub joint_stiffness: SVector<T, N>,
    /// Joint impedance damping per coordinate (Nms/rad, Ns/m), `≥ 0`.
    pub joint_damping: SVector<T, N>,
    /// Damping of the joint-damping task and of the safe output (Nms/rad), `≥ 0`.
    pub safe_damping: SVector<T, N>,
    /// The largest loop gain `κ = Δt λ_max(M̃⁻¹ D)` of each joint task's damping, `> 0`
    /// ([`crate::tasks::joint_impedance::sampled_damping`]).
    pub joint_damping_loop_gain: T,
    /// The platform.
    pub platform: PlatformParameters<T>,
    /// Output guards.
    pub output_limits: OutputLimits<T, N>,
    /// Input validation.
    pub input_limits: InputLimits<T>,
    /// Contact detection.
    pub observer: ObserverParameters<T>,
    /// Contact-force limiter on the observer's estimate ([`super::force_limit`]).
    pub force_limit: ForceLimitParameters<T>,
    /// The joint speed barrier ([`mod@super::speed_barrier`]).
    pub speed_barrier: SpeedBarrierParameters<T>,
    /// The return from the safe output ([`super::recovery`]).
    pub recovery: RecoveryParameters<T>,
}

impl<T: RealField + Copy, const N: usize, const A: usize> ControllerConfig<T, N, A> {
    /// Checks every controller parameter once (the tasks' and the platform's own parameters
    /// are checked when their objects are built): the first one out of range is named in
    /// [`ConfigError::InvalidParameter`].
    pub fn validate(&self) -> Result<(), ConfigError> {
        let config = self;
        let positive = |x: T| x.is_finite() && x > T::zero();
        let non_negative = |v: &SVector<T, N>| v.iter().all(|x| x.is_finite() && *x >= T::zero());
        let limits = &config.output_limits;
        let force_limit = &config.force_limit;
        let checks: [(bool, &'static str); 16] = [
            (config.speed_barrier.is_valid(), "speed_barrier"),
            (config.recovery.is_valid(), "recovery"),
            (positive(config.period_s), "period_s"),
            (positive(config.transition_s), "transition_s"),
            (non_negative(&config.joint_stiffness), "joint_stiffness"),
            (non_negative(&config.joint_damping), "joint_damping"),
            (non_negative(&config.safe_damping), "safe_damping"),
            (positive(config.joint_damping_loop_gain), "joint_damping_loop_gain"),
            (limits.torque_rate.iter().all(|x| positive(*x)), "torque_rate"),
            (limits.base_velocity.iter().chain(limits.base_acceleration.iter()).all(|x| positive(*x)), "base limits"),
            (positive(limits.leg_rate), "leg_rate"),
            (
                config.input_limits.position_tolerance.is_finite()
                    && config.input_limits.position_tolerance >= T::zero(),
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
}

#[cfg(test)]
mod tests {
    use super::{ArmId, Field, JointGroup, TaskKind};

    #[test]
    fn justins_list_holds_every_task_kind_of_every_arm_field_and_group_in_order() {
        use JointGroup::{Arm, Platform, Torso, UpperBody};
        let (right, left) = (ArmId::RIGHT, ArmId::LEFT);
        let groups = [Platform, Torso, Arm(right), Arm(left), UpperBody];
        let expected: heapless::Vec<TaskKind, 18> = [
            TaskKind::CartesianImpedance(right),
            TaskKind::CartesianImpedance(left),
            TaskKind::CollisionAvoidance(Field::Strong),
            TaskKind::CollisionAvoidance(Field::Weak),
            TaskKind::SingularityAvoidance(right),
            TaskKind::SingularityAvoidance(left),
            TaskKind::EndStops,
            TaskKind::TorsoWorkspace,
        ]
        .into_iter()
        .chain(groups.map(TaskKind::JointImpedance))
        .chain(groups.map(TaskKind::JointDamping))
        .collect();
        assert_eq!(TaskKind::all::<2>().as_slice(), expected.as_slice());
        assert_eq!(TaskKind::all::<1>().len(), 14);
        assert_eq!(TaskKind::all::<4>().len(), 26);
    }

    #[test]
    fn every_task_kind_is_listed_once_with_its_own_name() {
        let all = TaskKind::all::<4>();
        for (i, a) in all.iter().enumerate() {
            for b in all.iter().skip(i + 1) {
                assert_ne!(a, b);
                assert_ne!(a.name(), b.name());
            }
        }
        assert_eq!(TaskKind::JointDamping(JointGroup::Arm(ArmId::LEFT)).name(), "joint_damping_left_arm");
        assert_eq!(TaskKind::CartesianImpedance(ArmId(5)).name(), "unknown_arm");
    }
}
