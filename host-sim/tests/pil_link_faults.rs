//! The firmware image under QEMU (Cortex-M7) refuses every kind of bad link input with a typed
//! link fault (also in its decoded defmt log) and the controller's safe output, recovers after the controller's recovery wait
//! (`valid_cycles` valid frames, [`kernel::controller::recovery`]), and a
//! firmware that stops answering is a timeout on the host. A bad setup message (a corrupted
//! chunk, a wrong total, a sequence cut short, bytes that are no setup, an invalid
//! configuration) is refused with a typed setup fault, and the board without a controller
//! answers sensor frames with zero torque and the brake. Needs `qemu-system-arm` and builds
//! the image: run by `.ci/test.sh` (`--ignored`).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]

use std::time::{Duration, Instant};

use fixtures::justin;
use fixtures::justin::whole_body;
use hal::{JointTorqueInterface, PlatformVelocityInterface};
use host_sim::pil::{rig_setup, sensor_message, setup_chunks, Firmware, Target};
use host_sim::scenarios::RunOptions;
use host_sim::wbc::{chapter_6_rig, Rig};
use kernel::controller::config::{ArmId, TaskKind, TaskSpec};
use kernel::controller::faults::SafeOutput;
use kernel::controller::SensorFrame;
use kernel::tasks::collision::{Core, SweptSphere};
use link::{ActuatorMsg, LinkFault, OutputMode, Payload, RigSetup, SetupChunk, SetupFault, SetupReply};
use nalgebra::Vector3;

/// The simulated robot's sensor frame, numbered `cycle`.
fn frame(rig: &mut Rig, cycle: u64) -> SensorFrame<f64, { justin::UPPER_DOF }> {
    let mut joints = JointTorqueInterface::read(&mut rig.sim).unwrap();
    let mut platform = PlatformVelocityInterface::read(&mut rig.sim).unwrap();
    joints.cycle = cycle;
    platform.cycle = cycle;
    SensorFrame { joints, platform }
}

/// The encoded sensor frame of `cycle` (takes the next sequence number).
fn wire(firmware: &mut Firmware, rig: &mut Rig, cycle: u64) -> Vec<u8> {
    firmware.encode(Payload::Sensor(sensor_message(&frame(rig, cycle)).unwrap())).unwrap()
}

/// Asserts the answer is the safe output for the last valid cycle, naming `fault`.
fn assert_safe(answer: &ActuatorMsg, last_valid: u64, fault: LinkFault) {
    assert_eq!(answer.link_fault, Some(fault), "{answer:?}");
    assert_eq!(answer.cycle, last_valid);
    assert_ne!(answer.mode, OutputMode::Normal);
    assert_eq!(answer.fault_code, 4, "the controller's StaleFrame fault");
    assert!(answer.torque.iter().all(|t| t.is_finite()));
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware build (run by .ci/test.sh)"]
fn bad_link_input_gives_a_typed_fault_and_the_safe_output() {
    // The only thread of this test binary that touches the environment.
    std::env::set_var("PIL_TIMEOUT_S", "3");
    let mut firmware = Firmware::start(Target::CortexM7).unwrap();
    let mut rig = chapter_6_rig(ArmId::RIGHT, &[], &RunOptions::default()).unwrap();
    firmware.configure(&rig_setup(&[], [true; 3], &whole_body::fig_6_3_hierarchy(ArmId::RIGHT)).unwrap()).unwrap();

    let normal = firmware.step(&frame(&mut rig, 1)).unwrap();
    assert_eq!(normal.mode, SafeOutput::Normal);
    assert!(normal.torque.iter().any(|t| t.abs() > 1.0), "gravity compensation: {:?}", normal.torque);

    // Corrupted: one byte of the frame changed.
    let mut corrupted = wire(&mut firmware, &mut rig, 2);
    corrupted[40] ^= 0x01;
    firmware.send_bytes(&corrupted).unwrap();
    assert_safe(&firmware.next_actuator().unwrap(), 1, LinkFault::Corrupted);
    // ... and the firmware's defmt log, decoded on the host, names it.
    let logged = firmware.log_line("link fault Corrupted", Duration::from_secs(5));
    assert!(logged.as_deref().is_some_and(|line| line.contains("WARN")), "{logged:?}");

    // Truncated: the frame cut inside its first COBS run.
    let whole = wire(&mut firmware, &mut rig, 2);
    let run = usize::from(whole[0]);
    assert!(run >= 2);
    firmware.send_bytes(&[&whole[..run - 1], &[0]].concat()).unwrap();
    assert_safe(&firmware.next_actuator().unwrap(), 1, LinkFault::Truncated);

    // Replayed: a valid frame sent twice; the first copy is stepped (and, as the two refused
    // frames' sequence numbers never arrived, reported after a gap). It is a valid frame of the
    // recovery wait: still the hold.
    let valid = wire(&mut firmware, &mut rig, 2);
    firmware.send_bytes(&valid).unwrap();
    firmware.send_bytes(&valid).unwrap();
    let first = firmware.next_actuator().unwrap();
    assert_eq!((first.cycle, first.link_fault, first.mode), (2, Some(LinkFault::Missing), OutputMode::Hold));
    assert_safe(&firmware.next_actuator().unwrap(), 2, LinkFault::Replayed);

    // Missing in the sequence: a frame encoded and never sent; the next one is stepped and the
    // gap reported.
    let _lost = wire(&mut firmware, &mut rig, 3);
    let next = wire(&mut firmware, &mut rig, 3);
    firmware.send_bytes(&next).unwrap();
    let after_gap = firmware.next_actuator().unwrap();
    assert_eq!((after_gap.cycle, after_gap.link_fault), (3, Some(LinkFault::Missing)));

    // Missing in time: no frame for the watchdog's 500 periods (of QEMU's clock, which runs
    // slower than the wall clock on a loaded machine: up to five answer timeouts).
    let silent = Instant::now();
    let watchdog = (0..5).find_map(|_| firmware.next_actuator().ok()).unwrap();
    assert_safe(&watchdog, 3, LinkFault::Missing);
    assert!(silent.elapsed().as_secs_f64() > 0.3, "watchdog after {:?}", silent.elapsed());

    // Valid frames: the hold lasts for the recovery wait, then the robot is controlled again.
    let wait = u64::from(rig.controller.config().recovery.valid_cycles);
    let modes: Vec<SafeOutput> =
        (4..4 + wait).map(|cycle| firmware.step(&frame(&mut rig, cycle)).unwrap().mode).collect();
    assert!(modes.iter().all(|m| *m == SafeOutput::Hold), "{modes:?}");
    assert_eq!(firmware.step(&frame(&mut rig, 4 + wait)).unwrap().mode, SafeOutput::Normal);
    let next = 5 + wait;

    // A firmware that stops answering: a timeout, not a hang.
    let stopped = std::process::Command::new("kill").args(["-STOP", &firmware.qemu_id().to_string()]).status();
    assert!(stopped.unwrap().success());
    let waiting = Instant::now();
    let error = firmware.step(&frame(&mut rig, next)).unwrap_err();
    assert!(error.starts_with("timeout"), "{error}");
    assert!((2.5..6.0).contains(&waiting.elapsed().as_secs_f64()), "{:?}", waiting.elapsed());
}

/// A setup of two chunks or more: four environment triangles out of reach, the Fig. 6.3
/// hierarchy for the right hand.
fn two_chunk_setup() -> RigSetup {
    let triangles: Vec<SweptSphere<f64>> = (0..4)
        .map(|i| {
            let x = 3.0 + f64::from(i);
            let corners = [Vector3::new(x, 0.0, 0.0), Vector3::new(x, 1.0, 0.0), Vector3::new(x, 0.0, 1.0)];
            SweptSphere { core: Core::Triangle(corners), radius: 0.01 }
        })
        .collect();
    rig_setup(&triangles, [true; 3], &whole_body::fig_6_3_hierarchy(ArmId::RIGHT)).unwrap()
}

/// Sends `chunks` as setup frames.
fn send_chunks(firmware: &mut Firmware, chunks: &[SetupChunk]) {
    for chunk in chunks {
        firmware.send(Payload::Setup(chunk.clone())).unwrap();
    }
}

/// Asserts the answer is the safe output of a board without a controller for `cycle`.
fn assert_unconfigured(answer: &ActuatorMsg, cycle: u64) {
    assert_eq!((answer.cycle, answer.link_fault), (cycle, Some(LinkFault::Unconfigured)), "{answer:?}");
    assert_eq!((answer.mode, answer.brake), (OutputMode::Brake, true));
    assert!(answer.torque.iter().all(|t| *t == 0.0), "{:?}", answer.torque);
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware build (run by .ci/test.sh)"]
fn bad_setup_input_gives_a_typed_fault_and_no_controller() {
    let mut firmware = Firmware::start(Target::CortexM7).unwrap();
    let mut rig = chapter_6_rig(ArmId::RIGHT, &[], &RunOptions::default()).unwrap();
    let setup = two_chunk_setup();
    let (chunks, checksum) = setup_chunks(&setup).unwrap();
    assert!(chunks.len() >= 2, "{} chunks", chunks.len());

    // No setup yet: zero torque and the brake.
    let sensor = wire(&mut firmware, &mut rig, 1);
    firmware.send_bytes(&sensor).unwrap();
    assert_unconfigured(&firmware.next_actuator().unwrap(), 1);

    // Corrupted: one byte of the second chunk's frame changed.
    send_chunks(&mut firmware, &chunks[..1]);
    let mut corrupted = firmware.encode(Payload::Setup(chunks[1].clone())).unwrap();
    assert!(corrupted[0] >= 2, "byte 1 is inside the first COBS run");
    corrupted[1] = corrupted[1].wrapping_add(1).max(1);
    firmware.send_bytes(&corrupted).unwrap();
    assert_eq!(firmware.next_setup_reply().unwrap(), SetupReply::Refused(SetupFault::Link(LinkFault::Corrupted)));
    let logged = firmware.log_line("setup Refused(Link(Corrupted))", Duration::from_secs(5));
    assert!(logged.as_deref().is_some_and(|line| line.contains("INFO")), "{logged:?}");

    // A wrong total on the second chunk.
    send_chunks(&mut firmware, &[chunks[0].clone(), SetupChunk { total: chunks[1].total + 1, ..chunks[1].clone() }]);
    assert_eq!(firmware.next_setup_reply().unwrap(), SetupReply::Refused(SetupFault::WrongTotal));

    // Truncated: a sensor frame before the last chunk; still no controller.
    send_chunks(&mut firmware, &chunks[..1]);
    let sensor = wire(&mut firmware, &mut rig, 2);
    firmware.send_bytes(&sensor).unwrap();
    assert_eq!(firmware.next_setup_reply().unwrap(), SetupReply::Refused(SetupFault::Incomplete));
    assert_unconfigured(&firmware.next_actuator().unwrap(), 2);

    // Bytes that are no setup.
    let garbage = SetupChunk { index: 0, total: 1, bytes: heapless::Vec::from_slice(&[0xff; 16]).unwrap() };
    send_chunks(&mut firmware, &[garbage]);
    assert_eq!(firmware.next_setup_reply().unwrap(), SetupReply::Refused(SetupFault::Undecodable));

    // Valid encodings of invalid configurations: the kernel's constructors refuse them.
    let mut bad_level = setup.clone();
    bad_level.hierarchy.push(TaskSpec { kind: TaskKind::EndStops, level: 200 }).unwrap();
    let error = firmware.configure(&bad_level).unwrap_err();
    assert!(error.contains("InvalidConfiguration"), "{error}");
    let mut bad_volume = setup.clone();
    bad_volume.environment[0].radius = f32::NAN;
    let error = firmware.configure(&bad_volume).unwrap_err();
    assert!(error.contains("InvalidEnvironment"), "{error}");

    // The valid setup: acknowledged with its checksum, and the robot is controlled.
    send_chunks(&mut firmware, &chunks);
    assert_eq!(firmware.next_setup_reply().unwrap(), SetupReply::Accepted { checksum });
    let normal = firmware.step(&frame(&mut rig, 3)).unwrap();
    assert_eq!(normal.mode, SafeOutput::Normal);
    assert!(normal.torque.iter().any(|t| t.abs() > 1.0), "gravity compensation: {:?}", normal.torque);
}
