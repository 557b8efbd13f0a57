//! The simulated robot (`host_sim::sim`), the loop-proving controller and their scenarios.
//!
//! - The integrator is checked independently of the kernel's own tests: energy conservation of
//!   the unforced planar 4-DOF arm of Fig. 4.1 and the period of a pendulum against the
//!   analytic value.
//! - The kinematic base follows its velocity command with the configured first-order lag.
//! - Torque commands are clamped at the effort limits, and bad commands trigger the documented
//!   safe reactions.
//! - The Cartesian impedance controller drives a TCP step of the Justin-like robot to steady
//!   state through the `hal` traits.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    reason = "test code: a failure is a test failure"
)]

use hal::{CycleClock, Error as _, ErrorKind, JointTorqueInterface, PlatformCommand, PlatformVelocityInterface, LEGS};
use host_sim::scenarios::{cartesian_step, energy_planar4, RunOptions};
use host_sim::sim::{run_loop, SimConfig, SimError, Simulator, CONTROL_PERIOD_S};
use kernel::model::{Inertia, JointDrive, JointKind, JointLimits, ModelBuilder, Placement};
use kernel::Model;
use nalgebra::{SVector, Unit, Vector3};

/// A 1 m mathematical pendulum: 1 kg point mass, revolute joint about world y, hanging along −z.
fn pendulum(length: f64) -> Model<f64, 1, 1, 1> {
    let mut b = ModelBuilder::<f64, 1, 1, 1>::new(Vector3::new(0.0, 0.0, -9.81));
    let link = b
        .add_body(
            None,
            Placement::identity(),
            JointKind::Revolute { axis: Unit::new_normalize(Vector3::y()) },
            JointDrive::actuated(0),
            Inertia::point_mass(1.0, Vector3::new(0.0, 0.0, -length)),
        )
        .unwrap();
    b.add_frame(Some(link), Placement::translation(0.0, 0.0, -length)).unwrap();
    b.try_build().unwrap()
}

/// A planar base (x, y prismatic, θ about z) carrying a two-link arm pitching about y, with
/// effort limits 5 Nm and 3 Nm on the arm joints. `N = 5`, `U = 2`.
fn mobile_arm() -> Model<f64, 5, 5, 2> {
    let mut b = ModelBuilder::<f64, 5, 5, 2>::new(Vector3::new(0.0, 0.0, -9.81));
    let axis = |v: Vector3<f64>| Unit::new_normalize(v);
    let x = b
        .add_body(
            None,
            Placement::identity(),
            JointKind::Prismatic { axis: axis(Vector3::x()) },
            JointDrive::actuated(0),
            Inertia::point_mass(10.0, Vector3::zeros()),
        )
        .unwrap();
    let y = b
        .add_body(
            Some(x),
            Placement::identity(),
            JointKind::Prismatic { axis: axis(Vector3::y()) },
            JointDrive::actuated(1),
            Inertia::point_mass(10.0, Vector3::zeros()),
        )
        .unwrap();
    let rotational = nalgebra::Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 2.0));
    let theta = b
        .add_body(
            Some(y),
            Placement::identity(),
            JointKind::Revolute { axis: axis(Vector3::z()) },
            JointDrive::actuated(2),
            Inertia { mass: 50.0, com: Vector3::zeros(), rotational },
        )
        .unwrap();
    let link1 = b
        .add_body(
            Some(theta),
            Placement::translation(0.2, 0.0, 0.8),
            JointKind::Revolute { axis: axis(Vector3::y()) },
            JointDrive::actuated(3),
            Inertia::point_mass(2.0, Vector3::new(0.0, 0.0, 0.2)),
        )
        .unwrap();
    let link2 = b
        .add_body(
            Some(link1),
            Placement::translation(0.0, 0.0, 0.4),
            JointKind::Revolute { axis: axis(Vector3::y()) },
            JointDrive::actuated(4),
            Inertia::point_mass(1.0, Vector3::new(0.0, 0.0, 0.2)),
        )
        .unwrap();
    b.add_frame(Some(link2), Placement::translation(0.0, 0.0, 0.4)).unwrap();
    b.add_frame(Some(link1), Placement::translation(0.0, 0.0, 0.4)).unwrap();
    let mut limits = JointLimits::unlimited();
    limits.effort[3] = 5.0;
    limits.effort[4] = 3.0;
    b.limits(limits);
    b.try_build().unwrap()
}

#[test]
fn planar4_energy_is_conserved_without_input() {
    let outcome = energy_planar4::simulate(&RunOptions::default()).unwrap();
    let drift = outcome.summary.get("energy_drift_rel").unwrap();
    let duration = outcome.summary.get("duration_s").unwrap();
    println!("energy_planar4: relative drift {drift:.3e} over {duration} s");
    assert!((duration - 10.0).abs() < 1e-9);
    assert!(drift < 1e-6, "relative energy drift {drift:e}");
    assert!(outcome.summary.failed_claims().is_empty(), "{:?}", outcome.summary.failed_claims());
    // The arm really moved: a drift bound on a resting arm would prove nothing.
    assert!(outcome.summary.get("energy_scale_j").unwrap() > 10.0);
}

#[test]
fn pendulum_period_matches_the_analytic_period() {
    // Small amplitude θ₀ = 0.01 rad: the small-angle period 2π√(l/g) is exact to θ₀²/16 =
    // 6.25e-6; with the first amplitude correction it is exact to 11θ₀⁴/3072 ≈ 4e-11.
    let (length, g, theta0) = (1.0, 9.81, 0.01);
    let mut sim = Simulator::<1, 1, 1, 1>::new(pendulum(length), SimConfig::default()).unwrap();
    sim.set_state(SVector::from([theta0]), SVector::zeros()).unwrap();
    let small_angle = 2.0 * std::f64::consts::PI * (length / g).sqrt();
    let mut crossings = Vec::new();
    let mut previous = (0.0, theta0);
    while sim.time_s() < 5.5 * small_angle {
        sim.step().unwrap();
        let now = (sim.time_s(), sim.q()[0]);
        if previous.1 < 0.0 && now.1 >= 0.0 {
            // Linear interpolation of the upward zero crossing (q is nearly linear there).
            crossings.push(previous.0 + (now.0 - previous.0) * previous.1 / (previous.1 - now.1));
        }
        previous = now;
    }
    assert_eq!(crossings.len(), 5);
    let period = (crossings[4] - crossings[0]) / 4.0;
    let corrected = small_angle * (1.0 + theta0 * theta0 / 16.0);
    println!("pendulum: period {period:.9} s, small-angle {small_angle:.9} s, corrected {corrected:.9} s");
    assert!((period / small_angle - 1.0).abs() < 1e-5, "small-angle period within 1e-5");
    assert!((period / corrected - 1.0).abs() < 1e-8, "amplitude-corrected period within 1e-8");
}

#[test]
fn base_velocity_follows_the_command_with_the_configured_lag() {
    let lag = 0.1;
    let config = SimConfig { base_lag_s: lag, ..SimConfig::default() };
    let mut sim = Simulator::<5, 5, 2, 2>::new(mobile_arm(), config).unwrap();
    let desired = [0.2, -0.1, 0.3];
    sim.write_velocity(&PlatformCommand { velocity: desired, leg_rates: [0.05, 0.0, -0.05, 2.0] }).unwrap();
    // The arm swings under zero torque; the base motion must not care.
    let report = run_loop(&mut sim, lag, CONTROL_PERIOD_S, |_, _| Ok::<(), SimError>(())).unwrap();
    assert_eq!((report.control_cycles, report.physics_steps), (100, 600));
    let sample = PlatformVelocityInterface::read(&mut sim).unwrap();
    let expected = 1.0 - (-1.0_f64).exp();
    for (v, d) in sample.velocity.iter().zip(desired) {
        let ratio = v / d;
        assert!((ratio - 0.632).abs() < 0.01, "first-order response at t = T: {ratio}");
        assert!((ratio - expected).abs() < 1e-9, "closed-form lag: {ratio} vs {expected}");
    }
    // r(T) = ṙ_des (T − T (1 − e⁻¹)) = ṙ_des T e⁻¹.
    for (r, d) in sample.pose.iter().zip(desired) {
        assert!((r - d * lag * (-1.0_f64).exp()).abs() < 1e-12);
    }
    // Legs integrate their rates and stop at the end stops.
    let nominal = SimConfig::default().initial_leg_length_m;
    assert!((sample.leg_lengths[0] - (nominal + 0.05 * lag)).abs() < 1e-12);
    assert!((sample.leg_lengths[2] - (nominal - 0.05 * lag)).abs() < 1e-12);
    assert_eq!(sample.leg_lengths[3], SimConfig::default().leg_length_max_m);
    assert_eq!(sim.now().unwrap(), 100_000, "clock in µs of simulated time");

    // Without lag the base velocity is the command from the first step on.
    let mut ideal = Simulator::<5, 5, 2, 2>::new(mobile_arm(), SimConfig::default()).unwrap();
    ideal.write_velocity(&PlatformCommand { velocity: desired, leg_rates: [0.0; LEGS] }).unwrap();
    ideal.step().unwrap();
    let sample = PlatformVelocityInterface::read(&mut ideal).unwrap();
    assert_eq!(sample.velocity, desired);
    assert_eq!(sample.cycle, 1);
}

#[test]
fn torque_commands_saturate_at_the_effort_limits() {
    let mut sim = Simulator::<5, 5, 2, 2>::new(mobile_arm(), SimConfig::default()).unwrap();
    JointTorqueInterface::write_torque(&mut sim, &[100.0, -100.0]).unwrap();
    assert!(sim.torque_saturated());
    assert_eq!(JointTorqueInterface::read(&mut sim).unwrap().torque, [5.0, -3.0]);
    assert!(sim.step().unwrap().torque_saturated);
    // The applied torque never exceeds the limits during a loop with an aggressive command.
    let report = run_loop(&mut sim, 0.05, CONTROL_PERIOD_S, |sim, _| {
        let sample = JointTorqueInterface::read(sim)?;
        assert!(sample.torque[0].abs() <= 5.0 && sample.torque[1].abs() <= 3.0);
        JointTorqueInterface::write_torque(sim, &[-1e4 * sample.velocity[0], 80.0])
    })
    .unwrap();
    assert_eq!(report.saturated_steps, report.physics_steps);
    JointTorqueInterface::write_torque(&mut sim, &[1.0, -2.0]).unwrap();
    assert!(!sim.torque_saturated());
    assert!(!sim.step().unwrap().torque_saturated);
}

#[test]
fn non_finite_commands_are_refused_with_the_safe_reaction() {
    let mut sim = Simulator::<5, 5, 2, 2>::new(mobile_arm(), SimConfig::default()).unwrap();
    sim.set_state(SVector::from([0.0, 0.0, 0.0, 0.3, -0.2]), SVector::from([0.0, 0.0, 0.0, 1.0, 0.5])).unwrap();
    let error = JointTorqueInterface::write_torque(&mut sim, &[f64::NAN, 0.0]).unwrap_err();
    assert_eq!(error.kind(), ErrorKind::OutOfRange);
    assert!(sim.brakes_engaged());
    sim.advance(0.1).unwrap();
    let sample = JointTorqueInterface::read(&mut sim).unwrap();
    assert_eq!(sample.position, [0.3, -0.2], "brakes hold the arm");
    assert_eq!(sample.velocity, [0.0, 0.0]);
    JointTorqueInterface::write_torque(&mut sim, &[0.0, 0.0]).unwrap();
    assert!(!sim.brakes_engaged(), "a valid command releases the brakes");

    sim.write_velocity(&PlatformCommand { velocity: [0.1, 0.0, 0.0], leg_rates: [0.0; LEGS] }).unwrap();
    let error = sim.write_velocity(&PlatformCommand { velocity: [f64::INFINITY, 0.0, 0.0], leg_rates: [0.0; LEGS] });
    assert_eq!(error.map_err(|e| e.kind()), Err(ErrorKind::OutOfRange));
    sim.step().unwrap();
    assert_eq!(PlatformVelocityInterface::read(&mut sim).unwrap().velocity, [0.0; 3], "the base stops");

    // A robot without a base refuses a base velocity but accepts standing still.
    let mut fixed = Simulator::<1, 1, 1, 1>::new(pendulum(1.0), SimConfig::default()).unwrap();
    let moving = PlatformCommand { velocity: [0.1, 0.0, 0.0], leg_rates: [0.0; LEGS] };
    assert_eq!(fixed.write_velocity(&moving), Err(SimError::FixedBase));
    assert!(fixed.write_velocity(&PlatformCommand { velocity: [0.0; 3], leg_rates: [0.0; LEGS] }).is_ok());
    // Dimensions are checked: 5 coordinates cannot be 0 or 3 base coordinates plus 1.
    assert!(matches!(
        Simulator::<5, 5, 2, 1>::new(mobile_arm(), SimConfig::default()),
        Err(SimError::InvalidDimensions { .. })
    ));
}

#[test]
fn cartesian_impedance_steps_the_justin_tcp_to_steady_state() {
    let outcome = cartesian_step::simulate(&RunOptions::default()).unwrap();
    let s = &outcome.summary;
    let (settle, final_error) = (s.get("settle_time_s").unwrap(), s.get("final_error_m").unwrap());
    println!(
        "cartesian_step: settle {settle:.3} s, error before push {:.2} mm, push deflection {:.1} mm, recovery {:.3} s, final {:.2} mm, max tau ratio {:.2}",
        s.get("error_before_push_m").unwrap() * 1e3,
        s.get("max_push_deflection_m").unwrap() * 1e3,
        s.get("recovery_time_s").unwrap(),
        final_error * 1e3,
        s.get("max_tau_ratio").unwrap(),
    );
    assert!(final_error < 5e-3, "final TCP error {final_error} m");
    assert!(settle <= 1.5, "settle time {settle} s");
    assert!(s.get("max_push_deflection_m").unwrap() > 5e-3, "the push must visibly deflect the TCP");
    assert!(outcome.series.rows().iter().flatten().all(|x| x.is_finite()), "no NaN");
    assert!(s.failed_claims().is_empty(), "{:?}", s.failed_claims());
}
