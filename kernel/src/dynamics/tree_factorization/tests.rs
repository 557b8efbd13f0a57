#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
use super::*;
use crate::dynamics::{crba, forward_kinematics};
use crate::model::Data;
use crate::test_models::{branched, state, N};
use nalgebra::Cholesky;
use proptest::prelude::*;

fn check<T: RealField + Copy>(seed: u64, tol: f64) -> Result<(), TestCaseError> {
    let model = branched::<T>();
    let mut data = Data::new(&model);
    let cast = |x: SVector<f64, N>| x.map(|e| nalgebra::convert::<f64, T>(e));
    forward_kinematics(&model, &mut data, &cast(state(seed, 2.0)), &SVector::zeros()).unwrap();
    let m = *crba(&model, &mut data);
    let mut tree = TreeFactorization::new(&model);
    tree.factorize(&m).unwrap();
    let l = tree.lower().map(|e| nalgebra::try_convert::<T, f64>(e).unwrap());
    let m64 = m.map(|e| nalgebra::try_convert::<T, f64>(e).unwrap());
    let scale = m64.amax();
    // L is lower triangular and LᵀL reproduces M.
    prop_assert!(l.upper_triangle().lower_triangle() == SMatrix::from_diagonal(&l.diagonal()));
    prop_assert!((l.transpose() * l - m64).amax() < tol * scale, "{}", (l.transpose() * l - m64).amax());
    // Solves agree with nalgebra's dense Cholesky.
    let b = state(seed ^ 11, 5.0);
    let mut x = cast(b);
    tree.solve_mut(&mut x);
    let x = x.map(|e| nalgebra::try_convert::<T, f64>(e).unwrap());
    let dense = Cholesky::new(m64).unwrap().solve(&b);
    prop_assert!((x - dense).amax() < tol * 1e3 * (1.0 + dense.amax()), "{}", (x - dense).amax());
    // (J L⁻¹)(J L⁻¹)ᵀ = J M⁻¹ Jᵀ for a 3 × N matrix with a zero column (outside a support path).
    let mut j = SMatrix::<f64, 3, N>::from_fn(|r, c| state(seed ^ (r as u64 + 3), 1.0)[c]);
    j.column_mut(N - 1).fill(0.0);
    let mut x = j.map(|e| nalgebra::convert::<f64, T>(e));
    tree.right_solve_mut(&mut x);
    let x = x.map(|e| nalgebra::try_convert::<T, f64>(e).unwrap());
    let reference = j * m64.try_inverse().unwrap() * j.transpose();
    let fast = x * x.transpose();
    prop_assert!((fast - reference).amax() < tol * 1e3 * (1.0 + reference.amax()), "{}", (fast - reference).amax());
    // The inverse reflected masses of two of those rows: the diagonal of J M⁻¹ Jᵀ.
    let row = |r: usize| -> [T; N] { core::array::from_fn(|c| nalgebra::convert::<f64, T>(j[(r, c)])) };
    let (first, second) = (row(0), row(2));
    let masses = tree.inverse_reflected_masses([&first, &second]).map(|e| nalgebra::try_convert::<T, f64>(e).unwrap());
    for (fast, r) in masses.iter().zip([0, 2]) {
        let plain = reference[(r, r)];
        prop_assert!((fast - plain).abs() < tol * 1e3 * (1.0 + plain.abs()), "row {r}: {fast} vs {plain}");
    }
    // M⁻¹ from the tree factor against the dense inverse.
    let inverse = tree.inverse().map(|e| nalgebra::try_convert::<T, f64>(e).unwrap());
    let dense_inverse = m64.try_inverse().unwrap();
    let error = (inverse - dense_inverse).amax();
    prop_assert!(error < tol * 1e3 * (1.0 + dense_inverse.amax()), "{}", error);
    Ok(())
}

proptest! {
    /// f64 and f32: `LᵀL = M`, the tree solve equals the dense Cholesky solve and the right solve
    /// gives `J M⁻¹ Jᵀ`.
    #[test]
    fn tree_factorization_matches_dense_cholesky(seed in any::<u64>()) {
        check::<f64>(seed, 1e-13)?;
        check::<f32>(seed, 1e-5)?;
    }
}

/// `decouple` of the factor of `M` equals (to the bit) the factorization of `M` with the
/// decoupled rows and columns cleared to a new diagonal, for root sets (no refactorization)
/// and for a set that is not closed under ancestors (refactorized); a non-positive
/// decoupled diagonal is rejected.
fn check_decouple<T: RealField + Copy>(seed: u64) {
    let model = branched::<T>();
    let mut data = Data::new(&model);
    let q = state(seed, 2.0).map(|e| nalgebra::convert::<f64, T>(e));
    forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
    let m = *crba(&model, &mut data);
    let mut plain = TreeFactorization::new(&model);
    plain.factorize(&m).unwrap();
    for set in [&[0_usize][..], &[0, 1], &[2], &[1, 4]] {
        let mut decoupled = [false; N];
        let mut cleared = m;
        for &c in set {
            decoupled[c] = true;
            let diagonal = nalgebra::convert::<f64, T>(0.5 + c as f64);
            cleared.row_mut(c).fill(T::zero());
            cleared.column_mut(c).fill(T::zero());
            cleared[(c, c)] = diagonal;
        }
        let mut fast = plain.clone();
        fast.decouple(&decoupled, &cleared).unwrap();
        let mut reference = TreeFactorization::new(&model);
        reference.factorize(&cleared).unwrap();
        assert_eq!(fast.lower(), reference.lower(), "set {set:?}");
        // The inverse of the decoupled factor is the inverse of the cleared matrix.
        let to64 = |x: SMatrix<T, N, N>| x.map(|e| nalgebra::try_convert::<T, f64>(e).unwrap());
        let dense_inverse = to64(cleared).try_inverse().unwrap();
        let tol = if core::mem::size_of::<T>() == 8 { 1e-10 } else { 1e-3 };
        assert!((to64(fast.inverse()) - dense_inverse).amax() < tol * (1.0 + dense_inverse.amax()), "set {set:?}");
        cleared[(set[0], set[0])] = T::zero();
        let mut fast = plain.clone();
        assert_eq!(fast.decouple(&decoupled, &cleared), Err(DynamicsError::MassMatrixNotPositiveDefinite));
    }
}

#[test]
fn decoupling_equals_factorizing_the_cleared_matrix() {
    for seed in 0..20 {
        check_decouple::<f64>(seed);
        check_decouple::<f32>(seed);
    }
}

#[test]
fn branched_model_has_two_chains_and_rejects_indefinite() {
    let model = branched::<f64>();
    let tree = TreeFactorization::<f64, N>::new(&model);
    // Trunk 0 (base) – 1 (yaw); branch 2 – 3 (pitch, elbow and the joint coupled to both);
    // branch 4 – 5 (prismatic, wrist) hangs from the yaw, not from the other branch.
    assert_eq!(tree.parents(), [None, Some(0), Some(1), Some(2), Some(1), Some(4)]);
    let mut t = tree.clone();
    let mut m = SMatrix::<f64, N, N>::identity();
    m[(2, 2)] = -1.0;
    assert_eq!(t.factorize(&m), Err(DynamicsError::MassMatrixNotPositiveDefinite));
}
