//! # Whole-body impedance control kernel
//!
//! A `no_std`, allocation-free, panic-free implementation of the controller of A. Dietrich,
//! *Whole-Body Impedance Control of Wheeled Humanoid Robots* (TU München, 2015), for robots
//! whose degrees of freedom are known at compile time.
//!
//! ## Layers
//! Each layer uses only the layers listed before it:
//! 1. [`math`]: spatial vector algebra, guarded scalar operations.
//! 2. [`model`]: the constant robot description [`model::Model`] (kinematic tree, coupled
//!    joints, frames, limits, validated once) and its preallocated workspace [`model::Data`].
//! 3. [`dynamics`]: rigid-body algorithms (kinematics, Jacobians, RNEA, CRBA, Coriolis matrix,
//!    energies), one per file, writing into `Data`.
//! 4. [`tasks`]: the control tasks of Ch. 3 as one-dimensional task rows.
//! 5. [`hierarchy`]: the null space projections of Ch. 4 by a scalar-inverse row recursion.
//! 6. [`platform`]: the wheeled platform: admittance, coupling compensation, storage function
//!    (Sec. 5.1) and the ICR singularity avoidance with leg motion (Sec. 3.2).
//! 7. [`controller`]: the whole-body controller of Ch. 6 (the hierarchy as data, one `step` per
//!    cycle from a sensor frame to an actuator frame, faults and safe outputs, output guards) and
//!    the planner channel of Ch. 7.
//!
//! ## Conventions
//! - Sizes are const generics: `N` coordinates, `B` bodies, `F` frames; all matrices are
//!   nalgebra fixed-size types. Scalars are generic over `T: RealField + Copy` and tested in
//!   `f64` and `f32`.
//! - Spatial quantities are world-frame, angular first; user-facing Jacobians are world-aligned
//!   at the frame origin with linear rows first.
//!
//! ## Panic-freedom contract
//! Outside tests the crate denies `unwrap`, `expect`, `panic!`, `unreachable!` and slice
//! indexing (clippy lints in the workspace manifest). Runtime indices are accessed with
//! `get`/iterators; bad inputs (non-finite states, unknown ids, an indefinite mass matrix)
//! return typed errors and leave outputs unchanged.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod controller;
pub mod dynamics;
pub mod hierarchy;
pub mod math;
pub mod model;
pub mod platform;
pub mod tasks;

#[cfg(test)]
mod test_models;

pub use model::{BodyId, Data, FrameId, Model};
