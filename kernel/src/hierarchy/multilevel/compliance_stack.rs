//! The input of the multi-level controller: compliance rows on priority levels.

use heapless::Vec;
use nalgebra::{RealField, RowSVector};

use super::error::MultilevelError;
use crate::tasks::TaskRow;

/// One task row of a compliance level, with what the multi-level controller needs beyond a
/// [`TaskRow`]: the row's time derivative (for `Ż`) and its force split into the spring and
/// the damper part (for the storage rate (5.65) and the sets (5.63)).
///
/// Sign convention of [`crate::tasks`]: the forces act along the row, `f = −∂V/∂x − d ẋ`
/// with `ẋ = j q̇`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ComplianceRow<T, const N: usize> {
    /// Jacobian row `j` (1×N).
    pub jacobian: RowSVector<T, N>,
    /// Its time derivative `j̇ = Σ_k (∂j/∂q_k) q̇_k` (1×N), e.g. from
    /// [`crate::dynamics::frame_jacobian_derivative`] with direction `q̇`; zero for joint rows.
    pub jacobian_rate: RowSVector<T, N>,
    /// Spring part `−∂V/∂x` of the row force (N or Nm).
    pub stiffness_force: T,
    /// Damper part `−(D ẋ)` of the row force (N or Nm).
    pub damping_force: T,
    /// The row's share of the level's potential `V_i` (J).
    pub potential: T,
}

impl<T: RealField + Copy, const N: usize> ComplianceRow<T, N> {
    /// A row from a task row, its rate and the spring part of its force; the damper part is
    /// the rest, `f − stiffness_force`.
    pub fn from_task_row(row: &TaskRow<T, N>, jacobian_rate: RowSVector<T, N>, stiffness_force: T) -> Self {
        Self {
            jacobian: row.jacobian,
            jacobian_rate,
            stiffness_force,
            damping_force: row.force - stiffness_force,
            potential: row.potential,
        }
    }

    /// Total row force `f = stiffness_force + damping_force`.
    pub fn force(&self) -> T {
        self.stiffness_force + self.damping_force
    }

    pub(super) fn is_finite(&self) -> bool {
        self.stiffness_force.is_finite()
            && self.damping_force.is_finite()
            && self.potential.is_finite()
            && crate::math::all_finite(&self.jacobian)
            && crate::math::all_finite(&self.jacobian_rate)
    }
}

/// The compliance rows of all levels (capacity `R`), each tagged with its priority level
/// (0 = highest). Within a level, rows are used in insertion order.
#[derive(Clone, Debug, PartialEq)]
pub struct ComplianceStack<T, const N: usize, const R: usize> {
    rows: Vec<(usize, ComplianceRow<T, N>), R>,
}

impl<T: RealField + Copy, const N: usize, const R: usize> Default for ComplianceStack<T, N, R> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: RealField + Copy, const N: usize, const R: usize> ComplianceStack<T, N, R> {
    /// An empty stack.
    pub const fn new() -> Self {
        Self { rows: Vec::new() }
    }

    /// Removes every row.
    pub fn clear(&mut self) {
        self.rows.clear();
    }

    /// Appends one row on `level`. Errors: the stack is full.
    pub fn push(&mut self, level: usize, row: ComplianceRow<T, N>) -> Result<(), MultilevelError> {
        self.rows.push((level, row)).map_err(|_| MultilevelError::Capacity { capacity: R })
    }

    /// The rows `(level, row)` in insertion order.
    pub fn rows(&self) -> &[(usize, ComplianceRow<T, N>)] {
        &self.rows
    }

    /// The rows of one level, in insertion order.
    pub fn level(&self, level: usize) -> impl Iterator<Item = &ComplianceRow<T, N>> + '_ {
        self.rows.iter().filter(move |(l, _)| *l == level).map(|(_, row)| row)
    }

    /// Number of levels in use (highest level + 1; 0 when empty).
    pub fn level_count(&self) -> usize {
        self.rows.iter().map(|(level, _)| level + 1).max().unwrap_or(0)
    }
}
