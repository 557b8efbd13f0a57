//! The drift term `J̇(q, q̇) q̇` of point and frame Jacobians.

use nalgebra::{RealField, Vector3, Vector6};

use super::error::DynamicsError;
use crate::math::spatial::{angular, linear, linear_at_point};
use crate::model::{BodyId, Data, FrameId, Model};

/// `J̇(q, q̇) q̇` for the point `point` (world coordinates) attached to `body`: the point's
/// classical acceleration `[p̈; ω̇]` at `q̈ = 0` without gravity, world-aligned, linear first.
///
/// With the body's velocity-product spatial acceleration `ζ = (ω̇; a_O)` and velocity
/// `(ω; v_O)`: `p̈ = a_O + ω̇ × p + ω × ṗ` with `ṗ = v_O + ω × p`. It completes the task-space
/// acceleration `ẍ = J q̈ + J̇ q̇` used by the acceleration-level controllers (Sec. 4.2.3).
///
/// Precondition: [`super::forward_kinematics`] was called for the current state.
/// Cost O(1). Errors: [`DynamicsError::UnknownBody`].
pub fn point_drift<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    body: BodyId,
    point: &Vector3<T>,
) -> Result<Vector6<T>, DynamicsError> {
    model.body(body).ok_or(DynamicsError::UnknownBody)?;
    let velocity = data.body_velocities.get(body.0).ok_or(DynamicsError::UnknownBody)?;
    let drift = data.body_drift_accelerations.get(body.0).ok_or(DynamicsError::UnknownBody)?;
    let omega = angular(velocity);
    let omega_dot = angular(drift);
    let point_velocity = linear_at_point(velocity, point);
    let a = linear(drift) + omega_dot.cross(point) + omega.cross(&point_velocity);
    Ok(Vector6::new(a.x, a.y, a.z, omega_dot.x, omega_dot.y, omega_dot.z))
}

/// `J̇(q, q̇) q̇` of the origin of frame `frame` (see [`point_drift`]); zero for a world frame.
pub fn frame_drift<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    frame: FrameId,
) -> Result<Vector6<T>, DynamicsError> {
    let f = model.frame(frame).ok_or(DynamicsError::UnknownFrame)?;
    let origin = data.frame_placements.get(frame.0).ok_or(DynamicsError::UnknownFrame)?.translation.vector;
    match f.parent {
        Some(body) => point_drift(model, data, body, &origin),
        None => Ok(Vector6::zeros()),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::dynamics::{forward_kinematics, frame_jacobian};
    use crate::test_models::{branched, state, N, TCP, WRIST};
    use nalgebra::{SMatrix, SVector};
    use proptest::prelude::*;

    proptest! {
        /// J̇ q̇ from the drift equals (J(q + h q̇) − J(q − h q̇)) q̇ / 2h.
        #[test]
        fn drift_matches_jacobian_derivative(seed in any::<u64>()) {
            let model = branched::<f64>();
            let mut data = Data::new(&model);
            let (q, v) = (state(seed, 2.0), state(seed ^ 5, 1.5));
            for frame in [TCP, WRIST] {
                forward_kinematics(&model, &mut data, &q, &v).unwrap();
                let drift = frame_drift(&model, &data, frame).unwrap();
                let h = 1e-6;
                let mut jac = |q: SVector<f64, N>| {
                    forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
                    let mut j = SMatrix::<f64, 6, N>::zeros();
                    frame_jacobian(&model, &data, frame, &mut j).unwrap();
                    j
                };
                let fd = (jac(q + v * h) - jac(q - v * h)) * v / (2.0 * h);
                prop_assert!((fd - drift).amax() < 1e-6 * (1.0 + drift.amax()), "{}", (fd - drift).amax());
            }
        }
    }
}
