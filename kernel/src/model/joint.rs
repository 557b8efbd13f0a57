//! Joints: their motion type and how they are driven by the generalized coordinates.

use heapless::Vec;
use nalgebra::{RealField, Rotation3, Translation3, Unit, Vector3};

use crate::math::spatial::Placement;

/// Motion a joint allows between its joint frame and its child body frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum JointKind<T: RealField> {
    /// Rotation about `axis` (unit vector in the joint frame); joint value in rad.
    Revolute {
        /// Rotation axis in the joint frame.
        axis: Unit<Vector3<T>>,
    },
    /// Translation along `axis` (unit vector in the joint frame); joint value in m.
    Prismatic {
        /// Translation axis in the joint frame.
        axis: Unit<Vector3<T>>,
    },
}

impl<T: RealField + Copy> JointKind<T> {
    /// Placement of the child body frame in the joint frame for joint value `value`.
    pub fn motion(&self, value: T) -> Placement<T> {
        match self {
            Self::Revolute { axis } => {
                Placement::from_parts(Translation3::identity(), Rotation3::from_axis_angle(axis, value))
            }
            Self::Prismatic { axis } => {
                Placement::from_parts(Translation3::from(axis.into_inner() * value), Rotation3::identity())
            }
        }
    }

    /// The joint axis in the joint frame.
    pub fn axis(&self) -> Unit<Vector3<T>> {
        match self {
            Self::Revolute { axis } | Self::Prismatic { axis } => *axis,
        }
    }
}

/// Most coordinates one joint can depend on.
///
/// Three covers Justin's passive torso joint `q_t4 = −(q_t2 + q_t3)` (3.41) with room for one
/// more; ordinary joints use one term.
pub const MAX_DRIVE_TERMS: usize = 3;

/// One term `coefficient · q[coordinate]` of a joint's drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveTerm<T> {
    /// Index of the generalized coordinate.
    pub coordinate: usize,
    /// Dimensionless coefficient.
    pub coefficient: T,
}

/// How a joint's value follows the generalized coordinates: `q_joint = Σ c_k q_k + offset`.
///
/// This is one row of the constant coupling matrix `G` with `q_tree = G q + offset`; every
/// dynamics quantity of the model is the tree quantity mapped through `G`
/// (`M = Gᵀ M_tree G`, `J = J_tree G`, `τ = Gᵀ τ_tree`). An actuated joint has one term with
/// coefficient 1; a URDF `mimic` joint has one term with the multiplier; Justin's passive torso
/// joint has two terms (3.41).
#[derive(Clone, Debug, PartialEq)]
pub struct JointDrive<T> {
    terms: Vec<DriveTerm<T>, MAX_DRIVE_TERMS>,
    offset: T,
}

impl<T: RealField + Copy> JointDrive<T> {
    /// A joint driven directly by coordinate `coordinate`.
    pub fn actuated(coordinate: usize) -> Self {
        let mut terms = Vec::new();
        // Capacity is at least one, so the push cannot fail.
        let _ = terms.push(DriveTerm { coordinate, coefficient: T::one() });
        Self { terms, offset: T::zero() }
    }

    /// A joint coupled to several coordinates; `None` if more than [`MAX_DRIVE_TERMS`] terms.
    pub fn coupled(terms: &[(usize, T)], offset: T) -> Option<Self> {
        let mut out = Vec::new();
        for &(coordinate, coefficient) in terms {
            out.push(DriveTerm { coordinate, coefficient }).ok()?;
        }
        Some(Self { terms: out, offset })
    }

    /// The terms of the drive.
    pub fn terms(&self) -> &[DriveTerm<T>] {
        &self.terms
    }

    /// Constant offset (rad or m).
    pub fn offset(&self) -> T {
        self.offset
    }

    /// Joint value (or, with `offset = false`, rate) for coordinates `q`.
    pub fn evaluate<const N: usize>(&self, q: &nalgebra::SVector<T, N>, with_offset: bool) -> T {
        let base = if with_offset { self.offset } else { T::zero() };
        self.terms
            .iter()
            .fold(base, |acc, t| acc + t.coefficient * q.get(t.coordinate).copied().unwrap_or_else(T::zero))
    }
}
