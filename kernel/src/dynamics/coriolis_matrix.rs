//! The Christoffel-consistent Coriolis/centrifugal matrix.

use nalgebra::{RealField, SMatrix, Vector6};

use super::crba::accumulate_world_composites;
use super::kernels::{add6, add_coupled, add_entry, add_scaled6, dot6, scale6, walk_drives};
use super::rnea::force_cross;
use crate::math::spatial::{SpatialForce, SpatialMatrix};
use crate::model::{Data, Model, WorldInertia};

/// Coriolis/centrifugal matrix `C(q, q̇)` of (2.1) built from the Christoffel symbols of the
/// first kind, so that `Ṁ = C + Cᵀ` (2.7) and `C q̇` is the velocity-product term of RNEA.
///
/// With world-frame body Jacobians `J_i` (columns `S_j`, `j ∈ support(i)`) and
/// `J̇_i` (columns `Ṡ_j = v_j × S_j`):
/// `C = Σ_i J_iᵀ (I_i J̇_i + B_i J_i)`, with the body operator
/// `B_i = ½ [(v_i ×*) I_i + (I_i v_i)×̄ − I_i (v_i ×)]`
/// (Echeandia & Wensing's Christoffel-consistent factorization; `B_i + B_iᵀ = İ_i`, which is
/// what makes `Ṁ = C + Cᵀ` hold, and `B_i v_i = v_i ×* I_i v_i`). Since `(v ×*) = −(v ×)ᵀ`,
/// `B_i = ½ İ_i + ½ (I_i v_i)×̄`: a symmetric part that is the rate of the inertia (ten
/// parameters, [`crate::model::WorldInertia::rate`]) and a skew part linear in the momentum. The subtree
/// composites are therefore `B^c_j = ½ İ^c_j + ½ (p^c_j)×̄` with `İ^c_j = Σ İ_k` and momentum
/// `p^c_j = Σ I_k v_k`, accumulated in one backward pass. Then, in O(B·depth), for each body `j`
/// - `C[a][j] = S_aᵀ (I^c_j Ṡ_j + B^c_j S_j)` for `a` on the path from `j` to the root,
/// - `C[j][b] = (I^c_j S_j)ᵀ Ṡ_b + (B^cᵀ_j S_j)ᵀ S_b` for `b` a strict ancestor of `j`,
///
/// with `B^c_j S = ½ İ^c_j S + ½ S ×* p^c_j` and `B^cᵀ_j S = ½ İ^c_j S − ½ S ×* p^c_j`,
/// mapped to coordinates as `Gᵀ C_tree G`. Entries of bodies on different branches are zero
/// and never visited.
///
/// The walks apply `B^c_j` to motion subspaces without forming the 6×6 operator
/// ([`composite_coriolis_operators`] forms it on request).
///
/// Precondition: [`super::forward_kinematics`] at `(q, q̇)`. Writes `composite_world_inertias`,
/// `composite_inertia_rates`, `composite_momenta` and `coriolis` (returned).
pub fn coriolis_matrix<'d, T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &'d mut Data<T, N, B, F>,
) -> &'d SMatrix<T, N, N> {
    let half = nalgebra::convert::<f64, T>(0.5);
    for (((rate, momentum), inertia), v) in data
        .composite_inertia_rates
        .iter_mut()
        .zip(data.composite_momenta.iter_mut())
        .zip(data.world_inertias.iter())
        .zip(data.body_velocities.iter())
    {
        *rate = inertia.rate(v);
        *momentum = inertia.apply(v);
    }
    accumulate_world_composites(model, &data.world_inertias, &mut data.composite_world_inertias);
    for (i, body) in model.bodies().iter().enumerate().rev() {
        let (Some(own_rate), Some(own_momentum)) =
            (data.composite_inertia_rates.get(i).copied(), data.composite_momenta.get(i).copied())
        else {
            continue;
        };
        if let Some(p) = body.parent {
            if let Some(parent) = data.composite_inertia_rates.get_mut(p.0) {
                parent.add(&own_rate);
            }
            if let Some(parent) = data.composite_momenta.get_mut(p.0) {
                *parent = add6(parent, &own_momentum);
            }
        }
    }

    data.coriolis.as_mut_slice().fill(T::zero());
    let bodies = model.bodies();
    let drives = walk_drives(model);
    // `g_a S_a` and `g_a Ṡ_a`: a walk step is three products with the body's scaled vectors.
    let mut scaled = [(Vector6::zeros(), Vector6::zeros()); B];
    for (((x, s), s_dot), d) in
        scaled.iter_mut().zip(data.motion_subspaces.iter()).zip(data.subspace_rates.iter()).zip(drives.iter())
    {
        *x = (scale6(s, d.coefficient), scale6(s_dot, d.coefficient));
    }
    let m: &mut [[T; N]; N] = &mut data.coriolis.data.0;
    let per_body = bodies
        .iter()
        .zip(data.composite_world_inertias.iter())
        .zip(data.composite_inertia_rates.iter())
        .zip(data.composite_momenta.iter())
        .zip(data.motion_subspaces.iter().zip(data.subspace_rates.iter()))
        .zip(drives.iter());
    for (((((body, ic), rate), momentum), (s_j, s_dot_j)), own) in per_body {
        let d = scale6(&rate.apply(s_j), half);
        let e = scale6(&force_cross(s_j, momentum), half);
        let column_force = add6(&add6(&ic.apply(s_dot_j), &d), &e);
        let row_inertia = ic.apply(s_j);
        let row_coriolis = add_scaled6(&d, &e, -T::one());
        let terms = body.drive.terms();
        if own.coordinate >= N {
            // A coupled joint: every entry through both drive rows.
            add_coupled::<T, N>(m.as_flattened_mut(), terms, terms, dot6(s_j, &column_force));
            let mut a = own.parent;
            while let (Some(ancestor), Some(s_a), Some(s_dot_a), Some(next)) =
                (bodies.get(a), data.motion_subspaces.get(a), data.subspace_rates.get(a), drives.get(a))
            {
                let column = dot6(s_a, &column_force);
                let row = dot6(&row_inertia, s_dot_a) + dot6(&row_coriolis, s_a);
                let terms_a = ancestor.drive.terms();
                add_coupled::<T, N>(m.as_flattened_mut(), terms_a, terms, column);
                add_coupled::<T, N>(m.as_flattened_mut(), terms, terms_a, row);
                a = next.parent;
            }
            continue;
        }
        let c = own.coordinate;
        let g = own.coefficient;
        add_entry(m, c, c, dot6(s_j, &column_force) * g * g);
        let (column_force_g, row_inertia_g, row_coriolis_g) =
            (scale6(&column_force, g), scale6(&row_inertia, g), scale6(&row_coriolis, g));
        let mut a = own.parent;
        while let (Some(next), Some((s_a, s_dot_a))) = (drives.get(a), scaled.get(a)) {
            if next.coordinate < N {
                let column = dot6(s_a, &column_force_g);
                let row = dot6(&row_inertia_g, s_dot_a) + dot6(&row_coriolis_g, s_a);
                add_entry(m, next.coordinate, c, column);
                add_entry(m, c, next.coordinate, row);
            } else if let (Some(ancestor), Some(s_a), Some(s_dot_a)) =
                (bodies.get(a), data.motion_subspaces.get(a), data.subspace_rates.get(a))
            {
                let column = dot6(s_a, &column_force);
                let row = dot6(&row_inertia, s_dot_a) + dot6(&row_coriolis, s_a);
                let terms_a = ancestor.drive.terms();
                add_coupled::<T, N>(m.as_flattened_mut(), terms_a, terms, column);
                add_coupled::<T, N>(m.as_flattened_mut(), terms, terms_a, row);
            }
            a = next.parent;
        }
    }
    &data.coriolis
}

/// The 6×6 composite Coriolis operators `B^c_j = ½ İ^c_j + ½ (p^c_j)×̄` of every subtree
/// (the operators of [`coriolis_matrix`]) from the composite inertia rates and momenta that
/// [`coriolis_matrix`] stored: call it first, at the same state. Writes `composite_coriolis`
/// (returned). Cost O(B).
pub fn composite_coriolis_operators<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    data: &mut Data<T, N, B, F>,
) -> &[SpatialMatrix<T>; B] {
    let half = nalgebra::convert::<f64, T>(0.5);
    for ((bc, rate), momentum) in
        data.composite_coriolis.iter_mut().zip(data.composite_inertia_rates.iter()).zip(data.composite_momenta.iter())
    {
        *bc = coriolis_operator(rate, momentum, half);
    }
    &data.composite_coriolis
}

/// The 6×6 operator `B = ½ İ + ½ (p)×̄` from the inertia rate `İ` (ten-parameter form, zero
/// mass) and the momentum `p = (n; f)`, with `(p)×̄ = [[−[n]×, −[f]×], [−[f]×, 0]]`
/// ([`crate::math::spatial::force_bar_matrix`]).
fn coriolis_operator<T: RealField + Copy>(
    rate: &WorldInertia<T>,
    momentum: &SpatialForce<T>,
    half: T,
) -> SpatialMatrix<T> {
    let [h0, h1, h2] = rate.first_moment.map(|x| x * half);
    let [xx, yy, zz, xy, xz, yz] = rate.rotational.map(|x| x * half);
    let [n0, n1, n2, f0, f1, f2] = momentum.data.0[0].map(|x| x * half);
    let z = T::zero();
    // Columns of ½ [[İ_rot, [ḣ]×], [−[ḣ]×, 0]] + ½ [[−[n]×, −[f]×], [−[f]×, 0]].
    SpatialMatrix::from_data(nalgebra::ArrayStorage([
        [xx, xy - n2, xz + n1, z, -h2 - f2, h1 + f1],
        [xy + n2, yy, yz - n0, h2 + f2, z, -h0 - f0],
        [xz - n1, yz + n0, zz, -h1 - f1, h0 + f0, z],
        [z, h2 - f2, f1 - h1, z, z, z],
        [f2 - h2, z, h0 - f0, z, z, z],
        [h1 - f1, f0 - h0, z, z, z, z],
    ]))
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
