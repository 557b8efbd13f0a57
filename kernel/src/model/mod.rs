//! The constant robot description: a kinematic tree of bodies with joint drives, fixed frames
//! and joint limits (Pinocchio's `Model`), validated once when it is built.
//!
//! Sizes are const generics: `N` generalized coordinates (DOF), at most `B` bodies (one per
//! moving joint, `B ≥ N`; more when joints are coupled) and at most `F` fixed frames.
//! Bodies are stored in topological order (a parent's index is smaller than its child's), so
//! every tree algorithm is a forward and/or backward loop over a parent array, never recursion.

mod data;
mod description;
mod error;
mod inertia;
mod joint;

pub use crate::math::spatial::Placement;
pub use data::Data;
pub use description::{Body, BodyId, Frame, FrameId, JointLimits, Model, ModelBuilder};
pub use error::ModelError;
pub use inertia::{Inertia, WorldInertia};
pub use joint::{DriveTerm, JointDrive, JointKind, MAX_DRIVE_TERMS};
