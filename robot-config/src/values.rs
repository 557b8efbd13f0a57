//! The value types of the file: each refuses a bad value while it is read, so the error
//! carries the key and the line.

use kernel::controller::config::{ArmId, TaskKind, MAX_LEVELS, MAX_TASKS};
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

/// A task by the kernel's name for it ([`TaskKind::name`], e.g. `cartesian_right`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TaskName(pub TaskKind);

impl Serialize for TaskName {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.0.name())
    }
}

impl<'de> Deserialize<'de> for TaskName {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let name = String::deserialize(deserializer)?;
        let all = TaskKind::all::<ARMS>();
        match all.iter().find(|kind| kind.name() == name) {
            Some(kind) => Ok(Self(*kind)),
            None => {
                let known: Vec<&str> = all.iter().map(|kind| kind.name()).collect();
                Err(D::Error::custom(format!("unknown task `{name}` (known: {})", known.join(", "))))
            }
        }
    }
}

/// The arms a configuration file names: two, Justin's right and left ([`ArmId::name`]).
pub const ARMS: usize = 2;

/// A TCP by its arm's name ([`ArmId::name`]): `right` or `left`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HandName(pub ArmId);

impl HandName {
    fn name(self) -> &'static str {
        self.0.name()
    }
}

impl Serialize for HandName {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}

impl<'de> Deserialize<'de> for HandName {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let name = String::deserialize(deserializer)?;
        match ArmId::all::<ARMS>().into_iter().map(HandName).find(|hand| hand.name() == name) {
            Some(hand) => Ok(hand),
            None => Err(D::Error::custom(format!("unknown hand `{name}` (known: right, left)"))),
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
