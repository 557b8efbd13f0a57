//! Kinetic and potential energy of the robot.

use nalgebra::RealField;

use crate::model::{Data, Model};

/// Kinetic energy `T = ½ q̇ᵀ M(q) q̇ = ½ Σ_i v_iᵀ I_i v_i` (J), summed over bodies (so it does
/// not depend on [`super::crba`] and can check it).
///
/// Precondition: [`super::forward_kinematics`] at `(q, q̇)`. Cost O(B).
pub fn kinetic_energy<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
) -> T {
    let half = nalgebra::convert::<f64, T>(0.5);
    data.body_velocities
        .iter()
        .zip(data.body_inertias.iter())
        .take(model.bodies().len())
        .fold(T::zero(), |e, (v, i)| e + v.dot(&(i * v)) * half)
}

/// Gravitational potential energy `V_g = −Σ_i m_i gᵀ c_i` (J), with `c_i` the world centre of
/// mass of body `i`; `g(q) = ∂V_g/∂q`.
///
/// Precondition: [`super::forward_kinematics`] at `q`. Cost O(B).
pub fn potential_energy<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
) -> T {
    model.bodies().iter().zip(data.body_placements.iter()).fold(T::zero(), |e, (body, x)| {
        let com = x.rotation * body.inertia.com + x.translation.vector;
        e - model.gravity.dot(&com) * body.inertia.mass
    })
}
