//! Contact detection from the generalized momentum (Sec. 7.2: "physical values such as the
//! momentum (to detect contacts)").
//!
//! With `p = M(q) q̇` and `Ṁ = C + Cᵀ` (2.7), the dynamics (2.1) give
//! `ṗ = τ + τ_ext + Cᵀ q̇ − g`. The residual
//! `r = K_O (p − p(0) − ∫ (τ + Cᵀ q̇ − g + r) dt)` obeys `ṙ = K_O (τ_ext − r)`: a first-order
//! low-pass estimate of the external torque that needs no acceleration. It is evaluated on the
//! torque-controlled coordinates only; the platform coordinates are velocity controlled (their
//! rows of (2.1) carry the unknown wheel forces), so their entries are zero.

use nalgebra::{RealField, SVector};

use crate::model::Data;

/// State of the momentum observer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MomentumObserver<T, const N: usize> {
    gain: T,
    initial_momentum: SVector<T, N>,
    integral: SVector<T, N>,
    residual: SVector<T, N>,
    started: bool,
}

impl<T: RealField + Copy, const N: usize> MomentumObserver<T, N> {
    /// An observer with gain `K_O` (1/s); it starts at the first update.
    pub fn new(gain: T) -> Self {
        Self {
            gain,
            initial_momentum: SVector::zeros(),
            integral: SVector::zeros(),
            residual: SVector::zeros(),
            started: false,
        }
    }

    /// Restarts at the next update (after a fault the integral is no longer meaningful).
    pub fn reset(&mut self) {
        self.started = false;
        self.residual = SVector::zeros();
    }

    /// The estimate of `τ_ext` (Nm, N).
    pub fn residual(&self) -> &SVector<T, N> {
        &self.residual
    }

    /// One period `dt`. Reads `M`, `C`, `g` and `q̇` from `data` (after `crba`,
    /// `coriolis_matrix` and `gravity` at the measured state); `torque` is the measured joint
    /// torque; coordinates with `observed = false` are ignored. Cost O(N²).
    pub fn update<const B: usize, const F: usize>(
        &mut self,
        data: &Data<T, N, B, F>,
        torque: &SVector<T, N>,
        observed: &[bool; N],
        dt: T,
    ) -> &SVector<T, N> {
        let coriolis = data.coriolis.transpose() * data.v;
        self.update_with(data, &coriolis, torque, observed, dt)
    }

    /// [`Self::update`] with `Cᵀ q̇` given (from [`crate::dynamics::coriolis_transpose_velocity`]):
    /// reads `M`, `g` and `q̇` from `data`, not `data.coriolis`.
    pub fn update_with<const B: usize, const F: usize>(
        &mut self,
        data: &Data<T, N, B, F>,
        coriolis_transpose_velocity: &SVector<T, N>,
        torque: &SVector<T, N>,
        observed: &[bool; N],
        dt: T,
    ) -> &SVector<T, N> {
        let velocity = &data.v;
        let mask =
            SVector::<T, N>::from_fn(
                |i, _| if observed.get(i).copied().unwrap_or(false) { T::one() } else { T::zero() },
            );
        let momentum = (data.mass_matrix * velocity).component_mul(&mask);
        if !self.started {
            self.initial_momentum = momentum;
            self.integral = SVector::zeros();
            self.residual = SVector::zeros();
            self.started = true;
            return &self.residual;
        }
        let rate = (torque + coriolis_transpose_velocity - data.gravity_torque + self.residual).component_mul(&mask);
        self.integral += rate * dt;
        self.residual = (momentum - self.initial_momentum - self.integral) * self.gain;
        &self.residual
    }
}
