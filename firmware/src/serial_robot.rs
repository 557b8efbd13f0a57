//! The robot as the board sees it over the serial link: the `hal` joint-torque and
//! platform-velocity interfaces implemented on the `link` frames.
//!
//! [`SerialRobot::receive`] takes the bytes the port has ready and reports what a complete frame
//! was: a sensor frame (it becomes the sample both `read`s return), a planner command, a piece of
//! the setup message, or a link fault. `write_torque` and `write_velocity` stage the cycle's output, which
//! [`SerialRobot::send_actuator`] sends as one actuator frame together with what the traits
//! cannot carry (output mode, brake, fault codes): a partial update of some joints never goes
//! out. The watchdog is the robot's own, as the `hal` contract asks: `read` returns
//! [`ErrorKind::Stale`] once no sensor frame came for `watchdog_periods` control periods
//! ([`SerialRobot::periods_elapsed`]), [`ErrorKind::NotReady`] before the first one.

use hal::PlatformVelocityInterface;
use hal::{ErrorKind, ErrorType, JointSample, JointTorqueInterface, PlatformCommand, PlatformSample, LEGS};
use link::{
    write_frame, ActuatorMsg, Frame, FrameReader, Joints, LinkError, LinkFault, OutputMode, Payload, SetupChunk,
    MAX_MESSAGE_BYTES,
};

/// What one call of [`SerialRobot::receive`] found.
// The payloads are bounded buffers held by value: there is no heap to box them into.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum Received {
    /// No complete frame yet.
    Nothing,
    /// A new sensor sample; `lost` frames were skipped before it.
    Sensor {
        /// Frames the host sent before this one that never arrived.
        lost: u32,
    },
    /// A planner command (the kernel's postcard encoding).
    Command(heapless::Vec<u8, MAX_MESSAGE_BYTES>),
    /// A piece of the setup message (`link::setup`).
    Setup(SetupChunk),
    /// A frame the link refused.
    Fault(LinkFault),
    /// The port failed or closed: nothing more this period.
    Closed,
}

/// What the actuator frame carries besides the staged torque and platform command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OutputStatus {
    /// Cycle counter of the sensor frame the output answers.
    pub cycle: u64,
    /// Which output the controller produced.
    pub mode: OutputMode,
    /// The controller's brake request.
    pub brake: bool,
    /// The kernel's fault code (`messages::fault_code`).
    pub fault_code: u8,
    /// The link fault that made this a safe output, if any.
    pub link_fault: Option<LinkFault>,
}

/// The upper body and the platform behind a serial port, `U` joints.
pub struct SerialRobot<P, const U: usize> {
    port: P,
    reader: FrameReader,
    tx_seq: u32,
    sample: Option<(JointSample<f32, U>, PlatformSample<f32>)>,
    periods_without_frame: u32,
    watchdog_periods: u32,
    torque: [f32; U],
    platform: PlatformCommand<f32>,
    brake: bool,
    send_failures: u32,
}

impl<P, const U: usize> SerialRobot<P, U>
where
    P: embedded_io::Read + embedded_io::ReadReady + embedded_io::Write,
{
    /// The robot behind `port`; its sample is stale after `watchdog_periods` periods without a
    /// sensor frame.
    pub const fn new(port: P, watchdog_periods: u32) -> Self {
        Self {
            port,
            reader: FrameReader::new(),
            tx_seq: 0,
            sample: None,
            periods_without_frame: 0,
            watchdog_periods,
            torque: [0.0; U],
            platform: PlatformCommand { velocity: [0.0; 3], leg_rates: [0.0; LEGS] },
            brake: false,
            send_failures: 0,
        }
    }

    /// Takes the bytes the port has ready, up to the end of one frame.
    pub fn receive(&mut self) -> Received {
        match self.reader.poll(&mut self.port) {
            None => Received::Nothing,
            Some(Ok(received)) => match received.frame.payload {
                Payload::Sensor(msg) => match msg.to_samples::<U>() {
                    Some(sample) => {
                        self.sample = Some(sample);
                        self.periods_without_frame = 0;
                        Received::Sensor { lost: received.lost }
                    }
                    None => Received::Fault(LinkFault::Corrupted),
                },
                Payload::Command(bytes) => Received::Command(bytes),
                Payload::Setup(chunk) => Received::Setup(chunk),
                // Frames only the board sends.
                Payload::Actuator(_) | Payload::Telemetry(_) | Payload::Stats(_) | Payload::SetupReply(_) => {
                    Received::Nothing
                }
            },
            Some(Err(LinkError::Io(_) | LinkError::Closed)) => Received::Closed,
            Some(Err(e)) => Received::Fault(link_fault(&e)),
        }
    }

    /// Counts `periods` control periods without a sensor frame (the watchdog).
    pub fn periods_elapsed(&mut self, periods: u32) {
        self.periods_without_frame = self.periods_without_frame.saturating_add(periods);
    }

    /// Sends the staged torque and platform command with `status` as one actuator frame; the
    /// brake is requested if the controller or a refused write asked for it.
    pub fn send_actuator(&mut self, status: OutputStatus) {
        let actuator = ActuatorMsg {
            cycle: status.cycle,
            torque: Joints::from_slice(&self.torque).unwrap_or_default(),
            base_velocity: self.platform.velocity,
            leg_rates: self.platform.leg_rates,
            brake: status.brake || core::mem::take(&mut self.brake),
            mode: status.mode,
            fault_code: status.fault_code,
            link_fault: status.link_fault,
        };
        self.send(Payload::Actuator(actuator));
    }

    /// Sends `payload` as the next frame (a failing port is counted: [`Self::send_failures`]).
    pub fn send(&mut self, payload: Payload) {
        if write_frame(&mut self.port, &Frame { seq: self.tx_seq, payload }).is_err() {
            self.send_failures = self.send_failures.saturating_add(1);
        }
        self.tx_seq = self.tx_seq.wrapping_add(1);
    }

    /// Frames the port failed to send.
    pub fn send_failures(&self) -> u32 {
        self.send_failures
    }

    /// The newest sample, unless the watchdog has run out.
    fn fresh_sample(&self) -> Result<(JointSample<f32, U>, PlatformSample<f32>), ErrorKind> {
        let sample = self.sample.ok_or(ErrorKind::NotReady)?;
        if self.periods_without_frame >= self.watchdog_periods {
            return Err(ErrorKind::Stale);
        }
        Ok(sample)
    }

    /// Refuses a non-finite command: zero torque and velocity are staged and the brake requested
    /// (the documented safe reaction).
    fn refuse_command(&mut self) -> Result<(), ErrorKind> {
        self.torque = [0.0; U];
        self.platform = PlatformCommand { velocity: [0.0; 3], leg_rates: [0.0; LEGS] };
        self.brake = true;
        Err(ErrorKind::OutOfRange)
    }
}

impl<P, const U: usize> ErrorType for SerialRobot<P, U> {
    type Error = ErrorKind;
}

impl<P, const U: usize> JointTorqueInterface<f32, U> for SerialRobot<P, U>
where
    P: embedded_io::Read + embedded_io::ReadReady + embedded_io::Write,
{
    fn read(&mut self) -> Result<JointSample<f32, U>, ErrorKind> {
        self.fresh_sample().map(|(joints, _)| joints)
    }

    fn write_torque(&mut self, torque: &[f32; U]) -> Result<(), ErrorKind> {
        if !torque.iter().all(|t| t.is_finite()) {
            return self.refuse_command();
        }
        self.torque = *torque;
        Ok(())
    }
}

impl<P, const U: usize> PlatformVelocityInterface<f32> for SerialRobot<P, U>
where
    P: embedded_io::Read + embedded_io::ReadReady + embedded_io::Write,
{
    fn read(&mut self) -> Result<PlatformSample<f32>, ErrorKind> {
        self.fresh_sample().map(|(_, platform)| platform)
    }

    fn write_velocity(&mut self, command: &PlatformCommand<f32>) -> Result<(), ErrorKind> {
        if !command.velocity.iter().chain(&command.leg_rates).all(|v| v.is_finite()) {
            return self.refuse_command();
        }
        self.platform = *command;
        Ok(())
    }
}

/// The fault a refused frame counts as.
fn link_fault<E>(error: &LinkError<E>) -> LinkFault {
    match error {
        LinkError::Truncated => LinkFault::Truncated,
        LinkError::Oversized => LinkFault::Oversized,
        LinkError::Replayed { .. } => LinkFault::Replayed,
        LinkError::Corrupted | LinkError::Closed | LinkError::Io(_) => LinkFault::Corrupted,
    }
}
