//! Processor-in-the-loop: the firmware image (`firmware/src/bin/runtime.rs`, the Justin
//! controller in `f32`) running under QEMU as the whole-body rig's controller.
//!
//! [`Firmware::start`] builds the image for the target core if needed (`cargo build` in
//! `firmware/`, its own target directory per core), listens on a loopback TCP port, starts QEMU
//! with UART0 connected to it, and waits for the connection. [`Firmware::configure`] sends the
//! scenario's rig as the setup message ([`rig_setup`], `link::setup`: environment volumes, free
//! platform axes, hierarchy, in CRC-checked chunks) and waits for the firmware to acknowledge it
//! with the configuration's checksum: one image for every scenario. [`Firmware::step`] sends one sensor
//! frame and waits for the actuator frame of the same cycle: lockstep on simulated time,
//! however slowly QEMU runs. An answer that does not come within the timeout is an error,
//! never a hang. The image logs through defmt on QEMU's semihosting stdout (faults, mode changes,
//! statistics once per second): a thread decodes it with the image's `.defmt` table
//! (`defmt-decoder`), prints each line as `pil: firmware: …`, keeps it ([`Firmware::log_line`])
//! and writes it to `runtime.log` beside the image. With `PIL_PLUGIN` naming a build of the
//! counting plugin (`firmware/wcet/wcet_insn.c`, `firmware/wcet/build_plugin.sh`), QEMU loads
//! it and counts the instructions of every controller step of the image (region 0 of its
//! markers) into `step-counts.txt` beside the image ([`Firmware::step_counts`]). Dropping the
//! [`Firmware`] kills QEMU.
//!
//! The run's options name the target ([`crate::scenarios::RunOptions::pil`], the `--pil`
//! option); [`crate::wbc::rig`] then attaches the firmware to the rig it builds.

use std::fs::File;
use std::io::{BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command as Process, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use embedded_io_adapters::std::FromStd;
use fixtures::justin;
use hal::{JointSample, PlatformSample};
use kernel::controller::config::TaskSpec;
use kernel::controller::faults::SafeOutput;
use kernel::controller::messages::{encode_command, Command};
use kernel::controller::{ActuatorFrame, SensorFrame};
use kernel::tasks::collision::SweptSphere;
use link::setup::{self, MAX_SETUP_BYTES};
use link::{
    encode, write_frame, ActuatorMsg, Frame, FrameReader, LinkError, OutputMode, Payload, RigSetup, RuntimeStats,
    SensorMsg, SetupChunk, SetupReply, Volume, MAX_ENCODED, MAX_MESSAGE_BYTES,
};

use crate::scalar::{narrow_command, widen_actuator_frame};

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
    /// The counting plugin's output file, when the plugin is loaded.
    counts: Option<PathBuf>,
    /// The decoded defmt log lines so far.
    log: Arc<Mutex<Vec<String>>>,
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
        let counts = std::env::var_os("PIL_PLUGIN").map(|plugin| (plugin, elf.with_file_name("step-counts.txt")));
        let mut qemu = Process::new("qemu-system-arm");
        if let Some((plugin, file)) = &counts {
            let _ = std::fs::remove_file(file);
            let mut argument = plugin.clone();
            argument.push(",out=");
            argument.push(file);
            qemu.arg("-plugin").arg(argument);
        }
        let mut qemu = qemu
            .args(["-machine", target.machine(), "-display", "none", "-monitor", "none", "-serial"])
            .arg(format!("tcp:127.0.0.1:{port}"))
            .args(["-semihosting-config", "enable=on,target=native", "-kernel"])
            .arg(&elf)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .map_err(|e| format!("qemu-system-arm: {e}"))?;
        let log = decode_log(&elf, &mut qemu, log)?;
        let mut firmware = Self::connect(target, qemu, &listener, timeout, log)?;
        firmware.counts = counts.map(|(_, file)| file);
        firmware.qemu_alive()?;
        eprintln!("pil: {} on QEMU {} connected (log: {})", target.label(), target.machine(), log_path.display());
        Ok(firmware)
    }

    /// Waits for QEMU to connect its UART to `listener`.
    fn connect(
        target: Target,
        mut qemu: Child,
        listener: &TcpListener,
        timeout: Duration,
        log: Arc<Mutex<Vec<String>>>,
    ) -> Result<Self, String> {
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
            counts: None,
            log,
            stats: None,
        })
    }

    /// The target the image was built for.
    pub fn target(&self) -> Target {
        self.target
    }

    /// The first decoded log line (`<s.ms> <LEVEL> <message>`) that contains `text`, waiting up
    /// to `within` for it (the firmware logs after it answers a frame); `None` if none came.
    pub fn log_line(&self, text: &str, within: Duration) -> Option<String> {
        let deadline = Instant::now() + within;
        loop {
            let found = self.log.lock().ok()?.iter().find(|line| line.contains(text)).cloned();
            if found.is_some() || Instant::now() > deadline {
                return found;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// The instruction counts of the controller steps run so far, when the counting plugin is
    /// loaded (`PIL_PLUGIN`).
    pub fn step_counts(&self) -> Result<Option<StepCounts>, String> {
        let Some(file) = &self.counts else { return Ok(None) };
        let text = std::fs::read_to_string(file).map_err(|e| format!("{}: {e}", file.display()))?;
        Ok(StepCounts::parse(&text))
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

    /// Configures the firmware's controller for the rig `setup` and waits for its
    /// acknowledgement; an error if the firmware refuses it (its typed fault) or acknowledges
    /// another configuration (checksum).
    pub fn configure(&mut self, setup: &RigSetup) -> Result<(), String> {
        let (chunks, checksum) = setup_chunks(setup)?;
        for chunk in chunks {
            self.send(Payload::Setup(chunk))?;
        }
        match self.next_setup_reply()? {
            SetupReply::Accepted { checksum: acknowledged } if acknowledged == checksum => Ok(()),
            SetupReply::Accepted { checksum: acknowledged } => {
                Err(format!("setup: the firmware acknowledged checksum {acknowledged:#010x}, sent {checksum:#010x}"))
            }
            SetupReply::Refused(fault) => Err(format!("setup refused by the firmware: {fault:?}")),
        }
    }

    /// Sends a planner command (converted to `f32`); the firmware applies it before the next frame.
    pub fn apply(&mut self, command: &Command<f64>) -> Result<(), String> {
        let command = narrow_command(command)?;
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
        self.next_frame(|payload| match payload {
            Payload::Actuator(answer) => Some(answer),
            _ => None,
        })
    }

    /// The firmware's next reply to a setup; an error after the answer timeout.
    pub fn next_setup_reply(&mut self) -> Result<SetupReply, String> {
        self.next_frame(|payload| match payload {
            Payload::SetupReply(reply) => Some(reply),
            _ => None,
        })
    }

    /// The first frame `wanted` picks from what the firmware sends (statistics frames on the
    /// way are kept); an error after the answer timeout.
    fn next_frame<T>(&mut self, wanted: impl Fn(Payload) -> Option<T>) -> Result<T, String> {
        let deadline = Instant::now() + self.timeout;
        loop {
            let received = self.reader.read(&mut self.input).map_err(|e| self.link_error(&e))?;
            if let Payload::Stats(stats) = received.frame.payload {
                self.stats = Some(stats);
            } else if let Some(found) = wanted(received.frame.payload) {
                return Ok(found);
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

/// Instructions per controller step of the firmware (QEMU counting plugin).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StepCounts {
    /// Steps counted.
    pub steps: usize,
    /// The median step's instructions.
    pub median: u64,
    /// The most expensive step's instructions.
    pub max: u64,
}

impl StepCounts {
    /// The counts of the plugin's region-0 sample lines (`wcet region=0 sample=K insns=X …`);
    /// `None` without any.
    pub fn parse(text: &str) -> Option<Self> {
        let mut counts: Vec<u64> = text
            .lines()
            .filter_map(|line| line.strip_prefix("wcet region=0 sample="))
            .filter_map(|rest| rest.split_whitespace().find_map(|field| field.strip_prefix("insns=")))
            .filter_map(|insns| insns.parse().ok())
            .collect();
        counts.sort_unstable();
        let median = *counts.get((counts.len().checked_sub(1)?) / 2)?;
        Some(Self { steps: counts.len(), median, max: *counts.last()? })
    }
}

/// Starts a thread that decodes the defmt frames on QEMU's stdout with `elf`'s `.defmt` table;
/// each line is printed, written to `file` and kept in the returned list.
fn decode_log(elf: &Path, qemu: &mut Child, file: File) -> Result<Arc<Mutex<Vec<String>>>, String> {
    let bytes = std::fs::read(elf).map_err(|e| format!("{}: {e}", elf.display()))?;
    let table = defmt_decoder::Table::parse(&bytes)
        .map_err(|e| format!("defmt table of {}: {e}", elf.display()))?
        .ok_or_else(|| format!("{} has no defmt table", elf.display()))?;
    let stdout = qemu.stdout.take().ok_or("QEMU's stdout is not piped")?;
    let lines = Arc::new(Mutex::new(Vec::new()));
    let kept = Arc::clone(&lines);
    std::thread::spawn(move || print_log(&table, stdout, file, &kept));
    Ok(lines)
}

/// Decodes `stdout` until QEMU closes it.
fn print_log(table: &defmt_decoder::Table, mut stdout: ChildStdout, mut file: File, lines: &Mutex<Vec<String>>) {
    let mut decoder = table.new_stream_decoder();
    let mut chunk = [0u8; 1024];
    while let Ok(n @ 1..) = stdout.read(&mut chunk) {
        decoder.received(chunk.get(..n).unwrap_or_default());
        loop {
            let line = match decoder.decode() {
                Ok(frame) => frame.display(false).to_string(),
                // rzcobs (the default) drops the bad frame; the raw encoding cannot resynchronise.
                Err(defmt_decoder::DecodeError::Malformed) if table.encoding().can_recover() => {
                    "(malformed defmt frame)".to_string()
                }
                Err(defmt_decoder::DecodeError::Malformed) => return,
                Err(defmt_decoder::DecodeError::UnexpectedEof) => break,
            };
            eprintln!("pil: firmware: {line}");
            let _ = writeln!(file, "{line}");
            if let Ok(mut lines) = lines.lock() {
                lines.push(line);
            }
        }
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

/// The setup message of a rig: its environment volumes (world frame, rounded to `f32`), the
/// platform axes its admittance moves and its hierarchy.
pub fn rig_setup(
    environment: &[SweptSphere<f64>],
    free_base_axes: [bool; 3],
    hierarchy: &[TaskSpec],
) -> Result<RigSetup, String> {
    let volumes: Vec<Volume> = environment.iter().map(Volume::from_swept_sphere).collect();
    Ok(RigSetup {
        environment: heapless::Vec::from_slice(&volumes).map_err(|_| "setup: too many environment volumes")?,
        free_base_axes,
        hierarchy: heapless::Vec::from_slice(hierarchy).map_err(|_| "setup: too many tasks")?,
    })
}

/// The chunks of `setup` and the checksum the firmware acknowledges it with.
pub fn setup_chunks(setup: &RigSetup) -> Result<(Vec<SetupChunk>, u32), String> {
    let mut encoded = [0u8; MAX_SETUP_BYTES];
    let chunks: Vec<SetupChunk> =
        setup::split(setup, &mut encoded).ok_or("setup: larger than the firmware's buffer")?.collect();
    let length = chunks.iter().map(|chunk| chunk.bytes.len()).sum();
    let checksum = setup::checksum(encoded.get(..length).ok_or("setup: chunk lengths")?);
    Ok((chunks, checksum))
}

/// The actuator frame in `f64`.
fn actuator_frame(answer: &ActuatorMsg) -> Result<ActuatorFrame<f64, U>, String> {
    let torque: [f32; U] = answer.torque.as_slice().try_into().map_err(|_| "wrong joint count in the answer")?;
    Ok(widen_actuator_frame(&ActuatorFrame {
        torque,
        platform: answer.platform_command(),
        brake: answer.brake,
        mode: match answer.mode {
            OutputMode::Normal => SafeOutput::Normal,
            OutputMode::Hold => SafeOutput::Hold,
            OutputMode::Brake => SafeOutput::Brake,
        },
    }))
}

#[cfg(test)]
mod tests {
    use super::StepCounts;

    #[test]
    fn step_counts_are_read_from_the_plugins_region_0_samples() {
        let text = "wcet region=0 sample=0 insns=300 fp_div_sqrt=4\n\
                    wcet region=1 sample=0 insns=9999 fp_div_sqrt=0\n\
                    wcet region=0 sample=1 insns=100 fp_div_sqrt=2\n\
                    wcet region=0 sample=2 insns=200 fp_div_sqrt=3\n\
                    wcet region=0 sample=3 insns=400 fp_div_sqrt=5\n\
                    wcet SUMMARY region=0 samples=4 min=100 max=400 mean=250.0 spread=300\n";
        assert_eq!(StepCounts::parse(text), Some(StepCounts { steps: 4, median: 200, max: 400 }));
        assert_eq!(StepCounts::parse("wcet total guest insns=5\n"), None);
    }
}
