//! The stack of task rows tagged with priority levels.

use heapless::Vec;
use nalgebra::RealField;

use super::error::HierarchyError;
use crate::tasks::{TaskRow, TaskRows};

/// One task row on a priority level (0 = highest priority).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StackRow<T, const N: usize> {
    /// Priority level.
    pub level: usize,
    /// The row.
    pub row: TaskRow<T, N>,
    /// `j W⁻¹ jᵀ` with the step's inverse-inertia weighting ([`super::Weighting::InverseInertia`]),
    /// when the row's task computed it over the same inertia factor (the collision rows on the
    /// tree factor, [`TaskRows::metric_norm_squared`]); the projection uses it with that
    /// weighting instead of forming the quadratic form. `None` for rows pushed one by one.
    pub metric_norm_squared: Option<T>,
}

/// All rows of all tasks, capacity `R`, in insertion order. Levels need not be inserted in
/// order; [`super::project`] processes them from 0 upwards and, within a level, in insertion
/// order.
///
/// Every row on the stack has a finite Jacobian, force and activation (a row that does not is
/// refused by [`Self::push`]; the rows of a [`TaskRows`] are finite by construction), so the
/// projection does not test them again.
#[derive(Clone, Debug, PartialEq)]
pub struct Stack<T, const N: usize, const R: usize> {
    rows: Vec<StackRow<T, N>, R>,
    /// Highest level + 1 (0 when empty).
    level_count: usize,
}

impl<T: RealField + Copy, const N: usize, const R: usize> Default for Stack<T, N, R> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: RealField + Copy, const N: usize, const R: usize> Stack<T, N, R> {
    /// An empty stack.
    pub const fn new() -> Self {
        Self { rows: Vec::new(), level_count: 0 }
    }

    /// Removes every row.
    pub fn clear(&mut self) {
        self.rows.clear();
        self.level_count = 0;
    }

    /// Appends one row on `level`. Errors (nothing appended): a full stack, a row with a
    /// non-finite Jacobian entry, force or activation.
    pub fn push(&mut self, level: usize, row: TaskRow<T, N>) -> Result<(), HierarchyError> {
        if !finite(&row) {
            return Err(HierarchyError::NonFinite);
        }
        self.push_finite(level, row, None)
    }

    /// Appends one row known to be finite (a row of a [`TaskRows`], possibly with its force and
    /// activation scaled by a weight in `[0, 1]`) with its `j W⁻¹ jᵀ`, if known.
    pub(super) fn push_finite(
        &mut self,
        level: usize,
        row: TaskRow<T, N>,
        metric_norm_squared: Option<T>,
    ) -> Result<(), HierarchyError> {
        self.rows
            .push(StackRow { level, row, metric_norm_squared })
            .map_err(|_| HierarchyError::Capacity { capacity: R })?;
        self.level_count = self.level_count.max(level.saturating_add(1));
        Ok(())
    }

    /// Appends all rows of a task on `level`, with the `j W⁻¹ jᵀ` they carry; all or nothing.
    pub fn push_rows<const Q: usize>(&mut self, level: usize, rows: &TaskRows<T, N, Q>) -> Result<(), HierarchyError> {
        if self.rows.len() + rows.len() > R {
            return Err(HierarchyError::Capacity { capacity: R });
        }
        rows.rows()
            .iter()
            .zip(rows.metric_norm_squared())
            .try_for_each(|(row, &metric)| self.push_finite(level, *row, metric))
    }

    /// The rows in insertion order.
    pub fn rows(&self) -> &[StackRow<T, N>] {
        &self.rows
    }

    /// Number of levels in use (highest level + 1; 0 when empty).
    pub fn level_count(&self) -> usize {
        self.level_count
    }
}

/// `true` if the Jacobian, the force and the activation of `row` are finite. `x · 0` is `±0` for
/// a finite `x` and NaN otherwise, and NaN propagates through the sum: one multiply-add per
/// entry instead of a test and a branch.
fn finite<T: RealField + Copy, const N: usize>(row: &TaskRow<T, N>) -> bool {
    let zero = T::zero();
    let probe = row.jacobian.as_slice().iter().fold(row.force * zero + row.activation * zero, |sum, &x| sum + x * zero);
    probe == zero
}
