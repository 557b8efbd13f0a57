//! Symmetric eigendecomposition by the cyclic Jacobi method with a fixed sweep bound.
//!
//! Used by the damping design for the small (2×2 … 6×6) task-space matrices. Jacobi is chosen
//! over a QR-based solver because it is generic over any const size without extra trait bounds,
//! accurate for symmetric matrices (small relative errors in small eigenvalues), and its cost
//! is bounded by [`MAX_SWEEPS`] — a known worst case for the real-time step.

use nalgebra::{RealField, SMatrix, SVector};

/// Upper bound on Jacobi sweeps. Convergence is quadratic; matrices up to 6×6 converge to
/// machine precision in 6–8 sweeps.
pub const MAX_SWEEPS: usize = 16;

/// `A = V diag(λ) Vᵀ` for a symmetric `A` (both triangles are read: pass a symmetric matrix).
/// Returns `(λ, V)`, eigenvalues unsorted, `V` orthonormal.
/// Cost ≤ `MAX_SWEEPS · D²/2` plane rotations of O(D).
pub fn symmetric_eigen<T: RealField + Copy, const D: usize>(a: &SMatrix<T, D, D>) -> (SVector<T, D>, SMatrix<T, D, D>) {
    let mut a = *a;
    let mut v = SMatrix::<T, D, D>::identity();
    let tiny = T::default_epsilon() * T::default_epsilon();
    for _ in 0..MAX_SWEEPS {
        let off = off_diagonal_norm(&a);
        if off <= T::default_epsilon() * (a.norm() + tiny) {
            break;
        }
        for p in 0..D {
            for q in (p + 1)..D {
                let apq = at(&a, p, q);
                if apq.abs() <= tiny {
                    continue;
                }
                let tau = (at(&a, q, q) - at(&a, p, p)) / (apq + apq);
                let t = tau.signum() / (tau.abs() + (T::one() + tau * tau).sqrt());
                let t = if tau == T::zero() { T::one() } else { t };
                let c = T::one() / (T::one() + t * t).sqrt();
                let s = t * c;
                rotate_columns(&mut a, p, q, c, s);
                rotate_rows(&mut a, p, q, c, s);
                rotate_columns(&mut v, p, q, c, s);
            }
        }
    }
    (a.diagonal(), v)
}

fn off_diagonal_norm<T: RealField + Copy, const D: usize>(a: &SMatrix<T, D, D>) -> T {
    let mut sum = T::zero();
    for (index, x) in a.iter().enumerate() {
        if index % (D + 1) != 0 {
            sum += *x * *x;
        }
    }
    sum.sqrt()
}

#[inline]
fn at<T: RealField + Copy, const D: usize>(a: &SMatrix<T, D, D>, i: usize, j: usize) -> T {
    a.get((i, j)).copied().unwrap_or_else(T::zero)
}

/// Columns `p, q` ← `(c·col_p − s·col_q, s·col_p + c·col_q)`.
fn rotate_columns<T: RealField + Copy, const D: usize>(m: &mut SMatrix<T, D, D>, p: usize, q: usize, c: T, s: T) {
    for k in 0..D {
        let (xp, xq) = (at(m, k, p), at(m, k, q));
        if let Some(e) = m.get_mut((k, p)) {
            *e = c * xp - s * xq;
        }
        if let Some(e) = m.get_mut((k, q)) {
            *e = s * xp + c * xq;
        }
    }
}

/// Rows `p, q` ← `(c·row_p − s·row_q, s·row_p + c·row_q)`.
fn rotate_rows<T: RealField + Copy, const D: usize>(m: &mut SMatrix<T, D, D>, p: usize, q: usize, c: T, s: T) {
    for k in 0..D {
        let (xp, xq) = (at(m, p, k), at(m, q, k));
        if let Some(e) = m.get_mut((p, k)) {
            *e = c * xp - s * xq;
        }
        if let Some(e) = m.get_mut((q, k)) {
            *e = s * xp + c * xq;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix6;

    #[test]
    fn reconstructs_random_symmetric_matrices() {
        for seed in 1..50u64 {
            let b =
                Matrix6::<f64>::from_fn(|i, j| (((seed * 31 + i as u64 * 7 + j as u64 * 13) % 17) as f64 - 8.0) / 3.0);
            let a = b + b.transpose();
            let (lambda, v) = symmetric_eigen(&a);
            assert!((v.transpose() * v - Matrix6::identity()).amax() < 1e-13);
            assert!((v * Matrix6::from_diagonal(&lambda) * v.transpose() - a).amax() < 1e-12 * a.amax());
            let mut sorted = lambda;
            sorted.as_mut_slice().sort_by(f64::total_cmp);
            let mut reference = a.symmetric_eigenvalues();
            reference.as_mut_slice().sort_by(f64::total_cmp);
            assert!((sorted - reference).amax() < 1e-12 * a.amax());
        }
    }

    #[test]
    fn diagonal_and_repeated_eigenvalues() {
        let a = SMatrix::<f32, 3, 3>::from_diagonal(&SVector::from([2.0, 2.0, -1.0]));
        let (lambda, v) = symmetric_eigen(&a);
        assert_eq!(lambda, SVector::from([2.0, 2.0, -1.0]));
        assert_eq!(v, SMatrix::<f32, 3, 3>::identity());
    }
}
