//! The hierarchy the controller runs: every task with the level it comes from and the level it
//! goes to, blended with the cubic (4.68) while it moves between levels, fades in or fades out
//! after a planner command.

use heapless::Vec;
use nalgebra::RealField;

use super::capacity::{MAX_ACTIVE, MAX_LEVELS, MAX_TASKS, MAX_TASK_ROWS};
use super::config::{TaskKind, TaskSpec};
use super::error::CommandError;
use crate::hierarchy::{transition_weight, HierarchyError, TaskWindow};

/// A hierarchy entry, possibly moving: on `from` with weight `1 − σ` and on `to` with `σ`,
/// `σ = transition_weight(progress)` (4.68); `None` is "not in the hierarchy".
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ActiveTask<T> {
    pub(super) kind: TaskKind,
    pub(super) from: Option<u8>,
    pub(super) to: Option<u8>,
    pub(super) progress: T,
}

impl<T: RealField + Copy> ActiveTask<T> {
    /// Places the task's rows, appended to the stack through `rows`: on its level with weight
    /// one when at rest, with the transition weight (4.68) on the levels it moves between, fades
    /// in or out of.
    pub(super) fn place<const N: usize, const R: usize>(
        &self,
        rows: TaskWindow<'_, T, N, R, MAX_TASK_ROWS>,
    ) -> Result<(), HierarchyError> {
        let sigma = transition_weight(self.progress);
        match (self.from, self.to) {
            (Some(from), Some(to)) if from != to => rows.place_transitioning(from.into(), to.into(), self.progress),
            (_, Some(to)) if self.from.is_none() => rows.place_scaled(to.into(), sigma),
            (Some(from), None) => rows.place_scaled(from.into(), T::one() - sigma),
            (_, Some(to)) => rows.place(to.into()),
            (None, None) => {
                rows.discard();
                Ok(())
            }
        }
    }
}

/// The entries of the running hierarchy: the planner's tasks plus those fading out.
#[derive(Clone, Debug)]
pub(super) struct ActiveHierarchy<T> {
    entries: Vec<ActiveTask<T>, MAX_ACTIVE>,
}

/// Checks a hierarchy: levels below `MAX_LEVELS`, no task twice.
fn validate_hierarchy(tasks: &[TaskSpec]) -> Result<(), CommandError> {
    for (i, spec) in tasks.iter().enumerate() {
        if usize::from(spec.level) >= MAX_LEVELS {
            return Err(CommandError::LevelOverflow { level: spec.level });
        }
        if tasks.iter().skip(i + 1).any(|other| other.kind == spec.kind) {
            return Err(CommandError::DuplicateTask);
        }
    }
    Ok(())
}

impl<T: RealField + Copy> ActiveHierarchy<T> {
    /// The entries of a validated initial hierarchy (no transitions).
    pub(super) fn initial(tasks: &[TaskSpec]) -> Result<Self, CommandError> {
        if tasks.len() > MAX_TASKS {
            return Err(CommandError::OutOfRange { field: "hierarchy length" });
        }
        validate_hierarchy(tasks)?;
        let mut entries = Vec::new();
        for spec in tasks {
            entries
                .push(ActiveTask { kind: spec.kind, from: Some(spec.level), to: Some(spec.level), progress: T::one() })
                .map_err(|_| CommandError::OutOfRange { field: "hierarchy length" })?;
        }
        Ok(Self { entries })
    }

    /// The entries in hierarchy order.
    pub(super) fn entries(&self) -> &[ActiveTask<T>] {
        &self.entries
    }

    /// The hierarchy as the planner last set it: `(task, level)` of every entry that is not
    /// fading out.
    pub(super) fn planned(&self) -> impl Iterator<Item = TaskSpec> + '_ {
        self.entries.iter().filter_map(|a| a.to.map(|level| TaskSpec { kind: a.kind, level }))
    }

    /// `true` while a task moves between levels or fades.
    pub(super) fn in_transition(&self) -> bool {
        self.entries.iter().any(|a| a.from != a.to)
    }

    /// `true` if `kind` is an entry (also while it fades in or out).
    pub(super) fn contains(&self, kind: TaskKind) -> bool {
        self.entries.iter().any(|a| a.kind == kind)
    }

    /// Advances every transition by `step` (the period over the transition time); a finished
    /// task rests on its new level, a faded-out one leaves the hierarchy.
    pub(super) fn advance(&mut self, step: T) {
        for task in self.entries.iter_mut().filter(|t| t.from != t.to) {
            task.progress = (task.progress + step).min(T::one());
            if task.progress >= T::one() {
                task.from = task.to;
            }
        }
        self.entries.retain(|t| t.to.is_some());
    }

    /// Replaces the hierarchy by `tasks`: a task on the same level stays, one on another level
    /// moves, a new one fades in, a dropped one fades out. Refused, with nothing changed, for an
    /// invalid hierarchy, while a transition is running, or if a task is not `available`.
    pub(super) fn replace(
        &mut self,
        tasks: &[TaskSpec],
        available: impl Fn(TaskKind) -> bool,
    ) -> Result<(), CommandError> {
        validate_hierarchy(tasks)?;
        if self.in_transition() {
            return Err(CommandError::TransitionInProgress);
        }
        if !tasks.iter().all(|t| available(t.kind)) {
            return Err(CommandError::UnknownTask);
        }
        let mut next: Vec<ActiveTask<T>, MAX_ACTIVE> = Vec::new();
        for spec in tasks {
            let current = self.entries.iter().find(|a| a.kind == spec.kind).and_then(|a| a.to);
            let (from, progress) = match current {
                Some(level) if level == spec.level => (Some(level), T::one()),
                other => (other, T::zero()),
            };
            next.push(ActiveTask { kind: spec.kind, from, to: Some(spec.level), progress })
                .map_err(|_| CommandError::OutOfRange { field: "hierarchy length" })?;
        }
        for old in self.entries.iter().filter(|a| !tasks.iter().any(|t| t.kind == a.kind)) {
            next.push(ActiveTask { kind: old.kind, from: old.to, to: None, progress: T::zero() })
                .map_err(|_| CommandError::OutOfRange { field: "hierarchy length" })?;
        }
        self.entries = next;
        Ok(())
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, reason = "test code: failures should panic")]
mod tests {
    use super::*;
    use crate::controller::config::Field;
    use crate::controller::layout::{ArmId, JointGroup};

    const CARTESIAN: TaskKind = TaskKind::CartesianImpedance(ArmId::RIGHT);
    const COLLISION: TaskKind = TaskKind::CollisionAvoidance(Field::Strong);
    const DAMPING: TaskKind = TaskKind::JointDamping(JointGroup::UpperBody);

    fn spec(kind: TaskKind, level: u8) -> TaskSpec {
        TaskSpec { kind, level }
    }

    fn levels(h: &ActiveHierarchy<f64>) -> std::vec::Vec<(TaskKind, Option<u8>, Option<u8>)> {
        h.entries().iter().map(|a| (a.kind, a.from, a.to)).collect()
    }

    #[test]
    fn a_new_hierarchy_moves_fades_in_and_out_then_rests() {
        let mut h = ActiveHierarchy::<f64>::initial(&[spec(CARTESIAN, 0), spec(DAMPING, 1)]).unwrap();
        assert!(!h.in_transition());
        h.replace(&[spec(CARTESIAN, 0), spec(COLLISION, 0), spec(DAMPING, 2)], |_| true).unwrap();
        assert_eq!(
            levels(&h),
            [(CARTESIAN, Some(0), Some(0)), (COLLISION, None, Some(0)), (DAMPING, Some(1), Some(2))]
        );
        assert!(h.in_transition());
        assert_eq!(h.replace(&[spec(CARTESIAN, 0)], |_| true), Err(CommandError::TransitionInProgress));
        h.advance(0.5);
        assert!(h.in_transition());
        h.advance(0.5);
        assert!(!h.in_transition());
        assert_eq!(
            h.planned().collect::<std::vec::Vec<_>>(),
            [spec(CARTESIAN, 0), spec(COLLISION, 0), spec(DAMPING, 2)]
        );
        // A dropped task fades out: still an entry, no longer planned, gone once faded.
        h.replace(&[spec(CARTESIAN, 0), spec(DAMPING, 2)], |_| true).unwrap();
        assert!(h.contains(COLLISION));
        assert!(!h.planned().any(|s| s.kind == COLLISION));
        h.advance(1.0);
        assert!(!h.contains(COLLISION));
        assert_eq!(levels(&h), [(CARTESIAN, Some(0), Some(0)), (DAMPING, Some(2), Some(2))]);
    }

    #[test]
    fn invalid_hierarchies_are_refused_and_change_nothing() {
        let mut h = ActiveHierarchy::<f64>::initial(&[spec(CARTESIAN, 0)]).unwrap();
        let before = levels(&h);
        let overflow = u8::try_from(MAX_LEVELS).unwrap();
        assert_eq!(
            h.replace(&[spec(CARTESIAN, overflow)], |_| true),
            Err(CommandError::LevelOverflow { level: overflow })
        );
        assert_eq!(h.replace(&[spec(DAMPING, 0), spec(DAMPING, 1)], |_| true), Err(CommandError::DuplicateTask));
        assert_eq!(h.replace(&[spec(DAMPING, 0)], |kind| kind != DAMPING), Err(CommandError::UnknownTask));
        assert_eq!(levels(&h), before);
        let too_many = [spec(CARTESIAN, 0); MAX_TASKS + 1];
        assert_eq!(
            ActiveHierarchy::<f64>::initial(&too_many).err(),
            Some(CommandError::OutOfRange { field: "hierarchy length" })
        );
    }
}
