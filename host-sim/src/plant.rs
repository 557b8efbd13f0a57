//! What separates the real robot from the ideal one: joint friction, the torque loop's lag,
//! the delay between sensing and actuation, and noisy, offset, quantised sensors.
//!
//! The ideal plant ([`PlantKind::Ideal`], the default) applies a torque command exactly and at
//! once and reads the state exactly, so the thesis' figures keep their exact numbers. The
//! realistic plant ([`PlantKind::Realistic`], `--plant realistic`) adds, per upper-body joint
//! ([`PlantModel::justin`] gives the magnitudes and where each comes from):
//!
//! - **Friction** at the link: `τ_f = −τ_c tanh(q̇/v_s) − d q̇`, Coulomb friction smoothed over
//!   `v_s` plus viscous friction, both proportional to the joint's peak torque (none on a joint
//!   without an effort limit, such as those of the thesis' planar models). It acts in
//!   every Runge–Kutta stage like the dynamics; the torque sensor does not see it (the sensor
//!   sits between gear and link, the friction of the output bearing after it).
//! - **Torque loop**: the applied torque follows its set point through a first-order lag `T`
//!   (the joint's own torque controller), integrated exactly per physics step with the set
//!   point held: `τ ← τ + (1 − e^{−h/T}) (τ_set − τ)`.
//! - **Delay**: the command written in control cycle `k` becomes the set point when cycle
//!   `k + 1` reads the sensors (one cycle of bus transfer and computation).
//! - **Sensors**: joint positions with Gaussian noise, quantised to the encoder resolution;
//!   velocities with Gaussian noise (differentiated, filtered encoder signal); joint torques
//!   with a constant offset per joint (drawn once, uniform in `±offset`), Gaussian noise, and
//!   quantised to the converter's resolution.
//!
//! All randomness comes from one seeded generator (xoshiro256++), so a run is reproducible
//! from its seed.

use nalgebra::SVector;
use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

/// Which plant the simulator drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum PlantKind {
    /// Torques act exactly and at once; sensors are exact; no friction.
    #[default]
    Ideal,
    /// Friction, torque-loop lag, one cycle of delay, noisy sensors (magnitudes: `PlantModel::justin`).
    Realistic,
}

impl PlantKind {
    /// The name on the command line (`ideal`, `realistic`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Ideal => "ideal",
            Self::Realistic => "realistic",
        }
    }
}

/// Magnitudes of the non-ideal effects. Friction is given relative to each joint's peak
/// torque (the model's effort limit), so one model fits joints of every size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantModel {
    /// Coulomb friction `τ_c` as a fraction of the joint's peak torque.
    pub coulomb_fraction: f64,
    /// Viscous friction `d` as a fraction of the peak torque per rad/s (s/rad).
    pub viscous_fraction_s: f64,
    /// Velocity `v_s` over which the Coulomb friction changes sign (rad/s), `> 0`.
    pub friction_velocity: f64,
    /// Time constant `T` of the torque loop (s), `≥ 0`.
    pub torque_lag_s: f64,
    /// Control cycles between sensing and actuation (0 or 1).
    pub delay_cycles: u8,
    /// Encoder resolution (rad), `≥ 0`; 0 means no quantisation.
    pub encoder_resolution_rad: f64,
    /// Standard deviation of the position noise (rad).
    pub position_noise_rad: f64,
    /// Standard deviation of the velocity noise (rad/s).
    pub velocity_noise_rad_s: f64,
    /// Largest torque-sensor offset (Nm); each joint draws one uniformly in `±` this.
    pub torque_offset_nm: f64,
    /// Standard deviation of the torque-sensor noise (Nm).
    pub torque_noise_nm: f64,
    /// Torque-sensor resolution (Nm), `≥ 0`; 0 means no quantisation.
    pub torque_resolution_nm: f64,
    /// Seed of the noise generator.
    pub seed: u64,
}

impl PlantModel {
    /// Magnitudes for Justin's joints (DLR LWR III arms and torso: harmonic-drive joints with
    /// link-side torque sensors and a joint torque controller at 3 kHz):
    /// - friction: 1 % of the peak torque Coulomb and 0.5 %/(rad/s) viscous — what remains of
    ///   the gear friction under joint torque control (the torque loop suppresses most of the
    ///   several-percent raw harmonic-drive friction), smoothed over 0.05 rad/s;
    /// - torque loop: `T` = 0.5 ms, a closed-loop bandwidth of ≈ 300 Hz, a tenth of the 3 kHz
    ///   loop rate;
    /// - delay: one 1 ms control cycle (sensor frame in, torque frame out over the bus);
    /// - encoders: 2π/2²⁰ rad (a 20-bit resolution at the link), noise 10 µrad;
    /// - velocity: noise 5 mrad/s, the scale of a 1 kHz difference of the quantised position
    ///   (resolution / 1 ms ≈ 6 mrad/s) after filtering;
    /// - torque sensors: offsets up to ±0.2 Nm (drift between calibrations), noise 0.05 Nm,
    ///   resolution 0.01 Nm (a 16-bit converter over ±300 Nm).
    pub fn justin(seed: u64) -> Self {
        Self {
            coulomb_fraction: 0.01,
            viscous_fraction_s: 0.005,
            friction_velocity: 0.05,
            torque_lag_s: 5e-4,
            delay_cycles: 1,
            encoder_resolution_rad: core::f64::consts::TAU / f64::from(1u32 << 20),
            position_noise_rad: 1e-5,
            velocity_noise_rad_s: 5e-3,
            torque_offset_nm: 0.2,
            torque_noise_nm: 0.05,
            torque_resolution_nm: 0.01,
            seed,
        }
    }

    /// Errors: a magnitude out of its documented range (or NaN), named.
    pub fn validate(&self) -> Result<(), &'static str> {
        let non_negative = [
            (self.coulomb_fraction, "coulomb_fraction"),
            (self.viscous_fraction_s, "viscous_fraction_s"),
            (self.torque_lag_s, "torque_lag_s"),
            (self.encoder_resolution_rad, "encoder_resolution_rad"),
            (self.position_noise_rad, "position_noise_rad"),
            (self.velocity_noise_rad_s, "velocity_noise_rad_s"),
            (self.torque_offset_nm, "torque_offset_nm"),
            (self.torque_noise_nm, "torque_noise_nm"),
            (self.torque_resolution_nm, "torque_resolution_nm"),
        ];
        if let Some((_, name)) = non_negative.iter().find(|(x, _)| !(x.is_finite() && *x >= 0.0)) {
            return Err(name);
        }
        if !(self.friction_velocity.is_finite() && self.friction_velocity > 0.0) {
            return Err("friction_velocity");
        }
        if self.delay_cycles > 1 {
            return Err("delay_cycles");
        }
        Ok(())
    }
}

/// The realistic plant's state in a simulator of `U` upper-body joints: the torque set point,
/// the command waiting for the next cycle, the per-joint friction and offsets, the generator.
#[derive(Clone, Debug)]
pub(crate) struct RealisticJoints<const U: usize> {
    model: PlantModel,
    coulomb: SVector<f64, U>,
    viscous: SVector<f64, U>,
    offsets: SVector<f64, U>,
    set_point: SVector<f64, U>,
    pending: SVector<f64, U>,
    rng: Xoshiro256PlusPlus,
}

impl<const U: usize> RealisticJoints<U> {
    /// The plant of joints with peak torques `effort`; draws the torque-sensor offsets. A joint
    /// without an effort limit (`f64::MAX` from `Limits::unlimited`, as in the thesis' planar
    /// models, or infinite) has no friction: the fractions have no peak torque to scale.
    pub(crate) fn new(model: PlantModel, effort: &SVector<f64, U>) -> Self {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(model.seed);
        let offsets = SVector::from_fn(|_, _| model.torque_offset_nm * rng.random_range(-1.0..=1.0));
        let peak = effort.map(|e| if e < f64::MAX { e } else { 0.0 });
        Self {
            model,
            coulomb: peak * model.coulomb_fraction,
            viscous: peak * model.viscous_fraction_s,
            offsets,
            set_point: SVector::zeros(),
            pending: SVector::zeros(),
            rng,
        }
    }

    /// The friction torque at joint velocities `v`.
    pub(crate) fn friction(&self, v: &SVector<f64, U>) -> SVector<f64, U> {
        let v_s = self.model.friction_velocity;
        v.zip_zip_map(&self.coulomb, &self.viscous, |v, c, d| -(c * (v / v_s).tanh() + d * v))
    }

    /// The largest friction torque magnitude at joint velocities `v`, `τ_c + d |q̇|`: what
    /// the friction can hold against at any velocity (the full Coulomb level, the smoothing
    /// aside).
    pub(crate) fn friction_bound(&self, v: &SVector<f64, U>) -> SVector<f64, U> {
        v.zip_zip_map(&self.coulomb, &self.viscous, |v, c, d| c + d * v.abs())
    }

    /// A new torque command (already clamped): the set point now, or at the next cycle.
    pub(crate) fn command(&mut self, torque: &SVector<f64, U>) {
        if self.model.delay_cycles == 0 {
            self.set_point = *torque;
        }
        self.pending = *torque;
    }

    /// A new control cycle reads the sensors: the delayed command becomes the set point.
    pub(crate) fn next_cycle(&mut self) {
        self.set_point = self.pending;
    }

    /// Drops every command (brakes): set point and pending command zero.
    pub(crate) fn stop(&mut self) {
        self.set_point = SVector::zeros();
        self.pending = SVector::zeros();
    }

    /// Moves the applied torque one physics step `h` towards the set point (exact first-order
    /// response with the set point held).
    pub(crate) fn follow(&self, applied: &mut SVector<f64, U>, h: f64) {
        let alpha = if self.model.torque_lag_s > 0.0 { 1.0 - (-h / self.model.torque_lag_s).exp() } else { 1.0 };
        *applied += (self.set_point - *applied) * alpha;
    }

    /// What the encoders report for positions `q`.
    pub(crate) fn sense_position(&mut self, q: &SVector<f64, U>) -> SVector<f64, U> {
        let (sigma, step) = (self.model.position_noise_rad, self.model.encoder_resolution_rad);
        let rng = &mut self.rng;
        q.map(|q| quantise(q + sigma * gaussian(rng), step))
    }

    /// What the velocity estimate reports for velocities `v`.
    pub(crate) fn sense_velocity(&mut self, v: &SVector<f64, U>) -> SVector<f64, U> {
        let sigma = self.model.velocity_noise_rad_s;
        let rng = &mut self.rng;
        v.map(|v| v + sigma * gaussian(rng))
    }

    /// What the torque sensors report for the applied torque.
    pub(crate) fn sense_torque(&mut self, applied: &SVector<f64, U>) -> SVector<f64, U> {
        let (sigma, step) = (self.model.torque_noise_nm, self.model.torque_resolution_nm);
        let rng = &mut self.rng;
        applied.zip_map(&self.offsets, |tau, offset| quantise(tau + offset + sigma * gaussian(rng), step))
    }
}

/// One draw of the standard normal distribution.
fn gaussian(rng: &mut Xoshiro256PlusPlus) -> f64 {
    StandardNormal.sample(rng)
}

/// `x` rounded to a multiple of `step` (`x` itself for `step = 0`).
fn quantise(x: f64, step: f64) -> f64 {
    if step > 0.0 {
        (x / step).round() * step
    } else {
        x
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "test code")]
mod tests {
    use super::*;

    fn joints() -> RealisticJoints<2> {
        RealisticJoints::new(PlantModel::justin(7), &SVector::from([100.0, 20.0]))
    }

    #[test]
    fn friction_opposes_motion_and_scales_with_the_peak_torque() {
        let plant = joints();
        let f = plant.friction(&SVector::from([1.0, -1.0]));
        // 1 % Coulomb (tanh(20) = 1 to 1e-17) + 0.5 %/(rad/s) viscous.
        assert!((f[0] + 1.5).abs() < 1e-12 && (f[1] - 0.3).abs() < 1e-12);
        assert_eq!(plant.friction(&SVector::zeros()), SVector::<f64, 2>::zeros());
        // Half of the Coulomb level at v = v_s · atanh(½).
        let v = 0.05 * 0.5f64.atanh();
        assert!((plant.friction(&SVector::from([v, 0.0]))[0] + 0.5 + 0.5 * v).abs() < 1e-12);
    }

    #[test]
    fn a_command_acts_one_cycle_later_through_the_lag() {
        let mut plant = joints();
        let mut applied = SVector::<f64, 2>::zeros();
        plant.command(&SVector::from([10.0, -4.0]));
        plant.follow(&mut applied, 1e-3);
        assert_eq!(applied, SVector::<f64, 2>::zeros(), "not before the next cycle");
        plant.next_cycle();
        let h = 1.0 / 6000.0;
        for _ in 0..3 {
            plant.follow(&mut applied, h);
        }
        // After 0.5 ms = one time constant: 1 − e⁻¹ of the step.
        let expected = 1.0 - (-1.0f64).exp();
        assert!((applied[0] / 10.0 - expected).abs() < 1e-12 && (applied[1] / -4.0 - expected).abs() < 1e-12);
        plant.stop();
        plant.next_cycle();
        for _ in 0..600 {
            plant.follow(&mut applied, h);
        }
        assert!(applied.amax() < 1e-12);
    }

    #[test]
    fn sensors_are_offset_noisy_and_quantised_with_the_documented_statistics() {
        let mut plant = joints();
        let model = PlantModel::justin(7);
        let n = 20_000;
        let (mut sum, mut sum_sq) = (SVector::<f64, 2>::zeros(), SVector::<f64, 2>::zeros());
        for _ in 0..n {
            let tau = plant.sense_torque(&SVector::from([5.0, -3.0]));
            for i in 0..2 {
                // On the converter's grid.
                assert!(((tau[i] / 0.01).round() - tau[i] / 0.01).abs() < 1e-6);
            }
            sum += tau;
            sum_sq += tau.component_mul(&tau);
        }
        let mean = sum / f64::from(n);
        let var = sum_sq / f64::from(n) - mean.component_mul(&mean);
        for (i, applied) in [5.0, -3.0].into_iter().enumerate() {
            let offset = mean[i] - applied;
            assert!(offset.abs() <= model.torque_offset_nm + 0.01, "offset {offset}");
            assert!((offset - plant.offsets[i]).abs() < 0.005, "mean offset {offset} vs drawn {}", plant.offsets[i]);
            // Noise 0.05 Nm plus the quantisation's 0.01²/12.
            let sigma = var[i].sqrt();
            assert!((sigma - (0.05f64.powi(2) + 1e-4 / 12.0).sqrt()).abs() < 0.003, "σ = {sigma}");
        }
        let q = plant.sense_position(&SVector::from([0.3, -1.2]));
        let step = model.encoder_resolution_rad;
        assert!(((q[0] / step).round() - q[0] / step).abs() < 1e-6);
        assert!((q[0] - 0.3).abs() < 1e-4 && (q[1] + 1.2).abs() < 1e-4);
    }

    #[test]
    fn a_joint_without_an_effort_limit_has_no_friction() {
        let p = RealisticJoints::<3>::new(PlantModel::justin(1), &SVector::from([100.0, f64::MAX, f64::INFINITY]));
        let friction = p.friction(&SVector::from([1.0, 1.0, 1.0]));
        // 1 % Coulomb (tanh(1/0.05) = 1 − 8e-18) plus 0.5 %/(rad/s) viscous of 100 Nm at 1 rad/s.
        assert!((friction[0] + 1.5).abs() < 1e-12, "{friction}");
        assert_eq!((friction[1], friction[2]), (0.0, 0.0));
    }

    #[test]
    fn the_seed_decides_the_noise() {
        let draw = |seed| {
            let mut p = RealisticJoints::<2>::new(PlantModel::justin(seed), &SVector::from([100.0, 20.0]));
            p.sense_torque(&SVector::zeros())
        };
        assert_eq!(draw(3), draw(3));
        assert_ne!(draw(3), draw(4));
    }

    #[test]
    fn validation_names_the_bad_magnitude() {
        let mut m = PlantModel::justin(1);
        assert_eq!(m.validate(), Ok(()));
        m.torque_lag_s = -1.0;
        assert_eq!(m.validate(), Err("torque_lag_s"));
        m = PlantModel::justin(1);
        m.delay_cycles = 2;
        assert_eq!(m.validate(), Err("delay_cycles"));
        use clap::ValueEnum;
        assert_eq!(PlantKind::from_str("realistic", false), Ok(PlantKind::Realistic));
        assert!(PlantKind::from_str("ideal ", false).is_err());
        for kind in PlantKind::value_variants() {
            assert_eq!(kind.to_possible_value().map(|v| v.get_name().to_owned()), Some(kind.name().to_owned()));
        }
    }
}
