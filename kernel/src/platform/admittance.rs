//! The admittance interface of the velocity-controlled platform, (5.1)–(5.5) and (5.15).
//!
//! A virtual inertia `M_adm` and damping `D_adm` (both diagonal, (5.2)–(5.3)) turn the virtual
//! platform forces `τ_r,vir` of the whole-body impedance (and, if the platform has force
//! sensors, the measured external forces `τ_r,ext`) into the velocity `ṙ_des` that the base's
//! velocity controller realises:
//!
//! `M_adm r̈_des + D_adm ṙ_des = τ_r,vir + τ_r,ext` (5.1).
//!
//! Per axis this is the first-order low-pass `s R_i(s) = K_i / (T_i s + 1) · τ_i(s)` (5.4) with
//! the gain `K_i = 1/d_i` and the time constant `T_i = m_i/d_i` (5.5). Because the input force
//! is bounded by `F_max,i`, the velocity is bounded by `K_i F_max,i`: "via `K_i` the respective
//! maximum admittance velocity can be directly computed" ([`AdmittanceConfig::velocity_limit`]).
//!
//! The admittance is integrated exactly for a force held over the control period (zero-order
//! hold): `ṙ⁺ = α ṙ + (1 − α) K τ`, `α = exp(−Δt/T)`. This is stable for every `Δt > 0` and keeps
//! `|ṙ| ≤ K F_max` because `ṙ⁺` is a convex combination of `ṙ` and `K τ`.

use nalgebra::{RealField, Vector3};

use super::{clamp_symmetric, PlatformError};

/// Parameters of the admittance (5.1). Validate with [`Admittance::try_new`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AdmittanceConfig<T> {
    /// Diagonal of the virtual inertia `M_adm = diag(m_1, m_2, m_3)` (5.2): kg, kg, kg m².
    /// Table 5.2: `(7.5, 7.5, 2.5)`; the critical set of Sec. 5.1.4: `(3, 3, 1)`.
    pub mass: Vector3<T>,
    /// Diagonal of the virtual damping `D_adm = diag(d_1, d_2, d_3)` (5.3): kg/s, kg/s,
    /// kg m²/s. Table 5.2: `(24, 24, 8)`; critical set: `(21, 21, 7)`.
    pub damping: Vector3<T>,
    /// Bound `F_max,i ≥ 0` on the force entering axis `i` (N, N, Nm), `+∞` for none. With (5.5)
    /// it bounds the velocity by `K_i F_max,i`.
    pub force_limit: Vector3<T>,
    /// Axes `(x, y, θ)` the admittance drives; a locked axis is held at rest (`ṙ_des,i = 0`,
    /// `r̈_i = 0`).
    pub free_axes: [bool; 3],
}

impl<T: RealField + Copy> AdmittanceConfig<T> {
    /// The parameters from the intuitive gains of (5.4)–(5.5): the perceived inertia follows
    /// from the gain `K_i` ((m/s)/N, (rad/s)/Nm) and the time constant `T_i` (s) as
    /// `d_i = 1/K_i`, `m_i = T_i/K_i`. `None` if a gain is not positive and finite.
    ///
    /// ```
    /// use kernel::platform::admittance::AdmittanceConfig;
    /// use nalgebra::Vector3;
    /// // Table 5.2: K = 1/24 (m/s)/N, T = 7.5/24 s gives back m = 7.5 kg, d = 24 kg/s.
    /// let c = AdmittanceConfig::from_gains(Vector3::new(1.0 / 24.0, 1.0 / 24.0, 1.0 / 8.0),
    ///     Vector3::repeat(0.3125_f64), Vector3::repeat(f64::INFINITY), [true; 3]).unwrap();
    /// assert!((c.mass.x - 7.5).abs() < 1e-12 && (c.damping.z - 8.0).abs() < 1e-12);
    /// ```
    pub fn from_gains(
        gain: Vector3<T>,
        time_constant: Vector3<T>,
        force_limit: Vector3<T>,
        free_axes: [bool; 3],
    ) -> Option<Self> {
        if !gain.iter().all(|k| k.is_finite() && *k > T::zero()) {
            return None;
        }
        let damping = gain.map(|k| T::one() / k);
        Some(Self { mass: time_constant.component_mul(&damping), damping, force_limit, free_axes })
    }

    /// Gains `K_i = 1/d_i` (5.5): (m/s)/N, (m/s)/N, (rad/s)/Nm.
    pub fn gain(&self) -> Vector3<T> {
        self.damping.map(|d| T::one() / d)
    }

    /// Time constants `T_i = m_i/d_i` (5.5), s. Table 5.2: 0.3125 s; critical set: 0.143 s.
    pub fn time_constant(&self) -> Vector3<T> {
        self.mass.component_div(&self.damping)
    }

    /// Largest velocity the admittance can reach, `K_i F_max,i` (m/s, m/s, rad/s): the steady
    /// state of (5.4) for the largest admissible force. `+∞` for an unbounded force.
    pub fn velocity_limit(&self) -> Vector3<T> {
        self.force_limit.component_div(&self.damping)
    }
}

/// What one [`Admittance::step`] produced.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AdmittanceOutput<T> {
    /// `ṙ_des` at the end of the step, the command for the platform's velocity interface
    /// (m/s, m/s, rad/s; world frame).
    pub velocity: Vector3<T>,
    /// `r̈ = M_adm⁻¹ (τ_r,vir + τ_r,ext − D_adm ṙ_des)` (5.15) at the start of the step
    /// (m/s², rad/s²): the base acceleration the coupling compensation (5.14) uses, taken from
    /// the admittance instead of a measurement (`r ≈ r_des`).
    pub acceleration: Vector3<T>,
    /// The force that drove the admittance, `τ_r,vir + τ_r,ext` clamped to `±F_max` (N, Nm);
    /// zero on locked axes.
    pub force: Vector3<T>,
    /// `true` where the force limit clamped the force.
    pub saturated: [bool; 3],
}

/// The admittance (5.1) with its state `ṙ_des`.
///
/// ```
/// use kernel::platform::admittance::{Admittance, AdmittanceConfig};
/// use nalgebra::Vector3;
/// let config = AdmittanceConfig { mass: Vector3::new(7.5, 7.5, 2.5), damping: Vector3::new(24.0, 24.0, 8.0),
///     force_limit: Vector3::repeat(48.0_f64), free_axes: [true, true, true] };
/// let mut admittance = Admittance::try_new(config).unwrap();
/// // A constant 100 N is clamped to 48 N: the velocity settles at K F_max = 48/24 = 2 m/s.
/// for _ in 0..10_000 {
///     admittance.step(&Vector3::new(100.0, 0.0, 0.0), &Vector3::zeros(), 1e-3).unwrap();
/// }
/// assert!((admittance.velocity().x - 2.0).abs() < 1e-9);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Admittance<T> {
    config: AdmittanceConfig<T>,
    velocity: Vector3<T>,
}

impl<T: RealField + Copy> Admittance<T> {
    /// Validates `config` (masses and dampings finite and `> 0`: `M_adm`, `D_adm` positive
    /// definite as (5.19) requires; force limits `≥ 0`, not NaN, `+∞` allowed) and starts at rest.
    /// Errors: [`PlatformError::InvalidParameter`] naming the field.
    pub fn try_new(config: AdmittanceConfig<T>) -> Result<Self, PlatformError> {
        let positive = |v: &Vector3<T>| v.iter().all(|x| x.is_finite() && *x > T::zero());
        if !positive(&config.mass) {
            return Err(PlatformError::InvalidParameter { name: "mass" });
        }
        if !positive(&config.damping) {
            return Err(PlatformError::InvalidParameter { name: "damping" });
        }
        if !config.force_limit.iter().all(|f| *f >= T::zero()) {
            return Err(PlatformError::InvalidParameter { name: "force_limit" });
        }
        Ok(Self { config, velocity: Vector3::zeros() })
    }

    /// The validated parameters.
    pub fn config(&self) -> &AdmittanceConfig<T> {
        &self.config
    }

    /// The current `ṙ_des` (m/s, m/s, rad/s).
    pub fn velocity(&self) -> Vector3<T> {
        self.velocity
    }

    /// Sets the state `ṙ_des` (e.g. to the measured base velocity when the admittance is
    /// switched on). Locked axes are set to 0 and every axis is clamped to its velocity limit.
    /// Errors: a non-finite velocity (the state is unchanged).
    pub fn reset(&mut self, velocity: &Vector3<T>) -> Result<(), PlatformError> {
        if !crate::math::all_finite(velocity) {
            return Err(PlatformError::NonFinite { input: "velocity" });
        }
        self.velocity = self.limited(velocity);
        Ok(())
    }

    /// One control period `dt` (s) with the forces held: returns `ṙ_des` for the velocity
    /// interface and `r̈` (5.15) for the coupling compensation. `external_force` is the
    /// measured `τ_r,ext` or zero if the platform has no force sensors ("τ_r,ext has to be set
    /// to zero in (5.1)").
    ///
    /// Errors: non-finite forces, `dt` not finite and `> 0` (the state is unchanged).
    /// Cost: three exponentials.
    pub fn step(
        &mut self,
        virtual_force: &Vector3<T>,
        external_force: &Vector3<T>,
        dt: T,
    ) -> Result<AdmittanceOutput<T>, PlatformError> {
        if !(crate::math::all_finite(virtual_force) && crate::math::all_finite(external_force)) {
            return Err(PlatformError::NonFinite { input: "force" });
        }
        if !(dt.is_finite() && dt > T::zero()) {
            return Err(PlatformError::InvalidParameter { name: "dt" });
        }
        let c = &self.config;
        let mut out = AdmittanceOutput {
            velocity: Vector3::zeros(),
            acceleration: Vector3::zeros(),
            force: Vector3::zeros(),
            saturated: [false; 3],
        };
        let axes = c.mass.iter().zip(c.damping.iter()).zip(c.force_limit.iter()).zip(c.free_axes.iter());
        let inputs = virtual_force.iter().zip(external_force.iter()).zip(self.velocity.iter());
        let outputs = out.velocity.iter_mut().zip(out.acceleration.iter_mut()).zip(out.force.iter_mut());
        for ((((((m, d), limit), free), ((vir, ext), v)), ((v_next, a), f)), saturated) in
            axes.zip(inputs).zip(outputs).zip(out.saturated.iter_mut())
        {
            if !*free {
                continue;
            }
            let raw = *vir + *ext;
            let force = clamp_symmetric(raw, *limit);
            *saturated = force != raw;
            // (5.15): r̈ = M⁻¹ (τ_vir + τ_ext − D ṙ_des); m > 0 is validated.
            *a = (force - *d * *v) / *m;
            // Exact zero-order-hold solution of (5.1) over dt: ṙ⁺ = α ṙ + (1 − α) K τ.
            let alpha = (-dt * *d / *m).exp();
            *v_next = alpha * *v + (T::one() - alpha) * force / *d;
            *f = force;
        }
        out.velocity = self.limited(&out.velocity);
        self.velocity = out.velocity;
        Ok(out)
    }

    /// `velocity` with locked axes zeroed and every axis within `±K_i F_max,i`.
    fn limited(&self, velocity: &Vector3<T>) -> Vector3<T> {
        let limit = self.config.velocity_limit();
        let mut out = Vector3::zeros();
        for (((o, v), l), free) in
            out.iter_mut().zip(velocity.iter()).zip(limit.iter()).zip(self.config.free_axes.iter())
        {
            if *free {
                *o = clamp_symmetric(*v, *l);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;

    fn c<T: RealField + Copy>(x: f64) -> T {
        nalgebra::convert(x)
    }

    fn table_5_2<T: RealField + Copy>() -> AdmittanceConfig<T> {
        AdmittanceConfig {
            mass: Vector3::new(c(7.5), c(7.5), c(2.5)),
            damping: Vector3::new(c(24.0), c(24.0), c(8.0)),
            force_limit: Vector3::repeat(c(f64::INFINITY)),
            free_axes: [true; 3],
        }
    }

    /// The step response of (5.4): ṙ(t) = K τ (1 − e^{−t/T}) at every sample, r̈ from (5.15)
    /// equals the derivative of the response, and the gains (5.5) match Table 5.2.
    fn first_order_response<T: RealField + Copy>(tolerance: f64) {
        let config = table_5_2::<T>();
        assert!((config.time_constant() - Vector3::repeat(c(0.3125))).amax() < c(1e-6));
        assert!((config.gain() - Vector3::new(c(1.0 / 24.0), c(1.0 / 24.0), c(0.125))).amax() < c(1e-6));
        let mut admittance = Admittance::try_new(config).unwrap();
        let force = Vector3::new(c(12.0), c(-6.0), c(2.0));
        let dt: T = c(1e-3);
        for k in 1..=2000 {
            let before = admittance.velocity();
            let out = admittance.step(&force, &Vector3::zeros(), dt).unwrap();
            let t: T = dt * c(f64::from(k));
            for i in 0..3 {
                let gain = T::one() / config.damping[i];
                let tau = config.mass[i] / config.damping[i];
                let exact = gain * force[i] * (T::one() - (-t / tau).exp());
                assert!((out.velocity[i] - exact).abs() < c(tolerance), "k = {k}, axis {i}");
                let expected_acceleration = (force[i] - config.damping[i] * before[i]) / config.mass[i];
                assert!((out.acceleration[i] - expected_acceleration).abs() < c(tolerance));
            }
        }
        // After 2 s ≈ 6.4 T the velocity is within 0.2 % of K τ.
        assert!((admittance.velocity().x - c(0.5)).abs() < c(1e-3));
    }

    #[test]
    fn step_response_is_the_first_order_low_pass_f64() {
        first_order_response::<f64>(1e-12);
    }

    #[test]
    fn step_response_is_the_first_order_low_pass_f32() {
        first_order_response::<f32>(2e-5);
    }

    #[test]
    fn force_limits_bound_the_velocity_and_locked_axes_stay_at_rest() {
        for free_axes in [[true, false, false], [false, true, true]] {
            let config =
                AdmittanceConfig { force_limit: Vector3::new(30.0, 30.0, 4.0), free_axes, ..table_5_2::<f64>() };
            let limit = config.velocity_limit();
            assert_eq!(limit, Vector3::new(1.25, 1.25, 0.5));
            let mut admittance = Admittance::try_new(config).unwrap();
            let mut peak = Vector3::<f64>::zeros();
            for k in 0..5000 {
                let sign = if (k / 1500) % 2 == 0 { 1.0 } else { -1.0 };
                let out = admittance
                    .step(&Vector3::new(500.0, -80.0, 9.0 * sign), &Vector3::new(0.0, 0.0, 1.0), 2e-3)
                    .unwrap();
                for i in 0..3 {
                    peak[i] = peak[i].max(out.velocity[i].abs());
                    if !free_axes[i] {
                        assert_eq!((out.velocity[i], out.acceleration[i], out.force[i]), (0.0, 0.0, 0.0));
                    } else {
                        assert!(out.saturated[i] && out.force[i].abs() == config.force_limit[i]);
                    }
                }
            }
            for i in 0..3 {
                assert!(peak[i] <= limit[i]);
                if free_axes[i] {
                    assert!(peak[i] > 0.99 * limit[i], "axis {i} reaches its limit: {}", peak[i]);
                }
            }
        }
    }

    #[test]
    fn gains_and_invalid_input() {
        let from = AdmittanceConfig::from_gains(
            Vector3::new(1.0 / 21.0, 1.0 / 21.0, 1.0 / 7.0),
            Vector3::repeat(1.0 / 7.0_f32),
            Vector3::repeat(1.0),
            [true; 3],
        )
        .unwrap();
        assert!((from.mass - Vector3::new(3.0, 3.0, 1.0)).amax() < 1e-5, "critical set of Sec. 5.1.4");
        assert_eq!(
            AdmittanceConfig::from_gains(
                Vector3::new(0.0, 1.0, 1.0),
                Vector3::repeat(1.0_f64),
                Vector3::repeat(1.0),
                [true; 3]
            ),
            None
        );
        let good = table_5_2::<f64>();
        assert_eq!(
            Admittance::try_new(AdmittanceConfig { mass: Vector3::new(1.0, 0.0, 1.0), ..good }),
            Err(PlatformError::InvalidParameter { name: "mass" })
        );
        assert_eq!(
            Admittance::try_new(AdmittanceConfig { damping: Vector3::new(1.0, f64::NAN, 1.0), ..good }),
            Err(PlatformError::InvalidParameter { name: "damping" })
        );
        assert_eq!(
            Admittance::try_new(AdmittanceConfig { force_limit: Vector3::new(1.0, -1.0, 1.0), ..good }),
            Err(PlatformError::InvalidParameter { name: "force_limit" })
        );
        let mut admittance = Admittance::try_new(good).unwrap();
        admittance.step(&Vector3::new(1.0, 0.0, 0.0), &Vector3::zeros(), 0.01).unwrap();
        let before = admittance;
        assert_eq!(
            admittance.step(&Vector3::new(f64::NAN, 0.0, 0.0), &Vector3::zeros(), 0.01),
            Err(PlatformError::NonFinite { input: "force" })
        );
        assert_eq!(
            admittance.step(&Vector3::zeros(), &Vector3::zeros(), 0.0),
            Err(PlatformError::InvalidParameter { name: "dt" })
        );
        assert_eq!(
            admittance.reset(&Vector3::new(0.0, f64::INFINITY, 0.0)),
            Err(PlatformError::NonFinite { input: "velocity" })
        );
        assert_eq!(admittance, before);
    }
}
