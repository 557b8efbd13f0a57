//! `wbc_trajectory`: the right TCP of Rollin' Justin follows a 1 m forward-and-back trajectory
//! under the whole-body impedance controller (Sec. 6.2, Fig. 6.5 and 6.6).
//!
//! Setup: the rig of [`crate::wbc::chapter_6_rig`] (Fig. 6.3 hierarchy for the right TCP);
//! `k_tra = 500 N/m`, `k_rot = 100 Nm/rad`, `ξ = 0.7` (**thesis**). The TCP goal moves
//! [`DISTANCE_M`] forward along world `x` on the controller's cubic in [`SEGMENT_S`] and back in
//! the same time (`TcpGoal` commands, orientation held). The arm alone cannot reach 1 m further:
//! the platform admittance takes the rest.
//!
//! Claims: the tracking error (TCP − desired position) stays bounded (< [`MAX_TRACKING_M`]; its
//! maximum is reported); the TCP returns to its start within 1 cm; no self-collision; the joint
//! configuration at the end differs from the start (the redundancy is not restored: the
//! thesis' Fig. 6.6 remark on the null space), its norm reported; no fault.

use kernel::controller::config::{ArmId, MAX_LEVELS};
use kernel::controller::messages::Command;
use nalgebra::{SVector, Vector3};

use super::wbc_step::{
    col, common_claims, distance_to, line, platform_velocity_panels, points, pose_of, subtask_lines, tcp_columns,
};
use super::{Outcome, RunOptions};
use crate::output::{Figure, Line, Panel, Span, Summary, TimeSeries};
use crate::wbc;

/// Registry name.
pub const NAME: &str = "wbc_trajectory";
/// One-line description.
pub const DESCRIPTION: &str =
    "Justin whole-body impedance: right TCP 1 m forward and back (cubic, 8 s each), subtask torques (Fig. 6.5/6.6)";
/// Start of the forward segment (s).
pub const FORWARD_AT_S: f64 = 0.5;
/// Duration of each segment (s), as in Fig. 6.5.
pub const SEGMENT_S: f64 = 8.0;
/// Start of the backward segment (s).
pub const BACKWARD_AT_S: f64 = FORWARD_AT_S + SEGMENT_S + 0.5;
/// Simulated time (s).
pub const DURATION_S: f64 = BACKWARD_AT_S + SEGMENT_S + 1.5;
/// Length of the motion (m).
pub const DISTANCE_M: f64 = 1.0;
/// Bound of the tracking error (m): a fifth of the path. Chosen.
pub const MAX_TRACKING_M: f64 = 0.2;
/// Return tolerance (m).
pub const RETURN_TOLERANCE_M: f64 = 0.01;

/// The phases the replay names: forward, back, the end pose.
pub fn phases() -> Vec<(f64, String)> {
    vec![
        (
            FORWARD_AT_S,
            format!(
                "the right hand's goal moves {DISTANCE_M:.0} m forward in {SEGMENT_S:.0} s: beyond the arm's reach, the \
                 platform follows"
            ),
        ),
        (BACKWARD_AT_S, "the goal moves back to the start".into()),
        (
            BACKWARD_AT_S + SEGMENT_S,
            "the hand is back; the joints are not (the null space is not restored, Fig. 6.6)".into(),
        ),
    ]
}

/// Runs the scenario: run, tracking error, claims, figures.
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    let mut rig = wbc::chapter_6_rig(ArmId::RIGHT, &[], options)?;
    let run = run(&mut rig, options)?;
    let tracking = tracking_error(&run)?;
    let summary = claims(&run, &tracking, &rig)?;
    let figures = figures(&run, &tracking)?;
    Ok(Outcome { summary, series: run.series, figures })
}

/// What a run recorded beside the standard time series.
struct Run {
    series: TimeSeries,
    /// The right TCP's start position (m).
    start: Vector3<f64>,
    /// The desired TCP position after each cycle (m).
    desired: Vec<Vector3<f64>>,
    /// The level torque norms after each cycle (Nm).
    levels: Vec<[f64; MAX_LEVELS]>,
    /// The configuration at the first cycle.
    q0: SVector<f64, { fixtures::justin::N }>,
}

/// Runs [`DURATION_S`] with the goals forward and back.
fn run(rig: &mut wbc::Rig, options: &RunOptions) -> Result<Run, String> {
    let mut start = None;
    let mut desired: Vec<Vector3<f64>> = Vec::new();
    let mut levels: Vec<[f64; MAX_LEVELS]> = Vec::new();
    let mut q0 = None;
    let series = rig.run(DURATION_S, |rig, info| {
        if info.cycle % 100 == 0 {
            options.progress.report(NAME, info.time_s, DURATION_S);
        }
        let target = rig.tcp_target(ArmId::RIGHT)?.pose;
        let begin = *start.get_or_insert(target);
        q0.get_or_insert(*rig.sim.q());
        let near = |t: f64| (info.time_s - t).abs() < 0.5 * crate::sim::CONTROL_PERIOD_S;
        for (at, offset) in [(FORWARD_AT_S, DISTANCE_M), (BACKWARD_AT_S, 0.0)] {
            if near(at) {
                let mut goal = begin;
                goal.translation.vector.x += offset;
                let command = Command::TcpGoal { hand: ArmId::RIGHT, pose: pose_of(&goal), duration_s: SEGMENT_S };
                rig.apply(&command).map_err(|e| format!("goal: {e}"))?;
            }
        }
        desired.push(rig.tcp_target(ArmId::RIGHT)?.pose.translation.vector);
        levels.push(rig.controller.telemetry().level_torque_norm);
        Ok(())
    })?;
    options.progress.finish();
    let start = start.ok_or("no cycle ran")?.translation.vector;
    let q0 = q0.ok_or("no cycle ran")?;
    Ok(Run { series, start, desired, levels, q0 })
}

/// The tracking error ‖p − p_des‖ per row (m).
fn tracking_error(run: &Run) -> Result<Vec<f64>, String> {
    let Run { series, start, desired, .. } = run;
    let tcp = tcp_columns(series, ArmId::RIGHT)?;
    // The desired pose recorded after cycle k is the one cycle k + 1 uses; compare with the
    // next row's TCP (one period of lag is 0.2 mm at the peak speed).
    let [px, py, pz] = &tcp;
    let tracking: Vec<f64> = px
        .iter()
        .zip(py.iter())
        .zip(pz.iter())
        .enumerate()
        .map(|(k, ((x, y), z))| {
            let d = desired.get(k.saturating_sub(1)).copied().unwrap_or(*start);
            (Vector3::new(*x, *y, *z) - d).norm()
        })
        .collect();
    Ok(tracking)
}

/// Metrics and claims (module docs).
fn claims(run: &Run, tracking: &[f64], rig: &wbc::Rig) -> Result<Summary, String> {
    let Run { series, start, q0, .. } = run;
    let tcp = tcp_columns(series, ArmId::RIGHT)?;
    let max_tracking = tracking.iter().copied().fold(0.0, f64::max);
    let final_error = distance_to(&tcp, start).last().copied().unwrap_or(f64::NAN);
    let q_end = *rig.sim.q();
    let upper = (q_end - q0).rows(3, fixtures::justin::UPPER_DOF).norm();
    let base_dx = col(series, "q.base_x")?;
    let base_peak = base_dx.iter().copied().fold(f64::NEG_INFINITY, f64::max);

    let mut summary = Summary::new(NAME);
    summary
        .metric("max_tracking_error_m", max_tracking)
        .metric("final_error_m", final_error)
        .metric("joint_configuration_change_rad", upper)
        .metric("base_peak_x_m", base_peak)
        .metric("base_final_x_m", base_dx.last().copied().unwrap_or(f64::NAN));
    summary.claim(
        &format!("tracking error bounded: max {:.1} mm < {:.0} mm", max_tracking * 1e3, MAX_TRACKING_M * 1e3),
        max_tracking < MAX_TRACKING_M,
    );
    summary.claim(
        &format!("the TCP returns to its start: {:.1} mm < {:.0} mm", final_error * 1e3, RETURN_TOLERANCE_M * 1e3),
        final_error < RETURN_TOLERANCE_M,
    );
    summary.claim(
        &format!("the upper-body configuration at the end differs from the start: ‖Δq‖ = {upper:.3} rad > 0.01 rad (null space not restored)"),
        upper > 0.01,
    );
    common_claims(&mut summary, rig, series)?;
    Ok(summary)
}

/// The figures `tcp_trajectory.svg` and `torques.svg`.
fn figures(run: &Run, tracking: &[f64]) -> Result<Vec<(&'static str, Figure)>, String> {
    let Run { series, start, desired, levels, .. } = run;
    let t = col(series, "t")?;
    let tcp = tcp_columns(series, ArmId::RIGHT)?;
    let spans = || {
        vec![
            Span { label: "forward".into(), from: FORWARD_AT_S, to: FORWARD_AT_S + SEGMENT_S },
            Span { label: "backward".into(), from: BACKWARD_AT_S, to: BACKWARD_AT_S + SEGMENT_S },
        ]
    };
    let rel: Vec<f64> = tcp[0].iter().map(|x| x - start.x).collect();
    let des: Vec<f64> = desired.iter().map(|d| d.x - start.x).collect();
    let level_line = |l: usize| {
        Line::new(
            format!("level {l}"),
            points(&t, &levels.iter().map(|v| v.get(l).copied().unwrap_or(f64::NAN)).collect::<Vec<_>>(), 10, 1.0),
        )
    };
    let [translation, rotation] = platform_velocity_panels(series, &spans())?;
    let main = Figure {
        title: "wbc_trajectory: right TCP 1 m forward and back, k_tra = 500 N/m, k_rot = 100 Nm/rad (cf. Fig. 6.5)"
            .into(),
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: "TCP x relative to the start (world) and platform x".into(),
                y_label: "x (m)".into(),
                lines: vec![
                    Line::new("TCP", points(&t, &rel, 10, 1.0)),
                    Line::dashed("desired", points(&t, &des, 10, 1.0)),
                    line(series, "platform", "q.base_x", 1.0)?,
                ],
                spans: spans(),
            },
            Panel {
                title: "tracking error ‖p − p_des‖".into(),
                y_label: "error (mm)".into(),
                lines: vec![Line::new("tracking error", points(&t, tracking, 10, 1e3))],
                spans: spans(),
            },
            translation,
            rotation,
        ],
    };
    let torques = Figure {
        title: "wbc_trajectory: subtask and level torque norms (cf. Fig. 6.5/6.6)".into(),
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: "subtask torque norms ‖τ_i‖ before projection".into(),
                y_label: "‖τ‖ (Nm)".into(),
                lines: subtask_lines(series)?,
                spans: spans(),
            },
            Panel {
                title: "level torque norms ‖N_i τ_i‖".into(),
                y_label: "‖τ‖ (Nm)".into(),
                lines: vec![level_line(0), level_line(1)],
                spans: spans(),
            },
            Panel {
                title: "smallest collision distance".into(),
                y_label: "distance (mm)".into(),
                lines: vec![line(series, "min pair distance", "min_distance", 1e3)?],
                spans: spans(),
            },
        ],
    };
    Ok(vec![("tcp_trajectory.svg", main), ("torques.svg", torques)])
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;

    #[test]
    fn wbc_trajectory_tracks_and_returns() {
        let outcome = simulate(&RunOptions::default()).unwrap();
        let s = &outcome.summary;
        assert!(s.failed_claims().is_empty(), "failed: {:?}", s.failed_claims());
        assert!(s.get("max_tracking_error_m").unwrap() < MAX_TRACKING_M);
        assert!(s.get("final_error_m").unwrap() < RETURN_TOLERANCE_M);
        assert!(s.get("joint_configuration_change_rad").unwrap() > 0.01);
    }
}
