//! `host-sim` command line: run scenarios, list them, evaluate dynamics of a URDF, import a robot.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use host_sim::generic::RobotName;
use host_sim::import::ImportOptions;
use host_sim::plant::PlantKind;
use host_sim::scalar::Scalar;
use host_sim::scenarios::{Progress, RunOptions, DEFAULT_RECORD_EVERY};

/// Simulated Rollin' Justin under whole-body impedance control.
#[derive(Parser)]
#[command(
    version,
    about,
    after_help = "Environment variables:\n  SOAK_SECONDS  simulated seconds of the `soak` scenario (default 60)\n  SOAK_SEED     seed of the `soak` scenario's goals and pushes (decimal or 0x hexadecimal)\n  SOAK_RECORD_FROM  simulated second from which the `soak` scenario records its rows (default: the whole run)\n  PIL_TIMEOUT_S seconds host-sim waits for the firmware under --pil (default 10)\n  PIL_PLUGIN    a build of the QEMU counting plugin (firmware/wcet/build_plugin.sh): --pil counts every step's instructions into summary.json"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a named scenario; write timeseries.csv, summary.json, SVG plots and, for the robot
    /// scenarios, replay.html (columns and units: docs/OUTPUT.md).
    Run {
        /// Scenario name (see `list`).
        scenario: String,
        /// Output directory (created if missing) [default: out/<scenario>].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Write every N-th control cycle into timeseries.csv (1: every cycle, 1 kHz).
        #[arg(long, value_name = "N", default_value_t = DEFAULT_RECORD_EVERY, value_parser = clap::value_parser!(u64).range(1..))]
        record_every: u64,
        /// The simulated robot: `ideal` (exact torques and sensors, the thesis' figures) or
        /// `realistic` (joint friction, torque-loop lag, one cycle of delay, sensor noise).
        #[arg(long, value_enum, default_value_t = PlantKind::Ideal)]
        plant: PlantKind,
        /// Run the whole-body controller on the firmware image under QEMU (processor in the loop).
        #[arg(long, value_enum)]
        pil: Option<host_sim::pil::Target>,
        /// The scalar of the whole-body controller on the host: `f32` runs it as the boards do (the
        /// simulator stays f64) with the f64 controller alongside on the same frames;
        /// summary.json adds their largest torque difference over the first 0.5 s. Only the
        /// scenarios of the whole-body rig (wbc_*, wipe_window, sweep_floor, clean_mug, soak) and
        /// the generic scenarios (reach, posture_push, self_collision, limits: the controller alone in
        /// f32).
        #[arg(long, value_enum, default_value_t = Scalar::F64, conflicts_with = "pil")]
        scalar: Scalar,
        /// The robot of a generic scenario (`reach`, `posture_push`, `self_collision`, `limits`):
        /// an imported one (`fixtures/robots/<name>`) or `justin` [default: panda]; the other
        /// scenarios run their own robot and refuse it.
        #[arg(long, value_enum)]
        robot: Option<RobotName>,
    },
    /// List the scenarios with a one-line description each.
    List,
    /// Print M, C, g and a frame Jacobian of a URDF robot at the states given as JSON.
    Dynamics {
        /// URDF file.
        #[arg(long)]
        urdf: PathBuf,
        /// Link (frame) whose origin Jacobian is printed.
        #[arg(long)]
        frame: String,
        /// JSON file with an array of {"q": [..], "v": [..]}.
        #[arg(long)]
        states: PathBuf,
    },
    /// Import a robot from its URDF into fixtures/robots/<name>/: the no_std model constructor
    /// (joints on the chains to the TCPs controlled, the others frozen), the swept-sphere
    /// collision model with its pair list, a README. Run from the repository root.
    Import {
        /// URDF file (repository-relative).
        #[arg(long)]
        urdf: String,
        /// Robot name: the directory and module fixtures::robots::<name> (lower case).
        #[arg(long)]
        name: String,
        /// TCP link; repeat for each arm.
        #[arg(long = "tcp", required = true)]
        tcps: Vec<String>,
        /// `planar`: add the platform coordinates x, y, θ in front of the root link.
        #[arg(long, value_enum)]
        base: Option<Base>,
        /// Directory holding the ROS packages that `package://` mesh URIs name.
        #[arg(long)]
        package_path: Option<String>,
        /// The posture of the configuration's gain rule, one value per controlled coordinate in
        /// coordinate order (rad, m), e.g. `--home=0,0.6,0,-1.2,0,0.9,0` [default: the middle of
        /// every joint's range]; needed where a TCP is singular at mid-range.
        #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
        home: Option<Vec<f64>>,
        /// The posture the generic scenarios start from (`HOME` of the module), same form as
        /// `--home`, without changing the gains [default: `--home`, else the middle of every
        /// joint's range].
        #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
        scenario_home: Option<Vec<f64>>,
    },
}

/// The base `import --base` adds.
#[derive(Clone, Copy, clap::ValueEnum)]
enum Base {
    /// An omnidirectional platform: prismatic x, y and continuous θ about z.
    Planar,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run { scenario, out, record_every, plant, pil, scalar, robot } => {
            let options = RunOptions { dir: out, record_every, plant, pil, scalar, robot, progress: Progress::Stderr };
            host_sim::scenarios::run(&scenario, &options)
        }
        Command::List => {
            let scenarios = host_sim::scenarios::list();
            let width = scenarios.iter().map(|(name, _)| name.len()).max().unwrap_or(0);
            for (name, description) in scenarios {
                println!("{name:width$}  {description}");
            }
            Ok(())
        }
        Command::Dynamics { urdf, frame, states } => {
            host_sim::dynamics_cli::run(&urdf, &frame, &states).map(|json| println!("{json}"))
        }
        Command::Import { urdf, name, tcps, base, package_path, home, scenario_home } => {
            let planar_base = matches!(base, Some(Base::Planar));
            let options = ImportOptions {
                root: PathBuf::from("."),
                urdf,
                name,
                tcps,
                planar_base,
                package_path,
                home,
                scenario_home,
            };
            host_sim::import::run(&options)
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}
