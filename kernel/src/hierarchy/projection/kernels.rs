//! Dense kernels of the recursion over column-major `N × N` storage: mat-vecs that skip the zero
//! entries of the vector, the fused norms, the in-place rank-one update and `W⁻¹` from a
//! Cholesky factor.

use nalgebra::{RealField, SMatrix};

use crate::math::sqrt;

/// `‖A e_b‖` for every column `b` of the column-major `N × N` matrix `a`: the transmission
/// `‖A jᵀ‖ / ‖jᵀ‖` of every row `j = α e_bᵀ`.
pub(super) fn column_norms_of<T: RealField + Copy, const N: usize>(a: &[T]) -> [T; N] {
    let mut norms = [T::zero(); N];
    for (norm, column) in norms.iter_mut().zip(a.chunks_exact(N.max(1))) {
        *norm = sqrt(norm_squared(column));
    }
    norms
}

/// `xᵀ A x` for the column-major `N × N` matrix `a`: `A x` over the nonzero entries of `x`,
/// accumulated in registers as in [`mat_vec`] and never stored, then dotted with `x` (bit for
/// bit the sums of [`mat_vec`] and [`dot`]).
pub(super) fn quadratic_form<T: RealField + Copy, const N: usize>(a: &[T], x: &[T]) -> T {
    let mut sum = [T::zero(); N];
    for (column, &xc) in a.chunks_exact(N.max(1)).zip(x) {
        if xc != T::zero() {
            for (v, &aic) in sum.iter_mut().zip(column) {
                *v += aic * xc;
            }
        }
    }
    dot(x, &sum)
}

/// `(‖x‖², ‖A x‖²)` for the column-major `N × N` matrix `a` in one pass over the nonzero entries
/// of `x`, adding `x f` to `t` in the same pass: `A x` is accumulated in registers as in
/// [`mat_vec`] and never stored. The sums equal those of [`norm_squared`], [`mat_vec`] and the
/// plain `t + x f` bit for bit (the skipped terms are `±0`).
pub(super) fn projected_norm_squared_adding<T: RealField + Copy, const N: usize>(
    a: &[T],
    x: &[T],
    f: T,
    t: &mut [T],
) -> (T, T) {
    let mut sum = [T::zero(); N];
    let mut x_squared = T::zero();
    for ((column, &xc), tc) in a.chunks_exact(N.max(1)).zip(x).zip(t.iter_mut()) {
        if xc != T::zero() {
            x_squared += xc * xc;
            *tc += xc * f;
            for (v, &aic) in sum.iter_mut().zip(column) {
                *v += aic * xc;
            }
        }
    }
    (x_squared, norm_squared(&sum))
}

/// `Σ xᵢ yᵢ`.
pub(super) fn dot<T: RealField + Copy>(x: &[T], y: &[T]) -> T {
    x.iter().zip(y).fold(T::zero(), |acc, (&a, &b)| acc + a * b)
}

/// `Σ xᵢ²`.
pub(super) fn norm_squared<T: RealField + Copy>(x: &[T]) -> T {
    x.iter().fold(T::zero(), |acc, &v| acc + v * v)
}

/// `y = A x` for the column-major `N × N` matrix `a`, column by column, accumulated in
/// registers; zero entries of `x` are skipped (task rows are sparse, projected rows often too).
pub(super) fn mat_vec<T: RealField + Copy, const N: usize>(a: &[T], x: &[T], y: &mut [T]) {
    // Accumulated in a local array the optimiser keeps in registers.
    let mut sum = [T::zero(); N];
    for (column, &xc) in a.chunks_exact(N.max(1)).zip(x) {
        if xc != T::zero() {
            for (v, &aic) in sum.iter_mut().zip(column) {
                *v += aic * xc;
            }
        }
    }
    for (v, s) in y.iter_mut().zip(sum) {
        *v = s;
    }
}

/// `y = A x` as [`mat_vec`], returning `x · y` formed from the registers (bit for bit
/// [`dot`]`(x, y)`).
pub(super) fn mat_vec_dot<T: RealField + Copy, const N: usize>(a: &[T], x: &[T], y: &mut [T]) -> T {
    let mut sum = [T::zero(); N];
    for (column, &xc) in a.chunks_exact(N.max(1)).zip(x) {
        if xc != T::zero() {
            for (v, &aic) in sum.iter_mut().zip(column) {
                *v += aic * xc;
            }
        }
    }
    for (v, s) in y.iter_mut().zip(sum) {
        *v = s;
    }
    dot(x, &sum)
}

/// `A ← A − u (c w)ᵀ` in place on the column-major `N × N` matrix `a`.
pub(super) fn rank_one_update<T: RealField + Copy, const N: usize>(a: &mut [T], u: &[T], w: &[T], c: T) {
    for (column, &wc) in a.chunks_exact_mut(N.max(1)).zip(w) {
        let coefficient = wc * c;
        for (aic, &ui) in column.iter_mut().zip(u) {
            *aic -= ui * coefficient;
        }
    }
}

/// `(L Lᵀ)⁻¹ = L⁻ᵀ L⁻¹` from the column-major storage of the lower-triangular `L` (only its
/// lower triangle is read). The rows of `X = L⁻¹` by forward substitution,
/// `X_i = (e_iᵀ − Σ_{k<i} L_ik X_k) / L_ii`, kept as the columns `y_i = X_iᵀ` of `Y = Xᵀ`;
/// then column `b` of `XᵀX` is `Σ_{k ≥ b} X_kb y_k`. Every inner loop runs over a whole column
/// (length `N`, accumulated in registers): about `N³/2` multiply-adds, most of them on zeros
/// of the triangles, but without the loop overhead of triangular index ranges.
pub(super) fn cholesky_inverse<T: RealField + Copy, const N: usize>(l: &[T]) -> SMatrix<T, N, N> {
    let n = N.max(1);
    let mut y = SMatrix::<T, N, N>::zeros();
    for i in 0..N {
        let Some(&diagonal) = l.get(i * n + i) else {
            break;
        };
        // Σ_{k<i} L_ik y_k accumulated with `+` (the same roundings as `−` from 0, by symmetry);
        // y_k[i] = 0 for k < i, so entry i is `1 − (±0)`.
        let mut sum = [T::zero(); N];
        for (yk, lk) in y.as_slice().chunks_exact(n).zip(l.chunks_exact(n)).take(i) {
            let lik = lk.get(i).copied().unwrap_or_else(T::zero);
            if lik != T::zero() {
                for (v, &ykj) in sum.iter_mut().zip(yk) {
                    *v += lik * ykj;
                }
            }
        }
        let Some(column) = y.as_mut_slice().chunks_exact_mut(n).nth(i) else {
            break;
        };
        for (j, (yi, v)) in column.iter_mut().zip(sum).enumerate() {
            let unit = if j == i { T::one() } else { T::zero() };
            *yi = (unit - v) / diagonal;
        }
    }
    let mut inverse = SMatrix::<T, N, N>::zeros();
    for (b, out) in inverse.as_mut_slice().chunks_exact_mut(n).enumerate() {
        let mut sum = [T::zero(); N];
        for yk in y.as_slice().chunks_exact(n).skip(b) {
            let xkb = yk.get(b).copied().unwrap_or_else(T::zero);
            if xkb != T::zero() {
                for (v, &ykj) in sum.iter_mut().zip(yk) {
                    *v += xkb * ykj;
                }
            }
        }
        for (o, v) in out.iter_mut().zip(sum) {
            *o = v;
        }
    }
    inverse
}
