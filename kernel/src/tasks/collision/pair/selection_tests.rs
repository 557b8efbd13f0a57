//! The selection a field shares with the later fields of its cycle through the
//! [`PairRowCache`], against each field's own selection with a fresh cache and against a sort.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
use super::tests::{collision_model, P};
use super::*;
use crate::dynamics::{crba, forward_kinematics, TreeFactorization};
use crate::model::Data;
use crate::tasks::collision::CollisionData;
use crate::tasks::{TaskRow, TaskRows};
use crate::test_models::{branched, state, N};
use nalgebra::{convert, RealField};

/// Fields with emit distances below, at and above each other's, `K` free rows: the rows and
/// report of every field evaluated after another one on a shared cache equal (to the bit) those
/// of the field alone, and its rows are those of the `K` smallest `(distance, pair index)` of
/// its candidates; distances rounded to 5 cm make ties at the selection's boundary.
fn shared_selection_matches_own<T: RealField + Copy, const K: usize>() {
    let robot = branched::<T>();
    let cm = collision_model(&robot);
    let mut cd = CollisionData::new(&cm);
    let mut data = Data::new(&robot);
    let field = |emit: f64| {
        CollisionParameters::try_new(convert(25.0), convert(1.0), convert(0.7), convert(0.0), convert(emit)).unwrap()
    };
    let fields = [field(0.3), field(0.6), field(0.45), field(1.2)];
    let (mut shared_selections, mut ties) = (0, 0);
    for seed in 0..60 {
        let (q, v) = (state(seed, 1.5).cast::<T>(), state(seed + 900, 1.0).cast::<T>());
        forward_kinematics(&robot, &mut data, &q, &v).unwrap();
        crba(&robot, &mut data);
        let mut tree = TreeFactorization::new(&robot);
        tree.factorize(&data.mass_matrix).unwrap();
        cm.update(&data, &mut cd);
        if seed % 2 == 1 {
            for x in cd.proximities.iter_mut() {
                let rounded = (nalgebra::try_convert::<T, f64>(x.distance).unwrap() * 20.0).round() / 20.0;
                x.distance = convert(rounded);
            }
        }
        for order in [[0, 1, 2, 3], [3, 2, 1, 0], [1, 0, 3, 2]] {
            let mut cache = PairRowCache::<T, N, P, P>::default();
            for (position, &f) in order.iter().enumerate() {
                let p = &fields[f];
                let shared = cache.selection.is_some_and(|s| s.count == K);
                let mut rows = TaskRows::<T, N, K>::new();
                let report = collision_rows_shared(&cm, &cd, &robot, &data, &tree, p, &mut cache, &mut rows).unwrap();
                let mut own_rows = TaskRows::<T, N, K>::new();
                let own = collision_rows_from_geometry(&cm, &cd, &robot, &data, &tree, p, &mut own_rows).unwrap();
                assert_eq!(report, own, "seed {seed} order {order:?} field {f}");
                assert_eq!(rows, own_rows, "seed {seed} order {order:?} field {f}");
                // Against a sort by (distance, pair index).
                let mut candidates: std::vec::Vec<(T, usize)> = cd
                    .proximities
                    .iter()
                    .take(cm.pairs().len())
                    .enumerate()
                    .filter(|(_, x)| x.distance < p.emit_distance() && x.direction.is_some())
                    .map(|(i, x)| (x.distance, i))
                    .collect();
                candidates.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap().then(a.1.cmp(&b.1)));
                let mut closest: std::vec::Vec<usize> = candidates.iter().take(K).map(|c| c.1).collect();
                closest.sort_unstable();
                let mut fresh = PairRowCache::<T, N, P, P>::default();
                let expected: std::vec::Vec<TaskRow<T, N>> = closest
                    .iter()
                    .map(|&pair| {
                        super::rows::pair_row(
                            &cm,
                            &cd,
                            &robot,
                            &data,
                            &super::kinematics::PairFactor::Tree(&tree),
                            p,
                            pair,
                            &mut fresh,
                        )
                        .unwrap()
                    })
                    .collect();
                assert_eq!(rows.rows(), &expected[..], "seed {seed} order {order:?} field {f}");
                if candidates.len() > K {
                    let boundary = candidates[K - 1].0;
                    ties += usize::from(candidates[K].0 == boundary);
                }
                shared_selections += usize::from(shared && position > 0);
            }
        }
    }
    assert!(shared_selections > 100 && ties > 10, "{shared_selections} shared selections, {ties} ties");
}

#[test]
fn shared_selection_matches_own_f64() {
    shared_selection_matches_own::<f64, 2>();
    shared_selection_matches_own::<f64, 4>();
}

#[test]
fn shared_selection_matches_own_f32() {
    shared_selection_matches_own::<f32, 2>();
    shared_selection_matches_own::<f32, 4>();
}
