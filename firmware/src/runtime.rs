//! The board runtime: sensor frames from the link in, `Controller::step`, actuator frames out.
//!
//! Board-independent: [`Runtime::period`] is called once per control period (1 kHz tick) with
//! the link's port. It takes frames until the period's sensor frame: a sensor frame is stepped
//! and answered with an actuator frame; a planner command is applied. A frame the link refuses (corrupted,
//! truncated, oversized, replayed, wrong joint count), or no sensor frame for `watchdog_ticks`
//! periods, is a [`LinkFault`]: the controller is stepped with the last valid sensor frame
//! again, which it refuses as `StaleFrame` and answers with its safe output (Hold, then Brake),
//! and the actuator frame names the link fault. Before the first valid frame there is nothing to
//! hold and nothing is sent. Every [`STATS_PERIODS`] periods the runtime sends its
//! [`RuntimeStats`] and the kernel's telemetry message.

use fixtures::justin::{self, whole_body};
use kernel::controller::faults::SafeOutput;
use kernel::controller::messages::{fault_code, TelemetryMessage};
use kernel::controller::SensorFrame;
use link::{
    write_frame, ActuatorMsg, Frame, FrameReader, Joints, LinkError, LinkFault, OutputMode, Payload, Received,
    RuntimeStats, MAX_MESSAGE_BYTES,
};

/// The controller the images run: Justin's whole-body controller in `f32`.
pub type Controller = whole_body::JustinController<f32>;
/// Upper-body joints in a sensor frame.
const U: usize = justin::UPPER_DOF;
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
    reader: FrameReader,
    last_valid: Option<SensorFrame<f32, U>>,
    tx_seq: u32,
    periods_without_frame: u32,
    watchdog_periods: u32,
    periods_to_stats: u32,
    mode: OutputMode,
    stats: RuntimeStats,
}

impl Runtime {
    /// A runtime that declares the sensor stream missing after `watchdog_periods` periods
    /// without a sensor frame.
    pub const fn new(watchdog_periods: u32) -> Self {
        Self {
            reader: FrameReader::new(),
            last_valid: None,
            tx_seq: 0,
            periods_without_frame: 0,
            watchdog_periods,
            periods_to_stats: STATS_PERIODS,
            mode: OutputMode::Normal,
            stats: RuntimeStats { cycles: 0, deadline_misses: 0, worst_cycle_cost: 0, link_faults: 0 },
        }
    }

    /// One control period: takes frames from `port` until a sensor frame has been stepped or
    /// `period_over()` (a UART without DMA delivers the frame byte by byte during the period),
    /// then the watchdog and the statistics. `missed` periods went by unhandled since the last
    /// call (a deadline miss each).
    pub fn period<P, O>(
        &mut self,
        port: &mut P,
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
            match self.reader.poll(port) {
                None => {}
                Some(Ok(received)) => self.on_frame(port, controller, received, &mut report),
                Some(Err(LinkError::Io(_) | LinkError::Closed)) => break,
                Some(Err(e)) => self.on_link_fault(port, controller, link_fault(&e), &mut report),
            }
        }
        if report.steps == 0 && self.last_valid.is_some() {
            self.periods_without_frame = self.periods_without_frame.saturating_add(1 + missed);
            if self.periods_without_frame >= self.watchdog_periods {
                self.on_link_fault(port, controller, LinkFault::Missing, &mut report);
            }
        }
        self.periods_to_stats = self.periods_to_stats.saturating_sub(1 + missed);
        if self.periods_to_stats == 0 {
            self.periods_to_stats = STATS_PERIODS;
            self.send(port, Payload::Stats(self.stats));
            let mut bytes = [0u8; MAX_MESSAGE_BYTES];
            let message = TelemetryMessage::from_telemetry(controller.telemetry(), controller.output().mode);
            if let Ok(encoded) = message.encode(&mut bytes) {
                if let Ok(telemetry) = heapless::Vec::from_slice(encoded) {
                    self.send(port, Payload::Telemetry(telemetry));
                }
            }
            report.stats = Some(self.stats);
        }
        report
    }

    /// Records the cost of the period just run (core clock cycles).
    pub fn record_cost(&mut self, cost: u32) {
        self.stats.worst_cycle_cost = self.stats.worst_cycle_cost.max(cost);
    }

    fn on_frame<P: embedded_io::Write>(
        &mut self,
        port: &mut P,
        controller: &mut Controller,
        received: Received,
        report: &mut PeriodReport,
    ) {
        match received.frame.payload {
            Payload::Sensor(msg) => match msg.to_samples::<U>() {
                Some((joints, platform)) => {
                    let frame = SensorFrame { joints, platform };
                    self.last_valid = Some(frame);
                    self.periods_without_frame = 0;
                    let fault = (received.lost > 0).then_some(LinkFault::Missing);
                    if let Some(fault) = fault {
                        self.count_fault(fault, report);
                    }
                    self.step(port, controller, &frame, fault, report);
                }
                None => self.on_link_fault(port, controller, LinkFault::Corrupted, report),
            },
            Payload::Command(bytes) => {
                if controller.apply_bytes(&bytes).is_err() {
                    report.rejected_commands += 1;
                }
            }
            // Frames only the board sends: ignored.
            Payload::Actuator(_) | Payload::Telemetry(_) | Payload::Stats(_) => {}
        }
    }

    /// The safe output: the last valid frame again (the controller holds), if there was one.
    fn on_link_fault<P: embedded_io::Write>(
        &mut self,
        port: &mut P,
        controller: &mut Controller,
        fault: LinkFault,
        report: &mut PeriodReport,
    ) {
        self.count_fault(fault, report);
        if let Some(frame) = self.last_valid {
            self.step(port, controller, &frame, Some(fault), report);
        }
    }

    fn count_fault(&mut self, fault: LinkFault, report: &mut PeriodReport) {
        self.stats.link_faults = self.stats.link_faults.saturating_add(1);
        report.link_fault = Some(fault);
    }

    fn step<P: embedded_io::Write>(
        &mut self,
        port: &mut P,
        controller: &mut Controller,
        frame: &SensorFrame<f32, U>,
        link_fault: Option<LinkFault>,
        report: &mut PeriodReport,
    ) {
        let output = *controller.step(frame);
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
        let actuator = ActuatorMsg {
            cycle: frame.joints.cycle,
            torque: Joints::from_slice(&output.torque).unwrap_or_default(),
            base_velocity: output.platform.velocity,
            leg_rates: output.platform.leg_rates,
            brake: output.brake,
            mode,
            fault_code: report.fault_code,
            link_fault,
        };
        self.send(port, Payload::Actuator(actuator));
    }

    fn send<P: embedded_io::Write>(&mut self, port: &mut P, payload: Payload) {
        // A failing UART has no one to report to but the log (the caller sees the fault count).
        if write_frame(port, &Frame { seq: self.tx_seq, payload }).is_err() {
            self.stats.link_faults = self.stats.link_faults.saturating_add(1);
        }
        self.tx_seq = self.tx_seq.wrapping_add(1);
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
