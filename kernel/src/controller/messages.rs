//! The planner channel (Sec. 7.1–7.2) in one place: fixed-size commands in ([`Command`], defined
//! with the command path in [`super::command`]) and a telemetry summary out
//! ([`TelemetryMessage`], defined with the telemetry in [`super::telemetry`]), with a byte
//! encoding (postcard: compact, `no_std`, no allocation) so that a host planner and the firmware
//! can talk over any link.
//!
//! A command is validated completely before anything changes: [`super::Controller::apply`]
//! either applies all of it or returns a [`CommandError`] and leaves the controller as it was.

pub use super::command::{decode_command, encode_command, Command, Pose, WireScalar, MAX_GOAL_VALUES};
pub use super::error::CommandError;
pub use super::telemetry::{fault_code, TelemetryMessage};
