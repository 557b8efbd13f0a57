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

use panic_semihosting as _;

firmware::step_image! {
    controller: wcet_stages::JustinController,
    bench: wcet_stages,
    step: wcet_stages::wcet_step,
    model: fixtures::justin::model::<wcet_stages::S>(),
    window: 64 * 1024,
    refused: "capacity commands refused",
    name: "wcet-step",
}
