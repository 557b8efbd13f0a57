//! Smooth switching functions: the transition shaping of Sec. 4.4.

use nalgebra::RealField;

/// Activation `a = 1 − N_des(ϑ)` (4.65) of a unilateral constraint with the cubic transition
/// (4.68) and the boundary conditions of Table 4.4: `a = 1` for `ϑ ≤ ϑ₁` (`full`), `a = 0` for
/// `ϑ ≥ ϑ₂` (`start`) and `N_des = 3σ² − 2σ³`, `σ = (ϑ − ϑ₁)/(ϑ₂ − ϑ₁)` in between, so `a` is C¹
/// with zero slope at both ends and the largest slope `N'_max = 1.5/(ϑ₂ − ϑ₁)` (4.69) at the
/// middle of the interval.
///
/// `ϑ` is the task's distance-like variable (distance to a stop, manipulability). If
/// `start ≤ full` the transition degenerates to a step at `start` (no division by zero); a NaN
/// `ϑ` gives 0.
///
/// ```
/// use kernel::math::switching::transition_activation;
/// assert_eq!(transition_activation(0.5_f64, 0.0, 1.0), 0.5);
/// assert_eq!(transition_activation(-1.0_f64, 0.0, 1.0), 1.0);
/// assert_eq!(transition_activation(2.0_f64, 0.0, 1.0), 0.0);
/// ```
pub fn transition_activation<T: RealField + Copy>(theta: T, full: T, start: T) -> T {
    // Not "less than start" also catches a NaN ϑ.
    if theta.partial_cmp(&start) != Some(core::cmp::Ordering::Less) {
        return T::zero();
    }
    if theta <= full {
        return T::one();
    }
    let width = start - full;
    let sigma = (theta - full) / width;
    let three: T = nalgebra::convert(3.0);
    let two: T = nalgebra::convert(2.0);
    T::one() - sigma * sigma * (three - two * sigma)
}

/// The cubic (4.68) weight of a transition's `progress ∈ [0, 1]`: 0 at the start, 1 at the end,
/// zero slope at both ends. Non-finite progress gives 0.
pub fn transition_weight<T: RealField + Copy>(progress: T) -> T {
    if progress.is_finite() {
        T::one() - transition_activation(progress, T::zero(), T::one())
    } else {
        T::zero()
    }
}

/// The transition band `[ϑ₁, ϑ₂]` of (4.68) for the largest admissible slope `N'_max` (4.69):
/// the conditions of Table 4.4 fix the width `ϑ₂ − ϑ₁ = 3 / (2 N'_max)`. Returns `ϑ₁` for the
/// given `ϑ₂` (Table 4.5: `ϑ₂ = 0.13 m`, `N'_max = 18.75 1/m` gives `ϑ₁ = 0.05 m`), or `None`
/// for a non-positive or non-finite slope.
///
/// ```
/// use kernel::math::switching::band_start_for_max_slope;
/// let full = band_start_for_max_slope(0.23_f64, 30.0).unwrap();
/// assert!((full - 0.18).abs() < 1e-15); // Fig. 4.11: m0 = 0.23, N'max = 30
/// ```
pub fn band_start_for_max_slope<T: RealField + Copy>(start: T, max_slope: T) -> Option<T> {
    if !(max_slope.is_finite() && start.is_finite()) || max_slope <= T::zero() {
        return None;
    }
    Some(start - nalgebra::convert::<f64, T>(1.5) / max_slope)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_4_4_conditions_hold() {
        let (full, start) = (0.05_f64, 0.13);
        let h = 1e-7;
        let slope = |t: f64| {
            -(transition_activation(t + h, full, start) - transition_activation(t - h, full, start)) / (2.0 * h)
        };
        assert_eq!(transition_activation(full, full, start), 1.0);
        assert_eq!(transition_activation(start, full, start), 0.0);
        // N'_des = 6σ(1 − σ)/Δ: zero at both ends of the band (C¹ junctions), 1.5/Δ mid-band.
        let width = start - full;
        for sigma in [1e-4, 0.1, 0.25, 0.5, 0.75, 0.9, 1.0 - 1e-4] {
            let analytic = 6.0 * sigma * (1.0 - sigma) / width;
            assert!((slope(full + sigma * width) - analytic).abs() < 1e-5, "σ = {sigma}");
        }
        // Largest slope at the middle: N'max = 1.5 / 0.08 = 18.75 (Table 4.5 prints 18.8).
        assert!((slope(0.09) - 18.75).abs() < 1e-6);
        assert!((band_start_for_max_slope(start, 18.75).unwrap_or(f64::NAN) - full).abs() < 1e-15);
        assert_eq!(band_start_for_max_slope(start, 0.0), None);
        assert_eq!(transition_activation(f64::NAN, full, start), 0.0);
    }
}
