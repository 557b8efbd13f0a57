//! Repulsion of the wheels by leg motion, (3.37)–(3.40), and the gains of the return-to-nominal
//! loop of Fig. 3.10.
//!
//! On a platform with variable footprint the wheel can also move away from the ICR: "a leg
//! motion does not result in a deviation from the nominal trajectory in the plane". Each leg
//! gets a nonlinear admittance
//!
//! `m_w λ̈_i + d_w λ̇_i + k_w(λ_i) (λ_i − λ_i,0) = F_w` (3.37), `k_w = c₁ (λ_i − λ_i,0)²` (3.38),
//!
//! driven by the repulsive force projected on the leg of the nearest wheel,
//! `F_w = −ηᵀ l F_sap(d_sap)` (3.39), which gives (3.40)
//! `λ̈_i = −ηᵀ l F_sap/m_w − (d_w/m_w) λ̇_i − (c₁/m_w)(λ_i − λ_i,0)³`. The cubic spring is soft
//! near the nominal length and hard far from it, which limits the leg excursion.
//!
//! The return loop of Fig. 3.10 leads the platform back to its nominal trajectory "as soon as
//! the ICR has left the potential field": its PD gains `k₁`, `k₂` are active outside the fields.
//! The thesis makes them functions `k₁(d_sap)`, `k₂(d_sap)` without giving them; here they are
//! `k_j(d_sap) = k_j σ(d_sap)` with the C¹ ramp `σ` from 0 at the field border `d₀` to 1 at
//! `d₀ + blend` ([`ReturnGains::gain`]), so the commanded acceleration stays continuous.

use nalgebra::{RealField, Vector2};

use super::icr::{NearestWheel, Repulsion};
use super::{PlatformError, LEGS};
use crate::math::sqrt;
use crate::math::switching::transition_activation;

/// Parameters of the leg admittance (3.37)–(3.38); none is given by the thesis.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LegAdmittanceConfig<T> {
    /// Virtual mass `m_w` (kg), `> 0`.
    pub mass: T,
    /// Virtual damping `d_w` (kg/s), `≥ 0`.
    pub damping: T,
    /// Coefficient `c₁` of the cubic spring (3.38) (N/m³), `≥ 0`.
    pub cubic_stiffness: T,
    /// Equilibrium leg length `λ_i,0` (m) of every leg.
    pub nominal_length: T,
    /// Shortest leg length (m), the inner end stop.
    pub min_length: T,
    /// Longest leg length (m), the outer end stop.
    pub max_length: T,
}

impl<T: RealField + Copy> LegAdmittanceConfig<T> {
    /// Validates the parameters. Errors: [`PlatformError::InvalidParameter`].
    pub fn validate(&self) -> Result<(), PlatformError> {
        let bad = |name| Err(PlatformError::InvalidParameter { name });
        if !(self.mass.is_finite() && self.mass > T::zero()) {
            return bad("mass");
        }
        if !(self.damping.is_finite() && self.damping >= T::zero()) {
            return bad("damping");
        }
        if !(self.cubic_stiffness.is_finite() && self.cubic_stiffness >= T::zero()) {
            return bad("cubic_stiffness");
        }
        let ordered = self.min_length.is_finite()
            && self.max_length.is_finite()
            && self.min_length > T::zero()
            && self.min_length <= self.nominal_length
            && self.nominal_length <= self.max_length;
        if !ordered {
            return bad("leg lengths");
        }
        Ok(())
    }
}

/// Leg force `F_w = −ηᵀ l F_sap` (3.39) of the nearest wheel (N): positive extends the leg.
/// Zero if there is no ICR.
pub fn leg_force<T: RealField + Copy>(repulsion: &Repulsion<T>) -> T {
    repulsion.nearest.map_or_else(T::zero, |w| -w.direction.dot(&w.leg_direction) * repulsion.force)
}

/// Leg acceleration (3.40): `λ̈ = F_w/m_w − (d_w/m_w) λ̇ − (c₁/m_w)(λ − λ₀)³` (m/s²) for the
/// deviation `λ − λ₀` (m), rate `λ̇` (m/s) and leg force `F_w` (N).
///
/// ```
/// use kernel::platform::legs::{leg_acceleration, LegAdmittanceConfig};
/// let c = LegAdmittanceConfig { mass: 0.2, damping: 1.0, cubic_stiffness: 1000.0_f64,
///     nominal_length: 0.53, min_length: 0.45, max_length: 0.7 };
/// // 0.1 m out, at rest: the cubic spring pulls back with 1000 · 0.1³ = 1 N, i.e. 5 m/s².
/// assert!((leg_acceleration(&c, 0.1, 0.0, 0.0) + 5.0).abs() < 1e-12);
/// ```
pub fn leg_acceleration<T: RealField + Copy>(config: &LegAdmittanceConfig<T>, deviation: T, rate: T, force: T) -> T {
    (force - config.damping * rate - config.cubic_stiffness * deviation * deviation * deviation) / config.mass
}

/// The four leg admittances (3.37) with their state `λ_i`, `λ̇_i`, integrated with end stops.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LegAdmittance<T> {
    config: LegAdmittanceConfig<T>,
    lengths: [T; LEGS],
    rates: [T; LEGS],
}

impl<T: RealField + Copy> LegAdmittance<T> {
    /// Validates `config` and starts at rest at the nominal length.
    pub fn try_new(config: LegAdmittanceConfig<T>) -> Result<Self, PlatformError> {
        config.validate()?;
        Ok(Self { config, lengths: [config.nominal_length; LEGS], rates: [T::zero(); LEGS] })
    }

    /// The validated parameters.
    pub fn config(&self) -> &LegAdmittanceConfig<T> {
        &self.config
    }

    /// Leg lengths `λ_i` (m).
    pub fn lengths(&self) -> [T; LEGS] {
        self.lengths
    }

    /// Leg rates `λ̇_i` (m/s).
    pub fn rates(&self) -> [T; LEGS] {
        self.rates
    }

    /// Sets the state (lengths clamped to the end stops). Errors: non-finite values.
    pub fn reset(&mut self, lengths: &[T; LEGS], rates: &[T; LEGS]) -> Result<(), PlatformError> {
        if !lengths.iter().chain(rates.iter()).all(|x| x.is_finite()) {
            return Err(PlatformError::NonFinite { input: "leg state" });
        }
        for (((l, r), new_l), new_r) in
            self.lengths.iter_mut().zip(self.rates.iter_mut()).zip(lengths.iter()).zip(rates.iter())
        {
            *l = new_l.max(self.config.min_length).min(self.config.max_length);
            *r = *new_r;
        }
        Ok(())
    }

    /// Integrates the leg accelerations `accelerations` (m/s², e.g. (3.40) plus the return loop)
    /// over `dt` (semi-implicit Euler). A leg that reaches an end stop stops there (its rate is
    /// zeroed). Returns the rates. Errors: non-finite input or `dt ≤ 0` (state unchanged).
    pub fn integrate(&mut self, accelerations: &[T; LEGS], dt: T) -> Result<[T; LEGS], PlatformError> {
        if !accelerations.iter().all(|a| a.is_finite()) {
            return Err(PlatformError::NonFinite { input: "leg accelerations" });
        }
        if !(dt.is_finite() && dt > T::zero()) {
            return Err(PlatformError::InvalidParameter { name: "dt" });
        }
        let (lo, hi) = (self.config.min_length, self.config.max_length);
        for ((length, rate), acceleration) in
            self.lengths.iter_mut().zip(self.rates.iter_mut()).zip(accelerations.iter())
        {
            *rate += *acceleration * dt;
            let next = *length + *rate * dt;
            if next <= lo || next >= hi {
                *rate = T::zero();
            }
            *length = next.max(lo).min(hi);
        }
        Ok(self.rates)
    }
}

/// Limits of the leg motion by the steering it needs. "The legs of Rollin' Justin are passive
/// prismatic joints moved by steering and driving the wheels": a leg rate `λ̇` adds `λ̇ l` to the
/// velocity of its wheel, `v = v_b + λ̇ l` with `v_b = θ̇ J (p − p_icr)` the velocity the
/// platform motion gives the contact point (`J` the quarter turn, `‖v_b‖ = |θ̇| d_sap`). Two
/// effects make a fast leg motion near the ICR demand more steering than the ICR avoidance
/// saves:
/// - the leg acceleration turns the wheel at `(v × l) λ̈ / ‖v‖²`, at most `|λ̈| / ‖v‖`, and
///   `‖v‖` is small exactly when the ICR is near the wheel;
/// - the leg rate moves the point whose velocity vanishes (where the steering is singular):
///   `v = θ̇ J (p − (λ̇/θ̇) J l − p_icr)`, i.e. `|λ̇/θ̇|` across the leg away from the contact point,
///   where the repulsion does not see it.
///
/// [`SteeringLimit::limit`] therefore bounds `|λ̈| ≤ steering_rate · ‖v‖` and
/// `|λ̇| ≤ speed_ratio · ‖v_b‖`: the leg's own steering demand stays below `steering_rate`, and
/// the singular point stays within `speed_ratio · d_sap` of the wheel, so `‖v‖ ≥ (1 −
/// speed_ratio) |θ̇| d_sap`. Far from the ICR (`‖v_b‖` large) the legs move freely.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SteeringLimit<T> {
    /// Steering rate (rad/s) a leg acceleration may demand of its wheel, `> 0`.
    pub steering_rate: T,
    /// Largest leg rate per contact speed of the platform motion, `0 < ratio < 1`.
    pub speed_ratio: T,
}

impl<T: RealField + Copy> SteeringLimit<T> {
    /// Validates the limits. Errors: [`PlatformError::InvalidParameter`].
    pub fn validate(&self) -> Result<(), PlatformError> {
        let rate_ok = self.steering_rate.is_finite() && self.steering_rate > T::zero();
        let ratio_ok = self.speed_ratio > T::zero() && self.speed_ratio < T::one();
        if rate_ok && ratio_ok {
            Ok(())
        } else {
            Err(PlatformError::InvalidParameter { name: "steering limit" })
        }
    }

    /// The leg acceleration (m/s²) nearest to `acceleration` within the limits, for the leg
    /// rate `rate` (m/s), the contact velocity `base_contact_velocity` of the platform motion
    /// alone (`v_b`, m/s), the unit leg direction and the period `dt` (s): first
    /// `|λ̈| ≤ steering_rate · ‖v_b + λ̇ l‖`, then the rate after `dt` clamped to
    /// `± speed_ratio · ‖v_b‖` (which may brake harder than the first bound: a leg that is too
    /// fast for the approaching ICR must slow down).
    ///
    /// ```
    /// use kernel::platform::legs::SteeringLimit;
    /// use nalgebra::Vector2;
    /// let limit = SteeringLimit { steering_rate: 2.0_f64, speed_ratio: 0.5 };
    /// let across = Vector2::new(0.0, 0.05); // 5 cm/s across the leg (x)
    /// // |λ̈| ≤ 2 rad/s · 0.05 m/s = 0.1 m/s².
    /// assert!((limit.limit(1.0, 0.0, &across, &Vector2::x(), 1e-3) - 0.1).abs() < 1e-12);
    /// // Already at 0.025 m/s = 0.5 · 0.05 m/s: no faster.
    /// assert!(limit.limit(1.0, 0.025, &across, &Vector2::x(), 1e-3).abs() < 1e-12);
    /// ```
    pub fn limit(
        &self,
        acceleration: T,
        rate: T,
        base_contact_velocity: &Vector2<T>,
        leg_direction: &Vector2<T>,
        dt: T,
    ) -> T {
        let contact_speed = sqrt((base_contact_velocity + leg_direction * rate).norm_squared());
        let bound = self.steering_rate * contact_speed;
        let steered = acceleration.max(-bound).min(bound);
        let rate_bound = self.speed_ratio * sqrt(base_contact_velocity.norm_squared());
        let next = (rate + steered * dt).max(-rate_bound).min(rate_bound);
        (next - rate) / dt
    }
}

/// PD gains of the return-to-nominal loop (Fig. 3.10); none is given by the thesis ("Their
/// values are dependent on the desired closed-loop poles of the second-order system").
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReturnGains<T> {
    /// Position gain `k₁` (1/s²); a double pole at `−ω` has `k₁ = ω²`.
    pub stiffness: T,
    /// Velocity gain `k₂` (1/s); a double pole at `−ω` has `k₂ = 2ω`.
    pub damping: T,
    /// Width of the ramp outside the field border over which the gains fade in (m), `≥ 0`.
    pub blend: T,
}

impl<T: RealField + Copy> ReturnGains<T> {
    /// Gains for a critically damped double pole at `−ω` (rad/s): `k₁ = ω²`, `k₂ = 2ω`.
    pub fn critically_damped(omega: T, blend: T) -> Self {
        Self { stiffness: omega * omega, damping: omega + omega, blend }
    }

    /// Validates the gains (finite, `≥ 0`).
    pub fn validate(&self) -> Result<(), PlatformError> {
        if [self.stiffness, self.damping, self.blend].iter().all(|x| x.is_finite() && *x >= T::zero()) {
            Ok(())
        } else {
            Err(PlatformError::InvalidParameter { name: "return gains" })
        }
    }

    /// Share `σ ∈ [0, 1]` of the gains active at the nearest wheel's distance: 0 inside the field
    /// (`d_sap ≤ d₀`), 1 from `d₀ + blend` on (and without an ICR), C¹ in between.
    pub fn gain(&self, nearest: Option<&NearestWheel<T>>) -> T {
        nearest.map_or_else(T::one, |w| {
            T::one() - transition_activation(w.distance, w.extension, w.extension + self.blend)
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::platform::icr::{BaseTwist, IcrRepulsion, IcrRepulsionConfig};
    use core::f64::consts::FRAC_PI_4;
    use nalgebra::Vector2;

    fn legs<T: RealField + Copy>() -> LegAdmittanceConfig<T> {
        let c = |x: f64| nalgebra::convert::<f64, T>(x);
        LegAdmittanceConfig {
            mass: c(0.5),
            damping: c(4.0),
            cubic_stiffness: c(1.2e4),
            nominal_length: c(0.53),
            min_length: c(0.45),
            max_length: c(0.7),
        }
    }

    /// A constant leg force settles where the cubic spring balances it: (3.37)–(3.38) statics
    /// `c₁ Δλ³ = F_w`; the leg moves away from the ICR.
    fn settles_at_the_cubic_equilibrium<T: RealField + Copy>(tolerance: f64) {
        let c = |x: f64| nalgebra::convert::<f64, T>(x);
        let repulsion = IcrRepulsion::try_new(IcrRepulsionConfig {
            leg_directions: [c(FRAC_PI_4), c(3.0 * FRAC_PI_4), c(-3.0 * FRAC_PI_4), c(-FRAC_PI_4)],
            max_extension: c(0.2),
            extension_ratio: c(0.4),
            max_force: c(2.0),
            min_yaw_rate: c(1e-3),
        })
        .unwrap();
        // ICR 5 cm outside wheel 2 (index 1) along its leg: the leg must retract.
        let lengths = [c(0.53); LEGS];
        let p = repulsion.wheel_positions(&lengths)[1] * c(0.58 / 0.53);
        let twist = BaseTwist { forward: p.y, lateral: -p.x, yaw_rate: T::one() };
        let out = repulsion.repulsion(&twist, &lengths).unwrap();
        let force = leg_force(&out);
        assert!(force < T::zero(), "retract: {force}");
        let config = legs::<T>();
        let mut admittance = LegAdmittance::try_new(config).unwrap();
        for _ in 0..20_000 {
            let state = admittance.lengths();
            let rates = admittance.rates();
            let mut accelerations = [T::zero(); LEGS];
            accelerations[1] = leg_acceleration(&config, state[1] - config.nominal_length, rates[1], force);
            admittance.integrate(&accelerations, c(1e-3)).unwrap();
        }
        let deviation = admittance.lengths()[1] - config.nominal_length;
        let expected = -(-force / config.cubic_stiffness).cbrt();
        assert!((deviation - expected).abs() < c(tolerance), "{deviation} vs {expected}");
        assert_eq!(admittance.lengths()[0], config.nominal_length);
    }

    #[test]
    fn leg_settles_at_the_cubic_equilibrium_f64() {
        settles_at_the_cubic_equilibrium::<f64>(1e-6);
    }

    #[test]
    fn leg_settles_at_the_cubic_equilibrium_f32() {
        settles_at_the_cubic_equilibrium::<f32>(1e-4);
    }

    /// The steering limit bounds `|λ̈|` by the steering rate it causes and `|λ̇|` by the
    /// platform's contact speed; far from the ICR it lets the admittance through.
    fn steering_limit_bounds_the_leg_motion<T: RealField + Copy>(tolerance: f64) {
        let c = |x: f64| nalgebra::convert::<f64, T>(x);
        let f = |x: T| -> f64 { nalgebra::try_convert(x).unwrap() };
        let limit = SteeringLimit { steering_rate: c(2.0), speed_ratio: c(0.5) };
        let leg = Vector2::new(T::one(), T::zero());
        let dt = c(1e-3);
        // ICR near the wheel: 5 cm/s across the leg.
        let slow = Vector2::new(T::zero(), c(0.05));
        assert!((f(limit.limit(c(1.0), T::zero(), &slow, &leg, dt)) - 0.1).abs() < tolerance);
        assert!((f(limit.limit(c(-1.0), T::zero(), &slow, &leg, dt)) + 0.1).abs() < tolerance);
        // At the rate bound 0.5 · 0.05 m/s no faster; above it braked back to it within dt.
        assert!(f(limit.limit(c(1.0), c(0.025), &slow, &leg, dt)).abs() < tolerance);
        assert!((f(limit.limit(T::zero(), c(0.04), &slow, &leg, dt)) + 15.0).abs() < 1e3 * tolerance);
        // The wheel direction turns at most at the steering rate during a limited step.
        let rate = c(0.01);
        let a = limit.limit(c(5.0), rate, &slow, &leg, dt);
        let before = slow + leg * rate;
        let after = slow + leg * (rate + a * dt);
        let turn = f(after.y.atan2(after.x) - before.y.atan2(before.x)).abs() / f(dt);
        assert!(turn <= 2.0 * (1.0 + 1e-2) && turn > 1.9, "steering rate {turn}");
        // Far from the ICR (1 m/s): the admittance's 1 m/s² passes unchanged.
        let fast = Vector2::new(T::zero(), T::one());
        assert!((f(limit.limit(c(1.0), c(0.1), &fast, &leg, dt)) - 1.0).abs() < 1e3 * tolerance);
        assert!(limit.validate().is_ok());
        assert!(SteeringLimit { speed_ratio: T::one(), ..limit }.validate().is_err());
        assert!(SteeringLimit { steering_rate: T::zero(), ..limit }.validate().is_err());
    }

    #[test]
    fn steering_limit_bounds_the_leg_motion_f64() {
        steering_limit_bounds_the_leg_motion::<f64>(1e-9);
    }

    #[test]
    fn steering_limit_bounds_the_leg_motion_f32() {
        steering_limit_bounds_the_leg_motion::<f32>(1e-4);
    }

    #[test]
    fn end_stops_and_return_gain() {
        let config = legs::<f64>();
        let mut admittance = LegAdmittance::try_new(config).unwrap();
        for _ in 0..2000 {
            admittance.integrate(&[5.0, -5.0, 0.0, 0.0], 1e-3).unwrap();
        }
        assert_eq!(admittance.lengths()[..2], [0.7, 0.45]);
        assert_eq!(admittance.rates()[..2], [0.0, 0.0]);
        assert!(admittance.integrate(&[f64::NAN; LEGS], 1e-3).is_err());
        let gains = ReturnGains::critically_damped(2.0, 0.05);
        assert_eq!((gains.stiffness, gains.damping), (4.0, 4.0));
        let wheel = |distance| NearestWheel {
            index: 0,
            distance,
            extension: 0.2,
            direction: Vector2::x(),
            leg_direction: Vector2::x(),
        };
        assert_eq!(gains.gain(Some(&wheel(0.1))), 0.0);
        assert_eq!(gains.gain(Some(&wheel(0.2))), 0.0);
        assert_eq!(gains.gain(Some(&wheel(0.225))), 0.5);
        assert_eq!(gains.gain(Some(&wheel(0.3))), 1.0);
        assert_eq!(gains.gain(None), 1.0);
        let bad = LegAdmittanceConfig { nominal_length: 0.8, ..config };
        assert_eq!(LegAdmittance::try_new(bad).err(), Some(PlatformError::InvalidParameter { name: "leg lengths" }));
        assert!(ReturnGains { stiffness: -1.0, damping: 0.0, blend: 0.0 }.validate().is_err());
    }
}
