//! Region markers and stack painting of the measurement images (wcet/README.md); the runtime
//! brackets each controller step as region 0, so a PIL run under the counting plugin counts it.
//!
//! `mark_begin::<R>()` / `mark_end::<R>()` emit `dbg #2R` / `dbg #2R+1`, which the TCG plugin
//! `wcet_insn.c` turns into exact instruction counts of region `R`. `paint_stack::<W>()` fills
//! the `W` bytes below the current stack pointer with a pattern; `stack_used::<W>(sp)` returns
//! how deep the code run in between wrote into them (the high-water mark). `exit` ends the
//! QEMU run with a status; a hard fault ends it as a failure.

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
