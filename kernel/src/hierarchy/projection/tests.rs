#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
use super::*;
use crate::dynamics::{crba, forward_kinematics, mass_matrix_cholesky};
use crate::hierarchy::{push_transitioning, Stack};
use crate::math::CholeskyFactor;
use crate::tasks::{TaskRow, TaskRows};
use crate::test_models::{branched, state, N};
use crate::Data;
use nalgebra::{DMatrix, RowSVector};

const CONTINUOUS: Shaping<f64> = Shaping::Continuous { singular_full: 0.05, singular_start: 0.15 };

fn row(j: RowSVector<f64, N>, f: f64) -> TaskRow<f64, N> {
    TaskRow { jacobian: j, force: f, potential: 0.0, activation: 1.0 }
}

fn random_stack(seed: u64, levels: &[usize]) -> Stack<f64, N, 8> {
    let mut stack = Stack::new();
    for (k, &level) in levels.iter().enumerate() {
        let j = state(seed * 31 + k as u64, 1.0).transpose();
        stack.push(level, row(j, 10.0 * state(seed + 99, 1.0)[k % N])).unwrap();
    }
    stack
}

fn mass_factor(seed: u64) -> CholeskyFactor<f64, N> {
    let model = branched::<f64>();
    let mut data = Data::new(&model);
    forward_kinematics(&model, &mut data, &state(seed, 2.0), &SVector::zeros()).unwrap();
    crba(&model, &mut data);
    mass_matrix_cholesky(&data).unwrap()
}

/// Direct augmented projector I − Jₐᵀ (Jₐ W⁻¹ Jₐᵀ)⁺ Jₐ W⁻¹ (4.9), (4.15) by SVD.
fn direct_projector(rows: &[RowSVector<f64, N>], w_inv: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    if rows.is_empty() {
        return SMatrix::identity();
    }
    let ja = DMatrix::from_fn(rows.len(), N, |r, c| rows[r][c]);
    let w = DMatrix::from_fn(N, N, |r, c| w_inv[(r, c)]);
    let inner = (&ja * &w * ja.transpose()).pseudo_inverse(1e-12).unwrap();
    let p = DMatrix::identity(N, N) - ja.transpose() * inner * &ja * &w;
    SMatrix::from_fn(|r, c| p[(r, c)])
}

fn config<'a>(recursion: Recursion, weighting: Weighting<'a, f64, N>) -> HierarchyConfig<'a, f64, N> {
    HierarchyConfig { recursion, weighting, shaping: CONTINUOUS, diagnose_last_level: true }
}

#[test]
fn scalar_recursion_equals_the_direct_augmented_projector() {
    let mut checked = 0;
    for seed in 1..30 {
        let factor = mass_factor(seed);
        let m_inv = factor.inverse();
        let stack = random_stack(seed, &[0, 0, 1, 2, 2]);
        for (weighting, w_inv) in [(Weighting::Identity, SMatrix::identity()), (Weighting::Inertia(&factor), m_inv)] {
            let mut data = HierarchyData::<f64, N, 8, 4>::default();
            let tau = *project(&config(Recursion::Augmented, weighting), &stack, &mut data).unwrap();
            // Equality holds when no row is near singular: every ρ above the shaping band,
            // so every activation is exactly 1.
            let min_ratio =
                data.rows[..stack.rows().len()].iter().map(|r| r.projected_norm_ratio).fold(f64::MAX, f64::min);
            if min_ratio < 0.15 {
                continue;
            }
            checked += 1;
            let mut expected = SVector::<f64, N>::zeros();
            let mut above = std::vec::Vec::new();
            for level in 0..3 {
                let n = direct_projector(&above, &w_inv);
                for r in stack.rows().iter().filter(|r| r.level == level) {
                    expected += n * r.row.jacobian.transpose() * r.row.force;
                }
                above.extend(stack.rows().iter().filter(|r| r.level == level).map(|r| r.row.jacobian));
            }
            assert!(
                (tau - expected).amax() < 1e-9 * (1.0 + expected.amax()),
                "seed {seed}: {}",
                (tau - expected).amax()
            );
            assert!((data.projector - direct_projector(&above, &w_inv)).amax() < 1e-9, "seed {seed}");
        }
    }
    assert!(checked >= 30, "only {checked} of 58 cases were non-singular");
}

#[test]
fn table_4_3_strictness_and_idempotence() {
    let factor = mass_factor(7);
    let m_inv = factor.inverse();
    let stack = random_stack(3, &[0, 1, 1]);
    let level0: SVector<f64, N> = stack.rows()[0].row.jacobian.transpose();
    for (weighting, dynamic) in [
        (Weighting::Identity, false),
        (Weighting::Inertia(&factor), true),
        (Weighting::AccelerationBased(&factor), true),
    ] {
        let mut data = HierarchyData::<f64, N, 8, 4>::default();
        project(&config(Recursion::Augmented, weighting), &stack, &mut data).unwrap();
        let n = data.projector;
        // Static strictness N_j J_iᵀ = 0 (W = I, W = M); dynamic J_i M⁻¹ N_j = 0 (W = M, accel).
        match weighting {
            Weighting::AccelerationBased(_) => {
                let full = factor.l() * factor.l().transpose() * n * m_inv;
                assert!((level0.transpose() * m_inv * full).amax() < 1e-10);
            }
            _ => {
                assert!((n * level0).amax() < 1e-10);
                if dynamic {
                    assert!((level0.transpose() * m_inv * n).amax() < 1e-10);
                }
            }
        }
        assert!((n * n - n).amax() < 1e-10, "augmented projectors are idempotent");
    }
    // Successive projectors (two non-orthogonal rows on consecutive levels) are not.
    let mut data = HierarchyData::<f64, N, 8, 4>::default();
    project(&config(Recursion::Successive, Weighting::Identity), &random_stack(3, &[0, 1, 2]), &mut data).unwrap();
    assert!((data.projector * data.projector - data.projector).amax() > 1e-3);
}

#[test]
fn invariance_4_77_only_the_critical_direction_is_touched() {
    let j = RowSVector::<f64, N>::from_fn(|_, c| [1.0, -2.0, 0.5, 0.0, 1.5, 0.3][c]);
    for activation in [0.0, 0.3, 1.0] {
        let mut stack = Stack::<f64, N, 8>::new();
        stack.push(0, TaskRow { activation, ..row(j, 1.0) }).unwrap();
        let mut data = HierarchyData::<f64, N, 8, 4>::default();
        project(&config(Recursion::Augmented, Weighting::Identity), &stack, &mut data).unwrap();
        let n = data.projector;
        assert!((n * j.transpose() - j.transpose() * (1.0 - activation)).amax() < 1e-12);
        let v = SVector::<f64, N>::from_fn(|r, _| [2.0, 1.0, 0.0, 3.0, 0.0, 0.0][r]);
        assert!(j.dot(&v.transpose()).abs() < 1e-15);
        assert!((n * v - v).amax() < 1e-12, "directions orthogonal to the row are untouched");
    }
}

/// Two rows on levels 0 and 1 that become parallel as `t → 0`: an algorithmic
/// singularity. Returns the level-2 torque as a function of `t`.
fn torque_near_singularity(t: f64, shaping: Shaping<f64>) -> SVector<f64, N> {
    let a = RowSVector::<f64, N>::from_fn(|_, c| [1.0, 0.0, 0.0, 0.0, 0.0, 0.0][c]);
    let b = RowSVector::<f64, N>::from_fn(|_, c| [1.0, t, 0.0, 0.0, 0.0, 0.0][c]);
    let mut stack = Stack::<f64, N, 8>::new();
    stack.push(0, row(a, 1.0)).unwrap();
    stack.push(1, row(b, 1.0)).unwrap();
    stack.push(2, row(RowSVector::from_fn(|_, c| [0.3, 1.0, 0.2, 0.0, 0.0, 0.0][c]), 5.0)).unwrap();
    let mut data = HierarchyData::<f64, N, 8, 4>::default();
    let cfg = HierarchyConfig {
        recursion: Recursion::Augmented,
        weighting: Weighting::Identity,
        shaping,
        diagnose_last_level: true,
    };
    *project(&cfg, &stack, &mut data).unwrap()
}

#[test]
fn continuous_through_an_algorithmic_singularity_classical_jumps() {
    let classical = Shaping::Discontinuous { singular_threshold: 1e-3 };
    let (mut worst_continuous, mut worst_classical) = (0.0_f64, 0.0_f64);
    let steps = 4000;
    for k in 0..steps {
        let t0 = 0.4 * k as f64 / steps as f64;
        let t1 = 0.4 * (k + 1) as f64 / steps as f64;
        worst_continuous = worst_continuous
            .max((torque_near_singularity(t1, CONTINUOUS) - torque_near_singularity(t0, CONTINUOUS)).amax());
        worst_classical = worst_classical
            .max((torque_near_singularity(t1, classical) - torque_near_singularity(t0, classical)).amax());
    }
    // Step 1e-4 in t: a continuous torque changes by O(1e-3); the classical one jumps by
    // the full blocked component (5 · 1.0 of the level-2 force along the unlocked axis).
    assert!(worst_continuous < 1e-2, "continuous shaping jumped by {worst_continuous}");
    assert!(worst_classical > 1.0, "classical projector should jump, max step {worst_classical}");
}

#[test]
fn level_transition_is_continuous_and_exact_at_the_ends() {
    let mut task = TaskRows::<f64, N, 2>::new();
    task.push(row(RowSVector::from_fn(|_, c| [0.0, 1.0, 0.5, 0.0, 0.0, 0.0][c]), 4.0)).unwrap();
    let other = row(RowSVector::from_fn(|_, c| [0.2, 1.0, 0.0, 0.0, 0.0, 0.0][c]), -3.0);
    let torque = |progress: f64| {
        let mut stack = Stack::<f64, N, 8>::new();
        stack.push(1, other).unwrap();
        push_transitioning(&mut stack, &task, 2, 0, progress).unwrap();
        let mut data = HierarchyData::<f64, N, 8, 4>::default();
        *project(&config(Recursion::Augmented, Weighting::Identity), &stack, &mut data).unwrap()
    };
    let on = |level: usize| {
        let mut stack = Stack::<f64, N, 8>::new();
        stack.push(1, other).unwrap();
        stack.push_rows(level, &task).unwrap();
        let mut data = HierarchyData::<f64, N, 8, 4>::default();
        *project(&config(Recursion::Augmented, Weighting::Identity), &stack, &mut data).unwrap()
    };
    assert!((torque(0.0) - on(2)).amax() < 1e-12 && (torque(1.0) - on(0)).amax() < 1e-12);
    let mut worst = 0.0_f64;
    for k in 0..1000 {
        worst = worst.max((torque((k + 1) as f64 / 1000.0) - torque(k as f64 / 1000.0)).amax());
    }
    assert!(worst < 0.05, "max torque step {worst} for a progress step of 1e-3");
}

#[test]
fn bad_input_is_rejected_without_output() {
    let mut stack = random_stack(1, &[0, 5]);
    let mut data = HierarchyData::<f64, N, 8, 4> { torque: SVector::repeat(7.0), ..Default::default() };
    let cfg = config(Recursion::Augmented, Weighting::Identity);
    assert_eq!(project(&cfg, &stack, &mut data), Err(HierarchyError::TooManyLevels { capacity: 4 }));
    // A non-finite row never reaches the projection: the stack refuses it and stays as it was.
    stack.clear();
    stack.push(1, row(RowSVector::from_element(1.0), 1.0)).unwrap();
    let before = stack.clone();
    assert_eq!(
        stack.push(0, TaskRow { force: f64::NAN, ..row(RowSVector::zeros(), 0.0) }),
        Err(HierarchyError::NonFinite)
    );
    for (entry, value) in [(0, f64::INFINITY), (N - 1, f64::NEG_INFINITY), (2, f64::NAN)] {
        let mut j = RowSVector::<f64, N>::from_element(1e300);
        j[entry] = value;
        assert_eq!(stack.push(3, row(j, 1.0)), Err(HierarchyError::NonFinite), "entry {entry}");
    }
    let infinite = TaskRow { activation: f64::NEG_INFINITY, ..row(RowSVector::from_element(1.0), 0.0) };
    assert_eq!(stack.push(0, infinite), Err(HierarchyError::NonFinite));
    assert_eq!(stack, before);
    assert_eq!(stack.level_count(), 2);
    assert_eq!(data.torque, SVector::<f64, N>::repeat(7.0));
    let bad = HierarchyConfig { shaping: Shaping::Continuous { singular_full: 0.2, singular_start: 0.1 }, ..cfg };
    assert_eq!(project(&bad, &Stack::<f64, N, 8>::new(), &mut data), Err(HierarchyError::InvalidShaping));
}

/// Fast [`project`] against the plain reference recursion on random stacks (every
/// recursion × weighting × shaping, with and without last-level diagnostics), on the
/// branched test model (its mass matrix at random states, a random SPD stiffness).
#[test]
fn fast_recursion_equals_the_reference_on_the_test_model() {
    let (mut worst64, mut worst32) = (0.0_f64, 0.0_f64);
    for seed in 0..40 {
        let mut rng = reference::TestRng::new(seed);
        let mass = mass_factor(seed + 1);
        let mass = mass.l() * mass.l().transpose();
        let stiffness = reference::random_spd::<N>(&mut rng);
        let stack = reference::random_stack::<N, 16>(&mut rng, 2 + seed as usize % 3);
        worst64 = worst64.max(reference::compare_f64::<N, 16, 16, 4>(&stack, &mass, &stiffness, 1e-9));
        worst32 = worst32.max(reference::compare_f32::<N, 16, 16, 4>(&stack, &mass, &stiffness, 4.0, 1e-6));
    }
    // The comparison is not vacuous: rounding differs (other summation order).
    assert!(worst64 > 0.0 && worst32 > 0.0, "{worst64} {worst32}");
}

/// The same on a Justin-size system (`N = 20`, random SPD mass and stiffness matrices,
/// up to four levels).
#[test]
fn fast_recursion_equals_the_reference_for_20_coordinates() {
    for seed in 0..20 {
        let mut rng = reference::TestRng::new(1000 + seed);
        let mass = reference::random_spd::<20>(&mut rng);
        let stiffness = reference::random_spd::<20>(&mut rng);
        let stack = reference::random_stack::<20, 24>(&mut rng, 2 + seed as usize % 3);
        reference::compare_f64::<20, 24, 24, 4>(&stack, &mass, &stiffness, 1e-9);
        reference::compare_f32::<20, 24, 24, 4>(&stack, &mass, &stiffness, 4.0, 1e-6);
    }
}

/// [`quadratic_form`], [`mat_vec_dot`] and [`projected_norm_squared_adding`] (one pass) give bit
/// for bit the sums of the plain [`mat_vec`], [`dot`], [`norm_squared`] and [`add_scaled`] they replace, in f64
/// and f32, on random matrices and sparse random vectors (including the zero vector).
#[test]
fn fused_norms_equal_the_plain_mat_vec_bit_for_bit() {
    fn check<T: RealField + Copy, const M: usize>(a: &SMatrix<T, M, M>, x: &SVector<T, M>) {
        let mut ax = SVector::<T, M>::zeros();
        mat_vec::<T, M>(a.as_slice(), x.as_slice(), ax.as_mut_slice());
        let quadratic = quadratic_form::<T, M>(a.as_slice(), x.as_slice());
        assert_eq!(quadratic, dot(x.as_slice(), ax.as_slice()));
        let mut fused = SVector::<T, M>::zeros();
        assert_eq!(mat_vec_dot::<T, M>(a.as_slice(), x.as_slice(), fused.as_mut_slice()), quadratic);
        assert_eq!(fused, ax);
        let force = T::from_f64(-1.7).unwrap();
        let mut torque = SVector::<T, M>::from_fn(|i, _| T::from_f64(0.25 + i as f64).unwrap());
        let mut plain = torque;
        let (x_squared, ax_squared) =
            projected_norm_squared_adding::<T, M>(a.as_slice(), x.as_slice(), force, torque.as_mut_slice());
        assert_eq!(x_squared, norm_squared(x.as_slice()));
        assert_eq!(ax_squared, norm_squared(ax.as_slice()));
        add_scaled(plain.as_mut_slice(), x.as_slice(), force);
        assert_eq!(torque, plain);
        // Not vacuous: the plain mat-vec agrees with nalgebra's product to rounding.
        let expected = a * x;
        assert!((ax - expected).amax() <= T::from_f64(1e-5).unwrap() * (T::one() + expected.amax()));
    }
    let mut rng = reference::TestRng::new(77);
    for case in 0..200 {
        let density = [0.0, 0.2, 0.5, 1.0][case % 4];
        let a = SMatrix::<f64, 20, 20>::from_fn(|_, _| rng.symmetric());
        let x = SVector::<f64, 20>::from_fn(|_, _| if rng.unit() < density { rng.symmetric() } else { 0.0 });
        check(&a, &x);
        check(&a.cast::<f32>(), &x.cast::<f32>());
        let a = reference::random_spd::<N>(&mut rng);
        let x = SVector::<f64, N>::from_fn(|_, _| if rng.unit() < density { rng.symmetric() } else { 0.0 });
        check(&a, &x);
        check(&a.cast::<f32>(), &x.cast::<f32>());
    }
}

/// Joint rows `α e_bᵀ` below a projecting level (with diagnostics) take their transmission from the input
/// projector's column norms: equal to the general `‖N_in jᵀ‖ / ‖jᵀ‖` for every weighting
/// (the acceleration-based one keeps the general form).
#[test]
fn joint_row_transmissions_are_the_input_projector_column_norms() {
    let factor = mass_factor(4);
    for seed in 0..10 {
        let level0 = random_stack(seed, &[0, 0, 0]);
        let mut stack = Stack::<f64, N, 16>::new();
        for r in level0.rows() {
            stack.push(r.level, r.row).unwrap();
        }
        for b in 0..N {
            let alpha = [2.0, -0.5, 1.0][b % 3];
            stack.push(1, row(RowSVector::from_fn(|_, c| if c == b { alpha } else { 0.0 }), 1.0)).unwrap();
        }
        for weighting in [Weighting::Identity, Weighting::Inertia(&factor), Weighting::AccelerationBased(&factor)] {
            for diagnose_last_level in [false, true] {
                let cfg = HierarchyConfig { diagnose_last_level, ..config(Recursion::Augmented, weighting) };
                let mut data = HierarchyData::<f64, N, 16, 4>::default();
                project(&cfg, &stack, &mut data).unwrap();
                let mut input = HierarchyData::<f64, N, 8, 4>::default();
                project(&config(Recursion::Augmented, weighting), &level0, &mut input).unwrap();
                let mut smallest = 1.0_f64;
                for (b, diagnostics) in data.rows[3..3 + N].iter().enumerate() {
                    let j = stack.rows()[3 + b].row.jacobian;
                    let (mut tmp, mut torque) = (SVector::zeros(), SVector::zeros());
                    let general = transmission(&weighting, &input.projector, j.as_slice(), 1.0, &mut torque, &mut tmp);
                    assert_eq!(torque, j.transpose());
                    // The last level forms its transmissions only with diagnostics.
                    assert_eq!(diagnostics.transmission.is_some(), diagnose_last_level, "seed {seed} column {b}");
                    if let Some(t) = diagnostics.transmission {
                        assert!((t - general).abs() < 1e-12, "seed {seed} column {b}");
                    }
                    smallest = smallest.min(general);
                }
                // Not vacuous: the static and dynamic projectors (norm ≤ 1 per column
                // direction) pass less than all of some joint direction.
                let accelerated = matches!(weighting, Weighting::AccelerationBased(_));
                assert!(accelerated || smallest < 0.99, "level 0 projects no joint direction: {smallest}");
            }
        }
    }
}

#[test]
fn f32_agrees_with_f64() {
    let stack = random_stack(5, &[0, 0, 1, 2]);
    let mut stack32 = Stack::<f32, N, 8>::new();
    for r in stack.rows() {
        stack32
            .push(
                r.level,
                TaskRow { jacobian: r.row.jacobian.cast(), force: r.row.force as f32, potential: 0.0, activation: 1.0 },
            )
            .unwrap();
    }
    let mut d64 = HierarchyData::<f64, N, 8, 4>::default();
    let mut d32 = HierarchyData::<f32, N, 8, 4>::default();
    let t64 = *project(&config(Recursion::Augmented, Weighting::Identity), &stack, &mut d64).unwrap();
    let cfg32 = HierarchyConfig {
        recursion: Recursion::Augmented,
        weighting: Weighting::Identity,
        shaping: Shaping::Continuous { singular_full: 0.05_f32, singular_start: 0.15 },
        diagnose_last_level: true,
    };
    let t32 = project(&cfg32, &stack32, &mut d32).unwrap().cast::<f64>();
    assert!((t64 - t32).amax() < 1e-4 * (1.0 + t64.amax()));
}

/// Lower levels made of joint rows `α e_bᵀ` (one nonzero entry: their task torque is the one
/// product `α f` at `b`), zero rows and full rows, below a projecting level: fast against the
/// reference for every recursion × weighting × shaping, with and without last-level
/// diagnostics, in f64 and f32.
#[test]
fn joint_rows_below_a_projecting_level_equal_the_reference() {
    let mut rng = reference::TestRng::new(4242);
    for case in 0..12 {
        let mass = reference::random_spd::<N>(&mut rng);
        let stiffness = reference::random_spd::<N>(&mut rng);
        let mut stack = Stack::<f64, N, 16>::new();
        for _ in 0..2 {
            stack.push(0, row(RowSVector::from_fn(|_, _| rng.symmetric()), 10.0 * rng.symmetric())).unwrap();
        }
        for level in 1..3 {
            for b in 0..N {
                let alpha = 3.0 * rng.symmetric();
                let j = RowSVector::from_fn(|_, c| if c == (b + case) % N { alpha } else { 0.0 });
                if stack.push(level, row(j, 10.0 * rng.symmetric())).is_err() {
                    break;
                }
            }
        }
        // An empty and a full row on the last level.
        stack.push(2, row(RowSVector::zeros(), 1.0)).ok();
        stack.push(2, row(RowSVector::from_fn(|_, _| rng.symmetric()), 2.0)).ok();
        let worst64 = reference::compare_f64::<N, 16, 16, 4>(&stack, &mass, &stiffness, 1e-9);
        reference::compare_f32::<N, 16, 16, 4>(&stack, &mass, &stiffness, 4.0, 1e-6);
        // The stack has joint rows on the projected levels (the path under test).
        let joint = stack.rows().iter().filter(|r| r.level > 0 && single_entry(r.row.jacobian.as_slice()).is_some());
        assert!(joint.count() >= N, "case {case}: {worst64}");
    }
}

/// Rows that carry their `j W⁻¹ jᵀ` ([`StackRow::metric_norm_squared`](crate::hierarchy::StackRow),
/// here the dense `j M⁻¹ jᵀ` of the test model's inertia formed outside the projection) give
/// the projection with [`Weighting::InverseInertia`] of the projection without them (the
/// quadratic form) to rounding, and both that of [`reference::project_reference`]: random
/// stacks on two and three levels (a task of each level pushed with `push_rows`, one moving
/// between levels with `push_transitioning`), both recursions, f64 and f32. Other weightings
/// ignore the carried values (bit-identical results).
#[test]
fn carried_metrics_give_the_projection_of_the_quadratic_form() {
    fn check<T: RealField + Copy>(seed: u64, tolerance: f64) -> usize {
        let c = |x: f64| nalgebra::convert::<f64, T>(x);
        let mut rng = reference::TestRng::new(7000 + seed);
        let m_inv = mass_factor(seed + 3).inverse();
        let inverse = m_inv.map(c);
        let levels = 2 + seed as usize % 2;
        let (mut carried, mut plain) = (Stack::<T, N, 16>::new(), Stack::<T, N, 16>::new());
        for level in 0..levels {
            let mut task = TaskRows::<T, N, 4>::new();
            for k in 0..3 {
                let jacobian =
                    RowSVector::<f64, N>::from_fn(
                        |_, _| {
                            if k == 2 && rng.unit() < 0.5 {
                                0.0
                            } else {
                                rng.symmetric()
                            }
                        },
                    );
                let metric = (jacobian * m_inv * jacobian.transpose()).x;
                let (force, activation) = (10.0 * rng.symmetric(), 0.5 + 0.5 * rng.unit());
                task.push_with_metric(|r| {
                    *r = TaskRow {
                        jacobian: jacobian.map(c),
                        force: c(force),
                        potential: T::zero(),
                        activation: c(activation),
                    };
                    Some(c(metric))
                })
                .unwrap();
            }
            assert!(task.metric_norm_squared().iter().all(Option::is_some));
            if level == 1 {
                push_transitioning(&mut carried, &task, 0, 1, c(0.3)).unwrap();
            } else {
                carried.push_rows(level, &task).unwrap();
            }
            let mut without = TaskRows::<T, N, 4>::new();
            for r in task.rows() {
                without.push(*r).unwrap();
            }
            if level == 1 {
                push_transitioning(&mut plain, &without, 0, 1, c(0.3)).unwrap();
            } else {
                plain.push_rows(level, &without).unwrap();
            }
        }
        assert!(carried.rows().iter().all(|r| r.metric_norm_squared.is_some()));
        assert!(plain.rows().iter().all(|r| r.metric_norm_squared.is_none()));
        let f = |x: T| nalgebra::try_convert::<T, f64>(x).unwrap();
        let mut compared = 0;
        for recursion in [Recursion::Augmented, Recursion::Successive] {
            let shaping = Shaping::Continuous { singular_full: c(0.05), singular_start: c(0.15) };
            let config = HierarchyConfig {
                recursion,
                weighting: Weighting::InverseInertia(&inverse),
                shaping,
                diagnose_last_level: true,
            };
            let mut with = HierarchyData::<T, N, 16, 4>::default();
            let mut without = HierarchyData::<T, N, 16, 4>::default();
            let a = *project(&config, &carried, &mut with).unwrap();
            let b = *project(&config, &plain, &mut without).unwrap();
            let r = reference::project_reference::<T, N, 16, 16, 4>(&config, &plain).torque;
            let scale = 1.0 + f(b.amax());
            for ((a, b), r) in a.iter().zip(b.iter()).zip(r.iter()) {
                assert!(f((*a - *b).abs()) <= tolerance * scale, "{recursion:?}: {a} vs {b}");
                assert!(f((*a - *r).abs()) <= tolerance * scale, "{recursion:?}: {a} vs reference {r}");
            }
            for (x, y) in with.rows.iter().zip(&without.rows).take(carried.rows().len()) {
                assert!(f((x.projected_norm_ratio - y.projected_norm_ratio).abs()) <= tolerance);
                assert!(f((x.activation - y.activation).abs()) <= tolerance);
            }
            // Another weighting ignores the carried values.
            let identity = HierarchyConfig { weighting: Weighting::Identity, ..config };
            let a = *project(&identity, &carried, &mut with).unwrap();
            let b = *project(&identity, &plain, &mut without).unwrap();
            assert_eq!(a, b);
            compared += 1;
        }
        compared
    }
    let mut compared = 0;
    for seed in 0..30 {
        compared += check::<f64>(seed, 1e-9);
        compared += check::<f32>(seed, 2e-3);
    }
    assert_eq!(compared, 120);
}

/// Rows written through a window's `push_with` carry their columns
/// ([`StackRow::support`](crate::hierarchy::StackRow)), and a level's task torque is added over
/// them only: the projection equals that of the same rows pushed whole (support all columns)
/// bit for bit — torque, projector and every diagnostic —, with the sparse rows on the first,
/// a middle and the last level, with and without last-level diagnostics, for every weighting
/// and recursion.
#[test]
fn rows_with_a_support_project_as_the_same_rows_pushed_whole() {
    use crate::tasks::RowSink;
    let factor = mass_factor(2);
    let mut rng = reference::TestRng::new(77);
    let mut narrow = 0;
    for case in 0..24 {
        let levels = [case % 3, 1 + case % 2, 2];
        let (mut sparse, mut whole) = (Stack::<f64, N, 16>::new(), Stack::<f64, N, 16>::new());
        for stack in [&mut sparse, &mut whole] {
            stack.push(0, row(RowSVector::from_fn(|_, c| (c + case) as f64 * 0.3 - 0.7), 4.0)).unwrap();
        }
        for &level in &levels {
            let mut window = sparse.task::<8>();
            let mut rows = std::vec::Vec::new();
            for _ in 0..4 {
                let first = (rng.symmetric().abs() * N as f64) as usize % N;
                let end = (first + 1 + (rng.symmetric().abs() * 3.0) as usize).min(N);
                let values: std::vec::Vec<f64> = (first..end).map(|_| 2.0 * rng.symmetric()).collect();
                let (force, activation) = (10.0 * rng.symmetric(), rng.symmetric().abs());
                window
                    .push_with(first..end, |r| {
                        r.jacobian.copy_from_slice(&values);
                        r.force = force;
                        r.activation = activation;
                    })
                    .unwrap();
                let j = RowSVector::from_fn(|_, c| if (first..end).contains(&c) { values[c - first] } else { 0.0 });
                rows.push(TaskRow { jacobian: j, force, potential: 0.0, activation });
                narrow += usize::from(end - first < N);
            }
            window.place(level).unwrap();
            for r in rows {
                whole.push(level, r).unwrap();
            }
        }
        assert!(sparse.rows().iter().skip(1).all(|r| r.support != (0, N)));
        for weighting in [Weighting::Identity, Weighting::Inertia(&factor), Weighting::AccelerationBased(&factor)] {
            for recursion in [Recursion::Augmented, Recursion::Successive] {
                for diagnose_last_level in [false, true] {
                    let cfg = HierarchyConfig { diagnose_last_level, ..config(recursion, weighting) };
                    let (mut a, mut b) =
                        (HierarchyData::<f64, N, 16, 4>::default(), HierarchyData::<f64, N, 16, 4>::default());
                    let torque = *project(&cfg, &sparse, &mut a).unwrap();
                    assert_eq!(torque, *project(&cfg, &whole, &mut b).unwrap(), "case {case}");
                    assert_eq!((a.projector, a.rows, a.level_torques), (b.projector, b.rows, b.level_torques));
                }
            }
        }
    }
    assert!(narrow > 80, "{narrow} narrow rows");
}
