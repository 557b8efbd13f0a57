//! The mobile platform (Sec. 3.2 and 5.1): the scenarios `stability_map`, `mobile_impedance`,
//! `mobile_impedance_critical` and `icr_avoidance` reproduce the claims of Fig. 5.3, 5.5/5.6,
//! 5.9/5.10 and 3.11–3.13; independent checks of the stability map against the characteristic
//! polynomials and of the Justin experiments against a continuous-time linearisation; no NaN for
//! any base twist (proptest).

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    reason = "test code: a failure is a test failure"
)]

use fixtures::justin::{self, N, RIGHT_TCP, UPPER_DOF};
use hal::{PlatformSample, LEGS};
use host_sim::scenarios::{icr_avoidance, mobile_impedance, mobile_impedance_critical, stability_map, RunOptions};
use host_sim::wheels::{WheelConfig, Wheels};
use kernel::dynamics::{coriolis_matrix, crba, forward_kinematics, gravity, rnea};
use kernel::platform::admittance::{Admittance, AdmittanceConfig};
use kernel::platform::avoidance::{PlatformAvoidance, PlatformReference};
use kernel::platform::coupling_compensation::{coupling_compensation, CompensationSwitch};
use kernel::platform::icr::{instantaneous_center, sap_jacobian, BaseTwist, IcrRepulsion};
use kernel::tasks::cartesian_impedance::{
    cartesian_impedance, AxisMask, CartesianImpedance, CartesianImpedanceConfig, CartesianTarget, StiffnessFrame,
};
use kernel::tasks::TaskRows;
use kernel::Data;
use nalgebra::{Cholesky, DMatrix, DVector, Matrix3, SVector, Vector3, Vector6};
use proptest::prelude::*;

fn assert_claims(outcome: &host_sim::scenarios::Outcome) {
    let failed = outcome.summary.failed_claims();
    assert!(failed.is_empty(), "failed claims: {failed:#?}");
    for claim in outcome.summary.passed_claims() {
        eprintln!("pass: {claim}");
    }
}

fn metric(outcome: &host_sim::scenarios::Outcome, name: &str) -> f64 {
    outcome.summary.get(name).expect("metric recorded")
}

// ---------------------------------------------------------------------------------------------
// Fig. 5.3: the stability map.

/// Largest real part of the roots of `c₀ + c₁ s + … + c₄ s⁴` (companion matrix).
fn max_real_root(c: [f64; 5]) -> f64 {
    let mut companion = DMatrix::zeros(4, 4);
    for k in 0..3 {
        companion[(k + 1, k)] = 1.0;
    }
    for k in 0..4 {
        companion[(k, 3)] = -c[k] / c[4];
    }
    companion.complex_eigenvalues().iter().map(|l| l.re).fold(f64::NEG_INFINITY, f64::max)
}

/// The closed-loop poles assembled from the kernel (fixture, admittance, compensation) agree
/// with the roots of the characteristic polynomials derived by hand in THESIS-NUMBERS §4.2:
/// uncompensated `s² [(m s + d)(s³ + 3s² + 2s + 2) + 1]`, compensated
/// `s² [(m s + d)(s³ + 3s² + 2s + 2) + s² + 3s + 1]` (the `s²` is the double pole at 0).
#[test]
fn stability_map_agrees_with_the_characteristic_polynomials() {
    let points = stability_map::grid(0.05).unwrap();
    assert_eq!(points.len(), 30 * 20);
    let mut worst: f64 = 0.0;
    for p in &points {
        let (m, d) = (p.m_adm, p.d_adm);
        // (m s + d)(s³ + 3s² + 2s + 2) = m s⁴ + (3m + d) s³ + (2m + 3d) s² + (2m + 2d) s + 2d.
        let base = [2.0 * d, 2.0 * m + 2.0 * d, 2.0 * m + 3.0 * d, 3.0 * m + d, m];
        let uncompensated = [base[0] + 1.0, base[1], base[2], base[3], base[4]];
        let compensated = [base[0] + 1.0, base[1] + 3.0, base[2] + 1.0, base[3], base[4]];
        let expected = [max_real_root(uncompensated).max(0.0), max_real_root(compensated).max(0.0)];
        for (got, want) in [p.uncompensated, p.compensated].iter().zip(expected) {
            worst = worst.max((got - want).abs());
            assert!((got - want).abs() < 1e-7, "({m}, {d}): {got} vs {want}");
        }
    }
    eprintln!("stability map vs polynomial roots: worst difference {worst:e}");
    // Sample points of THESIS-NUMBERS §4.2.
    let mut system = stability_map::LinearMobile::new().unwrap();
    let mut off = |m, d| system.max_real_eigenvalue(m, d, CompensationSwitch::OFF).unwrap();
    assert!((off(0.5, 0.2) - 0.0992).abs() < 1e-3);
    assert!((off(1.0, 0.1) - 0.0142).abs() < 1e-3);
    for (m, d) in [(1.2, 0.1), (1.0, 1.0), (0.1, 0.5)] {
        assert!(off(m, d) <= stability_map::STABLE_TOLERANCE, "({m}, {d}) is stable");
    }
}

#[test]
fn stability_map_scenario_has_an_unstable_region_only_without_compensation() {
    let outcome = stability_map::simulate(&RunOptions::default()).unwrap();
    assert_claims(&outcome);
    assert_eq!(outcome.series.columns(), ["m_adm", "d_adm", "max_real_eig_uncompensated", "max_real_eig_compensated"]);
    assert_eq!(outcome.series.rows().len(), 150 * 100);
    // THESIS-NUMBERS §4.2: unstable for roughly m_adm < 1.12 kg and d_adm < 0.507 kg/s.
    assert!((metric(&outcome, "unstable_m_adm_max_kg") - 1.12).abs() < 0.015);
    assert!((metric(&outcome, "unstable_d_adm_max_kg_s") - 0.50).abs() < 0.015);
    assert!(metric(&outcome, "max_real_eig_compensated_per_s") <= stability_map::STABLE_TOLERANCE);
}

// ---------------------------------------------------------------------------------------------
// Fig. 5.5/5.6 and 5.9/5.10 on the Justin-like robot.

#[test]
fn mobile_impedance_energy_decays_with_compensation_and_oscillates_without() {
    let outcome = mobile_impedance::simulate(&RunOptions::default()).unwrap();
    assert_claims(&outcome);
    let settle = |tag: &str| metric(&outcome, &format!("{tag}_energy_settle_forward_s"));
    assert!(settle("on") < settle("off"));
    assert!(metric(&outcome, "on_peak_energy_j") < metric(&outcome, "off_peak_energy_j"));
    assert!(metric(&outcome, "on_final_error_m") < 1e-3);
}

#[test]
fn mobile_impedance_critical_set_is_stable_only_with_compensation() {
    let [on, off] = mobile_impedance_critical::experiments(
        mobile_impedance_critical::DURATION_S,
        host_sim::sim::DEFAULT_PHYSICS_STEP_S,
    );
    let on = mobile_impedance::run(&on, &RunOptions::default(), "ON").unwrap();
    let off = mobile_impedance::run(&off, &RunOptions::default(), "OFF").unwrap();
    let outcome = mobile_impedance_critical::evaluate(&on, &off).unwrap();
    assert_claims(&outcome);
    assert!(off.stopped_at_s.is_some() && on.stopped_at_s.is_none());
    assert!(metric(&outcome, "on_settle_after_push_s") < 2.0);
    // "changing the direction of motion twice per second": the platform reverses repeatedly.
    assert!(outcome.summary.to_json()["off_platform_direction_changes"].as_u64().unwrap() >= 6);
}

/// The same control law in continuous time (plant: the upper body with the base following
/// `ṙ_des` through a first-order lag; controller: (5.10)–(5.15) with the Table 5.2 damping
/// design) linearised by central differences around the home pose: the poles say which
/// experiments are stable, independently of the simulator. With compensation every case is
/// stable; without it the critical admittance is stable for a fast velocity loop and unstable
/// for the scenario's 50 ms lag, while Table 5.2 stays stable.
#[test]
fn linearised_justin_loop_explains_the_critical_experiment() {
    const U: usize = UPPER_DOF;
    const S: usize = 2 * U + 3;
    let model = justin::model::<f64>().unwrap();
    let home = justin::home_configuration::<f64>();
    let mut data = Data::new(&model);
    forward_kinematics(&model, &mut data, &home, &SVector::zeros()).unwrap();
    let target = CartesianTarget::at_rest(data.frame_placements[RIGHT_TCP.0]);
    let task = CartesianImpedance::try_new(CartesianImpedanceConfig {
        frame: RIGHT_TCP,
        axes: AxisMask::ALL,
        stiffness_frame: StiffnessFrame::World,
        translational_stiffness: Matrix3::identity() * 1000.0,
        rotational_stiffness: Matrix3::identity() * 100.0,
        damping_ratio: 0.7,
        force_lower: Vector6::repeat(f64::NEG_INFINITY),
        force_upper: Vector6::repeat(f64::INFINITY),
        fallback_damping: Vector6::repeat(10.0),
    })
    .unwrap();
    // State: upper-body offsets from home, their rates, base x, base ẋ, admittance ṙ_des.
    let derivative = |admittance: &AdmittanceConfig<f64>, switch: CompensationSwitch, lag: f64, x: &DVector<f64>| {
        let settings = mobile_impedance::settings(*admittance, switch).unwrap();
        let (mut q, mut v) = (home, SVector::<f64, N>::zeros());
        for k in 0..U {
            q[3 + k] += x[k];
            v[3 + k] = x[U + k];
        }
        (q[0], v[0]) = (x[2 * U], x[2 * U + 1]);
        let desired_rate = x[2 * U + 2];
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &q, &v).unwrap();
        crba(&model, &mut data);
        coriolis_matrix(&model, &mut data);
        gravity(&model, &mut data);
        let mut task_data = data.clone();
        task_data.v[0] = 0.0;
        let mut rows = TaskRows::<f64, N, 6>::new();
        let report = cartesian_impedance(&model, &task_data, &task, &target, &mut rows).unwrap();
        let spring = task.stiffness() * report.error;
        let (mut tau_task, mut tau_spring) = (SVector::<f64, N>::zeros(), SVector::<f64, N>::zeros());
        for (row, k) in rows.rows().iter().zip(spring.iter()) {
            tau_task += row.jacobian.transpose() * row.force;
            tau_spring -= row.jacobian.transpose() * *k;
        }
        let mut platform = Admittance::try_new(*admittance).unwrap();
        platform.reset(&Vector3::new(desired_rate, 0.0, 0.0)).unwrap();
        let r_dd_adm =
            platform.step(&Vector3::new(tau_spring[0], 0.0, 0.0), &Vector3::zeros(), 1e-3).unwrap().acceleration;
        let compensation = coupling_compensation(&data, &settings.layout, &r_dd_adm).unwrap().torque(switch);
        let (qu, vu) = (q.fixed_rows::<U>(3).into_owned(), v.fixed_rows::<U>(3).into_owned());
        let tau: SVector<f64, U> = tau_task.fixed_rows::<U>(3)
            - (qu - settings.posture).component_mul(&settings.posture_stiffness)
            - vu.component_mul(&settings.posture_damping)
            + compensation.fixed_rows::<U>(3);
        let r_dd = (desired_rate - v[0]) / lag;
        let mut qdd = SVector::<f64, N>::zeros();
        qdd[0] = r_dd;
        let bias = *rnea(&model, &mut data, &qdd).unwrap();
        let m_uu = data.mass_matrix.fixed_view::<U, U>(3, 3).into_owned();
        let a = Cholesky::new(m_uu).unwrap().solve(&(tau - bias.fixed_rows::<U>(3)));
        let mut out = DVector::zeros(S);
        for k in 0..U {
            out[k] = x[U + k];
            out[U + k] = a[k];
        }
        (out[2 * U], out[2 * U + 1], out[2 * U + 2]) = (v[0], r_dd, r_dd_adm.x);
        out
    };
    // Largest real part among the oscillatory poles (the null space adds neutral real poles).
    let max_oscillatory_real_part = |admittance: AdmittanceConfig<f64>, switch, lag| {
        let h = 1e-6;
        let mut a = DMatrix::zeros(S, S);
        for k in 0..S {
            let mut e = DVector::zeros(S);
            e[k] = h;
            a.set_column(
                k,
                &((derivative(&admittance, switch, lag, &e) - derivative(&admittance, switch, lag, &-e)) / (2.0 * h)),
            );
        }
        a.complex_eigenvalues().iter().filter(|l| l.im.abs() > 2.0).map(|l| l.re).fold(f64::NEG_INFINITY, f64::max)
    };
    let (table, critical) = (mobile_impedance::table_5_2_admittance(), mobile_impedance::critical_admittance());
    let lag = mobile_impedance::BASE_LAG_S;
    for (admittance, lag_s) in [(table, 0.005), (table, lag), (critical, 0.005), (critical, lag)] {
        let on = max_oscillatory_real_part(admittance, CompensationSwitch::ON, lag_s);
        assert!(on < -0.5, "compensated: {on}");
    }
    let off = |admittance, lag_s| max_oscillatory_real_part(admittance, CompensationSwitch::OFF, lag_s);
    let (critical_fast, critical_lagged, table_lagged) = (off(critical, 0.005), off(critical, lag), off(table, lag));
    eprintln!("OFF: critical {critical_fast:.3} (5 ms lag), {critical_lagged:.3} ({lag} s lag); Table 5.2 {table_lagged:.3} 1/s");
    assert!(critical_fast < 0.0 && critical_lagged > 0.05 && table_lagged < -0.5);
}

// ---------------------------------------------------------------------------------------------
// Fig. 3.11–3.13: ICR singularity avoidance.

#[test]
fn icr_avoidance_reduces_the_steering_rates_and_legs_reduce_the_deviation() {
    let outcome = icr_avoidance::simulate(&RunOptions::default()).unwrap();
    assert_claims(&outcome);
    assert!(metric(&outcome, "steering_rate_ratio_on_off") < 1.0 / 3.0);
    assert!(metric(&outcome, "on_max_translation_error_m") <= 0.07);
    assert!(metric(&outcome, "on_max_rotation_error_deg") <= 15.0);
    // The leg-motion run holds the same statements itself.
    assert!(metric(&outcome, "steering_rate_ratio_legs_off") < 1.0 / 3.0);
    assert!(metric(&outcome, "legs_peak_misalignment_rad") < 0.05);
    assert!(metric(&outcome, "legs_max_translation_error_m") <= 0.07);
    assert!(metric(&outcome, "legs_max_rotation_error_deg") <= 15.0);
    assert!(metric(&outcome, "legs_translation_error_reduction") > 0.0);
    assert!(metric(&outcome, "legs_rotation_error_reduction") > 0.0);
    // With leg motion the repulsion needed is smaller (Fig. 3.13 bottom).
    assert!(
        metric(&outcome, "wheel2_pass_legs_peak_avoidance_acceleration_rad_s2")
            < metric(&outcome, "wheel2_pass_on_peak_avoidance_acceleration_rad_s2")
    );
}

#[test]
fn quintic_bezier_trajectory_is_c2_and_follows_the_design() {
    let spline = icr_avoidance::nominal_trajectory(&icr_avoidance::DESIGN);
    let h = 1e-6;
    for k in 1..400 {
        let t = f64::from(k) * 0.0563;
        let (a, b, c) = (spline.evaluate(t - h), spline.evaluate(t), spline.evaluate(t + h));
        assert!(((c.pose - a.pose) / (2.0 * h) - b.velocity).amax() < 1e-5, "ṙ at {t}");
        assert!(((c.velocity - a.velocity) / (2.0 * h) - b.acceleration).amax() < 1e-4, "r̈ at {t}");
        // The body twist of the spline is the design's to within the knot interpolation.
        let twist = BaseTwist::from_world(&b.velocity, b.pose.z);
        let (p, omega) = icr_avoidance::design(&icr_avoidance::DESIGN, t);
        assert!((twist.yaw_rate - omega).abs() < 1e-3 && (twist.forward - omega * p.y).abs() < 2e-3, "t = {t}");
    }
    // Continuity across a knot (0.25 s): value, first and second derivative.
    let (l, r) = (spline.evaluate(0.25 * 29.0 - 1e-9), spline.evaluate(0.25 * 29.0 + 1e-9));
    assert!(
        (l.pose - r.pose).amax() < 1e-8
            && (l.velocity - r.velocity).amax() < 1e-7
            && (l.acceleration - r.acceleration).amax() < 1e-6
    );
}

// ---------------------------------------------------------------------------------------------
// No NaN for any base twist (proptest).

/// Twist components: exact zeros, denormal-level values, and ordinary ones.
fn component() -> impl Strategy<Value = f64> {
    prop_oneof![Just(0.0), Just(-0.0), Just(1e-300), Just(-1e-300), Just(1e-9), -3.0..3.0_f64]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn no_nan_for_any_base_twist(
        forward in component(),
        lateral in component(),
        yaw_rate in component(),
        heading in -10.0..10.0_f64,
        legs in proptest::array::uniform4(0.45..0.7_f64),
        on_wheel in proptest::option::of(0..LEGS),
    ) {
        let config = icr_avoidance::avoidance_config(icr_avoidance::Mode::Legs);
        let repulsion = IcrRepulsion::try_new(config.repulsion).unwrap();
        // Optionally place the ICR exactly on a wheel.
        let twist = match on_wheel {
            Some(i) if yaw_rate != 0.0 => {
                let p = repulsion.wheel_positions(&legs)[i];
                BaseTwist { forward: yaw_rate * p.y, lateral: -yaw_rate * p.x, yaw_rate }
            }
            _ => BaseTwist { forward, lateral, yaw_rate },
        };
        let icr = instantaneous_center(&twist, 1e-6);
        prop_assert!(icr.speed.is_finite() && icr.direction.is_finite());
        prop_assert!(icr.position.is_none_or(|p| p.iter().all(|x| x.is_finite())));
        prop_assert!(sap_jacobian(&twist, 1e-6).is_none_or(|j| j.iter().all(|x| x.is_finite())));
        let out = repulsion.repulsion(&twist, &legs).unwrap();
        let values = [out.force, out.potential, out.direction_rate, out.yaw_acceleration];
        prop_assert!(values.iter().chain(out.icr_velocity.iter()).chain(out.body_acceleration.iter()).all(|x| x.is_finite()));

        // The whole loop and the wheels, with the twist as the commanded and measured motion.
        let (s, c) = heading.sin_cos();
        let world = Vector3::new(c * twist.forward - s * twist.lateral, s * twist.forward + c * twist.lateral, twist.yaw_rate);
        let mut avoidance = PlatformAvoidance::try_new(config).unwrap();
        avoidance.reset(&world, &legs).unwrap();
        let pose = Vector3::new(0.3, -0.2, heading);
        let reference = PlatformReference { pose, velocity: world, acceleration: Vector3::zeros() };
        let mut wheels = Wheels::new(WheelConfig::default());
        for _ in 0..3 {
            let step = avoidance.step(&reference, &pose, &world, 1e-3).unwrap();
            prop_assert!(step.velocity.iter().chain(step.leg_rates.iter()).chain(step.acceleration.iter()).all(|x| x.is_finite()));
            let sample = PlatformSample { pose: pose.into(), velocity: world.into(), leg_lengths: step.leg_lengths, cycle: 0 };
            let states = wheels.update(&sample, &step.leg_rates, 1e-3);
            prop_assert!(states.iter().all(|w| [w.required_angle_rad, w.required_rate_rad_s, w.angle_rad, w.misalignment_rad, w.propulsion_rad_s].iter().all(|x| x.is_finite())));
        }

        // The admittance with the twist as force.
        let mut admittance = Admittance::try_new(mobile_impedance::critical_admittance()).unwrap();
        let step = admittance.step(&Vector3::new(forward, lateral, yaw_rate), &Vector3::zeros(), 1e-3).unwrap();
        prop_assert!(step.velocity.iter().chain(step.acceleration.iter()).all(|x| x.is_finite()));
    }
}
