//! The value types of the file: each refuses a bad value while it is read, so the error
//! carries the key and the line.

use kernel::controller::config::{ArmId, JointGroup, TaskKind, MAX_ARMS, MAX_LEVELS, MAX_TASKS};
use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// A stiffness, damping, gain, limit, mass or time: finite and `≥ 0`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(transparent)]
pub struct NonNegative(pub f64);

impl<'de> Deserialize<'de> for NonNegative {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let accepted = |value: f64| value.is_finite() && value >= 0.0;
        read_number(deserializer, accepted, "is not finite and non-negative").map(Self)
    }
}

/// A number `accepted` keeps, or the error "`<number> <refusal>`".
fn read_number<'de, D: Deserializer<'de>>(
    deserializer: D,
    accepted: impl Fn(f64) -> bool,
    refusal: &str,
) -> Result<f64, D::Error> {
    let value = f64::deserialize(deserializer)?;
    if accepted(value) {
        Ok(value)
    } else {
        Err(D::Error::custom(format!("{value} {refusal}")))
    }
}

/// A force limit: any number but NaN (`inf` and `-inf` for no limit).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(transparent)]
pub struct ForceBound(pub f64);

impl<'de> Deserialize<'de> for ForceBound {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        read_number(deserializer, |value| !value.is_nan(), "is not a force limit (inf or -inf for none)").map(Self)
    }
}

/// The robot's parts, the file's `[robot]`: its arms by name (one per TCP, in the order of
/// the robot's TCPs), whether it has a torso and a platform. Task and hand names are checked
/// against it.
#[derive(Clone, Debug, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Robot {
    /// The arms' names (lower case letters, digits, `_`), arm 0 first.
    pub arms: Vec<String>,
    /// Joints of every arm: the length of the per-coordinate tables' `arm` lists.
    pub arm_joints: u32,
    /// `true` if the robot has a torso.
    pub torso: bool,
    /// `true` if the robot has the admitted platform `(x, y, θ)`.
    pub platform: bool,
}

impl Robot {
    /// The name of `kind` on this robot (`cartesian_<arm>`, `singularity_<arm>`,
    /// `joint_impedance_<arm>_arm`, `joint_damping_<arm>_arm`; the others the kernel's
    /// [`TaskKind::name`]), `None` for a task of a part the robot does not have.
    pub fn task_name(&self, kind: TaskKind) -> Option<String> {
        let arm = |arm: ArmId| self.arms.get(arm.index());
        let group = |group: JointGroup| match group {
            JointGroup::Arm(a) => arm(a).map(|name| format!("{name}_arm")),
            JointGroup::Torso => self.torso.then(|| "torso".to_owned()),
            JointGroup::Platform => self.platform.then(|| "platform".to_owned()),
            JointGroup::UpperBody => Some("upper_body".to_owned()),
        };
        match kind {
            TaskKind::CartesianImpedance(a) => arm(a).map(|name| format!("cartesian_{name}")),
            TaskKind::SingularityAvoidance(a) => arm(a).map(|name| format!("singularity_{name}")),
            TaskKind::JointImpedance(g) => group(g).map(|name| format!("joint_impedance_{name}")),
            TaskKind::JointDamping(g) => group(g).map(|name| format!("joint_damping_{name}")),
            TaskKind::TorsoWorkspace => self.torso.then(|| kind.name().to_owned()),
            TaskKind::CollisionAvoidance(_) | TaskKind::EndStops => Some(kind.name().to_owned()),
        }
    }

    /// Every task the robot has, with its name.
    fn tasks(&self) -> Vec<(String, TaskKind)> {
        TaskKind::all::<MAX_ARMS>().into_iter().filter_map(|kind| Some((self.task_name(kind)?, kind))).collect()
    }

    /// Runs `read` with this robot as the one task and hand names are read against.
    pub(crate) fn reading<R>(&self, read: impl FnOnce() -> R) -> R {
        let previous = READ_AGAINST.with(|robot| robot.replace(self.clone()));
        let result = read();
        READ_AGAINST.with(|robot| robot.replace(previous));
        result
    }
}

thread_local! {
    /// The robot whose file is being read or written ([`Robot::reading`]): serde's
    /// `Deserialize` takes no context.
    static READ_AGAINST: std::cell::RefCell<Robot> = std::cell::RefCell::new(Robot::default());
}

fn robot_read_against() -> Robot {
    READ_AGAINST.with(|robot| robot.borrow().clone())
}

/// A task by its name on the robot ([`Robot::task_name`], e.g. `cartesian_right`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TaskName(pub TaskKind);

impl Serialize for TaskName {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let name = robot_read_against().task_name(self.0);
        let name = name.ok_or_else(|| serde::ser::Error::custom(format!("no name for {:?}", self.0)))?;
        serializer.serialize_str(&name)
    }
}

impl<'de> Deserialize<'de> for TaskName {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let name = String::deserialize(deserializer)?;
        let tasks = robot_read_against().tasks();
        match tasks.iter().find(|(known, _)| *known == name) {
            Some((_, kind)) => Ok(Self(*kind)),
            None => {
                let known: Vec<&str> = tasks.iter().map(|(known, _)| known.as_str()).collect();
                Err(D::Error::custom(format!("unknown task `{name}` (known: {})", known.join(", "))))
            }
        }
    }
}

/// One value per joint of an arm, for every arm (`arm` of a per-coordinate table): as many as
/// `[robot] arm_joints`.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(transparent)]
pub struct ArmValues(pub Vec<NonNegative>);

impl<'de> Deserialize<'de> for ArmValues {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let values = Vec::deserialize(deserializer)?;
        let joints = robot_read_against().arm_joints;
        if usize::try_from(joints).ok() == Some(values.len()) {
            Ok(Self(values))
        } else {
            Err(D::Error::custom(format!("{} values for arms of {joints} joints ([robot] arm_joints)", values.len())))
        }
    }
}

/// A value of the platform (`#[serde(deserialize_with)]`): refused on a robot without one.
pub fn platform_part<'de, D: Deserializer<'de>, X: Deserialize<'de>>(deserializer: D) -> Result<Option<X>, D::Error> {
    part(deserializer, robot_read_against().platform, "platform")
}

/// A value of the torso (`#[serde(deserialize_with)]`): refused on a robot without one.
pub fn torso_part<'de, D: Deserializer<'de>, X: Deserialize<'de>>(deserializer: D) -> Result<Option<X>, D::Error> {
    part(deserializer, robot_read_against().torso, "torso")
}

fn part<'de, D: Deserializer<'de>, X: Deserialize<'de>>(
    deserializer: D,
    has: bool,
    name: &str,
) -> Result<Option<X>, D::Error> {
    if has {
        X::deserialize(deserializer).map(Some)
    } else {
        Err(D::Error::custom(format!("the robot has no {name} ([robot] {name} = false)")))
    }
}

/// A TCP by its arm's name (`[robot] arms`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HandName(pub ArmId);

impl Serialize for HandName {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let robot = robot_read_against();
        let name = robot.arms.get(self.0.index());
        serializer.serialize_str(name.ok_or_else(|| serde::ser::Error::custom(format!("no arm {}", self.0 .0)))?)
    }
}

impl<'de> Deserialize<'de> for HandName {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let name = String::deserialize(deserializer)?;
        let robot = robot_read_against();
        match robot.arms.iter().position(|arm| *arm == name).and_then(|i| u8::try_from(i).ok()) {
            Some(index) => Ok(HandName(ArmId(index))),
            None => Err(D::Error::custom(format!("unknown hand `{name}` (known: {})", robot.arms.join(", ")))),
        }
    }
}

/// A task hierarchy: its levels from the highest priority down, each a list of tasks. Refused:
/// an empty level, more than [`MAX_LEVELS`] levels or [`MAX_TASKS`] tasks (the kernel's
/// capacities), a task twice.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(transparent)]
pub struct Levels(pub Vec<Vec<TaskName>>);

impl<'de> Deserialize<'de> for Levels {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let levels = Levels(Vec::deserialize(deserializer)?);
        levels.check().map_err(D::Error::custom)?;
        Ok(levels)
    }
}

impl Levels {
    /// Every task with its level, level 0 first.
    pub fn tasks(&self) -> impl Iterator<Item = (usize, TaskKind)> + '_ {
        self.0.iter().enumerate().flat_map(|(level, tasks)| tasks.iter().map(move |task| (level, task.0)))
    }

    fn check(&self) -> Result<(), String> {
        if self.0.len() > MAX_LEVELS {
            return Err(format!("level overflow: {} levels, the kernel holds {MAX_LEVELS} (MAX_LEVELS)", self.0.len()));
        }
        if let Some(level) = self.0.iter().position(Vec::is_empty) {
            return Err(format!("level {level} is empty"));
        }
        let count = self.tasks().count();
        if count > MAX_TASKS {
            return Err(format!("level overflow: {count} tasks, the kernel holds {MAX_TASKS} (MAX_TASKS)"));
        }
        let tasks: Vec<(usize, TaskKind)> = self.tasks().collect();
        for (i, (level, kind)) in tasks.iter().enumerate() {
            if let Some((other, _)) = tasks.iter().skip(i + 1).find(|(_, other)| other == kind) {
                return Err(format!("duplicate task `{}` on levels {level} and {other}", kind.name()));
            }
        }
        Ok(())
    }
}
