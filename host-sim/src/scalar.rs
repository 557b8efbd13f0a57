//! The host controller's scalar (`--scalar f64|f32`): the whole-body controller in `f32` on the
//! host, as the boards run it, so `f32` regressions show without QEMU.
//!
//! The simulator stays in `f64` (the plant is physics); [`F32Controller`] sees it the way the
//! firmware does: the sensor frame narrowed to the link's `f32` message
//! ([`crate::pil::sensor_message`]) and read back as the board reads it, planner commands
//! narrowed like the ones [`crate::pil::Firmware::apply`] sends ([`narrow_command`]), the
//! actuator frame widened back to `f64` ([`widen_actuator_frame`], also the firmware's answer).
//! [`crate::wbc::rig`] builds it beside the rig's `f64` controller, which runs alongside on the
//! same frames for the telemetry columns and the torque comparison, as in a PIL run.

use fixtures::justin;
use hal::PlatformCommand;
use kernel::controller::config::TaskSpec;
use kernel::controller::messages::Command;
use kernel::controller::{ActuatorFrame, SensorFrame};
use kernel::tasks::collision::{Core, SweptSphere};

use crate::wbc::{whole_body_controller, ConfigChanges, PAIRS, VOLUMES};

/// Upper-body joints of a frame.
const U: usize = justin::UPPER_DOF;

/// The scalar the host runs the whole-body controller in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Scalar {
    /// Double precision, the reference (the thesis' figures and numbers).
    #[default]
    F64,
    /// Single precision, as on the Cortex-M boards.
    F32,
}

impl Scalar {
    /// The option's value on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::F64 => "f64",
            Self::F32 => "f32",
        }
    }
}

/// The whole-body controller of the rig in `f32`.
pub type RigControllerF32 = justin::whole_body::WholeBodyController<f32, VOLUMES, PAIRS>;

/// The rig's whole-body controller in `f32`, behind the frames a board exchanges.
pub struct F32Controller {
    /// Boxed: the controller takes ~70 KB.
    controller: Box<RigControllerF32>,
}

impl F32Controller {
    /// The controller of [`crate::wbc::rig`] in `f32`: the same environment volumes,
    /// configuration changes and hierarchy.
    pub fn new(
        environment: &[SweptSphere<f64>],
        changes: ConfigChanges,
        hierarchy: &[TaskSpec],
    ) -> Result<Self, String> {
        let environment: Vec<SweptSphere<f32>> = environment.iter().map(narrow_volume).collect();
        let controller = whole_body_controller::<f32>(&environment, changes, hierarchy)?;
        Ok(Self { controller: Box::new(controller) })
    }

    /// One control cycle on the `f64` frame, narrowed as the link narrows it; the output in `f64`.
    pub fn step(&mut self, frame: &SensorFrame<f64, U>) -> Result<ActuatorFrame<f64, U>, String> {
        let message = crate::pil::sensor_message(frame)?;
        let (joints, platform) = message.to_samples::<U>().ok_or("sensor message: wrong joint count")?;
        Ok(widen_actuator_frame(self.controller.step(&SensorFrame { joints, platform })))
    }

    /// Applies a planner command, narrowed to `f32`.
    pub fn apply(&mut self, command: &Command<f64>) -> Result<(), String> {
        self.controller.apply(&narrow_command(command)?).map_err(|e| e.to_string())
    }
}

/// A planner command in `f32`, as the planner sends it to a board: every number rounded to the
/// nearest `f32`, infinite force limits kept (through CBOR, which stores floats as they are;
/// JSON has no infinity). The command's own validation runs when it is applied.
pub fn narrow_command(command: &Command<f64>) -> Result<Command<f32>, String> {
    let mut bytes = Vec::new();
    ciborium::into_writer(command, &mut bytes).map_err(|e| format!("command: {e}"))?;
    ciborium::from_reader(bytes.as_slice()).map_err(|e| format!("command in f32: {e}"))
}

/// An actuator frame in `f64` (exact: every `f32` is an `f64`).
pub fn widen_actuator_frame(frame: &ActuatorFrame<f32, U>) -> ActuatorFrame<f64, U> {
    ActuatorFrame {
        torque: frame.torque.map(f64::from),
        platform: PlatformCommand {
            velocity: frame.platform.velocity.map(f64::from),
            leg_rates: frame.platform.leg_rates.map(f64::from),
        },
        brake: frame.brake,
        mode: frame.mode,
    }
}

/// An environment volume in `f32`.
fn narrow_volume(volume: &SweptSphere<f64>) -> SweptSphere<f32> {
    let core = match &volume.core {
        Core::Point(p) => Core::Point(p.cast()),
        Core::Segment(s) => Core::Segment(s.each_ref().map(|p| p.cast())),
        Core::Triangle(t) => Core::Triangle(t.each_ref().map(|p| p.cast())),
    };
    SweptSphere { core, radius: volume.radius as f32 }
}

#[cfg(test)]
#[allow(clippy::indexing_slicing, reason = "test")]
mod tests {
    use kernel::controller::config::{ArmId, CartesianParameters};
    use kernel::controller::messages::Command;

    use super::narrow_command;

    #[test]
    fn commands_narrow_to_the_nearest_f32_and_keep_infinite_force_limits() {
        let (inf, narrow) = (f64::INFINITY, |v: [f64; 6]| v.map(|x| x as f32));
        let parameters = CartesianParameters {
            translational_stiffness: [500.0, 0.1, 800.0],
            rotational_stiffness: [100.0; 3],
            damping_ratio: 0.7,
            force_lower: [-inf, -20.0, -20.0, -inf, -inf, -inf],
            force_upper: [10.0, inf, 20.0, inf, inf, inf],
        };
        let expected = CartesianParameters {
            translational_stiffness: [500.0, 0.1_f32, 800.0],
            rotational_stiffness: [100.0; 3],
            damping_ratio: 0.7_f32,
            force_lower: narrow(parameters.force_lower),
            force_upper: narrow(parameters.force_upper),
        };
        assert_eq!((expected.force_lower[0], expected.force_upper[1]), (f32::NEG_INFINITY, f32::INFINITY));
        assert_eq!(
            narrow_command(&Command::SetCartesian { hand: ArmId::LEFT, parameters }),
            Ok(Command::SetCartesian { hand: ArmId::LEFT, parameters: expected })
        );
    }
}
