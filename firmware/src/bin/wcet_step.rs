//! WCET measurement image of the full controller step (issue 8): exact per-call instruction
//! counts and stack high-water marks of `Controller::step` of the Justin controller
//! (`whole_body::controller_config` with the "Clean the mug!" force limits on both TCPs,
//! `fig_6_3_hierarchy(ArmId::RIGHT)`, all 214 pairs).
//!
//! One region, `wcet_step`, bracketed by `dbg #0` / `dbg #1` (the TCG plugin
//! `wcet/wcet_insn.c` counts the instructions between them), called once per frame of
//! `stages::step_frame`: a nominal sequence (home pose, small motion), adversarial
//! configurations (many pairs in both collision fields, joints at stops, torso at its boundary,
//! stretched arms, fast joints), a faulty (NaN) frame and a frame after it, then the capacity
//! frames (both collision fields widened so every pair is exact and both fields are full: the
//! bound of BENCHMARKS.md). Separate from
//! `wcet.rs` so that the controller (136 KB in f64) and the stack its construction needs fit the
//! 512 KiB RAM of `memory.x` together. The scalar is `f32`, or `f64` with `wcet-f64`.
//! Run by `wcet/measure.sh`; `cargo run --release --bin wcet-step` also works.
#![no_std]
#![no_main]

use cortex_m_rt::{entry, exception, ExceptionFrame};
use cortex_m_semihosting::hprintln;
use fixtures::justin;
use panic_semihosting as _;

use wcet_stages::*;

use firmware::probe::{self, exit, mark_begin, mark_end, GUARD, PAINT};

/// A hard fault ends the run as a failure, naming where.
#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    probe::hard_fault(frame)
}

/// Bytes of stack painted below the stack pointer before each measured call.
const WINDOW: usize = 64 * 1024;

fn paint_stack() -> usize {
    probe::paint_stack::<WINDOW>()
}

fn stack_used(sp: usize) -> usize {
    probe::stack_used::<WINDOW>(sp)
}

// The controller lives in a static (`.bss`), not on the stack being painted.
static mut CONTROLLER: core::mem::MaybeUninit<JustinController> = core::mem::MaybeUninit::uninit();

extern "C" {
    /// End of `.bss` (cortex-m-rt's link.x): the lowest address the stack may reach.
    static __sheap: u32;
}

/// Paints everything between the end of the statics and the current stack pointer.
fn paint_all() -> (usize, usize) {
    let bottom = core::ptr::addr_of!(__sheap) as usize;
    let sp = cortex_m::register::msp::read() as usize;
    let mut p = (bottom + 3) & !3;
    while p < sp - GUARD {
        unsafe { core::ptr::write_volatile(p as *mut u32, PAINT) };
        p += 4;
    }
    (bottom, sp)
}

/// Lowest word the stack ever reached since `paint_all`: returns (bytes used below `sp`,
/// bytes never touched above the statics).
fn whole_run_stack((bottom, sp): (usize, usize)) -> (usize, usize) {
    let mut p = (bottom + 3) & !3;
    while p < sp - GUARD {
        if unsafe { core::ptr::read_volatile(p as *const u32) } != PAINT {
            break;
        }
        p += 4;
    }
    (sp - p, p - bottom)
}

/// Builds the controller into `slot`. Not inlined, so that the by-value temporaries of
/// `Controller::try_new` (one controller, 68 KB f32 / 136 KB f64, plus the models) live in this
/// frame only, not in `run_step`'s for the whole run.
#[inline(never)]
fn init(slot: &mut core::mem::MaybeUninit<JustinController>) -> Option<&mut JustinController> {
    Some(slot.write(new_controller()?))
}

/// The full controller step over the nominal, adversarial and faulty frames (region 0).
fn run_step() -> Result<(), &'static str> {
    let speed = justin::model::<S>().map_err(|_| "model")?.limits.velocity;
    // SAFETY: single-threaded, no interrupts; borrowed once here.
    let controller = unsafe { init(&mut *core::ptr::addr_of_mut!(CONTROLLER)) }.ok_or("controller")?;
    let mut max_stack = 0usize;
    for k in 0..STEP_FRAMES {
        if !prepare(controller, k) {
            return Err("capacity commands refused");
        }
        let frame = step_frame(k, &speed);
        let sp = paint_stack();
        mark_begin::<0>();
        let sum = wcet_step(controller, &frame);
        mark_end::<0>();
        let used = stack_used(sp);
        max_stack = max_stack.max(used);
        let t = controller.telemetry();
        hprintln!(
            "step {} class={} mode={:?} fault={} levels={} collision_rows={} torque_sum={} stack={}",
            k,
            frame_class(k),
            controller.output().mode,
            t.fault.is_some(),
            t.level_count,
            t.collision_rows,
            sum,
            used
        );
    }
    hprintln!("wcet-stack step={} (bytes, max over {} frames; window {})", max_stack, STEP_FRAMES, WINDOW);
    Ok(())
}

#[entry]
fn main() -> ! {
    let painted = paint_all();
    match run_step() {
        Ok(()) => {
            let (used, free) = whole_run_stack(painted);
            hprintln!("wcet-stack whole-run={} free-above-statics={} (bytes)", used, free);
            exit(true)
        }
        Err(what) => {
            hprintln!("wcet-step run failed: {}", what);
            exit(false)
        }
    }
}
