//! What the projection is asked to do: the recursion, the weighting (consistency), the
//! transition shaping and the diagnostics.

use crate::math::switching::transition_activation;
use crate::math::CholeskyFactor;

/// How the null space projector of a level is built from the levels above it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Recursion {
    /// No projection: all task torques are added (the sixth variant of Fig. 4.2).
    Unprojected,
    /// Successive projections (4.4)–(4.6): `N_i = N_{i−1}(I − J_{i−1}ᵀ(J_{i−1}^#)ᵀ)` with each
    /// level's own (unprojected) Jacobian.
    Successive,
    /// Augmented projections (4.9)–(4.13): every row is projected by the accumulated
    /// projector of all rows above it.
    Augmented,
}

/// The weighting `W` of the generalized inverse (4.15), i.e. the consistency of the projector.
#[derive(Clone, Copy, Debug)]
pub enum Weighting<'a, T: nalgebra::RealField, const N: usize> {
    /// `W = I`: statically consistent (Def. 4.1).
    Identity,
    /// `W = M(q)`, given by its Cholesky factor: dynamically consistent (Def. 4.2, (4.29)).
    Inertia(&'a CholeskyFactor<T, N>),
    /// `W = M(q)`, given by the dense `W⁻¹ = M⁻¹` (e.g. [`crate::dynamics::TreeFactorization::inverse`]
    /// of the closed-loop inertia): dynamically consistent (Def. 4.2, (4.29)), as
    /// [`Weighting::Inertia`].
    InverseInertia(&'a nalgebra::SMatrix<T, N, N>),
    /// `W = K(q₀)`, given by its Cholesky factor: stiffness consistent (Def. 4.3, (4.51)).
    Stiffness(&'a CholeskyFactor<T, N>),
    /// Acceleration-based, dynamically consistent with `W = I` in acceleration space:
    /// `N = M N^s M⁻¹` with the static recursion `N^s` (4.38)–(4.42). Takes `M`'s factor.
    AccelerationBased(&'a CholeskyFactor<T, N>),
}

/// How activations enter the projector (Sec. 4.4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shaping<T> {
    /// Continuous: a row locks the lower levels with its activation `a` (unilateral
    /// constraints, (4.73)–(4.76)) times the transition shaping (4.68) of its projected-row
    /// norm ratio `ρ = √(j̄W⁻¹j̄ᵀ / jW⁻¹jᵀ)` over the band `[singular_full, singular_start]`
    /// (an algorithmic singularity fades out instead of switching).
    Continuous {
        /// `ρ` at and below which the row no longer locks (fully faded out).
        singular_full: T,
        /// `ρ` at and above which the row locks completely.
        singular_start: T,
    },
    /// Classical (4.62): a row locks completely if its activation is positive and `ρ` exceeds
    /// the threshold, otherwise not at all. Discontinuous; kept for comparison.
    Discontinuous {
        /// Rank threshold `ε` on `ρ`.
        singular_threshold: T,
    },
}

impl<T: nalgebra::RealField + Copy> Shaping<T> {
    /// The activation with which a row updates the projector: its task activation (clamped to
    /// `[0, 1]`) shaped by its projected-row norm ratio `ρ`: (4.68) over the singular band for
    /// [`Shaping::Continuous`], the classical switch (4.62) for [`Shaping::Discontinuous`].
    pub fn row_activation(&self, task_activation: T, ratio: T) -> T {
        let clamped = task_activation.max(T::zero()).min(T::one());
        match *self {
            Self::Continuous { singular_full, singular_start } => {
                clamped * (T::one() - transition_activation(ratio, singular_full, singular_start))
            }
            Self::Discontinuous { singular_threshold } => {
                if clamped > T::zero() && ratio > singular_threshold {
                    T::one()
                } else {
                    T::zero()
                }
            }
        }
    }
}

/// Configuration of one projection.
#[derive(Clone, Copy, Debug)]
pub struct HierarchyConfig<'a, T: nalgebra::RealField, const N: usize> {
    /// Successive, augmented or none.
    pub recursion: Recursion,
    /// Consistency (weighting).
    pub weighting: Weighting<'a, T, N>,
    /// Continuous or classical activation.
    pub shaping: Shaping<T>,
    /// `true`: the rows of the last level also update the projector and get full diagnostics
    /// ([`HierarchyData::projector`](super::HierarchyData::projector) then covers every row). `false`: they are skipped — nothing
    /// lies below them, so the torque is identical — which saves about `6 N²` operations per
    /// last-level row (the controller's choice; its low-priority level holds most rows).
    /// Skipped rows report their task activation, `ρ = 0` and no transmission (`None`).
    pub diagnose_last_level: bool,
}
