//! Faults and the input validation at the step boundary.
//!
//! Every cycle the sensor frame is checked before anything is computed from it. A fault never
//! panics and never lets an unchecked torque out: [`super::Controller::step`] writes the safe
//! output of [`SafeOutput`] instead and reports the fault in the telemetry.
//!
//! | fault | detected by | output |
//! | --- | --- | --- |
//! | [`Fault::NonFiniteSensor`] | any NaN/inf in positions, velocities, torques, platform pose, velocity or leg lengths | hold |
//! | [`Fault::PositionOutOfRange`] | `q_i` beyond its model limit by more than `position_tolerance` | hold |
//! | [`Fault::VelocityOutOfRange`] | `|q̇_i|` of a joint or `|ṙ_i|` of the platform beyond `velocity_factor` × its model limit | hold |
//! | [`Fault::StaleFrame`] | cycle counter not advanced (repeated or old frame) | hold |
//! | [`Fault::CycleGap`] | cycle counter advanced by more than `max_cycle_gap` | hold |
//! | [`Fault::InconsistentFrame`] | joint and platform cycle counters differ | hold |
//! | [`Fault::Dynamics`], [`Fault::Task`], [`Fault::Hierarchy`], [`Fault::Platform`] | a kernel algorithm refused the (valid-looking) state | hold |
//! | [`Fault::NonFiniteOutput`] | a computed torque or platform command is not finite | hold |
//!
//! "Hold" ([`SafeOutput::Hold`]): joint torque `g(q) − D_safe q̇` (gravity at the measured
//! positions if they are finite, else at the last valid ones; damping only with finite
//! velocities), through the torque and torque-rate guards; platform velocity ramped to zero at
//! the acceleration limit, legs stopped. After `brake_after_cycles` consecutive faulty cycles the
//! output additionally requests the brakes ([`SafeOutput::Brake`]).
//!
//! The way back is [`super::recovery`]'s: `valid_cycles` valid frames against thresholds
//! tightened by a margin (the hold and the fault's report last meanwhile), then a blend of the
//! torque from the hold torque to the whole-body torque.

use core::fmt;

use nalgebra::RealField;

use crate::dynamics::DynamicsError;
use crate::hierarchy::HierarchyError;
use crate::model::Model;
use crate::platform::PlatformError;
use crate::tasks::TaskError;

pub use super::frames::SafeOutput;
use super::frames::SensorFrame;

/// Why a cycle fell back to the safe output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Fault {
    /// A sensor value is NaN or infinite.
    NonFiniteSensor {
        /// Which signal.
        field: &'static str,
    },
    /// A joint position is outside its limits (beyond the tolerance).
    PositionOutOfRange {
        /// The coordinate.
        coordinate: usize,
    },
    /// A joint velocity exceeds its limit times the allowed factor.
    VelocityOutOfRange {
        /// The coordinate.
        coordinate: usize,
    },
    /// The frame's cycle counter did not advance (a repeated or reordered frame).
    StaleFrame {
        /// Cycle of the last accepted frame.
        last: u64,
        /// Cycle of this frame.
        received: u64,
    },
    /// Frames were missed.
    CycleGap {
        /// How many cycles the counter advanced.
        gap: u64,
    },
    /// The joint and platform samples are from different cycles.
    InconsistentFrame,
    /// The dynamics refused the state.
    Dynamics(DynamicsError),
    /// A task refused its input.
    Task(TaskError),
    /// The projection refused the stack.
    Hierarchy(HierarchyError),
    /// A platform component refused its input.
    Platform(PlatformError),
    /// A computed command was not finite.
    NonFiniteOutput,
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFiniteSensor { field } => write!(f, "non-finite sensor value in {field}"),
            Self::PositionOutOfRange { coordinate } => write!(f, "position of coordinate {coordinate} out of range"),
            Self::VelocityOutOfRange { coordinate } => write!(f, "velocity of coordinate {coordinate} out of range"),
            Self::StaleFrame { last, received } => write!(f, "stale frame {received} (last {last})"),
            Self::CycleGap { gap } => write!(f, "cycle counter jumped by {gap}"),
            Self::InconsistentFrame => f.write_str("joint and platform samples from different cycles"),
            Self::Dynamics(e) => write!(f, "dynamics: {e}"),
            Self::Task(e) => write!(f, "task: {e}"),
            Self::Hierarchy(e) => write!(f, "hierarchy: {e}"),
            Self::Platform(e) => write!(f, "platform: {e}"),
            Self::NonFiniteOutput => f.write_str("non-finite command"),
        }
    }
}

impl core::error::Error for Fault {}

/// Thresholds of the input validation ([`validate_frame`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InputLimits<T> {
    /// How far a joint position may be beyond its model limit before it is a fault (rad, m),
    /// `≥ 0` (sensor noise, elastic stops).
    pub position_tolerance: T,
    /// A joint velocity beyond `velocity_factor` times its model limit is a fault, `≥ 1`.
    pub velocity_factor: T,
    /// A sensor frame whose cycle counter advanced by more than this is a fault (missed
    /// frames), `≥ 1`.
    pub max_cycle_gap: u64,
    /// Consecutive faulty cycles after which the safe output requests the brakes, `≥ 1`.
    pub brake_after_cycles: u32,
}

/// Checks a sensor frame against the model limits and the last accepted cycle.
///
/// Returns the first fault found, in the order of the module's table. `last_cycle` is `None`
/// before the first accepted frame. Cost O(N).
pub fn validate_frame<T: RealField + Copy, const N: usize, const B: usize, const F: usize, const U: usize>(
    model: &Model<T, N, B, F>,
    limits: &InputLimits<T>,
    frame: &SensorFrame<T, U>,
    upper_offset: usize,
    last_cycle: Option<u64>,
) -> Result<(), Fault> {
    let joints = &frame.joints;
    let platform = &frame.platform;
    let signals: [(&'static str, &[T]); 6] = [
        ("joint position", &joints.position),
        ("joint velocity", &joints.velocity),
        ("joint torque", &joints.torque),
        ("platform pose", &platform.pose),
        ("platform velocity", &platform.velocity),
        ("leg lengths", &platform.leg_lengths),
    ];
    for (field, values) in signals {
        if !values.iter().all(|x| x.is_finite()) {
            return Err(Fault::NonFiniteSensor { field });
        }
    }
    let limits_of = &model.limits;
    for (k, (q, v)) in joints.position.iter().zip(joints.velocity.iter()).enumerate() {
        let coordinate = k + upper_offset;
        let (Some(&lower), Some(&upper), Some(&speed)) = (
            limits_of.position_lower.get(coordinate),
            limits_of.position_upper.get(coordinate),
            limits_of.velocity.get(coordinate),
        ) else {
            return Err(Fault::PositionOutOfRange { coordinate });
        };
        if *q < lower - limits.position_tolerance || *q > upper + limits.position_tolerance {
            return Err(Fault::PositionOutOfRange { coordinate });
        }
        if v.abs() > speed * limits.velocity_factor {
            return Err(Fault::VelocityOutOfRange { coordinate });
        }
    }
    // The measured platform velocity enters the dynamics (C ṙ) and the platform loop: an absurd
    // finite value would otherwise pass unchecked.
    for (coordinate, v) in platform.velocity.iter().enumerate().take(upper_offset) {
        if let Some(&speed) = limits_of.velocity.get(coordinate) {
            if v.abs() > speed * limits.velocity_factor {
                return Err(Fault::VelocityOutOfRange { coordinate });
            }
        }
    }
    if joints.cycle != platform.cycle {
        return Err(Fault::InconsistentFrame);
    }
    if let Some(last) = last_cycle {
        if joints.cycle <= last {
            return Err(Fault::StaleFrame { last, received: joints.cycle });
        }
        let gap = joints.cycle.saturating_sub(last);
        if gap > limits.max_cycle_gap {
            return Err(Fault::CycleGap { gap });
        }
    }
    Ok(())
}
