//! Composite rigid-body algorithm: the joint-space inertia matrix.

use nalgebra::{RealField, SMatrix, Vector6};

use super::kernels::{add_coupled, add_entry, dot6, scale6, walk_drives};
use crate::math::spatial::SpatialMatrix;
use crate::model::{Data, Model, WorldInertia};

/// Joint-space inertia matrix `M(q)` ((2.1)) by the composite rigid-body algorithm.
///
/// Backward pass: composite inertias `I^c_p += I^c_i` (ten-parameter form). Then for every
/// body `i` the force `F = I^c_i S_i` gives `M_tree[j][i] = S_jᵀ F` for each `j` on the path
/// from `i` to the root (world coordinates need no transforms), mapped to coordinates as
/// `Gᵀ M_tree G`. Entries of bodies on different branches are never visited (branch-induced
/// sparsity: they are zero). Both triangles are filled; `M` is symmetric positive definite for a
/// valid model.
///
/// Precondition: [`super::forward_kinematics`] or [`super::placement_kinematics`] at `q`. Writes
/// `composite_world_inertias` (ten-parameter form; [`composite_inertia_matrices`] forms the 6×6
/// matrices on request) and `mass_matrix` (returned). Cost O(B·depth).
pub fn crba<'d, T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &'d mut Data<T, N, B, F>,
) -> &'d SMatrix<T, N, N> {
    accumulate_world_composites(model, &data.world_inertias, &mut data.composite_world_inertias);
    data.mass_matrix.as_mut_slice().fill(T::zero());
    let bodies = model.bodies();
    let drives = walk_drives(model);
    // `g_a S_a`: a walk step is one product with the body's scaled force.
    let mut scaled = [Vector6::zeros(); B];
    for ((x, s), d) in scaled.iter_mut().zip(data.motion_subspaces.iter()).zip(drives.iter()) {
        *x = scale6(s, d.coefficient);
    }
    let m: &mut [[T; N]; N] = &mut data.mass_matrix.data.0;
    for (((body, composite), s_i), own) in
        bodies.iter().zip(data.composite_world_inertias.iter()).zip(data.motion_subspaces.iter()).zip(drives.iter())
    {
        let force = composite.apply(s_i);
        let terms = body.drive.terms();
        if own.coordinate >= N {
            // A coupled joint: every entry through both drive rows.
            add_coupled::<T, N>(m.as_flattened_mut(), terms, terms, dot6(s_i, &force));
            let mut a = own.parent;
            while let (Some(ancestor), Some(s_a), Some(d)) =
                (bodies.get(a), data.motion_subspaces.get(a), drives.get(a))
            {
                let value = dot6(s_a, &force);
                add_coupled::<T, N>(m.as_flattened_mut(), ancestor.drive.terms(), terms, value);
                add_coupled::<T, N>(m.as_flattened_mut(), terms, ancestor.drive.terms(), value);
                a = d.parent;
            }
            continue;
        }
        let c = own.coordinate;
        let scaled_force = scale6(&force, own.coefficient);
        add_entry(m, c, c, dot6(s_i, &scaled_force) * own.coefficient);
        let mut a = own.parent;
        while let (Some(d), Some(s_a)) = (drives.get(a), scaled.get(a)) {
            if d.coordinate < N {
                let value = dot6(s_a, &scaled_force);
                add_entry(m, d.coordinate, c, value);
                add_entry(m, c, d.coordinate, value);
            } else if let (Some(ancestor), Some(raw)) = (bodies.get(a), data.motion_subspaces.get(a)) {
                let value = dot6(raw, &force);
                add_coupled::<T, N>(m.as_flattened_mut(), ancestor.drive.terms(), terms, value);
                add_coupled::<T, N>(m.as_flattened_mut(), terms, ancestor.drive.terms(), value);
            }
            a = d.parent;
        }
    }
    &data.mass_matrix
}

/// The 6×6 composite inertia `I^c_i` of every subtree from the ten-parameter composites that
/// [`crba`] (or [`super::coriolis_matrix`]) stored: call it first, at the same `q`. Writes
/// `composite_inertias` (returned). Cost O(B).
pub fn composite_inertia_matrices<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    data: &mut Data<T, N, B, F>,
) -> &[SpatialMatrix<T>; B] {
    for (matrix, composite) in data.composite_inertias.iter_mut().zip(data.composite_world_inertias.iter()) {
        *matrix = composite.matrix();
    }
    &data.composite_inertias
}

/// `out_i = Σ_{k ∈ subtree(i)} per_body_k` for ten-parameter inertias (one backward pass).
pub(super) fn accumulate_world_composites<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    per_body: &[WorldInertia<T>; B],
    out: &mut [WorldInertia<T>; B],
) {
    *out = *per_body;
    for (i, body) in model.bodies().iter().enumerate().rev() {
        let Some(own) = out.get(i).copied() else { continue };
        if let Some(parent) = body.parent.and_then(|p| out.get_mut(p.0)) {
            parent.add(&own);
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::dynamics::{forward_kinematics, gravity, kinetic_energy, rnea};
    use crate::test_models::{branched, state};
    use nalgebra::SVector;
    use proptest::prelude::*;

    proptest! {
        /// M is symmetric positive definite, ½ q̇ᵀ M q̇ equals the body-wise kinetic energy,
        /// and RNEA(q, 0, q̈) − g(q) = M q̈ (CRBA against RNEA).
        #[test]
        fn mass_matrix_agrees_with_energy_and_rnea(seed in any::<u64>()) {
            let model = branched::<f64>();
            let mut data = Data::new(&model);
            let (q, v, a) = (state(seed, 2.0), state(seed ^ 1, 2.0), state(seed ^ 2, 3.0));
            forward_kinematics(&model, &mut data, &q, &v).unwrap();
            let m = *crba(&model, &mut data);
            prop_assert!((m - m.transpose()).amax() < 1e-14);
            prop_assert!(m.symmetric_eigenvalues().min() > 1e-6, "M must be positive definite");
            let kinetic = kinetic_energy(&model, &data);
            prop_assert!((0.5 * v.dot(&(m * v)) - kinetic).abs() < 1e-12 * (1.0 + kinetic));

            forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
            let g = *gravity(&model, &mut data);
            let tau = *rnea(&model, &mut data, &a).unwrap();
            prop_assert!((tau - g - m * a).amax() < 1e-11 * (1.0 + tau.amax()));
        }
    }

    #[test]
    fn f32_mass_matrix_is_within_tolerance_of_f64() {
        let (m64, m32) = (branched::<f64>(), branched::<f32>());
        let (mut d64, mut d32) = (Data::new(&m64), Data::new(&m32));
        for seed in 0..20 {
            let q = state(seed, 2.0);
            forward_kinematics(&m64, &mut d64, &q, &SVector::zeros()).unwrap();
            forward_kinematics(&m32, &mut d32, &q.cast(), &SVector::zeros()).unwrap();
            let (a, b) = (*crba(&m64, &mut d64), crba(&m32, &mut d32).cast::<f64>());
            // f32 has ~1.2e-7 relative resolution; a few dozen roundings per entry.
            assert!((a - b).amax() < 2e-5 * a.amax(), "seed {seed}: {}", (a - b).amax());
        }
    }
}
