//! Host benchmark of one full projection ([`kernel::hierarchy::project`]) of a 20-DOF,
//! 40-row stack: four levels of ten rows, for every recursion × weighting.
//!
//! The rows are Justin-derived (`fixtures::justin` at its home pose, slightly moved): level 1
//! the right TCP pose (6) and the left TCP position (3) and x-rotation (1); level 2 the left
//! TCP y/z rotation (2), the right hand pose (6) and the chest position x/y (2); levels 3 and 4
//! joint rows (torso and arm joints, ten each). `W = M` is the robot's inertia at that pose,
//! `W = K` a diagonal joint stiffness; both Cholesky factors are computed outside the timed
//! loop (the controller needs `M`'s factor anyway). The timed call is `project` alone: the
//! level torques, the row-by-row rank-one projector updates (with the `W⁻¹` solves), the
//! diagnostics.
//!
//! What the figures mean: the cost is O(R N²). Successive recursions update their level
//! projector for every row. Augmented ones skip the rank-one update of a row whose projected
//! norm ratio has faded out (dependent on the rows above: with 40 rows on 20 DOF at least the
//! last 20 are), so they are cheaper per row there — a worst-case bound must count every row
//! as active. Unprojected skips all updates.
//!
//! Run with `cargo bench -p host-sim --bench hierarchy`.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use fixtures::justin;
use kernel::dynamics::{crba, forward_kinematics, frame_jacobian, mass_matrix_cholesky};
use kernel::hierarchy::{project, HierarchyConfig, HierarchyData, Recursion, Shaping, Stack, Weighting};
use kernel::math::CholeskyFactor;
use kernel::model::{Data, FrameId};
use kernel::tasks::TaskRow;
use nalgebra::{Cholesky, RowSVector, SMatrix, SVector};

const N: usize = 20;
const ROWS: usize = 40;
const LEVELS: usize = 4;

/// Justin at home moved by `0.2 sin(1.3 k + 0.5)`.
fn configuration() -> SVector<f64, N> {
    justin::home_configuration::<f64>()
        + SVector::<f64, N>::from_fn(|k, _| 0.2 * (1.3 * f64::from(u8::try_from(k).unwrap_or(0)) + 0.5).sin())
}

fn rows_of(
    model: &justin::JustinModel<f64>,
    data: &Data<f64, N, { justin::BODIES }, { justin::FRAMES }>,
    frame: FrameId,
    rows: &[usize],
) -> Vec<RowSVector<f64, N>> {
    let mut j = SMatrix::<f64, 6, N>::zeros();
    let _ = frame_jacobian(model, data, frame, &mut j);
    rows.iter().map(|r| j.row(*r).into_owned()).collect()
}

/// The 40-row stack and the factors of `M` and `K`.
fn setup() -> (Stack<f64, N, ROWS>, CholeskyFactor<f64, N>, CholeskyFactor<f64, N>) {
    let Ok(model) = justin::model::<f64>() else {
        std::process::exit(1);
    };
    let mut data = Data::new(&model);
    let _ = forward_kinematics(&model, &mut data, &configuration(), &SVector::zeros());
    crba(&model, &mut data);
    let Ok(mass) = mass_matrix_cholesky(&data) else {
        std::process::exit(1);
    };
    let stiffness = SMatrix::<f64, N, N>::from_diagonal(&SVector::from_fn(|k, _| {
        100.0 + 20.0 * f64::from(u8::try_from(k).unwrap_or(0))
    }));
    let Some(stiffness) = Cholesky::new(stiffness) else {
        std::process::exit(1);
    };
    let unit = |k: usize| RowSVector::<f64, N>::from_fn(|_, c| if c == k { 1.0 } else { 0.0 });
    let mut levels: [Vec<RowSVector<f64, N>>; LEVELS] = Default::default();
    levels[0].extend(rows_of(&model, &data, justin::RIGHT_TCP, &[0, 1, 2, 3, 4, 5]));
    levels[0].extend(rows_of(&model, &data, justin::LEFT_TCP, &[0, 1, 2, 3]));
    levels[1].extend(rows_of(&model, &data, justin::LEFT_TCP, &[4, 5]));
    levels[1].extend(rows_of(&model, &data, justin::RIGHT_HAND, &[0, 1, 2, 3, 4, 5]));
    levels[1].extend(rows_of(&model, &data, justin::TORSO_TOP, &[0, 1]));
    levels[2].extend((3..13).map(unit));
    levels[3].extend((10..20).map(unit));
    let mut stack = Stack::new();
    for (level, rows) in levels.iter().enumerate() {
        for (k, j) in rows.iter().enumerate() {
            let force = 5.0 * (0.7 * f64::from(u8::try_from(level * 10 + k).unwrap_or(0))).cos();
            let _ = stack.push(level, TaskRow { jacobian: *j, force, potential: 0.0, activation: 1.0 });
        }
    }
    (stack, mass, stiffness)
}

fn projections(c: &mut Criterion) {
    let (stack, mass, stiffness) = setup();
    let shaping = Shaping::Continuous { singular_full: 0.02, singular_start: 0.05 };
    let variants: [(&str, Recursion, Weighting<'_, f64, N>); 9] = [
        ("unprojected", Recursion::Unprojected, Weighting::Identity),
        ("successive_static", Recursion::Successive, Weighting::Identity),
        ("successive_dynamic", Recursion::Successive, Weighting::Inertia(&mass)),
        ("successive_stiffness", Recursion::Successive, Weighting::Stiffness(&stiffness)),
        ("successive_accel", Recursion::Successive, Weighting::AccelerationBased(&mass)),
        ("augmented_static", Recursion::Augmented, Weighting::Identity),
        ("augmented_dynamic", Recursion::Augmented, Weighting::Inertia(&mass)),
        ("augmented_stiffness", Recursion::Augmented, Weighting::Stiffness(&stiffness)),
        ("augmented_accel", Recursion::Augmented, Weighting::AccelerationBased(&mass)),
    ];
    let mut group = c.benchmark_group("hierarchy_20dof_40rows");
    for (name, recursion, weighting) in variants {
        let config = HierarchyConfig { recursion, weighting, shaping, diagnose_last_level: true };
        let mut data = HierarchyData::<f64, N, ROWS, LEVELS>::default();
        group.bench_function(name, |b| {
            b.iter(|| project(black_box(&config), black_box(&stack), &mut data).map(|t| t.sum()));
        });
    }
    group.finish();
}

criterion_group!(benches, projections);
criterion_main!(benches);
