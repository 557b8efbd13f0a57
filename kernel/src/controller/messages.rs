//! The planner channel (Sec. 7.1–7.2): fixed-size commands in (task selection and levels,
//! Table 7.1 parameters, goals and trajectories) and a telemetry summary out, with a byte
//! encoding (postcard: compact, `no_std`, no allocation) so that a host planner and the firmware
//! can talk over any link.
//!
//! A command is validated completely before anything changes: [`super::Controller::apply`]
//! either applies all of it or returns a [`CommandError`] and leaves the controller as it was.

use core::fmt;

use heapless::Vec;
use nalgebra::{Quaternion, RealField, Rotation3, SVector, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use super::config::{
    CartesianParameters, CollisionFieldParameters, Consistency, Field, Hand, JointGroup, TaskKind, TaskSpec,
    MAX_LEVELS, MAX_TASKS,
};
use super::faults::SafeOutput;
use super::trajectory::{JointTrajectory, PoseTrajectory};
use super::{cartesian_task, collision_parameters, ActiveTask, Controller, Telemetry, MAX_ACTIVE};
use crate::math::Placement;
use crate::tasks::cartesian_impedance::CartesianTarget;

/// A scalar that crosses the planner channel: `f32` or `f64` (any real field with serde).
pub trait WireScalar: RealField + Copy + Serialize + for<'de> Deserialize<'de> {}

impl<T: RealField + Copy + Serialize + for<'de> Deserialize<'de>> WireScalar for T {}

/// Most values in one joint goal (a group's coordinates).
pub const MAX_GOAL_VALUES: usize = 32;

/// A pose on the wire: position (m) and unit quaternion `(w, x, y, z)`, world frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose<T> {
    /// Position (m).
    pub position: [T; 3],
    /// Orientation quaternion `(w, x, y, z)`; normalised on receipt, its norm must be within
    /// 1 % of 1.
    pub orientation: [T; 4],
}

/// A command from the planner.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Command<T> {
    /// Replaces the hierarchy: which tasks run on which level. Tasks that move, appear or
    /// disappear are blended continuously over the configured transition time; a new hierarchy
    /// is refused while a transition is running.
    SetHierarchy(Vec<TaskSpec, MAX_TASKS>),
    /// Table 7.1 parameters of a TCP's Cartesian impedance.
    SetCartesian {
        /// Which TCP.
        hand: Hand,
        /// Stiffnesses, damping ratio and force limits.
        parameters: CartesianParameters<T>,
    },
    /// Parameters of a collision field.
    SetCollisionField {
        /// Which field.
        field: Field,
        /// Its parameters.
        parameters: CollisionFieldParameters<T>,
    },
    /// The consistency of the projections: static for contact tasks with force limits, dynamic
    /// for free motion. Takes effect in the next cycle.
    SetConsistency(Consistency),
    /// Move a TCP to a goal along the cubic of [`super::trajectory`] in `duration_s`.
    TcpGoal {
        /// Which TCP.
        hand: Hand,
        /// The goal.
        pose: Pose<T>,
        /// Duration (s), `≥ 0`.
        duration_s: T,
    },
    /// One sample of a planner-generated TCP trajectory (pose and twist), held until the next.
    TcpSample {
        /// Which TCP.
        hand: Hand,
        /// Desired pose.
        pose: Pose<T>,
        /// Desired linear velocity (m/s, world).
        linear_velocity: [T; 3],
        /// Desired angular velocity (rad/s, world).
        angular_velocity: [T; 3],
    },
    /// Move a group's joint-impedance goal (the platform's `(x, y, θ)` for a base goal) along
    /// the cubic in `duration_s`; `values` are the group's coordinates in order.
    JointGoal {
        /// Which group.
        group: JointGroup,
        /// Goal values (rad, m).
        values: Vec<T, MAX_GOAL_VALUES>,
        /// Duration (s), `≥ 0`.
        duration_s: T,
    },
}

/// Why a command was rejected. Nothing was changed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CommandError {
    /// A value is NaN or infinite where a finite one is required.
    NonFinite {
        /// Which field.
        field: &'static str,
    },
    /// A value is out of its range (negative stiffness, force limit of the wrong sign,
    /// non-unit quaternion, negative duration).
    OutOfRange {
        /// Which field.
        field: &'static str,
    },
    /// A task's level is `≥ MAX_LEVELS`.
    LevelOverflow {
        /// The level.
        level: u8,
    },
    /// A task appears twice in the hierarchy.
    DuplicateTask,
    /// A task the robot cannot run (e.g. the torso workspace without a coupled torso).
    UnknownTask,
    /// A joint goal's length is not its group's size.
    WrongLength {
        /// Values the group needs.
        expected: usize,
        /// Values received.
        received: usize,
    },
    /// A hierarchy change arrived while a transition is running.
    TransitionInProgress,
    /// A goal arrived before the first valid sensor frame (no start pose yet).
    NotStarted,
    /// The bytes do not decode to a command.
    Decode,
}

impl fmt::Display for CommandError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFinite { field } => write!(f, "non-finite {field}"),
            Self::OutOfRange { field } => write!(f, "{field} out of range"),
            Self::LevelOverflow { level } => write!(f, "level {level} is not below {MAX_LEVELS}"),
            Self::DuplicateTask => f.write_str("a task appears twice"),
            Self::UnknownTask => f.write_str("task not available on this robot"),
            Self::WrongLength { expected, received } => write!(f, "expected {expected} values, received {received}"),
            Self::TransitionInProgress => f.write_str("a hierarchy transition is running"),
            Self::NotStarted => f.write_str("no valid sensor frame yet"),
            Self::Decode => f.write_str("undecodable command"),
        }
    }
}

impl core::error::Error for CommandError {}

/// Checks a hierarchy: levels below `MAX_LEVELS`, no task twice.
fn validate_hierarchy(tasks: &[TaskSpec]) -> Result<(), CommandError> {
    for (i, spec) in tasks.iter().enumerate() {
        if usize::from(spec.level) >= MAX_LEVELS {
            return Err(CommandError::LevelOverflow { level: spec.level });
        }
        if tasks.iter().skip(i + 1).any(|other| other.kind == spec.kind) {
            return Err(CommandError::DuplicateTask);
        }
    }
    Ok(())
}

/// The hierarchy entries of a validated initial hierarchy (no transitions).
pub(super) fn initial_hierarchy<T: RealField + Copy>(
    tasks: &[TaskSpec],
) -> Result<Vec<ActiveTask<T>, MAX_ACTIVE>, CommandError> {
    if tasks.len() > MAX_TASKS {
        return Err(CommandError::OutOfRange { field: "hierarchy length" });
    }
    validate_hierarchy(tasks)?;
    let mut active = Vec::new();
    for spec in tasks {
        active
            .push(ActiveTask { kind: spec.kind, from: Some(spec.level), to: Some(spec.level), progress: T::one() })
            .map_err(|_| CommandError::OutOfRange { field: "hierarchy length" })?;
    }
    Ok(active)
}

fn finite<T: RealField + Copy>(values: &[T], field: &'static str) -> Result<(), CommandError> {
    if values.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(CommandError::NonFinite { field })
    }
}

fn duration<T: RealField + Copy>(value: T) -> Result<T, CommandError> {
    finite(&[value], "duration_s")?;
    if value < T::zero() {
        return Err(CommandError::OutOfRange { field: "duration_s" });
    }
    Ok(value)
}

/// A validated placement from a wire pose.
fn placement<T: RealField + Copy>(pose: &Pose<T>) -> Result<Placement<T>, CommandError> {
    finite(&pose.position, "position")?;
    finite(&pose.orientation, "orientation")?;
    let [w, x, y, z] = pose.orientation;
    let quaternion = Quaternion::new(w, x, y, z);
    let norm = quaternion.norm();
    let tolerance: T = nalgebra::convert(0.01);
    if (norm - T::one()).abs() > tolerance {
        return Err(CommandError::OutOfRange { field: "orientation" });
    }
    let rotation: Rotation3<T> = UnitQuaternion::new_normalize(quaternion).to_rotation_matrix();
    let [px, py, pz] = pose.position;
    Ok(Placement::from_parts(Translation3::new(px, py, pz), rotation))
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
    /// Applies a planner command, all or nothing (see the module docs).
    pub fn apply(&mut self, command: &Command<T>) -> Result<(), CommandError> {
        match command {
            Command::SetHierarchy(tasks) => self.set_hierarchy(tasks),
            Command::SetCartesian { hand, parameters } => {
                let p = parameters;
                finite(&p.translational_stiffness, "translational_stiffness")?;
                finite(&p.rotational_stiffness, "rotational_stiffness")?;
                finite(&[p.damping_ratio], "damping_ratio")?;
                let task = cartesian_task(&self.config, *hand, p)
                    .map_err(|_| CommandError::OutOfRange { field: "cartesian parameters" })?;
                if let (Some(slot), Some(config)) =
                    (self.tasks.cartesian.get_mut(hand.index()), self.config.cartesian.get_mut(hand.index()))
                {
                    *slot = task;
                    *config = *p;
                }
                Ok(())
            }
            Command::SetCollisionField { field, parameters } => {
                let p = parameters;
                finite(
                    &[p.max_force, p.influence_distance, p.damping_ratio, p.activation_full, p.activation_zero],
                    "collision parameters",
                )?;
                let validated =
                    collision_parameters(p).map_err(|_| CommandError::OutOfRange { field: "collision parameters" })?;
                if let (Some(slot), Some(config)) =
                    (self.tasks.collision.get_mut(field.index()), self.config.collision.get_mut(field.index()))
                {
                    *slot = validated;
                    *config = *p;
                }
                self.collision_data.exact_within = Some(self.tasks.broad_phase_distance());
                Ok(())
            }
            Command::SetConsistency(consistency) => {
                self.config.consistency = *consistency;
                Ok(())
            }
            Command::TcpGoal { hand, pose, duration_s } => {
                let goal = placement(pose)?;
                let duration = duration(*duration_s)?;
                let start = self.started_target(*hand)?;
                if let Some(slot) = self.hands.get_mut(hand.index()) {
                    *slot = PoseTrajectory::towards(start.pose, goal, duration);
                }
                Ok(())
            }
            Command::TcpSample { hand, pose, linear_velocity, angular_velocity } => {
                let pose = placement(pose)?;
                finite(linear_velocity, "linear_velocity")?;
                finite(angular_velocity, "angular_velocity")?;
                self.started_target(*hand)?;
                let target = CartesianTarget {
                    pose,
                    linear_velocity: Vector3::from(*linear_velocity),
                    angular_velocity: Vector3::from(*angular_velocity),
                };
                if let Some(slot) = self.hands.get_mut(hand.index()) {
                    *slot = PoseTrajectory::streamed(target);
                }
                Ok(())
            }
            Command::JointGoal { group, values, duration_s } => {
                finite(values, "values")?;
                let duration = duration(*duration_s)?;
                if !self.started {
                    return Err(CommandError::NotStarted);
                }
                let mask = self.config.layout.coordinates(*group);
                let expected = mask.iter().filter(|m| **m).count();
                if values.len() != expected {
                    return Err(CommandError::WrongLength { expected, received: values.len() });
                }
                let (start, _) = self.joint_goal.sample();
                let mut goal = *self.joint_goal.goal();
                let selected = goal.iter_mut().zip(mask.iter()).filter(|(_, m)| **m).map(|(g, _)| g);
                for (g, value) in selected.zip(values.iter()) {
                    *g = *value;
                }
                let mut from = start;
                // Coordinates outside the group keep their current goal without a new motion.
                for ((f, g), m) in from.iter_mut().zip(self.joint_goal.goal().iter()).zip(mask.iter()) {
                    if !m {
                        *f = *g;
                    }
                }
                self.joint_goal = JointTrajectory::towards(from, goal, duration);
                Ok(())
            }
        }
    }

    /// Decodes a command from postcard bytes and applies it.
    pub fn apply_bytes(&mut self, bytes: &[u8]) -> Result<(), CommandError>
    where
        T: for<'de> Deserialize<'de>,
    {
        let command = decode_command::<T>(bytes)?;
        self.apply(&command)
    }

    fn started_target(&self, hand: Hand) -> Result<CartesianTarget<T>, CommandError> {
        if !self.started {
            return Err(CommandError::NotStarted);
        }
        self.hands.get(hand.index()).map(PoseTrajectory::sample).ok_or(CommandError::UnknownTask)
    }

    fn set_hierarchy(&mut self, tasks: &[TaskSpec]) -> Result<(), CommandError> {
        validate_hierarchy(tasks)?;
        if self.in_transition() {
            return Err(CommandError::TransitionInProgress);
        }
        if self.config.torso_workspace.is_none() && tasks.iter().any(|t| t.kind == TaskKind::TorsoWorkspace) {
            return Err(CommandError::UnknownTask);
        }
        let mut next: Vec<ActiveTask<T>, MAX_ACTIVE> = Vec::new();
        for spec in tasks {
            let current = self.hierarchy.iter().find(|a| a.kind == spec.kind).and_then(|a| a.to);
            let (from, progress) = match current {
                Some(level) if level == spec.level => (Some(level), T::one()),
                other => (other, T::zero()),
            };
            next.push(ActiveTask { kind: spec.kind, from, to: Some(spec.level), progress })
                .map_err(|_| CommandError::OutOfRange { field: "hierarchy length" })?;
        }
        for old in self.hierarchy.iter().filter(|a| !tasks.iter().any(|t| t.kind == a.kind)) {
            next.push(ActiveTask { kind: old.kind, from: old.to, to: None, progress: T::zero() })
                .map_err(|_| CommandError::OutOfRange { field: "hierarchy length" })?;
        }
        self.hierarchy = next;
        Ok(())
    }
}

/// Encodes a command into `buffer` (postcard); returns the used prefix.
pub fn encode_command<'b, T: Serialize>(
    command: &Command<T>,
    buffer: &'b mut [u8],
) -> Result<&'b mut [u8], CommandError> {
    postcard::to_slice(command, buffer).map_err(|_| CommandError::Decode)
}

/// Decodes a command (postcard). Unknown variants, truncated or trailing-garbage-free input
/// that does not form a command give [`CommandError::Decode`].
pub fn decode_command<T: for<'de> Deserialize<'de>>(bytes: &[u8]) -> Result<Command<T>, CommandError> {
    postcard::from_bytes(bytes).map_err(|_| CommandError::Decode)
}

/// The telemetry summary the controller sends to the planner each cycle (Sec. 7.2): TCP
/// errors, storage functions and their rates per level, task activations, contact, energy,
/// output mode and fault.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TelemetryMessage<T> {
    /// Cycle counter.
    pub cycle: u64,
    /// Output mode of the cycle.
    pub mode: SafeOutput,
    /// Fault code (0 = none), see [`fault_code`].
    pub fault: u8,
    /// TCP errors, right then left: `(x, y, z, rx, ry, rz)` (m, rad-like).
    pub tcp_error: [[T; 6]; 2],
    /// Storage function (potential) per level (J).
    pub level_storage: Vec<T, MAX_LEVELS>,
    /// Its rate per level (W).
    pub level_storage_rate: Vec<T, MAX_LEVELS>,
    /// `(task, largest activation)` per hierarchy entry.
    pub activations: Vec<(TaskKind, T), MAX_ACTIVE>,
    /// Smallest collision distance (m), negative if none is computed.
    pub min_collision_distance: T,
    /// Norm of the external-torque estimate (Nm).
    pub external_torque_norm: T,
    /// Contact detected.
    pub contact: bool,
    /// Kinetic plus task potential energy (J).
    pub energy: T,
    /// Any output guard acted.
    pub saturated: bool,
}

/// A stable small code per fault class for the wire (0 = none).
pub fn fault_code(fault: Option<super::faults::Fault>) -> u8 {
    use super::faults::Fault;
    match fault {
        None => 0,
        Some(Fault::NonFiniteSensor { .. }) => 1,
        Some(Fault::PositionOutOfRange { .. }) => 2,
        Some(Fault::VelocityOutOfRange { .. }) => 3,
        Some(Fault::StaleFrame { .. }) => 4,
        Some(Fault::CycleGap { .. }) => 5,
        Some(Fault::InconsistentFrame) => 6,
        Some(Fault::Dynamics(_)) => 7,
        Some(Fault::Task(_)) => 8,
        Some(Fault::Hierarchy(_)) => 9,
        Some(Fault::Platform(_)) => 10,
        Some(Fault::NonFiniteOutput) => 11,
    }
}

impl<T: RealField + Copy> TelemetryMessage<T> {
    /// The summary of a cycle's telemetry.
    pub fn from_telemetry<const N: usize>(telemetry: &Telemetry<T, N>, mode: SafeOutput) -> Self {
        let t = telemetry;
        let levels = t.level_count.min(MAX_LEVELS);
        let collect = |values: &[T]| values.iter().take(levels).copied().collect::<Vec<T, MAX_LEVELS>>();
        let activations = t
            .tasks
            .iter()
            .zip(t.task_activation.iter())
            .take(t.task_count)
            .filter_map(|(kind, a)| kind.map(|k| (k, *a)))
            .collect();
        let external: SVector<T, N> = t.external_torque;
        Self {
            cycle: t.cycle,
            mode,
            fault: fault_code(t.fault),
            tcp_error: t.tcp_error.map(|e| e.into()),
            level_storage: collect(&t.level_storage),
            level_storage_rate: collect(&t.level_storage_rate),
            activations,
            min_collision_distance: t.min_collision_distance.unwrap_or_else(|| -T::one()),
            external_torque_norm: external.norm(),
            contact: t.contact,
            energy: t.kinetic_energy + t.potential_energy,
            saturated: t.saturation.any(),
        }
    }

    /// Encodes into `buffer` (postcard); returns the used prefix.
    pub fn encode<'b>(&self, buffer: &'b mut [u8]) -> Result<&'b mut [u8], CommandError>
    where
        T: Serialize,
    {
        postcard::to_slice(self, buffer).map_err(|_| CommandError::Decode)
    }
}
