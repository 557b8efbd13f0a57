//! The damping design of the Cartesian impedance: double diagonalisation (\[ASOFH03\], Sec. 5.1.4)
//! for the reflected inertia `Λ⁻¹ = J_x M⁻¹ J_xᵀ` of the selected rows, on a dense or a
//! tree-sparse factor of `M`.

use nalgebra::{Matrix6, RealField, SMatrix, SVector, Vector6};

use crate::dynamics::TreeFactorization;
use crate::math::cholesky::{cholesky_fixed, cholesky_in_place, solve_lower_in_place};
use crate::math::damping::{double_diagonalization_factored, DampingError, ReflectedInertia};
use crate::model::Data;

/// `S x` for a 6×6 matrix `S` as a loop over its columns.
pub(super) fn symmetric_times<T: RealField + Copy>(s: &Matrix6<T>, x: &Vector6<T>) -> Vector6<T> {
    let mut y = Vector6::zeros();
    for (column, xj) in s.as_slice().chunks_exact(6).zip(x.iter()) {
        if *xj != T::zero() {
            for (yi, sij) in y.iter_mut().zip(column.iter()) {
                *yi += *sij * *xj;
            }
        }
    }
    y
}

/// `D` by double diagonalisation for `Λ⁻¹ = J_x M⁻¹ J_xᵀ` (unselected rows of `J_x` are zero;
/// their diagonal entry of `Λ⁻¹` is set to 1 so the matrix stays invertible, and as they have no
/// stiffness they get no damping). `Λ⁻¹` counts as singular if a pivot of its Cholesky factor
/// has `L_ii² ≤ 100 ε max_i Λ⁻¹_ii`.
///
/// With `M = L Lᵀ`: `Y = L⁻¹ J_xᵀ` by forward substitution of the selected rows only (tight
/// loops on the column-major factor, [`crate::math::cholesky::solve_lower_in_place`]) and
/// `Λ⁻¹ = Yᵀ Y` (exactly symmetric). The factor of `Λ⁻¹` that checks the pivots is handed to
/// [`crate::math::damping::double_diagonalization_factored`].
pub(super) fn damping_matrix<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    data: &Data<T, N, B, F>,
    stiffness: &Matrix6<T>,
    damping_ratio: T,
    task_jacobian: &SMatrix<T, 6, N>,
    selected: &[bool; 6],
) -> Result<Matrix6<T>, DampingFallback> {
    let mut factor = data.mass_matrix;
    if !cholesky_in_place(factor.as_mut_slice(), N) {
        return Err(DampingFallback::MassMatrixNotPositiveDefinite);
    }
    // Y = L⁻¹ J_xᵀ, one column per selected row (zero for the others).
    let mut reduced = SMatrix::<T, N, 6>::zeros();
    for (axis, (column, flag)) in reduced.as_mut_slice().chunks_exact_mut(N).zip(selected.iter()).enumerate() {
        if !flag {
            continue;
        }
        for (y, j) in column.iter_mut().zip(task_jacobian.as_slice().chunks_exact(6)) {
            *y = j.get(axis).copied().unwrap_or_else(T::zero);
        }
        if !solve_lower_in_place(factor.as_slice(), column) {
            return Err(DampingFallback::MassMatrixNotPositiveDefinite);
        }
    }
    let mut inverse_inertia = Matrix6::<T>::identity();
    for (i, (yi, si)) in reduced.as_slice().chunks_exact(N).zip(selected.iter()).enumerate() {
        if !si {
            continue;
        }
        for (j, (yj, sj)) in reduced.as_slice().chunks_exact(N).zip(selected.iter()).enumerate().take(i + 1) {
            if !sj {
                continue;
            }
            let dot = yi.iter().zip(yj.iter()).fold(T::zero(), |s, (a, b)| s + *a * *b);
            if let Some(x) = inverse_inertia.get_mut((i, j)) {
                *x = dot;
            }
            if let Some(x) = inverse_inertia.get_mut((j, i)) {
                *x = dot;
            }
        }
    }
    design_from_inverse_inertia(stiffness, damping_ratio, &inverse_inertia)
}

/// [`damping_matrix`] on the tree-sparse factor `M = Lᵀ L`: `X = J_x L⁻¹`
/// ([`TreeFactorization::right_solve_mut`], only the support-path columns of `J_x` are
/// touched) and `Λ⁻¹ = X Xᵀ` summed over the nonzero columns of `X`, unselected diagonal
/// entries set to 1; then the same pivot check and double diagonalisation.
pub(super) fn damping_matrix_tree<T: RealField + Copy, const N: usize>(
    factor: Option<&TreeFactorization<T, N>>,
    stiffness: &Matrix6<T>,
    damping_ratio: T,
    task_jacobian: &SMatrix<T, 6, N>,
    selected: &[bool; 6],
) -> Result<Matrix6<T>, DampingFallback> {
    let factor = factor.ok_or(DampingFallback::MassMatrixNotPositiveDefinite)?;
    let mut reduced = *task_jacobian;
    factor.right_solve_mut(&mut reduced);
    // The lower triangle as rank-one updates over the nonzero columns of X (fixed-length loops
    // on the column arrays), then mirrored: Λ⁻¹ is exactly symmetric.
    let mut inverse_inertia = Matrix6::<T>::zeros();
    for column in reduced.data.0.iter() {
        if column.iter().all(|x| *x == T::zero()) {
            continue;
        }
        for (j, (target, xj)) in inverse_inertia.data.0.iter_mut().zip(column.iter()).enumerate() {
            for i in j..6 {
                if let (Some(t), Some(xi)) = (target.get_mut(i), column.get(i)) {
                    *t += *xi * *xj;
                }
            }
        }
    }
    for j in 0..6 {
        for i in (j + 1)..6 {
            if let Some(x) = inverse_inertia.get((i, j)).copied() {
                if let Some(y) = inverse_inertia.get_mut((j, i)) {
                    *y = x;
                }
            }
        }
    }
    for (i, s) in selected.iter().enumerate() {
        if !s {
            if let Some(x) = inverse_inertia.get_mut((i, i)) {
                *x = T::one();
            }
        }
    }
    design_from_inverse_inertia(stiffness, damping_ratio, &inverse_inertia)
}

/// The pivot check of `Λ⁻¹` and the double diagonalisation (shared by both damping designs).
fn design_from_inverse_inertia<T: RealField + Copy>(
    stiffness: &Matrix6<T>,
    damping_ratio: T,
    inverse_inertia: &Matrix6<T>,
) -> Result<Matrix6<T>, DampingFallback> {
    // A rounding-level pivot would pass the factorization inside the design but give a
    // meaningless (huge) damping along the lost direction: treat it as singular.
    let mut pivots = *inverse_inertia;
    if !cholesky_fixed(&mut pivots.data.0) {
        return Err(DampingFallback::TaskJacobianSingular);
    }
    let floor = nalgebra::convert::<f64, T>(100.0) * T::default_epsilon() * inverse_inertia.diagonal().amax();
    if pivots.diagonal().iter().any(|l| *l * *l <= floor) {
        return Err(DampingFallback::TaskJacobianSingular);
    }
    if !inverse_inertia.as_slice().iter().all(|x| x.is_finite()) {
        return Err(DampingFallback::Design(DampingError::NonFinite));
    }
    let ratios = SVector::<T, 6>::repeat(damping_ratio);
    double_diagonalization_factored(ReflectedInertia::Inverse(&pivots), stiffness, &ratios)
        .map_err(DampingFallback::Design)
}

/// Why the task used its fallback damping.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DampingFallback {
    /// The mass matrix failed its Cholesky factorization (was `crba` called?).
    MassMatrixNotPositiveDefinite,
    /// `Λ⁻¹ = J_x M⁻¹ J_xᵀ` is numerically singular (a Cholesky pivot at rounding level): the
    /// selected axes are not independent at this configuration (kinematic singularity, or more
    /// axes than the frame has joints).
    TaskJacobianSingular,
    /// The double diagonalisation failed.
    Design(DampingError),
}
