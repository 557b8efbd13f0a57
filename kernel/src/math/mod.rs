//! Numerical building blocks shared by every layer above: spatial (6-D) vector algebra,
//! guarded scalar operations, the square root by the FPU, Cholesky factorisation and triangular substitutions, a bounded-cost symmetric eigensolver, the damping design and the
//! transition shaping of Sec. 4.4.

pub mod cholesky;
pub mod damping;
pub mod eigen;
pub mod guard;
pub mod spatial;
pub mod sqrt;
pub mod switching;

pub use guard::{all_finite, guarded_divide};
pub use sqrt::sqrt;

/// Cholesky factor of an `N×N` symmetric positive definite matrix (`M(q)`, `K(q₀)`).
pub type CholeskyFactor<T, const N: usize> = nalgebra::Cholesky<T, nalgebra::Const<N>>;
pub use spatial::{Motion, Placement, SpatialForce, SpatialMatrix};
