//! Contact detection from the generalized momentum (Sec. 7.2: "physical values such as the
//! momentum (to detect contacts)").
//!
//! With `p = M(q) q̇` and `Ṁ = C + Cᵀ` (2.7), the dynamics (2.1) give
//! `ṗ = τ + τ_ext + Cᵀ q̇ − g`. The residual
//! `r = K_O (p − p(0) − ∫ (τ + Cᵀ q̇ − g + r) dt)` obeys `ṙ = K_O (τ_ext − r)`: a first-order
//! low-pass estimate of the external torque that needs no acceleration. It is evaluated on the
//! torque-controlled coordinates only; the platform coordinates are velocity controlled (their
//! rows of (2.1) carry the unknown wheel forces), so their entries are zero.
//!
//! ## Contact threshold and sensor noise
//! The residual feeds the measured velocity through at once: noise `δq̇` on it gives
//! `K_O M δq̇` on `r`, unfiltered, and a torque-sensor offset `δτ` gives a constant `−δτ`.
//! With independent velocity noise of standard deviation `σ_v` per observed joint, the
//! noise part of `r` has the root-mean-square norm `K_O σ_v ‖M_o‖_F` (`M_o` the observed rows
//! and columns of `M`, Frobenius norm). A threshold chosen for exact sensors (model error,
//! the contacts to tell apart) keeps its meaning on noisy ones when the noise floor
//! [`noise_floor`] — three of these standard deviations plus the largest offset bias
//! `δτ √n_o` — is added to it; with exact sensors the floor is zero.

use nalgebra::{RealField, SMatrix, SVector};

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
        let velocity = data.v.as_slice();
        let mask =
            SVector::<T, N>::from_fn(
                |i, _| if observed.get(i).copied().unwrap_or(false) { T::one() } else { T::zero() },
            );
        // M q̇ as a sum of the columns of M (column-major storage), in column order.
        let mut momentum = SVector::<T, N>::zeros();
        for (column, v) in data.mass_matrix.data.0.iter().zip(velocity.iter()) {
            for (p, m) in momentum.as_mut_slice().iter_mut().zip(column.iter()) {
                *p += *v * *m;
            }
        }
        let momentum = momentum.component_mul(&mask);
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

/// The level the residual's sensor noise stays below at rest (module docs, "Contact threshold
/// and sensor noise"): `3 K_O σ_v ‖M_o‖_F + δτ √n_o` for the gain `K_O` (1/s), the velocity
/// noise's standard deviation `σ_v` (rad/s), the largest torque-sensor offset `δτ` (Nm) and the
/// inertia `mass_matrix` at the working configuration, over the `observed` coordinates (`n_o`
/// of them). Zero for exact sensors. For the configuration, not the control cycle: O(N²).
pub fn noise_floor<T: RealField + Copy, const N: usize>(
    mass_matrix: &SMatrix<T, N, N>,
    observed: &[bool; N],
    gain: T,
    velocity_noise: T,
    torque_offset: T,
) -> T {
    let mut frobenius = T::zero();
    let mut count = T::zero();
    for (column, observed_j) in mass_matrix.column_iter().zip(observed.iter()) {
        if *observed_j {
            count += T::one();
            for (m, observed_i) in column.iter().zip(observed.iter()) {
                if *observed_i {
                    frobenius += *m * *m;
                }
            }
        }
    }
    let three: T = nalgebra::convert(3.0);
    three * gain * velocity_noise * frobenius.sqrt() + torque_offset * count.sqrt()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::dynamics::{coriolis_matrix, crba, forward_kinematics, gravity};
    use crate::test_models::{branched, state, N};

    /// The plain observer through nalgebra's products (the reference of the loops of
    /// [`MomentumObserver::update`]).
    fn reference_update<T: RealField + Copy, const B: usize, const F: usize>(
        o: &mut MomentumObserver<T, N>,
        data: &Data<T, N, B, F>,
        torque: &SVector<T, N>,
        observed: &[bool; N],
        dt: T,
    ) {
        let mask = SVector::<T, N>::from_fn(|i, _| if observed[i] { T::one() } else { T::zero() });
        let momentum = (data.mass_matrix * data.v).component_mul(&mask);
        if !o.started {
            o.initial_momentum = momentum;
            o.integral = SVector::zeros();
            o.residual = SVector::zeros();
            o.started = true;
            return;
        }
        let rate =
            (torque + data.coriolis.transpose() * data.v - data.gravity_torque + o.residual).component_mul(&mask);
        o.integral += rate * dt;
        o.residual = (momentum - o.initial_momentum - o.integral) * o.gain;
    }

    /// Fast and reference observers over 50 random states of the branched model (first
    /// coordinate not observed): the same residual to rounding.
    fn loops_match_the_reference<T: RealField + Copy>(tolerance: f64) {
        let model = branched::<T>();
        let mut data = Data::new(&model);
        let gain = nalgebra::convert::<f64, T>(25.0);
        let (mut fast, mut plain) = (MomentumObserver::<T, N>::new(gain), MomentumObserver::<T, N>::new(gain));
        let observed = [false, true, true, true, true, true];
        let dt = nalgebra::convert::<f64, T>(1e-3);
        let mut worst = 0.0_f64;
        for seed in 0..50_u64 {
            let (q, v): (SVector<T, N>, SVector<T, N>) = (state(seed, 1.5).cast(), state(seed ^ 7, 2.0).cast());
            forward_kinematics(&model, &mut data, &q, &v).unwrap();
            crba(&model, &mut data);
            coriolis_matrix(&model, &mut data);
            gravity(&model, &mut data);
            let torque: SVector<T, N> = state(seed ^ 5, 30.0).cast();
            let r = *fast.update(&data, &torque, &observed, dt);
            reference_update(&mut plain, &data, &torque, &observed, dt);
            let to_f64 = |x: T| -> f64 { nalgebra::try_convert(x).unwrap() };
            let error = to_f64((r - plain.residual).amax()) / (to_f64(plain.residual.amax()) + 1.0);
            assert!(error <= tolerance, "seed {seed}: {error:e}");
            assert_eq!(r[0], T::zero());
            worst = worst.max(error);
        }
        assert!(plain.residual.amax() > T::zero(), "the residual moved");
        eprintln!("observer fast vs reference: {worst:e}");
    }

    /// The floor of a diagonal 3 × 3 inertia, first coordinate not observed:
    /// `3 · 50 · 0.01 · √(2² + 3²) + 0.2 √2`; zero for exact sensors.
    #[test]
    fn noise_floor_from_the_observed_block() {
        let mass = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(100.0, 2.0, 3.0));
        let observed = [false, true, true];
        let floor = noise_floor(&mass, &observed, 50.0, 0.01, 0.2);
        let expected = 1.5 * 13.0_f64.sqrt() + 0.2 * 2.0_f64.sqrt();
        assert!((floor - expected).abs() < 1e-12, "{floor} vs {expected}");
        assert_eq!(noise_floor(&mass, &observed, 50.0, 0.0, 0.0), 0.0);
    }

    #[test]
    fn loops_match_the_reference_f64() {
        loops_match_the_reference::<f64>(1e-12);
    }

    #[test]
    fn loops_match_the_reference_f32() {
        loops_match_the_reference::<f32>(1e-4);
    }
}
