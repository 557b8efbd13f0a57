//! `wbc_phri`: physical human-robot interaction with the whole-body impedance of Rollin' Justin
//! (Sec. 6.2, Fig. 6.7): a person pushes the right hand; the whole robot, platform included,
//! yields compliantly and returns when released.
//!
//! Setup: the rig of [`crate::wbc::chapter_6_rig`] (Fig. 6.3 hierarchy for the right TCP, goal
//! held at the start pose). Two horizontal pushes of [`PUSH_N`] for [`PUSH_S`] on the right TCP
//! frame: forward (world `+x`) at [`PUSHES`]`[0]` and sideways (`+y`, to the robot's left) at
//! [`PUSHES`]`[1]`. Force, duration and directions are chosen (the thesis shows a person
//! pulling the hand, without numbers).
//!
//! Claims: the base reacts (Sec. 6.2: "the mobile base tries to compensate for that error"):
//! while a push acts, its velocity command points against the push, i.e. the platform moves so
//! as to bring the displaced TCP back to its desired pose (the TCP spring's force on the
//! platform coordinates), which causes a null-space motion of the upper body; the TCP returns
//! (position error < 1 cm, orientation error < 1° at the end); the contact indicator of
//! the momentum observer is set during the pushes and not at rest; the energy stays bounded
//! (below the work of the pushes) and decays; no self-collision; no fault.
//!
//! The contact indicator compares the observer's residual norm with the configured threshold
//! (8 Nm, chosen for exact sensors); on the realistic plant the rig raises it by the sensors'
//! noise floor ([`kernel::controller::observer::noise_floor`], README `--plant`), recorded
//! as `contact_threshold_nm`.

use kernel::controller::config::ArmId;
use nalgebra::Vector3;

use super::wbc_step::{
    col, common_claims, distance_to, line, max_in, platform_velocity_panels, tcp_columns, PUSH_FRAME,
};
use super::{Outcome, RunOptions};
use crate::output::{Figure, Panel, Span, Summary, TimeSeries};
use crate::wbc;

/// Registry name.
pub const NAME: &str = "wbc_phri";
/// One-line description.
pub const DESCRIPTION: &str =
    "Justin whole-body impedance, pHRI: two 40 N pushes on the right hand, the base compensates and the hand returns (Fig. 6.7)";
/// Push force (N). Chosen.
pub const PUSH_N: f64 = 40.0;
/// Push duration (s). Chosen.
pub const PUSH_S: f64 = 0.5;
/// Push start times (s) and world directions.
pub const PUSHES: [(f64, [f64; 3]); 2] = [(1.0, [1.0, 0.0, 0.0]), (5.0, [0.0, 1.0, 0.0])];
/// Simulated time (s).
pub const DURATION_S: f64 = 8.0;
/// Position tolerance at the end (m).
pub const RETURN_TOLERANCE_M: f64 = 0.01;
/// Orientation tolerance at the end (rad): 1°.
pub const ORIENTATION_TOLERANCE_RAD: f64 = core::f64::consts::PI / 180.0;
/// Base velocity against the push that counts as a reaction (m/s).
pub const YIELD_SPEED_M_S: f64 = 0.01;

/// The phases the replay names: the pushes.
pub fn phases() -> Vec<(f64, String)> {
    PUSHES
        .iter()
        .map(|(t, [x, y, z])| {
            (*t, format!("a person pushes the right hand with {PUSH_N:.0} N along ({x}, {y}, {z}) for {PUSH_S} s"))
        })
        .collect()
}

/// Runs the scenario: setup, run, claims, figure.
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    let mut rig = setup(options)?;
    let (series, start) = run(&mut rig, options)?;
    let signals = Signals::new(&series, &start)?;
    let summary = claims(&signals, &series, &rig)?;
    let figure = figure(&signals, &series)?;
    Ok(Outcome { summary, series, figures: vec![("phri.svg", figure)] })
}

/// The Ch. 6 rig with the two pushes scheduled.
fn setup(options: &RunOptions) -> Result<wbc::Rig, String> {
    let mut rig = wbc::chapter_6_rig(ArmId::RIGHT, &[], options)?;
    for (at, direction) in PUSHES {
        rig.sim.push(PUSH_FRAME, Vector3::from(direction) * PUSH_N, at, PUSH_S).map_err(|e| format!("push: {e}"))?;
    }
    Ok(rig)
}

/// Runs [`DURATION_S`]; returns the series and the right TCP's goal (its start pose).
fn run(rig: &mut wbc::Rig, options: &RunOptions) -> Result<(TimeSeries, Vector3<f64>), String> {
    let mut start = None;
    let series = rig.run(DURATION_S, |rig, info| {
        if info.cycle % 100 == 0 {
            options.progress.report(NAME, info.time_s, DURATION_S);
        }
        start.get_or_insert(rig.tcp_target(ArmId::RIGHT)?.pose.translation.vector);
        Ok(())
    })?;
    options.progress.finish();
    Ok((series, start.ok_or("no cycle ran")?))
}

/// The signals the claims and the figure share.
struct Signals {
    /// Time (s).
    t: Vec<f64>,
    /// TCP distance from its start (m).
    error: Vec<f64>,
    /// Controller energy above the rest state before the first push (J).
    energy: Vec<f64>,
}

impl Signals {
    fn new(series: &TimeSeries, start: &Vector3<f64>) -> Result<Self, String> {
        let t = col(series, "t")?;
        let error = distance_to(&tcp_columns(series, ArmId::RIGHT)?, start);
        // Energy relative to the rest state before the first push (the level-1 potentials, e.g.
        // the torso workspace, are not zero at rest).
        let total: Vec<f64> =
            col(series, "kinetic_j")?.iter().zip(col(series, "potential_j")?.iter()).map(|(k, p)| k + p).collect();
        let rest_energy =
            t.iter().zip(total.iter()).take_while(|(t, _)| **t < PUSHES[0].0).map(|(_, e)| *e).last().unwrap_or(0.0);
        let energy = total.iter().map(|e| e - rest_energy).collect();
        Ok(Self { t, error, energy })
    }
}

/// Metrics and claims (module docs).
fn claims(signals: &Signals, series: &TimeSeries, rig: &wbc::Rig) -> Result<Summary, String> {
    let Signals { t, error, energy } = signals;
    let final_error = error.last().copied().unwrap_or(f64::NAN);
    let orientation = ["e0.rx", "e0.ry", "e0.rz"]
        .iter()
        .map(|c| col(series, c).map(|v| v.last().copied().unwrap_or(f64::NAN)))
        .collect::<Result<Vec<f64>, String>>()?
        .iter()
        .map(|x| x * x)
        .sum::<f64>()
        .sqrt();
    let (vx, vy) = (col(series, "vcmd.x")?, col(series, "vcmd.y")?);
    let contact = col(series, "contact")?;
    let peak_energy = energy.iter().copied().fold(0.0, f64::max);
    let final_energy = energy.last().copied().unwrap_or(f64::NAN);
    let peak_deflection = error.iter().copied().fold(0.0, f64::max);

    let mut summary = Summary::new(NAME);
    let mut yields = true;
    let mut contact_during = true;
    for (k, (at, d)) in PUSHES.iter().enumerate() {
        let along: Vec<f64> = vx.iter().zip(vy.iter()).map(|(x, y)| x * d[0] + y * d[1]).collect();
        let against: Vec<f64> = along.iter().map(|v| -v).collect();
        let peak = max_in(t, &against, *at, at + PUSH_S);
        let share = {
            let window: Vec<f64> = t
                .iter()
                .zip(contact.iter())
                .filter(|(t, _)| **t >= *at && **t < at + PUSH_S)
                .map(|(_, c)| *c)
                .collect();
            window.iter().sum::<f64>() / window.len().max(1) as f64
        };
        summary
            .metric(&format!("push{k}_base_velocity_against_m_s"), peak)
            .metric(&format!("push{k}_contact_share"), share);
        yields &= peak > YIELD_SPEED_M_S;
        contact_during &= share > 0.5;
    }
    let rest = |from: f64, to: f64| {
        t.iter().zip(contact.iter()).filter(|(t, _)| **t >= from && **t < to).all(|(_, c)| *c == 0.0)
    };
    let at_rest = rest(0.1, PUSHES[0].0) && rest(DURATION_S - 1.0, DURATION_S);
    let work = PUSH_N * peak_deflection * PUSHES.len() as f64;
    summary
        .metric("final_error_m", final_error)
        .metric("final_orientation_error_rad", orientation)
        .metric("peak_deflection_m", peak_deflection)
        .metric("peak_energy_j", peak_energy)
        .metric("final_energy_j", final_energy)
        .metric("push_work_bound_j", work)
        .metric("contact_threshold_nm", rig.controller.config().observer.contact_threshold);
    summary.claim(
        &format!(
            "the base compensates the TCP deflection (Sec. 6.2): its velocity command points against each push while it acts (> {YIELD_SPEED_M_S} m/s)"
        ),
        yields,
    );
    summary.claim(
        &format!(
            "the TCP returns: position error {:.1} mm < {:.0} mm, orientation error {:.2}° < 1° at the end",
            final_error * 1e3,
            RETURN_TOLERANCE_M * 1e3,
            orientation.to_degrees()
        ),
        final_error < RETURN_TOLERANCE_M && orientation < ORIENTATION_TOLERANCE_RAD,
    );
    summary.claim("the contact indicator is set during most of each push and never at rest", contact_during && at_rest);
    summary.claim(
        &format!(
            "the energy (above the rest state) stays bounded: peak {peak_energy:.2} J < the pushes' work bound {work:.2} J, and decays to {final_energy:.3} J < 10 % of the peak"
        ),
        peak_energy < work && final_energy < 0.1 * peak_energy,
    );
    common_claims(&mut summary, rig, series)?;
    Ok(summary)
}

/// The figure `phri.svg`.
fn figure(signals: &Signals, series: &TimeSeries) -> Result<Figure, String> {
    let Signals { t, error, energy } = signals;
    let spans =
        || PUSHES.iter().map(|(at, _)| Span { label: "push".into(), from: *at, to: at + PUSH_S }).collect::<Vec<_>>();
    let deflection = crate::output::Line::new("‖p − p_start‖", super::wbc_step::points(t, error, 10, 1e3));
    let [translation, rotation] = platform_velocity_panels(series, &spans())?;
    Ok(Figure {
        title: "wbc_phri: 40 N pushes on the right hand, whole-body compliance (cf. Fig. 6.7)".into(),
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: "TCP deflection".into(),
                y_label: "deflection (mm)".into(),
                lines: vec![deflection],
                spans: spans(),
            },
            translation,
            rotation,
            Panel {
                title: "external torque estimate".into(),
                y_label: "torque (Nm)".into(),
                lines: vec![line(series, "‖τ_ext‖", "tau_ext_norm", 1.0)?],
                spans: spans(),
            },
            Panel {
                title: "contact detected by the controller".into(),
                y_label: "contact (1: detected)".into(),
                lines: vec![line(series, "contact", "contact", 1.0)?],
                spans: spans(),
            },
            Panel {
                title: "energy".into(),
                y_label: "energy (J)".into(),
                lines: vec![
                    line(series, "kinetic", "kinetic_j", 1.0)?,
                    line(series, "potential", "potential_j", 1.0)?,
                    crate::output::Line::new("total above rest", super::wbc_step::points(t, energy, 10, 1.0)),
                ],
                spans: spans(),
            },
        ],
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;

    #[test]
    fn wbc_phri_base_compensates_and_hand_returns() {
        let outcome = simulate(&RunOptions::default()).unwrap();
        let s = &outcome.summary;
        assert!(s.failed_claims().is_empty(), "failed: {:?}", s.failed_claims());
        assert!(s.get("final_error_m").unwrap() < RETURN_TOLERANCE_M);
        assert!(s.get("push0_base_velocity_against_m_s").unwrap() > YIELD_SPEED_M_S);
        assert!(s.get("push1_base_velocity_against_m_s").unwrap() > YIELD_SPEED_M_S);
    }
}
