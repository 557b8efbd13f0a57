//! `--scalar f32` end to end: `wbc_step` (3 s simulated) with the whole-body controller in `f32`
//! on the host, the `f64` controller alongside on the same frames; the scenarios without the
//! whole-body rig refuse the option.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]

use host_sim::scalar::Scalar;
use host_sim::scenarios::{run, RunOptions};

#[test]
fn wbc_step_passes_its_claims_in_f32_with_torques_close_to_f64() {
    let dir = std::env::temp_dir().join(format!("host-sim-scalar-f32-{}", std::process::id()));
    let options = RunOptions { dir: Some(dir.clone()), scalar: Scalar::F32, ..RunOptions::default() };
    // `run` fails if a claim fails.
    run("wbc_step", &options).unwrap();
    let text = std::fs::read_to_string(dir.join("summary.json")).unwrap();
    let summary: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(summary["controller"], "host f32", "{summary}");
    assert_eq!(summary["failed_claims"].as_array().unwrap().len(), 0, "{summary}");
    assert_eq!(summary["passed_claims"].as_array().unwrap().len(), 4, "{summary}");
    // Gravity torques up to ~100 Nm, computed in f32 from frames rounded to f32: the whole step
    // agrees with f64 to ~1e-4 Nm (measured 1.1e-4 Nm), and it is not the f64 controller.
    let difference = summary["torque_difference_to_host_f64_first_0_5_s_nm"].as_f64().unwrap();
    assert!(difference < 1e-2, "{difference} Nm");
    assert!(difference > 1e-7, "{difference} Nm: the f32 controller's torques equal the f64 controller's");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn scenarios_without_the_whole_body_rig_refuse_f32() {
    let options = RunOptions { scalar: Scalar::F32, ..RunOptions::default() };
    let error = run("energy_planar4", &options).unwrap_err();
    assert!(error.starts_with("--scalar f32: energy_planar4 does not run the whole-body controller"), "{error}");
    assert!(error.contains("wbc_step"), "{error}");
}
