//! Panic-freedom check of `Controller::step`, `Controller::apply_bytes` (issues 8 and 16) and
//! the runtime's setup (issue 14): this image is only linked, never run.
//!
//! `main` calls `wcet_step` (the full `Controller::step` of the Justin controller, f32 or f64
//! with `wcet-f64`) and `wcet_step_panda` (the imported Panda's, `wcet_stages::panda`) on
//! controllers and frames the optimiser cannot see (`black_box`ed pointers), `apply_bytes`
//! (command decoding and `Controller::apply`) on bytes it cannot see, and the setup path of
//! the board runtime on a chunk and a model it cannot see (assembling the chunks, decoding the
//! setup, building the controller through the kernel's constructors:
//! `ControllerSlot::configure`; the model is built once at boot, before the link is served), so
//! the image contains all of them and everything they can reach, and nothing else of the kernel. The panic handler calls a function that does not exist: if any panic path
//! survives optimisation, the link fails with `undefined symbol: step_has_a_panic_path`.
//! With the `panic-check-report` feature the handler is an ordinary loop instead, so that
//! `wcet/panic_check.sh` can list the call sites of the remaining panic functions.
//! Built by `wcet/panic_check.sh` (feature `panic-check`).
#![no_std]
#![no_main]

use core::mem::MaybeUninit;
use core::panic::PanicInfo;

use cortex_m_rt::entry;
use firmware::runtime::ControllerSlot;
use fixtures::justin::JustinModel;
use link::setup::{SetupAssembler, SetupChunk};

use wcet_stages::panda::{wcet_step_panda, PandaController, PandaFrame};
use wcet_stages::*;

static mut CONTROLLER: MaybeUninit<JustinController> = MaybeUninit::uninit();
static mut FRAME: MaybeUninit<Frame> = MaybeUninit::uninit();
static mut PANDA: MaybeUninit<PandaController> = MaybeUninit::uninit();
static mut PANDA_FRAME: MaybeUninit<PandaFrame> = MaybeUninit::uninit();
static mut COMMAND: [u8; 256] = [0; 256];
static mut SLOT: ControllerSlot = ControllerSlot::new();
static mut MODEL: MaybeUninit<JustinModel<f32>> = MaybeUninit::uninit();
static mut CHUNK: MaybeUninit<SetupChunk> = MaybeUninit::uninit();
static mut ASSEMBLER: SetupAssembler = SetupAssembler::new();

#[entry]
fn main() -> ! {
    // Never executed (the check only links); the pointers are opaque to the optimiser.
    let controller = core::hint::black_box(core::ptr::addr_of_mut!(CONTROLLER)).cast::<JustinController>();
    let frame = core::hint::black_box(core::ptr::addr_of!(FRAME)).cast::<Frame>();
    let panda = core::hint::black_box(core::ptr::addr_of_mut!(PANDA)).cast::<PandaController>();
    let panda_frame = core::hint::black_box(core::ptr::addr_of!(PANDA_FRAME)).cast::<PandaFrame>();
    let bytes = core::hint::black_box(core::ptr::addr_of!(COMMAND));
    let length = core::hint::black_box(256_usize);
    let slot = core::hint::black_box(core::ptr::addr_of_mut!(SLOT));
    let chunk = core::hint::black_box(core::ptr::addr_of!(CHUNK)).cast::<SetupChunk>();
    let assembler = core::hint::black_box(core::ptr::addr_of_mut!(ASSEMBLER));
    let model = core::hint::black_box(core::ptr::addr_of!(MODEL)).cast::<JustinModel<f32>>();
    loop {
        // SAFETY: not run; see the module docs.
        let sum = unsafe { wcet_step(&mut *controller, &*frame) };
        core::hint::black_box(sum);
        // SAFETY: as above.
        core::hint::black_box(unsafe { wcet_step_panda(&mut *panda, &*panda_frame) });
        // SAFETY: as above.
        let command = unsafe { (*bytes).get(..length).unwrap_or(&[]) };
        // SAFETY: as above.
        let applied = unsafe { (*controller).apply_bytes(command) };
        core::hint::black_box(applied.is_ok());
        // SAFETY: as above.
        if let Ok(Some(encoded)) = unsafe { (*assembler).push(&*chunk) } {
            // SAFETY: as above.
            core::hint::black_box(unsafe { (*slot).configure(&*model, encoded) });
        }
    }
}

#[cfg(not(feature = "panic-check-report"))]
#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    extern "C" {
        /// Deliberately undefined: referenced only if a panic path survives.
        fn step_has_a_panic_path() -> !;
    }
    // SAFETY: never linked successfully if reachable.
    unsafe { step_has_a_panic_path() }
}

#[cfg(feature = "panic-check-report")]
#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    loop {
        core::hint::black_box(());
    }
}
