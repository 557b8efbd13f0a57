//! Host benchmarks of the multi-level compliance controller (Sec. 5.2, (5.58)–(5.60)) with the
//! three-level hierarchy of Table 5.6 (TCP translation, TCP orientation, joint compliance on
//! every coordinate):
//! - `arm7`: the 7-DOF right arm of the Justin-like robot
//!   (`host_sim::scenarios::multilevel_arm::right_arm_model`, 3 + 3 + 7 rows, a one-dimensional
//!   last level);
//! - `justin20`: the whole 20-DOF Justin-like robot (`fixtures::justin`), right TCP, 3 + 3 + 20
//!   rows, a 14-dimensional last level.
//!
//! What each benchmark times:
//! - `<robot>/controller_step`: one full `ArmHierarchy::step` — forward kinematics, CRBA,
//!   Coriolis matrix, gravity, Cholesky factor, TCP Jacobian and its derivative, the Cartesian
//!   tasks (with their double-diagonalisation damping) and the joint task, the row rates, and
//!   `multilevel_control` (decomposition with `Ż`, projected torques, `τ_μ`, storage functions);
//! - `<robot>/multilevel_control`: the kernel's control law alone on the same rows and model
//!   terms;
//! - `<robot>/decompose`: the hierarchical dynamics representation alone (`Z`, `Ż`, `J̄`, `Λ`);
//! - `<robot>/coriolis_decoupling`: `τ_μ` alone, given the decomposition.
//!
//! Run with `cargo bench -p host-sim --bench multilevel`. Host figures only.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use host_sim::scenarios::multilevel_arm::{arm_home, right_arm_model, ArmHierarchy};
use kernel::dynamics::{coriolis_matrix, crba, forward_kinematics, gravity, mass_matrix_cholesky};
use kernel::hierarchy::multilevel::{
    coriolis_decoupling, decompose, multilevel_control, Decomposition, DynamicsTerms, MultilevelConfig, MultilevelData,
};
use kernel::model::{Data, FrameId, Model, Placement};
use nalgebra::{SVector, Translation3, Vector3};

/// A moving, non-special state around `q0`: `q_k = q0_k + 0.2 sin(1.7 k + 0.4)`,
/// `q̇_k = 0.5 cos(0.9 k)`.
fn state<const N: usize>(q0: &SVector<f64, N>) -> (SVector<f64, N>, SVector<f64, N>) {
    let k = |i: usize| f64::from(u32::try_from(i).unwrap_or(0));
    let q = q0 + SVector::<f64, N>::from_fn(|i, _| 0.2 * (1.7 * k(i) + 0.4).sin());
    let v = SVector::<f64, N>::from_fn(|i, _| 0.5 * (0.9 * k(i)).cos());
    (q, v)
}

fn bench<const N: usize, const B: usize, const F: usize>(
    c: &mut Criterion,
    name: &str,
    model: Model<f64, N, B, F>,
    tcp: FrameId,
    q0: &SVector<f64, N>,
) {
    let (q, v) = state(q0);
    let mut data = Data::new(&model);
    if forward_kinematics(&model, &mut data, &q, &v).is_err() {
        return;
    }
    let Some(pose) = data.frame_placements.get(tcp.0).copied() else {
        return;
    };
    let target = Placement::from_parts(
        Translation3::from(pose.translation.vector + Vector3::new(0.03, -0.02, 0.01)),
        pose.rotation,
    );
    let Ok(mut controller) = ArmHierarchy::new(model.clone(), tcp, target, q + SVector::repeat(0.1)) else {
        eprintln!("skipping {name}: controller");
        return;
    };
    if let Err(e) = controller.step(&q, &v) {
        eprintln!("skipping {name}: {e}");
        return;
    }
    let mut group = c.benchmark_group(name);
    group.bench_function("controller_step", |b| b.iter(|| controller.step(black_box(&q), black_box(&v)).map(|t| t[0])));

    let mass = *crba(&model, &mut data);
    let coriolis = *coriolis_matrix(&model, &mut data);
    let g = *gravity(&model, &mut data);
    let Ok(factor) = mass_matrix_cholesky(&data) else {
        return;
    };
    let terms =
        DynamicsTerms { mass_matrix: &mass, mass_factor: &factor, coriolis: &coriolis, gravity: &g, velocity: &v };
    let config = MultilevelConfig::default();
    let stack = controller.stack().clone();
    let mut out = MultilevelData::<f64, N, 3>::default();
    group.bench_function("multilevel_control", |b| {
        b.iter(|| multilevel_control(&config, black_box(&stack), black_box(&terms), &mut out).map(|t| t[0]));
    });
    let mut decomposition = Decomposition::<f64, N, 3>::default();
    group.bench_function("decompose", |b| {
        b.iter(|| {
            decompose(&config, black_box(&stack), black_box(&terms), &mut decomposition).map(|d| d.level_count())
        });
    });
    group.bench_function("coriolis_decoupling", |b| {
        b.iter(|| coriolis_decoupling(black_box(&decomposition), black_box(&terms)))
    });
    group.finish();
}

fn multilevel(c: &mut Criterion) {
    match right_arm_model() {
        Ok((arm, tcp)) => bench(c, "arm7", arm, tcp, &arm_home()),
        Err(e) => eprintln!("skipping arm7: {e}"),
    }
    match fixtures::justin::model::<f64>() {
        Ok(robot) => bench(c, "justin20", robot, fixtures::justin::RIGHT_TCP, &fixtures::justin::home_configuration()),
        Err(e) => eprintln!("skipping justin20: {e}"),
    }
}

criterion_group!(benches, multilevel);
criterion_main!(benches);
