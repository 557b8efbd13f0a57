//! The command path (Sec. 7.1): the planner's [`Command`]s (task selection and levels, Table 7.1
//! parameters, goals and trajectories), their byte encoding (postcard: compact, `no_std`, no
//! allocation) and how the controller applies them: validated completely, then applied, or
//! refused with a [`CommandError`] and nothing changed ([`super::Controller::apply`]).

use heapless::Vec;
use nalgebra::{Quaternion, RealField, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use super::config::{CartesianParameters, CollisionFieldParameters, Consistency, Field, TaskSpec, MAX_TASKS};
use super::error::CommandError;
use super::layout::{ArmId, JointGroup};
use super::settings::ControllerSettings;
use super::state::{ControllerState, Workspace};
use super::task_set::{cartesian_task, collision_parameters};
use super::trajectory::{JointTrajectory, PoseTrajectory};
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
        /// Which TCP: its arm, `OutOfRange` for an arm the robot does not have.
        hand: ArmId,
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
        /// Which TCP: its arm, `OutOfRange` for an arm the robot does not have.
        hand: ArmId,
        /// The goal.
        pose: Pose<T>,
        /// Duration (s), `≥ 0`.
        duration_s: T,
    },
    /// One sample of a planner-generated TCP trajectory (pose and twist), held until the next.
    TcpSample {
        /// Which TCP: its arm, `OutOfRange` for an arm the robot does not have.
        hand: ArmId,
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

/// The refusal of a command for an arm the robot does not have.
const OUT_OF_RANGE_ARM: CommandError = CommandError::OutOfRange { field: "hand" };

/// What a command may change: the settings, the state and the collision workspace's broad-phase
/// distance.
pub(super) struct CommandTarget<
    'a,
    T: RealField,
    const N: usize,
    const B: usize,
    const F: usize,
    const U: usize,
    const V: usize,
    const P: usize,
    const A: usize,
> {
    pub(super) settings: &'a mut ControllerSettings<T, N, B, F, V, P, A>,
    pub(super) state: &'a mut ControllerState<T, N, U, A>,
    pub(super) work: &'a mut Workspace<T, N, B, F, V, P, A>,
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
    > CommandTarget<'_, T, N, B, F, U, V, P, A>
{
    /// Applies a planner command, all or nothing (see the module docs).
    pub(super) fn apply(&mut self, command: &Command<T>) -> Result<(), CommandError> {
        match command {
            Command::SetHierarchy(tasks) => {
                let task_set = &self.settings.tasks;
                self.state.hierarchy.replace(tasks, |kind| task_set.supports(kind))
            }
            Command::SetCartesian { hand, parameters } => {
                let p = parameters;
                finite(&p.translational_stiffness, "translational_stiffness")?;
                finite(&p.rotational_stiffness, "rotational_stiffness")?;
                finite(&[p.damping_ratio], "damping_ratio")?;
                let frame = *hand.of(&self.settings.config.layout.tcp).ok_or(OUT_OF_RANGE_ARM)?;
                let task = cartesian_task(&self.settings.config, frame, p)
                    .map_err(|_| CommandError::OutOfRange { field: "cartesian parameters" })?;
                if let (Some(slot), Some(config)) =
                    (hand.of_mut(&mut self.settings.tasks.cartesian), hand.of_mut(&mut self.settings.config.cartesian))
                {
                    (*slot, *config) = (task, *p);
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
                if let (Some(slot), Some(config)) = (
                    self.settings.tasks.collision.get_mut(field.index()),
                    self.settings.config.collision.get_mut(field.index()),
                ) {
                    *slot = validated;
                    *config = *p;
                }
                self.work.collision_data.exact_within = Some(self.settings.tasks.broad_phase_distance());
                Ok(())
            }
            Command::SetConsistency(consistency) => {
                self.settings.config.consistency = *consistency;
                Ok(())
            }
            Command::TcpGoal { hand, pose, duration_s } => {
                let goal = placement(pose)?;
                let duration = duration(*duration_s)?;
                let start = self.started_target(*hand)?;
                if let Some(trajectory) = hand.of_mut(&mut self.state.hands) {
                    *trajectory = PoseTrajectory::towards(start.pose, goal, duration);
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
                if let Some(trajectory) = hand.of_mut(&mut self.state.hands) {
                    *trajectory = PoseTrajectory::streamed(target);
                }
                Ok(())
            }
            Command::JointGoal { group, values, duration_s } => {
                finite(values, "values")?;
                let duration = duration(*duration_s)?;
                if !self.state.started {
                    return Err(CommandError::NotStarted);
                }
                if matches!(group, JointGroup::Arm(arm) if arm.index() >= A) {
                    return Err(OUT_OF_RANGE_ARM);
                }
                let mask = self.settings.config.layout.coordinates(*group);
                let expected = mask.iter().filter(|m| **m).count();
                if values.len() != expected {
                    return Err(CommandError::WrongLength { expected, received: values.len() });
                }
                let (start, _) = self.state.joint_goal.sample();
                let mut goal = *self.state.joint_goal.goal();
                let selected = goal.iter_mut().zip(mask.iter()).filter(|(_, m)| **m).map(|(g, _)| g);
                for (g, value) in selected.zip(values.iter()) {
                    *g = *value;
                }
                let mut from = start;
                // Coordinates outside the group keep their current goal without a new motion.
                for ((f, g), m) in from.iter_mut().zip(self.state.joint_goal.goal().iter()).zip(mask.iter()) {
                    if !m {
                        *f = *g;
                    }
                }
                self.state.joint_goal = JointTrajectory::towards(from, goal, duration);
                Ok(())
            }
        }
    }

    /// The current target of `hand`'s TCP; `OutOfRange` for an arm the robot does not have,
    /// `NotStarted` before the first valid frame.
    fn started_target(&self, hand: ArmId) -> Result<CartesianTarget<T>, CommandError> {
        let trajectory = hand.of(&self.state.hands).ok_or(OUT_OF_RANGE_ARM)?;
        if !self.state.started {
            return Err(CommandError::NotStarted);
        }
        Ok(trajectory.sample())
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

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::{encode_command, Command, Pose};
    use crate::controller::config::{CartesianParameters, TaskKind, TaskSpec};
    use crate::controller::layout::{ArmId, JointGroup};

    fn pose() -> Pose<f32> {
        Pose { position: [0.5, -0.25, 1.0], orientation: [1.0, 0.0, 0.0, 0.0] }
    }

    /// Justin's commands on the wire, pinned byte for byte: the arm is one byte (0 right, 1 left)
    /// in the command and in the task kinds of a hierarchy.
    #[test]
    fn justin_commands_keep_their_bytes() {
        let hierarchy = [
            TaskSpec { kind: TaskKind::CartesianImpedance(ArmId::LEFT), level: 0 },
            TaskSpec { kind: TaskKind::SingularityAvoidance(ArmId::RIGHT), level: 1 },
            TaskSpec { kind: TaskKind::JointImpedance(JointGroup::Arm(ArmId::LEFT)), level: 2 },
            TaskSpec { kind: TaskKind::JointDamping(JointGroup::UpperBody), level: 2 },
        ];
        let parameters = CartesianParameters {
            translational_stiffness: [1000.0_f32, 2000.0, 3000.0],
            rotational_stiffness: [10.0, 20.0, 30.0],
            damping_ratio: 0.7,
            force_lower: [f32::NEG_INFINITY, -5.0, -5.0, -1.0, -1.0, -1.0],
            force_upper: [10.0, 5.0, 5.0, 1.0, 1.0, f32::INFINITY],
        };
        let commands: [(Command<f32>, &str); 4] = [
            (Command::SetHierarchy(hierarchy.iter().copied().collect()), "000400010002000105020102060302"),
            (Command::SetCartesian { hand: ArmId::LEFT, parameters }, "010100007a440000fa4400803b45000020410000a0410000f0413333333f000080ff0000a0c00000a0c0000080bf000080bf000080bf000020410000a0400000a0400000803f0000803f0000807f"),
            (
                Command::TcpGoal { hand: ArmId::RIGHT, pose: pose(), duration_s: 2.0 },
                "04000000003f000080be0000803f0000803f00000000000000000000000000000040",
            ),
            (
                Command::TcpSample {
                    hand: ArmId::LEFT,
                    pose: pose(),
                    linear_velocity: [0.1, 0.0, 0.0],
                    angular_velocity: [0.0, 0.0, 0.5],
                },
                "05010000003f000080be0000803f0000803f000000000000000000000000cdcccc3d000000000000000000000000000000000000003f",
            ),
        ];
        for (command, expected) in commands {
            let mut buffer = [0_u8; 256];
            let bytes = encode_command(&command, &mut buffer).unwrap();
            let hex: std::string::String = bytes.iter().map(|b| std::format!("{b:02x}")).collect();
            assert_eq!(hex, expected, "{command:?}");
        }
    }
}
