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
        self.push_finite(level, row)
    }

    /// Appends one row known to be finite.
    fn push_finite(&mut self, level: usize, row: TaskRow<T, N>) -> Result<(), HierarchyError> {
        self.rows
            .push(StackRow { level, row, metric_norm_squared: None })
            .map_err(|_| HierarchyError::Capacity { capacity: R })?;
        self.level_count = self.level_count.max(level.saturating_add(1));
        Ok(())
    }

    /// Appends all rows of a task on `level`, with the `j W⁻¹ jᵀ` they carry; all or nothing.
    pub fn push_rows<const Q: usize>(&mut self, level: usize, rows: &TaskRows<T, N, Q>) -> Result<(), HierarchyError> {
        self.push_task(level, rows, None)
    }

    /// Appends all rows of a task on `level` (finite: the rows of a [`TaskRows`]) with force and
    /// activation scaled by `weight ∈ (0, 1]` (`None`: unscaled), each with the `j W⁻¹ jᵀ` it
    /// carries (the Jacobians are not scaled); all or nothing. One pass: the capacity is
    /// checked once, the level count set once.
    pub(super) fn push_task<const Q: usize>(
        &mut self,
        level: usize,
        rows: &TaskRows<T, N, Q>,
        weight: Option<T>,
    ) -> Result<(), HierarchyError> {
        if self.rows.len() + rows.len() > R {
            return Err(HierarchyError::Capacity { capacity: R });
        }
        for (row, &metric_norm_squared) in rows.rows().iter().zip(rows.metric_norm_squared()) {
            let row = match weight {
                // A finite row scaled by a weight in `(0, 1]` stays finite.
                Some(w) => TaskRow { force: row.force * w, activation: row.activation * w, ..*row },
                None => *row,
            };
            if self.rows.push(StackRow { level, row, metric_norm_squared }).is_err() {
                return Err(HierarchyError::Capacity { capacity: R });
            }
        }
        if !rows.is_empty() {
            self.level_count = self.level_count.max(level.saturating_add(1));
        }
        Ok(())
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
