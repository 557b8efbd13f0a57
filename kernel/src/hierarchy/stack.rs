//! The stack of task rows tagged with priority levels, and the windows through which tasks write
//! their rows into it.
//!
//! **One owner of the row storage, no copies.** The stack owns `R` row slots; the projection
//! reads the rows in those slots in place ([`Stack::rows`]). A task does not build its rows in
//! a list of its own to have them copied onto the stack: it appends them through a
//! [`TaskWindow`] ([`Stack::task`]), a [`RowSink`] over the free slots, so each row is written
//! once, by its task, where the projection reads it. Once the task is done, the window places
//! its rows ([`TaskWindow::place`], [`TaskWindow::place_scaled`],
//! [`TaskWindow::place_transitioning`]): it tags them with their level and applies the level
//! weight to force and activation in place. Only a task moving between two levels has its rows
//! on the stack twice (once per level, each with its weight), so only then are rows copied.
//! A row's slot is reused from cycle to cycle: a writer that writes the whole row
//! ([`RowSink::push_with_metric`]: the collision, Cartesian and manipulability rows) does not
//! clear the slot first; one that writes a few entries ([`RowSink::push_with`]: joint, end-stop
//! and torso workspace rows) gets it as a zero row.
//!
//! Lists built elsewhere ([`TaskRows`]) are still put on the stack with [`Stack::push_rows`],
//! [`super::push_scaled`] and [`super::push_transitioning`] (one copy per row), with the same
//! placement.

use nalgebra::{RealField, RowSVector};

use super::error::HierarchyError;
use crate::math::switching::transition_weight;
use crate::tasks::{fill_entries, RowEntries, RowSink, TaskError, TaskRow, TaskRows};

/// One task row on a priority level (0 = highest priority).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StackRow<T, const N: usize> {
    /// Priority level.
    pub level: usize,
    /// The row.
    pub row: TaskRow<T, N>,
    /// `j W⁻¹ jᵀ` with the step's inverse-inertia weighting ([`super::Weighting::InverseInertia`]),
    /// when the row's task computed it over the same inertia factor (the collision rows on the
    /// tree factor, [`TaskRows::metric_norm_squared`], [`RowSink::push_with_metric`]); the
    /// projection uses it with that weighting instead of forming the quadratic form. `None` for
    /// rows pushed one by one.
    pub metric_norm_squared: Option<T>,
    /// `(first, end)`: the Jacobian entries outside `first..end` are zero (rows appended with
    /// [`RowSink::push_with`] carry their columns; `(0, N)` for the others). The projection adds
    /// a last-level row's torque over these columns only.
    pub support: (usize, usize),
}

/// All rows of all tasks, capacity `R`, in insertion order. Levels need not be inserted in
/// order; [`super::project`] processes them from 0 upwards and, within a level, in insertion
/// order.
///
/// Every row on the stack has a finite Jacobian, force and activation (a row that does not is
/// refused by [`Self::push`] and by the [`TaskWindow`]s; the rows of a [`TaskRows`] are finite by
/// construction), so the projection does not test them again.
#[derive(Clone, Debug)]
pub struct Stack<T, const N: usize, const R: usize> {
    /// Row slots: the first `len` are the stack's rows, the others hold rows of earlier cycles
    /// (written over when a task appends into them).
    slots: [StackRow<T, N>; R],
    len: usize,
    /// Highest level + 1 (0 when empty).
    level_count: usize,
}

impl<T: PartialEq, const N: usize, const R: usize> PartialEq for Stack<T, N, R> {
    fn eq(&self, other: &Self) -> bool {
        self.slots.get(..self.len) == other.slots.get(..other.len) && self.level_count == other.level_count
    }
}

impl<T: RealField + Copy, const N: usize, const R: usize> Default for Stack<T, N, R> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: RealField + Copy, const N: usize, const R: usize> Stack<T, N, R> {
    /// An empty stack.
    pub fn new() -> Self {
        let zero =
            TaskRow { jacobian: RowSVector::zeros(), force: T::zero(), potential: T::zero(), activation: T::zero() };
        let slot = StackRow { level: 0, row: zero, metric_norm_squared: None, support: (0, N) };
        Self { slots: [slot; R], len: 0, level_count: 0 }
    }

    /// Removes every row.
    pub fn clear(&mut self) {
        self.len = 0;
        self.level_count = 0;
    }

    /// Appends one row on `level`. Errors (nothing appended): a full stack, a row with a
    /// non-finite Jacobian entry, force or activation.
    pub fn push(&mut self, level: usize, row: TaskRow<T, N>) -> Result<(), HierarchyError> {
        if !finite(&row) {
            return Err(HierarchyError::NonFinite);
        }
        let Some(slot) = self.slots.get_mut(self.len) else {
            return Err(HierarchyError::Capacity { capacity: R });
        };
        *slot = StackRow { level, row, metric_norm_squared: None, support: (0, N) };
        self.len += 1;
        self.level_count = self.level_count.max(level.saturating_add(1));
        Ok(())
    }

    /// Appends all rows of a task on `level`, with the `j W⁻¹ jᵀ` they carry; all or nothing.
    pub fn push_rows<const Q: usize>(&mut self, level: usize, rows: &TaskRows<T, N, Q>) -> Result<(), HierarchyError> {
        self.push_task(level, rows, None)
    }

    /// Appends all rows of a task on `level` (finite: the rows of a [`TaskRows`]) with force and
    /// activation scaled by `weight ∈ (0, 1]` (`None`: unscaled), each with the `j W⁻¹ jᵀ` it
    /// carries (the Jacobians are not scaled); all or nothing.
    pub(super) fn push_task<const Q: usize>(
        &mut self,
        level: usize,
        rows: &TaskRows<T, N, Q>,
        weight: Option<T>,
    ) -> Result<(), HierarchyError> {
        let window = self.copy_task(rows, rows.len())?;
        match weight {
            Some(w) => window.place_scaled(level, w),
            None => window.place(level),
        }
    }

    /// A window holding a copy of `rows` (the `j W⁻¹ jᵀ` they carry with them), if `needed`
    /// slots are free.
    pub(super) fn copy_task<const Q: usize>(
        &mut self,
        rows: &TaskRows<T, N, Q>,
        needed: usize,
    ) -> Result<TaskWindow<'_, T, N, R, Q>, HierarchyError> {
        if self.len.saturating_add(needed) > R {
            return Err(HierarchyError::Capacity { capacity: R });
        }
        let start = self.len;
        let free = self.slots.get_mut(start..).unwrap_or_default();
        let mut copied = 0;
        for ((slot, row), &metric_norm_squared) in free.iter_mut().zip(rows.rows()).zip(rows.metric_norm_squared()) {
            *slot = StackRow { level: 0, row: *row, metric_norm_squared, support: (0, N) };
            copied += 1;
        }
        self.len = start + copied;
        Ok(TaskWindow { stack: self, start, overflow: false, placed: false })
    }

    /// A window for the rows of one task (at most `Q`): the task appends them into the stack's
    /// free slots through the window ([`RowSink`]), then the window places them on their level
    /// ([`TaskWindow::place`] and its siblings). Rows appended but not placed are removed when
    /// the window is dropped.
    pub fn task<const Q: usize>(&mut self) -> TaskWindow<'_, T, N, R, Q> {
        let start = self.len;
        TaskWindow { stack: self, start, overflow: false, placed: false }
    }

    /// The rows in insertion order.
    pub fn rows(&self) -> &[StackRow<T, N>] {
        self.slots.get(..self.len).unwrap_or_default()
    }

    /// Number of levels in use (highest level + 1; 0 when empty).
    pub fn level_count(&self) -> usize {
        self.level_count
    }
}

/// The rows one task appends to a [`Stack`] (at most `Q`, and no more than the stack's free
/// slots), written in place into the stack's slots ([`RowSink`]); see the module docs. A window
/// ends by placing its rows on their level(s), all or nothing; dropped without that, it removes
/// them from the stack.
#[derive(Debug)]
pub struct TaskWindow<'a, T, const N: usize, const R: usize, const Q: usize> {
    stack: &'a mut Stack<T, N, R>,
    /// The stack's length when the window was opened: the task's rows are the slots from here.
    start: usize,
    /// An append failed because the stack (not the task's `Q`) was full.
    overflow: bool,
    placed: bool,
}

impl<T, const N: usize, const R: usize, const Q: usize> Drop for TaskWindow<'_, T, N, R, Q> {
    fn drop(&mut self) {
        if !self.placed {
            self.stack.len = self.start;
        }
    }
}

impl<T: RealField + Copy, const N: usize, const R: usize, const Q: usize> TaskWindow<'_, T, N, R, Q> {
    /// The task's rows appended so far (unplaced: level and weight not yet applied).
    pub fn rows(&self) -> &[StackRow<T, N>] {
        self.stack.slots.get(self.start..self.stack.len).unwrap_or_default()
    }

    /// The stack's capacity error if an append failed because the stack was full (the task
    /// then reports [`TaskError::Capacity`] with its own capacity `Q`).
    pub fn overflow(&self) -> Option<HierarchyError> {
        self.overflow.then_some(HierarchyError::Capacity { capacity: R })
    }

    /// Places the rows on `level` unscaled.
    pub fn place(mut self, level: usize) -> Result<(), HierarchyError> {
        self.place_rows(self.start, self.stack.len, level, None);
        self.placed = true;
        Ok(())
    }

    /// Places the rows on `level` with force and activation scaled by `weight ∈ [0, 1]` (a task
    /// fading in or out, (4.68)); the Jacobians and the carried `j W⁻¹ jᵀ` are not scaled. For
    /// `weight ≤ 0` the rows are removed; a non-finite weight removes them and is an error.
    pub fn place_scaled(mut self, level: usize, weight: T) -> Result<(), HierarchyError> {
        if !weight.is_finite() {
            return Err(HierarchyError::NonFinite);
        }
        if weight > T::zero() {
            self.place_rows(self.start, self.stack.len, level, Some(weight.min(T::one())));
            self.placed = true;
        }
        Ok(())
    }

    /// Places the rows of a task moving from level `from` to level `to` with progress
    /// `progress ∈ [0, 1]` (Sec. 4.4, dynamic hierarchies): on `from` scaled by `1 − σ` and on
    /// `to` by `σ`, `σ = transition_weight(progress)` (4.68), only the non-zero sides (the
    /// rows are copied once when both are). Errors (the rows removed): non-finite progress, no
    /// room for the copy.
    pub fn place_transitioning(mut self, from: usize, to: usize, progress: T) -> Result<(), HierarchyError> {
        if !progress.is_finite() {
            return Err(HierarchyError::NonFinite);
        }
        let sigma = transition_weight(progress);
        let (first, second) = (T::one() - sigma, sigma);
        match (first > T::zero(), second > T::zero()) {
            (true, true) => {}
            (true, false) => return self.place_scaled(from, first),
            (false, _) => return self.place_scaled(to, second),
        }
        let (start, end) = (self.start, self.stack.len);
        let count = end.saturating_sub(start);
        if end.saturating_add(count) > R {
            return Err(HierarchyError::Capacity { capacity: R });
        }
        let (head, tail) = self.stack.slots.split_at_mut(end);
        for (copy, row) in tail.iter_mut().zip(head.iter().skip(start)) {
            *copy = *row;
        }
        self.stack.len = end + count;
        self.place_rows(start, end, from, Some(first.min(T::one())));
        self.place_rows(end, end + count, to, Some(second.min(T::one())));
        self.placed = true;
        Ok(())
    }

    /// Removes the rows (a task that is in no level).
    pub fn discard(self) {}

    /// Tags slots `begin..end` with `level` and scales their force and activation by `weight`.
    fn place_rows(&mut self, begin: usize, end: usize, level: usize, weight: Option<T>) {
        let rows = self.stack.slots.get_mut(begin..end).unwrap_or_default();
        if rows.is_empty() {
            return;
        }
        for slot in rows.iter_mut() {
            slot.level = level;
            // A finite row scaled by a weight in `(0, 1]` stays finite.
            if let Some(w) = weight {
                slot.row.force *= w;
                slot.row.activation *= w;
            }
        }
        self.stack.level_count = self.stack.level_count.max(level.saturating_add(1));
    }

    /// The next free slot, if the task and the stack have room.
    fn slot(&mut self) -> Result<&mut StackRow<T, N>, TaskError> {
        if self.stack.len.saturating_sub(self.start) >= Q {
            return Err(TaskError::Capacity { capacity: Q });
        }
        match self.stack.slots.get_mut(self.stack.len) {
            Some(slot) => Ok(slot),
            None => {
                self.overflow = true;
                Err(TaskError::Capacity { capacity: Q })
            }
        }
    }
}

impl<T: RealField + Copy, const N: usize, const R: usize, const Q: usize> RowSink<T, N, Q>
    for TaskWindow<'_, T, N, R, Q>
{
    fn len(&self) -> usize {
        self.stack.len.saturating_sub(self.start)
    }

    #[inline]
    fn push(&mut self, row: TaskRow<T, N>) -> Result<(), TaskError> {
        if !row.is_finite() {
            return Err(TaskError::NonFinite);
        }
        let slot = self.slot()?;
        slot.row = row;
        slot.metric_norm_squared = None;
        slot.support = (0, N);
        self.stack.len += 1;
        Ok(())
    }

    #[inline]
    fn push_with(
        &mut self,
        columns: core::ops::Range<usize>,
        fill: impl FnOnce(&mut RowEntries<'_, T>),
    ) -> Result<(), TaskError> {
        let slot = self.slot()?;
        slot.row.jacobian.fill(T::zero());
        let support = fill_entries(&mut slot.row, columns, fill).ok_or(TaskError::NonFinite)?;
        slot.metric_norm_squared = None;
        slot.support = support;
        self.stack.len += 1;
        Ok(())
    }

    #[inline]
    fn push_with_metric(&mut self, fill: impl FnOnce(&mut TaskRow<T, N>) -> Option<T>) -> Result<(), TaskError> {
        let slot = self.slot()?;
        let metric = fill(&mut slot.row).filter(|m| m.is_finite());
        if !slot.row.is_finite() {
            return Err(TaskError::NonFinite);
        }
        slot.metric_norm_squared = metric;
        slot.support = (0, N);
        self.stack.len += 1;
        Ok(())
    }

    fn truncate(&mut self, len: usize) {
        self.stack.len = self.start + len.min(self.stack.len.saturating_sub(self.start));
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

#[cfg(test)]
#[path = "stack_tests.rs"]
mod tests;
