//! host-sim's text parsers on arbitrary input: the URDF loader (models of 1, 7 and 20
//! coordinates) and the states file of the `dynamics` command. Errors are fine; panics are not.
#![no_main]

use host_sim::dynamics_cli::parse_states;
use host_sim::urdf::{load_str, Coupling};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let Ok(text) = std::str::from_utf8(bytes) else { return };
    for coupling in [Coupling::Independent, Coupling::Coupled] {
        let _ = load_str::<1, 4, 8>(text, coupling);
        let _ = load_str::<7, 8, 16>(text, coupling);
        let _ = load_str::<20, 24, 40>(text, coupling);
    }
    for n in [1, 7] {
        let _ = parse_states(text, n);
    }
});
