//! What travels on the link: the [`Frame`] and its [`Payload`]s.

use hal::{JointSample, PlatformCommand, PlatformSample, LEGS};
use serde::{Deserialize, Serialize};

use crate::setup::{SetupChunk, SetupReply};

/// Most joints a sensor or actuator frame carries.
pub const MAX_JOINTS: usize = 32;
/// Most bytes of an opaque planner command or telemetry message (the kernel's postcard encoding).
pub const MAX_MESSAGE_BYTES: usize = 384;

/// One value per joint, at most [`MAX_JOINTS`].
pub type Joints = heapless::Vec<f32, MAX_JOINTS>;

/// One message on the link: `seq` counts the sender's frames, +1 per frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Frame {
    /// The sender's frame counter.
    pub seq: u32,
    /// What the frame carries.
    pub payload: Payload,
}

/// The kinds of frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Payload {
    /// Host → board: one control cycle's sensor values.
    Sensor(SensorMsg),
    /// Board → host: the controller's output for one cycle.
    Actuator(ActuatorMsg),
    /// Host → board: a planner command, the kernel's postcard encoding of `Command<f32>`.
    Command(heapless::Vec<u8, MAX_MESSAGE_BYTES>),
    /// Board → host: the kernel's postcard encoding of a `TelemetryMessage<f32>`.
    Telemetry(heapless::Vec<u8, MAX_MESSAGE_BYTES>),
    /// Board → host: the runtime's counters.
    Stats(RuntimeStats),
    /// Host → board: one piece of the scenario's configuration ([`crate::setup`]).
    Setup(SetupChunk),
    /// Board → host: the answer to a setup.
    SetupReply(SetupReply),
}

/// One control cycle's sensor values: the joints of the upper body and the platform.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SensorMsg {
    /// Sensor cycle counter (the same for joints and platform).
    pub cycle: u64,
    /// Joint positions (rad, m).
    pub position: Joints,
    /// Joint velocities.
    pub velocity: Joints,
    /// Measured joint torques (Nm, N).
    pub torque: Joints,
    /// Platform pose `(x, y, θ)` in the world frame.
    pub pose: [f32; 3],
    /// Platform velocity in the world frame.
    pub base_velocity: [f32; 3],
    /// Leg lengths (m).
    pub leg_lengths: [f32; LEGS],
}

/// Which output the controller produced (the kernel's `SafeOutput`).
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum OutputMode {
    /// The controlled torque.
    Normal,
    /// The safe hold output after a fault.
    Hold,
    /// Hold with the brake requested.
    Brake,
}

/// A fault the board found on the link itself (before the controller saw the frame).
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum LinkFault {
    /// Bad COBS, CRC or payload encoding.
    Corrupted,
    /// Shorter than a CRC.
    Truncated,
    /// Longer than the receive buffer.
    Oversized,
    /// A sequence number already seen.
    Replayed,
    /// No sensor frame within the watchdog time, or a gap in the sequence numbers.
    Missing,
    /// A sensor frame before a valid setup: there is no controller to step.
    Unconfigured,
}

/// The controller's output for one cycle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ActuatorMsg {
    /// Cycle counter of the sensor frame this answers (the last valid one on a link fault).
    pub cycle: u64,
    /// Joint torques (Nm, N).
    pub torque: Joints,
    /// Platform velocity command.
    pub base_velocity: [f32; 3],
    /// Leg length rates (m/s).
    pub leg_rates: [f32; LEGS],
    /// Brake request.
    pub brake: bool,
    /// Which output this is.
    pub mode: OutputMode,
    /// The kernel's fault code of this cycle (`messages::fault_code`), 0 for none.
    pub fault_code: u8,
    /// The link fault that made this a safe output, if any.
    pub link_fault: Option<LinkFault>,
}

/// The board runtime's counters, sent once per second of control cycles.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RuntimeStats {
    /// Control cycles run.
    pub cycles: u64,
    /// Cycles that ended after their period (the timer had ticked again).
    pub deadline_misses: u32,
    /// The most expensive cycle's cost in timer counts (core clock cycles on SysTick).
    pub worst_cycle_cost: u32,
    /// Link faults seen.
    pub link_faults: u32,
}

impl SensorMsg {
    /// The message of a joint and a platform sample (the joint cycle counter is sent).
    /// `None` with more than [`MAX_JOINTS`] joints.
    pub fn from_samples<const U: usize>(joints: &JointSample<f32, U>, platform: &PlatformSample<f32>) -> Option<Self> {
        Some(Self {
            cycle: joints.cycle,
            position: Joints::from_slice(&joints.position).ok()?,
            velocity: Joints::from_slice(&joints.velocity).ok()?,
            torque: Joints::from_slice(&joints.torque).ok()?,
            pose: platform.pose,
            base_velocity: platform.velocity,
            leg_lengths: platform.leg_lengths,
        })
    }

    /// The joint and platform samples; `None` unless every joint vector has `U` entries.
    pub fn to_samples<const U: usize>(&self) -> Option<(JointSample<f32, U>, PlatformSample<f32>)> {
        let joints = JointSample {
            position: self.position.as_slice().try_into().ok()?,
            velocity: self.velocity.as_slice().try_into().ok()?,
            torque: self.torque.as_slice().try_into().ok()?,
            cycle: self.cycle,
        };
        let platform = PlatformSample {
            pose: self.pose,
            velocity: self.base_velocity,
            leg_lengths: self.leg_lengths,
            cycle: self.cycle,
        };
        Some((joints, platform))
    }
}

impl ActuatorMsg {
    /// The platform command of this message.
    pub fn platform_command(&self) -> PlatformCommand<f32> {
        PlatformCommand { velocity: self.base_velocity, leg_rates: self.leg_rates }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;

    #[test]
    fn samples_survive_the_message_and_a_wrong_joint_count_is_refused() {
        let joints = JointSample { position: [0.5_f32, -1.0], velocity: [0.25, 2.0], torque: [3.0, -4.0], cycle: 9 };
        let platform =
            PlatformSample { pose: [1.0, 2.0, 0.5], velocity: [0.1, 0.0, -0.2], leg_lengths: [0.4; LEGS], cycle: 9 };
        let msg = SensorMsg::from_samples(&joints, &platform).unwrap();
        assert_eq!(msg.to_samples::<2>(), Some((joints, platform)));
        assert_eq!(msg.to_samples::<3>(), None);
        assert!(SensorMsg::from_samples(
            &JointSample { position: [0.0; 33], velocity: [0.0; 33], torque: [0.0; 33], cycle: 0 },
            &platform
        )
        .is_none());
    }
}
