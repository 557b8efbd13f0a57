//! The way back from the safe output to normal operation, without chatter.
//!
//! A fault switches the output to [`SafeOutput::Hold`] at once ([`super::faults`]). Returning
//! at the first valid frame would let a signal near its threshold (a joint speed at 1.5× its
//! limit) toggle the mode every cycle. So leaving the safe output takes two phases:
//!
//! 1. **Waiting** ([`RecoveryParameters::valid_cycles`] consecutive cycles): the frame must
//!    pass the input validation with every threshold tightened by
//!    [`RecoveryParameters::margin`] ([`Recovery::input_limits`]), the whole-body controller
//!    runs (its observers and targets stay current), but the output is still the hold torque
//!    and the fault that caused it stays reported. Any failure starts the wait again.
//! 2. **Blending** ([`RecoveryParameters::blend_s`]): the output is `Normal` and its torque goes
//!    from the hold torque to the whole-body torque along the smooth transition (4.68) of the
//!    weight `β`: `τ = (1 − β) τ_hold + β (τ₀ + Σ τ_i^p)`. The torque guard receives the blend as
//!    the compensation `τ₀ + (1 − β)(τ_hold − τ₀)` and the levels scaled by `β`, so its priority
//!    rules and limits still hold.
//!
//! The telemetry counts the mode changes of the output.

use nalgebra::RealField;

use super::faults::InputLimits;
use super::faults::{Fault, SafeOutput};
use crate::math::switching::transition_activation;

/// Parameters of the return to normal operation (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RecoveryParameters<T> {
    /// Consecutive valid cycles before the blend starts, `≥ 1`.
    pub valid_cycles: u32,
    /// Relative tightening of the input thresholds while waiting, in `[0, 1)`: a speed must be
    /// below `(1 − margin)` times its fault threshold, a position inside the limits by less than
    /// `(1 − margin)` times the position tolerance.
    pub margin: T,
    /// Duration of the torque blend (s), `≥ 0`.
    pub blend_s: T,
}

impl<T: RealField + Copy> RecoveryParameters<T> {
    /// `true` if the parameters are in their documented ranges.
    pub fn is_valid(&self) -> bool {
        self.valid_cycles >= 1
            && self.margin >= T::zero()
            && self.margin < T::one()
            && self.blend_s >= T::zero()
            && self.blend_s.is_finite()
    }
}

/// Where the controller stands between a fault and normal operation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Recovery<T> {
    /// Normal operation.
    Normal,
    /// After a fault: `valid` consecutive valid cycles so far; `cause` the fault that started
    /// the wait (still reported).
    Waiting {
        /// Valid cycles counted.
        valid: u32,
        /// The fault that caused the safe output.
        cause: Fault,
    },
    /// The torque blend, at `progress ∈ [0, 1)` of its duration.
    Blending {
        /// Elapsed fraction of the blend.
        progress: T,
    },
}

impl<T: RealField + Copy> Recovery<T> {
    /// A fault happened this cycle: wait again from zero.
    pub fn fault(&mut self, cause: Fault) {
        *self = Self::Waiting { valid: 0, cause };
    }

    /// The input thresholds in effect: tightened by the margin while waiting.
    pub fn input_limits(&self, limits: &InputLimits<T>, parameters: &RecoveryParameters<T>) -> InputLimits<T> {
        match self {
            Self::Waiting { .. } => {
                let keep = T::one() - parameters.margin;
                InputLimits {
                    position_tolerance: limits.position_tolerance * keep,
                    velocity_factor: limits.velocity_factor * keep,
                    ..*limits
                }
            }
            Self::Normal | Self::Blending { .. } => *limits,
        }
    }

    /// The weight `β` of the whole-body torque this cycle: 0 while waiting, the transition
    /// (4.68) of the blend's progress while blending, 1 in normal operation.
    pub fn weight(&self) -> T {
        match self {
            Self::Normal => T::one(),
            Self::Waiting { .. } => T::zero(),
            Self::Blending { progress } => T::one() - transition_activation(*progress, T::zero(), T::one()),
        }
    }

    /// The mode of this cycle's output and the fault to report after a valid cycle.
    pub fn output(&self) -> (SafeOutput, Option<Fault>) {
        match self {
            Self::Waiting { cause, .. } => (SafeOutput::Hold, Some(*cause)),
            Self::Normal | Self::Blending { .. } => (SafeOutput::Normal, None),
        }
    }

    /// A valid cycle of period `dt` ended: count it, start or advance the blend.
    pub fn valid_cycle(&mut self, parameters: &RecoveryParameters<T>, dt: T) {
        *self = match *self {
            Self::Normal => Self::Normal,
            Self::Waiting { valid, cause } => {
                let valid = valid.saturating_add(1);
                if valid < parameters.valid_cycles {
                    Self::Waiting { valid, cause }
                } else {
                    Self::blend_from(T::zero(), parameters)
                }
            }
            Self::Blending { progress } => Self::blend_from(progress + dt / parameters.blend_s, parameters),
        };
    }

    fn blend_from(progress: T, parameters: &RecoveryParameters<T>) -> Self {
        // `progress < 1` is false for NaN (a zero blend time gives 0/0 or ∞): normal at once.
        if parameters.blend_s > T::zero() && progress < T::one() {
            Self::Blending { progress }
        } else {
            Self::Normal
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::indexing_slicing, reason = "tests")]
    use super::*;

    fn parameters() -> RecoveryParameters<f64> {
        RecoveryParameters { valid_cycles: 3, margin: 0.2, blend_s: 0.004 }
    }

    const CAUSE: Fault = Fault::VelocityOutOfRange { coordinate: 4 };

    #[test]
    fn waits_for_consecutive_valid_cycles_then_blends_then_is_normal() {
        let p = parameters();
        let mut r = Recovery::Normal;
        r.fault(CAUSE);
        let mut weights = std::vec::Vec::new();
        let mut modes = std::vec::Vec::new();
        for cycle in 0..10 {
            if cycle == 1 {
                r.fault(CAUSE); // a second fault restarts the wait
            }
            weights.push(r.weight());
            modes.push(r.output());
            r.valid_cycle(&p, 0.001);
        }
        let hold = (SafeOutput::Hold, Some(CAUSE));
        let normal = (SafeOutput::Normal, None);
        // Cycles 1, 2, 3 wait (restarted at 1), 4..7 blend over 4 ms, 8.. normal.
        assert_eq!(&modes[..4], &[hold, hold, hold, hold]);
        assert!(modes[4..].iter().all(|m| *m == normal));
        assert_eq!(&weights[..5], &[0.0, 0.0, 0.0, 0.0, 0.0]);
        let blend: std::vec::Vec<f64> = weights[4..9].to_vec();
        assert!(blend.windows(2).all(|w| w[1] > w[0]), "{blend:?}");
        assert!((weights[6] - 0.5).abs() < 1e-12, "the cubic is ½ at half the blend");
        assert_eq!(weights[8], 1.0);
        assert_eq!(r, Recovery::Normal);
    }

    #[test]
    fn thresholds_are_tightened_only_while_waiting() {
        let p = parameters();
        let limits =
            InputLimits { position_tolerance: 0.05, velocity_factor: 1.5, max_cycle_gap: 3, brake_after_cycles: 100 };
        let waiting = Recovery::Waiting { valid: 0, cause: CAUSE };
        let tight = waiting.input_limits(&limits, &p);
        assert!((tight.velocity_factor - 1.2).abs() < 1e-12 && (tight.position_tolerance - 0.04).abs() < 1e-12);
        assert_eq!(tight.max_cycle_gap, 3);
        assert_eq!(Recovery::Blending { progress: 0.5 }.input_limits(&limits, &p), limits);
        assert_eq!(Recovery::<f64>::Normal.input_limits(&limits, &p), limits);
    }

    #[test]
    fn zero_blend_time_returns_to_normal_at_once() {
        let p = RecoveryParameters { blend_s: 0.0, ..parameters() };
        let mut r = Recovery::Waiting { valid: 2, cause: CAUSE };
        r.valid_cycle(&p, 0.001);
        assert_eq!(r, Recovery::Normal);
        assert!(p.is_valid() && !RecoveryParameters { margin: 1.0, ..p }.is_valid());
        assert!(!RecoveryParameters { valid_cycles: 0, ..p }.is_valid());
    }
}
