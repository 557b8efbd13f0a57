//! The limiter's parameters, its per-cycle inputs and its state (module docs of [`super`]).

use nalgebra::{Matrix3, RealField, SVector, Vector6};

/// Parameters of the contact-force limiter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceLimitParameters<T> {
    /// `true` enables the command-side limit, the governor and the platform relief (the
    /// estimate is always reported).
    pub enabled: bool,
    /// Share `0 ≤ m < 1` of every finite bound kept free: the limiter holds the force within
    /// `(1 − m)` times the configured bounds, for what neither the command-side prediction nor
    /// the lagging estimate sees (surface compliance, friction changes, model error).
    pub margin: T,
    /// Governor gain `k_F > 0` (1/s): N of correction per N·s of excess.
    pub gain: T,
    /// Largest correction `c_max ≥ 0` per axis (N, Nm).
    pub max_correction: T,
    /// Regularisation `μ > 0` of the wrench estimate (m², in the units of `J Jᵀ`) and of the
    /// reflected inertia of the command-side limit (1/kg, in the units of `J M⁻¹ Jᵀ`).
    pub regularisation: T,
}

/// What one hand's limiter needs this cycle: its TCP frame, the orientation of the desired
/// frame and the task's configured bounds (desired-frame axes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HandLimits<T> {
    /// Orientation `A = R_des` of the desired TCP frame (world).
    pub axes: Matrix3<T>,
    /// Configured lower bounds (N, Nm), `≤ 0`, may be `−∞`.
    pub lower: Vector6<T>,
    /// Configured upper bounds (N, Nm), `≥ 0`, may be `+∞`.
    pub upper: Vector6<T>,
}

/// The `6 A` rows of the `A` hands stacked, hand by hand, six axes each: a column of the
/// stacked `J_u`, a right-hand side or a column of a `6 A × 6 A` matrix. An array of arrays (no
/// `6 A` length in a generic type); `as_flattened` gives the `6 A` entries in order.
pub type Stacked<X, const A: usize> = [[X; 6]; A];

/// State of the limiter of `A` hands: per hand the estimated applied wrench and the governor
/// corrections; the cycle's Jacobians and effective bounds for the command-side limit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceLimiter<T, const N: usize, const A: usize> {
    pub(super) applied: [Vector6<T>; A],
    pub(super) correction: [Vector6<T>; A],
    pub(super) relief: SVector<T, N>,
    /// `J_u` of every hand, stacked (`6 A × N`, a column per coordinate, desired-frame axes,
    /// platform columns zero).
    pub(super) stacked: [Stacked<T, A>; N],
    /// Effective bounds `(lower, upper)` per hand with an enabled limit, this cycle.
    pub(super) effective: [Option<(Vector6<T>, Vector6<T>)>; A],
}

impl<T: RealField + Copy, const N: usize, const A: usize> Default for ForceLimiter<T, N, A> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: RealField + Copy, const N: usize, const A: usize> ForceLimiter<T, N, A> {
    /// A limiter at rest (no correction).
    pub fn new() -> Self {
        Self {
            applied: [Vector6::zeros(); A],
            correction: [Vector6::zeros(); A],
            relief: SVector::zeros(),
            stacked: [[[T::zero(); 6]; A]; N],
            effective: [None; A],
        }
    }

    /// Forgets every correction and estimate (after a fault).
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// Estimated wrench the TCP of hand `index` applies on its environment, `a = −F̂_ext`
    /// (N, Nm, desired-frame axes).
    pub fn applied(&self) -> [Vector6<T>; A] {
        self.applied
    }

    /// Governor corrections `c` per hand and axis (N, Nm): positive lowers the upper bound,
    /// negative raises the lower bound.
    pub fn correction(&self) -> [Vector6<T>; A] {
        self.correction
    }

    /// Torque to add to the platform rows of `τ` (the estimated reaction along the limited
    /// axes; zero on the upper body).
    pub fn platform_relief(&self) -> &SVector<T, N> {
        &self.relief
    }
}
