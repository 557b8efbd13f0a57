//! Host counterpart of `firmware/src/bin/wcet.rs`: runs one input case (`wcet-host CASE`) of
//! the three stages, so that `valgrind --tool=callgrind --toggle-collect=wcet_<stage>` counts
//! exactly one call of each stage (one process per case; see `../measure.sh --callgrind`).
use fixtures::justin;
use kernel::hierarchy::{HierarchyConfig, Recursion, Shaping, Stack, Weighting};
use kernel::tasks::collision::{CollisionData, CollisionParameters};
use kernel::Data;
use nalgebra::SMatrix;

#[path = "../../stages.rs"]
#[allow(dead_code)]
mod stages;
use stages::*;

fn main() {
    let case: u32 = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(0);
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
    let config = HierarchyConfig { recursion: Recursion::Augmented, weighting: Weighting::Inertia(&factor), shaping };
    let torque = wcet_projection(&config, &stack, &mut hierarchy);
    println!("case {case} candidates={} rows={} torque_sum={torque}", report.candidates, report.rows);
}
