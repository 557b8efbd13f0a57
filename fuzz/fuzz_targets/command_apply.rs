//! Planner bytes into a running controller: `decode_command` + `apply` through `apply_bytes`,
//! in f64 and f32, then one cycle; the output contract must hold. A command that decodes must
//! survive an encode/decode round trip unchanged.
#![no_main]

use fuzz::{assert_contract, cached, home_frame, JustinController};
use kernel::controller::messages::{decode_command, encode_command, Command};
use libfuzzer_sys::fuzz_target;
use nalgebra::RealField;
use serde::{de::DeserializeOwned, Serialize};
use std::sync::OnceLock;

static F64: OnceLock<Box<JustinController<f64>>> = OnceLock::new();
static F32: OnceLock<Box<JustinController<f32>>> = OnceLock::new();

fn run<T: RealField + Copy + Serialize + DeserializeOwned>(
    cell: &'static OnceLock<Box<JustinController<T>>>,
    bytes: &[u8],
) {
    let mut controller = cached(cell);
    let _ = controller.apply_bytes(bytes);
    controller.step(&home_frame(2));
    assert_contract(&controller, "after apply_bytes");
    if let Ok(command) = decode_command::<T>(bytes) {
        let mut buffer = [0_u8; 2048];
        let encoded = encode_command(&command, &mut buffer).expect("a decoded command encodes");
        let again: Command<T> = decode_command(encoded).expect("an encoded command decodes");
        assert!(again == command || format!("{again:?}") == format!("{command:?}"), "round trip changed the command");
    }
}

fuzz_target!(|bytes: &[u8]| {
    run(&F64, bytes);
    run(&F32, bytes);
});
