//! The registry of named scenarios and the runner behind `host-sim run <scenario>`.
//!
//! A scenario is a module with a `NAME`, a one-line `DESCRIPTION` and a `simulate` function
//! that takes the [`RunOptions`] and returns an [`Outcome`] (time series, summary with its
//! checked claims, figures); [`run`] writes the outcome into the output directory following the
//! convention of [`crate::output`]. Every scenario drives its robot with the one scenario loop,
//! [`crate::sim::run_loop`], builds its simulator with [`RunOptions::simulator`] (or the
//! whole-body rig with [`crate::wbc::rig`]) so `--plant` reaches it, and reports its progress
//! through [`RunOptions::progress`]. `--pil` and `--scalar f32` choose the controller of the
//! whole-body rig ([`crate::wbc::Driver`]); [`run`] refuses them, before running, for the
//! scenarios without that rig (they run their own controllers in `f64`), except `--scalar` for
//! the generic scenarios ([`crate::generic`]), which also take `--robot` (refused by the
//! others). Errors are one-line
//! messages. Tests call the scenario functions directly and assert the same numbers the
//! summary reports.

use std::path::{Path, PathBuf};

use kernel::model::Model;
use kernel::tasks::collision::SweptSphere;

use crate::generic::{self, RobotName};
use crate::output::{self, Figure, Summary, TimeSeries};
use crate::pil::Target;
use crate::plant::{PlantKind, PlantModel};
use crate::replay::{self, Robot};
use crate::scalar::Scalar;
use crate::sim::{SimConfig, Simulator};

pub mod cartesian_step;
pub mod clean_mug;
pub mod energy_planar4;
pub mod hierarchy_common;
pub mod icr_avoidance;
pub mod mobile_impedance;
pub mod mobile_impedance_critical;
pub mod multilevel_arm;
pub mod multilevel_planar;
pub mod multilevel_sim1;
pub mod multilevel_sim2;
pub mod multilevel_sim3;
pub mod projectors_sim1;
pub mod sca_damping;
pub mod soak;
pub mod stability_map;
pub mod stiffness_sim2;
pub mod sweep_floor;
pub mod torso_workspace;
pub mod unilateral_sim;
pub mod wbc_grasp;
pub mod wbc_phri;
pub mod wbc_step;
pub mod wbc_trajectory;
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

/// A phase of a run: when it begins (s) and what happens.
type Phase = (f64, String);

/// A registered scenario.
struct Entry {
    name: &'static str,
    description: &'static str,
    simulate: fn(&RunOptions) -> Result<Outcome, String>,
    /// Extra output files beyond the standard ones, if the scenario has any.
    extra_files: Option<FileWriter>,
    /// The robot `replay.html` draws, if the scenario's table is a run of a robot over time.
    replay: Option<Robot>,
    /// The world-fixed collision volumes the replay draws (table, wall), if any.
    environment: Option<fn() -> Vec<SweptSphere<f64>>>,
    /// The objects the replay draws that the simulator models by their contact surfaces only
    /// (the mug), if any.
    objects: Option<fn() -> Vec<SweptSphere<f64>>>,
    /// The phases of the run the replay names (start time, caption), if the scenario gives them.
    phases: Option<fn() -> Vec<Phase>>,
    /// Where the replay's camera stands (the vector from the scene's centre, m), if the scenario
    /// chooses it.
    view: Option<[f64; 3]>,
    /// What the outcome's table holds.
    table: Table,
    /// Whether the scenario runs the whole-body rig ([`crate::wbc::rig`]), whose controller
    /// `--pil` and `--scalar` choose.
    whole_body_rig: bool,
    /// Whether the scenario runs the generic rig ([`crate::generic`]) on the robot `--robot`
    /// names, with the controller in the scalar `--scalar` names.
    generic_rig: bool,
}

/// What a scenario's [`Outcome::series`] holds, and so the file it is written to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Table {
    /// Samples over time: `timeseries.csv`, decimated by [`RunOptions::record_every`].
    TimeSeries,
    /// A map over a parameter grid, written whole into the named file.
    Grid(&'static str),
}

impl Entry {
    /// A scenario that writes the standard files only.
    const fn new(
        name: &'static str,
        description: &'static str,
        simulate: fn(&RunOptions) -> Result<Outcome, String>,
    ) -> Self {
        Self {
            name,
            description,
            simulate,
            extra_files: None,
            replay: None,
            environment: None,
            objects: None,
            phases: None,
            view: None,
            table: Table::TimeSeries,
            whole_body_rig: false,
            generic_rig: false,
        }
    }
}

/// The registry entry of scenario module `$module` (its `NAME`, `DESCRIPTION` and `simulate`),
/// with the robot its replay draws, if any.
macro_rules! entry {
    ($module:ident) => {
        Entry::new($module::NAME, $module::DESCRIPTION, $module::simulate)
    };
    ($module:ident, $robot:expr) => {
        Entry { replay: Some($robot), ..entry!($module) }
    };
}

/// The planar four-link arm of the thesis' Ch. 4 and 5 simulations with its TCP error columns.
const fn planar4(tcp_error: [&'static str; 2]) -> Robot {
    Robot::PlanarArm { links: 4, tcp_error }
}

/// The registry entry of scenario module `$module` that runs the whole-body rig (Justin).
macro_rules! rig_entry {
    ($module:ident) => {
        Entry { whole_body_rig: true, ..entry!($module, Robot::JUSTIN) }
    };
}

/// The registry entry of generic scenario module `$module` ([`crate::generic`]).
macro_rules! generic_entry {
    ($module:ident) => {
        Entry {
            generic_rig: true,
            ..Entry::new(generic::$module::NAME, generic::$module::DESCRIPTION, generic::$module::simulate)
        }
    };
}

/// The registry: every scenario `host-sim list` shows, in that order.
const SCENARIOS: &[Entry] = &[
    entry!(cartesian_step, cartesian_step::REPLAY),
    entry!(energy_planar4, planar4(["", ""])),
    entry!(projectors_sim1, planar4(["e1.x", "e2.y"])),
    entry!(stiffness_sim2, planar4(["e1.x", "e1.y"])),
    entry!(unilateral_sim, Robot::PlanarArm { links: 3, tcp_error: ["e2.x", "e2.y"] }),
    Entry {
        extra_files: Some(torso_workspace::write_files),
        table: Table::Grid(torso_workspace::GRID_FILE),
        ..entry!(torso_workspace)
    },
    entry!(sca_damping),
    entry!(multilevel_sim1, planar4(["e1.x", "e1.y"])),
    entry!(multilevel_sim2, planar4(["e1.x", "e1.y"])),
    entry!(multilevel_sim3, planar4(["e1.x", "e1.y"])),
    entry!(multilevel_arm, multilevel_arm::REPLAY),
    entry!(mobile_impedance, mobile_impedance::REPLAY),
    entry!(mobile_impedance_critical, mobile_impedance::REPLAY),
    Entry {
        extra_files: Some(stability_map::write_files),
        table: Table::Grid(stability_map::CSV_FILE),
        ..entry!(stability_map)
    },
    Entry { extra_files: Some(icr_avoidance::write_files), ..entry!(icr_avoidance, icr_avoidance::REPLAY) },
    Entry { phases: Some(wbc_step::phases), ..rig_entry!(wbc_step) },
    Entry { phases: Some(wbc_trajectory::phases), ..rig_entry!(wbc_trajectory) },
    Entry { phases: Some(wbc_phri::phases), ..rig_entry!(wbc_phri) },
    Entry {
        environment: Some(|| wbc_grasp::table().to_vec()),
        phases: Some(wbc_grasp::phases),
        ..rig_entry!(wbc_grasp)
    },
    Entry { phases: Some(wipe_window::phases), ..rig_entry!(wipe_window) },
    Entry { phases: Some(sweep_floor::phases), ..rig_entry!(sweep_floor) },
    Entry {
        objects: Some(clean_mug::mug),
        phases: Some(clean_mug::phases),
        view: Some(clean_mug::VIEW),
        ..rig_entry!(clean_mug)
    },
    rig_entry!(soak),
    generic_entry!(reach),
    generic_entry!(posture_push),
    generic_entry!(self_collision),
    generic_entry!(limits),
];

/// The scenarios: `(name, one-line description)`.
pub fn list() -> Vec<(&'static str, &'static str)> {
    SCENARIOS.iter().map(|s| (s.name, s.description)).collect()
}

/// How a scenario runs and where [`run`] writes its outputs: passed from the command line into
/// every scenario.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RunOptions {
    /// Output directory; `None`: `out/<scenario>`.
    pub dir: Option<PathBuf>,
    /// Write every `record_every`-th row of the time series into `timeseries.csv` (≥ 1).
    pub record_every: u64,
    /// The plant every simulator of the run drives ([`crate::plant`]).
    pub plant: PlantKind,
    /// The firmware target that controls the whole-body rig under QEMU, if any ([`crate::pil`]).
    pub pil: Option<Target>,
    /// The scalar of the whole-body rig's host controller ([`crate::scalar`]; ignored with `pil`).
    pub scalar: Scalar,
    /// The imported robot a generic scenario runs on (`--robot`; `None`: the Panda).
    pub robot: Option<RobotName>,
    /// Whether the scenario reports its progress on stderr.
    pub progress: Progress,
}

/// Default decimation of `timeseries.csv`: every 10th control cycle (100 Hz at the 1 kHz loop).
pub const DEFAULT_RECORD_EVERY: u64 = 10;

/// Seed of the realistic plant's noise in every scenario but the soak (which uses `SOAK_SEED`).
pub const PLANT_SEED: u64 = 0x91a7_5eed;

impl Default for RunOptions {
    /// `out/<scenario>`, every 10th row, the ideal plant, the host controller in `f64`, silent.
    fn default() -> Self {
        Self {
            dir: None,
            record_every: DEFAULT_RECORD_EVERY,
            plant: PlantKind::Ideal,
            pil: None,
            scalar: Scalar::F64,
            robot: None,
            progress: Progress::Silent,
        }
    }
}

impl RunOptions {
    /// The realistic plant's model with noise from `seed`, or `None` for the ideal plant.
    pub fn plant_model(&self, seed: u64) -> Option<PlantModel> {
        match self.plant {
            PlantKind::Ideal => None,
            PlantKind::Realistic => Some(PlantModel::justin(seed)),
        }
    }

    /// These options without the progress line (for a scenario's secondary runs).
    pub fn silent(&self) -> Self {
        Self { progress: Progress::Silent, ..self.clone() }
    }

    /// A simulator of `model` with `config`, driving the plant of these options (noise from
    /// [`PLANT_SEED`]).
    pub fn simulator<const N: usize, const B: usize, const F: usize, const U: usize>(
        &self,
        model: Model<f64, N, B, F>,
        config: SimConfig,
    ) -> Result<Simulator<N, B, F, U>, String> {
        let mut sim = Simulator::new(model, config)?;
        sim.set_plant_model(self.plant_model(PLANT_SEED))?;
        Ok(sim)
    }
}

/// Runs scenario `name` and writes `timeseries.csv`, `summary.json`, its SVG plots and, for a
/// run of a robot over time, `replay.html` into the output directory (created if missing);
/// prints a short result on stdout.
///
/// Errors: unknown scenario (the message lists the names), `--pil` or `--scalar f32` for a
/// scenario without the whole-body rig, a failed simulation, an I/O error, or failed claims
/// (after all outputs are written).
pub fn run(name: &str, options: &RunOptions) -> Result<(), String> {
    let Some(entry) = SCENARIOS.iter().find(|s| s.name == name) else {
        let names: Vec<&str> = SCENARIOS.iter().map(|s| s.name).collect();
        return Err(format!("unknown scenario `{name}`; known: {}", names.join(", ")));
    };
    if let (Some(robot), false) = (options.robot, entry.generic_rig) {
        let generic: Vec<&str> = SCENARIOS.iter().filter(|s| s.generic_rig).map(|s| s.name).collect();
        return Err(format!(
            "--robot {}: {name} runs its own robot; the scenarios for imported robots: {}",
            robot.name(),
            generic.join(", ")
        ));
    }
    let scalar_chosen = options.scalar != Scalar::F64 && !entry.generic_rig;
    let chosen = [(options.pil.is_some(), "--pil"), (scalar_chosen, "--scalar f32")];
    if let Some((_, option)) = chosen.iter().find(|(chosen, _)| *chosen && !entry.whole_body_rig) {
        let rigs: Vec<&str> = SCENARIOS.iter().filter(|s| s.whole_body_rig).map(|s| s.name).collect();
        return Err(format!(
            "{option}: {name} does not run the whole-body controller (its own controller runs on the host in f64); \
             the scenarios that do: {}",
            rigs.join(", ")
        ));
    }
    let out = options.dir.clone().unwrap_or_else(|| Path::new("out").join(name));
    let mut outcome = (entry.simulate)(options)?;
    outcome.summary.value("plant", options.plant.name());
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
    if let Some(robot) = entry.replay {
        let story = replay::Story {
            description: entry.description,
            phases: entry.phases.map(|phases| phases()).unwrap_or_default(),
            environment: entry.environment.map(|volumes| volumes()).unwrap_or_default(),
            objects: entry.objects.map(|volumes| volumes()).unwrap_or_default(),
            view: entry.view,
        };
        replay::write(&out, robot, &outcome.series, &outcome.summary, &story)?;
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
    if entry.replay.is_some() {
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
