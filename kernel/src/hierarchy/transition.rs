//! Dynamic hierarchies: a task changing its priority level online, continuously.

use nalgebra::RealField;

use super::{HierarchyError, Stack};
use crate::math::switching::transition_activation;
use crate::tasks::{TaskRow, TaskRows};

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
    let sigma = T::one() - transition_activation(progress, T::zero(), T::one());
    let sides = [(from, T::one() - sigma), (to, sigma)];
    let needed = sides.iter().filter(|(_, w)| *w > T::zero()).count() * rows.len();
    if stack.rows().len() + needed > R {
        return Err(HierarchyError::Capacity { capacity: R });
    }
    for (level, weight) in sides.into_iter().filter(|(_, w)| *w > T::zero()) {
        for row in rows.rows() {
            let scaled = TaskRow { force: row.force * weight, activation: row.activation * weight, ..*row };
            stack.push(level, scaled)?;
        }
    }
    Ok(())
}
