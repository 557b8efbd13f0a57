//! The measured kernel stages and their inputs, shared by the Cortex-M image
//! (`src/bin/wcet.rs`) and the host callgrind bench (`wcet/host`). See `wcet/measure.sh`.
//! The scalar is `f32`, or `f64` with the `wcet-f64` feature of the including crate.

use fixtures::justin;
use fixtures::justin::collision::JustinCollisionModel;
use fixtures::justin::JustinModel;
use kernel::dynamics::{coriolis_matrix, crba, forward_kinematics, frame_jacobian, gravity, mass_matrix_cholesky};
use kernel::hierarchy::{project, HierarchyConfig, HierarchyData, Stack};
use kernel::math::CholeskyFactor;
use kernel::tasks::collision::{self_collision_rows, CollisionData, CollisionReport, CollisionParameters};
use kernel::tasks::{TaskRow, TaskRows};
use kernel::{Data, FrameId};
use nalgebra::{ComplexField, RowSVector, SMatrix, SVector};

#[cfg(not(feature = "wcet-f64"))]
pub type S = f32;
#[cfg(feature = "wcet-f64")]
pub type S = f64;

pub const N: usize = justin::N;
/// Input cases: the home pose, then seeded perturbations.
pub const CASES: u32 = 10;
pub const COLLISION_ROWS: usize = 64;
pub const ROWS: usize = 40;
pub const LEVELS: usize = 4;

pub type JustinData = Data<S, N, { justin::BODIES }, { justin::FRAMES }>;
pub type Rows = TaskRows<S, N, COLLISION_ROWS>;
pub type Hierarchy = HierarchyData<S, N, ROWS, LEVELS>;

pub fn c(x: f64) -> S {
    nalgebra::convert::<f64, S>(x)
}

// --- the measured stages --------------------------------------------------------------------

/// Stage 0: the dynamics terms the controller needs every cycle.
#[no_mangle]
#[inline(never)]
pub fn wcet_dynamics(
    model: &JustinModel<S>,
    data: &mut JustinData,
    q: &SVector<S, N>,
    v: &SVector<S, N>,
    jacobian: &mut SMatrix<S, 6, N>,
) -> Option<CholeskyFactor<S, N>> {
    forward_kinematics(model, data, q, v).ok()?;
    crba(model, data);
    coriolis_matrix(model, data);
    gravity(model, data);
    let factor = mass_matrix_cholesky(data).ok()?;
    frame_jacobian(model, data, justin::RIGHT_TCP, jacobian).ok()?;
    Some(factor)
}

/// Stage 1: self-collision avoidance rows of the 214 pairs.
#[no_mangle]
#[inline(never)]
pub fn wcet_self_collision(
    collision: &JustinCollisionModel<S>,
    collision_data: &mut CollisionData<S, { justin::collision::VOLUMES }, { justin::collision::PAIRS }>,
    model: &JustinModel<S>,
    data: &JustinData,
    factor: &CholeskyFactor<S, N>,
    parameters: &CollisionParameters<S>,
    rows: &mut Rows,
) -> Option<CollisionReport<S>> {
    self_collision_rows(collision, collision_data, model, data, factor, parameters, rows).ok()
}

/// Stage 2: the hierarchical projection.
#[no_mangle]
#[inline(never)]
pub fn wcet_projection(config: &HierarchyConfig<'_, S, N>, stack: &Stack<S, N, ROWS>, out: &mut Hierarchy) -> S {
    project(config, stack, out).map_or(S::NAN, |t| t.sum())
}

// --- inputs ---------------------------------------------------------------------------------

struct XorShift(u32);
impl XorShift {
    /// Uniform in [-1, 1).
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 17;
        self.0 ^= self.0 << 5;
        f64::from(self.0) / f64::from(u32::MAX / 2 + 1) - 1.0
    }
}

fn push_frame_rows(stack: &mut Stack<S, N, ROWS>, data: &JustinData, model: &JustinModel<S>, level: usize, frame: FrameId, rows: &[usize]) -> Option<()> {
    let mut j = SMatrix::<S, 6, N>::zeros();
    frame_jacobian(model, data, frame, &mut j).ok()?;
    for r in rows {
        let k = stack.rows().len();
        let force = c(5.0) * ComplexField::cos(c(0.7) * c(k as f64));
        stack.push(level, TaskRow { jacobian: j.row(*r).into_owned(), force, potential: c(0.0), activation: c(1.0) }).ok()?;
    }
    Some(())
}

/// The 40-row stack of `host-sim/benches/hierarchy.rs` at the current pose.
pub fn build_stack(stack: &mut Stack<S, N, ROWS>, data: &JustinData, model: &JustinModel<S>) -> Option<()> {
    *stack = Stack::new();
    push_frame_rows(stack, data, model, 0, justin::RIGHT_TCP, &[0, 1, 2, 3, 4, 5])?;
    push_frame_rows(stack, data, model, 0, justin::LEFT_TCP, &[0, 1, 2, 3])?;
    push_frame_rows(stack, data, model, 1, justin::LEFT_TCP, &[4, 5])?;
    push_frame_rows(stack, data, model, 1, justin::RIGHT_HAND, &[0, 1, 2, 3, 4, 5])?;
    push_frame_rows(stack, data, model, 1, justin::TORSO_TOP, &[0, 1])?;
    for (level, joints) in [(2, 3..13), (3, 10..20)] {
        for joint in joints {
            let k = stack.rows().len();
            let jacobian = RowSVector::<S, N>::from_fn(|_, col| if col == joint { c(1.0) } else { c(0.0) });
            let force = c(5.0) * ComplexField::cos(c(0.7) * c(k as f64));
            stack.push(level, TaskRow { jacobian, force, potential: c(0.0), activation: c(1.0) }).ok()?;
        }
    }
    Some(())
}

/// Case 0 is the home pose with q̇ = 0.3 rad/s; the others perturb q by up to ±0.3 rad and
/// q̇ by ±0.5 rad/s (xorshift seeded with the case number).
pub fn case_input(case: u32) -> (SVector<S, N>, SVector<S, N>) {
    let mut rng = XorShift(0x9E37_79B9 ^ case.wrapping_mul(0x85EB_CA6B));
    let scale = if case == 0 { 0.0 } else { 1.0 };
    let q = justin::home_configuration::<S>() + SVector::<S, N>::from_fn(|_, _| c(0.3 * scale * rng.next()));
    let v = SVector::<S, N>::from_fn(|_, _| c(0.3 + 0.5 * scale * rng.next()));
    (q, v)
}
