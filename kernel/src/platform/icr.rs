//! The instantaneous centre of rotation (ICR) of the platform and its repulsion from the wheels'
//! steering axes, (3.25)–(3.36) and Fig. 3.8–3.9.
//!
//! The platform of Sec. 3.2 stands on [`LEGS`] steerable wheels; wheel `i` sits at
//! `p_i = λ_i l_i` in the platform frame, `l_i = (cos ψ_i, sin ψ_i)` the fixed leg direction and
//! `λ_i` the leg length. Every wheel must point perpendicular to the line from the ICR to its
//! contact point. When the ICR passes close to a wheel, that line turns quickly and the
//! steering rate explodes ("Crossing a wheel contact point would require an infinite steering
//! velocity"). The ICR is therefore kept away from the wheels by repulsive potentials.
//!
//! # ICR (3.25)–(3.27)
//! With the body-frame twist `(ẋ, ẏ, θ̇)` ([`BaseTwist`]):
//! `v = √(ẋ² + ẏ²)` (3.26), `γ = atan2(sgn(θ̇) ẋ, −sgn(θ̇) ẏ)` (3.27) and
//! `p_icr = (v/|θ̇|) (cos γ, sin γ)` (3.25), which equals `(−ẏ, ẋ)/θ̇`. For `θ̇ → 0` the ICR
//! moves to infinity (pure translation): below `min_yaw_rate` it is reported as `None`. Here
//! `sgn(0) = +1`, so `γ` is defined for every twist.
//!
//! # Controllability (3.28)–(3.29)
//! `ṗ_icr = J_sap (γ̇, θ̈)ᵀ + (cos γ, sin γ)ᵀ v̇/|θ̇|` with
//! `J_sap = [−(v/|θ̇|) sin γ, −sgn(θ̇)(v/θ̇²) cos γ; (v/|θ̇|) cos γ, −sgn(θ̇)(v/θ̇²) sin γ]`,
//! `det J_sap = v²/θ̇³`. With `r = v/|θ̇| = ‖p_icr‖`, `e_r = (cos γ, sin γ)` (radial) and
//! `e_t = (−sin γ, cos γ)` (tangential) the inverse is `γ̇ = e_tᵀ ṗ / r`, `θ̈ = −θ̇ e_rᵀ ṗ / r`:
//! the only singular case is the ICR at the platform centre (`r → 0`), where no repulsion is
//! needed (the fields never reach the centre).
//!
//! # Repulsion (3.30)–(3.36)
//! The nearest wheel (3.30), `d_sap = ‖p_icr − p_wheel‖`, repels the ICR with the force of a
//! potential analogous to (3.8):
//! `V = F_max/(3 d₀²) (d₀ − d)³`, `F_sap = F_max/d₀² (d − d₀)²` for `d < d₀`, zero beyond (C²
//! potential, continuous force). The force becomes an ICR velocity through the unit
//! `1 m/(N s)`: `ṗ_icr,sap = η F_sap` with `η = (p_icr − p_wheel)/d_sap` (3.31). With `v̇ = 0`,
//! `(γ̇_sap, θ̈_sap) = J_sap⁻¹ η F_sap` (3.32), and the translational accelerations that turn the
//! velocity at constant speed are `(ẍ, ÿ)_sap = γ̇_sap (−ẏ, ẋ)` (3.36), from (3.33)–(3.35).
//!
//! # Field extension (Fig. 3.9)
//! "In case of leg motions, it is useful to restrict the potential field extension depending on
//! the position of the wheel in order to avoid overlaps": `d₀(λ) = min(d₀,max, κ λ)` with
//! `0 < κ < √2/2`, so a field never reaches the platform centre (where the ICR of a pure
//! rotation sits) and never overlaps the field of a neighbouring wheel 90° away (distance
//! `√2 λ`). `d₀,max` and `κ` are not given by the thesis.

use nalgebra::{Matrix2, RealField, Vector2, Vector3};

use super::{PlatformError, LEGS};
use crate::math::sqrt;
use crate::math::switching::transition_activation;

/// The platform twist in its own (body) frame: `(ẋ, ẏ, θ̇)` of Fig. 3.7.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BaseTwist<T> {
    /// Velocity along the platform's x axis (m/s).
    pub forward: T,
    /// Velocity along the platform's y axis (m/s).
    pub lateral: T,
    /// Yaw rate `θ̇` (rad/s).
    pub yaw_rate: T,
}

impl<T: RealField + Copy> BaseTwist<T> {
    /// The body twist of the world-frame velocity `ṙ = (ẋ, ẏ, θ̇)` at heading `θ` (rad):
    /// `(ẋ_b, ẏ_b) = R(θ)ᵀ (ẋ, ẏ)`.
    pub fn from_world(velocity: &Vector3<T>, heading: T) -> Self {
        let (s, c) = heading.sin_cos();
        Self {
            forward: c * velocity.x + s * velocity.y,
            lateral: -s * velocity.x + c * velocity.y,
            yaw_rate: velocity.z,
        }
    }

    fn is_finite(&self) -> bool {
        self.forward.is_finite() && self.lateral.is_finite() && self.yaw_rate.is_finite()
    }
}

/// `R(θ) a`: a body-frame planar vector in world axes.
pub fn to_world<T: RealField + Copy>(body: &Vector2<T>, heading: T) -> Vector2<T> {
    let (s, c) = heading.sin_cos();
    Vector2::new(c * body.x - s * body.y, s * body.x + c * body.y)
}

/// The ICR of a twist, (3.25)–(3.27).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Icr<T> {
    /// Translational speed `v` (3.26), m/s.
    pub speed: T,
    /// Direction `γ` of the ICR seen from the platform centre (3.27), rad; `sgn(0) = +1`.
    pub direction: T,
    /// `p_icr` (3.25) in the platform frame (m); `None` if `|θ̇| ≤ min_yaw_rate` (at infinity).
    pub position: Option<Vector2<T>>,
}

/// The ICR of `twist` (3.25)–(3.27); `None` position for `|θ̇| ≤ min_yaw_rate` (rad/s).
///
/// ```
/// use kernel::platform::icr::{instantaneous_center, BaseTwist};
/// // Driving forward at 0.5 m/s while turning left at 1 rad/s: ICR 0.5 m to the left.
/// let icr = instantaneous_center(&BaseTwist { forward: 0.5_f64, lateral: 0.0, yaw_rate: 1.0 }, 1e-6);
/// let p = icr.position.unwrap();
/// assert!((p.x).abs() < 1e-12 && (p.y - 0.5).abs() < 1e-12);
/// assert!((icr.direction - core::f64::consts::FRAC_PI_2).abs() < 1e-12);
/// ```
pub fn instantaneous_center<T: RealField + Copy>(twist: &BaseTwist<T>, min_yaw_rate: T) -> Icr<T> {
    let (u, w, omega) = (twist.forward, twist.lateral, twist.yaw_rate);
    let speed = u.hypot(w);
    let sign = if omega >= T::zero() { T::one() } else { -T::one() };
    let direction = (sign * u).atan2(-sign * w);
    let position = (omega.abs() > min_yaw_rate).then(|| Vector2::new(-w, u) / omega);
    Icr { speed, direction, position }
}

/// The Jacobian `J_sap` (3.28) mapping `(γ̇, θ̈)` to the ICR velocity at constant speed; `None`
/// for `|θ̇| ≤ min_yaw_rate`. Its determinant is `v²/θ̇³` (3.29).
///
/// ```
/// use kernel::platform::icr::{sap_jacobian, BaseTwist};
/// let twist = BaseTwist { forward: 0.6_f64, lateral: -0.8, yaw_rate: -0.5 };
/// let j = sap_jacobian(&twist, 1e-6).unwrap();
/// assert!((j.determinant() - 1.0 / (-0.5_f64).powi(3)).abs() < 1e-12); // v = 1 m/s
/// ```
pub fn sap_jacobian<T: RealField + Copy>(twist: &BaseTwist<T>, min_yaw_rate: T) -> Option<Matrix2<T>> {
    let icr = instantaneous_center(twist, min_yaw_rate);
    icr.position?;
    let omega = twist.yaw_rate;
    let sign = omega.signum();
    let radius = icr.speed / omega.abs();
    let radial = icr.speed / (omega * omega);
    let (s, c) = icr.direction.sin_cos();
    Some(Matrix2::new(-radius * s, -sign * radial * c, radius * c, -sign * radial * s))
}

/// Parameters of the ICR repulsion. Validate with [`IcrRepulsion::try_new`]. The thesis gives
/// none of the values (THESIS-NUMBERS §6.2: "silent").
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct IcrRepulsionConfig<T> {
    /// Leg directions `ψ_i` (rad from the platform's x axis), wheel `i` at `λ_i (cos ψ_i, sin ψ_i)`.
    pub leg_directions: [T; LEGS],
    /// Largest field extension `d₀,max` (m), `> 0`.
    pub max_extension: T,
    /// Ratio `κ` of the leg-length limit `d₀ ≤ κ λ_i` (Fig. 3.9), `0 < κ < √2/2`.
    pub extension_ratio: T,
    /// `F_max` (N) of the potential analogous to (3.8): the force, and through `1 m/(N s)` the
    /// ICR speed (m/s), at contact (`d_sap = 0`), `> 0`.
    pub max_force: T,
    /// Yaw rate (rad/s) below which the ICR counts as at infinity, `> 0`; the repulsion fades in
    /// smoothly between this rate and twice it.
    pub min_yaw_rate: T,
}

/// The wheel nearest to the ICR.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NearestWheel<T> {
    /// Wheel index `0..LEGS`.
    pub index: usize,
    /// `d_sap = ‖p_icr − p_wheel‖` (3.30), m.
    pub distance: T,
    /// The wheel's field extension `d₀(λ)` (Fig. 3.9), m.
    pub extension: T,
    /// `η = (p_icr − p_wheel)/d_sap` (3.31), unit; the outward leg direction if `d_sap ≈ 0`.
    pub direction: Vector2<T>,
    /// The unit leg direction `l` of the wheel.
    pub leg_direction: Vector2<T>,
}

impl<T: RealField + Copy> NearestWheel<T> {
    /// `true` if the ICR is inside the wheel's field (`d_sap < d₀`).
    pub fn inside(&self) -> bool {
        self.distance < self.extension
    }
}

/// What the repulsion demands of the platform at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Repulsion<T> {
    /// The ICR of the twist.
    pub icr: Icr<T>,
    /// The nearest wheel; `None` if the ICR is at infinity.
    pub nearest: Option<NearestWheel<T>>,
    /// `F_sap(d_sap)` (N), faded in with the yaw rate; 0 outside every field.
    pub force: T,
    /// Potential of the field (J).
    pub potential: T,
    /// Required ICR velocity `ṗ_icr,sap = η F_sap · 1 m/(N s)` (3.31), platform frame (m/s).
    pub icr_velocity: Vector2<T>,
    /// `γ̇_sap` (3.32), rad/s.
    pub direction_rate: T,
    /// `θ̈_sap` (3.32), rad/s².
    pub yaw_acceleration: T,
    /// `(ẍ, ÿ)_sap = γ̇_sap (−ẏ, ẋ)` (3.36), platform frame (m/s²).
    pub body_acceleration: Vector2<T>,
}

impl<T: RealField + Copy> Repulsion<T> {
    fn idle(icr: Icr<T>, nearest: Option<NearestWheel<T>>) -> Self {
        Self {
            icr,
            nearest,
            force: T::zero(),
            potential: T::zero(),
            icr_velocity: Vector2::zeros(),
            direction_rate: T::zero(),
            yaw_acceleration: T::zero(),
            body_acceleration: Vector2::zeros(),
        }
    }
}

/// The validated ICR repulsion (3.30)–(3.36).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IcrRepulsion<T> {
    config: IcrRepulsionConfig<T>,
    leg_units: [Vector2<T>; LEGS],
}

/// Distances below this (m) count as zero: `η` falls back to the leg direction, `r → 0` gives no
/// conversion (3.32).
fn tiny<T: RealField + Copy>() -> T {
    nalgebra::convert(1e-6)
}

impl<T: RealField + Copy> IcrRepulsion<T> {
    /// Validates `config` (see the field docs). Errors: [`PlatformError::InvalidParameter`].
    pub fn try_new(config: IcrRepulsionConfig<T>) -> Result<Self, PlatformError> {
        let positive = |x: T| x.is_finite() && x > T::zero();
        if !config.leg_directions.iter().all(|a| a.is_finite()) {
            return Err(PlatformError::InvalidParameter { name: "leg_directions" });
        }
        if !positive(config.max_extension) {
            return Err(PlatformError::InvalidParameter { name: "max_extension" });
        }
        let half_sqrt2: T = nalgebra::convert(core::f64::consts::FRAC_1_SQRT_2);
        if !(positive(config.extension_ratio) && config.extension_ratio < half_sqrt2) {
            return Err(PlatformError::InvalidParameter { name: "extension_ratio" });
        }
        if !positive(config.max_force) {
            return Err(PlatformError::InvalidParameter { name: "max_force" });
        }
        if !positive(config.min_yaw_rate) {
            return Err(PlatformError::InvalidParameter { name: "min_yaw_rate" });
        }
        let leg_units = config.leg_directions.map(|a| {
            let (s, c) = a.sin_cos();
            Vector2::new(c, s)
        });
        Ok(Self { config, leg_units })
    }

    /// The validated parameters.
    pub fn config(&self) -> &IcrRepulsionConfig<T> {
        &self.config
    }

    /// Unit leg directions `l_i`.
    pub fn leg_directions(&self) -> &[Vector2<T>; LEGS] {
        &self.leg_units
    }

    /// Wheel contact points `p_i = λ_i l_i` in the platform frame (m).
    pub fn wheel_positions(&self, leg_lengths: &[T; LEGS]) -> [Vector2<T>; LEGS] {
        let mut out = [Vector2::zeros(); LEGS];
        for ((p, l), lambda) in out.iter_mut().zip(self.leg_units.iter()).zip(leg_lengths.iter()) {
            *p = *l * *lambda;
        }
        out
    }

    /// Field extension `d₀(λ) = min(d₀,max, κ λ)` (Fig. 3.9), m; 0 for `λ ≤ 0`.
    pub fn extension(&self, leg_length: T) -> T {
        (self.config.extension_ratio * leg_length).min(self.config.max_extension).max(T::zero())
    }

    /// Force `F_sap(d) = F_max/d₀² (d − d₀)²` for `0 ≤ d < d₀` (analogous to (3.10)) and its
    /// potential `F_max/(3 d₀²) (d₀ − d)³` (analogous to (3.8)); both zero for `d ≥ d₀` or
    /// `d₀ ≤ 0`.
    pub fn field(&self, distance: T, extension: T) -> (T, T) {
        // Not "less than" also catches a NaN distance.
        if distance.partial_cmp(&extension) != Some(core::cmp::Ordering::Less) || extension <= T::zero() {
            return (T::zero(), T::zero());
        }
        let gap = extension - distance.max(T::zero());
        let scale = self.config.max_force / (extension * extension);
        let three: T = nalgebra::convert(3.0);
        (scale * gap * gap, scale * gap * gap * gap / three)
    }

    /// The repulsion (3.30)–(3.36) for the body twist `twist` and leg lengths `leg_lengths` (m).
    ///
    /// Never divides by an unchecked value: no ICR (`|θ̇|` small) or no field reached gives zero
    /// accelerations; the ICR exactly on a wheel repels along the leg; the ICR at the centre
    /// (`r → 0`, not reachable by a field) gives zero accelerations. Errors: non-finite input.
    ///
    /// ```
    /// use kernel::platform::icr::{BaseTwist, IcrRepulsion, IcrRepulsionConfig};
    /// use core::f64::consts::FRAC_PI_4;
    /// let repulsion = IcrRepulsion::try_new(IcrRepulsionConfig { leg_directions: [FRAC_PI_4, 3.0 * FRAC_PI_4, -3.0 * FRAC_PI_4, -FRAC_PI_4],
    ///     max_extension: 0.2, extension_ratio: 0.4, max_force: 2.0, min_yaw_rate: 1e-3 }).unwrap();
    /// // ICR on the diagonal of wheel 1 (at 0.53 m), 0.1 m closer to the centre: pushed
    /// // inwards at F_max (0.1/0.2)² = 0.5 m/s, which a faster turn does (θ̈ = −θ̇ e_rᵀṗ/r > 0).
    /// let r = 0.43_f64;
    /// let twist = BaseTwist { forward: r * FRAC_PI_4.sin(), lateral: -r * FRAC_PI_4.cos(), yaw_rate: 1.0 };
    /// let out = repulsion.repulsion(&twist, &[0.53; 4]).unwrap();
    /// assert_eq!(out.nearest.unwrap().index, 0);
    /// assert!((out.force - 0.5).abs() < 1e-9);
    /// assert!((out.yaw_acceleration - 0.5 / r).abs() < 1e-9);
    /// ```
    pub fn repulsion(&self, twist: &BaseTwist<T>, leg_lengths: &[T; LEGS]) -> Result<Repulsion<T>, PlatformError> {
        if !twist.is_finite() {
            return Err(PlatformError::NonFinite { input: "twist" });
        }
        if !leg_lengths.iter().all(|l| l.is_finite()) {
            return Err(PlatformError::NonFinite { input: "leg_lengths" });
        }
        let icr = instantaneous_center(twist, self.config.min_yaw_rate);
        let Some(p) = icr.position else { return Ok(Repulsion::idle(icr, None)) };
        let wheels = self.wheel_positions(leg_lengths);
        let mut nearest: Option<NearestWheel<T>> = None;
        for (index, ((wheel, leg), lambda)) in
            wheels.iter().zip(self.leg_units.iter()).zip(leg_lengths.iter()).enumerate()
        {
            let offset = p - wheel;
            let distance = sqrt(offset.norm_squared());
            if nearest.is_some_and(|n| n.distance <= distance) {
                continue;
            }
            let direction = if distance > tiny() { offset / distance } else { *leg };
            nearest = Some(NearestWheel {
                index,
                distance,
                extension: self.extension(*lambda),
                direction,
                leg_direction: *leg,
            });
        }
        let Some(wheel) = nearest else { return Ok(Repulsion::idle(icr, None)) };
        let (force, potential) = self.field(wheel.distance, wheel.extension);
        let min_rate = self.config.min_yaw_rate;
        let fade = T::one() - transition_activation(twist.yaw_rate.abs(), min_rate, min_rate + min_rate);
        let (force, potential) = (force * fade, potential * fade);
        let radius = sqrt(p.norm_squared());
        if force <= T::zero() || radius <= tiny() {
            return Ok(Repulsion { force, potential, ..Repulsion::idle(icr, nearest) });
        }
        // (3.31) with the unit 1 m/(N s).
        let icr_velocity = wheel.direction * force;
        // (3.32) by the closed-form inverse of J_sap: γ̇ = e_tᵀ ṗ / r, θ̈ = −θ̇ e_rᵀ ṗ / r.
        let radial = p / radius;
        let tangential = Vector2::new(-radial.y, radial.x);
        let direction_rate = tangential.dot(&icr_velocity) / radius;
        let yaw_acceleration = -twist.yaw_rate * radial.dot(&icr_velocity) / radius;
        // (3.36): turn the velocity at constant speed.
        let body_acceleration = Vector2::new(-twist.lateral, twist.forward) * direction_rate;
        Ok(Repulsion {
            icr,
            nearest,
            force,
            potential,
            icr_velocity,
            direction_rate,
            yaw_acceleration,
            body_acceleration,
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use core::f64::consts::FRAC_PI_4;

    fn c<T: RealField + Copy>(x: f64) -> T {
        nalgebra::convert(x)
    }

    fn config<T: RealField + Copy>() -> IcrRepulsionConfig<T> {
        IcrRepulsionConfig {
            leg_directions: [c(FRAC_PI_4), c(3.0 * FRAC_PI_4), c(-3.0 * FRAC_PI_4), c(-FRAC_PI_4)],
            max_extension: c(0.2),
            extension_ratio: c(0.4),
            max_force: c(2.0),
            min_yaw_rate: c(1e-3),
        }
    }

    /// Twist whose ICR is `p` for yaw rate `omega`: `(ẋ, ẏ) = θ̇ (p_y, −p_x)`.
    fn twist_for<T: RealField + Copy>(p: Vector2<T>, omega: T) -> BaseTwist<T> {
        BaseTwist { forward: omega * p.y, lateral: -omega * p.x, yaw_rate: omega }
    }

    /// (3.25)/(3.27) agree with the direct form, J_sap (3.28) with finite differences of
    /// p(γ, θ̇, v) = (v/|θ̇|)(cos γ, sin γ), and det J_sap = v²/θ̇³ (3.29).
    fn icr_and_jacobian<T: RealField + Copy>(tolerance: f64) {
        for (u, w, omega) in [(0.4, -0.3, 1.2), (-0.7, 0.2, -0.5), (0.0, 0.9, 2.1), (1.0, 0.0, -0.05)] {
            let twist = BaseTwist { forward: c::<T>(u), lateral: c(w), yaw_rate: c(omega) };
            let icr = instantaneous_center(&twist, c(1e-6));
            let p = icr.position.unwrap();
            let thesis = Vector2::new(icr.direction.cos(), icr.direction.sin()) * (icr.speed / twist.yaw_rate.abs());
            assert!((p - thesis).amax() < c(tolerance), "(3.25) vs (−ẏ, ẋ)/θ̇");
            let j = sap_jacobian(&twist, c(1e-6)).unwrap();
            let position = |gamma: f64, rate: f64, v: f64| Vector2::new(gamma.cos(), gamma.sin()) * (v / rate.abs());
            let (g, v): (f64, f64) =
                (nalgebra::try_convert(icr.direction).unwrap(), nalgebra::try_convert(icr.speed).unwrap());
            let h = 1e-6;
            let dg = (position(g + h, omega, v) - position(g - h, omega, v)) / (2.0 * h);
            let dw = (position(g, omega + h, v) - position(g, omega - h, v)) / (2.0 * h);
            let fd = Matrix2::new(dg.x, dw.x, dg.y, dw.y);
            let j64: Matrix2<f64> = j.map(|x| nalgebra::try_convert(x).unwrap());
            assert!((j64 - fd).amax() < tolerance.max(1e-6) * (1.0 + fd.amax()), "{j64} vs {fd}");
            let det: f64 = nalgebra::try_convert(j.determinant()).unwrap();
            assert!((det - v * v / omega.powi(3)).abs() < tolerance * (1.0 + det.abs()));
        }
    }

    #[test]
    fn icr_and_sap_jacobian_f64() {
        icr_and_jacobian::<f64>(1e-9);
    }

    #[test]
    fn icr_and_sap_jacobian_f32() {
        icr_and_jacobian::<f32>(2e-4);
    }

    /// Applying the demanded accelerations for a short time moves the ICR with η F_sap (3.31)
    /// and keeps the speed constant (3.35); (3.33) returns γ̇_sap.
    fn repulsion_realises_the_icr_velocity<T: RealField + Copy>(tolerance: f64) {
        let repulsion = IcrRepulsion::try_new(config::<T>()).unwrap();
        let legs = [c::<T>(0.53); LEGS];
        let wheels = repulsion.wheel_positions(&legs);
        let mut checked = 0;
        for (k, offset) in [
            (0, Vector2::new(0.05, 0.03)),
            (1, Vector2::new(-0.02, -0.1)),
            (2, Vector2::new(0.12, 0.0)),
            (3, Vector2::new(-0.01, 0.015)),
        ] {
            for omega in [0.8, -1.3] {
                let p = wheels[k] + offset.map(c::<T>);
                let twist = twist_for(p, c(omega));
                let out = repulsion.repulsion(&twist, &legs).unwrap();
                let wheel = out.nearest.unwrap();
                assert_eq!(wheel.index, k);
                assert!(out.force > T::zero());
                let dt: T = c(1e-6);
                let moved = BaseTwist {
                    forward: twist.forward + out.body_acceleration.x * dt,
                    lateral: twist.lateral + out.body_acceleration.y * dt,
                    yaw_rate: twist.yaw_rate + out.yaw_acceleration * dt,
                };
                let p_next = instantaneous_center(&moved, c(1e-6)).position.unwrap();
                let velocity = (p_next - p) / dt;
                let scale = T::one() + out.icr_velocity.norm();
                assert!(
                    (velocity - out.icr_velocity).amax() < c::<T>(tolerance) * scale,
                    "{velocity} vs {}",
                    out.icr_velocity
                );
                let speed_rate = (moved.forward.hypot(moved.lateral) - twist.forward.hypot(twist.lateral)) / dt;
                assert!(speed_rate.abs() < c::<T>(tolerance) * scale, "v̇ = {speed_rate}");
                // (3.33) with the demanded body accelerations.
                let (u, w) = (twist.forward, twist.lateral);
                let (a, b) = (out.body_acceleration.x, out.body_acceleration.y);
                let gamma_rate = (u * b - w * a) / (u * u + w * w);
                assert!((gamma_rate - out.direction_rate).abs() < c::<T>(tolerance) * scale);
                // Repelled: η points away from the wheel.
                assert!(((p - wheels[k]).dot(&out.icr_velocity)) > T::zero());
                checked += 1;
            }
        }
        assert_eq!(checked, 8);
    }

    #[test]
    fn repulsion_realises_the_icr_velocity_f64() {
        repulsion_realises_the_icr_velocity::<f64>(1e-5);
    }

    #[test]
    fn repulsion_realises_the_icr_velocity_f32() {
        // f32: the difference quotient over 1e-6 s is meaningless; use 1e-3 s (O(dt) error).
        let repulsion = IcrRepulsion::try_new(config::<f32>()).unwrap();
        let legs = [0.53_f32; LEGS];
        let p = repulsion.wheel_positions(&legs)[1] + Vector2::new(0.04, -0.06);
        let twist = twist_for(p, 1.1);
        let out = repulsion.repulsion(&twist, &legs).unwrap();
        let dt = 1e-3_f32;
        let moved = BaseTwist {
            forward: twist.forward + out.body_acceleration.x * dt,
            lateral: twist.lateral + out.body_acceleration.y * dt,
            yaw_rate: twist.yaw_rate + out.yaw_acceleration * dt,
        };
        let p_next = instantaneous_center(&moved, 1e-6).position.unwrap();
        assert!(((p_next - p) / dt - out.icr_velocity).amax() < 2e-2 * (1.0 + out.icr_velocity.norm()));
    }

    #[test]
    fn field_is_the_potential_of_3_8_and_limited_by_the_leg_length() {
        let repulsion = IcrRepulsion::try_new(config::<f64>()).unwrap();
        assert_eq!(repulsion.extension(0.53), 0.2);
        assert!((repulsion.extension(0.45) - 0.18).abs() < 1e-12, "Fig. 3.9: κ λ bites for short legs");
        let d0 = 0.2;
        assert_eq!(repulsion.field(0.0, d0).0, 2.0, "F_max at contact");
        assert_eq!(repulsion.field(0.2, d0), (0.0, 0.0));
        for d in [0.01, 0.07, 0.15, 0.199] {
            let h = 1e-7;
            let dv = (repulsion.field(d + h, d0).1 - repulsion.field(d - h, d0).1) / (2.0 * h);
            assert!((repulsion.field(d, d0).0 + dv).abs() < 1e-7, "F = −∂V/∂d");
        }
    }

    #[test]
    fn singular_twists_give_finite_results() {
        let repulsion = IcrRepulsion::try_new(config::<f64>()).unwrap();
        let legs = [0.53; LEGS];
        let wheel = repulsion.wheel_positions(&legs)[2];
        let twists = [
            BaseTwist { forward: 0.0, lateral: 0.0, yaw_rate: 0.0 }, // standstill
            BaseTwist { forward: 0.0, lateral: 0.0, yaw_rate: 2.1 }, // pure rotation: ICR at the centre
            BaseTwist { forward: 1.0, lateral: 0.3, yaw_rate: 0.0 }, // pure translation: ICR at infinity
            BaseTwist { forward: 1.0, lateral: 0.3, yaw_rate: -1e-300 }, // θ̇ → 0
            twist_for(wheel, 1.0),                                   // ICR exactly on a wheel
            twist_for(wheel, 1.5e-3),                                // … while fading in
            BaseTwist { forward: 1e-300, lateral: 0.0, yaw_rate: 1e-300 },
        ];
        for twist in twists {
            let out = repulsion.repulsion(&twist, &legs).unwrap();
            let values =
                [out.force, out.potential, out.direction_rate, out.yaw_acceleration, out.icr.speed, out.icr.direction];
            assert!(values.iter().all(|x| x.is_finite()), "{twist:?}: {out:?}");
            assert!(out.body_acceleration.iter().chain(out.icr_velocity.iter()).all(|x| x.is_finite()));
            assert!(out
                .nearest
                .is_none_or(|n| n.direction.iter().all(|x| x.is_finite()) && (n.direction.norm() - 1.0).abs() < 1e-12));
        }
        let on_wheel = repulsion.repulsion(&twist_for(wheel, 1.0), &legs).unwrap();
        assert_eq!(on_wheel.force, 2.0);
        assert!(
            (on_wheel.icr_velocity - repulsion.leg_directions()[2] * 2.0).amax() < 1e-12,
            "pushed outwards along the leg"
        );
        assert_eq!(
            repulsion.repulsion(&BaseTwist { forward: 0.0, lateral: 0.0, yaw_rate: 2.1 }, &legs).unwrap().force,
            0.0
        );
        assert!(sap_jacobian(&BaseTwist { forward: 1.0, lateral: 0.0, yaw_rate: 0.0 }, 1e-6).is_none());
        assert!(repulsion.repulsion(&BaseTwist { forward: f64::NAN, lateral: 0.0, yaw_rate: 1.0 }, &legs).is_err());
        assert!(repulsion.repulsion(&twist_for(wheel, 1.0), &[0.5, f64::INFINITY, 0.5, 0.5]).is_err());
    }

    #[test]
    fn invalid_configurations_are_rejected() {
        let good = config::<f64>();
        let check = |cfg: IcrRepulsionConfig<f64>, name| {
            assert_eq!(IcrRepulsion::try_new(cfg).err(), Some(PlatformError::InvalidParameter { name }))
        };
        check(IcrRepulsionConfig { max_extension: 0.0, ..good }, "max_extension");
        check(IcrRepulsionConfig { extension_ratio: 0.75, ..good }, "extension_ratio");
        check(IcrRepulsionConfig { max_force: f64::NAN, ..good }, "max_force");
        check(IcrRepulsionConfig { min_yaw_rate: 0.0, ..good }, "min_yaw_rate");
        check(IcrRepulsionConfig { leg_directions: [0.0, f64::NAN, 0.0, 0.0], ..good }, "leg_directions");
        let twist = BaseTwist::from_world(&Vector3::new(1.0, 0.0, 0.5), core::f64::consts::FRAC_PI_2);
        assert!((twist.forward).abs() < 1e-15 && (twist.lateral + 1.0).abs() < 1e-15);
        assert!(
            (to_world(&Vector2::new(twist.forward, twist.lateral), core::f64::consts::FRAC_PI_2)
                - Vector2::new(1.0, 0.0))
            .amax()
                < 1e-15
        );
    }
}
