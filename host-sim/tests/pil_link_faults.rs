//! The firmware image under QEMU (Cortex-M7) refuses every kind of bad link input with a typed
//! link fault (also in its decoded defmt log) and the controller's safe output, recovers after the controller's recovery wait
//! (`valid_cycles` valid frames, [`kernel::controller::recovery`]), and a
//! firmware that stops answering is a timeout on the host. Needs `qemu-system-arm` and builds
//! the image: run by `.ci/test.sh` (`--ignored`).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]

use std::time::{Duration, Instant};

use fixtures::justin;
use hal::{JointTorqueInterface, PlatformVelocityInterface};
use host_sim::pil::{sensor_message, Firmware, Target};
use host_sim::scenarios::RunOptions;
use host_sim::wbc::{chapter_6_rig, Rig};
use kernel::controller::config::Hand;
use kernel::controller::faults::SafeOutput;
use kernel::controller::SensorFrame;
use link::{ActuatorMsg, LinkFault, OutputMode, Payload};

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
    let mut rig = chapter_6_rig(Hand::Right, &[], &RunOptions::default()).unwrap();

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

    // Missing in time: no frame for the watchdog's 500 periods.
    let silent = Instant::now();
    assert_safe(&firmware.next_actuator().unwrap(), 3, LinkFault::Missing);
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
