//! `mobile_impedance_critical`: the critical admittance of Sec. 5.1.4 and a short push at the
//! TCP, with and without the coupling compensation (Fig. 5.9 and 5.10).
//!
//! Same robot and controller as [`super::mobile_impedance`], but the admittance
//! `M_adm = diag(3 kg, 3 kg, 1 kg m²)`, `D_adm = diag(21 kg/s, 21 kg/s, 7 kg m²/s)`: "the
//! velocity controller is instructed to reduce the perceived inertia to only 2 % of the
//! original value". The TCP is held at its start pose; a [`PUSH_N`] pull backwards (world −x)
//! acts on the TCP during [`PUSH_START_S`] … + [`PUSH_DURATION_S`] ("While the user is pulling
//! the robot at the right end-effector …"). A run is ended like the experiment's emergency stop
//! once the storage function (5.21) exceeds [`STOP_ENERGY_J`].
//!
//! Claims: with compensation the transient is over within [`SETTLE_BOUND_S`] after the push
//! (the thesis: "The whole transient takes about 1.5 s only") and the passivity monitor stays
//! quiet; without it the loop is unstable ("Only slightly touching the end-effector immediately
//! destabilizes the system"): the storage grows until the emergency stop, and the monitor flags
//! it. On the realistic plant joint friction dissipates more than the coupling injects, so the
//! claim there is the non-passivity itself: after the push the uncompensated run gains more than
//! [`INJECTION_RATIO`] times the compensated run's energy beyond (5.22) and friction's work
//! (README `--plant`).

use nalgebra::Vector3;

use super::mobile_impedance::{critical_admittance, friction_dissipated_j, run, Disturbance, Experiment, Run, Sample};
use super::{Outcome, RunOptions};
use crate::output::{Figure, Line, Panel, Span, Summary, TimeSeries};
use crate::plant::PlantKind;
use crate::sim::{CONTROL_PERIOD_S, DEFAULT_PHYSICS_STEP_S};
use kernel::platform::coupling_compensation::CompensationSwitch;

/// Registry name.
pub const NAME: &str = "mobile_impedance_critical";
/// One-line description.
pub const DESCRIPTION: &str =
    "Justin-like robot, critical admittance M_adm = diag(3, 3, 1), D_adm = diag(21, 21, 7), push at the TCP: compensation ON stable, OFF unstable (Fig. 5.9/5.10)";
/// Simulated time (s).
pub const DURATION_S: f64 = 6.0;
/// Pull on the TCP, world −x (N). Invented (the thesis gives no force): a light touch.
pub const PUSH_N: f64 = 30.0;
/// Start of the push (s).
pub const PUSH_START_S: f64 = 0.5;
/// Duration of the push (s).
pub const PUSH_DURATION_S: f64 = 0.3;
/// Storage (J) at which a run is stopped (the experiment's emergency stop). Invented: four
/// times what the push puts in without compensation, forty times with it.
pub const STOP_ENERGY_J: f64 = 20.0;
/// Time after the push within which the compensated transient must be over (s); the thesis
/// reports about 1.5 s.
pub const SETTLE_BOUND_S: f64 = 2.0;
/// On the realistic plant: how many times the energy the compensated run gains beyond (5.22)
/// and friction after the push (the delay, lag and noise the balance leaves out) the
/// uncompensated run must gain for the claim "OFF is not passive" (README `--plant`). Chosen.
pub const INJECTION_RATIO: f64 = 4.0;
/// Energy (J) below which the transient counts as over.
pub const SETTLED_ENERGY_J: f64 = 0.01;

/// The two experiments (ON, OFF) of duration `duration_s`.
pub fn experiments(duration_s: f64, physics_step_s: f64) -> [Experiment; 2] {
    [CompensationSwitch::ON, CompensationSwitch::OFF].map(|compensation| Experiment {
        admittance: critical_admittance(),
        compensation,
        disturbance: Disturbance::Push {
            force_n: Vector3::new(-PUSH_N, 0.0, 0.0),
            start_s: PUSH_START_S,
            duration_s: PUSH_DURATION_S,
        },
        duration_s,
        physics_step_s,
        stop_energy_j: STOP_ENERGY_J,
    })
}

/// Runs the scenario.
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    let [on, off] = experiments(DURATION_S, DEFAULT_PHYSICS_STEP_S);
    let on = run(&on, options, "mobile_impedance_critical (compensation ON)")?;
    options.progress.finish();
    let off = run(&off, options, "mobile_impedance_critical (compensation OFF)")?;
    options.progress.finish();
    evaluate(&on, &off)
}

/// Metrics of one push run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PushMetrics {
    /// Time after the end of the push until the storage stays below [`SETTLED_ENERGY_J`] (s).
    pub settle_s: f64,
    /// Largest storage (J).
    pub peak_energy_j: f64,
    /// Largest storage during the push (J): the energy the push put in, roughly.
    pub push_energy_j: f64,
    /// Largest TCP deviation in x (m).
    pub max_deviation_m: f64,
    /// Largest platform excursion (m).
    pub max_base_x_m: f64,
    /// Largest torque ratio.
    pub torque_ratio: f64,
    /// Passivity monitor latched.
    pub flagged: bool,
    /// First time the monitor flagged (s).
    pub flagged_at_s: f64,
    /// Number of sign changes of the platform velocity after the push.
    pub direction_changes: usize,
    /// Energy put in after the push beyond what (5.22) and the joint friction account for:
    /// the storage change less `∫ (Ṡ_(5.22) + q̇ᵀ τ_f) dt` (J). (5.22) holds with the
    /// compensation, so without it this is the energy the uncompensated coupling injects.
    pub injected_after_push_j: f64,
    /// Energy the plant's joint friction dissipated after the push (J; zero on the ideal plant).
    pub friction_after_push_j: f64,
}

/// Metrics of a run.
pub fn metrics(run: &Run) -> PushMetrics {
    let s = &run.samples;
    let end = PUSH_START_S + PUSH_DURATION_S;
    let last_above = s.iter().rev().find(|x| x.storage[2] >= SETTLED_ENERGY_J).map(|x| x.t);
    let settle_s = match (last_above, s.last(), run.stopped_at_s) {
        (_, _, Some(_)) => f64::INFINITY,
        (None, Some(_), None) => 0.0,
        (Some(t), Some(last), None) if t < last.t => (t - end).max(0.0),
        _ => f64::INFINITY,
    };
    let after: Vec<&Sample> = s.iter().filter(|x| x.t >= end).collect();
    let direction_changes = after
        .windows(2)
        .filter(|w| match w {
            [a, b] => a.base[1].signum() != b.base[1].signum() && a.base[1].abs().max(b.base[1].abs()) > 1e-3,
            _ => false,
        })
        .count();
    PushMetrics {
        settle_s,
        peak_energy_j: s.iter().map(|x| x.storage[2]).fold(0.0, f64::max),
        push_energy_j: s.iter().filter(|x| x.t < end).map(|x| x.storage[2]).fold(0.0, f64::max),
        max_deviation_m: s.iter().map(|x| x.error[0].abs()).fold(0.0, f64::max),
        max_base_x_m: s.iter().map(|x| x.base[0].abs()).fold(0.0, f64::max),
        torque_ratio: s.iter().map(|x| x.torque_ratio).fold(0.0, f64::max),
        flagged: s.iter().any(|x| x.latched),
        flagged_at_s: s.iter().find(|x| x.latched).map_or(f64::INFINITY, |x| x.t),
        direction_changes,
        injected_after_push_j: after.iter().map(|x| x.rates[1] - x.rates[0] - x.friction_power_w).sum::<f64>()
            * CONTROL_PERIOD_S,
        friction_after_push_j: -after.iter().map(|x| x.friction_power_w).sum::<f64>() * CONTROL_PERIOD_S,
    }
}

/// Claims, metrics and figures of the two runs.
pub fn evaluate(on: &Run, off: &Run) -> Result<Outcome, String> {
    let (m_on, m_off) = (metrics(on), metrics(off));
    let mut summary = Summary::new(NAME);
    for (tag, m, r) in [("on", &m_on, on), ("off", &m_off, off)] {
        summary
            .metric(&format!("{tag}_settle_after_push_s"), m.settle_s)
            .metric(&format!("{tag}_peak_energy_j"), m.peak_energy_j)
            .metric(&format!("{tag}_push_energy_j"), m.push_energy_j)
            .metric(&format!("{tag}_friction_dissipated_j"), friction_dissipated_j(r))
            .metric(&format!("{tag}_injected_after_push_j"), m.injected_after_push_j)
            .metric(&format!("{tag}_friction_dissipated_after_push_j"), m.friction_after_push_j)
            .metric(&format!("{tag}_max_tcp_deviation_m"), m.max_deviation_m)
            .metric(&format!("{tag}_max_base_x_m"), m.max_base_x_m)
            .metric(&format!("{tag}_max_tau_ratio"), m.torque_ratio)
            .value(&format!("{tag}_passivity_flagged"), m.flagged)
            .metric(&format!("{tag}_passivity_flagged_at_s"), m.flagged_at_s)
            .value(&format!("{tag}_platform_direction_changes"), m.direction_changes)
            .metric(&format!("{tag}_emergency_stop_s"), r.stopped_at_s.unwrap_or(f64::NAN));
    }
    let finite = on.samples.iter().all(|s| s.storage.iter().chain(s.error.iter()).all(|x| x.is_finite()));
    summary.claim(
        &format!(
            "compensation ON is stable: transient over {:.2} s after the push (< {SETTLE_BOUND_S} s), peak energy {:.2} J, no emergency stop",
            m_on.settle_s, m_on.peak_energy_j
        ),
        m_on.settle_s < SETTLE_BOUND_S && on.stopped_at_s.is_none() && finite,
    );
    summary.claim("compensation ON: the passivity monitor stays quiet", !m_on.flagged);
    match off.plant {
        PlantKind::Ideal => summary.claim(
            &format!(
                "compensation OFF diverges: the storage grows from {:.2} J (push) to the {STOP_ENERGY_J} J emergency stop at {}",
                m_off.push_energy_j,
                off.stopped_at_s.map_or("never".to_owned(), |t| format!("{t:.2} s"))
            ),
            off.stopped_at_s.is_some(),
        ),
        PlantKind::Realistic => summary.claim(
            &format!(
                "compensation OFF is not passive: after the push the uncompensated coupling injects {:.2} J beyond (5.22) and the joint friction (ON: {:.2} J, the plant's delay and noise), more than {INJECTION_RATIO} times as much; friction dissipates {:.2} J ({})",
                m_off.injected_after_push_j,
                m_on.injected_after_push_j,
                m_off.friction_after_push_j,
                off.stopped_at_s.map_or("the storage decays".to_owned(), |t| format!("emergency stop at {t:.2} s"))
            ),
            m_off.injected_after_push_j > INJECTION_RATIO * m_on.injected_after_push_j.abs(),
        ),
    };
    summary.claim(
        &format!("compensation OFF: the passivity monitor flags the growth (at {:.2} s)", m_off.flagged_at_s),
        m_off.flagged,
    );
    Ok(Outcome { summary, series: series(on, off)?, figures: figures(on, off) })
}

/// The time series (compensated run's standard columns, both runs' signals).
fn series(on: &Run, off: &Run) -> Result<TimeSeries, String> {
    super::mobile_impedance::series(on, off)
}

fn figures(on: &Run, off: &Run) -> Vec<(&'static str, Figure)> {
    let line = |label: &str, run: &Run, f: &dyn Fn(&Sample) -> f64| {
        Line::new(label, run.samples.iter().map(|s| (s.t, f(s))).collect())
    };
    let push = || {
        vec![Span {
            label: format!("{PUSH_N} N pull at the TCP"),
            from: PUSH_START_S,
            to: PUSH_START_S + PUSH_DURATION_S,
        }]
    };
    let stop = |run: &Run| run.stopped_at_s.map(|t| Span { label: "emergency stop (OFF)".into(), from: t, to: t });
    let spans = || push().into_iter().chain(stop(off)).collect::<Vec<_>>();
    vec![(
        "push.svg",
        Figure {
            title: "mobile_impedance_critical: M_adm = diag(3, 3, 1), D_adm = diag(21, 21, 7) (cf. Fig. 5.8–5.10)"
                .into(),
            x_label: "time (s)".into(),
            panels: vec![
                Panel {
                    title: "TCP deviation in x".into(),
                    y_label: "deviation (m)".into(),
                    lines: vec![
                        line("compensation ON", on, &|s| s.error[0]),
                        line("compensation OFF", off, &|s| s.error[0]),
                    ],
                    spans: spans(),
                },
                Panel {
                    title: "platform x".into(),
                    y_label: "x (m)".into(),
                    lines: vec![
                        line("compensation ON", on, &|s| s.base[0]),
                        line("compensation OFF", off, &|s| s.base[0]),
                    ],
                    spans: spans(),
                },
                Panel {
                    title: "total energy (5.21)".into(),
                    y_label: "energy (J)".into(),
                    lines: vec![
                        line("compensation ON", on, &|s| s.storage[2]),
                        line("compensation OFF", off, &|s| s.storage[2]),
                    ],
                    spans: spans(),
                },
            ],
        },
    )]
}
