//! Arbitrary sensor frames interleaved with planner bytes, in f32 (the boards' scalar) and f64:
//! after every cycle the output contract must hold (finite, within the effort and platform
//! limits, mode `Normal` exactly without a fault).
#![no_main]

use arbitrary::Unstructured;
use fuzz::{assert_contract, cached, frame, JustinController};
use libfuzzer_sys::fuzz_target;
use nalgebra::RealField;
use serde::de::DeserializeOwned;
use std::sync::OnceLock;

static F64: OnceLock<Box<JustinController<f64>>> = OnceLock::new();
static F32: OnceLock<Box<JustinController<f32>>> = OnceLock::new();

/// At most this many cycles per input (keeps each run short).
const MAX_CYCLES: usize = 64;

fn run<T: RealField + Copy + DeserializeOwned>(cell: &'static OnceLock<Box<JustinController<T>>>, bytes: &[u8]) {
    let mut u = Unstructured::new(bytes);
    let mut controller = cached(cell);
    let mut last = 1;
    for cycle in 0..MAX_CYCLES {
        if u.is_empty() {
            break;
        }
        if u.ratio(1, 6).unwrap_or(false) {
            let length = usize::from(u.arbitrary::<u8>().unwrap_or(0)) % 96;
            let command = u.bytes(length.min(u.len())).unwrap_or(&[]);
            let _ = controller.apply_bytes(command);
        }
        let Ok(frame) = frame::<T>(&mut u, &mut last) else { break };
        controller.step(&frame);
        assert_contract(&controller, &format!("cycle {cycle}"));
    }
}

fuzz_target!(|bytes: &[u8]| {
    run(&F32, bytes);
    run(&F64, bytes);
});
