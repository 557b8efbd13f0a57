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
}

/// All rows of all tasks, capacity `R`, in insertion order. Levels need not be inserted in
/// order; [`super::project`] processes them from 0 upwards and, within a level, in insertion
/// order.
#[derive(Clone, Debug, PartialEq)]
pub struct Stack<T, const N: usize, const R: usize> {
    rows: Vec<StackRow<T, N>, R>,
}

impl<T: RealField + Copy, const N: usize, const R: usize> Default for Stack<T, N, R> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: RealField + Copy, const N: usize, const R: usize> Stack<T, N, R> {
    /// An empty stack.
    pub const fn new() -> Self {
        Self { rows: Vec::new() }
    }

    /// Removes every row.
    pub fn clear(&mut self) {
        self.rows.clear();
    }

    /// Appends one row on `level`.
    pub fn push(&mut self, level: usize, row: TaskRow<T, N>) -> Result<(), HierarchyError> {
        self.rows.push(StackRow { level, row }).map_err(|_| HierarchyError::Capacity { capacity: R })
    }

    /// Appends all rows of a task on `level`; all or nothing.
    pub fn push_rows<const Q: usize>(&mut self, level: usize, rows: &TaskRows<T, N, Q>) -> Result<(), HierarchyError> {
        if self.rows.len() + rows.len() > R {
            return Err(HierarchyError::Capacity { capacity: R });
        }
        rows.rows().iter().try_for_each(|row| self.push(level, *row))
    }

    /// The rows in insertion order.
    pub fn rows(&self) -> &[StackRow<T, N>] {
        &self.rows
    }

    /// Number of levels in use (highest level + 1; 0 when empty).
    pub fn level_count(&self) -> usize {
        self.rows.iter().map(|r| r.level + 1).max().unwrap_or(0)
    }
}
