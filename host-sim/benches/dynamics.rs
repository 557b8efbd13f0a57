//! Host benchmarks of the kernel's dynamics algorithms on the Justin-like robot
//! (`fixtures::justin`, N = 20, 21 bodies) and the Franka Panda (`fixtures/urdf/panda.urdf`
//! through `host_sim::urdf`, N = 9 with the two finger joints, 9 bodies), plus one simulator
//! physics step and one controller step on Justin.
//!
//! What each benchmark times:
//! - `<robot>/forward_kinematics`: `forward_kinematics(q, q̇)` alone.
//! - `<robot>/crba`, `rnea`, `coriolis_matrix`, `frame_jacobian`: the algorithm **alone**,
//!   after one `forward_kinematics` at the same state outside the timed loop (every one of them
//!   needs it; add the `forward_kinematics` figure for the cost from a fresh state).
//! - `<robot>/placement_kinematics`, `support_kinematics`: the position-only passes alone
//!   (every body; the support of the TCP's body).
//! - `<robot>/fk+crba`, `fk+rnea`, `fk+coriolis_matrix`, `fk+frame_jacobian`: the kinematics
//!   each algorithm needs followed by the algorithm, the work Pinocchio's `crba(q)`,
//!   `rnea(q, v, a)`, `computeCoriolisMatrix(q, v)` and `computeFrameJacobian(q, frame)` do
//!   (compare with `fixtures/pinocchio/bench_pinocchio.sh` run on the same machine):
//!   `placement_kinematics` before CRBA (placements and inertias, as Pinocchio's `crba`),
//!   `forward_kinematics` before RNEA and the Coriolis matrix (they need velocities),
//!   `support_kinematics` of the frame's body before the frame Jacobian (as Pinocchio's
//!   `computeFrameJacobian`, which walks the frame's support only).
//! - `justin/sim_physics_step`: one RK4 physics step of `host_sim::sim::Simulator` (four
//!   evaluations of kinematics, RNEA, CRBA and a 17×17 Cholesky solve).
//! - `justin/cartesian_impedance_step`: one `CartesianJointImpedance::step` through the `hal`
//!   traits (read, kinematics, gravity, Jacobian, CRBA, Cholesky, write).
//!
//! Run with `cargo bench -p host-sim --bench dynamics`. Host figures only; the real-time
//! figures of the board come from the firmware benchmark.

use std::hint::black_box;
use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion};
use host_sim::controllers::{CartesianJointGains, CartesianJointImpedance};
use host_sim::sim::{SimConfig, Simulator};
use host_sim::urdf::{load, Coupling};
use kernel::dynamics::{
    coriolis_matrix, crba, forward_kinematics, frame_jacobian, placement_kinematics, rnea, support_kinematics,
};
use kernel::model::{Data, FrameId, Model};
use nalgebra::{SMatrix, SVector};

/// Links of the Panda URDF (every link is a frame).
const PANDA_FRAMES: usize = 13;

/// A deterministic, non-special state: `q_k = 0.3 sin(1.7 k + 0.4)`, `q̇_k = 0.5 cos(0.9 k)`,
/// `q̈_k = 0.2 sin(2.3 k)` added to `q0`.
fn state<const N: usize>(q0: &SVector<f64, N>) -> (SVector<f64, N>, SVector<f64, N>, SVector<f64, N>) {
    let k = |i: usize| f64::from(u32::try_from(i).unwrap_or(0));
    let q = q0 + SVector::<f64, N>::from_fn(|i, _| 0.3 * (1.7 * k(i) + 0.4).sin());
    let v = SVector::<f64, N>::from_fn(|i, _| 0.5 * (0.9 * k(i)).cos());
    let a = SVector::<f64, N>::from_fn(|i, _| 0.2 * (2.3 * k(i)).sin());
    (q, v, a)
}

fn algorithms<const N: usize, const B: usize, const F: usize>(
    c: &mut Criterion,
    robot: &str,
    model: &Model<f64, N, B, F>,
    q0: &SVector<f64, N>,
    tcp: FrameId,
) {
    let (q, v, a) = state(q0);
    let mut data = Data::new(model);
    let mut group = c.benchmark_group(robot);
    group.bench_function("forward_kinematics", |b| {
        b.iter(|| forward_kinematics(model, &mut data, black_box(&q), black_box(&v)));
    });
    group.bench_function("placement_kinematics", |b| {
        b.iter(|| placement_kinematics(model, &mut data, black_box(&q)));
    });
    let Some(tcp_body) = model.frame(tcp).and_then(|f| f.parent) else {
        eprintln!("skipping {robot}: the TCP frame is not attached to a body");
        return;
    };
    group.bench_function("support_kinematics", |b| {
        b.iter(|| support_kinematics(model, &mut data, black_box(&q), black_box(tcp_body)));
    });
    let _ = forward_kinematics(model, &mut data, &q, &v);
    group.bench_function("crba", |b| b.iter(|| *crba(black_box(model), &mut data)));
    group.bench_function("rnea", |b| b.iter(|| rnea(black_box(model), &mut data, black_box(&a)).copied()));
    group.bench_function("coriolis_matrix", |b| b.iter(|| *coriolis_matrix(black_box(model), &mut data)));
    let mut jacobian = SMatrix::<f64, 6, N>::zeros();
    group.bench_function("frame_jacobian", |b| {
        b.iter(|| frame_jacobian(black_box(model), &data, black_box(tcp), &mut jacobian));
    });
    // From a fresh state, as Pinocchio's `crba(q)`, `rnea(q, v, a)`, `computeCoriolisMatrix(q, v)`
    // and `computeFrameJacobian(q, frame)` (fixtures/pinocchio/bench_pinocchio.sh) are timed.
    group.bench_function("fk+crba", |b| {
        b.iter(|| placement_kinematics(model, &mut data, black_box(&q)).map(|()| *crba(model, &mut data)));
    });
    group.bench_function("fk+rnea", |b| {
        b.iter(|| {
            forward_kinematics(model, &mut data, black_box(&q), black_box(&v))
                .and_then(|()| rnea(model, &mut data, black_box(&a)).copied())
        });
    });
    group.bench_function("fk+coriolis_matrix", |b| {
        b.iter(|| {
            forward_kinematics(model, &mut data, black_box(&q), black_box(&v))
                .map(|()| *coriolis_matrix(model, &mut data))
        });
    });
    group.bench_function("fk+frame_jacobian", |b| {
        b.iter(|| {
            support_kinematics(model, &mut data, black_box(&q), tcp_body)
                .and_then(|()| frame_jacobian(model, &data, black_box(tcp), &mut jacobian))
        });
    });
    group.finish();
}

fn justin(c: &mut Criterion) {
    use fixtures::justin::{home_configuration, model, BODIES, FRAMES, N, RIGHT_TCP, UPPER_DOF};
    let Ok(robot) = model::<f64>() else {
        eprintln!("skipping justin: the fixture does not build");
        return;
    };
    let home = home_configuration::<f64>();
    algorithms(c, "justin", &robot, &home, RIGHT_TCP);

    let Ok(mut sim) = Simulator::<N, BODIES, FRAMES, UPPER_DOF>::new(robot.clone(), SimConfig::default()) else {
        return;
    };
    let (q, v, _) = state(&home);
    let rest = home.fixed_rows::<UPPER_DOF>(N - UPPER_DOF).into_owned();
    let Ok(target) = sim.set_state(q, v).and_then(|()| sim.frame_placement(RIGHT_TCP)) else {
        return;
    };
    let Ok(mut controller) =
        CartesianJointImpedance::new(robot, RIGHT_TCP, CartesianJointGains::default(), rest, target)
    else {
        return;
    };
    let mut group = c.benchmark_group("justin");
    group.bench_function("cartesian_impedance_step", |b| {
        b.iter(|| controller.step(&mut sim).map(|t| t.torque_ratio));
    });
    group.bench_function("sim_physics_step", |b| {
        b.iter_batched_ref(|| sim.clone(), |s| s.step().map(|r| r.time_s), criterion::BatchSize::SmallInput);
    });
    group.finish();
}

fn panda(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/urdf/panda.urdf");
    let robot = match load::<9, 9, PANDA_FRAMES>(&path, Coupling::Independent) {
        Ok(robot) => robot,
        Err(e) => {
            eprintln!("skipping panda: {e}");
            return;
        }
    };
    let Some(tcp) = robot.frame("panda_hand_tcp") else {
        eprintln!("skipping panda: no panda_hand_tcp link");
        return;
    };
    algorithms(c, "panda", &robot.model, &SVector::zeros(), tcp);
}

criterion_group!(benches, justin, panda);
criterion_main!(benches);
