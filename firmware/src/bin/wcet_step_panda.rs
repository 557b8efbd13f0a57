//! WCET measurement image of the imported Franka Panda's full controller step (issue 15):
//! exact per-call instruction counts and stack high-water marks of `Controller::step` of the
//! fixed-base, single-arm controller of `wcet_stages::panda` (21 collision volumes, 80 pairs,
//! both collision fields in the hierarchy).
//!
//! One region, `wcet_step_panda`, bracketed by `dbg #0` / `dbg #1` (counted by the TCG plugin
//! `wcet/wcet_insn.c`), called once per frame of `panda::step_frame`: the nominal frames (a small
//! joint motion while the TCP goal moves), then the capacity frames (both collision fields
//! widened so every pair is exact and both fields are full: the bound). The image is
//! `firmware::step_image!`, as `wcet_step.rs`'s, so `wcet/measure.sh` reads both logs alike. The
//! scalar is `f32`, or `f64` with `wcet-f64`. Run by `wcet/measure.sh`;
//! `cargo run --release --bin wcet-step-panda` also works.
#![no_std]
#![no_main]

use panic_semihosting as _;

firmware::step_image! {
    controller: wcet_stages::panda::PandaController,
    bench: wcet_stages::panda,
    step: wcet_stages::panda::wcet_step_panda,
    model: fixtures::robots::panda::model::<wcet_stages::S>(),
    window: 32 * 1024,
    refused: "goal or capacity commands refused",
    name: "wcet-step-panda",
}
