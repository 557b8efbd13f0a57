//! The governor: per hand and limited axis, the correction that tightens the bounds of the
//! command-side limit while the estimated applied force exceeds them, and the platform relief
//! (module docs of [`super`]: "Governor", "Platform relief").

use nalgebra::{RealField, SMatrix, SVector, Vector6};

use super::limiter::{ForceLimitParameters, ForceLimiter, HandLimits, Stacked};
use crate::controller::layout::RobotLayout;

impl<T: RealField + Copy, const N: usize, const A: usize> ForceLimiter<T, N, A> {
    /// The effective bounds `(lower, upper)` of hand `index` for the configured ones.
    pub fn bounds(&self, index: usize, lower: &Vector6<T>, upper: &Vector6<T>) -> (Vector6<T>, Vector6<T>) {
        let c = self.correction.get(index).copied().unwrap_or_else(Vector6::zeros);
        (lower - c.map(|x| x.min(T::zero())), upper - c.map(|x| x.max(T::zero())))
    }

    /// The governor and the platform relief of one period `dt` after a successful estimate:
    /// `full` the TCP Jacobians of every hand (desired-frame axes), `external` the estimated
    /// `F̂_ext` of every hand stacked. A hand with `None` limits (or a disabled limiter) is reset.
    #[inline(always)]
    pub(super) fn govern(
        &mut self,
        parameters: &ForceLimitParameters<T>,
        layout: &RobotLayout<N, A>,
        hands: &[Option<HandLimits<T>>; A],
        full: &[SMatrix<T, 6, N>; A],
        external: &Stacked<T, A>,
        dt: T,
    ) {
        self.relief = SVector::zeros();
        let step = parameters.gain * dt;
        for (h, ((limits, jacobian), wrench)) in
            hands.iter().zip(full.iter()).zip(external.map(Vector6::from)).enumerate()
        {
            let applied = -wrench;
            if let Some(a) = self.applied.get_mut(h) {
                *a = applied;
            }
            let Some(correction) = self.correction.get_mut(h) else { continue };
            let Some(limits) = limits.filter(|_| parameters.enabled) else {
                *correction = Vector6::zeros();
                continue;
            };
            let share = T::one() - parameters.margin;
            let limits = HandLimits { lower: limits.lower * share, upper: limits.upper * share, ..limits };
            let mut reaction = Vector6::zeros();
            for axis in 0..6 {
                let get = |v: &Vector6<T>| v.get(axis).copied().unwrap_or_else(T::zero);
                let (a, lower, upper) = (get(&applied), get(&limits.lower), get(&limits.upper));
                let lower = Some(lower).filter(|x| x.is_finite());
                let upper = Some(upper).filter(|x| x.is_finite());
                if let Some(c) = correction.get_mut(axis) {
                    *c = governor_step(*c, a, lower, upper, step, parameters.max_correction);
                }
                let pressing = (upper.is_some() && a > T::zero()) || (lower.is_some() && a < T::zero());
                if let (true, Some(r)) = (pressing, reaction.get_mut(axis)) {
                    *r = get(&wrench);
                }
            }
            let bounds = self.bounds(h, &limits.lower, &limits.upper);
            if let Some(e) = self.effective.get_mut(h) {
                *e = Some(bounds);
            }
            // J_r,hᵀ P_h F̂: the platform columns of J_h only.
            for k in layout.platform.axes().iter().filter_map(|a| a.coordinate()) {
                if let (Some(r), Some(column)) = (self.relief.get_mut(k), jacobian.data.0.get(k)) {
                    *r += column.iter().zip(reaction.as_slice().iter()).fold(T::zero(), |s, (j, f)| s + *j * *f);
                }
            }
        }
    }
}

/// One step of the governor of one axis: correction `c`, applied force `a`, the finite bounds,
/// `step = k_F dt`, `|c| ≤ max` (module docs).
pub fn governor_step<T: RealField + Copy>(c: T, a: T, lower: Option<T>, upper: Option<T>, step: T, max: T) -> T {
    let zero = T::zero();
    match (upper, lower) {
        (Some(u), _) if c > zero || (c == zero && a > u) => (c + step * (a - u)).max(zero).min(max),
        (_, Some(l)) if c < zero || (c == zero && a < l) => (c + step * (a - l)).min(zero).max(-max),
        _ => zero,
    }
}
