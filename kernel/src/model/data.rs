//! Preallocated workspace written by the dynamics algorithms (Pinocchio's `Data`).

use nalgebra::{RealField, SMatrix, SVector};

use super::description::Model;
use super::inertia::WorldInertia;
use crate::math::spatial::{Motion, Placement, SpatialForce, SpatialMatrix};

/// Every buffer the dynamics algorithms write. Create it once per model with [`Data::new`];
/// no algorithm allocates.
///
/// All spatial quantities are in world coordinates at the world origin, angular part first
/// (see [`crate::math::spatial`]).
#[derive(Clone, Debug)]
pub struct Data<T: RealField, const N: usize, const B: usize, const F: usize> {
    /// Coordinates `q` of the last [`crate::dynamics::forward_kinematics`] call.
    pub q: SVector<T, N>,
    /// Velocities `q̇` of the last [`crate::dynamics::forward_kinematics`] call.
    pub v: SVector<T, N>,
    /// World placement of each body frame.
    pub body_placements: [Placement<T>; B],
    /// Motion subspace `S_i` of each body's joint (unit joint rate), world frame.
    pub motion_subspaces: [Motion<T>; B],
    /// Spatial velocity `v_i` of each body.
    pub body_velocities: [Motion<T>; B],
    /// Velocity-product acceleration of each body, `Σ_{j ∈ support(i)} (v_j × S_j) q̇_j`: the
    /// body's spatial acceleration for `q̈ = 0` and no gravity.
    pub body_drift_accelerations: [Motion<T>; B],
    /// Spatial acceleration of each body from the last `rnea` call (gravity included as a
    /// fictitious upward base acceleration).
    pub body_accelerations: [Motion<T>; B],
    /// Spatial inertia `I_i` of each body, world frame.
    pub body_inertias: [SpatialMatrix<T>; B],
    /// The same inertias `I_i` in ten-parameter form (written by `forward_kinematics`).
    pub world_inertias: [WorldInertia<T>; B],
    /// `Ṡ_i = v_i × S_i`, the time derivative of each world motion subspace
    /// (written by `forward_kinematics`).
    pub subspace_rates: [Motion<T>; B],
    /// Composite inertia `I^c_i` of each subtree in ten-parameter form (`crba`,
    /// `coriolis_matrix`).
    pub composite_world_inertias: [WorldInertia<T>; B],
    /// Time derivative `İ^c_i` of each composite inertia (`coriolis_matrix`).
    pub composite_inertia_rates: [WorldInertia<T>; B],
    /// Momentum `Σ_{k ∈ subtree(i)} I_k v_k` of each subtree (`coriolis_matrix`).
    pub composite_momenta: [SpatialForce<T>; B],
    /// Composite inertia of each body's subtree, 6×6 (`composite_inertia_matrices`, after
    /// `crba`).
    pub composite_inertias: [SpatialMatrix<T>; B],
    /// Composite Christoffel-consistent Coriolis operator of each subtree
    /// (`composite_coriolis_operators`, after `coriolis_matrix`).
    pub composite_coriolis: [SpatialMatrix<T>; B],
    /// Spatial force transmitted by each body's joint (`rnea`, `gravity`).
    pub body_forces: [SpatialForce<T>; B],
    /// World placement of each fixed frame.
    pub frame_placements: [Placement<T>; F],
    /// Joint-space inertia matrix `M(q)` (symmetric, both triangles filled) from `crba`.
    pub mass_matrix: SMatrix<T, N, N>,
    /// Coriolis/centrifugal matrix `C(q, q̇)` with `Ṁ = C + Cᵀ` (2.7), from `coriolis_matrix`.
    pub coriolis: SMatrix<T, N, N>,
    /// Generalized gravity `g(q)` from `gravity`.
    pub gravity_torque: SVector<T, N>,
    /// Generalized force from `rnea`.
    pub tau: SVector<T, N>,
}

impl<T: RealField + Copy, const N: usize, const B: usize, const F: usize> Data<T, N, B, F> {
    /// A zeroed workspace for `model`.
    pub fn new(_model: &Model<T, N, B, F>) -> Self {
        Self {
            q: SVector::zeros(),
            v: SVector::zeros(),
            body_placements: [Placement::identity(); B],
            motion_subspaces: [Motion::zeros(); B],
            body_velocities: [Motion::zeros(); B],
            body_drift_accelerations: [Motion::zeros(); B],
            body_accelerations: [Motion::zeros(); B],
            body_inertias: [SpatialMatrix::zeros(); B],
            world_inertias: [WorldInertia::zero(); B],
            subspace_rates: [Motion::zeros(); B],
            composite_world_inertias: [WorldInertia::zero(); B],
            composite_inertia_rates: [WorldInertia::zero(); B],
            composite_momenta: [SpatialForce::zeros(); B],
            composite_inertias: [SpatialMatrix::zeros(); B],
            composite_coriolis: [SpatialMatrix::zeros(); B],
            body_forces: [SpatialForce::zeros(); B],
            frame_placements: [Placement::identity(); F],
            mass_matrix: SMatrix::zeros(),
            coriolis: SMatrix::zeros(),
            gravity_torque: SVector::zeros(),
            tau: SVector::zeros(),
        }
    }
}
