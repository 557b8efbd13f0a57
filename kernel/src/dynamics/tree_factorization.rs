//! Tree-sparse `Lᵀ L` factorization of the joint-space inertia matrix (Featherstone,
//! *Rigid Body Dynamics Algorithms*, Sec. 6.5, "branch-induced sparsity").
//!
//! `M_ij` vanishes unless the joints of coordinates `i` and `j` lie on one path to the root.
//! Eliminating the coordinates from the last to the first, `M = Lᵀ L` with `L` lower triangular
//! creates no fill-in outside that pattern when the coordinate parents `λ(k) < k` describe the
//! tree; the factorization then costs O(Σ_k depth_k²) instead of O(N³/3), and each solve
//! O(Σ_k depth_k) instead of O(N²).

use nalgebra::{Cholesky, Const, RealField, SMatrix, SVector};

use super::error::DynamicsError;
use super::tree_kernels::{combine_ancestor_columns, eliminate};
use crate::math::sqrt;
use crate::model::Model;

mod reflected_mass;

/// The symbolic part of [`TreeFactorization`]: for every coordinate `k` its ancestor chain
/// `k, λ(k), λ(λ(k)), …` in the elimination tree. Depends on the model only.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TreeStructure<const N: usize> {
    /// `chains[k][d]`: the `d`-th ancestor of `k` (`chains[k][0] = k`) for `d ≤ depth[k]`.
    pub(super) chains: [[u16; N]; N],
    /// Number of ancestors of `k`.
    pub(super) depth: [u16; N],
}

impl<const N: usize> TreeStructure<N> {
    /// Symbolic analysis of `model`: the pattern of `M` (coordinates `r`, `c` coupled when a
    /// joint driven by `r` and a joint driven by `c` lie on one path to the root, through the
    /// drive terms), then the elimination tree for eliminating `N − 1, …, 0`:
    /// `λ(k) = max {j < k : (k, j) in the pattern}`, and the rest of row `k` joins row `λ(k)`
    /// (the fill of eliminating `k`). For an unbranched chain of single-term drives this is
    /// `λ(k) = k − 1`; Justin's two arms get disjoint chains that meet at the torso.
    pub fn new<T: RealField + Copy, const B: usize, const F: usize>(model: &Model<T, N, B, F>) -> Self {
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
        let mut chains = [[0_u16; N]; N];
        let mut depth = [0_u16; N];
        for (k, (chain, d)) in chains.iter_mut().zip(depth.iter_mut()).enumerate() {
            let mut next = Some(k);
            let mut count = 0_u16;
            for slot in chain.iter_mut() {
                let Some(j) = next else { break };
                *slot = u16::try_from(j).unwrap_or(0);
                count += 1;
                next = parents.get(j).copied().flatten().filter(|p| *p < j);
            }
            *d = count.saturating_sub(1);
        }
        Self { chains, depth }
    }

    /// The elimination-tree parents `λ(k)`.
    pub fn parents(&self) -> [Option<usize>; N] {
        let mut parents = [None; N];
        for ((p, chain), d) in parents.iter_mut().zip(self.chains.iter()).zip(self.depth.iter()) {
            if *d > 0 {
                *p = chain.get(1).map(|x| usize::from(*x));
            }
        }
        parents
    }

    /// The ancestors `λ(k), λ(λ(k)), …` of `k` (nearest first).
    #[inline]
    fn ancestors(&self, k: usize) -> &[u16] {
        let d = self.depth.get(k).map_or(0, |d| usize::from(*d));
        self.chains.get(k).and_then(|c| c.get(1..=d)).unwrap_or(&[])
    }
}

/// `M = Lᵀ L` over the elimination tree of the model's coordinates.
///
/// Build the [`TreeStructure`] once per model, then [`TreeFactorization::factorize`] each
/// `M(q)`. Row `k` of `L` is stored packed in column `k` of `rows`: `L_kk` first, then
/// `L_{k,a}` for the ancestors `a` of `k` nearest first. As the chain of an ancestor is a
/// suffix of the chain of `k`, every update pairs two packed rows element by element.
#[derive(Clone, Debug)]
pub struct TreeFactorization<T: RealField, const N: usize> {
    pub(super) structure: TreeStructure<N>,
    pub(super) rows: SMatrix<T, N, N>,
    /// `1 / L_kk` of every coordinate: the solves multiply by it.
    pub(super) reciprocal: [T; N],
}

impl<T: RealField + Copy, const N: usize> TreeFactorization<T, N> {
    /// The symbolic analysis of `model` ([`TreeStructure::new`]) with a zero factor.
    pub fn new<const B: usize, const F: usize>(model: &Model<T, N, B, F>) -> Self {
        Self::from_structure(TreeStructure::new(model))
    }

    /// A zero factor over `structure`.
    pub fn from_structure(structure: TreeStructure<N>) -> Self {
        Self { structure, rows: SMatrix::zeros(), reciprocal: [T::zero(); N] }
    }

    /// The symbolic part.
    pub fn structure(&self) -> &TreeStructure<N> {
        &self.structure
    }

    /// The elimination-tree parents `λ(k)`.
    pub fn parents(&self) -> [Option<usize>; N] {
        self.structure.parents()
    }

    /// The factor `L` of the last successful [`Self::factorize`] (`M = Lᵀ L`) as a dense lower
    /// triangular matrix.
    pub fn lower(&self) -> SMatrix<T, N, N> {
        let mut l = SMatrix::<T, N, N>::zeros();
        for (k, packed) in self.rows.as_slice().chunks_exact(N).enumerate() {
            if let (Some(d), Some(x)) = (packed.first(), l.get_mut((k, k))) {
                *x = *d;
            }
            for (a, value) in self.structure.ancestors(k).iter().zip(packed.iter().skip(1)) {
                if let Some(x) = l.get_mut((k, usize::from(*a))) {
                    *x = *value;
                }
            }
        }
        l
    }

    /// Factorizes `m` (symmetric; only the entries `(k, j)`, `j` on the ancestor chain of `k`,
    /// are read) as `M = Lᵀ L` (Featherstone's LTL algorithm, Table 6.3): for
    /// `k = N − 1, …, 0`, `L_kk = √H_kk`, `L_ki = H_ki · (1/L_kk)` for `i` on the chain of `k`
    /// (the reciprocal is kept for the solves), then `H_ij −= L_ki L_kj` for `i`, `j` on that
    /// chain (`j` an ancestor of `i` or `i`). Cost Σ_k depth_k²/2 multiply-adds and N divisions.
    ///
    /// Errors: [`DynamicsError::MassMatrixNotPositiveDefinite`] if a pivot is not positive
    /// (or NaN); the factor is unspecified then.
    pub fn factorize(&mut self, m: &SMatrix<T, N, N>) -> Result<(), DynamicsError> {
        let structure = &self.structure;
        let src = m.as_slice();
        for ((packed, chain), depth) in
            self.rows.as_mut_slice().chunks_exact_mut(N).zip(structure.chains.iter()).zip(structure.depth.iter())
        {
            let length = usize::from(*depth) + 1;
            let k = chain.first().map_or(0, |k| usize::from(*k));
            let column = src.get(k * N..k * N + N).unwrap_or(&[]);
            for (x, a) in packed.iter_mut().zip(chain.iter()).take(length) {
                *x = column.get(usize::from(*a)).copied().unwrap_or_else(T::zero);
            }
        }
        let rows: &mut [[T; N]; N] = &mut self.rows.data.0;
        for k in (0..N).rev() {
            let Some((before, rest)) = rows.split_at_mut_checked(k) else { break };
            let length = structure.depth.get(k).map_or(0, |d| usize::from(*d)) + 1;
            let Some((diagonal, below)) =
                rest.first_mut().and_then(|r| r.get_mut(..length)).and_then(|r| r.split_first_mut())
            else {
                break;
            };
            if *diagonal <= T::zero() || !diagonal.is_finite() {
                return Err(DynamicsError::MassMatrixNotPositiveDefinite);
            }
            let l_kk = sqrt(*diagonal);
            *diagonal = l_kk;
            let inverse = T::one() / l_kk;
            if let Some(r) = self.reciprocal.get_mut(k) {
                *r = inverse;
            }
            for x in below.iter_mut() {
                *x *= inverse;
            }
            eliminate(before, structure.ancestors(k), below);
        }
        Ok(())
    }

    /// Turns the factor of `M` into the factor of `M̃`, the matrix that equals `m` (also `M`
    /// outside the decoupled coordinates) with the rows and columns of the coordinates `c`
    /// with `decoupled[c]` cleared to their diagonal `m_cc` (the closed-loop inertia (5.17) of
    /// the platform coordinates). When every ancestor of a decoupled coordinate is decoupled
    /// (the platform coordinates are the roots of the tree), the elimination of the other
    /// coordinates never reads a decoupled one: their rows of `L` restricted to the other
    /// columns are those of `M`, the decoupled columns are zero and a decoupled row is
    /// `√m_cc`, so no refactorization is needed (same bits as [`Self::factorize`] of `m`).
    /// Otherwise `m` is factorized.
    ///
    /// Errors: [`DynamicsError::MassMatrixNotPositiveDefinite`] as [`Self::factorize`] of `m`.
    pub fn decouple(&mut self, decoupled: &[bool; N], m: &SMatrix<T, N, N>) -> Result<(), DynamicsError> {
        let roots = (0..N).filter(|c| decoupled.get(*c).copied().unwrap_or(false)).all(|c| {
            self.structure.ancestors(c).iter().all(|a| decoupled.get(usize::from(*a)).copied().unwrap_or(false))
        });
        if !roots {
            return self.factorize(m);
        }
        // The decoupled coordinates leave every chain (they are its last entries): their
        // columns of `L` are zero and they become roots.
        let structure = &mut self.structure;
        for (k, ((packed, depth), reciprocal)) in self
            .rows
            .as_mut_slice()
            .chunks_exact_mut(N)
            .zip(structure.depth.iter_mut())
            .zip(self.reciprocal.iter_mut())
            .enumerate()
        {
            let Some((diagonal, below)) = packed.split_first_mut() else { continue };
            if decoupled.get(k).copied().unwrap_or(false) {
                let d = m.get((k, k)).copied().unwrap_or_else(T::zero);
                if d <= T::zero() || !d.is_finite() {
                    return Err(DynamicsError::MassMatrixNotPositiveDefinite);
                }
                *diagonal = sqrt(d);
                *reciprocal = T::one() / *diagonal;
            }
            let chain = structure.chains.get(k).map_or(&[][..], |c| c.get(1..=usize::from(*depth)).unwrap_or(&[]));
            let kept = chain.iter().take_while(|a| !decoupled.get(usize::from(**a)).copied().unwrap_or(false)).count();
            for x in below.iter_mut().skip(kept) {
                *x = T::zero();
            }
            *depth = u16::try_from(kept).unwrap_or(0);
        }
        Ok(())
    }

    /// `(‖J₁ L⁻¹‖², …, ‖J_K L⁻¹‖²) = (J_k M⁻¹ J_kᵀ)_k` for the rows `J_k = rhs[k]`: the inverse
    /// reflected masses (3.20) by the substitution of [`Self::right_solve_mut`] on the `K × N`
    /// stack, each column's squares added to the norms as soon as it is solved.
    pub fn inverse_reflected_masses<const K: usize>(&self, rhs: [&[T; N]; K]) -> [T; K] {
        let mut x = [[T::zero(); K]; N];
        for (c, column) in x.iter_mut().enumerate() {
            for (e, b) in column.iter_mut().zip(rhs.iter()) {
                *e = b.get(c).copied().unwrap_or_else(T::zero);
            }
        }
        let mut norms = [T::zero(); K];
        for ((k, packed), inverse) in self.rows.data.0.iter().enumerate().zip(self.reciprocal.iter()).rev() {
            // The ancestors are all `< k`: solved columns are never touched again.
            let Some((before, rest)) = x.split_at_mut_checked(k) else { break };
            let Some(column) = rest.first_mut() else { break };
            if column.iter().all(|c| *c == T::zero()) {
                continue;
            }
            for (c, n) in column.iter_mut().zip(norms.iter_mut()) {
                *c *= *inverse;
                *n += *c * *c;
            }
            let column = &*column;
            for (a, l_ka) in self.structure.ancestors(k).iter().zip(packed.iter().skip(1)) {
                if let Some(target) = before.get_mut(usize::from(*a)) {
                    for (t, c) in target.iter_mut().zip(column.iter()) {
                        *t -= *l_ka * *c;
                    }
                }
            }
        }
        norms
    }

    /// `J M⁻¹ Jᵀ = ‖J L⁻¹‖²` for one row `J = row`: the inverse reflected mass (3.20) by the
    /// substitution of [`Self::inverse_reflected_masses`] restricted to the row's support. A
    /// point Jacobian is supported on the ancestor chain of its last nonzero coordinate (a path
    /// to the root), plus, in a decoupled factor ([`Self::decouple`]), roots without ancestors
    /// (the platform coordinates of `M̃`). The chain's entries are gathered into a packed
    /// vector, in which the ancestors of each chain coordinate are the entries after it in the
    /// order of its packed row of `L`: each column's update pairs two contiguous slices. The
    /// roots below the chain are solved alone. Same operations in the same order as
    /// [`Self::inverse_reflected_masses`]; a row with any other support (a nonzero entry
    /// between two chain coordinates or below the chain on a coordinate with ancestors) is
    /// passed to it. Cost: depth²/2 multiply-adds and one pass over the row.
    pub fn inverse_reflected_mass(&self, row: &[T; N]) -> T {
        let Some(leaf) = row.iter().rposition(|x| !x.is_zero()) else {
            return T::zero();
        };
        let depth = self.structure.depth.get(leaf).map_or(0, |d| usize::from(*d));
        let chain = self.structure.chains.get(leaf).and_then(|c| c.get(..=depth)).unwrap_or(&[]);
        // The chain entries, leaf first; a nonzero entry between two chain coordinates is off
        // the chain (`other`).
        let mut storage = [T::zero(); N];
        let packed = storage.get_mut(..chain.len()).unwrap_or(&mut []);
        let mut other = false;
        let mut above = leaf + 1;
        for (y, a) in packed.iter_mut().zip(chain.iter()) {
            let a = usize::from(*a);
            if let Some((value, gap)) = row.get(a..above).and_then(|s| s.split_first()) {
                *y = *value;
                other |= gap.iter().any(|x| !x.is_zero());
            }
            above = a;
        }
        let mut norm = T::zero();
        let mut tail = packed;
        for k in chain {
            let Some((y, ancestors)) = tail.split_first_mut() else { break };
            let k = usize::from(*k);
            let (Some(l), Some(inverse)) = (self.rows.data.0.get(k), self.reciprocal.get(k)) else { break };
            let x = *y * *inverse;
            norm += x * x;
            // The chain of `k` is the rest of the leaf's chain: its packed row pairs entry by entry.
            // Short loops: two exits instead of `zip` (whose common trip count invites an
            // unrolled body and a remainder dispatch that cost more than the few updates).
            let mut l = l.get(1..).unwrap_or(&[]).iter();
            for t in ancestors.iter_mut() {
                let Some(l_ka) = l.next() else { break };
                *t -= *l_ka * x;
            }
            tail = ancestors;
        }
        // Below the chain's root: roots are solved alone (from the last coordinate down).
        if let (Some(x), Some(d), Some(r)) =
            (row.get(..above), self.structure.depth.get(..above), self.reciprocal.get(..above))
        {
            for ((x, d), inverse) in x.iter().zip(d).zip(r).rev() {
                if !x.is_zero() {
                    other |= *d != 0;
                    let y = *x * *inverse;
                    norm += y * y;
                }
            }
        }
        if other {
            let [w] = self.inverse_reflected_masses([row]);
            return w;
        }
        norm
    }

    /// `X ← X L⁻¹` in place for the `R × N` matrix `X` (`X L = B` by columns from the last
    /// coordinate down). With `M = Lᵀ L`, `(J L⁻¹)(J L⁻¹)ᵀ = J M⁻¹ Jᵀ`, and `J L⁻¹` keeps the
    /// column support of `J` closed under ancestors (a Jacobian's support path): columns that
    /// are zero cost nothing.
    pub fn right_solve_mut<const R: usize>(&self, x: &mut SMatrix<T, R, N>) {
        let columns: &mut [[T; R]; N] = &mut x.data.0;
        for ((k, packed), inverse) in self.rows.data.0.iter().enumerate().zip(self.reciprocal.iter()).rev() {
            let Some(column) = columns.get_mut(k) else { break };
            if column.iter().all(|c| *c == T::zero()) {
                continue;
            }
            for c in column.iter_mut() {
                *c *= *inverse;
            }
            let column = *column;
            // The ancestors are all `< k`: solved columns are never touched again.
            for (a, l_ka) in self.structure.ancestors(k).iter().zip(packed.iter().skip(1)) {
                if let Some(target) = columns.get_mut(usize::from(*a)) {
                    for (t, c) in target.iter_mut().zip(column.iter()) {
                        *t -= *l_ka * *c;
                    }
                }
            }
        }
    }

    /// `M⁻¹ = L⁻¹ L⁻ᵀ` as a dense symmetric matrix, column by column from the first
    /// coordinate: with `Z = L⁻¹`, `L Z = I` gives `z_i = (e_i − Σ_a L_ia z_a) / L_ii` over the
    /// ancestors `a` of `i` (rows of `Z`), so for `j < i`
    /// `(M⁻¹)_ij = z_i · z_j = −(Σ_a L_ia (M⁻¹)_aj) / L_ii` (as `Z_ji = 0`) and
    /// `(M⁻¹)_ii = (1/L_ii − Σ_a L_ia (M⁻¹)_ai) / L_ii`: each column is a combination of the
    /// (already complete, by symmetry) columns of its ancestors. The entries above the diagonal
    /// are summed four rows at a time over the ancestors in registers
    /// (`combine_ancestor_columns`). Cost Σ_i i·depth_i multiply-adds, below the dense
    /// `N³/2`.
    pub fn inverse(&self) -> SMatrix<T, N, N> {
        let mut w = SMatrix::<T, N, N>::zeros();
        self.inverse_into(&mut w);
        w
    }

    /// [`Self::inverse`] written into `w` (every entry is overwritten; no temporary, no
    /// zero fill).
    pub fn inverse_into(&self, w: &mut SMatrix<T, N, N>) {
        let columns: &mut [[T; N]; N] = &mut w.data.0;
        for ((i, packed), &inverse) in self.rows.data.0.iter().enumerate().zip(self.reciprocal.iter()) {
            let Some((before, rest)) = columns.split_at_mut_checked(i) else { break };
            let (Some(column), Some(below)) = (rest.first_mut(), packed.get(1..)) else { break };
            let Some((head, tail)) = column.split_at_mut_checked(i) else { break };
            let ancestors = self.structure.ancestors(i);
            combine_ancestor_columns(head, before, ancestors, below, -inverse);
            let head = &*head;
            let sum = ancestors
                .iter()
                .zip(below.iter())
                .fold(T::zero(), |s, (a, l_ia)| s + *l_ia * head.get(usize::from(*a)).copied().unwrap_or_else(T::zero));
            if let Some(d) = tail.first_mut() {
                *d = (inverse - sum) * inverse;
            }
            // Symmetry: row i of the earlier columns.
            for (w_j, x) in before.iter_mut().zip(head.iter()) {
                if let Some(y) = w_j.get_mut(i) {
                    *y = *x;
                }
            }
        }
    }

    /// Solves `M x = b` in place (`x` holds `b` on entry) with the last factor:
    /// `Lᵀ y = b` (from the last coordinate up), then `L x = y` (from the first down), each
    /// along the ancestor chains only.
    pub fn solve_mut(&self, x: &mut SVector<T, N>) {
        let rows = self.rows.as_slice();
        let xs = x.as_mut_slice();
        // Lᵀ y = b: y_k = b_k / L_kk, then b_j −= L_kj y_k for j on the chain of k.
        for (k, packed) in rows.chunks_exact(N).enumerate().rev() {
            let (Some((l_kk, below)), Some(b_k)) = (packed.split_first(), xs.get_mut(k)) else { continue };
            let y_k = *b_k / *l_kk;
            *b_k = y_k;
            if y_k == T::zero() {
                continue;
            }
            for (a, l_kj) in self.structure.ancestors(k).iter().zip(below.iter()) {
                if let Some(x) = xs.get_mut(usize::from(*a)) {
                    *x -= *l_kj * y_k;
                }
            }
        }
        // L x = y: x_k = (y_k − Σ_j L_kj x_j) / L_kk over the chain of k.
        for (k, packed) in rows.chunks_exact(N).enumerate() {
            let Some((l_kk, below)) = packed.split_first() else { continue };
            let mut sum = xs.get(k).copied().unwrap_or_else(T::zero);
            for (a, l_kj) in self.structure.ancestors(k).iter().zip(below.iter()) {
                sum -= *l_kj * xs.get(usize::from(*a)).copied().unwrap_or_else(T::zero);
            }
            if let Some(x) = xs.get_mut(k) {
                *x = sum / *l_kk;
            }
        }
    }
}

/// A factor of the (closed-loop) inertia that consumers read `M⁻¹` from: the dense
/// `M = L Lᵀ` (nalgebra's Cholesky) or the tree-sparse `M = Lᵀ L`.
#[derive(Clone, Copy, Debug)]
pub enum InertiaFactor<'a, T: RealField, const N: usize> {
    /// Dense `M = L Lᵀ`.
    Dense(&'a Cholesky<T, Const<N>>),
    /// Tree-sparse `M = Lᵀ L` ([`TreeFactorization`]).
    Tree(&'a TreeFactorization<T, N>),
}

impl<'a, T: RealField, const N: usize> From<&'a Cholesky<T, Const<N>>> for InertiaFactor<'a, T, N> {
    fn from(factor: &'a Cholesky<T, Const<N>>) -> Self {
        Self::Dense(factor)
    }
}

impl<'a, T: RealField, const N: usize> From<&'a TreeFactorization<T, N>> for InertiaFactor<'a, T, N> {
    fn from(factor: &'a TreeFactorization<T, N>) -> Self {
        Self::Tree(factor)
    }
}

#[cfg(test)]
mod tests;
