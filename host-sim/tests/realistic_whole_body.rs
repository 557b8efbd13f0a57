//! Whole-body scenarios on the realistic plant (`--plant realistic`): friction, torque-loop
//! lag, one cycle of delay and noisy sensors. The scenarios' own claims must hold, so a change
//! of the plant or the controller that breaks them on the realistic plant shows here; the
//! numbers are those of the plant's seed (README `--plant`).
#![allow(clippy::unwrap_used, reason = "tests")]

use host_sim::plant::PlantKind;
use host_sim::scenarios::{clean_mug, sweep_floor, wbc_phri, wbc_step, wipe_window, RunOptions};

fn realistic() -> RunOptions {
    RunOptions { plant: PlantKind::Realistic, ..RunOptions::default() }
}

#[test]
fn wbc_step_settles_on_the_realistic_plant_with_a_friction_steady_state_error() {
    let outcome = wbc_step::simulate(&realistic()).unwrap();
    let s = &outcome.summary;
    assert!(s.failed_claims().is_empty(), "failed: {:?}", s.failed_claims());
    assert!(s.get("settling_time_s").unwrap() < wbc_step::THESIS_SETTLING_S);
    // Friction holds the TCP off the goal (4.2 mm with the plant's seed), inside 5 % of the step;
    // the ideal plant ends within 1 mm of it.
    let final_error = s.get("final_error_m").unwrap();
    assert!(final_error > 1e-3 && final_error < wbc_step::SETTLING_BAND_M, "{final_error}");
}

/// The window: the impact at the first touch (13.6 N) exceeds the +10 N limit by the friction
/// (its share 3.6 N, its bound 4.1 N there); less the friction bound of each cycle the force
/// stays within the limit (9.57 N), and friction holds the static force at 6.05 N.
#[test]
fn wipe_window_keeps_the_force_within_the_limit_plus_the_friction_bound() {
    let outcome = wipe_window::simulate(&realistic()).unwrap();
    let s = &outcome.summary;
    assert!(s.failed_claims().is_empty(), "failed: {:?}", s.failed_claims());
    let peak = s.get("run_peak_force_n").unwrap();
    let beyond = s.get("run_peak_beyond_friction_n").unwrap();
    let bound = s.get("friction_bound_at_run_peak_n").unwrap();
    assert!(peak > 10.0 && beyond <= 10.0, "peak {peak} N, less the friction bound {beyond} N");
    assert!(bound > 1.0 && bound < 10.0, "friction bound at the peak {bound} N");
    assert!(s.get("static_force_n").unwrap() < 8.0, "friction holds the static force below 80 % of the limit");
}

/// The mug: both faces peak at 23.3 N against the 20 N limit; the friction bound there is 8.1 N.
#[test]
fn clean_mug_keeps_the_force_within_the_limit_plus_the_friction_bound() {
    let outcome = clean_mug::simulate(&realistic()).unwrap();
    let s = &outcome.summary;
    assert!(s.failed_claims().is_empty(), "failed: {:?}", s.failed_claims());
    let (peak, beyond) = (s.get("run_peak_force_n").unwrap(), s.get("run_peak_beyond_friction_n").unwrap());
    assert!(peak > 20.0 && beyond <= 20.0, "peak {peak} N, less the friction bound {beyond} N");
}

/// The floor: friction holds the arms up (its share −6…−7 N against the 9.5 N the limiter lets
/// the spring press with), so the brooms touch 1.4 s after the references came to rest below the
/// surface; the planner waits for it (the controller's TCP error) and sweeps after it: static
/// force 9.45 N and 9.26 N, both ends touched in every cycle of the sweep.
#[test]
fn sweep_floor_waits_for_the_brooms_to_touch_on_the_realistic_plant() {
    let outcome = sweep_floor::simulate(&realistic()).unwrap();
    let s = &outcome.summary;
    assert!(s.failed_claims().is_empty(), "failed: {:?}", s.failed_claims());
    assert!(s.get("run_peak_beyond_friction_n").unwrap() <= 10.0);
    let waited = s.get("contact_wait_s").unwrap();
    assert!(waited > 1.0 && waited < sweep_floor::CONTACT_TIMEOUT_S, "waited {waited} s");
    let touch = s.get("surface_right_first_touch_s").unwrap();
    assert!(touch > sweep_floor::WAIT_AT_S && touch < sweep_floor::WAIT_AT_S + waited + 0.3, "touch {touch} s");
    assert!(s.get("static_force_n").unwrap() > 8.0, "the brooms press when the sweep starts");
    assert!(s.get("surface_left_contact_share").unwrap() > 0.99);
}

/// pHRI: with the threshold above the sensors' noise floor (8 + 15.1 Nm) the flag is set in
/// 97 % and 96 % of the pushes and never at rest (the residual's noise peaks at 15.1 Nm).
#[test]
fn wbc_phri_flags_the_pushes_above_the_noise_floor() {
    let outcome = wbc_phri::simulate(&realistic()).unwrap();
    let s = &outcome.summary;
    assert!(s.failed_claims().is_empty(), "failed: {:?}", s.failed_claims());
    let threshold = s.get("contact_threshold_nm").unwrap();
    assert!((threshold - 23.1).abs() < 0.1, "{threshold}");
    assert!(s.get("push0_contact_share").unwrap() > 0.9 && s.get("push1_contact_share").unwrap() > 0.9);
}
