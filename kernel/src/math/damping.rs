//! Damping design by double diagonalisation (\[ASOFH03\], used in Sec. 3.1.3 and 5.1.4).
//!
//! Given a reflected inertia `Λ ≻ 0` and a stiffness `K ⪰ 0` of a task (or of a collision pair),
//! find `Q` with `Λ = Q Qᵀ` and `K = Q K₀ Qᵀ`, `K₀ = diag(k₀ᵢ)`. In the coordinates `z = Qᵀ x`
//! the task dynamics `Λ ẍ + D ẋ + K x = 0` decouple into unit-mass oscillators
//! `z̈ᵢ + d₀ᵢ żᵢ + k₀ᵢ zᵢ = 0`; choosing `d₀ᵢ = 2 ξᵢ √k₀ᵢ` gives every mode the damping ratio
//! `ξᵢ`, and `D = Q diag(d₀ᵢ) Qᵀ`. Directions without stiffness (`k₀ᵢ = 0`, e.g. the common
//! mode of a collision pair, (3.21)–(3.23)) get no damping.

use core::fmt;

use nalgebra::{RealField, SMatrix, SVector};

use super::cholesky::{cholesky_in_place, solve_lower_in_place, solve_lower_transpose_in_place};
use super::eigen::symmetric_eigen;
use crate::math::sqrt;

/// The inertia given to [`double_diagonalization`]: either `Λ` itself or its inverse
/// `Λ⁻¹ = J M⁻¹ Jᵀ`, which is what a task computes directly (no matrix inverse is formed).
#[derive(Clone, Copy, Debug)]
pub enum ReflectedInertia<'a, T, const D: usize> {
    /// The reflected inertia `Λ` (kg, kg m²).
    Inertia(&'a SMatrix<T, D, D>),
    /// Its inverse `Λ⁻¹ = J M⁻¹ Jᵀ`.
    Inverse(&'a SMatrix<T, D, D>),
}

/// Why no damping matrix could be designed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DampingError {
    /// `Λ` (or `Λ⁻¹`) is not symmetric positive definite: e.g. a task at a singularity.
    InertiaNotPositiveDefinite,
    /// `K` has a clearly negative eigenvalue.
    StiffnessNotPositiveSemidefinite,
    /// A damping ratio is negative, NaN or infinite.
    InvalidDampingRatio,
    /// An input contains NaN or infinity.
    NonFinite,
}

impl fmt::Display for DampingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::InertiaNotPositiveDefinite => "reflected inertia is not positive definite",
            Self::StiffnessNotPositiveSemidefinite => "stiffness is not positive semidefinite",
            Self::InvalidDampingRatio => "damping ratio is negative or NaN",
            Self::NonFinite => "non-finite damping-design input",
        })
    }
}

impl core::error::Error for DampingError {}

/// Damping matrix `D = Q diag(2 ξᵢ √k₀ᵢ) Qᵀ` with `Λ = Q Qᵀ`, `K = Q K₀ Qᵀ` (double
/// diagonalisation, \[ASOFH03\]; (3.23) for collision pairs, Sec. 5.1.4 for Cartesian tasks).
///
/// With `Λ = L Lᵀ` (Cholesky): `L⁻¹ K L⁻ᵀ = V K₀ Vᵀ`, `Q = L V`. With `Λ⁻¹ = Lₐ Lₐᵀ`:
/// `Λ = Lₐ⁻ᵀ Lₐ⁻¹`, `Lₐᵀ K Lₐ = V K₀ Vᵀ`, `Q = Lₐ⁻ᵀ V` (a triangular solve). Only triangular
/// solves and a symmetric eigendecomposition ([`super::eigen::symmetric_eigen`]) are used, all
/// as loops over the column-major storage ([`cholesky_in_place`], [`solve_lower_in_place`],
/// [`solve_lower_transpose_in_place`]).
///
/// Inputs: `Λ` or `Λ⁻¹` symmetric positive definite, `K` symmetric positive semidefinite
/// (N/m, Nm/rad), `ξ ≥ 0` per mode (the mode order follows the eigen-solver; pass equal
/// ratios unless the modes are known). Cost O(D³).
///
/// ```
/// use kernel::math::damping::{double_diagonalization, ReflectedInertia};
/// use nalgebra::{Matrix1, Vector1};
/// // One mass of 2 kg on a 800 N/m spring, ξ = 0.7: d = 2·0.7·√(800·2) = 56 Ns/m.
/// let d = double_diagonalization(ReflectedInertia::Inertia(&Matrix1::new(2.0_f64)), &Matrix1::new(800.0),
///     &Vector1::new(0.7)).unwrap();
/// assert!((d[0] - 56.0).abs() < 1e-12);
/// ```
pub fn double_diagonalization<T: RealField + Copy, const D: usize>(
    inertia: ReflectedInertia<'_, T, D>,
    stiffness: &SMatrix<T, D, D>,
    damping_ratio: &SVector<T, D>,
) -> Result<SMatrix<T, D, D>, DampingError> {
    let given = match inertia {
        ReflectedInertia::Inertia(m) | ReflectedInertia::Inverse(m) => m,
    };
    let finite = |m: &SMatrix<T, D, D>| m.as_slice().iter().all(|x| x.is_finite());
    if !(finite(given) && finite(stiffness)) {
        return Err(DampingError::NonFinite);
    }
    if damping_ratio.iter().any(|x| !x.is_finite() || *x < T::zero()) {
        return Err(DampingError::InvalidDampingRatio);
    }
    let mut factor = *given;
    if !cholesky_in_place(factor.as_mut_slice(), D) {
        return Err(DampingError::InertiaNotPositiveDefinite);
    }
    let factored = match inertia {
        ReflectedInertia::Inertia(_) => ReflectedInertia::Inertia(&factor),
        ReflectedInertia::Inverse(_) => ReflectedInertia::Inverse(&factor),
    };
    double_diagonalization_factored(factored, stiffness, damping_ratio)
}

/// [`double_diagonalization`] from the Cholesky factor: `inertia` holds `L` with `Λ = L Lᵀ`
/// ([`ReflectedInertia::Inertia`]) or `Lₐ` with `Λ⁻¹ = Lₐ Lₐᵀ` ([`ReflectedInertia::Inverse`]),
/// as [`cholesky_in_place`] leaves it (only the lower triangle is read; positive diagonal).
/// Same design and errors as [`double_diagonalization`] except that the inertia is not checked
/// again (`K` and `ξ` are assumed finite, `ξ ≥ 0`): for a caller that has factored `Λ⁻¹`
/// itself (the Cartesian impedance checks its pivots). Cost O(D³), no D×D matrix product of
/// nalgebra.
pub fn double_diagonalization_factored<T: RealField + Copy, const D: usize>(
    inertia: ReflectedInertia<'_, T, D>,
    stiffness: &SMatrix<T, D, D>,
    damping_ratio: &SVector<T, D>,
) -> Result<SMatrix<T, D, D>, DampingError> {
    let half = nalgebra::convert::<f64, T>(0.5);
    // The reduced stiffness L⁻¹ K L⁻ᵀ or Lₐᵀ K Lₐ, symmetrised.
    let mut reduced = *stiffness;
    match inertia {
        ReflectedInertia::Inertia(l) => {
            // X = L⁻¹ K (column by column), then L⁻¹ Xᵀ = L⁻¹ K L⁻ᵀ (K symmetric: Xᵀ = K L⁻ᵀ).
            for column in reduced.as_mut_slice().chunks_exact_mut(D) {
                if !solve_lower_in_place(l.as_slice(), column) {
                    return Err(DampingError::InertiaNotPositiveDefinite);
                }
            }
            reduced.transpose_mut();
            for column in reduced.as_mut_slice().chunks_exact_mut(D) {
                if !solve_lower_in_place(l.as_slice(), column) {
                    return Err(DampingError::InertiaNotPositiveDefinite);
                }
            }
        }
        ReflectedInertia::Inverse(l) => {
            // W = K Lₐ, then (Lₐᵀ W)_ij = Σ_{k ≥ i} L_ki W_kj.
            let mut w = SMatrix::<T, D, D>::zeros();
            for (j, (w_column, l_column)) in
                w.as_mut_slice().chunks_exact_mut(D).zip(l.as_slice().chunks_exact(D)).enumerate()
            {
                let lower = l_column.get(j..).unwrap_or(&[]);
                for (k_column, l_kj) in stiffness.as_slice().chunks_exact(D).skip(j).zip(lower.iter()) {
                    if *l_kj != T::zero() {
                        for (w, k) in w_column.iter_mut().zip(k_column.iter()) {
                            *w += *k * *l_kj;
                        }
                    }
                }
            }
            for (r_column, w_column) in reduced.as_mut_slice().chunks_exact_mut(D).zip(w.as_slice().chunks_exact(D)) {
                for (i, (r, l_column)) in r_column.iter_mut().zip(l.as_slice().chunks_exact(D)).enumerate() {
                    let tail = l_column.get(i..).unwrap_or(&[]).iter().zip(w_column.get(i..).unwrap_or(&[]));
                    *r = tail.fold(T::zero(), |s, (a, b)| s + *a * *b);
                }
            }
        }
    }
    symmetrise(&mut reduced, half);
    let (k0, v) = symmetric_eigen(&reduced);
    let mut q = v;
    match inertia {
        ReflectedInertia::Inertia(l) => {
            // Q = L V: Q_ij = Σ_{k ≤ i} L_ik V_kj, column by column with axpy over L's columns.
            for (q_column, v_column) in q.as_mut_slice().chunks_exact_mut(D).zip(v.as_slice().chunks_exact(D)) {
                q_column.fill(T::zero());
                for (k, (l_column, v_kj)) in l.as_slice().chunks_exact(D).zip(v_column.iter()).enumerate() {
                    let targets = q_column.get_mut(k..).unwrap_or(&mut []);
                    for (x, l_ik) in targets.iter_mut().zip(l_column.get(k..).unwrap_or(&[]).iter()) {
                        *x += *l_ik * *v_kj;
                    }
                }
            }
        }
        ReflectedInertia::Inverse(l) => {
            for column in q.as_mut_slice().chunks_exact_mut(D) {
                if !solve_lower_transpose_in_place(l.as_slice(), column) {
                    return Err(DampingError::InertiaNotPositiveDefinite);
                }
            }
        }
    }
    // The eigensolver returns a stiffness-free mode (e.g. the common mode of a collision pair)
    // as O(ε max k₀) rather than 0; damping it by 2ξ√(ε k) would be spurious, and unboundedly
    // so relative to the real damping as the inertias grow apart. Modes within rounding of
    // zero are zero.
    let tolerance = nalgebra::convert::<f64, T>(1e3) * T::default_epsilon() * k0.amax();
    let two = nalgebra::convert::<f64, T>(2.0);
    // D = Σ_k d₀ₖ q_k q_kᵀ over the columns q_k of Q.
    let mut damping = SMatrix::<T, D, D>::zeros();
    for ((q_column, k), xi) in q.as_slice().chunks_exact(D).zip(k0.iter()).zip(damping_ratio.iter()) {
        if *k < -tolerance {
            return Err(DampingError::StiffnessNotPositiveSemidefinite);
        }
        if *k <= tolerance {
            continue;
        }
        let d0 = two * *xi * sqrt(*k);
        for (d_column, q_j) in damping.as_mut_slice().chunks_exact_mut(D).zip(q_column.iter()) {
            let scale = d0 * *q_j;
            for (d, q_i) in d_column.iter_mut().zip(q_column.iter()) {
                *d += *q_i * scale;
            }
        }
    }
    Ok(damping)
}

/// `A ← (A + Aᵀ)/2` in place (`half` = ½).
fn symmetrise<T: RealField + Copy, const D: usize>(a: &mut SMatrix<T, D, D>, half: T) {
    for i in 0..D {
        for j in (i + 1)..D {
            let (Some(upper), Some(lower)) = (a.get((i, j)).copied(), a.get((j, i)).copied()) else { continue };
            let mean = (upper + lower) * half;
            if let Some(x) = a.get_mut((i, j)) {
                *x = mean;
            }
            if let Some(x) = a.get_mut((j, i)) {
                *x = mean;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use nalgebra::{Cholesky, Matrix2, Matrix3, Matrix4, Vector2, Vector3};

    /// The plain design through nalgebra's `Cholesky`, triangular `solve_*` and matrix products:
    /// the reference for [`double_diagonalization`] (same eigen-solver).
    fn reference_double_diagonalization<T: RealField + Copy, const D: usize>(
        inertia: ReflectedInertia<'_, T, D>,
        stiffness: &SMatrix<T, D, D>,
        damping_ratio: &SVector<T, D>,
    ) -> Result<SMatrix<T, D, D>, DampingError> {
        let given = match inertia {
            ReflectedInertia::Inertia(m) | ReflectedInertia::Inverse(m) => m,
        };
        if !(crate::math::all_finite(given) && crate::math::all_finite(stiffness)) {
            return Err(DampingError::NonFinite);
        }
        if damping_ratio.iter().any(|x| !x.is_finite() || *x < T::zero()) {
            return Err(DampingError::InvalidDampingRatio);
        }
        let factor = Cholesky::new(*given).ok_or(DampingError::InertiaNotPositiveDefinite)?;
        let l = factor.l();
        let reduced = match inertia {
            ReflectedInertia::Inertia(_) => {
                let x = l.solve_lower_triangular(stiffness).ok_or(DampingError::InertiaNotPositiveDefinite)?;
                l.solve_lower_triangular(&x.transpose()).ok_or(DampingError::InertiaNotPositiveDefinite)?
            }
            ReflectedInertia::Inverse(_) => l.transpose() * stiffness * l,
        };
        let reduced = (reduced + reduced.transpose()) * nalgebra::convert::<f64, T>(0.5);
        let (k0, v) = symmetric_eigen(&reduced);
        let q = match inertia {
            ReflectedInertia::Inertia(_) => l * v,
            ReflectedInertia::Inverse(_) => {
                l.transpose().solve_upper_triangular(&v).ok_or(DampingError::InertiaNotPositiveDefinite)?
            }
        };
        let tolerance = nalgebra::convert::<f64, T>(1e3) * T::default_epsilon() * k0.amax();
        let mut modal = SVector::<T, D>::zeros();
        for ((d0, k), xi) in modal.iter_mut().zip(k0.iter()).zip(damping_ratio.iter()) {
            if *k < -tolerance {
                return Err(DampingError::StiffnessNotPositiveSemidefinite);
            }
            if *k > tolerance {
                *d0 = nalgebra::convert::<f64, T>(2.0) * *xi * k.sqrt();
            }
        }
        Ok(q * SMatrix::from_diagonal(&modal) * q.transpose())
    }

    /// xorshift in [−1, 1].
    fn uniform(x: &mut u64) -> f64 {
        *x ^= *x << 13;
        *x ^= *x >> 7;
        *x ^= *x << 17;
        (*x >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }

    /// Random SPD inertia (condition up to ~1e3), PSD stiffness (some with a null direction) and
    /// ratios; fast against reference for both inertia inputs, in f64 and f32.
    fn fast_matches_reference<const D: usize>() {
        let mut x = 0x2545_F491_4F6C_DD1D_u64 ^ D as u64;
        let mut worst = [0.0_f64; 2];
        for case in 0..80 {
            let a = SMatrix::<f64, D, D>::from_fn(|_, _| uniform(&mut x));
            let inertia = a * a.transpose() + SMatrix::identity() * (0.05 + uniform(&mut x).abs());
            let b = SMatrix::<f64, D, D>::from_fn(|_, _| uniform(&mut x) * 30.0);
            let mut stiffness = b * b.transpose();
            if case % 3 == 0 {
                // A stiffness-free direction: K e = 0 for e = first axis.
                let mut p = SMatrix::<f64, D, D>::identity();
                p[(0, 0)] = 0.0;
                stiffness = p * stiffness * p;
            }
            let ratios =
                SVector::<f64, D>::from_fn(|_, _| if case % 2 == 0 { 0.7 } else { 0.2 + 0.5 * uniform(&mut x).abs() });
            let inverse = inertia.try_inverse().unwrap();
            for given in [ReflectedInertia::Inertia(&inertia), ReflectedInertia::Inverse(&inverse)] {
                let fast = double_diagonalization(given, &stiffness, &ratios).unwrap();
                let reference = reference_double_diagonalization(given, &stiffness, &ratios).unwrap();
                let scale = reference.amax().max(1e-30);
                let error = (fast - reference).amax() / scale;
                worst[0] = worst[0].max(error);
                assert!(error < 1e-10, "D = {D}, case {case}: relative difference {error:e}");
                assert!((fast - fast.transpose()).amax() <= 1e-14 * fast.amax());
                let given32 = match given {
                    ReflectedInertia::Inertia(_) => inertia.cast::<f32>(),
                    ReflectedInertia::Inverse(_) => inverse.cast::<f32>(),
                };
                let wrap = |m| match given {
                    ReflectedInertia::Inertia(_) => ReflectedInertia::Inertia(m),
                    ReflectedInertia::Inverse(_) => ReflectedInertia::Inverse(m),
                };
                let (k32, r32) = (stiffness.cast::<f32>(), ratios.cast::<f32>());
                let fast32 = double_diagonalization(wrap(&given32), &k32, &r32).unwrap();
                let reference32 = reference_double_diagonalization(wrap(&given32), &k32, &r32).unwrap();
                let error32 = ((fast32 - reference32).amax() / reference32.amax().max(1e-30)) as f64;
                worst[1] = worst[1].max(error32);
                assert!(error32 < 2e-5, "f32 D = {D}, case {case}: {error32:e}");
            }
        }
        eprintln!("D = {D}: worst relative difference fast vs reference f64 {:e}, f32 {:e}", worst[0], worst[1]);
    }

    #[test]
    fn loops_match_the_nalgebra_reference() {
        fast_matches_reference::<1>();
        fast_matches_reference::<2>();
        fast_matches_reference::<3>();
        fast_matches_reference::<6>();
    }

    /// Damping ratios of the closed loop Λẍ + Dẋ + Kx = 0 from the eigenvalues of its state
    /// matrix (independent of the construction): ζ = −Re λ / |λ| for each complex pair.
    fn closed_loop_damping_ratios(lambda: &Matrix2<f64>, d: &Matrix2<f64>, k: &Matrix2<f64>) -> [f64; 2] {
        let inv = lambda.try_inverse().unwrap();
        let mut a = Matrix4::zeros();
        a.fixed_view_mut::<2, 2>(0, 2).copy_from(&Matrix2::identity());
        a.fixed_view_mut::<2, 2>(2, 0).copy_from(&(-inv * k));
        a.fixed_view_mut::<2, 2>(2, 2).copy_from(&(-inv * d));
        let eig = a.complex_eigenvalues();
        let mut ratios: Vec<f64> = eig.iter().filter(|l| l.im > 0.0).map(|l| -l.re / l.re.hypot(l.im)).collect();
        ratios.sort_by(f64::total_cmp);
        [ratios[0], ratios[1]]
    }

    #[test]
    fn every_mode_gets_its_damping_ratio_for_both_inertia_inputs() {
        let lambda = Matrix2::new(3.0, 0.8, 0.8, 1.5);
        let k = Matrix2::new(900.0, -200.0, -200.0, 400.0);
        let xi = Vector2::new(0.3, 0.3);
        let d = double_diagonalization(ReflectedInertia::Inertia(&lambda), &k, &xi).unwrap();
        let r = closed_loop_damping_ratios(&lambda, &d, &k);
        assert!((r[0] - 0.3).abs() < 1e-9 && (r[1] - 0.3).abs() < 1e-9, "{r:?}");
        let inverse = lambda.try_inverse().unwrap();
        let d_inv = double_diagonalization(ReflectedInertia::Inverse(&inverse), &k, &xi).unwrap();
        assert!((d - d_inv).amax() < 1e-9 * d.amax());
        // Distinct ratios land on the two modes (which mode gets which follows the solver).
        let d2 = double_diagonalization(ReflectedInertia::Inertia(&lambda), &k, &Vector2::new(0.2, 0.6)).unwrap();
        let r2 = closed_loop_damping_ratios(&lambda, &d2, &k);
        assert!((r2[0] - 0.2).abs() < 1e-9 && (r2[1] - 0.6).abs() < 1e-9, "{r2:?}");
    }

    #[test]
    fn collision_pair_closed_form() {
        // (3.21)–(3.23): pair stiffness k [[1,−1],[−1,1]], masses diag(m_i, m_j): the common
        // mode is undamped and D = 2ξ√(k m_eff) [[1,−1],[−1,1]], m_eff = m_i m_j / (m_i + m_j).
        let (mi, mj, k, xi): (f64, f64, f64, f64) = (4.0, 1.0, 300.0, 0.7);
        let lambda = Matrix2::new(mi, 0.0, 0.0, mj);
        let stiffness = Matrix2::new(k, -k, -k, k);
        let d = double_diagonalization(ReflectedInertia::Inertia(&lambda), &stiffness, &Vector2::repeat(xi)).unwrap();
        let expected = Matrix2::new(1.0, -1.0, -1.0, 1.0) * 2.0 * xi * (k * mi * mj / (mi + mj)).sqrt();
        assert!((d - expected).amax() < 1e-10, "{d}");
    }

    /// Without the rounding guard the common mode picks up damping of relative size
    /// √ε · m_max/m_min; with it the pair damping is exact at any mass ratio.
    #[test]
    fn stiffness_free_modes_get_no_damping_at_extreme_mass_ratios() {
        for ratio in [1.0, 1e2, 1e6, 1e9] {
            let (mi, mj, k, xi) = (1.0_f64, ratio, 300.0, 0.7);
            let expected = 2.0 * xi * (k * mi * mj / (mi + mj)).sqrt();
            let inverse = Matrix2::new(1.0 / mi, 0.0, 0.0, 1.0 / mj);
            let stiffness = Matrix2::new(k, -k, -k, k);
            let d =
                double_diagonalization(ReflectedInertia::Inverse(&inverse), &stiffness, &Vector2::repeat(xi)).unwrap();
            // Both points moving together (no relative velocity) must not be damped.
            let common = d * Vector2::new(1.0, 1.0);
            assert!(common.amax() < 1e-12 * expected, "ratio {ratio}: common mode damped by {common}");
            assert!((d[(0, 0)] - expected).abs() < 1e-9 * expected, "ratio {ratio}: {d}");
            let d32 = double_diagonalization(
                ReflectedInertia::Inverse(&inverse.cast::<f32>()),
                &stiffness.cast::<f32>(),
                &Vector2::repeat(0.7_f32),
            )
            .unwrap();
            assert!(((d32[(0, 0)] as f64) - expected).abs() < 1e-5 * expected, "f32, ratio {ratio}: {d32}");
            assert!(((d32[(0, 1)] as f64) + expected).abs() < 1e-5 * expected, "f32, ratio {ratio}: {d32}");
        }
    }

    #[test]
    fn invalid_inputs_are_errors() {
        let m = Matrix3::<f32>::identity();
        let k = Matrix3::from_diagonal(&Vector3::new(1.0, -5.0, 1.0));
        let xi = Vector3::repeat(0.7);
        assert_eq!(
            double_diagonalization(ReflectedInertia::Inertia(&m), &k, &xi),
            Err(DampingError::StiffnessNotPositiveSemidefinite)
        );
        assert_eq!(
            double_diagonalization(ReflectedInertia::Inertia(&(-m)), &m, &xi),
            Err(DampingError::InertiaNotPositiveDefinite)
        );
        assert_eq!(
            double_diagonalization(ReflectedInertia::Inverse(&m), &m, &Vector3::new(0.7, f32::NAN, 0.7)),
            Err(DampingError::InvalidDampingRatio)
        );
        assert_eq!(
            double_diagonalization(ReflectedInertia::Inertia(&m), &(m * f32::INFINITY), &xi),
            Err(DampingError::NonFinite)
        );
        let d = double_diagonalization(ReflectedInertia::Inertia(&m), &(m * 4.0), &xi).unwrap();
        assert!((d - m * 2.8).amax() < 1e-5, "f32 isotropic case: 2·0.7·√4 = 2.8");
    }
}
