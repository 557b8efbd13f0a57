//! The projection's typed errors.

use core::fmt;

/// Why a projection was refused. The torque output is left unchanged.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HierarchyError {
    /// A row names a level `≥ L`.
    TooManyLevels {
        /// The capacity `L`.
        capacity: usize,
    },
    /// More rows than the capacity.
    Capacity {
        /// The capacity `R`.
        capacity: usize,
    },
    /// A row or a shaping parameter is NaN or infinite.
    NonFinite,
    /// The shaping band is empty or negative.
    InvalidShaping,
}

impl fmt::Display for HierarchyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooManyLevels { capacity } => write!(f, "more than {capacity} priority levels"),
            Self::Capacity { capacity } => write!(f, "more than {capacity} stack rows"),
            Self::NonFinite => f.write_str("non-finite row or shaping parameter"),
            Self::InvalidShaping => f.write_str("invalid transition band"),
        }
    }
}

impl core::error::Error for HierarchyError {}
