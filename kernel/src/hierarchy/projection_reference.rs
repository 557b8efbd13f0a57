//! The plain scalar-inverse projector recursion: the straightforward nalgebra form of
//! `project` it replaced (the rank-one updates of (4.13) with `W⁻¹` applied by
//! full Cholesky solves, every product a generic nalgebra one). Test builds only: it is the
//! reference the fast recursion is compared with (kernel unit tests on the small test models,
//! `thesis-tests` on the Justin model, which include this file by path).
//!
//! The including module provides the names it uses (`use super::*`): nalgebra's `RealField`,
//! `RowSVector`, `SMatrix`, `SVector`, the hierarchy's `HierarchyConfig`, `HierarchyData`,
//! `Recursion`, `Shaping`, `Stack`, `Weighting`, `RowDiagnostics`, `LevelDiagnostics`,
//! `push_transitioning`, the tasks' `TaskRow` and `TaskRows`; and a
//! function `project` with the signature of the kernel's.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "test support: a failure is a test failure")]

use super::*;

/// Everything the reference projection produces (the outputs of `HierarchyData`).
#[derive(Clone, Debug)]
pub struct ReferenceOutput<T: RealField, const N: usize, const R: usize, const L: usize> {
    /// Accumulated projector after the last level.
    pub projector: SMatrix<T, N, N>,
    /// `τ = Σ_i N_i τ_i` (4.7).
    pub torque: SVector<T, N>,
    /// Per-row diagnostics, stack order processed level by level.
    pub rows: [RowDiagnostics<T>; R],
    /// Per-level diagnostics.
    pub levels: [LevelDiagnostics<T>; L],
    /// Projected torque of each level.
    pub level_torques: [SVector<T, N>; L],
    /// Number of levels.
    pub level_count: usize,
}

/// The reference recursion for a valid stack (at most `R` rows, levels below `L`; the caller
/// checks this, no validation here).
pub fn project_reference<T: RealField + Copy, const N: usize, const R: usize, const RS: usize, const L: usize>(
    config: &HierarchyConfig<'_, T, N>,
    stack: &Stack<T, N, RS>,
) -> ReferenceOutput<T, N, R, L> {
    let mut data = ReferenceOutput {
        projector: SMatrix::identity(),
        torque: SVector::zeros(),
        rows: [RowDiagnostics { level: 0, activation: T::zero(), projected_norm_ratio: T::zero(), transmission: None };
            R],
        levels: [LevelDiagnostics { torque_norm: T::zero(), projected_torque_norm: T::zero(), conflict: T::zero() }; L],
        level_torques: [SVector::zeros(); L],
        level_count: stack.level_count(),
    };
    let mut level_projector = SMatrix::<T, N, N>::identity();
    let level_count = stack.level_count();
    let mut diagnostics = data.rows.iter_mut();
    for (level, (level_diagnostics, level_torque)) in
        data.levels.iter_mut().zip(data.level_torques.iter_mut()).enumerate().take(level_count)
    {
        let on_level = || stack.rows().iter().filter(move |r| r.level == level);
        let input = data.projector;
        let torque: SVector<T, N> =
            on_level().fold(SVector::zeros(), |t, r| t + r.row.jacobian.transpose() * r.row.force);
        let projected = apply_projector(&config.weighting, &input, &torque);
        data.torque += projected;
        *level_torque = projected;
        *level_diagnostics = level_result(&torque, &projected);

        if config.recursion == Recursion::Successive {
            level_projector = SMatrix::identity();
        }
        let last = level + 1 == level_count;
        for stack_row in on_level() {
            if last && !config.diagnose_last_level {
                if let Some(slot) = diagnostics.next() {
                    *slot = RowDiagnostics {
                        level,
                        activation: stack_row.row.activation,
                        projected_norm_ratio: T::zero(),
                        transmission: None,
                    };
                }
                continue;
            }
            let working = match config.recursion {
                Recursion::Successive => &mut level_projector,
                Recursion::Augmented | Recursion::Unprojected => &mut data.projector,
            };
            let mut row =
                update_row(config, &input, working, stack_row.row.jacobian.transpose(), stack_row.row.activation);
            row.level = level;
            if let Some(slot) = diagnostics.next() {
                *slot = row;
            }
        }
        if config.recursion == Recursion::Successive {
            data.projector *= level_projector;
        }
    }
    data
}

fn update_row<T: RealField + Copy, const N: usize>(
    config: &HierarchyConfig<'_, T, N>,
    input: &SMatrix<T, N, N>,
    working: &mut SMatrix<T, N, N>,
    row: SVector<T, N>,
    task_activation: T,
) -> RowDiagnostics<T> {
    let transmission = transmission(&config.weighting, input, &row);
    let reference = row.dot(&metric_solve(&config.weighting, &row));
    let projected = *working * row;
    let w = metric_solve(&config.weighting, &projected);
    let s = projected.dot(&w);
    if !reference.is_finite() || reference <= T::zero() {
        return RowDiagnostics {
            level: 0,
            activation: T::zero(),
            projected_norm_ratio: T::zero(),
            transmission: Some(transmission),
        };
    }
    let ratio = (s.max(T::zero()) / reference).sqrt();
    let activation = config.shaping.row_activation(task_activation, ratio);
    if activation > T::zero() && s > T::zero() && config.recursion != Recursion::Unprojected {
        let u = *working * projected;
        *working -= u * (w.transpose() * (activation / s));
    }
    RowDiagnostics { level: 0, activation, projected_norm_ratio: ratio, transmission: Some(transmission) }
}

fn transmission<T: RealField + Copy, const N: usize>(
    weighting: &Weighting<'_, T, N>,
    input: &SMatrix<T, N, N>,
    row: &SVector<T, N>,
) -> T {
    let row_norm = row.norm();
    if row_norm > T::zero() {
        apply_projector(weighting, input, row).norm() / row_norm
    } else {
        T::one()
    }
}

fn metric_solve<T: RealField + Copy, const N: usize>(
    weighting: &Weighting<'_, T, N>,
    x: &SVector<T, N>,
) -> SVector<T, N> {
    match weighting {
        Weighting::Identity | Weighting::AccelerationBased(_) => *x,
        Weighting::Inertia(factor) | Weighting::Stiffness(factor) => factor.solve(x),
        Weighting::InverseInertia(inverse) => *inverse * x,
    }
}

fn apply_projector<T: RealField + Copy, const N: usize>(
    weighting: &Weighting<'_, T, N>,
    projector: &SMatrix<T, N, N>,
    torque: &SVector<T, N>,
) -> SVector<T, N> {
    match weighting {
        Weighting::AccelerationBased(mass) => {
            let l = mass.l();
            l * (l.transpose() * (projector * mass.solve(torque)))
        }
        _ => projector * torque,
    }
}

fn level_result<T: RealField + Copy, const N: usize>(
    torque: &SVector<T, N>,
    projected: &SVector<T, N>,
) -> LevelDiagnostics<T> {
    let (torque_norm, projected_torque_norm) = (torque.norm(), projected.norm());
    let conflict = if torque_norm > T::zero() {
        (T::one() - projected_torque_norm / torque_norm).max(T::zero()).min(T::one())
    } else {
        T::zero()
    };
    LevelDiagnostics { torque_norm, projected_torque_norm, conflict }
}

// --- comparison support: random stacks and the fast-vs-reference check ---------------------

/// A xorshift generator for reproducible random test data.
pub struct TestRng(u64);

impl TestRng {
    /// A generator from a seed (any value).
    pub fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }

    /// Uniform in `[0, 1)`.
    pub fn unit(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[-1, 1)`.
    pub fn symmetric(&mut self) -> f64 {
        2.0 * self.unit() - 1.0
    }

    /// Uniform in `0..n`.
    pub fn below(&mut self, n: usize) -> usize {
        ((self.unit() * n as f64) as usize).min(n.saturating_sub(1))
    }
}

/// A random symmetric positive definite matrix `A Aᵀ + I/2`.
pub fn random_spd<const N: usize>(rng: &mut TestRng) -> SMatrix<f64, N, N> {
    let a = SMatrix::<f64, N, N>::from_fn(|_, _| rng.symmetric());
    a * a.transpose() + SMatrix::identity() * 0.5
}

/// A random stack on `levels` levels (2–4 rows each, at most `RS` rows in all): dense rows,
/// sparse rows (most entries zero, as a kinematic chain's), joint rows `α e_bᵀ`, zero rows, rows nearly dependent
/// on earlier ones (a combination of two earlier rows plus a `1e-9` perturbation: an
/// algorithmic singularity) and rows with task activations in `(0, 1)`; plus, when there is
/// room, a two-row task in transition between two levels (forces and activations scaled by
/// the transition weight of a progress in `(0, 1)`).
pub fn random_stack<const N: usize, const RS: usize>(rng: &mut TestRng, levels: usize) -> Stack<f64, N, RS> {
    let mut stack = Stack::new();
    let mut earlier: [RowSVector<f64, N>; RS] = [RowSVector::zeros(); RS];
    let mut count = 0;
    for level in 0..levels {
        let rows = 2 + rng.below(3);
        for _ in 0..rows {
            if count + 2 >= RS {
                break;
            }
            let mut activation = 1.0;
            let jacobian = match rng.below(6) {
                0 => RowSVector::zeros(),
                1 if count >= 2 => {
                    let (a, b) = (earlier[rng.below(count)], earlier[rng.below(count)]);
                    a * rng.symmetric() + b * rng.symmetric() + RowSVector::from_fn(|_, _| 1e-9 * rng.symmetric())
                }
                2 => RowSVector::from_fn(|_, _| if rng.unit() < 0.3 { rng.symmetric() } else { 0.0 }),
                3 => {
                    activation = rng.unit();
                    RowSVector::from_fn(|_, _| rng.symmetric())
                }
                // A joint row `α e_bᵀ` (its transmission is a column norm of the input projector).
                5 => {
                    let (b, alpha) = (rng.below(N), 3.0 * rng.symmetric());
                    RowSVector::from_fn(|_, c| if c == b { alpha } else { 0.0 })
                }
                _ => RowSVector::from_fn(|_, _| rng.symmetric()),
            };
            earlier[count] = jacobian;
            count += 1;
            let row = TaskRow { jacobian, force: 10.0 * rng.symmetric(), potential: 0.0, activation };
            stack.push(level, row).unwrap();
        }
    }
    if levels >= 2 && count + 4 <= RS {
        let mut task = TaskRows::<f64, N, 2>::new();
        for _ in 0..2 {
            let jacobian = RowSVector::from_fn(|_, _| rng.symmetric());
            task.push(TaskRow { jacobian, force: 5.0 * rng.symmetric(), potential: 0.0, activation: 1.0 }).unwrap();
        }
        let (from, to) = (rng.below(levels), rng.below(levels));
        push_transitioning(&mut stack, &task, from, to, 0.05 + 0.9 * rng.unit()).unwrap();
    }
    stack
}

/// The stack in another scalar.
pub fn cast_stack<T: RealField + Copy, const N: usize, const RS: usize>(stack: &Stack<f64, N, RS>) -> Stack<T, N, RS> {
    let mut cast = Stack::new();
    for r in stack.rows() {
        let row = TaskRow {
            jacobian: r.row.jacobian.map(nalgebra::convert::<f64, T>),
            force: nalgebra::convert(r.row.force),
            potential: nalgebra::convert(r.row.potential),
            activation: nalgebra::convert(r.row.activation),
        };
        cast.push(r.level, row).unwrap();
    }
    cast
}

/// Number of configurations [`outputs`] runs: recursion (none, successive, augmented) ×
/// weighting (`W = I`, `M`, `K`, acceleration-based) × shaping (continuous, classical) × last-level
/// diagnostics (off, on).
pub const CONFIGURATIONS: usize = 48;

/// Outputs of one projection as named lists of numbers: torque, projector, level torques,
/// level diagnostics, row activations, norm ratios and transmissions (row levels and the level
/// count are compared exactly by [`outputs`] itself).
pub type Outputs = std::vec::Vec<(&'static str, std::vec::Vec<f64>)>;

/// Runs configuration `index < CONFIGURATIONS` on `stack` (cast to `T`) with the fast `project`
/// and with [`project_reference`]; returns a description and both outputs.
pub fn outputs<T: RealField + Copy, const N: usize, const RS: usize, const R: usize, const L: usize>(
    stack: &Stack<f64, N, RS>,
    mass: &SMatrix<f64, N, N>,
    stiffness: &SMatrix<f64, N, N>,
    index: usize,
) -> (std::string::String, Outputs, Outputs) {
    let stack = cast_stack::<T, N, RS>(stack);
    let mass_factor = nalgebra::Cholesky::new(mass.map(nalgebra::convert::<f64, T>)).unwrap();
    let stiffness_factor = nalgebra::Cholesky::new(stiffness.map(nalgebra::convert::<f64, T>)).unwrap();
    let c = nalgebra::convert::<f64, T>;
    let recursion = [Recursion::Unprojected, Recursion::Successive, Recursion::Augmented][index % 3];
    let weighting = [
        Weighting::Identity,
        Weighting::Inertia(&mass_factor),
        Weighting::Stiffness(&stiffness_factor),
        Weighting::AccelerationBased(&mass_factor),
    ][index / 3 % 4];
    let shaping = [
        Shaping::Continuous { singular_full: c(0.05), singular_start: c(0.15) },
        Shaping::Discontinuous { singular_threshold: c(0.01) },
    ][index / 12 % 2];
    let diagnose_last_level = index / 24 % 2 == 1;
    let config = HierarchyConfig { recursion, weighting, shaping, diagnose_last_level };
    let what = std::format!(
        "{recursion:?} {} {shaping:?} diagnose {diagnose_last_level}",
        ["W = I", "W = M", "W = K", "acceleration-based"][index / 3 % 4]
    );
    let mut fast = HierarchyData::<T, N, R, L>::default();
    project(&config, &stack, &mut fast).unwrap();
    let reference = project_reference::<T, N, R, RS, L>(&config, &stack);
    assert_eq!(fast.level_count, reference.level_count, "{what}");
    let rows = stack.rows().len();
    for (f, r) in fast.rows.iter().zip(&reference.rows).take(rows) {
        assert_eq!(f.level, r.level, "{what}");
    }
    let f64s = |x: &[T]| x.iter().map(|v| nalgebra::try_convert::<T, f64>(*v).unwrap()).collect::<std::vec::Vec<_>>();
    let flatten = |torque: &SVector<T, N>,
                   projector: &SMatrix<T, N, N>,
                   level_torques: &[SVector<T, N>],
                   levels: &[LevelDiagnostics<T>],
                   row_diagnostics: &[RowDiagnostics<T>]| {
        let count = reference.level_count;
        let level_torques: std::vec::Vec<T> =
            level_torques.iter().take(count).flat_map(|t| t.as_slice().iter().copied()).collect();
        let level_norms: std::vec::Vec<T> =
            levels.iter().take(count).flat_map(|l| [l.torque_norm, l.projected_torque_norm]).collect();
        let conflicts: std::vec::Vec<T> = levels.iter().take(count).map(|l| l.conflict).collect();
        let row = |f: fn(&RowDiagnostics<T>) -> T| {
            f64s(&row_diagnostics.iter().take(rows).map(f).collect::<std::vec::Vec<_>>())
        };
        std::vec![
            ("torque", f64s(torque.as_slice())),
            ("projector", f64s(projector.as_slice())),
            ("level torques", f64s(&level_torques)),
            ("level torque norms", f64s(&level_norms)),
            ("level conflicts", f64s(&conflicts)),
            ("row activations", row(|r| r.activation)),
            ("row norm ratios", row(|r| r.projected_norm_ratio)),
            // −1 (no ratio of norms is negative): a row that forms none.
            ("row transmissions", row(|r| r.transmission.unwrap_or(-T::one()))),
        ]
    };
    let fast_outputs = flatten(&fast.torque, &fast.projector, &fast.level_torques, &fast.levels, &fast.rows);
    let reference_outputs =
        flatten(&reference.torque, &reference.projector, &reference.level_torques, &reference.levels, &reference.rows);
    (what, fast_outputs, reference_outputs)
}

/// Largest difference of two lists relative to `1 + ` the largest magnitude of `b`.
pub fn scaled_difference(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(1.0_f64, |m, x| m.max(x.abs()));
    a.iter().zip(b).fold(0.0, |m, (x, y)| m.max((x - y).abs() / scale))
}

/// Every configuration in `f64`: fast and reference outputs agree within `tolerance` (scaled
/// by [`scaled_difference`]). Returns the largest difference.
pub fn compare_f64<const N: usize, const RS: usize, const R: usize, const L: usize>(
    stack: &Stack<f64, N, RS>,
    mass: &SMatrix<f64, N, N>,
    stiffness: &SMatrix<f64, N, N>,
    tolerance: f64,
) -> f64 {
    let mut worst = 0.0_f64;
    for index in 0..CONFIGURATIONS {
        let (what, fast, reference) = outputs::<f64, N, RS, R, L>(stack, mass, stiffness, index);
        for ((name, a), (_, b)) in fast.iter().zip(&reference) {
            let difference = scaled_difference(a, b);
            assert!(difference <= tolerance, "{what}: {name} differs by {difference:e}");
            worst = worst.max(difference);
        }
    }
    worst
}

/// Every configuration in `f32`, judged against the `f64` reference: the fast recursion's
/// error is at most `factor` times the `f32` reference's own error plus `floor · κ` (both
/// scaled by [`scaled_difference`]), where `κ = 1/ρ²` of the most nearly dependent row that
/// locks (`1/s` amplifies rounding by up to that much; 1 if none). Returns the largest
/// difference between the fast and the reference `f32` outputs.
pub fn compare_f32<const N: usize, const RS: usize, const R: usize, const L: usize>(
    stack: &Stack<f64, N, RS>,
    mass: &SMatrix<f64, N, N>,
    stiffness: &SMatrix<f64, N, N>,
    factor: f64,
    floor: f64,
) -> f64 {
    let mut worst = 0.0_f64;
    for index in 0..CONFIGURATIONS {
        let (what, fast, reference) = outputs::<f32, N, RS, R, L>(stack, mass, stiffness, index);
        let (_, _, exact) = outputs::<f64, N, RS, R, L>(stack, mass, stiffness, index);
        let activations = &exact[5].1;
        let ratios = &exact[6].1;
        let amplification = activations
            .iter()
            .zip(ratios)
            .filter(|(a, _)| **a > 0.0)
            .fold(1.0_f64, |k, (_, r)| k.max(1.0 / (r * r).max(1e-4)));
        for (((name, a), (_, b)), (_, e)) in fast.iter().zip(&reference).zip(&exact) {
            let (fast_error, reference_error) = (scaled_difference(a, e), scaled_difference(b, e));
            assert!(
                fast_error <= factor * reference_error + floor * amplification,
                "{what}: {name} off the f64 result by {fast_error:e} (the f32 reference by {reference_error:e})"
            );
            worst = worst.max(scaled_difference(a, b));
        }
    }
    worst
}
