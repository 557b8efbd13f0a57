//! Firmware image: the kernel's dynamics of the Justin-like robot on a Cortex-M board.
//!
//! Links the kernel without a global allocator — the build fails if anything in the kernel's
//! dependency graph needs `alloc` — and, run under QEMU, evaluates M, C, g and the right TCP
//! Jacobian in `f32` at the home pose and reports them over semihosting, exiting with success
//! only if every value is finite and M is positive definite.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use fixtures::justin;
use kernel::dynamics::{coriolis_matrix, crba, forward_kinematics, frame_jacobian, gravity, mass_matrix_cholesky};
use kernel::Data;
use nalgebra::{SMatrix, SVector};
use panic_semihosting as _;

/// Evaluates the dynamics once; `Err` names the first failure.
fn evaluate() -> Result<f32, &'static str> {
    let model = justin::model::<f32>().map_err(|_| "model")?;
    let mut data = Data::new(&model);
    let q = justin::home_configuration::<f32>();
    let v = SVector::<f32, { justin::N }>::repeat(0.1);
    forward_kinematics(&model, &mut data, &q, &v).map_err(|_| "forward kinematics")?;
    let trace = crba(&model, &mut data).trace();
    mass_matrix_cholesky(&data).map_err(|_| "mass matrix not positive definite")?;
    let coriolis = coriolis_matrix(&model, &mut data).norm();
    let g = gravity(&model, &mut data).norm();
    let mut jacobian = SMatrix::<f32, 6, { justin::N }>::zeros();
    frame_jacobian(&model, &data, justin::RIGHT_TCP, &mut jacobian).map_err(|_| "jacobian")?;
    let total = trace + coriolis + g + jacobian.norm();
    if total.is_finite() {
        Ok(total)
    } else {
        Err("non-finite dynamics")
    }
}

#[entry]
fn main() -> ! {
    match evaluate() {
        Ok(checksum) => {
            hprintln!("dynamics ok, checksum {}", checksum);
            debug::exit(debug::EXIT_SUCCESS);
        }
        Err(what) => {
            hprintln!("dynamics failed: {}", what);
            debug::exit(debug::EXIT_FAILURE);
        }
    }
    loop {
        cortex_m::asm::wfi();
    }
}
