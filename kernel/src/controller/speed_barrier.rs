//! Joint speed barrier: a dissipative torque that keeps every joint inside its speed limit.
//!
//! The tasks of the hierarchy know nothing of joint speeds. A goal change, a transition or a
//! push can accelerate a joint of small inertia in the null space of the tasks above it faster
//! than its limit allows, and the input validation then stops the robot
//! ([`super::faults::Fault::VelocityOutOfRange`]). The barrier adds, per joint, the damping
//!
//! `τ_b,i = −sat_{c τ_max,i}(a(ρ_i) d_i q̇_i)`,  `d_i = min(m_i / T_b, c τ_max,i / q̇_max,i)`,
//! `ρ_i = |q̇_i| / q̇_max,i`,
//!
//! with the activation `a = 1 − a_s(ρ)` of the smooth transition (4.68) between `onset` (no
//! barrier below) and `full` (full barrier above) and `m_i = M_ii` the joint's own inertia. The
//! damping `d_i` is the smaller of two bounds: the sampling bound `m_i / T_b` (with `T_b` a few
//! control periods the sampled damper stays stable, see below) and the torque budget: the
//! fraction `c` of the joint's peak torque at the speed limit. The magnitude is saturated at
//! `c τ_max,i`, so the barrier never takes the whole torque box from the tasks (the guard
//! scales the levels when `τ₀` grows). Why this design:
//! - **Passivity.** `q̇_i τ_b,i ≤ 0` for every joint (a saturated damping still opposes the
//!   motion): the barrier only dissipates, so the
//!   storage function of the hierarchy (Ch. 4, `V̇ ≤ 0`) keeps decreasing; it cannot destabilise
//!   the controller, whatever the tasks do. A potential barrier on the speed (as for the end
//!   stops) would store energy and could release it; a goal shaping would need to know every
//!   task's null-space motion in advance.
//! - **Priority.** It joins the compensation `τ₀` (gravity and platform coupling), which the
//!   torque guard keeps before any level ([`super::guard`]): near the limit the tasks yield,
//!   the speed limit does not. It is a hard constraint of the hardware, above every task.
//! - **Invisible in normal work.** Below `onset` (half the limit by default) it is exactly zero,
//!   so the thesis' scenarios keep their numbers; it is C¹ in `q̇`, so the torque-rate guard
//!   sees no step.
//! - **Discrete-time stable.** Per joint the barrier alone gives `m q̈ = −d q̇`; sampled at `Δt`
//!   and applied one cycle later, this decays without oscillation for `d Δt / m < 1`. With
//!   `d ≤ m / T_b` and `T_b = 2 Δt` the ratio is at most ½, a factor two of margin for the
//!   joint's effective inertia being below `M_ii` (other joints moving along).

use nalgebra::{RealField, SVector};

use crate::math::switching::transition_activation;

/// Parameters of the speed barrier (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpeedBarrierParameters<T> {
    /// `|q̇|/q̇_max` below which the barrier is zero, in `[0, full)`.
    pub onset: T,
    /// `|q̇|/q̇_max` from which the barrier acts fully, in `(onset, ∞)`.
    pub full: T,
    /// Sampling bound of the damping: `d_i ≤ M_ii / T_b` (s), `> 0`.
    pub braking_time_s: T,
    /// Largest barrier torque as a fraction `c` of the joint's peak torque, in `(0, 1]`.
    pub max_torque_fraction: T,
}

impl<T: RealField + Copy> SpeedBarrierParameters<T> {
    /// `true` if the parameters are in their documented ranges.
    pub fn is_valid(&self) -> bool {
        self.onset >= T::zero()
            && self.full > self.onset
            && self.full.is_finite()
            && self.braking_time_s > T::zero()
            && self.braking_time_s.is_finite()
            && self.max_torque_fraction > T::zero()
            && self.max_torque_fraction <= T::one()
    }
}

/// The joints' limits the barrier needs: speed limits and peak torques.
#[derive(Clone, Copy, Debug)]
pub struct JointLimits<'a, T, const N: usize> {
    /// Speed limit per coordinate (rad/s, m/s).
    pub speed: &'a SVector<T, N>,
    /// Peak torque per coordinate (Nm, N).
    pub effort: &'a SVector<T, N>,
}

/// The barrier torque `τ_b` of every coordinate marked `active` from the measured velocities
/// `v`, the joints' `limits` and the diagonal of the inertia matrix `inertia` (zero on inactive
/// coordinates, on coordinates with a non-positive or non-finite limit, and below the onset).
/// Cost O(N).
pub fn speed_barrier<T: RealField + Copy, const N: usize>(
    parameters: &SpeedBarrierParameters<T>,
    v: &SVector<T, N>,
    limits: JointLimits<'_, T, N>,
    inertia: &SVector<T, N>,
    active: &[bool; N],
) -> SVector<T, N> {
    let mut torque = SVector::<T, N>::zeros();
    let joints = v.iter().zip(limits.speed.iter()).zip(limits.effort.iter()).zip(inertia.iter());
    for ((tau, (((v, speed), effort), m)), active) in torque.iter_mut().zip(joints).zip(active.iter()) {
        if !*active || speed.partial_cmp(&T::zero()) != Some(core::cmp::Ordering::Greater) {
            continue;
        }
        let ratio = v.abs() / *speed;
        let activation = T::one() - transition_activation(ratio, parameters.onset, parameters.full);
        if activation > T::zero() {
            let cap = parameters.max_torque_fraction * *effort;
            let damping = (*m / parameters.braking_time_s).min(cap / *speed);
            *tau = (-activation * damping * *v).max(-cap).min(cap);
        }
    }
    torque
}

#[cfg(test)]
mod tests {
    #![allow(clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use nalgebra::Vector3;

    fn parameters() -> SpeedBarrierParameters<f64> {
        SpeedBarrierParameters { onset: 0.5, full: 0.9, braking_time_s: 0.01, max_torque_fraction: 0.5 }
    }

    fn limits<'a>(speed: &'a Vector3<f64>, effort: &'a Vector3<f64>) -> JointLimits<'a, f64, 3> {
        JointLimits { speed, effort }
    }

    #[test]
    fn zero_below_the_onset_full_damping_above() {
        let (limit, effort) = (Vector3::new(2.0, 2.0, 2.0), Vector3::new(400.0, 400.0, 200.0));
        let inertia = Vector3::new(0.5, 0.5, 0.5);
        let v = Vector3::new(0.99, -1.9, 3.0);
        let tau = speed_barrier(&parameters(), &v, limits(&limit, &effort), &inertia, &[true; 3]);
        assert_eq!(tau[0], 0.0, "ρ = 0.495 < onset");
        // ρ = 0.95 ≥ full: the whole damping min(m/T_b, c τ_max/q̇_max) = min(50, 100).
        assert!((tau[1] - 95.0).abs() < 1e-12);
        // Damping min(50, 50) at 3 rad/s: 150 Nm, capped at half of 200 Nm.
        assert!((tau[2] + 100.0).abs() < 1e-12);
        // A light joint: the torque budget bounds the damping (c τ_max / q̇_max = 10 Nms/rad).
        let light = speed_barrier(&parameters(), &v, limits(&limit, &Vector3::repeat(40.0)), &inertia, &[true; 3]);
        assert!((light[1] - 19.0).abs() < 1e-12);
        // Half-way between onset and full: the cubic gives a = ½.
        let v = Vector3::new(1.4, 0.0, 0.0);
        let tau = speed_barrier(&parameters(), &v, limits(&limit, &effort), &inertia, &[true; 3]);
        assert!((tau[0] + 0.5 * 50.0 * 1.4).abs() < 1e-12);
    }

    #[test]
    fn dissipative_and_only_on_active_coordinates() {
        let (limit, effort) = (Vector3::new(1.0, 1.0, 0.0), Vector3::new(5.0, 5.0, 5.0));
        let inertia = Vector3::new(0.2, 3.0, 1.0);
        let mut x = 0.3_f64;
        for _ in 0..200 {
            x = (x * 3.7 + 0.11).fract();
            let v = Vector3::new(2.0 * x - 1.0, 4.0 * x - 2.0, 3.0) * 1.3;
            let tau = speed_barrier(&parameters(), &v, limits(&limit, &effort), &inertia, &[true, false, true]);
            assert!(v.dot(&tau) <= 0.0);
            assert_eq!(tau[1], 0.0, "inactive");
            assert_eq!(tau[2], 0.0, "no limit");
        }
    }

    #[test]
    fn validity() {
        assert!(parameters().is_valid());
        let p = parameters();
        assert!(!SpeedBarrierParameters { onset: 0.9, ..p }.is_valid());
        assert!(!SpeedBarrierParameters { braking_time_s: 0.0, ..p }.is_valid());
        assert!(!SpeedBarrierParameters { onset: f64::NAN, ..p }.is_valid());
        assert!(!SpeedBarrierParameters { max_torque_fraction: 0.0, ..p }.is_valid());
    }
}
