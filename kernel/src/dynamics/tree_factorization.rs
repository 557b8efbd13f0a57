//! Tree-sparse `Lᵀ L` factorization of the joint-space inertia matrix (Featherstone,
//! *Rigid Body Dynamics Algorithms*, Sec. 6.5, "branch-induced sparsity").
//!
//! `M_ij` vanishes unless the joints of coordinates `i` and `j` lie on one path to the root.
//! Eliminating the coordinates from the last to the first, `M = Lᵀ L` with `L` lower triangular
//! creates no fill-in outside that pattern when the coordinate parents `λ(k) < k` describe the
//! tree; the factorization then costs O(Σ_k depth_k²) instead of O(N³/3), and each solve
//! O(Σ_k depth_k) instead of O(N²). Not wired into the controller.

use nalgebra::{RealField, SMatrix, SVector};

use super::DynamicsError;
use crate::model::Model;

/// `M = Lᵀ L` over the elimination tree of the model's coordinates.
///
/// Build once per model with [`TreeFactorization::new`] (symbolic analysis), then
/// [`TreeFactorization::factorize`] each `M(q)` and [`TreeFactorization::solve_mut`].
#[derive(Clone, Debug)]
pub struct TreeFactorization<T: RealField, const N: usize> {
    /// `λ(k)`: parent of coordinate `k` in the elimination tree (always `< k`), `None` for a
    /// root. Every nonzero `L_kj`, `j < k`, has `j` on the chain `λ(k), λ(λ(k)), …`.
    parents: [Option<usize>; N],
    /// The factor `L` (lower triangular; zero above the diagonal and off the ancestor chains).
    factor: SMatrix<T, N, N>,
}

impl<T: RealField + Copy, const N: usize> TreeFactorization<T, N> {
    /// Symbolic analysis of `model`: the pattern of `M` (coordinates `r`, `c` coupled when a
    /// joint driven by `r` and a joint driven by `c` lie on one path to the root, through the
    /// drive terms), then the elimination tree for eliminating `N − 1, …, 0`:
    /// `λ(k) = max {j < k : (k, j) in the pattern}`, and the rest of row `k` joins row `λ(k)`
    /// (the fill of eliminating `k`). For an unbranched chain of single-term drives this is
    /// `λ(k) = k − 1`; Justin's two arms get disjoint chains that meet at the torso.
    pub fn new<const B: usize, const F: usize>(model: &Model<T, N, B, F>) -> Self {
        let mut pattern = [[false; N]; N];
        let bodies = model.bodies();
        for (i, body) in bodies.iter().enumerate() {
            let mut next = Some(i);
            while let Some(j) = next {
                let Some(ancestor) = bodies.get(j) else { break };
                for r in body.drive.terms() {
                    for c in ancestor.drive.terms() {
                        if let Some(x) = pattern.get_mut(r.coordinate).and_then(|row| row.get_mut(c.coordinate)) {
                            *x = true;
                        }
                        if let Some(x) = pattern.get_mut(c.coordinate).and_then(|row| row.get_mut(r.coordinate)) {
                            *x = true;
                        }
                    }
                }
                next = ancestor.parent.map(|p| p.0).filter(|p| *p < j);
            }
        }
        let mut parents = [None; N];
        for k in (0..N).rev() {
            let Some(row) = pattern.get(k).copied() else { continue };
            let parent = row.iter().take(k).rposition(|x| *x);
            if let Some(p) = parent {
                for (j, _) in row.iter().enumerate().take(k).filter(|(_, x)| **x) {
                    if let Some(x) = pattern.get_mut(p).and_then(|r| r.get_mut(j)) {
                        *x = true;
                    }
                    if let Some(x) = pattern.get_mut(j).and_then(|r| r.get_mut(p)) {
                        *x = true;
                    }
                }
            }
            if let Some(slot) = parents.get_mut(k) {
                *slot = parent;
            }
        }
        Self { parents, factor: SMatrix::zeros() }
    }

    /// The elimination-tree parents `λ(k)`.
    pub fn parents(&self) -> &[Option<usize>; N] {
        &self.parents
    }

    /// The factor `L` of the last successful [`Self::factorize`] (`M = Lᵀ L`).
    pub fn factor(&self) -> &SMatrix<T, N, N> {
        &self.factor
    }

    /// Factorizes `m` (symmetric; only the lower triangle on the ancestor chains is read) as
    /// `M = Lᵀ L` (Featherstone's LTL algorithm, Table 6.3): for `k = N − 1, …, 0`,
    /// `L_kk = √H_kk`, `L_ki = H_ki / L_kk` for `i` on the chain of `k`, then
    /// `H_ij −= L_ki L_kj` for `i`, `j` on that chain (`j` an ancestor of `i` or `i`).
    ///
    /// Errors: [`DynamicsError::MassMatrixNotPositiveDefinite`] if a pivot is not positive
    /// (or NaN); the previous factor is kept then.
    pub fn factorize(&mut self, m: &SMatrix<T, N, N>) -> Result<(), DynamicsError> {
        let mut h = SMatrix::<T, N, N>::zeros();
        let parents = &self.parents;
        let chain = |k: usize| chain(parents, k);
        // Copy the pattern part of the lower triangle: (k, j) for j = k and j on the chain of k.
        {
            let (src, dst) = (m.as_slice(), h.as_mut_slice());
            for k in 0..N {
                let mut next = Some(k);
                while let Some(j) = next {
                    let idx = j * N + k;
                    if let (Some(d), Some(s)) = (dst.get_mut(idx), src.get(idx)) {
                        *d = *s;
                    }
                    next = chain(j);
                }
            }
        }
        let hs = h.as_mut_slice();
        for k in (0..N).rev() {
            let diag = hs.get(k * N + k).copied().unwrap_or_else(T::zero);
            if diag <= T::zero() || !diag.is_finite() {
                return Err(DynamicsError::MassMatrixNotPositiveDefinite);
            }
            let l_kk = diag.sqrt();
            if let Some(d) = hs.get_mut(k * N + k) {
                *d = l_kk;
            }
            let mut next = chain(k);
            while let Some(i) = next {
                if let Some(x) = hs.get_mut(i * N + k) {
                    *x /= l_kk;
                }
                next = chain(i);
            }
            let mut next_i = chain(k);
            while let Some(i) = next_i {
                let l_ki = hs.get(i * N + k).copied().unwrap_or_else(T::zero);
                let mut next_j = Some(i);
                while let Some(j) = next_j {
                    let l_kj = hs.get(j * N + k).copied().unwrap_or_else(T::zero);
                    if let Some(x) = hs.get_mut(j * N + i) {
                        *x -= l_ki * l_kj;
                    }
                    next_j = chain(j);
                }
                next_i = chain(i);
            }
        }
        self.factor = h;
        Ok(())
    }

    /// Solves `M x = b` in place (`x` holds `b` on entry) with the last factor:
    /// `Lᵀ y = b` (from the last coordinate up), then `L x = y` (from the first down), each
    /// along the ancestor chains only.
    pub fn solve_mut(&self, x: &mut SVector<T, N>) {
        let l = self.factor.as_slice();
        let parents = &self.parents;
        let xs = x.as_mut_slice();
        // Lᵀ y = b: y_k = b_k / L_kk, then b_j −= L_kj y_k for j on the chain of k.
        for k in (0..N).rev() {
            let (Some(&l_kk), Some(&b_k)) = (l.get(k * N + k), xs.get(k)) else { continue };
            let y_k = b_k / l_kk;
            if let Some(x) = xs.get_mut(k) {
                *x = y_k;
            }
            let mut next = chain(parents, k);
            while let Some(j) = next {
                if let (Some(&l_kj), Some(x)) = (l.get(j * N + k), xs.get_mut(j)) {
                    *x -= l_kj * y_k;
                }
                next = chain(parents, j);
            }
        }
        // L x = y: x_k = (y_k − Σ_j L_kj x_j) / L_kk over the chain of k.
        for k in 0..N {
            let mut sum = xs.get(k).copied().unwrap_or_else(T::zero);
            let mut next = chain(parents, k);
            while let Some(j) = next {
                if let (Some(&l_kj), Some(&x_j)) = (l.get(j * N + k), xs.get(j)) {
                    sum -= l_kj * x_j;
                }
                next = chain(parents, j);
            }
            if let (Some(&l_kk), Some(x)) = (l.get(k * N + k), xs.get_mut(k)) {
                *x = sum / l_kk;
            }
        }
    }
}

/// `λ(k)`, guarded to be `< k` (so every chain walk terminates).
#[inline]
fn chain<const N: usize>(parents: &[Option<usize>; N], k: usize) -> Option<usize> {
    parents.get(k).copied().flatten().filter(|p| *p < k)
}

#[cfg(test)]
mod tests {
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
        let l = tree.factor().map(|e| nalgebra::try_convert::<T, f64>(e).unwrap());
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
        Ok(())
    }

    proptest! {
        /// f64 and f32: `LᵀL = M` and the tree solve equals the dense Cholesky solve.
        #[test]
        fn tree_factorization_matches_dense_cholesky(seed in any::<u64>()) {
            check::<f64>(seed, 1e-13)?;
            check::<f32>(seed, 1e-5)?;
        }
    }

    #[test]
    fn branched_model_has_two_chains_and_rejects_indefinite() {
        let model = branched::<f64>();
        let tree = TreeFactorization::<f64, N>::new(&model);
        // Trunk 0 (base) – 1 (yaw); branch 2 – 3 (pitch, elbow and the joint coupled to both);
        // branch 4 – 5 (prismatic, wrist) hangs from the yaw, not from the other branch.
        assert_eq!(tree.parents(), &[None, Some(0), Some(1), Some(2), Some(1), Some(4)]);
        let mut t = tree.clone();
        let mut m = SMatrix::<f64, N, N>::identity();
        m[(2, 2)] = -1.0;
        assert_eq!(t.factorize(&m), Err(DynamicsError::MassMatrixNotPositiveDefinite));
    }
}
