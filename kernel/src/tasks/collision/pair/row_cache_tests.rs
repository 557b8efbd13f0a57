//! The pair rows of a call share one support table, the buffers of `pair_kinematics` and the
//! [`PairRowCache`] (entries written in place, the distance rate cached with them, a spare
//! buffer when the cache is full): against each pair evaluated alone with fresh buffers and a
//! fresh cache, and against the reference [`evaluate_pair`].
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
use super::kinematics::{factor_rows, PairFactor};
use super::rows::pair_row;
use super::tests::{collision_model, P};
use super::*;
use crate::dynamics::{crba, forward_kinematics, mass_matrix_cholesky, TreeFactorization};
use crate::model::Data;
use crate::tasks::collision::CollisionData;
use crate::tasks::{TaskRow, TaskRows};
use crate::test_models::{branched, state, N};
use nalgebra::{convert, RealField};

fn field<T: RealField + Copy>(force: f64, emit: f64, ratio: f64) -> CollisionParameters<T> {
    CollisionParameters::try_new(convert(force), convert(emit), convert(ratio), convert(0.0), convert(emit)).unwrap()
}

/// Two fields in a row on one cache with room for `C` pairs (`C = 2`: most pairs go through
/// the spare buffer), over the dense factor rows and the tree factor: every row of both fields
/// equals, to the bit, the row of its pair evaluated alone (fresh buffers, fresh cache), the
/// carried `j M⁻¹ jᵀ` equals that of the field evaluated alone, and the rows agree with the
/// reference [`evaluate_pair`] to `tolerance` (relative to the largest Jacobian entry).
fn shared_rows_equal_rows_alone<T: RealField + Copy, const C: usize>(tolerance: f64) {
    let robot = branched::<T>();
    let cm = collision_model(&robot);
    let mut cd = CollisionData::new(&cm);
    let mut data = Data::new(&robot);
    let fields = [field::<T>(150.0, 0.6, 1.0), field::<T>(25.0, 1.2, 0.7)];
    let (mut rows_compared, mut from_cache) = (0, 0);
    for seed in 0..80 {
        let (q, v) = (state(seed, 1.5).cast::<T>(), state(seed + 300, 1.0).cast::<T>());
        forward_kinematics(&robot, &mut data, &q, &v).unwrap();
        crba(&robot, &mut data);
        let dense = mass_matrix_cholesky(&data).unwrap();
        let mut tree = TreeFactorization::new(&robot);
        tree.factorize(&data.mass_matrix).unwrap();
        cm.update(&data, &mut cd);
        for use_tree in [false, true] {
            let factor = if use_tree { PairFactor::Tree(&tree) } else { PairFactor::Rows(factor_rows(&dense)) };
            let mut cache = PairRowCache::<T, N, P, C>::default();
            for (position, p) in fields.iter().enumerate() {
                let mut rows = TaskRows::<T, N, P>::new();
                let report = if use_tree {
                    collision_rows_shared(&cm, &cd, &robot, &data, &tree, p, &mut cache, &mut rows).unwrap()
                } else {
                    collision_rows_shared(&cm, &cd, &robot, &data, &dense, p, &mut cache, &mut rows).unwrap()
                };
                let mut alone = TaskRows::<T, N, P>::new();
                if use_tree {
                    collision_rows_from_geometry(&cm, &cd, &robot, &data, &tree, p, &mut alone).unwrap();
                } else {
                    collision_rows_from_geometry(&cm, &cd, &robot, &data, &dense, p, &mut alone).unwrap();
                }
                assert_eq!(rows, alone, "seed {seed} tree {use_tree} field {position}");
                assert_eq!(rows.metric_norm_squared(), alone.metric_norm_squared(), "seed {seed} field {position}");
                let pairs = (0..cm.pairs().len()).filter(|&k| {
                    cd.proximities[k].distance < p.emit_distance() && cd.proximities[k].direction.is_some()
                });
                let mut emitted = 0;
                for (row, pair) in rows.rows().iter().zip(pairs) {
                    let mut fresh = PairRowCache::<T, N, P, C>::default();
                    let single: TaskRow<T, N> =
                        pair_row(&cm, &cd, &robot, &data, &factor, p, pair, &mut fresh).unwrap();
                    assert_eq!(*row, single, "seed {seed} tree {use_tree} field {position} pair {pair}");
                    let reference = evaluate_pair(&cm, &cd, &robot, &data, &dense, p, pair).unwrap().row;
                    let scale = 1.0 + nalgebra::try_convert::<T, f64>(reference.jacobian.amax()).unwrap();
                    let difference = (row.jacobian - reference.jacobian).amax();
                    assert!(nalgebra::try_convert::<T, f64>(difference).unwrap() <= tolerance * scale);
                    let force = nalgebra::try_convert::<T, f64>((row.force - reference.force).abs()).unwrap();
                    let magnitude = 1.0 + nalgebra::try_convert::<T, f64>(reference.force.abs()).unwrap();
                    assert!(force <= tolerance * magnitude, "seed {seed} pair {pair}: {row:?} vs {reference:?}");
                    emitted += 1;
                }
                assert_eq!(emitted, report.rows);
                rows_compared += emitted;
                if position == 1 {
                    from_cache += emitted.min(C);
                }
            }
        }
    }
    assert!(rows_compared > 1000 && from_cache > 100, "{rows_compared} rows, {from_cache} from the cache");
}

#[test]
fn shared_rows_equal_rows_alone_f64() {
    shared_rows_equal_rows_alone::<f64, 2>(1e-12);
    shared_rows_equal_rows_alone::<f64, P>(1e-12);
}

#[test]
fn shared_rows_equal_rows_alone_f32() {
    shared_rows_equal_rows_alone::<f32, 2>(2e-4);
    shared_rows_equal_rows_alone::<f32, P>(2e-4);
}

/// A pair whose evaluation fails (a zero pivot in the factor rows) leaves no entry in the
/// cache: the same cache then gives the pair's row over a valid factor, equal to the row with a
/// fresh cache, and still has room for as many pairs.
#[test]
fn failed_pair_leaves_no_cache_entry() {
    let robot = branched::<f64>();
    let cm = collision_model(&robot);
    let mut cd = CollisionData::new(&cm);
    let mut data = Data::new(&robot);
    let p = field::<f64>(25.0, 1.2, 0.7);
    let mut checked = 0;
    for seed in 0..20 {
        forward_kinematics(&robot, &mut data, &state(seed, 1.5), &state(seed + 40, 1.0)).unwrap();
        crba(&robot, &mut data);
        let rows_of_l = factor_rows(&mass_matrix_cholesky(&data).unwrap());
        let mut singular = rows_of_l;
        singular.fill_diagonal(0.0);
        cm.update(&data, &mut cd);
        let mut pairs = (0..cm.pairs().len())
            .filter(|&k| cd.proximities[k].distance < p.emit_distance() && cd.proximities[k].direction.is_some());
        let (Some(first), Some(second)) = (pairs.next(), pairs.next()) else { continue };
        let mut cache = PairRowCache::<f64, N, P, 1>::default();
        let failed = pair_row(&cm, &cd, &robot, &data, &PairFactor::Rows(singular), &p, first, &mut cache);
        assert_eq!(failed, Err(TaskError::Singular));
        assert_eq!(cache.len(), 0, "seed {seed}");
        let valid = PairFactor::Rows(rows_of_l);
        for pair in [first, second, first] {
            let row = pair_row(&cm, &cd, &robot, &data, &valid, &p, pair, &mut cache).unwrap();
            let fresh =
                pair_row(&cm, &cd, &robot, &data, &valid, &p, pair, &mut PairRowCache::<f64, N, P, 1>::default());
            assert_eq!(row, fresh.unwrap(), "seed {seed} pair {pair}");
            assert_eq!(cache.len(), 1, "seed {seed}: the first pair cached, the second one computed alone");
        }
        checked += 1;
    }
    assert!(checked > 10, "{checked}");
}
