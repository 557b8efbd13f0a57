//! `host-sim` command line: run scenarios, list them, evaluate dynamics of a URDF.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Simulated Rollin' Justin under whole-body impedance control.
#[derive(Parser)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a named scenario and write timeseries.csv, summary.json and SVG plots.
    Run {
        /// Scenario name (see `list`).
        scenario: String,
        /// Output directory (created if missing).
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Run the whole-body controller on the firmware image under QEMU (processor in the loop).
        #[arg(long, value_enum)]
        pil: Option<host_sim::pil::Target>,
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
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run { scenario, out, pil } => match pil {
            None => host_sim::scenario::run(&scenario, &out),
            Some(target) => {
                host_sim::pil::select(target).and_then(|()| host_sim::scenario::run(&scenario, &out)).and_then(|()| {
                    if host_sim::pil::started() {
                        Ok(())
                    } else {
                        Err(format!(
                            "--pil: {scenario} does not run the whole-body rig; its controller ran on the host"
                        ))
                    }
                })
            }
        },
        Command::List => {
            for (name, description) in host_sim::scenario::list() {
                println!("{name:24} {description}");
            }
            Ok(())
        }
        Command::Dynamics { urdf, frame, states } => {
            host_sim::dynamics_cli::run(&urdf, &frame, &states).map(|json| println!("{json}"))
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
