//! The output contract of the Justin whole-body controller, checked from outside: whatever the
//! input, the actuator frame is finite and within the model's effort limits and the configured
//! platform limits, and its mode says `Normal` exactly when no fault is reported. The oracle of
//! the proptest fuzz test (`tests/tests/fuzz.rs`) and of the cargo-fuzz targets (`fuzz/`).

use fixtures::justin::whole_body::JustinController;
use kernel::controller::faults::SafeOutput;
use kernel::controller::PLATFORM_DOF;
use nalgebra::RealField;

/// Relative slack on every limit (rounding of the limiter's own arithmetic).
const SLACK: f64 = 1e-6;

/// `Err` with what is violated if the controller's last output breaks the contract.
pub fn check_output<T: RealField + Copy>(controller: &JustinController<T>) -> Result<(), String> {
    let f = |x: T| -> f64 { nalgebra::try_convert(x).unwrap_or(f64::NAN) };
    let out = controller.output();
    let effort = controller.model().limits.effort;
    let limits = &controller.config().output_limits;
    for (i, tau) in out.torque.iter().enumerate() {
        let (tau, e) = (f(*tau), effort.get(i + PLATFORM_DOF).map_or(f64::NAN, |e| f(*e)));
        if !(tau.is_finite() && tau.abs() <= e * (1.0 + SLACK)) {
            return Err(format!("τ_{i} = {tau} (limit {e})"));
        }
    }
    for (axis, (v, vmax)) in out.platform.velocity.iter().zip(limits.base_velocity.iter()).enumerate() {
        let (v, vmax) = (f(*v), f(*vmax));
        if !(v.is_finite() && v.abs() <= vmax * (1.0 + SLACK)) {
            return Err(format!("base velocity {axis} = {v} (limit {vmax})"));
        }
    }
    for rate in &out.platform.leg_rates {
        let (rate, limit) = (f(*rate), f(limits.leg_rate));
        if !(rate.is_finite() && rate.abs() <= limit * (1.0 + SLACK)) {
            return Err(format!("leg rate {rate} (limit {limit})"));
        }
    }
    let fault = controller.telemetry().fault;
    if fault.is_none() != (out.mode == SafeOutput::Normal) {
        return Err(format!("mode {:?} with fault {fault:?}", out.mode));
    }
    if out.brake != (out.mode == SafeOutput::Brake) {
        return Err(format!("brake {} in mode {:?}", out.brake, out.mode));
    }
    Ok(())
}
