//! Errors found while building a model.

use core::fmt;

/// Why a model description was rejected by [`super::description::ModelBuilder`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ModelError {
    /// More bodies than the capacity `B`.
    TooManyBodies {
        /// The capacity.
        capacity: usize,
    },
    /// More frames than the capacity `F`.
    TooManyFrames {
        /// The capacity.
        capacity: usize,
    },
    /// A body's parent is not an earlier body (the tree must be in topological order).
    ParentNotBefore {
        /// The offending body.
        body: usize,
    },
    /// A frame refers to a body that does not exist.
    UnknownBody {
        /// The missing body.
        body: usize,
    },
    /// A joint drive refers to a coordinate `≥ N`.
    CoordinateOutOfRange {
        /// The offending body.
        body: usize,
        /// The coordinate it names.
        coordinate: usize,
    },
    /// A joint is driven by no coordinate.
    UndrivenJoint {
        /// The offending body.
        body: usize,
    },
    /// A coordinate drives no joint, so the mass matrix would be singular.
    UndrivenCoordinate {
        /// The coordinate.
        coordinate: usize,
    },
    /// Mass negative, inertia not symmetric or violating the triangle inequality, or NaN.
    NonPhysicalInertia {
        /// The offending body.
        body: usize,
    },
    /// A limit is NaN, lower > upper, or a velocity/effort limit is negative.
    InvalidLimits {
        /// The coordinate.
        coordinate: usize,
    },
    /// A value that must be finite is not.
    NonFinite {
        /// What was not finite.
        what: &'static str,
    },
}

impl fmt::Display for ModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooManyBodies { capacity } => write!(f, "more than {capacity} bodies"),
            Self::TooManyFrames { capacity } => write!(f, "more than {capacity} frames"),
            Self::ParentNotBefore { body } => write!(f, "body {body}: parent must be an earlier body"),
            Self::UnknownBody { body } => write!(f, "unknown body {body}"),
            Self::CoordinateOutOfRange { body, coordinate } => {
                write!(f, "body {body}: coordinate {coordinate} out of range")
            }
            Self::UndrivenJoint { body } => write!(f, "body {body}: joint driven by no coordinate"),
            Self::UndrivenCoordinate { coordinate } => write!(f, "coordinate {coordinate} drives no joint"),
            Self::NonPhysicalInertia { body } => write!(f, "body {body}: inertia is not physical"),
            Self::InvalidLimits { coordinate } => write!(f, "coordinate {coordinate}: invalid limits"),
            Self::NonFinite { what } => write!(f, "{what} is not finite"),
        }
    }
}

impl core::error::Error for ModelError {}
