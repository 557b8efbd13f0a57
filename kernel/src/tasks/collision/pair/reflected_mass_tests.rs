//! [`TreeFactorization::inverse_reflected_mass`], the reflected masses of the pair rows over
//! the tree factor, against the reference [`TreeFactorization::inverse_reflected_masses`] and
//! the dense inverse.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
use crate::dynamics::{crba, forward_kinematics, TreeFactorization};
use crate::model::Data;
use crate::test_models::{branched, state, N};
use nalgebra::{RealField, SMatrix, SVector};

/// The branched model's inertia `M` at `state(seed)`, factorized, then decoupled for no root,
/// the first root and the first two (the set's rows and columns of `M` cleared to their
/// diagonal): per set, the set, its factor and the dense inverse of its inertia in `f64`.
fn decoupled_factors<T: RealField + Copy>(
    seed: u64,
) -> [(&'static [usize], TreeFactorization<T, N>, SMatrix<f64, N, N>); 3] {
    let model = branched::<T>();
    let mut data = Data::new(&model);
    let q = state(seed, 2.0).map(|e| nalgebra::convert::<f64, T>(e));
    forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
    let m = *crba(&model, &mut data);
    let mut plain = TreeFactorization::new(&model);
    plain.factorize(&m).unwrap();
    [&[][..], &[0][..], &[0, 1][..]].map(|set| {
        let mut tree = plain.clone();
        let mut cleared = m;
        let mut decoupled = [false; N];
        for &c in set {
            decoupled[c] = true;
            let diagonal = cleared[(c, c)];
            cleared.row_mut(c).fill(T::zero());
            cleared.column_mut(c).fill(T::zero());
            cleared[(c, c)] = diagonal;
        }
        tree.decouple(&decoupled, &cleared).unwrap();
        let dense_inverse = cleared.map(|x| nalgebra::try_convert::<T, f64>(x).unwrap()).try_inverse().unwrap();
        (set, tree, dense_inverse)
    })
}

/// The elimination-tree ancestor chain `k, λ(k), λ(λ(k)), …` of `k`.
fn chain<T: RealField + Copy>(tree: &TreeFactorization<T, N>, k: usize) -> std::vec::Vec<usize> {
    let parents = tree.parents();
    let mut chain = vec![k];
    while let Some(p) = parents[*chain.last().unwrap()] {
        chain.push(p);
    }
    chain
}

/// `inverse_reflected_mass` (one row along its support path) against the reference
/// `inverse_reflected_masses` (every column) and the dense `J M⁻¹ Jᵀ`, on the plain factor
/// and on decoupled ones, for rows supported on each coordinate's chain (point Jacobians),
/// on a chain plus decoupled roots, on other supports (the fallback) and for a zero row.
/// The fast path makes the reference's operations in its order here (the roots off the
/// chain precede it), so the two are equal to the bit.
fn check_single_row_masses<T: RealField + Copy>(seed: u64, tol: f64) {
    let to64 = |x: T| nalgebra::try_convert::<T, f64>(x).unwrap();
    let (mut fast_paths, mut fallbacks) = (0, 0);
    for (set, tree, dense_inverse) in decoupled_factors::<T>(seed) {
        let mut rows = std::vec::Vec::new();
        for leaf in 0..N {
            let chain = chain(&tree, leaf);
            let values = state(seed ^ (leaf as u64 + 101), 1.0);
            let mut on_chain = [T::zero(); N];
            for &a in &chain {
                on_chain[a] = nalgebra::convert(values[a]);
            }
            let mut with_roots = on_chain;
            for &c in set {
                with_roots[c] = nalgebra::convert(0.5 + values[c]);
            }
            rows.push(on_chain);
            rows.push(with_roots);
        }
        rows.push(core::array::from_fn(|c| nalgebra::convert(state(seed ^ 7, 1.0)[c])));
        let mut two_branches = [T::zero(); N];
        two_branches[3] = T::one();
        two_branches[5] = nalgebra::convert(-0.7);
        rows.push(two_branches);
        rows.push([T::zero(); N]);
        for row in &rows {
            let fast = tree.inverse_reflected_mass(row);
            let [reference] = tree.inverse_reflected_masses([row]);
            assert_eq!(fast, reference, "set {set:?} row {row:?}");
            let j = SVector::<f64, N>::from_fn(|c, _| to64(row[c]));
            let dense = (j.transpose() * dense_inverse * j).x;
            assert!((to64(fast) - dense).abs() <= tol * (1.0 + dense.abs()), "set {set:?}: {} vs {dense}", to64(fast));
            let leaf = row.iter().rposition(|x| !x.is_zero());
            let chain = leaf.map_or(std::vec::Vec::new(), |l| chain(&tree, l));
            let off_chain = (0..N).filter(|c| !row[*c].is_zero() && !chain.contains(c));
            if off_chain.clone().all(|c| tree.parents()[c].is_none()) {
                fast_paths += 1;
            } else {
                fallbacks += 1;
            }
        }
    }
    assert!(fast_paths > 30 && fallbacks >= 2, "{fast_paths} fast, {fallbacks} fallbacks");
}

#[test]
fn single_row_reflected_masses_match_the_reference() {
    for seed in 0..20 {
        check_single_row_masses::<f64>(seed, 1e-10);
        check_single_row_masses::<f32>(seed, 1e-3);
    }
}

/// `inverse_reflected_mass_of_head` (the leaf given) against the reference
/// `inverse_reflected_masses` (every column): to the bit for heads that end at each
/// coordinate, with their whole chain filled, with the leaf's own entry zero, with decoupled
/// roots below the chain, with entries off the chain (the fallback) and for an empty head, on
/// the plain factor and on decoupled ones; and against the dense `J M⁻¹ Jᵀ`.
fn check_head_masses<T: RealField + Copy>(seed: u64, tol: f64) {
    let to64 = |x: T| nalgebra::try_convert::<T, f64>(x).unwrap();
    let mut compared = 0;
    for (set, tree, dense_inverse) in decoupled_factors::<T>(seed) {
        for leaf in 0..N {
            let values = state(seed ^ (leaf as u64 + 211), 1.0);
            let mut on_chain = [T::zero(); N];
            for &a in &chain(&tree, leaf) {
                on_chain[a] = nalgebra::convert(values[a]);
            }
            let mut with_roots = on_chain;
            for &c in set {
                with_roots[c] = nalgebra::convert(0.5 + values[c]);
            }
            let mut zero_leaf = with_roots;
            zero_leaf[leaf] = T::zero();
            let mut off_chain = on_chain;
            for c in 0..=leaf {
                off_chain[c] = nalgebra::convert(0.25 + values[c]);
            }
            for row in [on_chain, with_roots, zero_leaf, off_chain] {
                // The head ends at the leaf or at a decoupled root after it.
                let end = row.iter().rposition(|x| !x.is_zero()).map_or(0, |p| p + 1).max(leaf + 1);
                let fast = tree.inverse_reflected_mass_of_head(&row[..end]);
                let [reference] = tree.inverse_reflected_masses([&row]);
                assert_eq!(fast, reference, "set {set:?} leaf {leaf} row {row:?}");
                let j = SVector::<f64, N>::from_fn(|c, _| to64(row[c]));
                let dense = (j.transpose() * dense_inverse * j).x;
                assert!((to64(fast) - dense).abs() <= tol * (1.0 + dense.abs()), "{} vs {dense}", to64(fast));
                compared += 1;
            }
        }
        assert_eq!(tree.inverse_reflected_mass_of_head(&[]), T::zero());
    }
    assert_eq!(compared, 3 * 4 * N);
}

#[test]
fn head_reflected_masses_match_the_reference() {
    for seed in 0..20 {
        check_head_masses::<f64>(seed, 1e-10);
        check_head_masses::<f32>(seed, 1e-3);
    }
}

/// `substitute_head` (the chain substitution with its solution `x = J L⁻¹`): the same bits as
/// `inverse_reflected_mass_of_head` where it succeeds, `None` exactly for the heads with
/// entries off the chain and its roots; and for every two solved heads `J₁`, `J₂` the
/// difference of their solutions gives the dense `(J₂ − J₁) M⁻¹ (J₂ − J₁)ᵀ` (the metric of a
/// pair row): heads on the same chain, on chains with shared ancestors and on disjoint ones
/// (decoupled roots), with and without roots, on the plain and on decoupled factors.
fn check_head_solutions<T: RealField + Copy>(seed: u64, tol: f64) {
    let to64 = |x: T| nalgebra::try_convert::<T, f64>(x).unwrap();
    let (mut solved_pairs, mut disjoint_pairs, mut refused) = (0, 0, 0);
    for (set, tree, dense_inverse) in decoupled_factors::<T>(seed) {
        // (head, solution) of every solved head.
        let mut solved: std::vec::Vec<([T; N], usize, [f64; N])> = std::vec::Vec::new();
        for leaf in 0..N {
            let values = state(seed ^ (leaf as u64 + 307), 1.0);
            let mut on_chain = [T::zero(); N];
            for &a in &chain(&tree, leaf) {
                on_chain[a] = nalgebra::convert(values[a]);
            }
            let mut with_roots = on_chain;
            for &c in set {
                with_roots[c] = nalgebra::convert(0.5 + values[c]);
            }
            let mut off_chain = on_chain;
            for c in 0..=leaf {
                off_chain[c] = nalgebra::convert(0.25 + values[c]);
            }
            for row in [on_chain, with_roots, off_chain] {
                let end = row.iter().rposition(|x| !x.is_zero()).map_or(0, |p| p + 1).max(leaf + 1);
                let mut x = [0.0; N];
                // A work buffer with stale content: its content on entry does not matter.
                let mut work = [nalgebra::convert::<f64, T>(7.5); N];
                let norm = tree.substitute_head(&row[..end], &mut work, |k, value| x[k] = to64(value));
                // The chain of the head's last coordinate and the roots below the chain's root.
                let path = chain(&tree, end - 1);
                let root = *path.last().unwrap();
                let on_support =
                    (0..N).all(|c| row[c].is_zero() || path.contains(&c) || tree.parents()[c].is_none() && c < root);
                match norm {
                    Some(norm) => {
                        assert!(on_support, "set {set:?} leaf {leaf}: solved a head off its chain");
                        assert_eq!(norm, tree.inverse_reflected_mass_of_head(&row[..end]));
                        let squared: f64 = x.iter().map(|v| v * v).sum();
                        assert!((squared - to64(norm)).abs() <= tol * (1.0 + squared));
                        solved.push((row, end, x));
                    }
                    None => {
                        assert!(!on_support, "set {set:?} leaf {leaf}: refused a head on its chain");
                        refused += 1;
                    }
                }
            }
        }
        for (first, end_first, x_first) in &solved {
            for (second, end_second, x_second) in &solved {
                let j = SVector::<f64, N>::from_fn(|c, _| to64(second[c]) - to64(first[c]));
                let dense = (j.transpose() * dense_inverse * j).x;
                let metric: f64 = x_first.iter().zip(x_second).map(|(a, b)| (b - a) * (b - a)).sum();
                let scale = 1.0
                    + to64(tree.inverse_reflected_mass_of_head(&first[..*end_first]))
                    + to64(tree.inverse_reflected_mass_of_head(&second[..*end_second]));
                assert!((metric - dense).abs() <= tol * scale, "set {set:?}: {metric} vs {dense}");
                solved_pairs += 1;
                let overlap = (0..N).any(|c| !first[c].is_zero() && !second[c].is_zero());
                disjoint_pairs += usize::from(!overlap);
            }
        }
    }
    assert!(solved_pairs > 500 && disjoint_pairs > 50 && refused > 5, "{solved_pairs} {disjoint_pairs} {refused}");
}

#[test]
fn head_solutions_give_the_pair_metric() {
    for seed in 0..10 {
        check_head_solutions::<f64>(seed, 1e-10);
        check_head_solutions::<f32>(seed, 1e-3);
    }
}
