//! Why the multi-level controller refused its input.

use core::fmt;

/// Why the multi-level decomposition or control law refused its input. Outputs are left
/// unchanged.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MultilevelError {
    /// More rows than the stack's capacity.
    Capacity {
        /// The capacity `R`.
        capacity: usize,
    },
    /// A row names a level `≥ L`.
    TooManyLevels {
        /// The capacity `L`.
        capacity: usize,
    },
    /// The levels above the last one have more rows than the robot has coordinates, so they
    /// cannot all be independent.
    TooManyConstraints {
        /// Rows on the levels `1 … r−1`.
        rows: usize,
    },
    /// A row, a dynamics term or the state is NaN or infinite.
    NonFinite,
    /// A row of `level` is (numerically) dependent on the rows above it or zero: the
    /// hierarchy is singular (Proposition 5.1 requires full row rank).
    Singular {
        /// The level (0 = highest).
        level: usize,
    },
    /// The remaining null space of the last level could not be spanned (rounding broke the
    /// rank count).
    NullSpaceDeficient,
    /// A setting of [`MultilevelConfig`](super::MultilevelConfig) is out of range.
    InvalidConfig,
    /// The stack has another number of levels than the decomposition it is used with.
    StackMismatch,
}

impl fmt::Display for MultilevelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Capacity { capacity } => write!(f, "more than {capacity} compliance rows"),
            Self::TooManyLevels { capacity } => write!(f, "more than {capacity} priority levels"),
            Self::TooManyConstraints { rows } => write!(f, "{rows} rows above the last level exceed the coordinates"),
            Self::NonFinite => f.write_str("non-finite row, dynamics term or state"),
            Self::Singular { level } => write!(f, "singular hierarchy: a row of level {level} is dependent"),
            Self::NullSpaceDeficient => f.write_str("the remaining null space could not be spanned"),
            Self::InvalidConfig => f.write_str("invalid multi-level configuration"),
            Self::StackMismatch => f.write_str("stack and decomposition have different levels"),
        }
    }
}

impl core::error::Error for MultilevelError {}
