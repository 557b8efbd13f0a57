//! Host counterpart of `firmware/src/bin/wcet.rs`.
//!
//! * `wcet-host CASE` runs one input case of the three stages, so that
//!   `valgrind --tool=callgrind --toggle-collect=wcet_<stage>` counts exactly one call of each
//!   stage (one process per case; see `../measure.sh --callgrind`).
//! * `wcet-host step K` runs the full-controller frame sequence up to frame `K`; only frame `K`
//!   goes through `wcet_step` (the earlier ones through `warm_step`, the same code), so
//!   `--toggle-collect=wcet_step` counts exactly frame `K`.
//! * `wcet-host time REPS` times every `step` of the sequence with `rdtsc` (REPS passes, a fresh
//!   controller each) and prints percentiles per input class (wcet/README.md: run it under
//!   `setarch x86_64 -R taskset -c 1`).
//! * `wcet-host search SAMPLES` is the seeded random search that produced
//!   `stages::ADVERSARIAL`.
use fixtures::justin;
use kernel::hierarchy::{HierarchyConfig, Recursion, Shaping, Stack, Weighting};
use kernel::tasks::collision::{CollisionData, CollisionParameters};
use kernel::Data;
use nalgebra::{SMatrix, SVector};

use wcet_stages::*;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize| args.get(i).and_then(|a| a.parse::<u32>().ok());
    match args.get(1).map(String::as_str) {
        Some("step") => step_once(arg(2).unwrap_or(0)),
        Some("time") => time(arg(2).unwrap_or(200)),
        Some("search") => search(arg(2).unwrap_or(20000)),
        Some("frames") => println!("{STEP_FRAMES}"),
        Some("size") => println!("size_of::<JustinController>() = {} bytes", core::mem::size_of::<JustinController>()),
        _ => stages_once(arg(1).unwrap_or(0)),
    }
}

fn stages_once(case: u32) {
    let model = justin::model::<S>().expect("model");
    let mut data = Box::new(Data::new(&model));
    let collision = Box::new(justin::collision::collision_model(&model).expect("collision model"));
    let mut collision_data = Box::new(CollisionData::new(&collision));
    let mut rows = Box::new(Rows::new());
    let mut stack = Box::new(Stack::new());
    let mut hierarchy = Box::new(Hierarchy::default());
    let parameters = CollisionParameters::try_new(c(25.0), c(1.0), c(0.7), c(0.0), c(1.0)).expect("parameters");
    let shaping = Shaping::Continuous { singular_full: c(0.02), singular_start: c(0.05) };
    let mut jacobian = SMatrix::<S, 6, N>::zeros();

    let (q, v) = case_input(case);
    let factor = wcet_dynamics(&model, &mut data, &q, &v, &mut jacobian).expect("dynamics");
    let report = wcet_self_collision(&collision, &mut collision_data, &model, &data, &factor, &parameters, &mut rows)
        .expect("self-collision");
    build_stack(&mut stack, &data, &model).expect("stack");
    let config = HierarchyConfig {
        recursion: Recursion::Augmented,
        weighting: Weighting::Inertia(&factor),
        shaping,
        diagnose_last_level: true,
    };
    let torque = wcet_projection(&config, &stack, &mut hierarchy);
    println!("case {case} candidates={} rows={} torque_sum={torque}", report.candidates, report.rows);
}

/// `Controller::step` under another name (frames before the counted one). It returns something
/// else than `wcet_step` so that the linker does not fold the two symbols into one.
#[no_mangle]
#[inline(never)]
pub fn warm_step(controller: &mut JustinController, frame: &Frame) -> S {
    let out = controller.step(frame);
    out.torque.first().copied().unwrap_or(c(0.0))
}

fn speed() -> SVector<S, N> {
    justin::model::<S>().expect("model").limits.velocity
}

fn step_once(k: u32) {
    let mut controller = Box::new(new_controller().expect("controller"));
    let speed = speed();
    for j in 0..k {
        assert!(prepare(&mut controller, j), "capacity commands refused");
        std::hint::black_box(warm_step(&mut controller, &step_frame(j, &speed)));
    }
    assert!(prepare(&mut controller, k), "capacity commands refused");
    let frame = step_frame(k, &speed);
    let sum = wcet_step(&mut controller, std::hint::black_box(&frame));
    let t = controller.telemetry();
    println!(
        "frame {k} class={} torque_sum={sum} mode={:?} fault={:?} levels={} collision_rows={} min_distance={:?}",
        frame_class(k),
        controller.output().mode,
        t.fault,
        t.level_count,
        t.collision_rows,
        t.min_collision_distance
    );
}

#[inline(always)]
fn rdtsc() -> u64 {
    // SAFETY: lfence and rdtsc have no memory effects; x86-64 only.
    unsafe {
        core::arch::x86_64::_mm_lfence();
        let t = core::arch::x86_64::_rdtsc();
        core::arch::x86_64::_mm_lfence();
        t
    }
}

fn time(reps: u32) {
    let template = Box::new(new_controller().expect("controller"));
    let speed = speed();
    let frames: Vec<Frame> = (0..STEP_FRAMES).map(|k| step_frame(k, &speed)).collect();
    // TSC rate against Instant.
    let (t0, i0) = (rdtsc(), std::time::Instant::now());
    while i0.elapsed().as_millis() < 200 {}
    let ghz = (rdtsc() - t0) as f64 / i0.elapsed().as_nanos() as f64;
    let overhead = (0..1000)
        .map(|_| {
            let a = rdtsc();
            rdtsc() - a
        })
        .min()
        .unwrap_or(0);
    let mut samples: std::collections::BTreeMap<&str, Vec<f64>> = Default::default();
    let mut controller = template.clone();
    for _ in 0..reps {
        controller.clone_from(&template);
        for (k, frame) in frames.iter().enumerate() {
            assert!(prepare(&mut controller, k as u32), "capacity commands refused");
            let a = rdtsc();
            std::hint::black_box(wcet_step(&mut controller, std::hint::black_box(frame)));
            let ticks = rdtsc() - a - overhead;
            let ns = ticks as f64 / ghz;
            samples.entry(frame_class(k as u32)).or_default().push(ns);
            samples.entry("all").or_default().push(ns);
        }
    }
    println!("TSC {ghz:.3} GHz, overhead {overhead} ticks subtracted, {reps} passes of {} frames", frames.len());
    println!(
        "{:<12} {:>7} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "class", "n", "min", "p50", "p90", "p99", "p99.9", "max"
    );
    for (class, mut v) in samples {
        v.sort_by(f64::total_cmp);
        let p = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize] / 1000.0;
        println!(
            "{class:<12} {:>7} {:>8.1}u {:>8.1}u {:>8.1}u {:>8.1}u {:>8.1}u {:>8.1}u",
            v.len(),
            p(0.0),
            p(0.5),
            p(0.9),
            p(0.99),
            p(0.999),
            p(1.0)
        );
    }
}

/// Seeded random search for configurations with many pairs inside the collision fields.
fn search(samples: u32) {
    let model = justin::model::<f64>().expect("model");
    let collision = justin::collision::collision_model(&model).expect("collision model");
    let mut cd = CollisionData::new(&collision);
    let mut data = Data::new(&model);
    let (lo, hi) = (model.limits.position_lower, model.limits.position_upper);
    let mut state = 0x2545_F491_u32;
    let mut rnd = move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        f64::from(state) / f64::from(u32::MAX)
    };
    let score =
        |q: &SVector<f64, N>,
         data: &mut Data<f64, N, { justin::BODIES }, { justin::FRAMES }>,
         cd: &mut CollisionData<f64, { justin::collision::VOLUMES }, { justin::collision::PAIRS }>| {
            kernel::dynamics::forward_kinematics(&model, data, q, &SVector::zeros()).expect("fk");
            collision.update(data, cd);
            let (mut strong, mut weak, mut touching) = (0, 0, 0);
            for p in cd.proximities.iter().take(collision.pairs().len()) {
                strong += usize::from(p.distance < 0.05 && p.direction.is_some());
                weak += usize::from(p.distance < 0.15 && p.direction.is_some());
                touching += usize::from(p.direction.is_none() || p.distance < -0.02);
            }
            let stops = (justin::BASE_DOF..N).filter(|&i| q[i] - lo[i] < 0.2 || hi[i] - q[i] < 0.2).count();
            // Deep penetration gives no rows (no direction): penalise it.
            ((strong.min(32) * 3 + weak.min(32)) as i64 + stops as i64 - 20 * touching as i64, strong, weak, stops)
        };
    let mut best: Vec<(i64, SVector<f64, N>, usize, usize, usize)> = Vec::new();
    for _ in 0..samples {
        let home = justin::home_configuration::<f64>();
        let mut q = home;
        for i in justin::BASE_DOF..N {
            let r = rnd();
            q[i] = if r < 0.15 {
                lo[i] + 0.01
            } else if r < 0.3 {
                hi[i] - 0.01
            } else {
                lo[i] + (hi[i] - lo[i]) * rnd()
            };
        }
        let (mut s, mut st, mut wk, mut sp) = score(&q, &mut data, &mut cd);
        // Hill climb.
        for _ in 0..60 {
            let mut trial = q;
            let i = justin::BASE_DOF + (rnd() * (N - justin::BASE_DOF) as f64) as usize % (N - justin::BASE_DOF);
            trial[i] = (trial[i] + 0.3 * (rnd() - 0.5)).clamp(lo[i] + 0.01, hi[i] - 0.01);
            let (t, a, b, d) = score(&trial, &mut data, &mut cd);
            if t >= s {
                (q, s, st, wk, sp) = (trial, t, a, b, d);
            }
        }
        best.push((s, q, st, wk, sp));
        best.sort_by(|a, b| b.0.cmp(&a.0));
        best.truncate(6);
    }
    for (s, q, st, wk, sp) in &best {
        let upper: Vec<String> = (justin::BASE_DOF..N).map(|i| format!("{:.3}", q[i])).collect();
        println!("    // score {s}: strong {st}, weak {wk}, joints near a stop {sp}");
        println!("    [{}],", upper.join(", "));
    }
}
