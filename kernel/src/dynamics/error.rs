//! Errors of the dynamics algorithms.

use core::fmt;

/// Why a dynamics algorithm refused its input. Outputs are left unchanged on error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DynamicsError {
    /// An input vector contains NaN or infinity.
    NonFinite {
        /// Which input.
        input: &'static str,
    },
    /// A frame id is not in the model.
    UnknownFrame,
    /// A body id is not in the model.
    UnknownBody,
    /// `M(q)` failed the Cholesky factorization (not positive definite, or NaN).
    MassMatrixNotPositiveDefinite,
}

impl fmt::Display for DynamicsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFinite { input } => write!(f, "input {input} is not finite"),
            Self::UnknownFrame => f.write_str("unknown frame"),
            Self::UnknownBody => f.write_str("unknown body"),
            Self::MassMatrixNotPositiveDefinite => f.write_str("mass matrix is not positive definite"),
        }
    }
}

impl core::error::Error for DynamicsError {}
