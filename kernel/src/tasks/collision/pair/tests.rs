#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
use super::kinematics::PairFactor;
use super::rows::pair_row;
use super::*;
use crate::dynamics::{crba, forward_kinematics, mass_matrix_cholesky, TreeFactorization};
use crate::tasks::collision::{CollisionModelBuilder, SweptSphere};
use crate::tasks::TaskRows;
use crate::test_models::{branched, state, Branched, B, F, N};
use nalgebra::{convert, Vector3};

const V: usize = 6;
pub(super) const P: usize = 15;

fn v3<T: RealField + Copy>(x: f64, y: f64, z: f64) -> Vector3<T> {
    Vector3::new(convert(x), convert(y), convert(z))
}

/// Volumes on both branches of the test tree and in the world: a capsule on the coupled
/// branch, a swept triangle and a sphere on the prismatic branch, a capsule on the pitch
/// body, a world-fixed floor triangle and a world-fixed sphere.
pub(super) fn collision_model<T: RealField + Copy>(robot: &Branched<T>) -> CollisionModel<T, V, P> {
    let mut c = CollisionModelBuilder::<T, V, P>::new();
    let r = |x: f64| convert::<f64, T>(x);
    c.add_volume(Some(BodyId(4)), SweptSphere::capsule(v3(0.0, 0.0, 0.0), v3(0.15, 0.02, 0.0), r(0.05))).unwrap();
    c.add_volume(
        Some(BodyId(6)),
        SweptSphere::swept_triangle(v3(0.0, 0.0, 0.0), v3(0.1, 0.0, 0.05), v3(0.0, 0.12, 0.1), r(0.03)),
    )
    .unwrap();
    c.add_volume(Some(BodyId(5)), SweptSphere::sphere(v3(0.05, -0.02, 0.1), r(0.06))).unwrap();
    c.add_volume(Some(BodyId(2)), SweptSphere::capsule(v3(0.05, 0.0, 0.0), v3(0.25, 0.0, 0.0), r(0.04))).unwrap();
    c.add_volume(
        None,
        SweptSphere::swept_triangle(v3(-5.0, -5.0, -0.2), v3(10.0, -5.0, -0.2), v3(-5.0, 10.0, -0.2), r(0.0)),
    )
    .unwrap();
    c.add_volume(None, SweptSphere::sphere(v3(0.4, 0.3, 0.5), r(0.1))).unwrap();
    c.try_build(robot, &[]).unwrap()
}

fn parameters<T: RealField + Copy>(xi: f64) -> CollisionParameters<T> {
    // d0 large enough that most pairs are inside their potential at random states.
    CollisionParameters::try_new(convert(25.0), convert(1.0), convert(xi), convert(0.1), convert(0.6)).unwrap()
}

#[test]
fn potential_force_and_stiffness() {
    let p = CollisionParameters::try_new(25.0_f64, 0.15, 0.7, 0.0, 0.15).unwrap();
    // (3.10): F(0) = F_max; local stiffness 2 F_max/d0 = 333 N/m at contact.
    assert_eq!(p.force(0.0), 25.0);
    assert!((p.stiffness(0.0) - 1000.0 / 3.0).abs() < 1e-12);
    assert!((p.potential(0.0) - 25.0 * 0.15 / 3.0).abs() < 1e-15);
    // F = −dV/dd and k = dF/dd... = −dF/dd, by central differences (relative 1e-6).
    let h = 1e-6;
    for k in 0..300 {
        let d = -0.05 + 0.2 * f64::from(k) / 300.0;
        if (d - 0.15).abs() < 2.0 * h {
            continue;
        }
        let force = -(p.potential(d + h) - p.potential(d - h)) / (2.0 * h);
        let stiffness = -(p.force(d + h) - p.force(d - h)) / (2.0 * h);
        assert!((force - p.force(d)).abs() <= 1e-6 * p.force(d).max(1e-3), "F at {d}");
        assert!((stiffness - p.stiffness(d)).abs() <= 1e-6 * p.stiffness(d).max(1e-3), "k at {d}");
    }
    // C² at d0: one-sided second differences of V on both sides tend to V''(d0) = 0.
    let d0 = 0.15;
    for h in [1e-3, 1e-4] {
        let left = (p.potential(d0) - 2.0 * p.potential(d0 - h) + p.potential(d0 - 2.0 * h)) / (h * h);
        let right = (p.potential(d0 + 2.0 * h) - 2.0 * p.potential(d0 + h) + p.potential(d0)) / (h * h);
        assert!(right == 0.0 && left.abs() <= 2.0 * 25.0 / (0.15 * 0.15) * 3.0 * h, "V'' left {left} right {right}");
    }
    assert_eq!((p.potential(d0), p.force(d0), p.stiffness(d0)), (0.0, 0.0, 0.0));
    // Activation band [0, d0]: 1 at contact, ½ in the middle, 0 beyond.
    assert_eq!((p.activation(0.0), p.activation(0.2)), (1.0, 0.0));
    assert!((p.activation(0.075) - 0.5).abs() < 1e-15);
    // Table 4.5 band: maximal slope 1.5/(ϑ2 − ϑ1) = 18.75 1/m.
    let t = CollisionParameters::try_new(30.0_f64, 0.10, 0.5, 0.05, 0.13).unwrap();
    let slope = (t.activation(0.09 - 1e-7) - t.activation(0.09 + 1e-7)) / 2e-7;
    assert!((slope - 18.75).abs() < 1e-5);
    // f32.
    let p32 = CollisionParameters::try_new(25.0_f32, 0.15, 0.7, 0.0, 0.15).unwrap();
    assert_eq!(p32.force(0.0), 25.0);
    assert!((p32.potential(0.05) - 25.0 / (3.0 * 0.0225) * 0.001).abs() < 1e-6);
    // Validation.
    assert_eq!(
        CollisionParameters::try_new(0.0_f64, 0.1, 0.5, 0.0, 0.1),
        Err(TaskError::InvalidParameter { name: "max_force" })
    );
    assert_eq!(
        CollisionParameters::try_new(1.0_f64, 0.1, -0.5, 0.0, 0.1),
        Err(TaskError::InvalidParameter { name: "damping_ratio" })
    );
    assert_eq!(
        CollisionParameters::try_new(1.0_f64, 0.1, 0.5, 0.2, 0.1),
        Err(TaskError::InvalidParameter { name: "activation band" })
    );
    assert_eq!(CollisionParameters::try_new(1.0_f64, f64::NAN, 0.5, 0.0, 0.1), Err(TaskError::NonFinite));
}

#[test]
fn pair_damping_matches_the_closed_form() {
    for seed in 7..207 {
        let s = state(seed, 1.0);
        let (mi, mj, k, xi) = (0.5 + 10.0 * s[0].abs(), 0.5 + 10.0 * s[1].abs(), 400.0 * s[2].abs(), 1.5 * s[3].abs());
        let (c, d) = pair_damping(&Vector2::new(1.0 / mi, 1.0 / mj), k, xi).unwrap();
        let expected = 2.0 * xi * (k * mi * mj / (mi + mj)).sqrt();
        assert!((c - expected).abs() <= 1e-12 * (1.0 + expected), "{c} vs {expected}");
        // D = c [[1, −1], [−1, 1]]: the common mode is undamped.
        assert_eq!(d * Vector2::new(1.0, 1.0), Vector2::zeros());
        // World-fixed partner: m_eff = m_i.
        let (c, _) = pair_damping(&Vector2::new(0.0, 1.0 / mj), k, xi).unwrap();
        assert!((c - 2.0 * xi * (k * mj).sqrt()).abs() <= 1e-9 * (1.0 + c));
    }
    // Extreme mass ratios (a point near a joint axis): still the closed form, f64 and f32.
    for ratio in [1e2, 1e4, 1e6, 1e9] {
        let (c, _) = pair_damping(&Vector2::new(1.0 / ratio, 0.5), 300.0_f64, 0.7).unwrap();
        let expected = 2.0 * 0.7 * (300.0 / (0.5 + 1.0 / ratio)).sqrt();
        assert!((c - expected).abs() <= 1e-10 * expected, "ratio {ratio}: {c} vs {expected}");
        let (c, _) = pair_damping(&Vector2::new(1.0 / ratio as f32, 0.5), 300.0_f32, 0.7).unwrap();
        assert!((f64::from(c) - expected).abs() <= 1e-4 * expected, "f32 ratio {ratio}: {c} vs {expected}");
    }
    assert_eq!(pair_damping(&Vector2::new(0.0, 0.0), 100.0, 0.7).unwrap().0, 0.0);
    assert_eq!(pair_damping(&Vector2::new(1.0, 1.0), 0.0, 0.7).unwrap().0, 0.0);
    assert_eq!(pair_damping(&Vector2::new(1.0, f64::NAN), 1.0, 0.7), Err(TaskError::NonFinite));
    // f32.
    let (c, _) = pair_damping(&Vector2::new(0.5_f32, 0.5), 200.0, 1.0).unwrap();
    assert!((c - 2.0 * 200.0_f32.sqrt()).abs() < 1e-3);
}

/// Total collision potential `Σ V(d_k(q))` of all enabled pairs.
fn total_potential(
    robot: &Branched<f64>,
    data: &mut Data<f64, N, B, F>,
    cm: &CollisionModel<f64, V, P>,
    cd: &mut CollisionData<f64, V, P>,
    p: &CollisionParameters<f64>,
    q: &SVector<f64, N>,
) -> f64 {
    forward_kinematics(robot, data, q, &SVector::zeros()).unwrap();
    cm.update(data, cd);
    cd.proximities.iter().take(cm.pairs().len()).map(|x| p.potential(x.distance)).sum()
}

/// τ = Σ jᵀ f equals −∂V/∂q (central differences, relative 1e-6) at random states, and
/// j q̇ equals the rate of each distance; with q̇ ≠ 0 the rows equal (3.24) with the 2×2
/// damping matrices.
#[test]
fn torques_are_the_negative_potential_gradient() {
    let robot = branched::<f64>();
    let cm = collision_model(&robot);
    assert_eq!(cm.pairs().len(), 13, "15 pairs minus world–world and wrist–prism (adjacent)");
    let mut cd = CollisionData::new(&cm);
    let mut data = Data::new(&robot);
    let p = parameters::<f64>(0.7);
    let mut checked = 0;
    for seed in 0..200 {
        let q = state(seed, 1.5);
        let v = state(seed + 1000, 1.0);
        forward_kinematics(&robot, &mut data, &q, &SVector::zeros()).unwrap();
        crba(&robot, &mut data);
        let factor = mass_matrix_cholesky(&data).unwrap();
        let mut rows = TaskRows::<f64, N, P>::new();
        let report = self_collision_rows(&cm, &mut cd, &robot, &data, &factor, &p, &mut rows).unwrap();
        assert_eq!(report.dropped, 0);
        if report.undefined_direction > 0 || rows.is_empty() {
            continue;
        }
        let tau = rows.torque();
        let h = 1e-6;
        let gradient = SVector::<f64, N>::from_fn(|k, _| {
            let e = SVector::<f64, N>::from_fn(|i, _| if i == k { h } else { 0.0 });
            (total_potential(&robot, &mut data, &cm, &mut cd, &p, &(q + e))
                - total_potential(&robot, &mut data, &cm, &mut cd, &p, &(q - e)))
                / (2.0 * h)
        });
        assert!((tau + gradient).amax() <= 1e-6 * tau.amax().max(1e-3), "seed {seed}: {tau} vs {gradient}");
        assert!((rows.potential() - total_potential(&robot, &mut data, &cm, &mut cd, &p, &q)).abs() < 1e-12);
        checked += 1;

        // Rates: j q̇ = ḋ by central differences along q̇.
        let distances = |data: &mut Data<f64, N, B, F>, cd: &mut CollisionData<f64, V, P>, q: &SVector<f64, N>| {
            forward_kinematics(&robot, data, q, &SVector::zeros()).unwrap();
            cm.update(data, cd);
            cd.proximities.map(|x| x.distance)
        };
        let (plus, minus) = (distances(&mut data, &mut cd, &(q + v * h)), distances(&mut data, &mut cd, &(q - v * h)));
        forward_kinematics(&robot, &mut data, &q, &v).unwrap();
        crba(&robot, &mut data);
        cm.update(&data, &mut cd);
        for pair in 0..cm.pairs().len() {
            if cd.proximities[pair].distance >= p.emit_distance() {
                continue;
            }
            let e = evaluate_pair(&cm, &cd, &robot, &data, &factor, &p, pair).unwrap();
            let rate = (plus[pair] - minus[pair]) / (2.0 * h);
            assert!(((e.row.jacobian * v).x - rate).abs() <= 1e-6 * (1.0 + rate.abs()));
            // (3.24) with the 2×2 matrix equals the row form.
            let row_torque = e.row.jacobian.transpose() * e.row.force;
            let thesis = e.torque(p.force(e.distance), &v);
            assert!((row_torque - thesis).amax() <= 1e-12 * (1.0 + row_torque.amax()), "{row_torque} vs {thesis}");
            // Reflected masses against an explicit inverse of M.
            let inverse = data.mass_matrix.try_inverse().unwrap();
            let wi = (e.jacobian_first * inverse * e.jacobian_first.transpose()).x;
            let wj = (e.jacobian_second * inverse * e.jacobian_second.transpose()).x;
            assert!((e.inverse_masses - Vector2::new(wi, wj)).amax() <= 1e-10 * (1.0 + wi.max(wj)));
            let world_fixed = cm.volume(cm.pairs()[pair].second).unwrap().body.is_none();
            assert_eq!(e.reflected_masses().1.is_none(), world_fixed);
        }
    }
    assert!(checked > 150, "only {checked} states had active pairs");
}

#[test]
fn rows_keep_the_closest_pairs_and_errors_leave_rows_unchanged() {
    let robot = branched::<f64>();
    let cm = collision_model(&robot);
    let mut cd = CollisionData::new(&cm);
    let mut data = Data::new(&robot);
    let q = state(3, 1.0);
    forward_kinematics(&robot, &mut data, &q, &state(4, 1.0)).unwrap();
    crba(&robot, &mut data);
    let factor = mass_matrix_cholesky(&data).unwrap();
    let p = parameters::<f64>(1.0);
    let mut all = TaskRows::<f64, N, P>::new();
    let full = self_collision_rows(&cm, &mut cd, &robot, &data, &factor, &p, &mut all).unwrap();
    assert!(full.candidates >= 4, "{full:?}");
    // Capacity 3 with one row already present: the two closest candidates.
    let mut few = TaskRows::<f64, N, 3>::new();
    let marker = TaskRow { jacobian: RowSVector::zeros(), force: 1.0, potential: 0.0, activation: 1.0 };
    few.push(marker).unwrap();
    let report = self_collision_rows(&cm, &mut cd, &robot, &data, &factor, &p, &mut few).unwrap();
    assert_eq!((report.rows, report.dropped), (2, full.candidates - 2));
    let mut candidates: std::vec::Vec<(f64, usize)> = cd
        .proximities
        .iter()
        .take(cm.pairs().len())
        .enumerate()
        .filter(|(_, x)| x.distance < p.emit_distance())
        .map(|(i, x)| (x.distance, i))
        .collect();
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut closest: std::vec::Vec<usize> = candidates.iter().take(2).map(|c| c.1).collect();
    closest.sort_unstable();
    // The rows are exactly those of the selected pairs (the fast form; it equals the
    // reference `evaluate_pair` to rounding, `fast_rows_match_the_reference_*`).
    let rows_of_l = factor_rows(&factor);
    for (row, pair) in few.rows()[1..].iter().zip(&closest) {
        let mut cache = PairRowCache::<f64, N, P, 4>::default();
        assert_eq!(
            *row,
            pair_row(&cm, &cd, &robot, &data, &PairFactor::Rows(rows_of_l), &p, *pair, &mut cache).unwrap()
        );
        let e = evaluate_pair(&cm, &cd, &robot, &data, &factor, &p, *pair).unwrap();
        assert!(row_difference(row, &e.row) <= 1e-12, "{row:?} vs {:?}", e.row);
    }
    // A full list stays as it was.
    let before = few.clone();
    let report = self_collision_rows(&cm, &mut cd, &robot, &data, &factor, &p, &mut few).unwrap();
    assert_eq!((report.rows, few), (0, before));
    // Unknown pair.
    assert!(evaluate_pair(&cm, &cd, &robot, &data, &factor, &p, 99).is_err());
}

/// [`CollisionModel::compute_distances`] (triangle frames computed once per volume) gives
/// every exact pair the proximity of [`crate::tasks::collision::proximity`] of its world volumes,
/// bit for bit, at random states (f64 and f32); with the broad phase (bounding spheres and
/// triangle slabs) every skipped pair reports a lower bound of its distance above the cull
/// distance, and the skipped pairs include pairs whose bounding spheres are not separated.
fn shared_triangle_frames_match_proximity<T: RealField + Copy>() {
    let robot = branched::<T>();
    let cm = collision_model(&robot);
    let mut cd = CollisionData::new(&cm);
    let mut data = Data::new(&robot);
    let (mut exact, mut culled, mut by_slab) = (0, 0, 0);
    let limit: T = convert(0.05);
    for seed in 0..100 {
        forward_kinematics(&robot, &mut data, &state(seed, 1.5).cast::<T>(), &SVector::zeros()).unwrap();
        cd.exact_within = if seed % 2 == 0 { None } else { Some(limit) };
        cm.update(&data, &mut cd);
        for (pair, proximity) in cm.pairs().iter().zip(&cd.proximities) {
            let (a, b) = (&cd.world_volumes[pair.first.0], &cd.world_volumes[pair.second.0]);
            let plain = crate::tasks::collision::proximity(a, b);
            if cd.exact_within.is_some() && *proximity != plain {
                assert!(proximity.direction.is_none() && proximity.distance > limit, "seed {seed} {pair:?}");
                assert!(proximity.distance <= plain.distance + convert(1e-5), "seed {seed} {pair:?}");
                let ((ca, ra), (cb, rb)) = (cd.bounding_spheres[pair.first.0], cd.bounding_spheres[pair.second.0]);
                by_slab += usize::from((ca - cb).norm() - ra - rb <= limit);
                culled += 1;
                continue;
            }
            assert_eq!(*proximity, plain, "seed {seed} {pair:?}");
            exact += 1;
        }
    }
    assert!(exact > 600 && culled > 300 && by_slab > 100, "{exact} exact, {culled} culled ({by_slab} by a slab)");
}

#[test]
fn shared_triangle_frames_match_proximity_f64() {
    shared_triangle_frames_match_proximity::<f64>();
}

#[test]
fn shared_triangle_frames_match_proximity_f32() {
    shared_triangle_frames_match_proximity::<f32>();
}

/// The heap selection of the `k` closest candidates against a sort: at random states and
/// every capacity `k` from 1 to 6, the rows of a field with `k` free rows are exactly the
/// rows (bit for bit, in pair order) of the `k` candidates with the smallest distances in a
/// field with room for all, f64 and f32.
fn selection_matches_a_sort<T: RealField + Copy>() {
    let robot = branched::<T>();
    let cm = collision_model(&robot);
    let mut cd = CollisionData::new(&cm);
    let mut data = Data::new(&robot);
    let p = parameters::<T>(0.7);
    let mut checked = 0;
    for seed in 0..100 {
        forward_kinematics(&robot, &mut data, &state(seed, 1.5).cast::<T>(), &state(seed + 300, 1.0).cast::<T>())
            .unwrap();
        crba(&robot, &mut data);
        let factor = mass_matrix_cholesky(&data).unwrap();
        let mut all = TaskRows::<T, N, P>::new();
        let full = self_collision_rows(&cm, &mut cd, &robot, &data, &factor, &p, &mut all).unwrap();
        assert_eq!(full.dropped, 0);
        let mut candidates: std::vec::Vec<(T, usize)> = cd
            .proximities
            .iter()
            .take(cm.pairs().len())
            .enumerate()
            .filter(|(_, x)| x.distance < p.emit_distance() && x.direction.is_some())
            .map(|(i, x)| (x.distance, i))
            .collect();
        let order: std::vec::Vec<usize> = candidates.iter().map(|c| c.1).collect();
        candidates.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap().then(a.1.cmp(&b.1)));
        for k in 1..=6_usize {
            let mut few = TaskRows::<T, N, 6>::new();
            for _ in k..6 {
                few.push(TaskRow {
                    jacobian: RowSVector::zeros(),
                    force: T::one(),
                    potential: T::zero(),
                    activation: T::one(),
                })
                .unwrap();
            }
            let report = collision_rows_from_geometry(&cm, &cd, &robot, &data, &factor, &p, &mut few).unwrap();
            let mut closest: std::vec::Vec<usize> = candidates.iter().take(k).map(|c| c.1).collect();
            closest.sort_unstable();
            assert_eq!(report.rows, closest.len());
            assert_eq!(report.dropped, candidates.len() - closest.len());
            for (row, pair) in few.rows()[6 - k..].iter().zip(&closest) {
                let position = order.iter().position(|x| x == pair).unwrap();
                assert_eq!(*row, all.rows()[position], "seed {seed} k {k} pair {pair}");
            }
            checked += usize::from(candidates.len() > k);
        }
    }
    assert!(checked > 300, "{checked} selections dropped candidates");
}

#[test]
fn selection_matches_a_sort_f64() {
    selection_matches_a_sort::<f64>();
}

#[test]
fn selection_matches_a_sort_f32() {
    selection_matches_a_sort::<f32>();
}

/// Largest relative difference of two rows' Jacobians, forces, potentials and activations.
fn row_difference<T: RealField + Copy>(fast: &TaskRow<T, N>, reference: &TaskRow<T, N>) -> f64 {
    let scale = |x: T| 1.0 + nalgebra::try_convert::<T, f64>(x.abs()).unwrap();
    let rel = |a: T, b: T| nalgebra::try_convert::<T, f64>((a - b).abs()).unwrap() / scale(b);
    let jacobian = fast
        .jacobian
        .iter()
        .zip(reference.jacobian.iter())
        .map(|(&a, &b)| nalgebra::try_convert::<T, f64>((a - b).abs()).unwrap() / scale(reference.jacobian.amax()))
        .fold(0.0, f64::max);
    jacobian
        .max(rel(fast.force, reference.force))
        .max(rel(fast.potential, reference.potential))
        .max(rel(fast.activation, reference.activation))
}

/// The fast pair rows ([`pair_row`], used by [`collision_rows_from_geometry`]) and the
/// fast reflected masses ([`inverse_reflected_masses`]) against the reference
/// [`evaluate_pair`] / [`inverse_reflected_mass`] at random states with random velocities,
/// every pair with a direction below the emit distance, f64 (tight) and f32.
fn fast_rows_match_reference<T: RealField + Copy>(tolerance: f64) {
    let robot = branched::<T>();
    let cm = collision_model(&robot);
    let mut cd = CollisionData::new(&cm);
    let mut data = Data::new(&robot);
    let p = parameters::<T>(0.7);
    let other_field =
        CollisionParameters::try_new(convert(150.0), convert(0.3), convert(1.0), convert(0.0), convert(1.2)).unwrap();
    let fresh_cache = PairRowCache::<T, N, P, P>::default;
    let (mut compared, mut damped) = (0, 0);
    for seed in 0..200 {
        let (q, v) = (state(seed, 1.5).cast::<T>(), state(seed + 500, 1.0).cast::<T>());
        forward_kinematics(&robot, &mut data, &q, &v).unwrap();
        crba(&robot, &mut data);
        let factor = mass_matrix_cholesky(&data).unwrap();
        let rows_of_l = factor_rows(&factor);
        let mut tree = TreeFactorization::new(&robot);
        tree.factorize(&data.mass_matrix).unwrap();
        let tree_factor = PairFactor::Tree(&tree);
        cm.update(&data, &mut cd);
        for pair in 0..cm.pairs().len() {
            let proximity = cd.proximities[pair];
            if proximity.distance >= p.emit_distance() || proximity.direction.is_none() {
                continue;
            }
            let reference = evaluate_pair(&cm, &cd, &robot, &data, &factor, &p, pair).unwrap();
            let fast =
                pair_row(&cm, &cd, &robot, &data, &PairFactor::Rows(rows_of_l), &p, pair, &mut fresh_cache()).unwrap();
            // Shared with another field (other force law and damping): the row from the
            // cache that field filled is the same row, to the bit.
            let mut shared = fresh_cache();
            pair_row(&cm, &cd, &robot, &data, &PairFactor::Rows(rows_of_l), &other_field, pair, &mut shared).unwrap();
            assert_eq!(
                pair_row(&cm, &cd, &robot, &data, &PairFactor::Rows(rows_of_l), &p, pair, &mut shared).unwrap(),
                fast
            );
            let difference = row_difference(&fast, &reference.row);
            assert!(difference <= tolerance, "seed {seed} pair {pair}: {difference:e}\n{fast:?}\n{:?}", reference.row);
            // The tree-sparse factor (M = LᵀL, reflected masses over the support paths).
            let tree_row = pair_row(&cm, &cd, &robot, &data, &tree_factor, &p, pair, &mut fresh_cache()).unwrap();
            let difference = row_difference(&tree_row, &reference.row);
            assert!(difference <= tolerance, "tree, seed {seed} pair {pair}: {difference:e}");
            let [wi, wj] = inverse_reflected_masses(
                &rows_of_l,
                [&reference.jacobian_first.transpose().into(), &reference.jacobian_second.transpose().into()],
            )
            .unwrap();
            for (fast, reference) in [(wi, reference.inverse_masses.x), (wj, reference.inverse_masses.y)] {
                let (f, r) = (
                    nalgebra::try_convert::<T, f64>(fast).unwrap(),
                    nalgebra::try_convert::<T, f64>(reference).unwrap(),
                );
                assert!((f - r).abs() <= tolerance * r.abs(), "seed {seed} pair {pair}: {f} vs {r}");
            }
            compared += 1;
            if reference.row.force != p.force(reference.distance) {
                damped += 1;
            }
        }
    }
    assert!(compared > 500 && damped > 300, "{compared} rows, {damped} damped");
}

#[test]
fn fast_rows_match_the_reference_f64() {
    fast_rows_match_reference::<f64>(1e-12);
}

#[test]
fn fast_rows_match_the_reference_f32() {
    fast_rows_match_reference::<f32>(2e-4);
}

/// The rows of [`collision_rows_from_geometry`] are the reference rows of the selected
/// pairs, in pair order.
#[test]
fn field_rows_are_the_reference_rows() {
    let robot = branched::<f64>();
    let cm = collision_model(&robot);
    let mut cd = CollisionData::new(&cm);
    let mut data = Data::new(&robot);
    let p = parameters::<f64>(0.9);
    let mut total = 0;
    for seed in 0..50 {
        forward_kinematics(&robot, &mut data, &state(seed, 1.5), &state(seed + 77, 1.0)).unwrap();
        crba(&robot, &mut data);
        let factor = mass_matrix_cholesky(&data).unwrap();
        let mut rows = TaskRows::<f64, N, P>::new();
        let report = self_collision_rows(&cm, &mut cd, &robot, &data, &factor, &p, &mut rows).unwrap();
        let expected: std::vec::Vec<TaskRow<f64, N>> = (0..cm.pairs().len())
            .filter(|&k| cd.proximities[k].distance < p.emit_distance() && cd.proximities[k].direction.is_some())
            .map(|k| evaluate_pair(&cm, &cd, &robot, &data, &factor, &p, k).unwrap().row)
            .collect();
        assert_eq!((report.rows, rows.len()), (expected.len(), expected.len()));
        for (fast, reference) in rows.rows().iter().zip(&expected) {
            assert!(row_difference(fast, reference) <= 1e-12, "seed {seed}: {fast:?} vs {reference:?}");
        }
        total += expected.len();
    }
    assert!(total > 100, "{total}");
}

/// Leading zeros of the right-hand sides are skipped; a zero pivot is an error.
#[test]
fn reflected_masses_of_sparse_rows_and_singular_factors() {
    let robot = branched::<f64>();
    let mut data = Data::new(&robot);
    forward_kinematics(&robot, &mut data, &state(9, 1.0), &SVector::zeros()).unwrap();
    crba(&robot, &mut data);
    let factor = mass_matrix_cholesky(&data).unwrap();
    let rows_of_l = factor_rows(&factor);
    let inverse = data.mass_matrix.try_inverse().unwrap();
    for start in 0..=N {
        let b = SVector::<f64, N>::from_fn(|i, _| if i < start { 0.0 } else { 0.3 + i as f64 });
        let [w] = inverse_reflected_masses(&rows_of_l, [&b.into()]).unwrap();
        let expected = (b.transpose() * inverse * b).x;
        assert!((w - expected).abs() <= 1e-12 * (1.0 + expected), "start {start}: {w} vs {expected}");
        let reference = inverse_reflected_mass(&factor, &b.transpose()).unwrap();
        assert!((w - reference).abs() <= 1e-14 * (1.0 + reference));
    }
    let mut singular = rows_of_l;
    singular[(2, 2)] = 0.0;
    let b = SVector::<f64, N>::repeat(1.0);
    assert_eq!(inverse_reflected_masses(&singular, [&b.into(), &b.into()]), Err(TaskError::Singular));
}

#[test]
fn f32_rows_agree_with_f64() {
    let (r64, r32) = (branched::<f64>(), branched::<f32>());
    let (c64, c32) = (collision_model(&r64), collision_model(&r32));
    let (mut d64, mut d32) = (Data::new(&r64), Data::new(&r32));
    let (mut k64, mut k32) = (CollisionData::new(&c64), CollisionData::new(&c32));
    let (p64, p32) = (parameters::<f64>(0.7), parameters::<f32>(0.7));
    for seed in 0..20 {
        let (q, v) = (state(seed, 1.5), state(seed + 50, 1.0));
        forward_kinematics(&r64, &mut d64, &q, &v).unwrap();
        forward_kinematics(&r32, &mut d32, &q.cast(), &v.cast()).unwrap();
        crba(&r64, &mut d64);
        crba(&r32, &mut d32);
        let (f64_, f32_) = (mass_matrix_cholesky(&d64).unwrap(), mass_matrix_cholesky(&d32).unwrap());
        let (mut rows64, mut rows32) = (TaskRows::<f64, N, P>::new(), TaskRows::<f32, N, P>::new());
        self_collision_rows(&c64, &mut k64, &r64, &d64, &f64_, &p64, &mut rows64).unwrap();
        self_collision_rows(&c32, &mut k32, &r32, &d32, &f32_, &p32, &mut rows32).unwrap();
        if rows64.len() != rows32.len() {
            continue; // a pair at the emit distance
        }
        let (t64, t32) = (rows64.torque(), rows32.torque().cast::<f64>());
        assert!((t64 - t32).amax() <= 1e-3 * (1.0 + t64.amax()), "seed {seed}: {:?}", (t64 - t32).transpose());
    }
}
