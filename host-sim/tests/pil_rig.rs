//! Processor in the loop, short: the whole-body rig of Ch. 6 controlled by the firmware image
//! under QEMU (Cortex-M7, f32) for 300 cycles, the host controller (f64) alongside on the same
//! frames. Needs `qemu-system-arm` and builds the image: run by `.ci/test.sh` (`--ignored`).
#![allow(clippy::unwrap_used, reason = "tests")]

use host_sim::pil::Target;
use host_sim::scenarios::RunOptions;
use host_sim::wbc::chapter_6_rig;
use kernel::controller::config::Hand;

#[test]
#[ignore = "needs qemu-system-arm and the firmware build (run by .ci/test.sh)"]
fn the_firmware_controls_the_robot_like_the_host_controller() {
    let options = RunOptions { pil: Some(Target::CortexM7), ..RunOptions::default() };
    let mut rig = chapter_6_rig(Hand::Right, &[], &options).unwrap();
    let series = rig.run(0.3, |_, _| Ok(())).unwrap();
    assert_eq!(series.rows().len(), 300);
    assert_eq!(rig.faulty_cycles, 0);
    // f32 on the board against f64 on the host, on the same frames (gravity torques up to
    // ~100 Nm): agreement to f32 rounding of the whole step.
    assert!(rig.firmware_torque_difference < 0.01, "{} Nm", rig.firmware_torque_difference);
    assert!(rig.firmware_torque_difference > 0.0, "the firmware's torques are not the host's");
    let stats = rig.firmware.as_ref().and_then(|f| f.stats).unwrap();
    assert_eq!(stats.link_faults, 0);
    assert!(stats.cycles > 0 && stats.cycles <= 300, "{stats:?}");
}
