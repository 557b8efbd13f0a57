//! Generalized gravity.

use nalgebra::{RealField, SVector};

use super::rnea::{backward_project, gravity_acceleration};
use crate::model::{Data, Model};

/// Generalized gravity `g(q) = ∂V_g/∂q` ((2.1)): RNEA with `q̇ = 0`, `q̈ = 0`, i.e. every body
/// carries `f_i = I_i (0; −g)` and the joints project the subtree sums.
///
/// Precondition: [`super::forward_kinematics`] or [`super::placement_kinematics`] at `q`
/// (velocities are not used). Writes
/// `body_forces`, `tau` and `gravity_torque` (returned). Cost O(B).
pub fn gravity<'d, T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &'d mut Data<T, N, B, F>,
) -> &'d SVector<T, N> {
    let base = gravity_acceleration(model);
    for (force, inertia) in data.body_forces.iter_mut().zip(data.world_inertias.iter()) {
        *force = inertia.apply(&base);
    }
    backward_project(model, data);
    data.gravity_torque = data.tau;
    &data.gravity_torque
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::dynamics::{forward_kinematics, potential_energy};
    use crate::test_models::{branched, state, N};
    use proptest::prelude::*;

    proptest! {
        /// g(q) = ∂V_g/∂q (2.1), checked against central differences of the potential energy.
        #[test]
        fn gravity_is_the_gradient_of_the_potential(seed in any::<u64>()) {
            let model = branched::<f64>();
            let mut data = Data::new(&model);
            let q = state(seed, 2.0);
            forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
            let g = *gravity(&model, &mut data);
            let h = 1e-6;
            for k in 0..N {
                let mut e = SVector::<f64, N>::zeros();
                e[k] = h;
                let mut v = |q: SVector<f64, N>| {
                    forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
                    potential_energy(&model, &data)
                };
                let fd = (v(q + e) - v(q - e)) / (2.0 * h);
                prop_assert!((fd - g[k]).abs() < 1e-6 * (1.0 + g[k].abs()), "k={k}: {fd} vs {}", g[k]);
            }
        }
    }
}
