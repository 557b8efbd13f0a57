//! Processor in the loop, short: the whole-body rig of Ch. 6 controlled by the firmware image
//! under QEMU (Cortex-M7, f32) for 300 cycles, the host controller (f64) alongside on the same
//! frames, the firmware's defmt log decoded on the host, every step's instructions counted by the
//! QEMU plugin. Needs `qemu-system-arm` and `gcc`, builds the image and the plugin: run by
//! `.ci/test.sh` (`--ignored`).
#![allow(clippy::unwrap_used, reason = "tests")]

use std::time::Duration;

use host_sim::pil::Target;
use host_sim::scenarios::RunOptions;
use host_sim::wbc::chapter_6_rig;
use kernel::controller::config::ArmId;

#[test]
#[ignore = "needs qemu-system-arm and the firmware build (run by .ci/test.sh)"]
fn the_firmware_controls_the_robot_like_the_host_controller() {
    // The counting plugin, built for the installed QEMU (the only thread touching the environment).
    let plugin = std::env::temp_dir().join(format!("pil-rig-wcet-insn-{}.so", std::process::id()));
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../firmware/wcet/build_plugin.sh");
    assert!(std::process::Command::new("bash").arg(script).arg(&plugin).status().unwrap().success());
    std::env::set_var("PIL_PLUGIN", &plugin);
    let options = RunOptions { pil: Some(Target::CortexM7), ..RunOptions::default() };
    let mut rig = chapter_6_rig(ArmId::RIGHT, &[], &options).unwrap();
    let series = rig.run(0.3, |_, _| Ok(())).unwrap();
    assert_eq!(series.rows().len(), 300);
    assert_eq!(rig.faulty_cycles, 0);
    // f32 on the board against f64 on the host, on the same frames (gravity torques up to
    // ~100 Nm): agreement to f32 rounding of the whole step.
    assert!(rig.torque_difference < 0.01, "{} Nm", rig.torque_difference);
    assert!(rig.torque_difference > 0.0, "the firmware's torques are not the host's");
    let firmware = rig.driver.firmware().unwrap();
    let stats = firmware.stats.unwrap();
    assert_eq!(stats.link_faults, 0);
    assert!(stats.cycles > 0 && stats.cycles <= 300, "{stats:?}");
    // The firmware's defmt log, decoded on the host: the start line and the same statistics.
    let start = firmware.log_line("runtime: 1000 Hz", Duration::ZERO);
    assert!(start.as_deref().is_some_and(|line| line.contains("INFO")), "{start:?}");
    let logged = firmware.log_line(&format!("cycles {} deadline misses", stats.cycles), Duration::from_secs(5));
    assert!(logged.is_some(), "no decoded statistics line for {stats:?}");
    // Every step counted: the nominal step of BENCHMARKS.md costs ~390 000 instructions on the
    // M7 in f32, its bound ~820 000.
    let counts = firmware.step_counts().unwrap().unwrap();
    assert_eq!(counts.steps, 300);
    assert!((200_000..1_000_000).contains(&counts.median), "{counts:?}");
    assert!(counts.median <= counts.max && counts.max < 1_000_000, "{counts:?}");
    std::fs::remove_file(&plugin).unwrap();
}
