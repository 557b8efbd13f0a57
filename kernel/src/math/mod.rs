//! Numerical building blocks shared by every layer above: spatial (6-D) vector algebra and
//! guarded scalar operations.

pub mod guard;
pub mod spatial;

pub use guard::{all_finite, guarded_divide};
pub use spatial::{Motion, Placement, SpatialForce, SpatialMatrix};
