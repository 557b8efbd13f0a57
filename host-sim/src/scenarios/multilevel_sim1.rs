//! `multilevel_sim1`: simulation #1 of Sec. 5.2.5 (decoupling, high damping).
//!
//! The planar 4-DOF arm under the multi-level compliance controller (5.58) with the hierarchy
//! of Table 5.4 and the "Sim. #1" gains of Table 5.5 (`K₁ = 1000 I` N/m, `D₁ = 40 I` Ns/m,
//! `K₂ = 800` Nm/rad, `D₂ = 5` Nms/rad, `K₃ = 2400` Nm/rad, `D₃ = 15` Nms/rad), exact model,
//! `τ_μ` on; see [`super::multilevel_planar`] for the setup. Simulated for 1 s (Fig. 5.16 shows
//! 0.5 s).
//!
//! Claims (L6573, L6907):
//! - "They all converge to zero within less than 0.5 s": every task coordinate enters and
//!   stays in a band of [`SETTLE_BAND_REL`] of its initial error before [`SETTLE_BOUND_S`];
//! - "Dynamic consistency is achieved … a strict hierarchy realized" (Fig. 5.17 right, axes
//!   ×10⁻¹² and ×10⁻¹³): every cross-level acceleration stays below [`CROSS_ACCELERATION_BOUND`].
//!
//! Reported for comparison: the torque ranges of `τ_1^p`, `τ_2^p`, `τ_3^p` (Fig. 5.17 left, axis
//! ticks about −50…150, −400…200, −100…200 Nm).

use super::multilevel_planar::{column, figures, peak, run, settle_time, Setup, SIM1_GAINS, THESIS_CONTROL_PERIOD_S};
use super::{Outcome, RunOptions};
use crate::output::Summary;

/// Registry name.
pub const NAME: &str = "multilevel_sim1";
/// One-line description.
pub const DESCRIPTION: &str =
    "planar 4-DOF arm, 3-level compliance (Tables 5.4/5.5, sim #1): errors settle < 0.5 s, no cross-level acceleration";
/// Simulated time (s).
pub const DURATION_S: f64 = 1.0;
/// Settling band, relative to each coordinate's initial error.
pub const SETTLE_BAND_REL: f64 = 0.02;
/// Latest admissible settling time (s).
pub const SETTLE_BOUND_S: f64 = 0.5;
/// Largest admissible cross-level acceleration (m/s², rad/s²).
pub const CROSS_ACCELERATION_BOUND: f64 = 1e-9;

pub use super::multilevel_planar::CROSS_COLUMNS;

/// Runs the scenario.
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    let setup = Setup {
        name: NAME,
        gains: SIM1_GAINS,
        controller_model: fixtures::planar::four_dof::<f64>().map_err(|e| e.to_string())?,
        coriolis_decoupling: true,
        duration_s: DURATION_S,
        control_period_s: THESIS_CONTROL_PERIOD_S,
    };
    let series = run(&setup, options)?;
    let t = column(&series, "t")?;
    let mut summary = Summary::new(NAME);
    let mut worst_settle: f64 = 0.0;
    for (name, key) in [("e1.x", "e1_x"), ("e1.y", "e1_y"), ("e2.rot", "e2_rot"), ("e3.q1", "e3_q1")] {
        let e = column(&series, name)?;
        let initial = e.first().copied().unwrap_or_default().abs();
        let settle = settle_time(&t, &e, SETTLE_BAND_REL * initial);
        worst_settle = worst_settle.max(settle);
        summary.metric(&format!("settle_time_{key}_s"), settle).metric(&format!("initial_error_{key}"), initial);
    }
    let mut worst_cross: f64 = 0.0;
    for name in CROSS_COLUMNS {
        let value = peak(&column(&series, name)?);
        worst_cross = worst_cross.max(value);
        summary.metric(&format!("max_{}", name.replace('.', "_")), value);
    }
    for level in 1..=3 {
        let mut all = Vec::new();
        for k in 1..=4 {
            all.extend(column(&series, &format!("tau{level}p.{k}"))?);
        }
        let (low, high) = all.iter().fold((0.0_f64, 0.0_f64), |(l, h), x| (l.min(*x), h.max(*x)));
        summary.metric(&format!("tau{level}p_min_nm"), low).metric(&format!("tau{level}p_max_nm"), high);
    }
    summary
        .metric("settle_time_max_s", worst_settle)
        .metric("cross_acceleration_max", worst_cross)
        .metric("duration_s", DURATION_S);
    summary.claim(
        &format!("all task errors within {SETTLE_BAND_REL} of their initial value after {worst_settle:.3} s < {SETTLE_BOUND_S} s"),
        worst_settle < SETTLE_BOUND_S,
    );
    summary.claim(
        &format!("cross-level accelerations {worst_cross:.1e} < {CROSS_ACCELERATION_BOUND:.0e} (dynamic consistency)"),
        worst_cross < CROSS_ACCELERATION_BOUND,
    );
    let figures = figures(&series, NAME)?;
    Ok(Outcome { summary, series, figures })
}
