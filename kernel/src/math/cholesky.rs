//! Dense Cholesky factorisation and triangular substitutions on column-major storage (the
//! layout of nalgebra's matrices), for any size known at run time: the kernels behind the
//! damping design, the Cartesian task's `Λ⁻¹`, the torso workspace, the contact-force limiter
//! and the manipulability measure. Tight loops over slices, no temporaries.

use nalgebra::RealField;

use crate::math::sqrt;

/// Cholesky factorisation `A = L Lᵀ` in place on the column-major storage of an `n×n`
/// symmetric matrix (`a.len() = n²`; the lower triangle is read): on success the lower
/// triangle holds `L` (positive diagonal) and the strict upper triangle is left as it was.
/// Left-looking, column by column, the same operation order as nalgebra's `Cholesky::new`.
/// Returns `false` (the storage then holds a partial factor) if a pivot is zero, negative or
/// NaN. Cost n³/6 multiply-adds.
pub fn cholesky_in_place<T: RealField + Copy>(a: &mut [T], n: usize) -> bool {
    if n == 0 || a.len() != n * n {
        return n == 0 && a.is_empty();
    }
    for j in 0..n {
        let Some((previous, rest)) = a.split_at_mut_checked(j * n) else { return false };
        let Some(column) = rest.get_mut(..n) else { return false };
        let Some(below) = column.get_mut(j..) else { return false };
        for l_column in previous.chunks_exact(n) {
            let Some(l_tail) = l_column.get(j..) else { return false };
            let Some(&l_jk) = l_tail.first() else { return false };
            if l_jk != T::zero() {
                for (x, l) in below.iter_mut().zip(l_tail.iter()) {
                    *x -= l_jk * *l;
                }
            }
        }
        let Some((diagonal, tail)) = below.split_first_mut() else { return false };
        if (*diagonal).partial_cmp(&T::zero()) != Some(core::cmp::Ordering::Greater) {
            return false;
        }
        let root = sqrt(*diagonal);
        *diagonal = root;
        for x in tail.iter_mut() {
            *x /= root;
        }
    }
    true
}

/// Forward substitution `L y = b` in place (`b ← L⁻¹ b`) with the column-major `n×n` lower
/// factor `l` of [`cholesky_in_place`] (`n = b.len()`, only the lower triangle is read).
/// Column-oriented: leading zeros of `b` cost nothing. Returns `false` if the sizes differ.
pub fn solve_lower_in_place<T: RealField + Copy>(l: &[T], b: &mut [T]) -> bool {
    let n = b.len();
    if n == 0 || l.len() != n * n {
        return n == 0 && l.is_empty();
    }
    for (j, column) in l.chunks_exact(n).enumerate() {
        let (Some((y, rest)), Some((diagonal, below))) =
            (b.get_mut(j..).and_then(|s| s.split_first_mut()), column.get(j..).and_then(|s| s.split_first()))
        else {
            return false;
        };
        if *y == T::zero() {
            continue;
        }
        *y /= *diagonal;
        let y = *y;
        for (x, l_ij) in rest.iter_mut().zip(below.iter()) {
            *x -= y * *l_ij;
        }
    }
    true
}

/// Backward substitution `Lᵀ x = y` in place (`y ← L⁻ᵀ y`) with the column-major lower factor
/// `l` of [`cholesky_in_place`] (`n = y.len()`): `x_j = (y_j − Σ_{i>j} L_ij x_i)/L_jj`, a dot
/// product with the contiguous part of column `j` below the diagonal. Returns `false` if the
/// sizes differ.
pub fn solve_lower_transpose_in_place<T: RealField + Copy>(l: &[T], y: &mut [T]) -> bool {
    let n = y.len();
    if n == 0 || l.len() != n * n {
        return n == 0 && l.is_empty();
    }
    for (j, column) in l.chunks_exact(n).enumerate().rev() {
        let (Some((x, rest)), Some((diagonal, below))) =
            (y.get_mut(j..).and_then(|s| s.split_first_mut()), column.get(j..).and_then(|s| s.split_first()))
        else {
            return false;
        };
        let sum = below.iter().zip(rest.iter()).fold(*x, |s, (l_ij, x_i)| s - *l_ij * *x_i);
        *x = sum / *diagonal;
    }
    true
}

/// [`cholesky_in_place`] for a size `D` known at compile time, on the column arrays `a` of a
/// `D×D` matrix (`SMatrix::data.0`): the same left-looking order and operations (the same
/// result, bit for bit) with fixed-length loops. Returns `false` on a pivot that is not
/// positive.
pub fn cholesky_fixed<T: RealField + Copy, const D: usize>(a: &mut [[T; D]; D]) -> bool {
    left_looking(a, |column| column.as_slice(), |column| column.as_mut_slice())
}

/// [`cholesky_fixed`] for a `6A × 6A` matrix stored as `A × A` blocks of six rows, column-major
/// (`a[b][j][k][i]` is row `6k + i`, column `6b + j`: the stacked systems of the contact-force
/// limiter, whose size `6A` cannot be an array length in code generic over `A`). The same
/// operations in the same order, with fixed-length loops for every `A`.
pub fn cholesky_blocks<T: RealField + Copy, const A: usize>(a: &mut [[[[T; 6]; A]; 6]; A]) -> bool {
    left_looking(a.as_flattened_mut(), |column| column.as_flattened(), |column| column.as_flattened_mut())
}

/// The left-looking factorisation of [`cholesky_in_place`] on the columns `a` (as many as each
/// has entries, read through `entries` and `entries_mut`); inlined into each fixed-size caller,
/// so that every trip count is a constant.
#[inline(always)]
fn left_looking<T: RealField + Copy, C>(
    a: &mut [C],
    entries: impl Fn(&C) -> &[T],
    entries_mut: impl Fn(&mut C) -> &mut [T],
) -> bool {
    let d = a.len();
    for j in 0..d {
        let Some((previous, rest)) = a.split_at_mut_checked(j) else { return false };
        let Some(column) = rest.first_mut().map(&entries_mut) else { return false };
        for l_column in previous.iter().map(&entries) {
            let Some(&l_jk) = l_column.get(j) else { return false };
            if l_jk != T::zero() {
                for i in j..d {
                    if let (Some(x), Some(l)) = (column.get_mut(i), l_column.get(i)) {
                        *x -= l_jk * *l;
                    }
                }
            }
        }
        let Some(diagonal) = column.get_mut(j) else { return false };
        if (*diagonal).partial_cmp(&T::zero()) != Some(core::cmp::Ordering::Greater) {
            return false;
        }
        let root = sqrt(*diagonal);
        *diagonal = root;
        for i in (j + 1)..d {
            if let Some(x) = column.get_mut(i) {
                *x /= root;
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use nalgebra::{Cholesky, Matrix2, SMatrix, SVector};

    fn uniform(x: &mut u64) -> f64 {
        *x ^= *x << 13;
        *x ^= *x >> 7;
        *x ^= *x << 17;
        (*x >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }

    #[test]
    fn triangular_kernels_invert_the_factor() {
        let mut x = 77_u64;
        for _ in 0..20 {
            let a = SMatrix::<f64, 7, 7>::from_fn(|_, _| uniform(&mut x));
            let m = a * a.transpose() + SMatrix::identity() * 0.1;
            let mut l = m;
            assert!(cholesky_in_place(l.as_mut_slice(), 7));
            let reference = Cholesky::new(m).unwrap();
            assert!((l.lower_triangle() - reference.l()).amax() < 1e-12);
            // Upper triangle untouched.
            assert_eq!(
                l.upper_triangle(),
                m.upper_triangle() - SMatrix::from_diagonal(&m.diagonal()) + SMatrix::from_diagonal(&l.diagonal())
            );
            let b = SVector::<f64, 7>::from_fn(|i, _| if i < 2 { 0.0 } else { uniform(&mut x) });
            let mut y = b;
            assert!(solve_lower_in_place(l.as_slice(), y.as_mut_slice()));
            assert!((reference.l() * y - b).amax() < 1e-12);
            let mut z = y;
            assert!(solve_lower_transpose_in_place(l.as_slice(), z.as_mut_slice()));
            assert!((m * z - b).amax() < 1e-10 * (1.0 + b.amax()));
        }
        let mut indefinite = Matrix2::new(1.0_f32, 2.0, 2.0, 1.0);
        assert!(!cholesky_in_place(indefinite.as_mut_slice(), 2));
        let mut nan = Matrix2::new(f32::NAN, 0.0, 0.0, 1.0);
        assert!(!cholesky_in_place(nan.as_mut_slice(), 2));
        assert!(!solve_lower_in_place(&[1.0_f32; 3], &mut [1.0, 2.0]));
    }

    /// [`cholesky_fixed`] equals [`cholesky_in_place`] bit for bit (random SPD matrices, f64 and
    /// f32, and a failing one).
    #[test]
    fn fixed_size_factor_equals_the_slice_factor() {
        fn check<T: RealField + Copy, const D: usize>(seed: u64) {
            let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
            let b = nalgebra::SMatrix::<f64, D, D>::from_fn(|_, _| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                (x >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
            });
            let spd: nalgebra::SMatrix<T, D, D> =
                (b * b.transpose() + nalgebra::SMatrix::<f64, D, D>::identity() * 0.1).cast();
            let (mut slice, mut fixed) = (spd, spd);
            assert!(cholesky_in_place(slice.as_mut_slice(), D));
            assert!(cholesky_fixed(&mut fixed.data.0));
            assert_eq!(slice, fixed);
            let indefinite = -spd;
            let (mut slice, mut fixed) = (indefinite, indefinite);
            assert!(!cholesky_in_place(slice.as_mut_slice(), D));
            assert!(!cholesky_fixed(&mut fixed.data.0));
        }
        for seed in 1..20 {
            check::<f64, 6>(seed);
            check::<f32, 6>(seed);
            check::<f64, 12>(seed);
            check::<f32, 12>(seed);
        }
    }
}
