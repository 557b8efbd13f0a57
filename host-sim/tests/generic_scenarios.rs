//! The generic scenarios (issue 15, item 4): `reach`, `posture_push`, `self_collision` and
//! `limits` on the Panda, on TIAGo++ and on Justin (its full controller: platform, torso,
//! two arms), with the controller in f64 and in f32, on the gains of each robot's `config.toml`;
//! `--robot` refused by the scenarios that run their own robot.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]

use host_sim::generic::{limits, posture_push, reach, self_collision, RobotName};
use host_sim::scalar::Scalar;
use host_sim::scenarios::{run, RunOptions};

/// The translational stiffness of the robot's `config.toml`, read at test time: the rig runs the
/// compiled file, so an edited value changes the run after a rebuild with no Rust edit (and this
/// test, which compiles nothing of the file, still compares the two).
fn file_stiffness(robot: RobotName) -> f64 {
    let path = format!("{}/../fixtures/robots/{}/config.toml", env!("CARGO_MANIFEST_DIR"), robot.name());
    robot_config::load(std::path::Path::new(&path)).unwrap().cartesian.translational_stiffness.0
}

/// Runs `reach` and checks its numbers: the rig's Cartesian stiffness is the file's (rounded to
/// `f32` for the `f32` controller), every claim holds, the static deflection is `F/K` within 5 %
/// (the claim's tolerance), the settling time is below the 1 s bound and above 0.1 s (a 1.5 Hz
/// impedance cannot be faster), no fault and no NaN.
fn reach_holds(robot: RobotName, scalar: Scalar) {
    let options = RunOptions { robot: Some(robot), scalar, ..RunOptions::default() };
    let outcome = reach::simulate(&options).unwrap();
    let summary = &outcome.summary;
    let file = file_stiffness(robot);
    let expected = if scalar == Scalar::F32 { f64::from(file as f32) } else { file };
    assert_eq!(summary.get("translational_stiffness_n_m"), Some(expected), "{robot:?}");
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
/// 1.3 × the projected push + 1 mm (measured: Panda 0.33 mm for 0.48 mm predicted, TIAGo++
/// 3.05 mm for 3.09 mm, Justin 13.90 mm for 15.44 mm), and the elbow moves farther than the TCP.
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
/// and with it every pair stays above `min_distance` (measured: Panda 29.8 mm, TIAGo++ 21.7 mm,
/// Justin 30.4 mm), the TCPs stop at least `min_shortfall` short (Panda 136.8 mm, TIAGo++ 49.0 mm,
/// Justin 70.0 mm per hand), the torques stay within their limits, no fault.
fn self_collision_holds(robot: RobotName, scalar: Scalar, min_distance: f64, min_shortfall: f64) {
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
    let shortfall = summary.get("shortfall_m").unwrap();
    assert!(shortfall > min_shortfall, "{shortfall} m");
    assert!(summary.get("largest_torque_ratio").unwrap() <= 1.0);
    assert_eq!(summary.get("faulty_cycles"), Some(0.0));
    assert_eq!(summary.get("non_finite_cycles"), Some(0.0));
    assert_eq!(outcome.series.rows().len(), 4000);
}

#[test]
fn self_collision_holds_on_the_panda_in_f64_and_f32() {
    self_collision_holds(RobotName::Panda, Scalar::F64, 0.025, 0.1);
    self_collision_holds(RobotName::Panda, Scalar::F32, 0.025, 0.1);
}

#[test]
fn self_collision_holds_on_tiago_dual_in_f64_and_f32() {
    self_collision_holds(RobotName::TiagoDual, Scalar::F64, 0.018, 0.04);
    self_collision_holds(RobotName::TiagoDual, Scalar::F32, 0.018, 0.04);
}

/// `self_collision` on Justin with his own collision model (`fixtures::justin::collision`, the
/// floor included) and the full controller (platform, torso, two arms): the hands meet 0.12 m
/// ahead of their midpoint; the fingers stay 30.4 mm apart (f64 and f32; reference −100.0 mm,
/// the cores touching), each hand stops 70.0 mm short for the 65.5 mm of
/// `(d_end − d_ref) / 2` (× 1.07), largest |τ|/τ_max 0.22.
#[test]
fn self_collision_holds_on_justin_in_f64_and_f32() {
    self_collision_holds(RobotName::Justin, Scalar::F64, 0.025, 0.05);
    self_collision_holds(RobotName::Justin, Scalar::F32, 0.025, 0.05);
}

/// `reach` on Justin: the full controller (platform admittance, torso, both arms) on Justin's
/// file (K = 500 N/m). The push is vertical, which the planar base cannot take up (`J_rᵀ F = 0`),
/// so the Cartesian spring alone carries it at rest: 39.95 mm for F/K = 40 mm (f64 and f32).
#[test]
fn reach_holds_on_justin_in_f64() {
    reach_holds(RobotName::Justin, Scalar::F64);
}

#[test]
fn reach_holds_on_justin_in_f32() {
    reach_holds(RobotName::Justin, Scalar::F32);
}

#[test]
fn posture_push_holds_on_justin_in_f64_and_f32() {
    posture_push_holds(RobotName::Justin, Scalar::F64);
    posture_push_holds(RobotName::Justin, Scalar::F32);
}

/// Runs `limits` and checks its numbers: every claim holds; every joint stays clear of its stops
/// (measured: Panda 0.367 rad, f32 0.340; TIAGo++ 1.3 mrad, arm joint 2), every speed below its
/// limit (Panda 0.88, TIAGo++ 0.91) and every torque (Panda 0.50, f32 0.58; TIAGo++ 0.60); the TCP
/// ends between the nearest point within the joint ranges and the nearest where no avoidance acts
/// with the hand's home orientation held (Panda 643.5 mm from the goal, f32 644.5, for
/// [642.2, 1035.9] mm; TIAGo++ 1074.8 mm for [995.7, 1128.8] mm; Justin 1087.3 mm for
/// [786.9, 1379.1] mm, f32 [786.9, 1378.5]), the goal is at least 0.5 m out of reach (by the
/// scenario's rule), no fault, no NaN.
fn limits_holds(robot: RobotName, scalar: Scalar) {
    let options = RunOptions { robot: Some(robot), scalar, ..RunOptions::default() };
    let outcome = limits::simulate(&options).unwrap();
    let summary = &outcome.summary;
    assert!(summary.failed_claims().is_empty(), "{:?}", summary.failed_claims());
    assert_eq!(summary.passed_claims().len(), 6);
    assert!(summary.get("stop_clearance_rad").unwrap() >= 0.0);
    assert!(summary.get("largest_velocity_ratio").unwrap() <= 1.0);
    assert!(summary.get("largest_torque_ratio").unwrap() <= 1.0);
    let (low, high) = (summary.get("nearest_in_range_m").unwrap(), summary.get("nearest_unguarded_m").unwrap());
    assert!(low > 0.5 && low <= high, "the goal is not out of reach: [{low}, {high}] m");
    let distance = summary.get("final_goal_distance_m").unwrap();
    assert!(distance >= low - 1e-3 && distance <= high + 1e-3, "{distance} m for [{low}, {high}] m");
    assert!(summary.get("settling_time_s").unwrap() <= summary.get("settling_bound_s").unwrap());
    assert_eq!(summary.get("faulty_cycles"), Some(0.0));
    assert_eq!(summary.get("non_finite_cycles"), Some(0.0));
    assert_eq!(outcome.series.rows().len(), 5000);
}

#[test]
fn limits_holds_on_the_panda_in_f64_and_f32() {
    limits_holds(RobotName::Panda, Scalar::F64);
    limits_holds(RobotName::Panda, Scalar::F32);
}

#[test]
fn limits_holds_on_tiago_dual_in_f64_and_f32() {
    limits_holds(RobotName::TiagoDual, Scalar::F64);
    limits_holds(RobotName::TiagoDual, Scalar::F32);
}

/// Justin with the end stops on top, the pull capped at K × 0.5 m = 250 N and the platform held.
#[test]
fn limits_holds_on_justin_in_f64_and_f32() {
    limits_holds(RobotName::Justin, Scalar::F64);
    limits_holds(RobotName::Justin, Scalar::F32);
}

#[test]
fn scenarios_with_their_own_robot_refuse_robot() {
    let options = RunOptions { robot: Some(RobotName::TiagoDual), ..RunOptions::default() };
    let error = run("wbc_step", &options).unwrap_err();
    assert!(error.starts_with("--robot tiago_dual: wbc_step runs its own robot"), "{error}");
    assert!(error.contains("reach"), "{error}");
}
