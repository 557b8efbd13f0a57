//! WCET measurement image: exact per-call instruction counts and stack high-water marks of the
//! kernel stages one by one (issue #8); the whole `Controller::step` is measured by `wcet_step.rs`.
//!
//! Stages, each a monomorphic `#[inline(never)]` symbol bracketed by `dbg #2r` / `dbg #2r+1`
//! markers (NOPs on silicon and in QEMU; the TCG plugin `wcet/wcet_insn.c` counts the
//! instructions between them):
//!
//! | region | stage | what |
//! |---|---|---|
//! | 0 | `wcet_dynamics` | forward kinematics, CRBA, C(q, q̇), g(q), Cholesky of M, right TCP Jacobian |
//! | 1 | `wcet_self_collision` | 214-pair self-collision rows, d₀ = 1 m (most pairs active) |
//! | 2 | `wcet_projection` | augmented, inertia-weighted, continuous projection of a 40-row, 4-level stack |
//!
//! Inputs: the home pose, then seeded perturbations (xorshift, ±0.3 rad, q̇ in ±0.5 rad/s).
//! The scalar is `f32`, or `f64` with the `wcet-f64` feature. Stack use of each stage is
//! measured by painting. Run by `wcet/measure.sh`; `cargo run --release --bin wcet` also works.
#![no_std]
#![no_main]

use cortex_m_rt::{entry, exception, ExceptionFrame};
use cortex_m_semihosting::hprintln;
use fixtures::justin;
use fixtures::justin::collision::JustinCollisionModel;
use kernel::hierarchy::{HierarchyConfig, Recursion, Shaping, Stack, Weighting};
use kernel::tasks::collision::{CollisionData, CollisionParameters};
use kernel::tasks::TaskRows;
use kernel::Data;
use nalgebra::SMatrix;
use panic_semihosting as _;

// The stages image uses the stage inputs only; the full-step frames are `wcet_step.rs`'s.
use wcet_stages::*;

use firmware::probe::{self, exit, mark_begin, mark_end};

/// A hard fault ends the run as a failure, naming where.
#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    probe::hard_fault(frame)
}

/// Bytes of stack painted below the stack pointer before each measured call.
const WINDOW: usize = 48 * 1024;

fn paint_stack() -> usize {
    probe::paint_stack::<WINDOW>()
}

fn stack_used(sp: usize) -> usize {
    probe::stack_used::<WINDOW>(sp)
}

// Large working sets live in statics (`.bss`), not on the stack being painted.
static mut DATA: Option<JustinData> = None;
static mut COLLISION: Option<JustinCollisionModel<S>> = None;
static mut COLLISION_DATA: Option<CollisionData<S, { justin::collision::VOLUMES }, { justin::collision::PAIRS }>> =
    None;
static mut ROWS_OUT: Rows = TaskRows::new();
static mut STACK: Option<Stack<S, N, ROWS>> = None;
static mut HIERARCHY: Option<Hierarchy> = None;

fn run() -> Result<(), &'static str> {
    let model = justin::model::<S>().map_err(|_| "model")?;
    // SAFETY: single-threaded, no interrupts use these; each is borrowed once here.
    let (data, collision, collision_data, rows, stack, hierarchy) = unsafe {
        let data = (*core::ptr::addr_of_mut!(DATA)).insert(Data::new(&model));
        let collision = (*core::ptr::addr_of_mut!(COLLISION))
            .insert(justin::collision::collision_model(&model).map_err(|_| "collision model")?);
        let collision_data = (*core::ptr::addr_of_mut!(COLLISION_DATA)).insert(CollisionData::new(collision));
        let hierarchy = (*core::ptr::addr_of_mut!(HIERARCHY)).insert(Hierarchy::default());
        (
            data,
            &*collision,
            collision_data,
            &mut *core::ptr::addr_of_mut!(ROWS_OUT),
            (*core::ptr::addr_of_mut!(STACK)).insert(Stack::new()),
            hierarchy,
        )
    };
    // d0 = 1 m: most pairs are active, the row path runs many times (worst-input flavour).
    let parameters = CollisionParameters::try_new(c(25.0), c(1.0), c(0.7), c(0.0), c(1.0)).map_err(|_| "parameters")?;
    let shaping = Shaping::Continuous { singular_full: c(0.02), singular_start: c(0.05) };
    let mut jacobian = SMatrix::<S, 6, N>::zeros();
    let mut max_stack = [0usize; 3];

    for case in 0..CASES {
        let (q, v) = case_input(case);

        let sp = paint_stack();
        mark_begin::<0>();
        let factor = wcet_dynamics(&model, data, &q, &v, &mut jacobian);
        mark_end::<0>();
        let s0 = stack_used(sp);
        let factor = factor.ok_or("dynamics")?;

        *rows = TaskRows::new();
        let sp = paint_stack();
        mark_begin::<1>();
        let report = wcet_self_collision(collision, collision_data, &model, data, &factor, &parameters, rows);
        mark_end::<1>();
        let s1 = stack_used(sp);
        let report = report.ok_or("self-collision")?;

        build_stack(stack, data, &model).ok_or("stack")?;
        let config = HierarchyConfig {
            recursion: Recursion::Augmented,
            weighting: Weighting::Inertia(&factor),
            shaping,
            diagnose_last_level: true,
        };
        let sp = paint_stack();
        mark_begin::<2>();
        let torque = wcet_projection(&config, stack, hierarchy);
        mark_end::<2>();
        let s2 = stack_used(sp);
        if !torque.is_finite() {
            return Err("projection");
        }

        for (m, s) in max_stack.iter_mut().zip([s0, s1, s2]) {
            *m = (*m).max(s);
        }
        hprintln!(
            "case {} candidates={} rows={} dropped={} torque_sum={} stack={},{},{}",
            case,
            report.candidates,
            report.rows,
            report.dropped,
            torque,
            s0,
            s1,
            s2
        );
    }
    hprintln!(
        "wcet-stack dynamics={} self_collision={} projection={} (bytes, max over {} cases; window {})",
        max_stack[0],
        max_stack[1],
        max_stack[2],
        CASES,
        WINDOW
    );
    Ok(())
}

#[entry]
fn main() -> ! {
    match run() {
        Ok(()) => exit(true),
        Err(what) => {
            hprintln!("wcet run failed: {}", what);
            exit(false)
        }
    }
}
