//! Processor-in-the-loop: the firmware image (`firmware/src/bin/runtime.rs`, the Justin
//! controller in `f32`) running under QEMU as the whole-body rig's controller.
//!
//! [`Firmware::start`] builds the image for the target core if needed (`cargo build` in
//! `firmware/`, its own target directory per core), listens on a loopback TCP port, starts QEMU
//! with UART0 connected to it, and waits for the connection. [`Firmware::step`] sends one sensor
//! frame and waits for the actuator frame of the same cycle: lockstep on simulated time,
//! however slowly QEMU runs. An answer that does not come within the timeout is an error,
//! never a hang. QEMU's semihosting log (faults, mode changes, statistics once per second) goes
//! to `runtime.log` beside the image. Dropping the [`Firmware`] kills QEMU.
//!
//! The run's options name the target ([`crate::scenarios::RunOptions::pil`], the `--pil`
//! option); [`crate::wbc::rig`] then attaches the firmware to the rig it builds.

use std::fs::File;
use std::io::BufReader;
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command as Process, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use embedded_io_adapters::std::FromStd;
use fixtures::justin;
use hal::{JointSample, PlatformCommand, PlatformSample};
use kernel::controller::faults::SafeOutput;
use kernel::controller::messages::{encode_command, Command};
use kernel::controller::{ActuatorFrame, SensorFrame};
use link::{
    encode, write_frame, ActuatorMsg, Frame, FrameReader, LinkError, OutputMode, Payload, RuntimeStats, SensorMsg,
    MAX_ENCODED, MAX_MESSAGE_BYTES,
};

/// Upper-body joints of a frame.
const U: usize = justin::UPPER_DOF;
/// How long QEMU may take to boot the image and connect.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(30);
/// Default time the firmware has to answer one frame (`PIL_TIMEOUT_S` overrides it).
const ANSWER_TIMEOUT: Duration = Duration::from_secs(10);

/// The cores an image is built for, with the QEMU board that emulates each.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Target {
    /// Cortex-M7 (single-precision FPU) on `mps2-an500`.
    #[value(name = "cortex-m7")]
    CortexM7,
    /// Cortex-M4F on `mps2-an386`.
    #[value(name = "cortex-m4f")]
    CortexM4f,
}

impl Target {
    /// The QEMU machine.
    pub fn machine(self) -> &'static str {
        match self {
            Self::CortexM7 => "mps2-an500",
            Self::CortexM4f => "mps2-an386",
        }
    }

    /// rustc's `target-cpu`.
    fn cpu(self) -> &'static str {
        match self {
            Self::CortexM7 => "cortex-m7",
            Self::CortexM4f => "cortex-m4",
        }
    }

    /// What `summary.json` records as the controller.
    pub fn label(self) -> String {
        let core = match self {
            Self::CortexM7 => "cortex-m7",
            Self::CortexM4f => "cortex-m4f",
        };
        format!("firmware {core} f32")
    }
}

/// Whether a firmware was started in this process.
static STARTED: AtomicBool = AtomicBool::new(false);

/// Whether a [`Firmware`] was started in this process (a scenario without the whole-body rig
/// never starts one, and ignores the `--pil` option).
pub fn started() -> bool {
    STARTED.load(Ordering::Relaxed)
}

/// The `firmware/` project beside this crate.
fn firmware_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join("firmware")
}

/// Builds the runtime image for `target` (cargo rebuilds only what changed); returns the ELF.
pub fn build(target: Target) -> Result<PathBuf, String> {
    let dir = firmware_dir();
    let target_dir = dir.join("target").join(format!("pil-{}", target.cpu()));
    eprintln!("pil: building the runtime image for {} …", target.cpu());
    let status = Process::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()))
        .current_dir(&dir)
        .args(["build", "--locked", "--release", "--bin", "runtime"])
        .env("CARGO_TARGET_DIR", &target_dir)
        .env("RUSTFLAGS", format!("-C link-arg=-Tlink.x -C target-cpu={}", target.cpu()))
        .status()
        .map_err(|e| format!("cargo build of the firmware: {e}"))?;
    if !status.success() {
        return Err(format!("cargo build of the firmware failed ({status})"));
    }
    Ok(target_dir.join("thumbv7em-none-eabihf").join("release").join("runtime"))
}

/// The firmware image running under QEMU, connected over its UART.
pub struct Firmware {
    target: Target,
    qemu: Child,
    input: FromStd<BufReader<TcpStream>>,
    output: FromStd<TcpStream>,
    reader: FrameReader,
    seq: u32,
    timeout: Duration,
    /// The firmware's latest statistics frame.
    pub stats: Option<RuntimeStats>,
}

impl Firmware {
    /// Builds the image if needed, starts QEMU and connects to the image's UART.
    pub fn start(target: Target) -> Result<Self, String> {
        let elf = build(target)?;
        let timeout = match std::env::var("PIL_TIMEOUT_S") {
            Ok(s) => Duration::from_secs_f64(s.parse().map_err(|e| format!("PIL_TIMEOUT_S: {e}"))?),
            Err(_) => ANSWER_TIMEOUT,
        };
        let listener = TcpListener::bind("127.0.0.1:0").map_err(|e| format!("listen: {e}"))?;
        let port = listener.local_addr().map_err(|e| format!("listen: {e}"))?.port();
        let log_path = elf.with_file_name("runtime.log");
        let log = File::create(&log_path).map_err(|e| format!("{}: {e}", log_path.display()))?;
        let qemu = Process::new("qemu-system-arm")
            .args(["-machine", target.machine(), "-display", "none", "-monitor", "none", "-serial"])
            .arg(format!("tcp:127.0.0.1:{port}"))
            .args(["-semihosting-config", "enable=on,target=native", "-kernel"])
            .arg(&elf)
            .stdin(Stdio::null())
            .stdout(log)
            .stderr(Stdio::inherit())
            .spawn()
            .map_err(|e| format!("qemu-system-arm: {e}"))?;
        let mut firmware = Self::connect(target, qemu, &listener, timeout)?;
        firmware.qemu_alive()?;
        STARTED.store(true, Ordering::Relaxed);
        eprintln!("pil: {} on QEMU {} connected (log: {})", target.label(), target.machine(), log_path.display());
        Ok(firmware)
    }

    /// Waits for QEMU to connect its UART to `listener`.
    fn connect(target: Target, mut qemu: Child, listener: &TcpListener, timeout: Duration) -> Result<Self, String> {
        listener.set_nonblocking(true).map_err(|e| format!("listen: {e}"))?;
        let start = Instant::now();
        let stream = loop {
            match listener.accept() {
                Ok((stream, _)) => break stream,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                Err(e) => return Err(format!("accept: {e}")),
            }
            if let Ok(Some(status)) = qemu.try_wait() {
                return Err(format!("QEMU exited before connecting ({status})"));
            }
            if start.elapsed() > CONNECT_TIMEOUT {
                let _ = qemu.kill();
                let _ = qemu.wait();
                return Err(format!("timeout: QEMU did not connect within {} s", CONNECT_TIMEOUT.as_secs()));
            }
            std::thread::sleep(Duration::from_millis(10));
        };
        let setup = |s: &TcpStream| -> std::io::Result<()> {
            s.set_nonblocking(false)?;
            s.set_nodelay(true)?;
            s.set_read_timeout(Some(timeout))
        };
        setup(&stream).map_err(|e| format!("socket: {e}"))?;
        let writer = stream.try_clone().map_err(|e| format!("socket: {e}"))?;
        Ok(Self {
            target,
            qemu,
            input: FromStd::new(BufReader::new(stream)),
            output: FromStd::new(writer),
            reader: FrameReader::new(),
            seq: 0,
            timeout,
            stats: None,
        })
    }

    /// The target the image was built for.
    pub fn target(&self) -> Target {
        self.target
    }

    /// The QEMU process id (to stop it in tests).
    pub fn qemu_id(&self) -> u32 {
        self.qemu.id()
    }

    fn qemu_alive(&mut self) -> Result<(), String> {
        match self.qemu.try_wait() {
            Ok(None) => Ok(()),
            Ok(Some(status)) => Err(format!("QEMU exited ({status})")),
            Err(e) => Err(format!("QEMU: {e}")),
        }
    }

    /// One control cycle on the firmware: the frame in `f32`, its answer back in `f64`.
    pub fn step(&mut self, frame: &SensorFrame<f64, U>) -> Result<ActuatorFrame<f64, U>, String> {
        let message = sensor_message(frame)?;
        let cycle = message.cycle;
        self.send(Payload::Sensor(message))?;
        loop {
            let answer = self.next_actuator()?;
            if answer.cycle == cycle && answer.link_fault.is_none() {
                return actuator_frame(&answer);
            }
        }
    }

    /// Sends a planner command (converted to `f32`); the firmware applies it before the next frame.
    pub fn apply(&mut self, command: &Command<f64>) -> Result<(), String> {
        let value = serde_json::to_value(command).map_err(|e| format!("command: {e}"))?;
        let command: Command<f32> = serde_json::from_value(value).map_err(|e| format!("command in f32: {e}"))?;
        let mut bytes = [0u8; MAX_MESSAGE_BYTES];
        let encoded = encode_command(&command, &mut bytes).map_err(|e| format!("command: {e}"))?;
        let bytes = heapless::Vec::from_slice(encoded).map_err(|_| "command too long".to_string())?;
        self.send(Payload::Command(bytes))
    }

    /// Sends `payload` as the next frame.
    pub fn send(&mut self, payload: Payload) -> Result<(), String> {
        let frame = Frame { seq: self.next_seq(), payload };
        write_frame(&mut self.output, &frame).map_err(|e| format!("link: {e}"))
    }

    /// Encodes `payload` as the next frame without sending it (fault injection: send it altered,
    /// twice, or not at all).
    pub fn encode(&mut self, payload: Payload) -> Result<Vec<u8>, String> {
        let mut out = [0u8; MAX_ENCODED];
        let frame = Frame { seq: self.next_seq(), payload };
        encode(&frame, &mut out).map(<[u8]>::to_vec).map_err(|e| format!("link: {e}"))
    }

    /// Sends raw bytes on the link.
    pub fn send_bytes(&mut self, bytes: &[u8]) -> Result<(), String> {
        embedded_io::Write::write_all(&mut self.output, bytes).map_err(|e| format!("link: {e}"))
    }

    fn next_seq(&mut self) -> u32 {
        let seq = self.seq;
        self.seq = self.seq.wrapping_add(1);
        seq
    }

    /// The next actuator frame the firmware sends (statistics and telemetry on the way are
    /// kept or skipped); an error after the answer timeout.
    pub fn next_actuator(&mut self) -> Result<ActuatorMsg, String> {
        let deadline = Instant::now() + self.timeout;
        loop {
            let received = self.reader.read(&mut self.input).map_err(|e| self.link_error(&e))?;
            match received.frame.payload {
                Payload::Actuator(answer) => return Ok(answer),
                Payload::Stats(stats) => self.stats = Some(stats),
                Payload::Telemetry(_) | Payload::Sensor(_) | Payload::Command(_) => {}
            }
            if Instant::now() > deadline {
                return Err(self.timeout_message());
            }
        }
    }

    fn link_error(&mut self, error: &LinkError<std::io::Error>) -> String {
        match error {
            LinkError::Io(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {
                self.timeout_message()
            }
            other => match self.qemu_alive() {
                Ok(()) => format!("link from the firmware: {other}"),
                Err(qemu) => format!("link from the firmware: {other}; {qemu}"),
            },
        }
    }

    fn timeout_message(&self) -> String {
        format!("timeout: the firmware did not answer within {:.1} s", self.timeout.as_secs_f64())
    }
}

impl Drop for Firmware {
    fn drop(&mut self) {
        let _ = self.qemu.kill();
        let _ = self.qemu.wait();
    }
}

/// The sensor frame in `f32` (the joint cycle counter is sent; the controller checks both).
pub fn sensor_message(frame: &SensorFrame<f64, U>) -> Result<SensorMsg, String> {
    let narrow = |v: &[f64; U]| v.map(|x| x as f32);
    let narrow3 = |v: &[f64; 3]| v.map(|x| x as f32);
    let joints = JointSample {
        position: narrow(&frame.joints.position),
        velocity: narrow(&frame.joints.velocity),
        torque: narrow(&frame.joints.torque),
        cycle: frame.joints.cycle,
    };
    let platform = PlatformSample {
        pose: narrow3(&frame.platform.pose),
        velocity: narrow3(&frame.platform.velocity),
        leg_lengths: frame.platform.leg_lengths.map(|x| x as f32),
        cycle: frame.platform.cycle,
    };
    SensorMsg::from_samples(&joints, &platform).ok_or_else(|| "more joints than a link frame carries".to_string())
}

/// The actuator frame in `f64`.
fn actuator_frame(answer: &ActuatorMsg) -> Result<ActuatorFrame<f64, U>, String> {
    let torque: [f32; U] = answer.torque.as_slice().try_into().map_err(|_| "wrong joint count in the answer")?;
    let platform = answer.platform_command();
    Ok(ActuatorFrame {
        torque: torque.map(f64::from),
        platform: PlatformCommand {
            velocity: platform.velocity.map(f64::from),
            leg_rates: platform.leg_rates.map(f64::from),
        },
        brake: answer.brake,
        mode: match answer.mode {
            OutputMode::Normal => SafeOutput::Normal,
            OutputMode::Hold => SafeOutput::Hold,
            OutputMode::Brake => SafeOutput::Brake,
        },
    })
}
