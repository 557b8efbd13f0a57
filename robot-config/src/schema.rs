//! The file's structure: one struct per section, every key required, unknown keys refused.
//! The meaning of each value is documented in the robot's file (Justin's:
//! `fixtures/robots/justin/config.toml`) and in the kernel type it fills.

use serde::{Deserialize, Serialize};

use crate::values::{platform_part, torso_part, ArmValues, ForceBound, HandName, Levels, NonNegative, Robot};
use kernel::controller::config::TaskKind;

/// A robot's whole-body configuration.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RobotConfig {
    /// The robot's parts: its arms by name, a torso, a platform.
    pub robot: Robot,
    /// Cycle time and the hierarchy's transitions and shaping.
    pub controller: Controller,
    /// The Cartesian impedance of every TCP.
    pub cartesian: Cartesian,
    /// The whole-body hierarchies by name.
    pub hierarchy: Hierarchies,
    /// The service tasks (Table 7.1 columns) by name.
    pub service_tasks: std::collections::BTreeMap<String, ServiceTask>,
    /// The strong and the weak collision-avoidance field.
    pub collision: Collision,
    /// The arm singularity avoidance.
    pub singularity: Singularity,
    /// The end-stop avoidance.
    pub end_stops: EndStops,
    /// The torso workspace (Justin's two pitch joints): only on a robot with a torso.
    #[serde(default, deserialize_with = "torso_part", skip_serializing_if = "Option::is_none")]
    pub torso_workspace: Option<TorsoWorkspace>,
    /// The joint impedance and damping per coordinate.
    pub joint: Joint,
    /// The platform admittance and the ICR avoidance with leg motion: only on a robot with a
    /// platform.
    #[serde(default, deserialize_with = "platform_part", skip_serializing_if = "Option::is_none")]
    pub platform: Option<Platform>,
    /// Limits of the controller's outputs.
    pub output_limits: OutputLimits,
    /// Limits the sensor frames must respect.
    pub input_limits: InputLimits,
    /// The external-torque observer.
    pub observer: Observer,
    /// The Cartesian force limitation.
    pub force_limit: ForceLimit,
    /// The joint speed barrier.
    pub speed_barrier: SpeedBarrier,
    /// The way back from a fault.
    pub recovery: Recovery,
}

/// `[controller]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Controller {
    /// Control period (s).
    pub period_s: NonNegative,
    /// Time a task takes to move between levels (s).
    pub transition_s: NonNegative,
    /// Continuous shaping: rows fade out between these fractions of their unprojected weight.
    pub shaping: Shaping,
}

/// `[controller.shaping]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Shaping {
    /// Fully faded below this fraction.
    pub singular_full: NonNegative,
    /// Fading starts below this fraction.
    pub singular_start: NonNegative,
}

/// `[cartesian]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Cartesian {
    /// Translational stiffness (N/m).
    pub translational_stiffness: NonNegative,
    /// Rotational stiffness (Nm/rad).
    pub rotational_stiffness: NonNegative,
    /// Damping ratio of the impedances.
    pub damping_ratio: NonNegative,
    /// Damping (Ns/m, Nms/rad) when the damping design fails.
    pub fallback_damping: [NonNegative; 6],
}

/// `[hierarchy]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Hierarchies {
    /// The hierarchy of Fig. 6.3, written for the right TCP.
    pub fig_6_3: Hierarchy,
}

/// A hierarchy.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Hierarchy {
    /// Its levels, highest priority first.
    pub levels: Levels,
}

/// `[service_tasks.<name>]`: a Table 7.1 column.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ServiceTask {
    /// The tool's hierarchy, highest priority first.
    pub levels: Levels,
    /// Translational stiffness `(x, y, z)` (N/m).
    pub translational_stiffness: [NonNegative; 3],
    /// Rotational stiffness (Nm/rad).
    pub rotational_stiffness: [NonNegative; 3],
    /// Lower force limits (N).
    pub force_lower: [ForceBound; 3],
    /// Upper force limits (N).
    pub force_upper: [ForceBound; 3],
    /// The TCPs that carry the tool.
    pub hands: Vec<HandName>,
    /// `true` if the platform moves.
    pub base: bool,
}

/// `[collision]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Collision {
    /// The tight, strong field.
    pub strong: CollisionField,
    /// The weak, extended field.
    pub weak: CollisionField,
}

/// A collision-avoidance field.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CollisionField {
    /// Force at contact (N).
    pub max_force: NonNegative,
    /// Distance where the field starts (m).
    pub influence_distance: NonNegative,
    /// Damping ratio.
    pub damping_ratio: NonNegative,
    /// Distance of full activation (m).
    pub activation_full: NonNegative,
    /// Distance of zero activation (m).
    pub activation_zero: NonNegative,
}

/// `[singularity]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Singularity {
    /// The TCP Jacobian rows of the manipulability (x, y, z, rx, ry, rz).
    pub rows: [bool; 6],
    /// Manipulability where the avoidance starts.
    pub threshold: NonNegative,
    /// Manipulability of full activation.
    pub full_activation: NonNegative,
    /// Stiffness.
    pub stiffness: NonNegative,
    /// Damping.
    pub damping: NonNegative,
}

/// The potential near every joint's limits: `[end_stops]`, one margin, the gains per coordinate.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct EndStops {
    /// Distance from the limit where the potential starts (rad, m).
    pub margin: NonNegative,
    /// Stiffness `k_mes` of each joint's potential `k_mes Δ²`.
    pub stiffness: PerCoordinate,
    /// Damping of each joint.
    pub damping: PerCoordinate,
}

/// `[torso_workspace]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TorsoWorkspace {
    /// Symmetric torque limit of the two pitch joints (Nm).
    pub torque_limit_nm: NonNegative,
    /// The load on the torso centre (N).
    pub load_force_n: NonNegative,
    /// Its direction from the horizontal (deg).
    pub load_angle_deg: NonNegative,
    /// The boundary repulsion.
    pub repulsion: TorsoRepulsion,
}

/// `[torso_workspace.repulsion]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TorsoRepulsion {
    /// Largest stiffness (N/m).
    pub max_stiffness: NonNegative,
    /// Distance where the repulsion starts (m).
    pub distance: NonNegative,
    /// Damping ratio.
    pub damping_ratio: NonNegative,
}

/// `[joint]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Joint {
    /// Joint impedance stiffness.
    pub stiffness: PerCoordinate,
    /// Joint impedance and joint damping task damping.
    pub damping: PerCoordinate,
    /// Damping of the safe (hold) output.
    pub safe_damping: PerCoordinate,
    /// Largest loop gain `Δt λ_max(M̃⁻¹ D)` of each joint task's damping.
    pub damping_loop_gain: NonNegative,
}

/// A value per coordinate: the platform's `(x, y, θ)` (a robot with a platform), one for every
/// torso joint (a robot with a torso), one per arm joint (the same for every arm).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PerCoordinate {
    /// Platform `x, y, θ`.
    #[serde(default, deserialize_with = "platform_part", skip_serializing_if = "Option::is_none")]
    pub platform: Option<[NonNegative; 3]>,
    /// Every torso joint.
    #[serde(default, deserialize_with = "torso_part", skip_serializing_if = "Option::is_none")]
    pub torso: Option<NonNegative>,
    /// Arm joints 1 to `[robot] arm_joints`.
    pub arm: ArmValues,
}

/// `[platform]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Platform {
    /// Force below which the base does not move (N, N, Nm).
    pub force_deadband: [NonNegative; 3],
    /// The compensation (5.14).
    pub compensation: Compensation,
    /// The admittance.
    pub admittance: Admittance,
    /// The ICR repulsion.
    pub icr_avoidance: IcrAvoidance,
    /// The leg admittance.
    pub legs: Legs,
}

/// `[platform.compensation]`: the terms of (5.14).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Compensation {
    /// The couplings `M_qr r̈ + C_qr ṙ` (Sec. 5.1.4 "ON").
    pub coupling: bool,
    /// The gravity torque `g_q`.
    pub gravity: bool,
}

/// `[platform.admittance]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Admittance {
    /// Mass (kg, kg, kg m²).
    pub mass: [NonNegative; 3],
    /// Damping.
    pub damping: [NonNegative; 3],
    /// Force limit.
    pub force_limit: [NonNegative; 3],
    /// Axes the admittance moves.
    pub free_axes: [bool; 3],
}

/// `[platform.icr_avoidance]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct IcrAvoidance {
    /// The avoidance on.
    pub enabled: bool,
    /// Field extension beyond a wheel (m).
    pub max_extension_m: NonNegative,
    /// Field extension per metre of leg deviation.
    pub extension_ratio: NonNegative,
    /// Largest repulsion.
    pub max_force: NonNegative,
    /// Smallest yaw rate of the ICR computation (rad/s).
    pub min_yaw_rate: NonNegative,
}

/// `[platform.legs]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Legs {
    /// Leg motion on.
    pub motion: bool,
    /// Admittance mass (kg).
    pub mass_kg: NonNegative,
    /// Admittance damping (kg/s).
    pub damping_kg_s: NonNegative,
    /// Cubic return stiffness (N/m³).
    pub cubic_stiffness_n_m3: NonNegative,
    /// Pole of the return-to-nominal loop (rad/s).
    pub return_pole_rad_s: NonNegative,
    /// Blend distance of the return gain near a wheel (m).
    pub return_blend_m: NonNegative,
}

/// `[output_limits]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct OutputLimits {
    /// Torque rate per coordinate (Nm/s).
    pub torque_rate: PerCoordinate,
    /// Base velocity (m/s, m/s, rad/s): a robot with a platform.
    #[serde(default, deserialize_with = "platform_part", skip_serializing_if = "Option::is_none")]
    pub base_velocity: Option<[NonNegative; 3]>,
    /// Base acceleration: a robot with a platform.
    #[serde(default, deserialize_with = "platform_part", skip_serializing_if = "Option::is_none")]
    pub base_acceleration: Option<[NonNegative; 3]>,
    /// Leg rate (m/s): a robot with a platform.
    #[serde(default, deserialize_with = "platform_part", skip_serializing_if = "Option::is_none")]
    pub leg_rate: Option<NonNegative>,
}

/// `[input_limits]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct InputLimits {
    /// Tolerance beyond a position limit (rad, m).
    pub position_tolerance: NonNegative,
    /// Factor on the velocity limits.
    pub velocity_factor: NonNegative,
    /// Largest cycle-counter step.
    pub max_cycle_gap: u32,
    /// Faulty cycles before the brake.
    pub brake_after_cycles: u32,
}

/// `[observer]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Observer {
    /// Observer gain (1/s).
    pub gain: NonNegative,
    /// External torque that counts as contact (Nm).
    pub contact_threshold: NonNegative,
}

/// `[force_limit]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ForceLimit {
    /// The limitation on.
    pub enabled: bool,
    /// Margin below the limit.
    pub margin: NonNegative,
    /// Correction gain (1/s).
    pub gain: NonNegative,
    /// Largest correction (N, Nm).
    pub max_correction: NonNegative,
    /// Regularisation.
    pub regularisation: NonNegative,
}

/// `[speed_barrier]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SpeedBarrier {
    /// Fraction of the speed limit where the barrier starts.
    pub onset: NonNegative,
    /// Fraction where it acts fully.
    pub full: NonNegative,
    /// Braking time (s).
    pub braking_time_s: NonNegative,
    /// Largest fraction of a joint's peak torque.
    pub max_torque_fraction: NonNegative,
}

/// `[recovery]`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Recovery {
    /// Valid frames before the way back.
    pub valid_cycles: u32,
    /// Margin the thresholds are tightened by.
    pub margin: NonNegative,
    /// Blend time back to the whole-body torque (s).
    pub blend_s: NonNegative,
}

impl RobotConfig {
    /// The first key the robot's parts (`[robot]`) need that the file leaves out, with the
    /// problem: the platform's tables and values on a robot with a platform, the torso's values
    /// on a robot with a torso, `[torso_workspace]` if a hierarchy has the `torso_workspace` task.
    pub(crate) fn missing_part(&self) -> Option<(String, String)> {
        let per_coordinate = [
            ("joint.stiffness", &self.joint.stiffness),
            ("joint.damping", &self.joint.damping),
            ("joint.safe_damping", &self.joint.safe_damping),
            ("output_limits.torque_rate", &self.output_limits.torque_rate),
        ];
        let mut missing: Vec<(String, &str)> = Vec::new();
        if self.robot.platform {
            let base = &self.output_limits;
            let tables = [
                ("platform", self.platform.is_some()),
                ("output_limits.base_velocity", base.base_velocity.is_some()),
                ("output_limits.base_acceleration", base.base_acceleration.is_some()),
                ("output_limits.leg_rate", base.leg_rate.is_some()),
            ];
            missing.extend(
                tables
                    .iter()
                    .filter(|(_, present)| !present)
                    .map(|(key, _)| ((*key).to_owned(), "[robot] platform = true")),
            );
            missing.extend(
                per_coordinate
                    .iter()
                    .filter(|(_, v)| v.platform.is_none())
                    .map(|(key, _)| (format!("{key}.platform"), "[robot] platform = true")),
            );
        }
        if self.robot.torso {
            missing.extend(
                per_coordinate
                    .iter()
                    .filter(|(_, v)| v.torso.is_none())
                    .map(|(key, _)| (format!("{key}.torso"), "[robot] torso = true")),
            );
        }
        if self.torso_workspace.is_none()
            && self.hierarchies().any(|levels| levels.tasks().any(|(_, kind)| kind == TaskKind::TorsoWorkspace))
        {
            missing.push(("torso_workspace".to_owned(), "a hierarchy has the torso_workspace task"));
        }
        missing.into_iter().next().map(|(key, reason)| (key, format!("missing key ({reason})")))
    }

    /// Every hierarchy of the file: Fig. 6.3's and the service tasks'.
    fn hierarchies(&self) -> impl Iterator<Item = &Levels> {
        std::iter::once(&self.hierarchy.fig_6_3.levels).chain(self.service_tasks.values().map(|task| &task.levels))
    }
}
