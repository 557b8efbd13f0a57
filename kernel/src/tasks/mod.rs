//! Control tasks of Chapter 3 as one-dimensional task rows.
//!
//! Every task — a Cartesian impedance, a joint impedance, an end stop, a self-collision pair —
//! produces **rows** (DESIGN.md, "Tasks emit one-dimensional rows"): a Jacobian row `j` (1×N),
//! a scalar task force `f` (from the gradient of the task's potential plus damping), the
//! row's share of the potential energy, and an activation `a ∈ [0, 1]`. An m-dimensional task
//! is m rows; the hierarchy (Ch. 4) puts rows on priority levels and projects them. Used alone,
//! a task's rows give the torque `τ = Σ jᵀ f = −(∂V/∂q)ᵀ − D q̇` ([`TaskRows::torque`]).
//!
//! Sign convention: `f` is the generalized force the task applies along its row direction,
//! `f = −∂V/∂x − d ẋ` with `ẋ = j q̇`.

use core::fmt;

use heapless::Vec;
use nalgebra::{RealField, RowSVector, SVector};

use crate::dynamics::DynamicsError;

/// One row of a task (one task-space direction).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TaskRow<T, const N: usize> {
    /// Jacobian row `j` (1×N): the task velocity along this row is `ẋ = j q̇`.
    pub jacobian: RowSVector<T, N>,
    /// Task force `f` along the row (N or Nm); its joint torque is `jᵀ f`.
    pub force: T,
    /// This row's share of the task's potential energy (J); a task's rows sum to its `V`.
    pub potential: T,
    /// Activation `a ∈ [0, 1]`: 1 for bilateral tasks; unilateral constraints and algorithmic
    /// singularities fade in and out (Sec. 4.4).
    pub activation: T,
}

impl<T: RealField + Copy, const N: usize> TaskRow<T, N> {
    /// `true` if the Jacobian, the force, the potential and the activation are all finite.
    ///
    /// One multiply-add per entry over the Jacobian's contiguous storage instead of a test and a
    /// branch: `x · 0` is `±0` for a finite `x` and NaN otherwise, and NaN propagates through
    /// the sum.
    #[inline]
    pub fn is_finite(&self) -> bool {
        let zero = T::zero();
        let start = self.force * zero + self.potential * zero + self.activation * zero;
        self.jacobian.as_slice().iter().fold(start, |sum, &x| sum + x * zero) == zero
    }
}

/// The entries of a row that [`RowSink::push_with`] lets its writer set, all zero on entry: the
/// Jacobian entries of the row's columns (`jacobian[i]` is the row's entry in column
/// `first + i`; the entries outside the columns stay zero), the force, the potential and the
/// activation.
#[derive(Debug)]
pub struct RowEntries<'a, T> {
    /// The Jacobian entries of the row's columns.
    pub jacobian: &'a mut [T],
    /// Task force `f` ([`TaskRow::force`]).
    pub force: T,
    /// The row's potential ([`TaskRow::potential`]).
    pub potential: T,
    /// Activation ([`TaskRow::activation`]).
    pub activation: T,
}

/// Lets `fill` write the entries `columns` (clamped to `0..N`) of `row`, whose Jacobian holds
/// zeros, and its force, potential and activation ([`RowEntries`]); returns the columns
/// `(first, end)` outside which the Jacobian is zero if the row is finite (checked on those
/// columns only, as [`TaskRow::is_finite`] does on all), `None` otherwise.
#[inline]
pub(crate) fn fill_entries<T: RealField + Copy, const N: usize>(
    row: &mut TaskRow<T, N>,
    columns: core::ops::Range<usize>,
    fill: impl FnOnce(&mut RowEntries<'_, T>),
) -> Option<(usize, usize)> {
    let zero = T::zero();
    let first = columns.start.min(N);
    let end = columns.end.clamp(first, N);
    let jacobian = row.jacobian.as_mut_slice().get_mut(first..end).unwrap_or_default();
    let mut entries = RowEntries { jacobian, force: zero, potential: zero, activation: zero };
    fill(&mut entries);
    let RowEntries { jacobian, force, potential, activation } = entries;
    let start = force * zero + potential * zero + activation * zero;
    let finite = jacobian.iter().fold(start, |sum, &x| sum + x * zero) == zero;
    (row.force, row.potential, row.activation) = (force, potential, activation);
    finite.then_some((first, end))
}

/// Where a task appends its rows, at most `R` of them: an owned [`TaskRows`] list, or the
/// task's window of the hierarchy stack ([`crate::hierarchy::TaskWindow`]), whose slots are the
/// rows the projection reads (each row is written once, where it is used). [`Self::len`] and
/// [`Self::truncate`] count the rows appended to this sink only. Every appended row is finite.
pub trait RowSink<T: RealField + Copy, const N: usize, const R: usize> {
    /// Number of rows appended.
    fn len(&self) -> usize;

    /// `true` if no row was appended.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Appends a row; rejects non-finite rows and a full sink (the sink is unchanged then).
    fn push(&mut self, row: TaskRow<T, N>) -> Result<(), TaskError>;

    /// Appends a row built in place whose Jacobian is zero outside `columns` (clamped to
    /// `0..N`): `fill` receives the entries it may write ([`RowEntries`]: the Jacobian entries
    /// of `columns`, force, potential and activation), all zero, and writes what it needs; only
    /// those entries are checked finite, and a stack window keeps the columns with the row
    /// ([`crate::hierarchy::StackRow::support`]). Rejects a full sink and a non-finite result
    /// (the sink is unchanged then).
    fn push_with(
        &mut self,
        columns: core::ops::Range<usize>,
        fill: impl FnOnce(&mut RowEntries<'_, T>),
    ) -> Result<(), TaskError>;

    /// Appends a row that `fill` writes completely in place — every Jacobian entry, the force,
    /// the potential and the activation: the slot it receives holds an unspecified row (a zero
    /// row in a [`TaskRows`], the slot's previous row in a stack window), so no zero row is
    /// written first. `fill` returns the row's `j M⁻¹ jᵀ` over the inertia factor its task used
    /// (the metric of the row's norm ratio with the inverse-inertia weighting, the squared norm
    /// `σ₁²` of (4.70)), kept with the row when finite. Rejects a full sink and a non-finite
    /// row (the sink is unchanged then).
    fn push_with_metric(&mut self, fill: impl FnOnce(&mut TaskRow<T, N>) -> Option<T>) -> Result<(), TaskError>;

    /// Keeps the first `len` rows appended (all if there are fewer).
    fn truncate(&mut self, len: usize);
}

impl<T: RealField + Copy, const N: usize, const R: usize> RowSink<T, N, R> for TaskRows<T, N, R> {
    fn len(&self) -> usize {
        TaskRows::len(self)
    }

    #[inline]
    fn push(&mut self, row: TaskRow<T, N>) -> Result<(), TaskError> {
        TaskRows::push(self, row)
    }

    #[inline]
    fn push_with(
        &mut self,
        columns: core::ops::Range<usize>,
        fill: impl FnOnce(&mut RowEntries<'_, T>),
    ) -> Result<(), TaskError> {
        TaskRows::push_with(self, columns, fill)
    }

    #[inline]
    fn push_with_metric(&mut self, fill: impl FnOnce(&mut TaskRow<T, N>) -> Option<T>) -> Result<(), TaskError> {
        TaskRows::push_with_metric(self, fill)
    }

    fn truncate(&mut self, len: usize) {
        TaskRows::truncate(self, len);
    }
}

/// A fixed-capacity list of task rows (capacity `R`).
///
/// A row may carry its `j M⁻¹ jᵀ` over the inertia factor its task used (the collision rows on
/// the tree factor: [`Self::metric_norm_squared`]), which the projection takes instead of forming it
/// with the inverse-inertia weighting. Two lists are equal when their rows are (the carried
/// values follow from the rows).
#[derive(Clone, Debug)]
pub struct TaskRows<T, const N: usize, const R: usize> {
    rows: Vec<TaskRow<T, N>, R>,
    /// Per row: its `j M⁻¹ jᵀ`, when its task provided it.
    metrics: Vec<Option<T>, R>,
}

impl<T: PartialEq, const N: usize, const R: usize> PartialEq for TaskRows<T, N, R> {
    fn eq(&self, other: &Self) -> bool {
        self.rows == other.rows
    }
}

impl<T: RealField + Copy, const N: usize, const R: usize> Default for TaskRows<T, N, R> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: RealField + Copy, const N: usize, const R: usize> TaskRows<T, N, R> {
    /// An empty list.
    pub const fn new() -> Self {
        Self { rows: Vec::new(), metrics: Vec::new() }
    }

    /// Removes every row.
    pub fn clear(&mut self) {
        self.rows.clear();
        self.metrics.clear();
    }

    /// Appends a row; rejects non-finite rows and a full list (the list is unchanged then).
    ///
    /// The finiteness check is [`TaskRow::is_finite`]; inlined, so that a row built at the call
    /// site is written into the list without an extra copy.
    #[inline]
    pub fn push(&mut self, row: TaskRow<T, N>) -> Result<(), TaskError> {
        if !row.is_finite() {
            return Err(TaskError::NonFinite);
        }
        self.rows.push(row).map_err(|_| TaskError::Capacity { capacity: R })?;
        self.metrics.push(None).map_err(|_| TaskError::Capacity { capacity: R })
    }

    /// Appends a row built in place, zero outside `columns` ([`RowSink::push_with`]): `fill`
    /// writes its [`RowEntries`] into the new slot, so the row is not built elsewhere and copied
    /// in. Rejects a full list and a non-finite result (the list is unchanged then).
    #[inline]
    pub fn push_with(
        &mut self,
        columns: core::ops::Range<usize>,
        fill: impl FnOnce(&mut RowEntries<'_, T>),
    ) -> Result<(), TaskError> {
        let zero =
            TaskRow { jacobian: RowSVector::zeros(), force: T::zero(), potential: T::zero(), activation: T::zero() };
        self.rows.push(zero).map_err(|_| TaskError::Capacity { capacity: R })?;
        let Some(row) = self.rows.last_mut() else {
            return Err(TaskError::Capacity { capacity: R });
        };
        if fill_entries(row, columns, fill).is_some() && self.metrics.push(None).is_ok() {
            Ok(())
        } else {
            self.rows.pop();
            Err(TaskError::NonFinite)
        }
    }

    /// [`Self::push_with`] for a task that also knows the row's `j M⁻¹ jᵀ` over the inertia
    /// factor it used (the metric of the row's norm ratio with the inverse-inertia weighting,
    /// the squared norm `σ₁²` of (4.70)): `fill` returns it, and it is kept with the row
    /// ([`Self::metric_norm_squared`]) when finite.
    #[inline]
    pub fn push_with_metric(&mut self, fill: impl FnOnce(&mut TaskRow<T, N>) -> Option<T>) -> Result<(), TaskError> {
        let zero =
            TaskRow { jacobian: RowSVector::zeros(), force: T::zero(), potential: T::zero(), activation: T::zero() };
        self.rows.push(zero).map_err(|_| TaskError::Capacity { capacity: R })?;
        let Some(row) = self.rows.last_mut() else {
            return Err(TaskError::Capacity { capacity: R });
        };
        let metric = fill(row).filter(|m| m.is_finite());
        if row.is_finite() && self.metrics.push(metric).is_ok() {
            Ok(())
        } else {
            self.rows.pop();
            Err(TaskError::NonFinite)
        }
    }

    /// Keeps the first `len` rows (all rows if there are fewer).
    pub fn truncate(&mut self, len: usize) {
        self.rows.truncate(len);
        self.metrics.truncate(len);
    }

    /// The rows.
    pub fn rows(&self) -> &[TaskRow<T, N>] {
        &self.rows
    }

    /// Per row (same order and length as [`Self::rows`]): its `j M⁻¹ jᵀ` over the inertia
    /// factor its task used, when the task provided it.
    pub fn metric_norm_squared(&self) -> &[Option<T>] {
        &self.metrics
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// `true` if there is no row.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// Torque of the rows used alone, without a hierarchy: `τ = Σ jᵀ f`.
    pub fn torque(&self) -> SVector<T, N> {
        self.rows.iter().fold(SVector::zeros(), |tau, r| tau + r.jacobian.transpose() * r.force)
    }

    /// Total potential energy of the rows (J).
    pub fn potential(&self) -> T {
        self.rows.iter().fold(T::zero(), |v, r| v + r.potential)
    }
}

/// Why a task could not produce its rows. The row list is left as it was before the call.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TaskError {
    /// The row list is full.
    Capacity {
        /// Its capacity.
        capacity: usize,
    },
    /// A computed or given value is NaN or infinite.
    NonFinite,
    /// A parameter is out of its valid range (negative stiffness, ξ < 0, lower > upper, ...).
    InvalidParameter {
        /// Which parameter.
        name: &'static str,
    },
    /// A quantity that must be inverted is (numerically) singular.
    Singular,
    /// The dynamics refused their input.
    Dynamics(DynamicsError),
}

impl From<DynamicsError> for TaskError {
    fn from(e: DynamicsError) -> Self {
        Self::Dynamics(e)
    }
}

impl fmt::Display for TaskError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Capacity { capacity } => write!(f, "more than {capacity} task rows"),
            Self::NonFinite => f.write_str("non-finite task value"),
            Self::InvalidParameter { name } => write!(f, "invalid task parameter {name}"),
            Self::Singular => f.write_str("singular task quantity"),
            Self::Dynamics(e) => write!(f, "dynamics: {e}"),
        }
    }
}

impl core::error::Error for TaskError {}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use nalgebra::{RowVector2, RowVector3};

    #[test]
    fn rows_sum_to_a_torque_and_reject_bad_input() {
        let mut rows = TaskRows::<f64, 2, 2>::new();
        let row = |j: [f64; 2], f| TaskRow {
            jacobian: RowVector2::new(j[0], j[1]),
            force: f,
            potential: 1.5,
            activation: 1.0,
        };
        rows.push(row([1.0, 0.0], 2.0)).unwrap();
        rows.push(row([0.5, 1.0], -4.0)).unwrap();
        assert_eq!(rows.torque(), SVector::<f64, 2>::new(0.0, -4.0));
        assert_eq!(rows.potential(), 3.0);
        assert_eq!(rows.push(row([0.0, 0.0], 1.0)), Err(TaskError::Capacity { capacity: 2 }));
        rows.clear();
        assert_eq!(rows.push(row([f64::NAN, 0.0], 1.0)), Err(TaskError::NonFinite));
        assert!(rows.is_empty());
    }

    /// [`TaskRow::is_finite`] (one multiply-add per entry) accepts and rejects exactly the rows
    /// the plain per-entry `is_finite` test does, in f32 and f64: every special value in every
    /// position (Jacobian entries and the three scalars), on top of finite rows with extreme
    /// magnitudes (whose `x · 0` must not overflow into a false rejection).
    #[test]
    fn row_finiteness_probe_equals_the_plain_test() {
        fn check<T: RealField + Copy>(values: &[T]) -> usize {
            let plain = |r: &TaskRow<T, 3>| {
                r.force.is_finite()
                    && r.potential.is_finite()
                    && r.activation.is_finite()
                    && r.jacobian.iter().all(|x| x.is_finite())
            };
            let mut rejected = 0;
            for &base in values.iter().filter(|v| v.is_finite()) {
                for position in 0..6 {
                    for &value in values {
                        let mut entries = [base; 6];
                        entries[position] = value;
                        let row = TaskRow {
                            jacobian: nalgebra::RowVector3::new(entries[0], entries[1], entries[2]),
                            force: entries[3],
                            potential: entries[4],
                            activation: entries[5],
                        };
                        assert_eq!(row.is_finite(), plain(&row), "value at {position}");
                        rejected += usize::from(!row.is_finite());
                    }
                }
            }
            rejected
        }
        let f64s = [
            0.0,
            -0.0,
            1.0,
            -2.5,
            f64::MAX,
            f64::MIN,
            f64::MIN_POSITIVE,
            1e-310,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        let f32s = [
            0.0,
            -0.0,
            1.0,
            -2.5,
            f32::MAX,
            f32::MIN,
            f32::MIN_POSITIVE,
            1e-40,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ];
        // Not vacuous: the three non-finite values are rejected in each of the six positions.
        assert_eq!(check(&f64s), 8 * 6 * 3);
        assert_eq!(check(&f32s), 8 * 6 * 3);
    }

    /// `push_with` fills a zero row in place: the same list as `push`; a non-finite row or a
    /// full list leaves the list unchanged; the writer sees the entries of its columns only.
    #[test]
    fn push_with_builds_the_row_in_place() {
        let mut rows = TaskRows::<f64, 3, 2>::new();
        rows.push_with(1..3, |r| {
            assert_eq!((&*r.jacobian, r.force, r.potential, r.activation), (&[0.0, 0.0][..], 0.0, 0.0, 0.0));
            r.jacobian[0] = 2.0;
            r.jacobian[1] = -3.0;
            r.force = -1.5;
            r.potential = 0.25;
            r.activation = 1.0;
        })
        .unwrap();
        let expected =
            TaskRow { jacobian: RowVector3::new(0.0, 2.0, -3.0), force: -1.5, potential: 0.25, activation: 1.0 };
        assert_eq!(rows.rows(), &[expected]);
        assert_eq!(rows.push_with(0..1, |r| r.jacobian[0] = f64::INFINITY), Err(TaskError::NonFinite));
        assert_eq!(rows.push_with(2..9, |r| r.jacobian[0] = f64::NAN), Err(TaskError::NonFinite));
        assert_eq!(rows.push_with(0..0, |r| r.potential = f64::NAN), Err(TaskError::NonFinite));
        assert_eq!(rows.rows(), &[expected]);
        rows.push_with(2..9, |r| {
            assert_eq!(r.jacobian.len(), 1, "clamped to the row");
            r.force = 1.0;
        })
        .unwrap();
        assert_eq!(rows.push_with(0..1, |r| r.force = 1.0), Err(TaskError::Capacity { capacity: 2 }));
        assert_eq!(rows.len(), 2);
        rows.truncate(1);
        assert_eq!(rows.rows(), &[expected]);
    }
}
pub mod collision;

pub mod cartesian_impedance;
pub mod end_stops;
pub mod joint_impedance;
pub mod manipulability;
pub mod torso_workspace;
