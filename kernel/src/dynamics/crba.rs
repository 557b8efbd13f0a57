//! Composite rigid-body algorithm: the joint-space inertia matrix.

use nalgebra::{RealField, SMatrix, Vector6};

use super::kernels::{add_coupled, dot6, scale6, walk_drives};
use crate::math::spatial::SpatialMatrix;
use crate::model::{Body, Data, Model, WorldInertia};

/// Joint-space inertia matrix `M(q)` ((2.1)) by the composite rigid-body algorithm.
///
/// One backward pass over the bodies (children before parents): the composite inertia
/// `I^c_i` (ten-parameter form) is complete when body `i` is reached, is added to its parent's,
/// and gives the force `F = I^c_i S_i`; then `M_tree[j][i] = S_jᵀ F` for each `j` on the path
/// from `i` to the root (world coordinates need no transforms), mapped to coordinates as
/// `Gᵀ M_tree G`. A joint driven by one coordinate `c` with coefficient `g` walks the scaled
/// subspaces `g_j S_j` of its ancestors with the scaled force `g_i F` (one product per entry);
/// entries through a joint coupled to several coordinates go through its drive row. Entries of
/// bodies on different branches are never visited (branch-induced sparsity: they are zero).
/// Both triangles are filled; `M` is symmetric positive definite for a valid model.
///
/// Precondition: [`super::forward_kinematics`] or [`super::placement_kinematics`] at `q`. Writes
/// `composite_world_inertias` (ten-parameter form; [`composite_inertia_matrices`] forms the 6×6
/// matrices on request) and `mass_matrix` (returned). Cost O(B·depth).
pub fn crba<'d, T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &'d mut Data<T, N, B, F>,
) -> &'d SMatrix<T, N, N> {
    let bodies = model.bodies();
    let walk = walk_table(model, &data.motion_subspaces);
    let composites = &mut data.composite_world_inertias;
    *composites = data.world_inertias;
    let m = data.mass_matrix.as_mut_slice();
    m.fill(T::zero());
    for (i, (s_i, own)) in data.motion_subspaces.iter().zip(walk.iter()).enumerate().rev() {
        // Every child has a larger index: the composite of body `i` is complete.
        let Some(composite) = composites.get(i).copied() else { continue };
        if let Some(parent) = composites.get_mut(own.parent) {
            parent.add(&composite);
        }
        let force = composite.apply(s_i);
        if own.coordinate >= N {
            coupled_column::<T, N, B>(m, bodies, &walk, &data.motion_subspaces, i, &force);
            continue;
        }
        let c = own.coordinate;
        let column = c * N;
        // `g_i F`: with the scaled subspaces `g_j S_j` every entry is one product.
        let f = scale6(&force, own.coefficient);
        if let Some(x) = m.get_mut(column + c) {
            *x += dot6(&own.scaled, &f);
        }
        let mut a = own.parent;
        while let Some(ancestor) = walk.get(a) {
            let value = dot6(&ancestor.scaled, &f);
            if ancestor.coordinate < N {
                let r = ancestor.coordinate;
                if let Some(x) = m.get_mut(column + r) {
                    *x += value;
                }
                if let Some(x) = m.get_mut(r * N + c) {
                    *x += value;
                }
            } else if let Some(b) = bodies.get(a) {
                // A coupled ancestor (its scaled subspace is the raw one): through its drive row.
                for t in b.drive.terms() {
                    let v = t.coefficient * value;
                    if let Some(x) = m.get_mut(column + t.coordinate) {
                        *x += v;
                    }
                    if let Some(x) = m.get_mut(t.coordinate * N + c) {
                        *x += v;
                    }
                }
            }
            a = ancestor.parent;
        }
    }
    &data.mass_matrix
}

/// One body as the walk of [`crba`] reads it: its parent (`B` for none), its coordinate and
/// coefficient (`N` and one for a joint coupled to several coordinates) and the scaled motion
/// subspace `g S` (the raw `S` for a coupled joint).
#[derive(Clone, Copy)]
struct WalkBody<T> {
    scaled: Vector6<T>,
    parent: usize,
    coordinate: usize,
    coefficient: T,
}

/// The [`WalkBody`] of every body, from [`walk_drives`] and the motion subspaces.
#[inline(always)]
fn walk_table<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    subspaces: &[Vector6<T>; B],
) -> [WalkBody<T>; B] {
    let drives = walk_drives(model);
    let mut out = [WalkBody { scaled: Vector6::zeros(), parent: B, coordinate: N, coefficient: T::one() }; B];
    for ((slot, s), d) in out.iter_mut().zip(subspaces.iter()).zip(drives.iter()) {
        *slot = WalkBody {
            scaled: scale6(s, d.coefficient),
            parent: d.parent,
            coordinate: d.coordinate,
            coefficient: d.coefficient,
        };
    }
    out
}

/// The entries of body `i`, whose joint is coupled to several coordinates (force
/// `F = I^c_i S_i`): its own `S_iᵀ F` and `S_jᵀ F` of every ancestor `j`, each through both
/// drive rows.
#[inline(never)]
fn coupled_column<T: RealField + Copy, const N: usize, const B: usize>(
    m: &mut [T],
    bodies: &[Body<T>],
    walk: &[WalkBody<T>; B],
    subspaces: &[Vector6<T>; B],
    i: usize,
    force: &Vector6<T>,
) {
    let (Some(body), Some(s_i), Some(own)) = (bodies.get(i), subspaces.get(i), walk.get(i)) else { return };
    let terms = body.drive.terms();
    add_coupled::<T, N>(m, terms, terms, dot6(s_i, force));
    let mut a = own.parent;
    while let (Some(ancestor), Some(s_a), Some(w)) = (bodies.get(a), subspaces.get(a), walk.get(a)) {
        let value = dot6(s_a, force);
        add_coupled::<T, N>(m, ancestor.drive.terms(), terms, value);
        add_coupled::<T, N>(m, terms, ancestor.drive.terms(), value);
        a = w.parent;
    }
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
