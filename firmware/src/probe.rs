//! Region markers and stack painting of the measurement images (wcet/README.md); the runtime
//! brackets each controller step as region 0, so a PIL run under the counting plugin counts it.
//!
//! `mark_begin::<R>()` / `mark_end::<R>()` emit `dbg #2R` / `dbg #2R+1`, which the TCG plugin
//! `wcet_insn.c` turns into exact instruction counts of region `R`. `paint_stack::<W>()` fills
//! the `W` bytes below the current stack pointer with a pattern; `stack_used::<W>(sp)` returns
//! how deep the code run in between wrote into them (the high-water mark); `paint_all` /
//! `whole_run_stack` do the same for everything between the statics and the stack pointer over
//! a whole run. `exit` ends the QEMU run with a status; a hard fault ends it as a failure.

use core::arch::asm;

use cortex_m_rt::ExceptionFrame;
use cortex_m_semihosting::{debug, hprintln};

/// Ends the QEMU run (semihosting exit) with success or failure.
pub fn exit(success: bool) -> ! {
    debug::exit(if success { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
    loop {
        cortex_m::asm::wfi();
    }
}

/// Reports a hard fault's program counter and ends the run as a failure (the measuring images'
/// `HardFault` handler calls it).
pub fn hard_fault(frame: &ExceptionFrame) -> ! {
    hprintln!("HardFault at pc={:#010x}", frame.pc());
    exit(false)
}

#[inline(always)]
pub fn mark_begin<const R: u32>() {
    // no `nomem`: the asm is a compiler barrier, nothing moves across it
    unsafe { asm!("dbg #{r}", r = const 2 * R, options(nostack, preserves_flags)) }
}

#[inline(always)]
pub fn mark_end<const R: u32>() {
    unsafe { asm!("dbg #{r}", r = const 2 * R + 1, options(nostack, preserves_flags)) }
}

/// The paint pattern.
pub const PAINT: u32 = 0xC0DE_CAFE;
/// Bytes just below the stack pointer left unpainted (the painting code's own frame).
pub const GUARD: usize = 64;

/// Paints the `WINDOW` bytes below the stack pointer; returns the stack pointer.
#[inline(always)]
pub fn paint_stack<const WINDOW: usize>() -> usize {
    let sp = cortex_m::register::msp::read() as usize;
    let mut p = sp - WINDOW;
    while p < sp - GUARD {
        unsafe { core::ptr::write_volatile(p as *mut u32, PAINT) };
        p += 4;
    }
    sp
}

/// Bytes of the painted window below `sp` that were overwritten.
#[inline(always)]
pub fn stack_used<const WINDOW: usize>(sp: usize) -> usize {
    let mut p = sp - WINDOW;
    while p < sp - GUARD {
        if unsafe { core::ptr::read_volatile(p as *const u32) } != PAINT {
            return sp - p;
        }
        p += 4;
    }
    0
}

extern "C" {
    /// End of `.bss` (cortex-m-rt's link.x): the lowest address the stack may reach.
    static __sheap: u32;
}

/// Paints everything between the end of the statics and the current stack pointer; returns
/// (end of the statics, stack pointer) for [`whole_run_stack`].
pub fn paint_all() -> (usize, usize) {
    let bottom = core::ptr::addr_of!(__sheap) as usize;
    let sp = cortex_m::register::msp::read() as usize;
    let mut p = (bottom + 3) & !3;
    while p < sp - GUARD {
        unsafe { core::ptr::write_volatile(p as *mut u32, PAINT) };
        p += 4;
    }
    (bottom, sp)
}

/// Lowest word the stack ever reached since [`paint_all`]: returns (bytes used below `sp`,
/// bytes never touched above the statics).
pub fn whole_run_stack((bottom, sp): (usize, usize)) -> (usize, usize) {
    let mut p = (bottom + 3) & !3;
    while p < sp - GUARD {
        if unsafe { core::ptr::read_volatile(p as *const u32) } != PAINT {
            break;
        }
        p += 4;
    }
    (sp - p, p - bottom)
}

/// The whole of a full-step measurement image (`src/bin/wcet_step.rs`, `wcet_step_panda.rs`):
/// its hard-fault handler, the controller in a static (`.bss`, not on the painted stack), its
/// construction in a frame of its own, and `main`, which paints the stack, then calls the
/// `step` function (region 0) once per frame `0..STEP_FRAMES` of the `bench` module (its
/// `new_controller`, `prepare`, `step_frame`, `frame_class`; `model` gives the joint speed
/// limits) with a painted `window` below the stack pointer, prints one line per frame
/// (`step K class=… mode=… fault=… levels=… collision_rows=… torque_sum=… stack=…`, read by
/// `wcet/measure.sh`) and the stack high-water marks, and exits with the run's success.
#[macro_export]
macro_rules! step_image {
    (
        controller: $controller:ty,
        bench: $($bench:ident)::+,
        step: $step:path,
        model: $model:expr,
        window: $window:expr,
        refused: $refused:literal,
        name: $name:literal $(,)?
    ) => {
        /// A hard fault ends the run as a failure, naming where.
        #[cortex_m_rt::exception]
        unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
            $crate::probe::hard_fault(frame)
        }

        /// Bytes of stack painted below the stack pointer before each measured call.
        const WINDOW: usize = $window;

        // The controller lives in a static (`.bss`), not on the stack being painted.
        static mut CONTROLLER: core::mem::MaybeUninit<$controller> = core::mem::MaybeUninit::uninit();

        /// Builds the controller into `slot`. Not inlined, so that the by-value temporaries of
        /// `Controller::try_new` (the controller and the models) live in this frame only, not in
        /// `run_step`'s for the whole run.
        #[inline(never)]
        fn init(slot: &mut core::mem::MaybeUninit<$controller>) -> Option<&mut $controller> {
            Some(slot.write($($bench)::+::new_controller()?))
        }

        /// The full controller step over every frame (region 0).
        fn run_step() -> Result<(), &'static str> {
            use $crate::probe::{mark_begin, mark_end, paint_stack, stack_used};
            use $($bench)::+ as bench;
            let speed = $model.map_err(|_| "model")?.limits.velocity;
            // SAFETY: single-threaded, no interrupts; borrowed once here.
            let controller = unsafe { init(&mut *core::ptr::addr_of_mut!(CONTROLLER)) }.ok_or("controller")?;
            let mut max_stack = 0usize;
            for k in 0..bench::STEP_FRAMES {
                if !bench::prepare(controller, k) {
                    return Err($refused);
                }
                let frame = bench::step_frame(k, &speed);
                let sp = paint_stack::<WINDOW>();
                mark_begin::<0>();
                let sum = $step(controller, &frame);
                mark_end::<0>();
                let used = stack_used::<WINDOW>(sp);
                max_stack = max_stack.max(used);
                let t = controller.telemetry();
                cortex_m_semihosting::hprintln!(
                    "step {} class={} mode={:?} fault={} levels={} collision_rows={} torque_sum={} stack={}",
                    k,
                    bench::frame_class(k),
                    controller.output().mode,
                    t.fault.is_some(),
                    t.level_count,
                    t.collision_rows,
                    sum,
                    used
                );
            }
            cortex_m_semihosting::hprintln!(
                "wcet-stack step={} (bytes, max over {} frames; window {})",
                max_stack,
                bench::STEP_FRAMES,
                WINDOW
            );
            Ok(())
        }

        #[cortex_m_rt::entry]
        fn main() -> ! {
            let painted = $crate::probe::paint_all();
            match run_step() {
                Ok(()) => {
                    let (used, free) = $crate::probe::whole_run_stack(painted);
                    cortex_m_semihosting::hprintln!("wcet-stack whole-run={} free-above-statics={} (bytes)", used, free);
                    $crate::probe::exit(true)
                }
                Err(what) => {
                    cortex_m_semihosting::hprintln!(concat!($name, " run failed: {}"), what);
                    $crate::probe::exit(false)
                }
            }
        }
    };
}
