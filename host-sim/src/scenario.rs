//! The registry of named scenarios and the runner behind `host-sim run <scenario>`.
//!
//! A scenario is a function that simulates and returns an [`Outcome`] (time series, summary with
//! its checked claims, figures); [`run`] writes the outcome into the output directory following
//! the convention of [`crate::output`]. Tests call the scenario functions directly and assert the
//! same numbers the summary reports.

use std::path::{Path, PathBuf};

use kernel::tasks::collision::SweptSphere;

use crate::output::{self, Figure, Summary, TimeSeries};
use crate::replay;

#[path = "scenarios/cartesian_step.rs"]
pub mod cartesian_step;
#[path = "scenarios/clean_mug.rs"]
pub mod clean_mug;
#[path = "scenarios/energy_planar4.rs"]
pub mod energy_planar4;
#[path = "scenarios/hierarchy_common.rs"]
pub mod hierarchy_common;
#[path = "scenarios/icr_avoidance.rs"]
pub mod icr_avoidance;
#[path = "scenarios/mobile_impedance.rs"]
pub mod mobile_impedance;
#[path = "scenarios/mobile_impedance_critical.rs"]
pub mod mobile_impedance_critical;
#[path = "scenarios/multilevel_arm.rs"]
pub mod multilevel_arm;
#[path = "scenarios/multilevel_planar.rs"]
pub mod multilevel_planar;
#[path = "scenarios/multilevel_sim1.rs"]
pub mod multilevel_sim1;
#[path = "scenarios/multilevel_sim2.rs"]
pub mod multilevel_sim2;
#[path = "scenarios/multilevel_sim3.rs"]
pub mod multilevel_sim3;
#[path = "scenarios/projectors_sim1.rs"]
pub mod projectors_sim1;
#[path = "scenarios/sca_damping.rs"]
pub mod sca_damping;
#[path = "scenarios/soak.rs"]
pub mod soak;
#[path = "scenarios/stability_map.rs"]
pub mod stability_map;
#[path = "scenarios/stiffness_sim2.rs"]
pub mod stiffness_sim2;
#[path = "scenarios/sweep_floor.rs"]
pub mod sweep_floor;
#[path = "scenarios/torso_workspace.rs"]
pub mod torso_workspace;
#[path = "scenarios/unilateral_sim.rs"]
pub mod unilateral_sim;
#[path = "scenarios/wbc_grasp.rs"]
pub mod wbc_grasp;
#[path = "scenarios/wbc_phri.rs"]
pub mod wbc_phri;
#[path = "scenarios/wbc_step.rs"]
pub mod wbc_step;
#[path = "scenarios/wbc_trajectory.rs"]
pub mod wbc_trajectory;
#[path = "scenarios/wipe_window.rs"]
pub mod wipe_window;

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

/// Writes the files a scenario draws itself from its [`Outcome`] (maps and plots that are not
/// line figures, extra tables); returns their names.
type FileWriter = fn(&Path, &Outcome) -> Result<Vec<&'static str>, String>;

/// A registered scenario.
struct Entry {
    name: &'static str,
    description: &'static str,
    simulate: fn(Progress) -> Result<Outcome, String>,
    /// Extra output files beyond the standard ones, if the scenario has any.
    extra_files: Option<FileWriter>,
    /// The world-fixed collision volumes the replay draws (table, wall), if any.
    environment: Option<fn() -> Vec<SweptSphere<f64>>>,
    /// What the outcome's table holds.
    table: Table,
}

/// What a scenario's [`Outcome::series`] holds, and so the file it is written to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Table {
    /// Samples over time: `timeseries.csv`, decimated by [`OutputOptions::record_every`].
    TimeSeries,
    /// A map over a parameter grid, written whole into the named file.
    Grid(&'static str),
}

const SCENARIOS: &[Entry] = &[
    Entry {
        name: cartesian_step::NAME,
        description: cartesian_step::DESCRIPTION,
        simulate: cartesian_step::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: energy_planar4::NAME,
        description: energy_planar4::DESCRIPTION,
        simulate: energy_planar4::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: projectors_sim1::NAME,
        description: projectors_sim1::DESCRIPTION,
        simulate: projectors_sim1::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: stiffness_sim2::NAME,
        description: stiffness_sim2::DESCRIPTION,
        simulate: stiffness_sim2::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: unilateral_sim::NAME,
        description: unilateral_sim::DESCRIPTION,
        simulate: unilateral_sim::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: torso_workspace::NAME,
        description: torso_workspace::DESCRIPTION,
        simulate: torso_workspace::simulate,
        extra_files: Some(torso_workspace::write_files),
        environment: None,
        table: Table::Grid(torso_workspace::GRID_FILE),
    },
    Entry {
        name: sca_damping::NAME,
        description: sca_damping::DESCRIPTION,
        simulate: sca_damping::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: multilevel_sim1::NAME,
        description: multilevel_sim1::DESCRIPTION,
        simulate: multilevel_sim1::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: multilevel_sim2::NAME,
        description: multilevel_sim2::DESCRIPTION,
        simulate: multilevel_sim2::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: multilevel_sim3::NAME,
        description: multilevel_sim3::DESCRIPTION,
        simulate: multilevel_sim3::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: multilevel_arm::NAME,
        description: multilevel_arm::DESCRIPTION,
        simulate: multilevel_arm::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: mobile_impedance::NAME,
        description: mobile_impedance::DESCRIPTION,
        simulate: mobile_impedance::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: mobile_impedance_critical::NAME,
        description: mobile_impedance_critical::DESCRIPTION,
        simulate: mobile_impedance_critical::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: stability_map::NAME,
        description: stability_map::DESCRIPTION,
        simulate: stability_map::simulate,
        extra_files: Some(stability_map::write_files),
        environment: None,
        table: Table::Grid(stability_map::CSV_FILE),
    },
    Entry {
        name: icr_avoidance::NAME,
        description: icr_avoidance::DESCRIPTION,
        simulate: icr_avoidance::simulate,
        extra_files: Some(icr_avoidance::write_files),
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: wbc_step::NAME,
        description: wbc_step::DESCRIPTION,
        simulate: wbc_step::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: wbc_trajectory::NAME,
        description: wbc_trajectory::DESCRIPTION,
        simulate: wbc_trajectory::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: wbc_phri::NAME,
        description: wbc_phri::DESCRIPTION,
        simulate: wbc_phri::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: wbc_grasp::NAME,
        description: wbc_grasp::DESCRIPTION,
        simulate: wbc_grasp::simulate,
        extra_files: None,
        environment: Some(|| wbc_grasp::table().to_vec()),
        table: Table::TimeSeries,
    },
    Entry {
        name: wipe_window::NAME,
        description: wipe_window::DESCRIPTION,
        simulate: wipe_window::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: sweep_floor::NAME,
        description: sweep_floor::DESCRIPTION,
        simulate: sweep_floor::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: clean_mug::NAME,
        description: clean_mug::DESCRIPTION,
        simulate: clean_mug::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
    Entry {
        name: soak::NAME,
        description: soak::DESCRIPTION,
        simulate: soak::simulate,
        extra_files: None,
        environment: None,
        table: Table::TimeSeries,
    },
];

/// The scenarios: `(name, one-line description)`.
pub fn list() -> Vec<(&'static str, &'static str)> {
    SCENARIOS.iter().map(|s| (s.name, s.description)).collect()
}

/// Where and how [`run`] writes a scenario's outputs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OutputOptions {
    /// Output directory; `None`: `out/<scenario>`.
    pub dir: Option<PathBuf>,
    /// Write every `record_every`-th row of the time series into `timeseries.csv` (≥ 1).
    pub record_every: u64,
}

/// Default decimation of `timeseries.csv`: every 10th control cycle (100 Hz at the 1 kHz loop).
pub const DEFAULT_RECORD_EVERY: u64 = 10;

impl Default for OutputOptions {
    fn default() -> Self {
        Self { dir: None, record_every: DEFAULT_RECORD_EVERY }
    }
}

/// Runs scenario `name` and writes `timeseries.csv`, `summary.json`, its SVG plots and, for a
/// scenario of the Justin robot, `replay.html` into the output directory (created if missing);
/// prints a short result on stdout.
///
/// Errors: unknown scenario (the message lists the names), a failed simulation, an I/O error,
/// or failed claims (after all outputs are written).
pub fn run(name: &str, options: &OutputOptions) -> Result<(), String> {
    let Some(entry) = SCENARIOS.iter().find(|s| s.name == name) else {
        let names: Vec<&str> = SCENARIOS.iter().map(|s| s.name).collect();
        return Err(format!("unknown scenario `{name}`; known: {}", names.join(", ")));
    };
    let out = options.dir.clone().unwrap_or_else(|| Path::new("out").join(name));
    let outcome = (entry.simulate)(Progress::Stderr)?;
    output::create_dir(&out)?;
    let (table_file, every) = match entry.table {
        Table::TimeSeries => ("timeseries.csv", options.record_every),
        Table::Grid(file) => (file, 1),
    };
    outcome.series.write_csv(&out.join(table_file), every)?;
    outcome.summary.write_json(&out.join("summary.json"))?;
    let mut files = vec![table_file, "summary.json"];
    for (file, figure) in &outcome.figures {
        output::plot(&out.join(file), figure)?;
        files.push(file);
    }
    if let Some(write) = entry.extra_files {
        files.extend(write(&out, &outcome)?);
    }
    let replayable = replay::is_replayable(&outcome.series);
    if replayable {
        let environment = entry.environment.map(|volumes| volumes()).unwrap_or_default();
        replay::write(&out, &outcome.series, &outcome.summary, &environment)?;
        files.push("replay.html");
    }
    let passed = outcome.summary.passed_claims();
    let failed = outcome.summary.failed_claims();
    println!("{name}: {} claims passed, {} failed", passed.len(), failed.len());
    for claim in passed {
        println!("  pass: {claim}");
    }
    for claim in failed {
        println!("  FAIL: {claim}");
    }
    println!("wrote {} in {}", files.join(", "), out.display());
    println!("columns and units of {table_file}: docs/OUTPUT.md");
    if replayable {
        println!("watch the robot: open {} in a browser", out.join("replay.html").display());
    }
    if failed.is_empty() {
        Ok(())
    } else {
        Err(format!("{name}: {} claim(s) failed", failed.len()))
    }
}

/// Standard column names for per-joint signals: `q.<joint>`, `dq.<joint>`, `tau.<joint>`.
pub fn joint_columns(names: &[&str]) -> Vec<String> {
    ["q", "dq", "tau"].iter().flat_map(|p| names.iter().map(move |n| format!("{p}.{n}"))).collect()
}

/// Columns `e<level>.x, .y, .z, .rx, .ry, .rz` of a 6-D Cartesian task error.
pub fn pose_error_columns(level: usize) -> Vec<String> {
    ["x", "y", "z", "rx", "ry", "rz"].iter().map(|a| format!("e{level}.{a}")).collect()
}

/// Index of `name` in a time series' columns.
pub(crate) fn column_index(series: &TimeSeries, name: &str) -> Result<usize, String> {
    series.columns().iter().position(|c| c == name).ok_or_else(|| format!("no column {name}"))
}
