//! Output guards: joint torque limits that keep the hierarchy's priorities, a torque-rate limit
//! that keeps the direction of the change, platform velocity and acceleration limits, leg-rate
//! limits.
//!
//! **Priority under saturation.** The joint torque is `τ = τ₀ + Σ_i τ_i^p`: the compensation
//! `τ₀` (gravity and platform coupling (5.14)) and the projected torques `τ_i^p = N_i τ_i` of
//! the levels (4.7). Each joint's admissible interval is its effort limit `±τ_max`. If `τ`
//! leaves the box, the levels are scaled from the lowest priority upwards: level `k` gets the
//! largest `s_k ∈ [0, 1]` with `τ₀ + Σ_{i<k} τ_i^p + s_k τ_k^p` inside the box; if no `s_k ≥ 0`
//! fits, `s_k = 0` and the next higher level is scaled. A higher level is therefore only reduced
//! once every level below it is switched off, and a level's torque keeps its direction (it stays
//! in the null space of the levels above). Only if `τ₀` alone does not fit is the torque clamped
//! per joint (reported as [`Saturation::compensation_clamped`]).
//!
//! **Rate.** The torque `τ_e` of the effort box is then reached from the previous output
//! `τ_prev` along the straight line between them, `τ = τ_prev + α (τ_e − τ_prev)` with the
//! largest `α ∈ [0, 1]` that moves no joint by more than `τ̇_max Δt` ([`limit_rate`]). The
//! change keeps its direction, so every joint arrives at `τ_e` in the same cycle and the output
//! converges to the priority-preserving torque; while it slews, the guard does not trade one
//! level against another. (A rate box inside the priority scaling does not work when `τ₀` itself
//! moves faster than the rate allows: scaling the levels towards a `τ₀` that lies outside the
//! box switches them off and on in alternate cycles.)

use nalgebra::{RealField, SVector, Vector3};

use super::capacity::MAX_LEVELS;
use crate::platform::LEGS;

/// What the guards changed in one cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Saturation<T> {
    /// Scale `s_i ∈ [0, 1]` applied to each level's projected torque (1 = untouched).
    pub level_scale: [T; MAX_LEVELS],
    /// `true` if the compensation alone exceeded the effort box and was clamped per joint.
    pub compensation_clamped: bool,
    /// `true` if the torque-rate limit slowed this cycle's change ([`limit_rate`]).
    pub torque_rate_limited: bool,
    /// `true` where the platform velocity was limited (by the velocity or the acceleration
    /// limit).
    pub base_limited: [bool; 3],
    /// `true` if some leg rate was limited.
    pub leg_rate_limited: bool,
}

impl<T: RealField + Copy> Saturation<T> {
    /// Nothing limited.
    pub fn none() -> Self {
        Self {
            level_scale: [T::one(); MAX_LEVELS],
            compensation_clamped: false,
            torque_rate_limited: false,
            base_limited: [false; 3],
            leg_rate_limited: false,
        }
    }

    /// `true` if any guard acted.
    pub fn any(&self) -> bool {
        self.compensation_clamped
            || self.torque_rate_limited
            || self.level_scale.iter().any(|s| *s < T::one())
            || self.base_limited.iter().any(|b| *b)
            || self.leg_rate_limited
    }
}

/// The rate limit (module docs, "Rate"): `τ_prev + α (desired − τ_prev)` with the largest
/// `α ∈ [0, 1]` such that no active coordinate moves by more than `rate · dt`, then clamped to
/// `±effort` (which only acts if `previous` lies outside the effort box: the limits changed).
/// Coordinates outside `active` are returned as `desired`. Returns the torque and whether the
/// rate limit slowed the change (`α < 1`).
pub fn limit_rate<T: RealField + Copy, const N: usize>(
    desired: &SVector<T, N>,
    previous: &SVector<T, N>,
    rate: &SVector<T, N>,
    effort: &SVector<T, N>,
    dt: T,
    active: &[bool; N],
) -> (SVector<T, N>, bool) {
    let change = desired - previous;
    let mut alpha = T::one();
    for ((c, r), a) in change.as_slice().iter().zip(rate.as_slice().iter()).zip(active.iter()) {
        let step = *r * dt;
        if *a && c.abs() > step {
            alpha = alpha.min(step / c.abs());
        }
    }
    let mut torque = *desired;
    for ((((t, p), c), e), a) in torque
        .as_mut_slice()
        .iter_mut()
        .zip(previous.as_slice().iter())
        .zip(change.as_slice().iter())
        .zip(effort.as_slice().iter())
        .zip(active.iter())
    {
        if *a {
            *t = (*p + *c * alpha).max(-*e).min(*e);
        }
    }
    (torque, alpha < T::one())
}

/// The largest `s ∈ [0, 1]` with `base + s · add` inside `±effort` on `active` coordinates,
/// `None` if `base` itself is outside.
fn largest_scale<T: RealField + Copy, const N: usize>(
    base: &SVector<T, N>,
    add: &SVector<T, N>,
    effort: &SVector<T, N>,
    active: &[bool; N],
) -> Option<T> {
    let mut scale = T::one();
    for (((b, a), e), active) in
        base.as_slice().iter().zip(add.as_slice().iter()).zip(effort.as_slice().iter()).zip(active.iter())
    {
        if !active {
            continue;
        }
        if *b < -*e || *b > *e {
            return None;
        }
        if *a > T::zero() {
            scale = scale.min((*e - *b) / *a);
        } else if *a < T::zero() {
            scale = scale.min((-*e - *b) / *a);
        }
    }
    Some(scale.max(T::zero()).min(T::one()))
}

/// Priority-preserving saturation in the effort box `±effort` (module docs): returns the guarded
/// torque and writes the level scales into `saturation`. `levels` are the projected level
/// torques, highest priority first.
pub fn saturate_with_priority<T: RealField + Copy, const N: usize>(
    compensation: &SVector<T, N>,
    levels: &[SVector<T, N>],
    effort: &SVector<T, N>,
    active: &[bool; N],
    saturation: &mut Saturation<T>,
) -> SVector<T, N> {
    let total = levels.iter().fold(*compensation, |t, l| t + l);
    if largest_scale(&total, &SVector::zeros(), effort, active).is_some() {
        return total;
    }
    // Scale from the lowest level upwards.
    for k in (0..levels.len()).rev() {
        let higher = levels.iter().take(k).fold(*compensation, |t, l| t + l);
        let Some(level) = levels.get(k) else { continue };
        let scale = largest_scale(&higher, level, effort, active);
        if let Some(slot) = saturation.level_scale.get_mut(k) {
            *slot = scale.unwrap_or_else(T::zero);
        }
        if let Some(s) = scale {
            return higher + level * s;
        }
    }
    saturation.compensation_clamped = true;
    let mut clamped = *compensation;
    for ((t, e), active) in clamped.iter_mut().zip(effort.iter()).zip(active.iter()) {
        if *active {
            *t = (*t).max(-*e).min(*e);
        }
    }
    clamped
}

/// Limits the platform velocity command: `|ṙ| ≤ v_max` and `|ṙ − ṙ_prev| ≤ a_max Δt` per axis.
pub fn limit_base_velocity<T: RealField + Copy>(
    command: &Vector3<T>,
    previous: &Vector3<T>,
    velocity_limit: &Vector3<T>,
    acceleration_limit: &Vector3<T>,
    dt: T,
    limited: &mut [bool; 3],
) -> Vector3<T> {
    let mut out = *command;
    for ((((v, p), vmax), amax), flag) in out
        .iter_mut()
        .zip(previous.iter())
        .zip(velocity_limit.iter())
        .zip(acceleration_limit.iter())
        .zip(limited.iter_mut())
    {
        let step = *amax * dt;
        let bounded = (*v).max(*p - step).min(*p + step).max(-*vmax).min(*vmax);
        *flag = bounded != *v;
        *v = bounded;
    }
    out
}

/// Limits the leg rates to `±limit`; returns whether any was limited.
pub fn limit_leg_rates<T: RealField + Copy>(rates: &mut [T; LEGS], limit: T) -> bool {
    let mut limited = false;
    for r in rates.iter_mut() {
        let bounded = (*r).max(-limit).min(limit);
        limited |= bounded != *r;
        *r = bounded;
    }
    limited
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use nalgebra::{Vector2, Vector3};

    #[test]
    fn lower_levels_are_scaled_before_higher_ones() {
        let compensation = Vector2::new(1.0_f64, 0.0);
        let levels = [Vector2::new(2.0, 0.0), Vector2::new(3.0, 1.0)];
        let mut saturation = Saturation::none();
        let tau = saturate_with_priority(&compensation, &levels, &Vector2::repeat(4.0), &[true; 2], &mut saturation);
        // Level 0 fits (1 + 2 = 3); level 1 is scaled to (4 − 3)/3.
        assert!((tau - Vector2::new(4.0, 1.0 / 3.0)).norm() < 1e-12);
        assert_eq!(saturation.level_scale[0], 1.0);
        assert!((saturation.level_scale[1] - 1.0 / 3.0).abs() < 1e-12);

        // A box that level 0 alone overflows: level 1 off, level 0 scaled, direction kept.
        let mut saturation = Saturation::none();
        let tau = saturate_with_priority(&compensation, &levels, &Vector2::repeat(2.0), &[true; 2], &mut saturation);
        assert!((tau - Vector2::new(2.0, 0.0)).norm() < 1e-12);
        assert_eq!(saturation.level_scale[1], 0.0);
        assert!((saturation.level_scale[0] - 0.5).abs() < 1e-12);
        assert!(!saturation.compensation_clamped);
    }

    #[test]
    fn compensation_outside_the_box_is_clamped_and_reported_in_f32() {
        let mut saturation = Saturation::none();
        let tau = saturate_with_priority(
            &Vector2::new(5.0_f32, -5.0),
            &[Vector2::new(1.0, 1.0)],
            &Vector2::repeat(3.0),
            &[true, true],
            &mut saturation,
        );
        assert_eq!(tau, Vector2::new(3.0, -3.0));
        assert!(saturation.compensation_clamped && saturation.level_scale[0] == 0.0);
    }

    #[test]
    fn the_rate_limit_slows_the_whole_change_and_keeps_its_direction() {
        let (effort, rate, dt) = (Vector3::repeat(10.0_f64), Vector3::repeat(1000.0), 1e-3);
        let active = [true, true, false];
        // (3, 1) from rest with 1 Nm per cycle: α = 1/3 on both active joints; the inactive
        // coordinate is passed through.
        let (tau, limited) = limit_rate(&Vector3::new(3.0, 1.0, 50.0), &Vector3::zeros(), &rate, &effort, dt, &active);
        assert!((tau - Vector3::new(1.0, 1.0 / 3.0, 50.0)).norm() < 1e-12 && limited);
        // Within one rate step: untouched, not reported.
        let (tau, limited) = limit_rate(&Vector3::new(0.5, -1.0, 0.0), &Vector3::zeros(), &rate, &effort, dt, &active);
        assert_eq!((tau, limited), (Vector3::new(0.5, -1.0, 0.0), false));
        // A previous torque outside the effort box (the limits changed): clamped to the box.
        let (tau, limited) =
            limit_rate(&Vector3::new(9.0, 0.0, 0.0), &Vector3::new(12.0, 0.0, 0.0), &rate, &effort, dt, &active);
        assert_eq!((tau, limited), (Vector3::new(10.0, 0.0, 0.0), true));
    }

    /// The compensation moves 5 rate steps in one cycle: the output slews to `τ₀ + τ_1^p` in 5
    /// cycles, every joint by at most one step, and the level is never switched off (a rate box
    /// inside the priority scaling would have set `s_1 = 0` in the first cycle).
    #[test]
    fn a_compensation_faster_than_the_rate_is_reached_without_switching_a_level_off() {
        let (compensation, level) = (Vector2::new(5.0_f32, 0.0), [Vector2::new(0.0, 1.0)]);
        let (effort, rate, dt) = (Vector2::repeat(10.0), Vector2::repeat(1000.0), 1e-3);
        let mut previous = Vector2::zeros();
        for cycle in 1..=5 {
            let mut saturation = Saturation::none();
            let within = saturate_with_priority(&compensation, &level, &effort, &[true; 2], &mut saturation);
            let (tau, limited) = limit_rate(&within, &previous, &rate, &effort, dt, &[true; 2]);
            assert_eq!(saturation.level_scale[0], 1.0, "cycle {cycle}");
            assert!((tau - previous).amax() <= 1.0 + 1e-6 && (limited || cycle == 5), "cycle {cycle}");
            previous = tau;
        }
        assert!((previous - Vector2::new(5.0, 1.0)).norm() < 1e-5);
    }
}
