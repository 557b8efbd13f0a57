//! The platform singularity avoidance loop of Fig. 3.10: nominal trajectory, ICR and leg
//! repulsion, return to the nominal trajectory, integrated into the commands of a
//! velocity-controlled platform.
//!
//! Per control period, with the commanded base velocity `ṙ_c` (world frame) as the motion the
//! wheels realise:
//! 1. the body twist of `ṙ_c` at the measured heading gives the ICR and its repulsion
//!    ([`IcrRepulsion::repulsion`], (3.25)–(3.36));
//! 2. the platform accelerations `r̈_sap = (R(θ)(ẍ, ÿ)_sap, θ̈_sap)` are added to the reference
//!    acceleration, and the return loop `σ(d_sap)(k₁ e + k₂ ė)` with `e = r_ref − r`,
//!    `ė = ṙ_ref − ṙ` ([`ReturnGains`]) leads back to the nominal trajectory once the ICR has left
//!    the field:
//!    `r̈_c = r̈_ref + r̈_sap + σ (k₁ e + k₂ ė)`;
//! 3. with leg motion, the nearest wheel's leg follows the nonlinear admittance (3.40), the
//!    other legs relax to their nominal length with the same admittance, plus the return loop;
//!    with a [`SteeringLimit`] ([`PlatformAvoidance::with_steering_limit`]) every leg's
//!    acceleration is then limited by the steering its wheel needs to follow it;
//! 4. `ṙ_c` and the leg lengths are integrated over the period; the outputs are `ṙ_des = ṙ_c`
//!    and the leg rates for the velocity interface (`r̈_sap = [ẍ ÿ θ̈ λ̈₁ … λ̈₄]_sap`, Sec. 3.2.5).
//!
//! Switching the ICR avoidance off leaves a plain trajectory tracker (`σ = 1`), the thesis'
//! "ICR control OFF"; switching the leg motion off keeps the legs at their current length.

use nalgebra::{RealField, Vector2, Vector3};

use super::icr::{to_world, BaseTwist, IcrRepulsion, IcrRepulsionConfig, Repulsion};
use super::legs::{leg_acceleration, leg_force, LegAdmittance, LegAdmittanceConfig, ReturnGains, SteeringLimit};
use super::{PlatformError, LEGS};

/// Parameters of the avoidance loop.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AvoidanceConfig<T> {
    /// ICR repulsion (3.30)–(3.36).
    pub repulsion: IcrRepulsionConfig<T>,
    /// Leg admittance (3.37)–(3.40).
    pub legs: LegAdmittanceConfig<T>,
    /// Return-to-nominal gains (Fig. 3.10).
    pub return_gains: ReturnGains<T>,
    /// Apply the ICR repulsion ("ICR control ON").
    pub icr_avoidance: bool,
    /// Let the legs move ((3.37)–(3.40)); needs `icr_avoidance`.
    pub leg_motion: bool,
}

/// One sample of the nominal platform trajectory `(r_ref, ṙ_ref, r̈_ref)`, world frame
/// (`(x, y, θ)` in m, rad and their derivatives).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlatformReference<T> {
    /// `r_ref`.
    pub pose: Vector3<T>,
    /// `ṙ_ref`.
    pub velocity: Vector3<T>,
    /// `r̈_ref`.
    pub acceleration: Vector3<T>,
}

/// What one [`PlatformAvoidance::step`] commands and found.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AvoidanceOutput<T> {
    /// `ṙ_des` for the velocity interface, world frame (m/s, m/s, rad/s).
    pub velocity: Vector3<T>,
    /// Leg rate commands `λ̇_i` (m/s).
    pub leg_rates: [T; LEGS],
    /// Leg lengths the loop integrated (m).
    pub leg_lengths: [T; LEGS],
    /// The commanded acceleration `r̈_c`, world frame.
    pub acceleration: Vector3<T>,
    /// `r̈_sap` of the platform, world frame (zero with the avoidance off).
    pub avoidance_acceleration: Vector3<T>,
    /// Leg accelerations `λ̈_i` (m/s²).
    pub leg_accelerations: [T; LEGS],
    /// The ICR repulsion of the commanded twist (computed also with the avoidance off).
    pub repulsion: Repulsion<T>,
    /// Share `σ` of the return gains in use.
    pub return_gain: T,
    /// `true` if a field is active (`F_sap > 0`) and the avoidance is on.
    pub repelling: bool,
}

/// The loop of Fig. 3.10 with its state: the commanded velocity and the leg admittances.
///
/// ```
/// use kernel::platform::avoidance::{AvoidanceConfig, PlatformAvoidance, PlatformReference};
/// use kernel::platform::icr::IcrRepulsionConfig;
/// use kernel::platform::legs::{LegAdmittanceConfig, ReturnGains};
/// use nalgebra::Vector3;
/// use core::f64::consts::FRAC_PI_4;
/// let mut avoidance = PlatformAvoidance::try_new(AvoidanceConfig {
///     repulsion: IcrRepulsionConfig { leg_directions: [FRAC_PI_4, 3.0 * FRAC_PI_4, -3.0 * FRAC_PI_4, -FRAC_PI_4],
///         max_extension: 0.12, extension_ratio: 0.4, max_force: 0.8, min_yaw_rate: 1e-3 },
///     legs: LegAdmittanceConfig { mass: 0.2, damping: 1.0, cubic_stiffness: 1000.0, nominal_length: 0.53,
///         min_length: 0.45, max_length: 0.7 },
///     return_gains: ReturnGains::critically_damped(2.0, 0.05),
///     icr_avoidance: true, leg_motion: true }).unwrap();
/// // 5 cm behind the reference at rest: the return loop accelerates at k₁ e = 4 · 0.05 m/s².
/// let reference = PlatformReference { pose: Vector3::new(0.05, 0.0, 0.0), velocity: Vector3::zeros(), acceleration: Vector3::zeros() };
/// let out = avoidance.step(&reference, &Vector3::zeros(), &Vector3::zeros(), 1e-3).unwrap();
/// assert!((out.acceleration.x - 0.2).abs() < 1e-12 && (out.velocity.x - 2e-4).abs() < 1e-15);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlatformAvoidance<T> {
    config: AvoidanceConfig<T>,
    repulsion: IcrRepulsion<T>,
    legs: LegAdmittance<T>,
    velocity: Vector3<T>,
    steering_limit: Option<SteeringLimit<T>>,
}

impl<T: RealField + Copy> PlatformAvoidance<T> {
    /// Validates the configuration; starts at rest with the legs at their nominal length.
    pub fn try_new(config: AvoidanceConfig<T>) -> Result<Self, PlatformError> {
        let repulsion = IcrRepulsion::try_new(config.repulsion)?;
        let legs = LegAdmittance::try_new(config.legs)?;
        config.return_gains.validate()?;
        Ok(Self { config, repulsion, legs, velocity: Vector3::zeros(), steering_limit: None })
    }

    /// The same loop with the leg motion limited by the steering it needs ([`SteeringLimit`]);
    /// without it the legs follow (3.40) and the return loop alone. Errors: invalid limits.
    pub fn with_steering_limit(self, limit: SteeringLimit<T>) -> Result<Self, PlatformError> {
        limit.validate()?;
        Ok(Self { steering_limit: Some(limit), ..self })
    }

    /// The validated parameters.
    pub fn config(&self) -> &AvoidanceConfig<T> {
        &self.config
    }

    /// The ICR repulsion in use.
    pub fn repulsion(&self) -> &IcrRepulsion<T> {
        &self.repulsion
    }

    /// Sets the commanded velocity and the leg state (e.g. to the measured values).
    pub fn reset(&mut self, velocity: &Vector3<T>, leg_lengths: &[T; LEGS]) -> Result<(), PlatformError> {
        if !crate::math::all_finite(velocity) {
            return Err(PlatformError::NonFinite { input: "velocity" });
        }
        self.legs.reset(leg_lengths, &[T::zero(); LEGS])?;
        self.velocity = *velocity;
        Ok(())
    }

    /// One control period `dt` (s): the reference, the measured pose `r` and velocity `ṙ`
    /// (world frame) in; `ṙ_des` and the leg rates out. Errors: non-finite input, `dt ≤ 0`
    /// (state unchanged). Cost: a handful of trigonometric functions, no iteration.
    pub fn step(
        &mut self,
        reference: &PlatformReference<T>,
        pose: &Vector3<T>,
        velocity: &Vector3<T>,
        dt: T,
    ) -> Result<AvoidanceOutput<T>, PlatformError> {
        let finite = [reference.pose, reference.velocity, reference.acceleration, *pose, *velocity]
            .iter()
            .all(crate::math::all_finite);
        if !finite {
            return Err(PlatformError::NonFinite { input: "reference or platform state" });
        }
        if !(dt.is_finite() && dt > T::zero()) {
            return Err(PlatformError::InvalidParameter { name: "dt" });
        }
        let heading = pose.z;
        let twist = BaseTwist::from_world(&self.velocity, heading);
        let lengths = self.legs.lengths();
        let repulsion = self.repulsion.repulsion(&twist, &lengths)?;
        let active = self.config.icr_avoidance;
        let repelling = active && repulsion.force > T::zero();
        let sigma = if active { self.config.return_gains.gain(repulsion.nearest.as_ref()) } else { T::one() };

        let avoidance_acceleration = if active {
            let planar = to_world(&repulsion.body_acceleration, heading);
            Vector3::new(planar.x, planar.y, repulsion.yaw_acceleration)
        } else {
            Vector3::zeros()
        };
        let gains = &self.config.return_gains;
        let feedback =
            ((reference.pose - pose) * gains.stiffness + (reference.velocity - velocity) * gains.damping) * sigma;
        let acceleration = reference.acceleration + avoidance_acceleration + feedback;

        let leg_accelerations = if active && self.config.leg_motion {
            self.leg_accelerations(&repulsion, &twist, sigma, dt)
        } else {
            [T::zero(); LEGS]
        };
        let next_velocity = self.velocity + acceleration * dt;
        if !crate::math::all_finite(&next_velocity) {
            return Err(PlatformError::NonFinite { input: "commanded velocity" });
        }
        let mut legs = self.legs;
        let leg_rates =
            if active && self.config.leg_motion { legs.integrate(&leg_accelerations, dt)? } else { [T::zero(); LEGS] };
        self.legs = legs;
        self.velocity = next_velocity;
        Ok(AvoidanceOutput {
            velocity: next_velocity,
            leg_rates,
            leg_lengths: self.legs.lengths(),
            acceleration,
            avoidance_acceleration,
            leg_accelerations,
            repulsion,
            return_gain: sigma,
            repelling,
        })
    }
}

impl<T: RealField + Copy> PlatformAvoidance<T> {
    /// The leg accelerations: (3.40) for the nearest wheel's leg (the others relax with the
    /// same admittance), plus the return loop with share `sigma`, limited by the steering
    /// limit if one is set, for the commanded body twist `twist` and the period `dt`.
    fn leg_accelerations(&self, repulsion: &Repulsion<T>, twist: &BaseTwist<T>, sigma: T, dt: T) -> [T; LEGS] {
        let force = leg_force(repulsion);
        let nearest = repulsion.nearest.map(|w| w.index);
        let (lengths, rates) = (self.legs.lengths(), self.legs.rates());
        let (legs, gains) = (&self.config.legs, &self.config.return_gains);
        let wheels = self.repulsion.wheel_positions(&lengths);
        let mut accelerations = [T::zero(); LEGS];
        for (i, ((((a, length), rate), position), direction)) in accelerations
            .iter_mut()
            .zip(lengths.iter())
            .zip(rates.iter())
            .zip(wheels.iter())
            .zip(self.repulsion.leg_directions().iter())
            .enumerate()
        {
            let f = if nearest == Some(i) { force } else { T::zero() };
            let deviation = *length - legs.nominal_length;
            *a = leg_acceleration(legs, deviation, *rate, f)
                - (deviation * gains.stiffness + *rate * gains.damping) * sigma;
            if let Some(limit) = &self.steering_limit {
                let base_contact_velocity = wheel_velocity(twist, position, direction, T::zero());
                *a = limit.limit(*a, *rate, &base_contact_velocity, direction, dt);
            }
        }
        accelerations
    }
}

/// The body-frame velocity of wheel `i`'s contact point, `(ẋ − θ̇ p_y, ẏ + θ̇ p_x) + λ̇ l` (m/s),
/// for the body twist, the contact point `p = λ l` and the leg rate: the direction the wheel
/// must be steered to (Fig. 3.7, "the wheel gets an additional velocity component in leg motion
/// direction").
pub fn wheel_velocity<T: RealField + Copy>(
    twist: &BaseTwist<T>,
    position: &Vector2<T>,
    leg_direction: &Vector2<T>,
    leg_rate: T,
) -> Vector2<T> {
    Vector2::new(twist.forward - twist.yaw_rate * position.y, twist.lateral + twist.yaw_rate * position.x)
        + leg_direction * leg_rate
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use core::f64::consts::FRAC_PI_4;

    fn config<T: RealField + Copy>(icr_avoidance: bool, leg_motion: bool) -> AvoidanceConfig<T> {
        let c = |x: f64| nalgebra::convert::<f64, T>(x);
        AvoidanceConfig {
            repulsion: IcrRepulsionConfig {
                leg_directions: [c(FRAC_PI_4), c(3.0 * FRAC_PI_4), c(-3.0 * FRAC_PI_4), c(-FRAC_PI_4)],
                max_extension: c(0.2),
                extension_ratio: c(0.4),
                max_force: c(2.0),
                min_yaw_rate: c(1e-3),
            },
            legs: LegAdmittanceConfig {
                mass: c(0.5),
                damping: c(4.0),
                cubic_stiffness: c(1.2e4),
                nominal_length: c(0.53),
                min_length: c(0.45),
                max_length: c(0.7),
            },
            return_gains: ReturnGains::critically_damped(c(2.0), c(0.05)),
            icr_avoidance,
            leg_motion,
        }
    }

    /// A reference whose ICR sweeps radially through wheel 3 (index 2): with the avoidance the
    /// ICR never gets closer than a fraction of the field, without it it passes within 1 cm.
    /// The kinematic platform follows the command exactly.
    /// Returns the closest ICR–wheel distance, the largest deviation and the largest leg rate per
    /// contact speed of the platform motion at the leg's wheel.
    fn closest_approach<T: RealField + Copy>(
        icr_avoidance: bool,
        leg_motion: bool,
        steering: Option<SteeringLimit<T>>,
    ) -> (f64, f64, f64) {
        let c = |x: f64| nalgebra::convert::<f64, T>(x);
        let mut avoidance = PlatformAvoidance::try_new(config::<T>(icr_avoidance, leg_motion)).unwrap();
        if let Some(limit) = steering {
            avoidance = avoidance.with_steering_limit(limit).unwrap();
        }
        let mut leg_speed_ratio = 0.0_f64;
        let direction = Vector2::new(c(-FRAC_PI_4.cos()), c(-FRAC_PI_4.sin()));
        let normal = Vector2::new(-direction.y, direction.x);
        let omega = c(0.7);
        let dt = c(1e-3);
        // Body-frame reference twist with ICR at ρ(t) d + 0.005 n; integrated to a world pose.
        let mut pose = Vector3::<T>::zeros();
        let mut reference_pose = Vector3::<T>::zeros();
        let mut closest = f64::INFINITY;
        let mut deviation = 0.0_f64;
        for k in 0..3000 {
            let t = c(f64::from(k) * 1e-3);
            let rho = c(0.2) + c(0.25) * t;
            let p = direction * rho + normal * c(0.005);
            let body = Vector2::new(omega * p.y, -omega * p.x);
            let planar = to_world(&body, reference_pose.z);
            let velocity = Vector3::new(planar.x, planar.y, omega);
            // d/dt of the world velocity: rotation of the body velocity plus its change.
            let body_rate = Vector2::new(omega * direction.y, -omega * direction.x) * c(0.25);
            let turn = to_world(&Vector2::new(-body.y, body.x), reference_pose.z) * omega;
            let planar_rate = to_world(&body_rate, reference_pose.z) + turn;
            let reference = PlatformReference {
                pose: reference_pose,
                velocity,
                acceleration: Vector3::new(planar_rate.x, planar_rate.y, T::zero()),
            };
            if k == 0 {
                avoidance.reset(&velocity, &[c(0.53); LEGS]).unwrap();
            }
            let measured_velocity = avoidance.velocity;
            let twist = BaseTwist::from_world(&measured_velocity, pose.z);
            let out = avoidance.step(&reference, &pose, &measured_velocity, dt).unwrap();
            let wheels = avoidance.repulsion().wheel_positions(&out.leg_lengths);
            for ((p, l), rate) in wheels.iter().zip(avoidance.repulsion().leg_directions()).zip(out.leg_rates) {
                let contact: f64 = nalgebra::try_convert(wheel_velocity(&twist, p, l, T::zero()).norm()).unwrap();
                let rate: f64 = nalgebra::try_convert(rate.abs()).unwrap();
                leg_speed_ratio = leg_speed_ratio.max(rate / contact.max(1e-9));
            }
            pose += out.velocity * dt;
            reference_pose += velocity * dt;
            let wheel = avoidance.repulsion().wheel_positions(&out.leg_lengths)[2];
            if let Some(icr) =
                crate::platform::icr::instantaneous_center(&BaseTwist::from_world(&out.velocity, pose.z), c(1e-6))
                    .position
            {
                let d: f64 = nalgebra::try_convert((icr - wheel).norm()).unwrap();
                closest = closest.min(d);
            }
            let e: f64 = nalgebra::try_convert((reference_pose - pose).fixed_rows::<2>(0).norm()).unwrap();
            deviation = deviation.max(e);
            assert!(out.velocity.iter().chain(out.leg_rates.iter()).all(|x| x.is_finite()));
        }
        (closest, deviation, leg_speed_ratio)
    }

    #[test]
    fn avoidance_keeps_the_icr_away_from_the_wheel_f64() {
        let (off, ..) = closest_approach::<f64>(false, false, None);
        let (on, deviation_on, _) = closest_approach::<f64>(true, false, None);
        let (legs, deviation_legs, _) = closest_approach::<f64>(true, true, None);
        eprintln!("closest ICR–wheel distance: off {off:.4} m, on {on:.4} m, on+legs {legs:.4} m; deviation {deviation_on:.4} m vs {deviation_legs:.4} m with legs");
        assert!(off < 0.01, "without avoidance the ICR passes the wheel: {off}");
        assert!(on > 0.05, "with avoidance it stays away: {on}");
        assert!(legs > 0.05, "{legs}");
        assert!(deviation_legs < deviation_on, "legs reduce the deviation: {deviation_legs} vs {deviation_on}");
    }

    #[test]
    fn avoidance_keeps_the_icr_away_from_the_wheel_f32() {
        let (on, ..) = closest_approach::<f32>(true, true, None);
        assert!(on > 0.05, "{on}");
    }

    /// With the steering limit every leg moves at most `speed_ratio` times as fast as the
    /// platform motion moves its wheel (one period's lag of the contact speed allowed); without
    /// it the leg near the ICR is faster than that. The ICR is still kept away.
    fn steering_limit_keeps_the_legs_slower_than_their_wheels<T: RealField + Copy>() {
        let c = |x: f64| nalgebra::convert::<f64, T>(x);
        let limit = SteeringLimit { steering_rate: c(1.5), speed_ratio: c(0.2) };
        let (_, _, free) = closest_approach::<T>(true, true, None);
        let (closest, _, limited) = closest_approach::<T>(true, true, Some(limit));
        assert!(free > 0.3, "without the limit: {free}");
        assert!(limited <= 0.2 * 1.02 && limited > 0.15, "with the limit: {limited}");
        assert!(closest > 0.05, "{closest}");
        let bad = SteeringLimit { speed_ratio: c(1.5), ..limit };
        let avoidance = PlatformAvoidance::try_new(config::<T>(true, true)).unwrap();
        assert_eq!(
            avoidance.with_steering_limit(bad).err(),
            Some(PlatformError::InvalidParameter { name: "steering limit" })
        );
    }

    #[test]
    fn steering_limit_keeps_the_legs_slower_than_their_wheels_f64() {
        steering_limit_keeps_the_legs_slower_than_their_wheels::<f64>();
    }

    #[test]
    fn steering_limit_keeps_the_legs_slower_than_their_wheels_f32() {
        steering_limit_keeps_the_legs_slower_than_their_wheels::<f32>();
    }

    #[test]
    fn wheel_velocity_is_perpendicular_to_the_icr_line() {
        let twist = BaseTwist { forward: 0.3, lateral: -0.2, yaw_rate: 0.9 };
        let icr = crate::platform::icr::instantaneous_center(&twist, 1e-6).position.unwrap();
        let l = Vector2::new(FRAC_PI_4.cos(), FRAC_PI_4.sin());
        let p = l * 0.53;
        let v = wheel_velocity(&twist, &p, &l, 0.0);
        assert!(v.dot(&(p - icr)).abs() < 1e-12);
        assert!((v.norm() - 0.9 * (p - icr).norm()).abs() < 1e-12);
        let with_leg = wheel_velocity(&twist, &p, &l, 0.1);
        assert!((with_leg - v - l * 0.1).amax() < 1e-15);
    }
}
