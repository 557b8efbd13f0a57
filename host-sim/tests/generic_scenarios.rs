//! The generic scenarios on the imported robots (issue 15, item 4): `reach`, `posture_push` and
//! `self_collision` on the Panda and on TIAGo++, with the controller in f64 and in f32; the gain
//! rule; `--robot` refused by the scenarios that run their own robot.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]

use host_sim::generic::{
    self, posture_push, reach, self_collision, RobotName, CARTESIAN_FREQUENCY_RAD_S, PANDA, TIAGO_DUAL,
};
use host_sim::scalar::Scalar;
use host_sim::scenarios::{run, RunOptions};

/// Runs `reach` and checks its numbers: every claim holds, the static deflection is `F/K` within
/// 5 % (the claim's tolerance), the settling time is below the 1 s bound and above 0.1 s (a
/// 1.5 Hz impedance cannot be faster), no fault and no NaN.
fn reach_holds(robot: RobotName, scalar: Scalar) {
    let options = RunOptions { robot: Some(robot), scalar, ..RunOptions::default() };
    let outcome = reach::simulate(&options).unwrap();
    let summary = &outcome.summary;
    assert!(summary.failed_claims().is_empty(), "{:?}", summary.failed_claims());
    assert_eq!(summary.passed_claims().len(), 4);
    let predicted = summary.get("predicted_deflection_m").unwrap();
    let deflection = summary.get("deflection_m").unwrap();
    assert!((deflection - predicted).abs() < 0.05 * predicted, "{deflection} m vs F/K {predicted} m");
    let settling = summary.get("settling_time_s").unwrap();
    assert!((0.1..=1.0).contains(&settling), "{settling} s");
    assert_eq!(summary.get("faulty_cycles"), Some(0.0));
    assert_eq!(summary.get("non_finite_cycles"), Some(0.0));
    assert_eq!(outcome.series.rows().len(), 4000);
}

#[test]
fn reach_holds_on_the_panda_in_f64() {
    reach_holds(RobotName::Panda, Scalar::F64);
}

#[test]
fn reach_holds_on_the_panda_in_f32() {
    reach_holds(RobotName::Panda, Scalar::F32);
}

#[test]
fn reach_holds_on_tiago_dual_in_f64() {
    reach_holds(RobotName::TiagoDual, Scalar::F64);
}

#[test]
fn reach_holds_on_tiago_dual_in_f32() {
    reach_holds(RobotName::TiagoDual, Scalar::F32);
}

/// Runs `posture_push` and checks its numbers: every claim holds, the TCP error stays within
/// 1.3 × the projected push + 1 mm (measured: Panda 0.34 mm for 0.49 mm predicted, TIAGo++
/// 5.4 mm for 6.4 mm), and the elbow moves farther than the TCP.
fn posture_push_holds(robot: RobotName, scalar: Scalar) {
    let options = RunOptions { robot: Some(robot), scalar, ..RunOptions::default() };
    let summary = posture_push::simulate(&options).unwrap().summary;
    assert!(summary.failed_claims().is_empty(), "{:?}", summary.failed_claims());
    assert_eq!(summary.passed_claims().len(), 3);
    let predicted = summary.get("predicted_tcp_deflection_m").unwrap();
    let tcp = summary.get("largest_tcp_error_m").unwrap();
    assert!(predicted > 1e-4 && tcp <= 1.3 * predicted + 1e-3, "{tcp} m vs {predicted} m");
    assert!(summary.get("elbow_motion_m").unwrap() > tcp);
}

#[test]
fn posture_push_holds_on_the_panda_in_f64_and_f32() {
    posture_push_holds(RobotName::Panda, Scalar::F64);
    posture_push_holds(RobotName::Panda, Scalar::F32);
}

#[test]
fn posture_push_holds_on_tiago_dual_in_f64_and_f32() {
    posture_push_holds(RobotName::TiagoDual, Scalar::F64);
    posture_push_holds(RobotName::TiagoDual, Scalar::F32);
}

/// Runs `self_collision` and checks its numbers: every claim holds; the goals collide without the
/// avoidance (the reference interpenetrates by more than 5 cm and reaches its goals within 25 mm)
/// and with it every pair stays above `min_distance` (measured: Panda 29.2 mm, TIAGo++ 15.7 mm),
/// the TCPs stop at least 10 cm short (Panda 136 mm, TIAGo++ 273 mm), the torques stay within
/// their limits, no fault.
fn self_collision_holds(robot: RobotName, scalar: Scalar, min_distance: f64) {
    let options = RunOptions { robot: Some(robot), scalar, ..RunOptions::default() };
    let outcome = self_collision::simulate(&options).unwrap();
    let summary = &outcome.summary;
    assert!(summary.failed_claims().is_empty(), "{:?}", summary.failed_claims());
    assert_eq!(summary.passed_claims().len(), 4);
    let reference = summary.get("reference_smallest_distance_m").unwrap();
    assert!(reference < -0.05, "the goals do not collide without avoidance: {reference} m");
    assert!(summary.get("reference_shortfall_m").unwrap() < 0.025);
    let smallest = summary.get("smallest_distance_m").unwrap();
    assert!(smallest > min_distance, "{smallest} m");
    assert!(summary.get("shortfall_m").unwrap() > 0.1);
    assert!(summary.get("largest_torque_ratio").unwrap() <= 1.0);
    assert_eq!(summary.get("faulty_cycles"), Some(0.0));
    assert_eq!(summary.get("non_finite_cycles"), Some(0.0));
    assert_eq!(outcome.series.rows().len(), 4000);
}

#[test]
fn self_collision_holds_on_the_panda_in_f64_and_f32() {
    self_collision_holds(RobotName::Panda, Scalar::F64, 0.025);
    self_collision_holds(RobotName::Panda, Scalar::F32, 0.025);
}

#[test]
fn self_collision_holds_on_tiago_dual_in_f64_and_f32() {
    self_collision_holds(RobotName::TiagoDual, Scalar::F64, 0.012);
    self_collision_holds(RobotName::TiagoDual, Scalar::F32, 0.012);
}

/// The gain rule gives the heaviest TCP direction the natural frequency `ω_c`: `K / λ_max = ω_c²`
/// within the range of a 7-DOF arm's reflected inertias (measured: the Panda's K = 451.25 N/m),
/// and every joint damping is positive.
#[test]
fn the_gain_rule_scales_the_stiffness_with_the_reflected_inertia() {
    let panda = generic::gains(&PANDA, &fixtures::robots::panda::model::<f64>().unwrap()).unwrap();
    let tiago = generic::gains(&TIAGO_DUAL, &fixtures::robots::tiago_dual::model::<f64>().unwrap()).unwrap();
    let w2 = CARTESIAN_FREQUENCY_RAD_S * CARTESIAN_FREQUENCY_RAD_S;
    for k in panda.translational_stiffness.iter().chain(&tiago.translational_stiffness) {
        // Reflected inertias of a 7-DOF arm's TCP: between 0.5 and 20 kg.
        assert!((0.5 * w2..20.0 * w2).contains(k), "{k} N/m");
    }
    // The same joint values on both TIAGo++ arms give nearly mirrored postures: 356.6 and 354.6 N/m.
    let [left, right] = tiago.translational_stiffness;
    assert!((left - right).abs() < 0.02 * left, "{left} vs {right} N/m");
    assert!((panda.translational_stiffness[0] - 451.25).abs() < 0.1, "{:?}", panda.translational_stiffness);
    assert!(panda.joint_damping.iter().chain(&tiago.joint_damping).all(|d| *d > 0.0));
}

#[test]
fn scenarios_with_their_own_robot_refuse_robot() {
    let options = RunOptions { robot: Some(RobotName::TiagoDual), ..RunOptions::default() };
    let error = run("wbc_step", &options).unwrap_err();
    assert!(error.starts_with("--robot tiago_dual: wbc_step runs its own robot"), "{error}");
    assert!(error.contains("reach"), "{error}");
}
