//! Guarded scalar operations: the control path divides only by checked denominators.

use nalgebra::{RealField, SMatrix};

/// `numerator / denominator` if `|denominator| > threshold`, otherwise `None`.
///
/// Used wherever a division could produce an infinite or NaN value; the caller decides the
/// defined fallback.
///
/// ```
/// use kernel::math::guarded_divide;
/// assert_eq!(guarded_divide(1.0_f64, 4.0, 1e-12), Some(0.25));
/// assert_eq!(guarded_divide(1.0_f64, 0.0, 1e-12), None);
/// ```
#[inline]
pub fn guarded_divide<T: RealField + Copy>(numerator: T, denominator: T, threshold: T) -> Option<T> {
    if denominator.abs() > threshold {
        Some(numerator / denominator)
    } else {
        None
    }
}

/// `true` if every entry of `m` is finite (no NaN, no infinity): one pass over the contiguous
/// storage (`as_slice`), without nalgebra's strided element iterator.
///
/// ```
/// use kernel::math::all_finite;
/// use nalgebra::Vector2;
/// assert!(all_finite(&Vector2::new(1.0_f64, 2.0)));
/// assert!(!all_finite(&Vector2::new(1.0_f64, f64::NAN)));
/// ```
#[inline]
pub fn all_finite<T: RealField + Copy, const R: usize, const C: usize>(m: &SMatrix<T, R, C>) -> bool {
    m.as_slice().iter().all(|x| x.is_finite())
}
