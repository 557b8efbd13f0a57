//! Wheel kinematics of the simulated platform: steering angle, steering rate and propulsion
//! rate of each of the four steerable wheels from the base twist and the leg motion (Sec. 3.2,
//! Fig. 3.7), with rate-limited steering actuators.
//!
//! The simulator's base is kinematic: it moves as commanded (`ṙ ≈ ṙ_des`). The wheels are what
//! a real platform would have to do to realise that motion, and where the ICR singularity
//! shows: wheel `i` at `p_i = λ_i l_i` (platform frame, `l_i = (cos ψ_i, sin ψ_i)`) moves with
//! `v_i = (ẋ_b − θ̇ p_i,y, ẏ_b + θ̇ p_i,x) + λ̇_i l_i` and must be steered along `v_i`. When the ICR
//! passes close to the wheel, `v_i` is small and turns quickly: the required steering rate
//! peaks.
//!
//! Conventions:
//! - the steering angle `β_i` is measured in the platform frame from its x axis and taken
//!   **modulo π** with a signed propulsion rate (a wheel reverses instead of turning half a
//!   revolution), unwrapped continuously;
//! - the *required* steering angle follows `v_i` exactly; below [`WheelConfig::min_speed_m_s`]
//!   its direction is undefined and the previous angle is kept;
//! - the *actual* steering angle follows the required one with at most
//!   [`WheelConfig::steering_rate_limit_rad_s`]; their difference (modulo π) is the
//!   **misalignment**, the cause of the "high internal forces which stress the mechanical
//!   structure" (Sec. 3.2.1);
//! - the propulsion rate is the component of `v_i` along the actual wheel direction divided by
//!   the wheel radius (rad/s).

use std::f64::consts::{FRAC_PI_2, PI};

use hal::{PlatformSample, LEGS};

/// Wheel parameters. [`Default`] is the Justin-like platform of `fixtures::justin`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WheelConfig {
    /// Leg directions `ψ_i` (rad from the platform's x axis).
    pub leg_directions: [f64; LEGS],
    /// Wheel radius (m).
    pub radius_m: f64,
    /// Largest steering rate of the steering actuators (rad/s).
    pub steering_rate_limit_rad_s: f64,
    /// Contact speed below which the steering direction counts as undefined (m/s).
    pub min_speed_m_s: f64,
}

/// Largest steering rate of the simulated steering drives (rad/s). **Invented** (the thesis
/// gives no steering-rate limit): Fig. 3.11 shows the steering rates with ICR control staying
/// within about ±5 rad/s and the uncontrolled peaks beyond ±10 rad/s, so 6 rad/s lets the
/// avoided motion pass unlimited and limits the uncontrolled peaks.
pub const STEERING_RATE_LIMIT_RAD_S: f64 = 6.0;

impl Default for WheelConfig {
    /// `fixtures::justin::{LEG_DIRECTIONS, WHEEL_RADIUS}`, [`STEERING_RATE_LIMIT_RAD_S`],
    /// a 1 cm/s speed floor.
    fn default() -> Self {
        Self {
            leg_directions: fixtures::justin::LEG_DIRECTIONS,
            radius_m: fixtures::justin::WHEEL_RADIUS,
            steering_rate_limit_rad_s: STEERING_RATE_LIMIT_RAD_S,
            min_speed_m_s: 0.01,
        }
    }
}

/// One wheel at one instant.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct WheelState {
    /// Required steering angle (rad, platform frame, continuous modulo π).
    pub required_angle_rad: f64,
    /// Rate of the required steering angle over the last update (rad/s).
    pub required_rate_rad_s: f64,
    /// Actual (rate-limited) steering angle (rad).
    pub angle_rad: f64,
    /// Actual steering rate (rad/s), `|·| ≤` the limit.
    pub rate_rad_s: f64,
    /// Required minus actual angle, wrapped to `(−π/2, π/2]` (rad).
    pub misalignment_rad: f64,
    /// Propulsion (spinning) rate along the actual wheel direction (rad/s, signed).
    pub propulsion_rad_s: f64,
    /// Speed of the contact point `‖v_i‖` (m/s).
    pub contact_speed_m_s: f64,
}

/// The four wheels with their steering state.
#[derive(Clone, Debug, PartialEq)]
pub struct Wheels {
    config: WheelConfig,
    states: [WheelState; LEGS],
    /// A wheel is aligned once its motion first defined a direction; before, it turns freely.
    aligned: [bool; LEGS],
}

/// `x` wrapped to `(−π/2, π/2]` (angles modulo π).
fn wrap_half_turn(x: f64) -> f64 {
    let wrapped = x - PI * (x / PI).round();
    if wrapped <= -FRAC_PI_2 {
        wrapped + PI
    } else {
        wrapped
    }
}

impl Wheels {
    /// Wheels at rest; each wheel is aligned with the motion the first time its contact point
    /// moves (an initial alignment, not counted as a steering rate).
    pub fn new(config: WheelConfig) -> Self {
        Self { config, states: [WheelState::default(); LEGS], aligned: [false; LEGS] }
    }

    /// The parameters.
    pub fn config(&self) -> &WheelConfig {
        &self.config
    }

    /// The wheel states of the last update.
    pub fn states(&self) -> &[WheelState; LEGS] {
        &self.states
    }

    /// Contact point velocities `v_i` in the platform frame (m/s) for the platform sample
    /// (world-frame velocity, heading, leg lengths) and the leg rates `λ̇_i` (m/s).
    pub fn contact_velocities(&self, sample: &PlatformSample<f64>, leg_rates: &[f64; LEGS]) -> [[f64; 2]; LEGS] {
        let [vx, vy, omega] = sample.velocity;
        let (s, c) = sample.pose[2].sin_cos();
        let (u, w) = (c * vx + s * vy, -s * vx + c * vy);
        let mut out = [[0.0; 2]; LEGS];
        for (((v, psi), lambda), rate) in
            out.iter_mut().zip(self.config.leg_directions.iter()).zip(sample.leg_lengths.iter()).zip(leg_rates.iter())
        {
            let (ls, lc) = psi.sin_cos();
            let (px, py) = (lambda * lc, lambda * ls);
            *v = [u - omega * py + rate * lc, w + omega * px + rate * ls];
        }
        out
    }

    /// Advances the steering by `dt_s` for the motion of `sample` with leg rates `leg_rates`.
    pub fn update(&mut self, sample: &PlatformSample<f64>, leg_rates: &[f64; LEGS], dt_s: f64) -> [WheelState; LEGS] {
        let velocities = self.contact_velocities(sample, leg_rates);
        let limit = self.config.steering_rate_limit_rad_s * dt_s;
        let dt = dt_s.max(f64::MIN_POSITIVE);
        for ((state, aligned), v) in self.states.iter_mut().zip(self.aligned.iter_mut()).zip(velocities.iter()) {
            let speed = v[0].hypot(v[1]);
            let previous = state.required_angle_rad;
            let defined = speed > self.config.min_speed_m_s;
            let first = defined && !*aligned;
            let required = if first {
                // Initial alignment: the wheel turns to the motion freely.
                *aligned = true;
                state.angle_rad = v[1].atan2(v[0]);
                state.angle_rad
            } else if defined {
                previous + wrap_half_turn(v[1].atan2(v[0]) - previous)
            } else {
                previous
            };
            let step = wrap_half_turn(required - state.angle_rad).clamp(-limit, limit);
            state.required_rate_rad_s = if first { 0.0 } else { (required - previous) / dt };
            state.rate_rad_s = step / dt;
            state.angle_rad += step;
            state.required_angle_rad = required;
            state.misalignment_rad = wrap_half_turn(required - state.angle_rad);
            let (s, c) = state.angle_rad.sin_cos();
            state.propulsion_rad_s = (v[0] * c + v[1] * s) / self.config.radius_m;
            state.contact_speed_m_s = speed;
        }
        self.states
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::indexing_slicing, reason = "tests")]
    use super::*;

    fn sample(velocity: [f64; 3], heading: f64, legs: f64) -> PlatformSample<f64> {
        PlatformSample { pose: [0.0, 0.0, heading], velocity, leg_lengths: [legs; LEGS], cycle: 0 }
    }

    #[test]
    fn pure_rotation_at_2_1_rad_s_needs_the_top_wheel_rate() {
        // Sec. 3.2.6: 2.1 rad/s "requires the maximum spinning rates of the wheels (13.9 rad/s)".
        let mut wheels = Wheels::new(WheelConfig::default());
        let legs = fixtures::justin::WHEEL_SPIN_RATE_MAX * fixtures::justin::WHEEL_RADIUS / 2.1;
        let states = wheels.update(&sample([0.0, 0.0, 2.1], 0.7, legs), &[0.0; LEGS], 1e-3);
        for (state, psi) in states.iter().zip(fixtures::justin::LEG_DIRECTIONS) {
            assert!((state.propulsion_rad_s.abs() - 13.9).abs() < 1e-9);
            // Steered tangentially: perpendicular to the leg.
            assert!(wrap_half_turn(state.angle_rad - psi - FRAC_PI_2).abs() < 1e-12);
        }
    }

    #[test]
    fn steering_is_rate_limited_and_reverses_instead_of_turning_half_a_revolution() {
        let mut wheels = Wheels::new(WheelConfig::default());
        wheels.update(&sample([0.5, 0.0, 0.0], 0.0, 0.53), &[0.0; LEGS], 1e-3);
        // Backwards: same steering angle, negative propulsion.
        let back = wheels.update(&sample([-0.5, 0.0, 0.0], 0.0, 0.53), &[0.0; LEGS], 1e-3);
        assert!(back.iter().all(|s| s.angle_rad.abs() < 1e-12 && s.propulsion_rad_s < 0.0 && s.rate_rad_s == 0.0));
        // Sideways: a quarter turn at 6 rad/s takes ≈ 262 ms.
        let mut steps = 0;
        while wheels.update(&sample([0.0, 0.5, 0.0], 0.0, 0.53), &[0.0; LEGS], 1e-3)[0].misalignment_rad.abs() > 1e-9 {
            steps += 1;
            assert!(wheels.states()[0].rate_rad_s.abs() <= STEERING_RATE_LIMIT_RAD_S + 1e-9);
        }
        assert!((261..=263).contains(&steps), "{steps}");
        assert!(wheels.states()[0].required_rate_rad_s == 0.0);
        // Standstill keeps the angle.
        let still = wheels.update(&sample([0.0; 3], 0.0, 0.53), &[0.0; LEGS], 1e-3);
        assert!(still.iter().all(|s| s.angle_rad.is_finite() && s.required_rate_rad_s == 0.0));
    }
}
