//! Pieces shared by the Chapter 4 scenarios (`projectors_sim1`, `stiffness_sim2`,
//! `unilateral_sim`): their control cycle, the settling-time criterion, wide time-series columns
//! for compared variants, and plot helpers.

use hal::JointTorqueInterface;
use nalgebra::SVector;

use crate::output::TimeSeries;
use crate::sim::Simulator;

/// A time series with the columns `t` and `signals`.
pub fn series_with_time(signals: Vec<String>) -> TimeSeries {
    let mut columns = vec!["t".to_owned()];
    columns.extend(signals);
    TimeSeries::new(columns)
}

/// One control cycle of a fixed-base arm at `time_s`: reads the joints, runs `control`
/// (positions, velocities → torque and the row's signals), writes the torque and returns the
/// row `t, q, q̇, τ (applied), signals…`.
pub fn control_cycle<const N: usize, const B: usize, const F: usize, S>(
    sim: &mut Simulator<N, B, F, N>,
    time_s: f64,
    control: impl FnOnce(&SVector<f64, N>, &SVector<f64, N>) -> Result<(SVector<f64, N>, S), String>,
) -> Result<Vec<f64>, String>
where
    S: IntoIterator<Item = f64>,
{
    let sample = JointTorqueInterface::read(sim)?;
    let (q, v) = (SVector::from(sample.position), SVector::from(sample.velocity));
    let (torque, signals) = control(&q, &v)?;
    JointTorqueInterface::write_torque(sim, &torque.into())?;
    let mut row = vec![time_s];
    row.extend(q.iter().chain(v.iter()).chain(sim.applied_torque().iter()));
    row.extend(signals);
    Ok(row)
}

/// Settling time (s) of `signal` towards its final value: the earliest sample time `t_k` after
/// which `|e(t) − e(T)| ≤ fraction · max_t |e(t) − e(T)|` holds up to the end `T`, i.e. the
/// signal stays within `fraction` (e.g. 2 %) of its largest excursion from the final value.
/// Measured from `from` (s). `0` for a constant signal; `NaN` for an empty or non-finite one.
///
/// Relative to the final value (not to zero) so that it measures when the steady state is
/// reached also where that steady state carries an error (successive or unprojected
/// hierarchies, the joint-impedance level).
pub fn settle_time(t: &[f64], signal: &[f64], from: f64, fraction: f64) -> f64 {
    let window: Vec<(f64, f64)> =
        t.iter().copied().zip(signal.iter().copied()).filter(|(ti, _)| *ti >= from - 1e-12).collect();
    let Some(&(_, end)) = window.last() else {
        return f64::NAN;
    };
    if window.iter().any(|(_, e)| !e.is_finite()) {
        return f64::NAN;
    }
    let excursion = window.iter().map(|(_, e)| (e - end).abs()).fold(0.0, f64::max);
    let band = fraction * excursion;
    // The first sample after the last one outside the band (the final sample is always inside).
    let last_outside = window.iter().rposition(|(_, e)| (e - end).abs() > band);
    match last_outside.and_then(|k| window.get(k + 1)) {
        Some((settled, _)) => settled - from,
        None => 0.0,
    }
}

/// Column names `<prefix><name>` for every name.
pub fn prefixed(prefix: &str, names: &[String]) -> Vec<String> {
    names.iter().map(|n| format!("{prefix}{n}")).collect()
}

/// `(t, y)` points of two equally long columns.
pub fn points(t: &[f64], y: &[f64]) -> Vec<(f64, f64)> {
    t.iter().copied().zip(y.iter().copied()).collect()
}

/// Column `name` of `series` or an error naming it.
pub fn column(series: &TimeSeries, name: &str) -> Result<Vec<f64>, String> {
    series.column(name).ok_or_else(|| format!("no column {name}"))
}

/// Largest absolute value (0 for an empty slice; NaN propagates as NaN).
pub fn max_abs(values: &[f64]) -> f64 {
    values.iter().fold(0.0_f64, |m, v| if v.is_nan() || m.is_nan() { f64::NAN } else { m.max(v.abs()) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settle_time_of_a_first_order_step() {
        let t: Vec<f64> = (0..=5000).map(|k| f64::from(k) * 1e-3).collect();
        let e: Vec<f64> = t.iter().map(|t| 0.2 * (-t / 0.5).exp()).collect();
        // |e − e(T)| ≤ 2 % of 0.2 (minus e(T) ≈ 9e-6): t ≈ 0.5 ln 50 = 1.956 s.
        let s = settle_time(&t, &e, 0.0, 0.02);
        assert!((s - 1.956).abs() < 2e-3, "{s}");
        assert_eq!(settle_time(&t, &vec![1.0; t.len()], 0.0, 0.02), 0.0);
        assert!(settle_time(&[], &[], 0.0, 0.02).is_nan());
    }
}
