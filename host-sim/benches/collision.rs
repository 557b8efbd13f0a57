//! Host benchmarks of the self-collision avoidance (Sec. 3.1) on the Justin-like collision model
//! (`fixtures::justin::collision`: 28 swept-sphere volumes, 214 enabled pairs).
//!
//! What each benchmark times (after one `forward_kinematics`, `crba` and Cholesky factor of `M`
//! at the same state outside the timed loop — the controller computes those once per cycle for
//! every task):
//! - `collision/update`: world update of the 28 volumes and the distance and closest points of
//!   all 214 pairs ([`CollisionModel::update`]).
//! - `collision/step_all_pairs` (f64, f32): [`self_collision_rows`] with `d0 = 10 m`, so every
//!   pair is active: the update plus, for all 214 pairs, the two point Jacobians along the
//!   collision direction (3.18), two reflected masses (3.20), the 2×2 damping by double
//!   diagonalisation (3.23) and the row. This is the worst case of one cycle; throughput is
//!   reported per pair.
//! - `collision/step_table_3_1`: the same with Table 3.1's parameters (`F_max = 25 N`,
//!   `d0 = 0.15 m`) at a pose with the hands 12 cm apart — the typical cost.
//!
//! Run with `cargo bench -p host-sim --bench collision`.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use fixtures::justin::{self, collision as jc};
use kernel::dynamics::{crba, forward_kinematics, mass_matrix_cholesky};
use kernel::tasks::collision::{self_collision_rows, CollisionData, CollisionParameters};
use kernel::tasks::TaskRows;
use kernel::Data;
use nalgebra::{convert, RealField, SVector};

const N: usize = justin::N;

/// Home pose with the left arm swung in towards the right hand (hands about 12 cm apart).
fn pose<T: RealField + Copy>() -> SVector<T, N> {
    let mut q = justin::home_configuration::<T>();
    let left = justin::LEFT_ARM_COORDINATES.start;
    for (k, delta) in [(left, -0.3), (left + 1, 0.15)] {
        if let Some(x) = q.get_mut(k) {
            *x += convert(delta);
        }
    }
    q
}

/// Robot and collision model with kinematics, `M` and its Cholesky factor at [`pose`].
struct Setup<T: RealField + Copy> {
    model: justin::JustinModel<T>,
    collision: jc::JustinCollisionModel<T>,
    data: Data<T, N, { justin::BODIES }, { justin::FRAMES }>,
    factor: nalgebra::Cholesky<T, nalgebra::Const<N>>,
}

fn setup<T: RealField + Copy>() -> Result<Setup<T>, String> {
    let model = justin::model::<T>().map_err(|e| e.to_string())?;
    let collision = jc::collision_model(&model).map_err(|e| e.to_string())?;
    let mut data = Data::new(&model);
    let v = SVector::<T, N>::repeat(convert(0.2));
    forward_kinematics(&model, &mut data, &pose(), &v).map_err(|e| e.to_string())?;
    crba(&model, &mut data);
    let factor = mass_matrix_cholesky(&data).map_err(|e| e.to_string())?;
    Ok(Setup { model, collision, data, factor })
}

fn step_all_pairs<T: RealField + Copy>(c: &mut Criterion, label: &str) {
    let Ok(Setup { model, collision, data, factor }) = setup::<T>() else {
        eprintln!("skipping step_all_pairs_{label}: the fixture does not build");
        return;
    };
    let mut cd = CollisionData::new(&collision);
    let k = |x: f64| convert::<f64, T>(x);
    let Ok(all) = CollisionParameters::try_new(k(25.0), k(10.0), k(0.7), k(0.0), k(10.0)) else {
        return;
    };
    let mut rows = Box::new(TaskRows::<T, N, { jc::PAIRS }>::new());
    let report = self_collision_rows(&collision, &mut cd, &model, &data, &factor, &all, &mut rows);
    println!("step_all_pairs_{label}: {:?} rows (of {} pairs)", report.map(|r| r.rows), jc::PAIRS);
    let mut group = c.benchmark_group("collision");
    group.throughput(Throughput::Elements(jc::PAIRS as u64));
    group.bench_function(format!("step_all_pairs_{label}"), |b| {
        b.iter(|| {
            rows.clear();
            black_box(self_collision_rows(&collision, &mut cd, &model, &data, &factor, &all, &mut rows)).map(|r| r.rows)
        });
    });
    group.finish();
}

fn justin(c: &mut Criterion) {
    let Ok(Setup { model, collision, data, factor }) = setup::<f64>() else {
        eprintln!("skipping collision: the fixture does not build");
        return;
    };
    let mut cd = CollisionData::new(&collision);
    let mut group = c.benchmark_group("collision");
    group.throughput(Throughput::Elements(jc::PAIRS as u64));
    group.bench_function("update", |b| b.iter(|| collision.update(black_box(&data), &mut cd)));
    group.throughput(Throughput::Elements(1));
    let Ok(table) = CollisionParameters::try_new(25.0, 0.15, 0.7, 0.0, 0.15) else {
        return;
    };
    let mut rows = TaskRows::<f64, N, 35>::new();
    let active = self_collision_rows(&collision, &mut cd, &model, &data, &factor, &table, &mut rows).map(|r| r.rows);
    println!("step_table_3_1: {active:?} active pairs at the benchmark pose");
    group.bench_function("step_table_3_1", |b| {
        b.iter(|| {
            rows.clear();
            black_box(self_collision_rows(&collision, &mut cd, &model, &data, &factor, &table, &mut rows))
                .map(|r| r.rows)
        });
    });
    group.finish();
    step_all_pairs::<f64>(c, "f64");
    step_all_pairs::<f32>(c, "f32");
}

criterion_group!(benches, justin);
criterion_main!(benches);
