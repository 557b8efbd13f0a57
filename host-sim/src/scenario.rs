//! The registry of named scenarios and the runner behind `host-sim run <scenario> --out <dir>`.
//!
//! A scenario is a function that simulates and returns an [`Outcome`] (time series, summary with
//! its checked claims, figures); [`run`] writes the outcome into the output directory following
//! the convention of [`crate::output`]. Tests call the scenario functions directly and assert the
//! same numbers the summary reports.

use std::path::Path;

use crate::output::{self, Figure, Summary, TimeSeries};

#[path = "scenarios/cartesian_step.rs"]
pub mod cartesian_step;
#[path = "scenarios/energy_planar4.rs"]
pub mod energy_planar4;

/// What a scenario produced.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The summary: metrics and claims.
    pub summary: Summary,
    /// The time series, one row per control cycle.
    pub series: TimeSeries,
    /// Figures with their file names (`*.svg`), the main one first.
    pub figures: Vec<(&'static str, Figure)>,
}

/// Whether a scenario reports its progress on stderr.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Progress {
    /// Print a progress line on stderr while running (the CLI).
    Stderr,
    /// Stay silent (tests).
    Silent,
}

impl Progress {
    /// Reports simulated time `t_s` of `total_s` for scenario `name` (overwrites its line).
    pub fn report(self, name: &str, t_s: f64, total_s: f64) {
        if self == Self::Stderr {
            eprint!("\r{name}: t = {t_s:5.2} s of {total_s:.2} s");
        }
    }

    /// Ends the progress line.
    pub fn finish(self) {
        if self == Self::Stderr {
            eprintln!();
        }
    }
}

/// A registered scenario.
struct Entry {
    name: &'static str,
    description: &'static str,
    simulate: fn(Progress) -> Result<Outcome, String>,
}

const SCENARIOS: &[Entry] = &[
    Entry {
        name: cartesian_step::NAME,
        description: cartesian_step::DESCRIPTION,
        simulate: cartesian_step::simulate,
    },
    Entry {
        name: energy_planar4::NAME,
        description: energy_planar4::DESCRIPTION,
        simulate: energy_planar4::simulate,
    },
];

/// The scenarios: `(name, one-line description)`.
pub fn list() -> Vec<(&'static str, &'static str)> {
    SCENARIOS.iter().map(|s| (s.name, s.description)).collect()
}

/// Runs scenario `name` and writes `timeseries.csv`, `summary.json` and its SVG plots into
/// `out` (created if missing); prints a short result on stdout.
///
/// Errors: unknown scenario (the message lists the names), a failed simulation, an I/O error,
/// or failed claims (after all outputs are written).
pub fn run(name: &str, out: &Path) -> Result<(), String> {
    let Some(entry) = SCENARIOS.iter().find(|s| s.name == name) else {
        let names: Vec<&str> = SCENARIOS.iter().map(|s| s.name).collect();
        return Err(format!("unknown scenario `{name}`; known: {}", names.join(", ")));
    };
    let outcome = (entry.simulate)(Progress::Stderr)?;
    output::create_dir(out)?;
    outcome.series.write_csv(&out.join("timeseries.csv"))?;
    outcome.summary.write_json(&out.join("summary.json"))?;
    let mut files = vec!["timeseries.csv", "summary.json"];
    for (file, figure) in &outcome.figures {
        output::plot(&out.join(file), figure)?;
        files.push(file);
    }
    let passed = outcome.summary.passed_claims();
    let failed = outcome.summary.failed_claims();
    println!(
        "{name}: {} claims passed, {} failed; wrote {} in {}",
        passed.len(),
        failed.len(),
        files.join(", "),
        out.display()
    );
    for claim in passed {
        println!("  pass: {claim}");
    }
    for claim in failed {
        println!("  FAIL: {claim}");
    }
    if failed.is_empty() {
        Ok(())
    } else {
        Err(format!("{name}: {} claim(s) failed", failed.len()))
    }
}

/// Standard column names for per-joint signals: `q.<joint>`, `dq.<joint>`, `tau.<joint>`.
pub fn joint_columns(names: &[&str]) -> Vec<String> {
    ["q", "dq", "tau"]
        .iter()
        .flat_map(|p| names.iter().map(move |n| format!("{p}.{n}")))
        .collect()
}

/// Columns `e<level>.x, .y, .z, .rx, .ry, .rz` of a 6-D Cartesian task error.
pub fn pose_error_columns(level: usize) -> Vec<String> {
    ["x", "y", "z", "rx", "ry", "rz"]
        .iter()
        .map(|a| format!("e{level}.{a}"))
        .collect()
}

/// Index of `name` in a time series' columns.
pub(crate) fn column_index(series: &TimeSeries, name: &str) -> Result<usize, String> {
    series
        .columns()
        .iter()
        .position(|c| c == name)
        .ok_or_else(|| format!("no column {name}"))
}
