//! Numerical building blocks shared by every layer above: spatial (6-D) vector algebra,
//! guarded scalar operations, a bounded-cost symmetric eigensolver and the damping design.

pub mod damping;
pub mod eigen;
pub mod guard;
pub mod spatial;

pub use guard::{all_finite, guarded_divide};
pub use spatial::{Motion, Placement, SpatialForce, SpatialMatrix};
