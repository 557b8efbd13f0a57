//! The Christoffel-consistent Coriolis/centrifugal matrix.

use nalgebra::{RealField, SMatrix};

use super::add_coupled;
use super::crba::accumulate_composites;
use crate::math::spatial::{force_bar_matrix, force_cross_matrix, motion_cross, motion_cross_matrix};
use crate::model::{BodyId, Data, Model};

/// Coriolis/centrifugal matrix `C(q, q̇)` of (2.1) built from the Christoffel symbols of the
/// first kind, so that `Ṁ = C + Cᵀ` (2.7) and `C q̇` is the velocity-product term of RNEA.
///
/// With world-frame body Jacobians `J_i` (columns `S_j`, `j ∈ support(i)`) and
/// `J̇_i` (columns `Ṡ_j = v_j × S_j`):
/// `C = Σ_i J_iᵀ (I_i J̇_i + B_i J_i)`, with the body operator
/// `B_i = ½ [(v_i ×*) I_i + (I_i v_i)×̄ − I_i (v_i ×)]`
/// (Echeandia & Wensing's Christoffel-consistent factorization; `B_i + B_iᵀ = İ_i`, which is
/// what makes `Ṁ = C + Cᵀ` hold, and `B_i v_i = v_i ×* I_i v_i`). It is evaluated with
/// subtree composites `I^c`, `B^c` in O(B·depth): for each body `j`
/// - `C[a][j] = S_aᵀ (I^c_j Ṡ_j + B^c_j S_j)` for `a` on the path from `j` to the root,
/// - `C[j][b] = (I^c_j S_j)ᵀ Ṡ_b + (B^cᵀ_j S_j)ᵀ S_b` for `b` a strict ancestor of `j`,
///
/// mapped to coordinates as `Gᵀ C_tree G`.
///
/// Precondition: [`super::forward_kinematics`] at `(q, q̇)`. Writes `composite_inertias`,
/// `composite_coriolis` and `coriolis` (returned).
pub fn coriolis_matrix<'d, T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &'d mut Data<T, N, B, F>,
) -> &'d SMatrix<T, N, N> {
    let half = nalgebra::convert::<f64, T>(0.5);
    for ((b, inertia), v) in
        data.composite_coriolis.iter_mut().zip(data.body_inertias.iter()).zip(data.body_velocities.iter())
    {
        let momentum = inertia * v;
        *b = (force_cross_matrix(v) * inertia + force_bar_matrix(&momentum) - inertia * motion_cross_matrix(v)) * half;
    }
    let per_body = data.composite_coriolis;
    accumulate_composites(model, &per_body, &mut data.composite_coriolis);
    accumulate_composites(model, &data.body_inertias, &mut data.composite_inertias);

    data.coriolis.fill(T::zero());
    for (j, body) in model.bodies().iter().enumerate() {
        let (Some(ic), Some(bc), Some(s_j), Some(v_j)) = (
            data.composite_inertias.get(j),
            data.composite_coriolis.get(j),
            data.motion_subspaces.get(j),
            data.body_velocities.get(j),
        ) else {
            continue;
        };
        let s_dot_j = motion_cross(v_j, s_j);
        let column_force = ic * s_dot_j + bc * s_j;
        let row_inertia = ic * s_j;
        let row_coriolis = bc.transpose() * s_j;
        for a in model.support(BodyId(j)) {
            let (Some(ancestor), Some(s_a), Some(v_a)) =
                (model.body(a), data.motion_subspaces.get(a.0), data.body_velocities.get(a.0))
            else {
                continue;
            };
            add_coupled(&mut data.coriolis, &ancestor.drive, &body.drive, s_a.dot(&column_force));
            if a.0 != j {
                let s_dot_a = motion_cross(v_a, s_a);
                let value = row_inertia.dot(&s_dot_a) + row_coriolis.dot(s_a);
                add_coupled(&mut data.coriolis, &body.drive, &ancestor.drive, value);
            }
        }
    }
    &data.coriolis
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::dynamics::{crba, forward_kinematics, gravity, rnea};
    use crate::test_models::{branched, state};
    use nalgebra::SVector;
    use proptest::prelude::*;

    fn mass(q: &SVector<f64, 6>) -> SMatrix<f64, 6, 6> {
        let model = branched::<f64>();
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, q, &SVector::zeros()).unwrap();
        *crba(&model, &mut data)
    }

    proptest! {
        /// (2.7): Ṁ = C + Cᵀ, i.e. Ṁ − 2C is skew-symmetric, with Ṁ from central differences
        /// along q̇; and C q̇ + g = RNEA(q, q̇, 0).
        #[test]
        fn mass_derivative_equals_c_plus_c_transpose(seed in any::<u64>()) {
            let model = branched::<f64>();
            let mut data = Data::new(&model);
            let (q, v) = (state(seed, 2.0), state(seed ^ 7, 2.0));
            forward_kinematics(&model, &mut data, &q, &v).unwrap();
            let c = *coriolis_matrix(&model, &mut data);
            let h = 1e-5;
            let m_dot = (mass(&(q + v * h)) - mass(&(q - v * h))) / (2.0 * h);
            let scale = 1.0 + m_dot.amax();
            prop_assert!((m_dot - c - c.transpose()).amax() < 1e-7 * scale,
                "Ṁ − C − Cᵀ = {}", (m_dot - c - c.transpose()).amax());
            let skew = m_dot - c * 2.0;
            prop_assert!((skew + skew.transpose()).amax() < 1e-7 * scale);

            let bias = *rnea(&model, &mut data, &SVector::zeros()).unwrap();
            let g = *gravity(&model, &mut data);
            prop_assert!((c * v + g - bias).amax() < 1e-11 * (1.0 + bias.amax()));
        }
    }

    #[test]
    fn f32_coriolis_is_within_tolerance_of_f64() {
        let (m64, m32) = (branched::<f64>(), branched::<f32>());
        let (mut d64, mut d32) = (Data::new(&m64), Data::new(&m32));
        for seed in 0..20 {
            let (q, v) = (state(seed, 2.0), state(seed + 100, 2.0));
            forward_kinematics(&m64, &mut d64, &q, &v).unwrap();
            forward_kinematics(&m32, &mut d32, &q.cast(), &v.cast()).unwrap();
            let (a, b) = (*coriolis_matrix(&m64, &mut d64), coriolis_matrix(&m32, &mut d32).cast::<f64>());
            assert!((a - b).amax() < 2e-5 * (1.0 + a.amax()), "seed {seed}: {}", (a - b).amax());
        }
    }
}
