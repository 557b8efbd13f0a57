//! The board runtime: the scenario's setup, then sensor frames from the robot in,
//! `Controller::step`, actuator frames out.
//!
//! Board-independent: [`Runtime::period`] is called once per control period (1 kHz tick) with
//! the robot behind its serial link ([`SerialRobot`], the `hal` joint-torque and
//! platform-velocity interfaces) and the [`ControllerSlot`]. The board starts without a
//! controller: the host first sends the setup message (`link::setup`: the rig's environment
//! volumes, free platform axes and hierarchy, in CRC-checked chunks). The runtime assembles it,
//! builds the controller through the kernel's validating constructor and answers with the
//! `SetupReply` (accepted with the configuration's checksum, or the typed `SetupFault`); a new
//! setup replaces the controller. Until a setup is accepted, a sensor frame is answered with
//! the safe output of a board without a controller (zero torque, brake) naming
//! [`LinkFault::Unconfigured`].
//!
//! Then each period it takes frames until the period's sensor frame: the sample is read through
//! the `hal` traits and stepped, the output written through them and sent as the actuator
//! frame; a planner command is applied. A frame the link refuses (corrupted, truncated,
//! oversized, replayed, wrong joint count), or a sample the robot reports stale (no sensor frame
//! for its watchdog time), is a [`LinkFault`]: the controller is stepped with the last valid
//! sensor frame again, which it refuses as `StaleFrame` and answers with its safe output (Hold,
//! then Brake), and the actuator frame names the link fault. Before the first valid frame there
//! is nothing to hold and nothing is sent. Every [`STATS_PERIODS`] periods the runtime sends its
//! [`RuntimeStats`] and the kernel's telemetry message.

use core::mem::MaybeUninit;

use fixtures::justin::{self, collision, whole_body, JustinModel};
use hal::{ErrorKind, JointTorqueInterface, PlatformCommand, PlatformVelocityInterface, LEGS};
use kernel::controller::faults::SafeOutput;
use kernel::controller::messages::{fault_code, TelemetryMessage};
use kernel::controller::SensorFrame;
use kernel::tasks::collision::SweptSphere;
use link::setup::{self, SetupAssembler, SetupChunk, SetupFault, SetupReply, MAX_ENVIRONMENT_VOLUMES};
use link::{LinkFault, OutputMode, Payload, RuntimeStats, MAX_MESSAGE_BYTES};

use crate::probe;
use crate::serial_robot::{OutputStatus, Received, SerialRobot};

/// Collision volumes: the robot's plus up to [`MAX_ENVIRONMENT_VOLUMES`] of the environment.
pub const VOLUMES: usize = collision::VOLUMES + MAX_ENVIRONMENT_VOLUMES;
/// Pair capacity: the robot's pairs plus 27 per environment volume (as `host-sim`'s rig).
pub const PAIRS: usize = collision::PAIRS + 27 * MAX_ENVIRONMENT_VOLUMES;
/// The controller the images run: Justin's whole-body controller in `f32`, with room for the
/// rig's environment volumes.
pub type Controller = whole_body::WholeBodyController<f32, VOLUMES, PAIRS>;
/// Upper-body joints in a sensor frame.
pub const U: usize = justin::UPPER_DOF;
/// Justin behind the board's serial link.
pub type Robot<P> = SerialRobot<P, U>;
/// Periods between two statistics frames (1 s at 1 kHz).
pub const STATS_PERIODS: u32 = 1_000;

/// The controller's storage (~90 KB in `f32`: a `static` in `.bss`, not on the stack), empty
/// until a setup is accepted.
pub struct ControllerSlot {
    controller: MaybeUninit<Controller>,
    configured: bool,
}

impl Default for ControllerSlot {
    fn default() -> Self {
        Self::new()
    }
}

impl ControllerSlot {
    /// An empty slot.
    pub const fn new() -> Self {
        Self { controller: MaybeUninit::uninit(), configured: false }
    }

    /// The controller, once a setup has been accepted.
    pub fn controller(&mut self) -> Option<&mut Controller> {
        // SAFETY: `configured` is set only after `controller` was written.
        self.configured.then(|| unsafe { self.controller.assume_init_mut() })
    }

    /// Empties the slot.
    pub fn clear(&mut self) {
        self.configured = false;
    }

    /// Builds the controller of the setup `encoded` for `model` in place (not inlined, so that
    /// its by-value temporaries leave the stack); the reply to send.
    #[inline(never)]
    pub fn configure(&mut self, model: &JustinModel<f32>, encoded: &[u8]) -> SetupReply {
        self.configured = false;
        match new_controller(model, encoded) {
            Ok(controller) => {
                self.controller.write(controller);
                self.configured = true;
                SetupReply::Accepted { checksum: setup::checksum(encoded) }
            }
            Err(fault) => SetupReply::Refused(fault),
        }
    }
}

/// The controller of a setup: Justin's `model` (built once at boot: the same for every setup),
/// its collision model with the setup's environment volumes, `controller_config` with its free
/// platform axes, its hierarchy; every part checked by the kernel's constructors. Inlined into
/// [`ControllerSlot::configure`], so that the controller is built in place there.
#[inline(always)]
fn new_controller(model: &JustinModel<f32>, encoded: &[u8]) -> Result<Controller, SetupFault> {
    let setup = setup::decode(encoded)?;
    let mut environment = heapless::Vec::<SweptSphere<f32>, MAX_ENVIRONMENT_VOLUMES>::new();
    for volume in &setup.environment {
        environment.push(volume.swept_sphere()).map_err(|_| SetupFault::InvalidEnvironment)?;
    }
    let collision = collision::collision_model_with_environment::<f32, VOLUMES, PAIRS>(model, &environment)
        .map_err(|_| SetupFault::InvalidEnvironment)?;
    let mut config = whole_body::controller_config::<f32>().map_err(|_| SetupFault::InvalidConfiguration)?;
    config.platform.admittance.free_axes = setup.free_base_axes;
    Controller::try_new(model.clone(), collision, config, &setup.hierarchy)
        .map_err(|_| SetupFault::InvalidConfiguration)
}

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
    /// Planner commands the controller rejected (or that came before a setup).
    pub rejected_commands: u32,
    /// The reply to a setup that ended this period.
    pub setup: Option<SetupReply>,
}

/// The runtime's state between periods.
pub struct Runtime {
    last_valid: Option<SensorFrame<f32, U>>,
    periods_to_stats: u32,
    mode: OutputMode,
    stats: RuntimeStats,
    setup: SetupAssembler,
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
            setup: SetupAssembler::new(),
        }
    }

    /// One control period: takes frames from `robot` until a sensor frame has been stepped or
    /// `period_over()` (a UART without DMA delivers the frame byte by byte during the period),
    /// then the watchdog and the statistics. `missed` periods went by unhandled since the last
    /// call (a deadline miss each).
    pub fn period<P, O>(
        &mut self,
        robot: &mut Robot<P>,
        slot: &mut ControllerSlot,
        model: &JustinModel<f32>,
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
            let received = robot.receive();
            let link_fault = match received {
                Received::Nothing | Received::Closed | Received::Setup(_) => None,
                Received::Sensor { .. } | Received::Command(_) => Some(None),
                Received::Fault(fault) => Some(Some(fault)),
            };
            if let Some(fault) = link_fault.and_then(|fault| self.setup.interrupt(fault)) {
                self.reply_to_setup(robot, SetupReply::Refused(fault), &mut report);
            }
            match received {
                Received::Nothing => {}
                Received::Closed => break,
                Received::Setup(chunk) => self.on_setup_chunk(robot, slot, model, &chunk, &mut report),
                Received::Sensor { lost } => {
                    let fault = (lost > 0).then_some(LinkFault::Missing);
                    if let Some(fault) = fault {
                        self.count_fault(fault, &mut report);
                    }
                    match slot.controller() {
                        Some(controller) => self.step_sample(robot, controller, fault, &mut report),
                        None => self.refuse_unconfigured(robot, &mut report),
                    }
                }
                Received::Command(bytes) => {
                    if slot.controller().is_none_or(|controller| controller.apply_bytes(&bytes).is_err()) {
                        report.rejected_commands += 1;
                    }
                }
                Received::Fault(fault) => self.on_link_fault(robot, slot, fault, &mut report),
            }
        }
        if report.steps == 0 {
            robot.periods_elapsed(1 + missed);
            if slot.controller().is_some() && JointTorqueInterface::read(robot) == Err(ErrorKind::Stale) {
                self.on_link_fault(robot, slot, LinkFault::Missing, &mut report);
            }
        }
        self.periods_to_stats = self.periods_to_stats.saturating_sub(1 + missed);
        if self.periods_to_stats == 0 {
            self.periods_to_stats = STATS_PERIODS;
            report.stats = Some(self.send_stats(robot, slot));
        }
        report
    }

    /// Takes one chunk of a setup: the first one drops the controller, the last one builds the
    /// new one; a chunk that breaks the sequence is refused.
    fn on_setup_chunk<P>(
        &mut self,
        robot: &mut Robot<P>,
        slot: &mut ControllerSlot,
        model: &JustinModel<f32>,
        chunk: &SetupChunk,
        report: &mut PeriodReport,
    ) where
        P: embedded_io::Read + embedded_io::ReadReady + embedded_io::Write,
    {
        if chunk.index == 0 {
            slot.clear();
            self.last_valid = None;
            self.mode = OutputMode::Normal;
        }
        let reply = match self.setup.push(chunk) {
            Ok(None) => return,
            Ok(Some(encoded)) => slot.configure(model, encoded),
            Err(fault) => SetupReply::Refused(fault),
        };
        self.reply_to_setup(robot, reply, report);
    }

    fn reply_to_setup<P>(&mut self, robot: &mut Robot<P>, reply: SetupReply, report: &mut PeriodReport)
    where
        P: embedded_io::Read + embedded_io::ReadReady + embedded_io::Write,
    {
        robot.send(Payload::SetupReply(reply));
        report.setup = Some(reply);
    }

    /// The safe output of a board without a controller: zero torque and platform command,
    /// the brake, for the sensor frame just received.
    fn refuse_unconfigured<P>(&mut self, robot: &mut Robot<P>, report: &mut PeriodReport)
    where
        P: embedded_io::Read + embedded_io::ReadReady + embedded_io::Write,
    {
        let Ok(joints) = JointTorqueInterface::read(robot) else { return };
        self.count_fault(LinkFault::Unconfigured, report);
        let _ = robot.write_torque(&[0.0; U]);
        let _ = robot.write_velocity(&PlatformCommand { velocity: [0.0; 3], leg_rates: [0.0; LEGS] });
        robot.send_actuator(OutputStatus {
            cycle: joints.cycle,
            mode: OutputMode::Brake,
            brake: true,
            fault_code: 0,
            link_fault: Some(LinkFault::Unconfigured),
        });
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
        slot: &mut ControllerSlot,
        fault: LinkFault,
        report: &mut PeriodReport,
    ) where
        P: embedded_io::Read + embedded_io::ReadReady + embedded_io::Write,
    {
        self.count_fault(fault, report);
        if let (Some(frame), Some(controller)) = (self.last_valid, slot.controller()) {
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

    /// Sends the statistics (link faults include frames the port failed to send) and, with a
    /// controller, the kernel's telemetry message; returns the statistics.
    fn send_stats<P>(&mut self, robot: &mut Robot<P>, slot: &mut ControllerSlot) -> RuntimeStats
    where
        P: embedded_io::Read + embedded_io::ReadReady + embedded_io::Write,
    {
        let stats =
            RuntimeStats { link_faults: self.stats.link_faults.saturating_add(robot.send_failures()), ..self.stats };
        robot.send(Payload::Stats(stats));
        let Some(controller) = slot.controller() else { return stats };
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
