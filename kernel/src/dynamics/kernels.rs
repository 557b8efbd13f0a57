//! What the tree walks share: drive-row accumulation into coordinate matrices, the per-call
//! single-coordinate drive table, 6-vector arithmetic and input checks.

use nalgebra::{RealField, SVector, Vector6};

use super::error::DynamicsError;
use crate::model::{DriveTerm, JointDrive};

/// `m += value · g_rowᵀ g_col`: adds a tree-level entry to a coordinate-level N×N matrix,
/// given as its column-major storage `m`, through the drive rows of two joints.
#[inline(always)]
pub(super) fn add_coupled<T: RealField + Copy, const N: usize>(
    m: &mut [T],
    row: &[DriveTerm<T>],
    col: &[DriveTerm<T>],
    value: T,
) {
    if let ([r], [c]) = (row, col) {
        // One term each (every ordinary joint): a single entry.
        if let Some(entry) = m.get_mut(c.coordinate * N + r.coordinate) {
            *entry += r.coefficient * c.coefficient * value;
        }
        return;
    }
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

/// One body as the ancestor walks of [`crba`] and [`coriolis_matrix`] see it: its parent
/// (`B` for none, so that a walk ends at the first index out of range; a parent index that is
/// not smaller than the body's own ends the walk too) and, for a joint driven by one
/// coordinate, that coordinate and its coefficient (`coordinate = N` and coefficient one for a
/// joint coupled to several coordinates, whose entries go through its drive row).
#[derive(Clone, Copy)]
pub(super) struct WalkDrive<T> {
    pub(super) parent: usize,
    pub(super) coordinate: usize,
    pub(super) coefficient: T,
}

/// The [`WalkDrive`] of every body, built once per algorithm call.
#[inline(always)]
pub(super) fn walk_drives<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &crate::model::Model<T, N, B, F>,
) -> [WalkDrive<T>; B] {
    let mut out = [WalkDrive { parent: B, coordinate: N, coefficient: T::one() }; B];
    for (i, (slot, body)) in out.iter_mut().zip(model.bodies()).enumerate() {
        slot.parent = body.parent.map(|p| p.0).filter(|p| *p < i).unwrap_or(B);
        if let [term] = body.drive.terms() {
            if term.coordinate < N {
                slot.coordinate = term.coordinate;
                slot.coefficient = term.coefficient;
            }
        }
    }
    out
}

/// `m[c][r] += value` on column arrays (entry `(r, c)` of a column-major matrix).
#[inline(always)]
pub(super) fn add_entry<T: RealField + Copy, const N: usize>(m: &mut [[T; N]; N], r: usize, c: usize, value: T) {
    if let Some(x) = m.get_mut(c).and_then(|column| column.get_mut(r)) {
        *x += value;
    }
}

/// `k a`, written out.
#[inline(always)]
pub(super) fn scale6<T: RealField + Copy>(a: &Vector6<T>, k: T) -> Vector6<T> {
    let [a0, a1, a2, a3, a4, a5] = a.data.0[0];
    Vector6::new(k * a0, k * a1, k * a2, k * a3, k * a4, k * a5)
}

/// `out += value · g`: adds a tree-level generalized force to the coordinate vector.
#[inline]
pub(super) fn add_to_coordinates<T: RealField + Copy, const N: usize>(
    out: &mut SVector<T, N>,
    drive: &JointDrive<T>,
    value: T,
) {
    for t in drive.terms() {
        if let Some(entry) = out.get_mut(t.coordinate) {
            *entry += t.coefficient * value;
        }
    }
}

/// `a · b` of two spatial vectors, written out.
#[inline(always)]
pub(super) fn dot6<T: RealField + Copy>(a: &Vector6<T>, b: &Vector6<T>) -> T {
    let [a0, a1, a2, a3, a4, a5] = a.data.0[0];
    let [b0, b1, b2, b3, b4, b5] = b.data.0[0];
    a0 * b0 + a1 * b1 + a2 * b2 + a3 * b3 + a4 * b4 + a5 * b5
}

/// `a + k b` of two spatial vectors, written out.
#[inline(always)]
pub(super) fn add_scaled6<T: RealField + Copy>(a: &Vector6<T>, b: &Vector6<T>, k: T) -> Vector6<T> {
    let [a0, a1, a2, a3, a4, a5] = a.data.0[0];
    let [b0, b1, b2, b3, b4, b5] = b.data.0[0];
    Vector6::new(a0 + k * b0, a1 + k * b1, a2 + k * b2, a3 + k * b3, a4 + k * b4, a5 + k * b5)
}

/// `a + b` of two spatial vectors, written out.
#[inline(always)]
pub(super) fn add6<T: RealField + Copy>(a: &Vector6<T>, b: &Vector6<T>) -> Vector6<T> {
    let [a0, a1, a2, a3, a4, a5] = a.data.0[0];
    let [b0, b1, b2, b3, b4, b5] = b.data.0[0];
    Vector6::new(a0 + b0, a1 + b1, a2 + b2, a3 + b3, a4 + b4, a5 + b5)
}

/// Checks that every entry of a state vector is finite.
#[inline]
pub(super) fn check_finite<T: RealField + Copy, const R: usize>(
    v: &SVector<T, R>,
    input: &'static str,
) -> Result<(), DynamicsError> {
    if crate::math::all_finite(v) {
        Ok(())
    } else {
        Err(DynamicsError::NonFinite { input })
    }
}
