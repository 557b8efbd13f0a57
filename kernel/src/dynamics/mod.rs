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

use nalgebra::{RealField, SVector, Vector6};

use crate::model::{DriveTerm, JointDrive};

/// `m += value · g_rowᵀ g_col`: adds a tree-level entry to a coordinate-level N×N matrix,
/// given as its column-major storage `m`, through the drive rows of two joints.
#[inline(always)]
fn add_coupled<T: RealField + Copy, const N: usize>(m: &mut [T], row: &[DriveTerm<T>], col: &[DriveTerm<T>], value: T) {
    for c in col {
        let scaled = c.coefficient * value;
        let start = c.coordinate * N;
        for r in row {
            if let Some(entry) = m.get_mut(start + r.coordinate) {
                *entry += r.coefficient * scaled;
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

/// `a · b` of two spatial vectors, written out.
#[inline(always)]
fn dot6<T: RealField + Copy>(a: &Vector6<T>, b: &Vector6<T>) -> T {
    let [a0, a1, a2, a3, a4, a5] = a.data.0[0];
    let [b0, b1, b2, b3, b4, b5] = b.data.0[0];
    a0 * b0 + a1 * b1 + a2 * b2 + a3 * b3 + a4 * b4 + a5 * b5
}

/// `a + k b` of two spatial vectors, written out.
#[inline(always)]
fn add_scaled6<T: RealField + Copy>(a: &Vector6<T>, b: &Vector6<T>, k: T) -> Vector6<T> {
    let [a0, a1, a2, a3, a4, a5] = a.data.0[0];
    let [b0, b1, b2, b3, b4, b5] = b.data.0[0];
    Vector6::new(a0 + k * b0, a1 + k * b1, a2 + k * b2, a3 + k * b3, a4 + k * b4, a5 + k * b5)
}

/// `a + b` of two spatial vectors, written out.
#[inline(always)]
fn add6<T: RealField + Copy>(a: &Vector6<T>, b: &Vector6<T>) -> Vector6<T> {
    let [a0, a1, a2, a3, a4, a5] = a.data.0[0];
    let [b0, b1, b2, b3, b4, b5] = b.data.0[0];
    Vector6::new(a0 + b0, a1 + b1, a2 + b2, a3 + b3, a4 + b4, a5 + b5)
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
