//! Copying a [`TreeFactorization`] into another one on the same chains: only what the factor's
//! methods read, so that a step can keep its factors in place instead of cloning them.

use nalgebra::RealField;

use super::tree_factorization::TreeFactorization;

impl<T: RealField + Copy, const N: usize> TreeFactorization<T, N> {
    /// `self ← source` for two factors built on the same ancestor chains (one
    /// [`super::TreeStructure`], e.g. the two factors a controller keeps between cycles; the
    /// chains are not compared): the depths, the reciprocal pivots and each packed row up to
    /// its depth are copied, which is all the factor's methods read (a packed row of `L` only
    /// up to the depth of its coordinate). Self's chains are kept. Cost O(Σ depth).
    pub(crate) fn assign(&mut self, source: &Self) {
        self.structure.depth = source.structure.depth;
        self.reciprocal = source.reciprocal;
        for ((target, packed), depth) in
            self.rows.data.0.iter_mut().zip(source.rows.data.0.iter()).zip(source.structure.depth.iter())
        {
            for (t, p) in target.iter_mut().zip(packed.iter()).take(usize::from(*depth) + 1) {
                *t = *p;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::dynamics::{crba, forward_kinematics};
    use crate::model::Data;
    use crate::test_models::{branched, state, N};
    use nalgebra::{SMatrix, SVector};
    use proptest::prelude::*;

    proptest! {
        /// A factor assigned over a stale (decoupled, other state) one reads like the source:
        /// the same `L`, inverse and solves, bit for bit; also after decoupling both alike.
        #[test]
        fn assigned_factor_reads_like_its_source(seed in any::<u64>()) {
            let model = branched::<f64>();
            let mut data = Data::new(&model);
            forward_kinematics(&model, &mut data, &state(seed, 2.0), &SVector::zeros()).unwrap();
            let m = *crba(&model, &mut data);
            let mut source = TreeFactorization::new(&model);
            source.factorize(&m).unwrap();
            forward_kinematics(&model, &mut data, &state(seed ^ 77, 2.0), &SVector::zeros()).unwrap();
            let stale_m = *crba(&model, &mut data);
            let mut target = TreeFactorization::new(&model);
            target.factorize(&stale_m).unwrap();
            let mut decoupled = [false; N];
            decoupled[0] = true;
            target.decouple(&decoupled, &stale_m).unwrap();
            target.assign(&source);
            prop_assert_eq!(target.lower(), source.lower());
            prop_assert_eq!(target.inverse(), source.inverse());
            let b = state(seed ^ 5, 3.0);
            let (mut x, mut y) = (b, b);
            target.solve_mut(&mut x);
            source.solve_mut(&mut y);
            prop_assert_eq!(x, y);
            let row = SMatrix::<f64, 1, N>::from_row_slice(b.as_slice());
            let (mut r, mut s) = (row, row);
            target.right_solve_mut(&mut r);
            source.right_solve_mut(&mut s);
            prop_assert_eq!(r, s);
            let mut closed = m;
            for k in 1..N {
                closed[(0, k)] = 0.0;
                closed[(k, 0)] = 0.0;
            }
            target.decouple(&decoupled, &closed).unwrap();
            source.decouple(&decoupled, &closed).unwrap();
            prop_assert_eq!(target.lower(), source.lower());
            prop_assert_eq!(target.inverse(), source.inverse());
        }
    }
}
