//! Dynamic hierarchies: a task changing its priority level online, continuously.

use nalgebra::RealField;

use super::error::HierarchyError;
use super::stack::Stack;
use crate::math::switching::transition_weight;
use crate::tasks::TaskRows;

/// Puts a task's rows on the stack while the task moves from level `from` to level `to`
/// (Sec. 4.4, dynamic hierarchies). `progress ∈ [0, 1]` is the transition's progress (e.g.
/// elapsed time over its duration); it is shaped with the cubic (4.68), `σ = 1 − a(progress)`,
/// so the weight has zero slope at both ends. The rows appear on `from` with force and
/// activation scaled by `1 − σ` and on `to` scaled by `σ`: the task's torque and its locking
/// of lower levels change continuously, and at `progress = 0` (`1`) the task is exactly on
/// `from` (`to`). Only the non-zero side is pushed at the ends. All or nothing.
pub fn push_transitioning<T: RealField + Copy, const N: usize, const R: usize, const Q: usize>(
    stack: &mut Stack<T, N, R>,
    rows: &TaskRows<T, N, Q>,
    from: usize,
    to: usize,
    progress: T,
) -> Result<(), HierarchyError> {
    if !progress.is_finite() {
        return Err(HierarchyError::NonFinite);
    }
    let sigma = transition_weight(progress);
    let sides = [T::one() - sigma, sigma].iter().filter(|w| **w > T::zero()).count();
    stack.copy_task(rows, sides * rows.len())?.place_transitioning(from, to, progress)
}

/// Puts a task's rows on `level` with force and activation scaled by `weight ∈ [0, 1]` (a task
/// fading in or out of the hierarchy: `weight = transition_weight(progress)` or its
/// complement). Nothing is pushed for `weight ≤ 0`. All or nothing.
pub fn push_scaled<T: RealField + Copy, const N: usize, const R: usize, const Q: usize>(
    stack: &mut Stack<T, N, R>,
    rows: &TaskRows<T, N, Q>,
    level: usize,
    weight: T,
) -> Result<(), HierarchyError> {
    if !weight.is_finite() {
        return Err(HierarchyError::NonFinite);
    }
    if weight <= T::zero() {
        return Ok(());
    }
    stack.push_task(level, rows, Some(weight))
}
