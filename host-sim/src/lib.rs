//! # host-sim: the simulated robot behind the `hal` traits
//!
//! The host side of the product: it loads robot descriptions (URDF), simulates the robot's
//! rigid-body dynamics at a fine fixed step with the mobile base driven kinematically by its
//! velocity interface, implements the `hal` traits over that simulation, runs named scenarios
//! (controller in the loop at 1 kHz) and writes their time series, summaries and plots.
//!
//! Modules:
//! - [`urdf`]: URDF → kernel [`kernel::Model`] (fixed links lumped into their parents).
//! - [`dynamics_cli`]: the `dynamics` subcommand (M, C, g, J of a URDF at given states).
//! - [`import`]: the `import` subcommand: a URDF → `fixtures/robots/<name>/` (model, collision model).
//! - [`sim`]: the simulator and its `hal` implementations.
//! - [`plant`]: the realistic plant's friction, torque lag, delay and sensor noise.
//! - [`controllers`]: controllers run in the loop by scenarios.
//! - [`output`]: the scenario output convention (CSV, summary JSON, SVG plots).
//! - [`scenarios`]: the registry of named scenarios, their run options, one module per scenario.
//! - [`replay`]: `replay.html`, the 3-D replay of a run of a robot (Justin, a planar arm, the platform).
//! - [`wbc`]: the simulated Justin under the kernel's whole-body controller.
//! - [`pil`]: processor-in-the-loop: the firmware image under QEMU as the rig's controller.
//! - [`scalar`]: `--scalar`: the rig's controller in `f32` on the host, fed as a board is fed.
//!
//! Errors at this level are reported as one-line messages; nothing here panics on bad input.

pub mod codegen;
pub mod controllers;
pub mod dynamics_cli;
pub mod generic;
pub mod import;
pub mod mobile_controller;
pub mod output;
pub mod pil;
pub mod plant;
pub mod replay;
pub mod scalar;
pub mod scenarios;
pub mod sim;
pub mod urdf;
pub mod wbc;
pub mod wheels;
