//! `cartesian_step`: the loop-proving controller holds, steps and recovers the right TCP of the
//! Justin-like robot.
//!
//! The robot ([`fixtures::justin`]) starts at rest at its home configuration. The
//! [`CartesianJointImpedance`] controller runs at 1 kHz through the `hal` traits of the
//! [`Simulator`] (RK4 at 1/6000 s, ideal base):
//! - `0 ≤ t < 0.5 s`: hold the right TCP at its home pose;
//! - `t = 0.5 s`: the target jumps [`STEP_M`] = 0.1 m in world +x (orientation unchanged);
//! - `2.5 s ≤ t < 2.7 s`: a [`PUSH_N`] = 20 N world-frame force pushes the right TCP in +y;
//! - `t = 4 s`: end.
//!
//! Claims: the TCP position error is below [`TOLERANCE_M`] = 5 mm within 1.5 s after the step
//! and stays there until the push; after the push it is back below 5 mm before the end; no
//! value is NaN; the commanded torque never reaches an effort limit (no clamping).

use fixtures::justin::{self, JustinModel, BODIES, FRAMES, JOINT_NAMES, N, RIGHT_TCP, UPPER_DOF};
use kernel::model::Placement;
use nalgebra::{Translation3, Vector3};

use super::{column_index, joint_columns, pose_error_columns, Outcome, RunOptions};
use crate::controllers::{CartesianJointGains, CartesianJointImpedance};
use crate::output::{Figure, Line, Panel, Span, Summary, TimeSeries};
use crate::replay::Robot;
use crate::sim::{run_loop, SimConfig, Simulator, CONTROL_PERIOD_S};

/// Registry name.
pub const NAME: &str = "cartesian_step";
/// One-line description.
pub const DESCRIPTION: &str =
    "Justin-like robot, Cartesian impedance: 0.1 m TCP step at 0.5 s, 20 N push at 2.5 s, 4 s";

/// The replay's robot: Justin with the run's platform pose, the right TCP's error in `e1.*` and
/// the push in `push.f*`.
pub const REPLAY: Robot = Robot::right_hand_at_level_1(&[
    ("q.base_x", "base.x"),
    ("q.base_y", "base.y"),
    ("q.base_theta", "base.theta"),
    ("force.right.x", "push.fx"),
    ("force.right.y", "push.fy"),
    ("force.right.z", "push.fz"),
]);
/// Simulated time (s).
pub const DURATION_S: f64 = 4.0;
/// Time of the target step (s).
pub const STEP_TIME_S: f64 = 0.5;
/// Size of the target step in world +x (m).
pub const STEP_M: f64 = 0.1;
/// Start of the push (s).
pub const PUSH_START_S: f64 = 2.5;
/// Duration of the push (s).
pub const PUSH_DURATION_S: f64 = 0.2;
/// Push force in world +y (N).
pub const PUSH_N: f64 = 20.0;
/// Settling tolerance of the TCP position error (m).
pub const TOLERANCE_M: f64 = 0.005;
/// Time allowed to settle after the step (s).
pub const SETTLE_BOUND_S: f64 = 1.5;

type Sim = Simulator<N, BODIES, FRAMES, UPPER_DOF>;
type Controller = CartesianJointImpedance<N, BODIES, FRAMES, UPPER_DOF>;

/// Runs the scenario.
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    let model: JustinModel<f64> = justin::model::<f64>().map_err(|e| format!("Justin model: {e}"))?;
    let home = justin::home_configuration::<f64>();
    let base_dof = N - UPPER_DOF;
    let rest = home.fixed_rows::<UPPER_DOF>(base_dof).into_owned();

    let mut sim: Sim = options.simulator(model.clone(), SimConfig::default())?;
    sim.set_state(home, nalgebra::SVector::zeros()).map_err(|e| e.to_string())?;
    sim.push(RIGHT_TCP, Vector3::new(0.0, PUSH_N, 0.0), PUSH_START_S, PUSH_DURATION_S).map_err(|e| e.to_string())?;
    let start = sim.frame_placement(RIGHT_TCP).map_err(|e| e.to_string())?;
    let stepped = Placement::from_parts(
        Translation3::from(start.translation.vector + Vector3::new(STEP_M, 0.0, 0.0)),
        start.rotation,
    );
    let mut controller =
        Controller::new(model, RIGHT_TCP, CartesianJointGains::default(), rest, start).map_err(|e| e.to_string())?;

    let names: Vec<&str> = JOINT_NAMES.iter().copied().skip(JOINT_NAMES.len().saturating_sub(UPPER_DOF)).collect();
    let mut columns = vec!["t".to_owned()];
    columns.extend(joint_columns(&names));
    columns.extend(pose_error_columns(1));
    columns.extend(
        ["x_des.x", "x_des.y", "x_des.z", "tcp.x", "tcp.y", "tcp.z", "push.fx", "push.fy", "push.fz", "tau_ratio_max"]
            .map(String::from),
    );
    columns.extend(["base.x", "base.y", "base.theta"].map(String::from));
    let mut series = TimeSeries::new(columns);

    let report = run_loop(&mut sim, DURATION_S, CONTROL_PERIOD_S, |sim, info| {
        if info.cycle % 100 == 0 {
            options.progress.report(NAME, info.time_s, DURATION_S);
        }
        if info.time_s >= STEP_TIME_S - 1e-9 {
            controller.set_target(stepped);
        }
        let telemetry = *controller.step(sim)?;
        let tcp = sim.frame_placement(RIGHT_TCP)?.translation.vector;
        let target = controller.target().translation.vector;
        let push = sim.push_force(RIGHT_TCP, info.time_s);
        let mut row = vec![info.time_s];
        row.extend(sim.upper_q().iter().chain(sim.upper_v().iter()).chain(sim.applied_torque().iter()));
        row.extend(telemetry.error.iter());
        row.extend(target.iter().chain(tcp.iter()).chain(push.iter()));
        row.push(telemetry.torque_ratio);
        row.extend(sim.q().iter().take(base_dof));
        series.push(row)
    })?;
    options.progress.finish();
    evaluate(&series, report.saturated_steps, sim.time_s())
}

/// Metrics, claims and figures from the recorded series.
fn evaluate(series: &TimeSeries, saturated_steps: u64, duration_s: f64) -> Result<Outcome, String> {
    let column = |name: &str| -> Result<Vec<f64>, String> {
        column_index(series, name)?;
        series.column(name).ok_or_else(|| format!("no column {name}"))
    };
    let t = column("t")?;
    let (ex, ey, ez) = (column("e1.x")?, column("e1.y")?, column("e1.z")?);
    let (erx, ery, erz) = (column("e1.rx")?, column("e1.ry")?, column("e1.rz")?);
    let position_error: Vec<f64> =
        ex.iter().zip(&ey).zip(&ez).map(|((x, y), z)| (x * x + y * y + z * z).sqrt()).collect();
    let rotation_error: Vec<f64> =
        erx.iter().zip(&ery).zip(&erz).map(|((x, y), z)| (x * x + y * y + z * z).sqrt()).collect();
    let ratio = column("tau_ratio_max")?;

    let push_end = PUSH_START_S + PUSH_DURATION_S;
    // Settling: the last time in [step, push) the error was above tolerance.
    let settle = settle_time(&t, &position_error, STEP_TIME_S, PUSH_START_S);
    let recovery_time = settle_time(&t, &position_error, push_end, DURATION_S + 1.0);
    let window_max = |from: f64, to: f64, x: &[f64]| {
        t.iter().zip(x).filter(|(ti, _)| **ti >= from && **ti < to).map(|(_, v)| *v).fold(0.0, f64::max)
    };
    let final_error = position_error.last().copied().unwrap_or(f64::NAN);
    let before_push = t
        .iter()
        .zip(&position_error)
        .filter(|(ti, _)| **ti < PUSH_START_S)
        .map(|(_, e)| *e)
        .next_back()
        .unwrap_or(f64::NAN);
    let overshoot = window_max(STEP_TIME_S, PUSH_START_S, &ex);
    let deflection = window_max(PUSH_START_S, DURATION_S + 1.0, &position_error);
    let max_ratio = ratio.iter().copied().fold(0.0, f64::max);
    let max_tau = series
        .columns()
        .iter()
        .enumerate()
        .filter(|(_, c)| c.starts_with("tau."))
        .flat_map(|(i, _)| series.rows().iter().filter_map(move |r| r.get(i)))
        .fold(0.0_f64, |m, x| m.max(x.abs()));
    let all_finite = series.rows().iter().flatten().all(|x| x.is_finite());
    let largest =
        |names: &[&str]| names.iter().filter_map(|c| series.column(c)).flatten().fold(0.0_f64, |m, x| m.max(x.abs()));
    let base_displacement = largest(&["base.x", "base.y"]);
    let base_rotation = largest(&["base.theta"]);

    let mut summary = Summary::new(NAME);
    summary
        .metric("settle_time_s", settle)
        .metric("error_before_push_m", before_push)
        .metric("overshoot_x_m", overshoot)
        .metric("max_push_deflection_m", deflection)
        .metric("recovery_time_s", recovery_time)
        .metric("final_error_m", final_error)
        .metric("final_rotation_error_rad", rotation_error.last().copied().unwrap_or(f64::NAN))
        .metric("max_tau_nm", max_tau)
        .metric("max_tau_ratio", max_ratio)
        .metric("max_base_displacement_m", base_displacement)
        .metric("max_base_rotation_rad", base_rotation)
        .metric("duration_s", duration_s)
        .value("saturated_physics_steps", saturated_steps);
    summary.claim(
        &format!("TCP error < 5 mm within {SETTLE_BOUND_S} s after the step (settled after {settle:.3} s)"),
        settle <= SETTLE_BOUND_S,
    );
    summary.claim(
        &format!("TCP error < 5 mm again after the push (recovered {recovery_time:.3} s after it ended)"),
        recovery_time < DURATION_S - push_end,
    );
    summary.claim(&format!("final TCP error {:.2} mm < 5 mm", final_error * 1e3), final_error < TOLERANCE_M);
    summary.claim("no NaN or infinite value", all_finite);
    summary.claim(
        &format!("torques within limits (max |tau_i|/tau_max,i = {max_ratio:.2} < 1, no clamping)"),
        max_ratio < 1.0 && saturated_steps == 0,
    );

    Ok(Outcome { summary, series: series.clone(), figures: figures(series, &t, &position_error)? })
}

/// Time after `from` at which `error` entered the tolerance for good (until `to`); infinite if
/// it never did.
fn settle_time(t: &[f64], error: &[f64], from: f64, to: f64) -> f64 {
    let window = t.iter().zip(error).filter(|(ti, _)| **ti >= from && **ti < to);
    let mut settled_at = Some(from);
    for (ti, e) in window {
        if *e >= TOLERANCE_M {
            settled_at = None;
        } else if settled_at.is_none() {
            settled_at = Some(*ti);
        }
    }
    settled_at.map_or(f64::INFINITY, |s| s - from)
}

fn figures(series: &TimeSeries, t: &[f64], position_error: &[f64]) -> Result<Vec<(&'static str, Figure)>, String> {
    let scaled = |name: &str, scale: f64| -> Result<Vec<(f64, f64)>, String> {
        let y = series.column(name).ok_or_else(|| format!("no column {name}"))?;
        Ok(t.iter().copied().zip(y.iter().map(|v| v * scale)).collect())
    };
    let gains = CartesianJointGains::default();
    let events = || {
        vec![
            Span { label: "target step +0.1 m in x".into(), from: STEP_TIME_S, to: STEP_TIME_S },
            Span { label: "20 N push in +y".into(), from: PUSH_START_S, to: PUSH_START_S + PUSH_DURATION_S },
        ]
    };
    let t_end = t.last().copied().unwrap_or(DURATION_S);
    let error_mm: Vec<(f64, f64)> = t.iter().copied().zip(position_error.iter().map(|e| e * 1e3)).collect();
    let tcp_error = Figure {
        title: format!(
            "cartesian_step: right TCP under Cartesian impedance (K = {:.0} N/m, ζ = {})",
            gains.translational_stiffness.x, gains.damping_ratio
        ),
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: "TCP position error x − x_des (world frame)".into(),
                y_label: "position error (mm)".into(),
                lines: vec![
                    Line::new("x", scaled("e1.x", 1e3)?),
                    Line::new("y", scaled("e1.y", 1e3)?),
                    Line::new("z", scaled("e1.z", 1e3)?),
                    Line::new("norm", error_mm),
                    Line::dashed("±5 mm tolerance", vec![(0.0, 5.0), (t_end, 5.0)]),
                    Line::dashed("", vec![(0.0, -5.0), (t_end, -5.0)]),
                ],
                spans: events(),
            },
            Panel {
                title: "TCP orientation error (rotation vector of R R_desᵀ)".into(),
                y_label: "orientation error (mrad)".into(),
                lines: vec![
                    Line::new("rx", scaled("e1.rx", 1e3)?),
                    Line::new("ry", scaled("e1.ry", 1e3)?),
                    Line::new("rz", scaled("e1.rz", 1e3)?),
                ],
                spans: events(),
            },
        ],
    };
    let torque_lines = |range: std::ops::Range<usize>| -> Result<Vec<Line>, String> {
        let names: Vec<String> = series.columns().iter().filter(|c| c.starts_with("tau.")).cloned().collect();
        names
            .get(range)
            .unwrap_or_default()
            .iter()
            .map(|c| Ok(Line::new(c.trim_start_matches("tau."), scaled(c, 1.0)?)))
            .collect()
    };
    let torques = Figure {
        title: "cartesian_step: commanded joint torques".into(),
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: "torso and right arm".into(),
                y_label: "torque (Nm)".into(),
                lines: torque_lines(0..10)?,
                spans: events(),
            },
            Panel {
                title: "left arm".into(),
                y_label: "torque (Nm)".into(),
                lines: torque_lines(10..UPPER_DOF)?,
                spans: events(),
            },
        ],
    };
    Ok(vec![("tcp_error.svg", tcp_error), ("joint_torques.svg", torques)])
}
