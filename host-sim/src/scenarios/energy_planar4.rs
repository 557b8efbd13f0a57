//! `energy_planar4`: the unforced planar 4-DOF arm of Fig. 4.1 conserves its energy.
//!
//! The arm ([`fixtures::planar::four_dof`]: four 0.5 m links, 1 kg point masses at their
//! centres, gravity 9.81 m/s² in the plane) is released at rest from the initial configuration
//! of Table 5.4 (TCP at (0.84 m, 0.96 m), `Σq = −1.37 rad`, `q₁ = 0.40 rad`) with `τ = 0` and no
//! damping, and swings for 10 s. Without input and dissipation the total energy `T + V` is a
//! constant of motion, so its drift measures the integrator (RK4 at [`PHYSICS_STEP_S`]) and the
//! consistency of the kernel's `M`, `C q̇ + g` and energies.
//!
//! Claim: the relative total-energy drift `max_t |E(t) − E(0)| / E_scale < 1e-6`. The scale
//! `E_scale = max_t T(t)` is the largest kinetic energy reached: the energy of the motion,
//! independent of the arbitrary zero of the potential.

use fixtures::planar::{four_dof, four_dof_configuration};
use nalgebra::SVector;

use super::{joint_columns, Outcome, RunOptions};
use crate::output::{Figure, Line, Panel, Summary, TimeSeries};
use crate::sim::{run_loop, SimConfig, Simulator, CONTROL_PERIOD_S, DEFAULT_PHYSICS_STEP_S};

/// Registry name.
pub const NAME: &str = "energy_planar4";
/// One-line description.
pub const DESCRIPTION: &str = "planar 4-DOF arm (Fig. 4.1), tau = 0, 10 s: total energy drift < 1e-6";
/// Simulated time (s).
pub const DURATION_S: f64 = 10.0;
/// Largest admissible relative energy drift.
pub const DRIFT_BOUND: f64 = 1e-6;

/// Physics step of the claim (s): a quarter of the default step.
///
/// The unforced chain whips its outer links to over 200 rad/s (the links are point masses, so
/// the last joint carries only 0.0625 kg m²). RK4's energy error per step grows like
/// `(ω h)⁵`; at the default 1/6000 s the drift over 10 s is about 3e-6, at 1/24000 s about
/// 1e-8 (fourth order: ×1/16 per halving). The summary reports both.
pub const PHYSICS_STEP_S: f64 = 1.0 / 24_000.0;

/// Energy record of one run: time series and the drift numbers.
struct Run {
    series: TimeSeries,
    drift_j: f64,
    scale_j: f64,
    initial_j: f64,
    duration_s: f64,
    physics_steps: u64,
}

/// Releases the arm from the Table 5.4 pose and records every control period (1 ms).
fn release(physics_step_s: f64, options: &RunOptions) -> Result<Run, String> {
    let model = four_dof::<f64>().map_err(|e| format!("planar model: {e}"))?;
    let config = SimConfig { physics_step_s, ..SimConfig::default() };
    let mut sim: Simulator<4, 4, 5, 4> = options.simulator(model, config)?;
    let q0 = four_dof_configuration(0.84, 0.96, -1.37, 0.40, false).ok_or("Table 5.4 pose unreachable")?;
    sim.set_state(q0, SVector::zeros()).map_err(|e| e.to_string())?;

    let names = ["1", "2", "3", "4"];
    let mut columns = vec!["t".to_owned()];
    columns.extend(joint_columns(&names));
    columns.extend(["kinetic_energy_j", "potential_energy_j", "total_energy_j"].map(String::from));
    let mut series = TimeSeries::new(columns);

    let report = run_loop(
        &mut sim,
        DURATION_S,
        CONTROL_PERIOD_S,
        // τ = 0: no controller, only the recording.
        |sim, info| {
            if info.cycle % 250 == 0 {
                options.progress.report(NAME, info.time_s, DURATION_S);
            }
            let energies = sim.energies()?;
            let mut row = vec![info.time_s];
            row.extend(sim.q().iter().chain(sim.v().iter()).chain(sim.applied_torque().iter()));
            row.extend([energies.kinetic, energies.potential, energies.total]);
            series.push(row)
        },
    )?;
    options.progress.finish();
    let last = sim.energies().map_err(|e| e.to_string())?;
    let kinetic = series.column("kinetic_energy_j").unwrap_or_default();
    let mut total = series.column("total_energy_j").unwrap_or_default();
    total.push(last.total);
    let initial_j = total.first().copied().unwrap_or(f64::NAN);
    Ok(Run {
        drift_j: total.iter().map(|e| (e - initial_j).abs()).fold(0.0, f64::max),
        scale_j: kinetic.iter().copied().fold(last.kinetic, f64::max),
        initial_j,
        duration_s: sim.time_s(),
        physics_steps: report.physics_steps,
        series,
    })
}

/// Runs the scenario: the claim at [`PHYSICS_STEP_S`], the drift at the default step for
/// comparison.
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    let run = release(PHYSICS_STEP_S, options)?;
    let coarse = release(DEFAULT_PHYSICS_STEP_S, &options.silent())?;
    let drift_rel = run.drift_j / run.scale_j;
    let coarse_rel = coarse.drift_j / coarse.scale_j;

    let mut summary = Summary::new(NAME);
    summary
        .metric("energy_drift_rel", drift_rel)
        .metric("energy_drift_j", run.drift_j)
        .metric("energy_scale_j", run.scale_j)
        .metric("initial_total_energy_j", run.initial_j)
        .metric("duration_s", run.duration_s)
        .metric("physics_step_s", PHYSICS_STEP_S)
        .value("physics_steps", run.physics_steps)
        .metric("energy_drift_rel_default_step", coarse_rel)
        .metric("default_physics_step_s", DEFAULT_PHYSICS_STEP_S);
    summary.claim(&format!("relative total-energy drift {drift_rel:.2e} < {DRIFT_BOUND:.0e}"), drift_rel < DRIFT_BOUND);

    let series = run.series;
    let scale = run.scale_j;
    let e0 = run.initial_j;
    let t = series.column("t").unwrap_or_default();
    let kinetic = series.column("kinetic_energy_j").unwrap_or_default();
    let potential = series.column("potential_energy_j").unwrap_or_default();
    let total = series.column("total_energy_j").unwrap_or_default();
    let coarse_total = coarse.series.column("total_energy_j").unwrap_or_default();
    let points = |y: &[f64]| t.iter().copied().zip(y.iter().copied()).collect::<Vec<_>>();
    let drift: Vec<f64> = total.iter().map(|e| (e - e0) / scale * 1e6).collect();
    let coarse_drift: Vec<f64> = coarse_total.iter().map(|e| (e - coarse.initial_j) / coarse.scale_j * 1e6).collect();
    let figure = Figure {
        title: "energy_planar4: unforced planar 4-DOF arm (Fig. 4.1) released from the Table 5.4 pose".into(),
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: "energies".into(),
                y_label: "energy (J)".into(),
                lines: vec![
                    Line::new("kinetic T", points(&kinetic)),
                    Line::new("potential V", points(&potential)),
                    Line::new("total T + V", points(&total)),
                ],
                spans: vec![],
            },
            Panel {
                title: format!("total-energy drift relative to max kinetic energy ({scale:.1} J)"),
                y_label: "(E − E0) / scale (ppm)".into(),
                lines: vec![
                    Line::new("RK4, h = 1/24000 s (claim)", points(&drift)),
                    Line::new("RK4, h = 1/6000 s (default)", points(&coarse_drift)),
                    Line::dashed("claim bound 1 ppm", vec![(0.0, -1.0), (DURATION_S, -1.0)]),
                    Line::dashed("", vec![(0.0, 1.0), (DURATION_S, 1.0)]),
                ],
                spans: vec![],
            },
        ],
    };
    Ok(Outcome { summary, series, figures: vec![("energy.svg", figure)] })
}
