//! Rigid-body dynamics of the kinematic tree (Sec. 2.1 of the thesis; Featherstone's
//! algorithms), one algorithm per file.
//!
//! Call [`forward_kinematics`] once per state; the other algorithms read the kinematics it
//! stored in [`crate::model::Data`] and write their own outputs there:
//!
//! | algorithm | computes | cost |
//! | --- | --- | --- |
//! | [`forward_kinematics`] | placements, motion subspaces, body velocities and drifts | O(B) |
//! | [`frame_jacobian`], [`point_jacobian`] | 6×N Jacobian, world-aligned, linear rows first | O(depth) |
//! | [`frame_drift`], [`point_drift`] | `J̇(q, q̇) q̇` | O(1) |
//! | [`rnea`] | `M q̈ + C q̇ + g` | O(B) |
//! | [`gravity`] | `g(q)` | O(B) |
//! | [`crba`] | `M(q)` | O(B·depth) |
//! | [`coriolis_matrix`] | `C(q, q̇)` with `Ṁ = C + Cᵀ` (2.7) | O(B·depth) |
//! | [`mass_matrix_cholesky`], [`forward_dynamics`] | `M = L Lᵀ`, `q̈ = M⁻¹(τ − C q̇ − g)` | O(N³) |
//! | [`kinetic_energy`], [`potential_energy`] | `½ q̇ᵀ M q̇`, `−Σ m_i gᵀ c_i` | O(B) |
//!
//! With coupled joints the tree quantities are mapped through the constant drive matrix `G`
//! (`q_tree = G q + offset`): `M = Gᵀ M_tree G`, `C = Gᵀ C_tree G`, `τ = Gᵀ τ_tree`,
//! `J = J_tree G`; see [`crate::model::JointDrive`].

mod coriolis_matrix;
mod crba;
mod energy;
mod error;
mod forward_dynamics;
mod forward_kinematics;
mod frame_drift;
mod frame_jacobian;
mod gravity;
mod rnea;

pub use coriolis_matrix::coriolis_matrix;
pub use crba::crba;
pub use energy::{kinetic_energy, potential_energy};
pub use error::DynamicsError;
pub use forward_dynamics::{forward_dynamics, mass_matrix_cholesky};
pub use forward_kinematics::forward_kinematics;
pub use frame_drift::{frame_drift, point_drift};
pub use frame_jacobian::{frame_jacobian, point_jacobian};
pub use gravity::gravity;
pub use rnea::rnea;

use nalgebra::{RealField, SMatrix, SVector};

use crate::model::JointDrive;

/// `m += value · g_rowᵀ g_col`: adds a tree-level entry to a coordinate-level matrix through
/// the drive rows of two joints.
#[inline]
fn add_coupled<T: RealField + Copy, const N: usize>(
    m: &mut SMatrix<T, N, N>,
    row: &JointDrive<T>,
    col: &JointDrive<T>,
    value: T,
) {
    for r in row.terms() {
        for c in col.terms() {
            if let Some(entry) = m.get_mut((r.coordinate, c.coordinate)) {
                *entry += r.coefficient * c.coefficient * value;
            }
        }
    }
}

/// `out += value · g`: adds a tree-level generalized force to the coordinate vector.
#[inline]
fn add_to_coordinates<T: RealField + Copy, const N: usize>(out: &mut SVector<T, N>, drive: &JointDrive<T>, value: T) {
    for t in drive.terms() {
        if let Some(entry) = out.get_mut(t.coordinate) {
            *entry += t.coefficient * value;
        }
    }
}

/// Checks that every entry of a state vector is finite.
#[inline]
fn check_finite<T: RealField + Copy, const R: usize>(
    v: &SVector<T, R>,
    input: &'static str,
) -> Result<(), DynamicsError> {
    if crate::math::all_finite(v) {
        Ok(())
    } else {
        Err(DynamicsError::NonFinite { input })
    }
}

mod jacobian_derivative;
pub use jacobian_derivative::{frame_jacobian_derivative, point_jacobian_derivative};
