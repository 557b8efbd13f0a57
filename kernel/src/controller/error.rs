//! The errors of the controller's interface: [`ConfigError`] when a controller is built,
//! [`CommandError`] when a planner command is refused.

use core::fmt;

use super::capacity::MAX_LEVELS;
use crate::platform::PlatformError;
use crate::tasks::TaskError;

/// Why [`super::Controller::try_new`] refused its inputs.
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
    Hierarchy(CommandError),
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Task(e) => write!(f, "task: {e}"),
            Self::Platform(e) => write!(f, "platform: {e}"),
            Self::InvalidParameter { name } => write!(f, "invalid parameter {name}"),
            Self::Hierarchy(e) => write!(f, "hierarchy: {e}"),
        }
    }
}

impl core::error::Error for ConfigError {}

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
