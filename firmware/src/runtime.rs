//! The board runtime: sensor frames from the robot in, `Controller::step`, actuator frames out.
//!
//! Board-independent: [`Runtime::period`] is called once per control period (1 kHz tick) with
//! the robot behind its serial link ([`SerialRobot`], the `hal` joint-torque and
//! platform-velocity interfaces). It takes frames until the period's sensor frame: the sample is
//! read through the `hal` traits and stepped, the output written through them and sent as the
//! actuator frame; a planner command is applied. A frame the link refuses (corrupted,
//! truncated, oversized, replayed, wrong joint count), or a sample the robot reports stale (no
//! sensor frame for its watchdog time), is a [`LinkFault`]: the controller is stepped with the
//! last valid sensor frame again, which it refuses as `StaleFrame` and answers with its safe
//! output (Hold, then Brake), and the actuator frame names the link fault. Before the first
//! valid frame there is nothing to hold and nothing is sent. Every [`STATS_PERIODS`] periods the
//! runtime sends its [`RuntimeStats`] and the kernel's telemetry message.

use fixtures::justin::{self, whole_body};
use hal::{ErrorKind, JointTorqueInterface, PlatformVelocityInterface};
use kernel::controller::faults::SafeOutput;
use kernel::controller::messages::{fault_code, TelemetryMessage};
use kernel::controller::SensorFrame;
use link::{LinkFault, OutputMode, Payload, RuntimeStats, MAX_MESSAGE_BYTES};

use crate::probe;
use crate::serial_robot::{OutputStatus, Received, SerialRobot};

/// The controller the images run: Justin's whole-body controller in `f32`.
pub type Controller = whole_body::JustinController<f32>;
/// Upper-body joints in a sensor frame.
pub const U: usize = justin::UPPER_DOF;
/// Justin behind the board's serial link.
pub type Robot<P> = SerialRobot<P, U>;
/// Periods between two statistics frames (1 s at 1 kHz).
pub const STATS_PERIODS: u32 = 1_000;

/// What happened in one period, for logging.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PeriodReport {
    /// Controller steps run.
    pub steps: u32,
    /// The last link fault of the period.
    pub link_fault: Option<LinkFault>,
    /// The output mode changed to this one.
    pub mode_change: Option<OutputMode>,
    /// The kernel's fault code of the period's last step (`messages::fault_code`, 0 for none).
    pub fault_code: u8,
    /// Statistics were sent.
    pub stats: Option<RuntimeStats>,
    /// Planner commands the controller rejected.
    pub rejected_commands: u32,
}

/// The runtime's state between periods.
pub struct Runtime {
    last_valid: Option<SensorFrame<f32, U>>,
    periods_to_stats: u32,
    mode: OutputMode,
    stats: RuntimeStats,
}

impl Default for Runtime {
    fn default() -> Self {
        Self::new()
    }
}

impl Runtime {
    /// A runtime before its first period.
    pub const fn new() -> Self {
        Self {
            last_valid: None,
            periods_to_stats: STATS_PERIODS,
            mode: OutputMode::Normal,
            stats: RuntimeStats { cycles: 0, deadline_misses: 0, worst_cycle_cost: 0, link_faults: 0 },
        }
    }

    /// One control period: takes frames from `robot` until a sensor frame has been stepped or
    /// `period_over()` (a UART without DMA delivers the frame byte by byte during the period),
    /// then the watchdog and the statistics. `missed` periods went by unhandled since the last
    /// call (a deadline miss each).
    pub fn period<P, O>(
        &mut self,
        robot: &mut Robot<P>,
        controller: &mut Controller,
        missed: u32,
        period_over: O,
    ) -> PeriodReport
    where
        P: embedded_io::Read + embedded_io::ReadReady + embedded_io::Write,
        O: Fn() -> bool,
    {
        let mut report = PeriodReport::default();
        self.stats.deadline_misses = self.stats.deadline_misses.saturating_add(missed);
        while report.steps == 0 && !period_over() {
            match robot.receive() {
                Received::Nothing => {}
                Received::Closed => break,
                Received::Sensor { lost } => {
                    let fault = (lost > 0).then_some(LinkFault::Missing);
                    if let Some(fault) = fault {
                        self.count_fault(fault, &mut report);
                    }
                    self.step_sample(robot, controller, fault, &mut report);
                }
                Received::Command(bytes) => {
                    if controller.apply_bytes(&bytes).is_err() {
                        report.rejected_commands += 1;
                    }
                }
                Received::Fault(fault) => self.on_link_fault(robot, controller, fault, &mut report),
            }
        }
        if report.steps == 0 {
            robot.periods_elapsed(1 + missed);
            if JointTorqueInterface::read(robot) == Err(ErrorKind::Stale) {
                self.on_link_fault(robot, controller, LinkFault::Missing, &mut report);
            }
        }
        self.periods_to_stats = self.periods_to_stats.saturating_sub(1 + missed);
        if self.periods_to_stats == 0 {
            self.periods_to_stats = STATS_PERIODS;
            report.stats = Some(self.send_stats(robot, controller));
        }
        report
    }

    /// Records the cost of the period just run (core clock cycles).
    pub fn record_cost(&mut self, cost: u32) {
        self.stats.worst_cycle_cost = self.stats.worst_cycle_cost.max(cost);
    }

    /// Steps the sample the robot just received, read through the `hal` traits.
    fn step_sample<P>(
        &mut self,
        robot: &mut Robot<P>,
        controller: &mut Controller,
        fault: Option<LinkFault>,
        report: &mut PeriodReport,
    ) where
        P: embedded_io::Read + embedded_io::ReadReady + embedded_io::Write,
    {
        let joints = JointTorqueInterface::read(robot);
        let platform = PlatformVelocityInterface::read(robot);
        if let (Ok(joints), Ok(platform)) = (joints, platform) {
            let frame = SensorFrame { joints, platform };
            self.last_valid = Some(frame);
            self.step(robot, controller, &frame, fault, report);
        }
    }

    /// The safe output: the last valid frame again (the controller holds), if there was one.
    fn on_link_fault<P>(
        &mut self,
        robot: &mut Robot<P>,
        controller: &mut Controller,
        fault: LinkFault,
        report: &mut PeriodReport,
    ) where
        P: embedded_io::Read + embedded_io::ReadReady + embedded_io::Write,
    {
        self.count_fault(fault, report);
        if let Some(frame) = self.last_valid {
            self.step(robot, controller, &frame, Some(fault), report);
        }
    }

    fn count_fault(&mut self, fault: LinkFault, report: &mut PeriodReport) {
        self.stats.link_faults = self.stats.link_faults.saturating_add(1);
        report.link_fault = Some(fault);
    }

    fn step<P>(
        &mut self,
        robot: &mut Robot<P>,
        controller: &mut Controller,
        frame: &SensorFrame<f32, U>,
        link_fault: Option<LinkFault>,
        report: &mut PeriodReport,
    ) where
        P: embedded_io::Read + embedded_io::ReadReady + embedded_io::Write,
    {
        // Region 0 of the counting plugin (`wcet/wcet_insn.c`): a NOP pair on the board.
        probe::mark_begin::<0>();
        let output = *controller.step(frame);
        probe::mark_end::<0>();
        self.stats.cycles += 1;
        report.steps += 1;
        let mode = match output.mode {
            SafeOutput::Normal => OutputMode::Normal,
            SafeOutput::Hold => OutputMode::Hold,
            SafeOutput::Brake => OutputMode::Brake,
        };
        if mode != self.mode {
            self.mode = mode;
            report.mode_change = Some(mode);
        }
        report.fault_code = fault_code(controller.telemetry().fault);
        // A refused (non-finite) write stages the robot's safe reaction, sent with the frame.
        let _ = robot.write_torque(&output.torque);
        let _ = robot.write_velocity(&output.platform);
        robot.send_actuator(OutputStatus {
            cycle: frame.joints.cycle,
            mode,
            brake: output.brake,
            fault_code: report.fault_code,
            link_fault,
        });
    }

    /// Sends the statistics (link faults include frames the port failed to send) and the
    /// kernel's telemetry message; returns the statistics.
    fn send_stats<P>(&mut self, robot: &mut Robot<P>, controller: &Controller) -> RuntimeStats
    where
        P: embedded_io::Read + embedded_io::ReadReady + embedded_io::Write,
    {
        let stats =
            RuntimeStats { link_faults: self.stats.link_faults.saturating_add(robot.send_failures()), ..self.stats };
        robot.send(Payload::Stats(stats));
        let mut bytes = [0u8; MAX_MESSAGE_BYTES];
        let message = TelemetryMessage::from_telemetry(controller.telemetry(), controller.output().mode);
        if let Ok(encoded) = message.encode(&mut bytes) {
            if let Ok(telemetry) = heapless::Vec::from_slice(encoded) {
                robot.send(Payload::Telemetry(telemetry));
            }
        }
        stats
    }
}
