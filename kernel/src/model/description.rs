//! The kinematic tree's types: bodies, fixed frames, joint limits, the [`Model`] and its
//! validating [`ModelBuilder`].

use super::error::ModelError;
use super::inertia::Inertia;
use super::joint::{JointDrive, JointKind};
use crate::math::spatial::Placement;
use heapless::Vec;
use nalgebra::{RealField, SVector, Vector3};

/// Index of a body in [`Model::bodies`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct BodyId(pub usize);

/// Index of a fixed frame in [`Model::frames`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct FrameId(pub usize);

/// One rigid body together with the joint that connects it to its parent.
#[derive(Clone, Debug, PartialEq)]
pub struct Body<T: RealField> {
    /// Parent body, or `None` if the joint connects the body to the world.
    pub parent: Option<BodyId>,
    /// Placement of the joint frame in the parent body frame (world frame for a root body).
    pub joint_placement: Placement<T>,
    /// Motion type of the joint; the body frame coincides with the joint frame at value 0.
    pub joint: JointKind<T>,
    /// How the joint value follows the generalized coordinates.
    pub drive: JointDrive<T>,
    /// Inertia of the body in its own frame.
    pub inertia: Inertia<T>,
}

/// A frame rigidly attached to a body (TCP, sensor, collision anchor, lumped fixed link).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame<T: RealField> {
    /// Body the frame is attached to, or `None` for a world-fixed frame.
    pub parent: Option<BodyId>,
    /// Placement of the frame in the parent body frame.
    pub placement: Placement<T>,
}

/// Per-coordinate limits. Infinite position limits describe continuous joints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointLimits<T, const N: usize> {
    /// Lower position limit (rad or m).
    pub position_lower: SVector<T, N>,
    /// Upper position limit (rad or m).
    pub position_upper: SVector<T, N>,
    /// Largest admissible speed magnitude (rad/s or m/s).
    pub velocity: SVector<T, N>,
    /// Largest admissible generalized force magnitude (Nm or N).
    pub effort: SVector<T, N>,
}

impl<T: RealField + Copy, const N: usize> JointLimits<T, N> {
    /// No limits at all (every bound infinite).
    pub fn unlimited() -> Self {
        let inf = SVector::repeat(T::max_value().unwrap_or_else(T::one));
        Self { position_lower: -inf, position_upper: inf, velocity: inf, effort: inf }
    }
}

/// The robot description. Build it with [`ModelBuilder`].
#[derive(Clone, Debug, PartialEq)]
pub struct Model<T: RealField, const N: usize, const B: usize, const F: usize> {
    bodies: Vec<Body<T>, B>,
    frames: Vec<Frame<T>, F>,
    /// Gravitational acceleration in the world frame (m/s²), e.g. `(0, 0, −9.81)`.
    pub gravity: Vector3<T>,
    /// Joint limits per generalized coordinate.
    pub limits: JointLimits<T, N>,
}

impl<T: RealField + Copy, const N: usize, const B: usize, const F: usize> Model<T, N, B, F> {
    /// The bodies in topological order.
    pub fn bodies(&self) -> &[Body<T>] {
        &self.bodies
    }

    /// The fixed frames.
    pub fn frames(&self) -> &[Frame<T>] {
        &self.frames
    }

    /// A body by id.
    pub fn body(&self, id: BodyId) -> Option<&Body<T>> {
        self.bodies.get(id.0)
    }

    /// A frame by id.
    pub fn frame(&self, id: FrameId) -> Option<&Frame<T>> {
        self.frames.get(id.0)
    }

    /// Iterator over `id` and its ancestors up to the root (at most `B` steps).
    pub fn support(&self, id: BodyId) -> impl Iterator<Item = BodyId> + '_ {
        let mut next = self.bodies.get(id.0).map(|_| id);
        core::iter::from_fn(move || {
            let current = next?;
            next = self.bodies.get(current.0).and_then(|b| b.parent);
            Some(current)
        })
        .take(B)
    }

    /// Total mass of the robot (kg).
    pub fn total_mass(&self) -> T {
        self.bodies.iter().fold(T::zero(), |m, b| m + b.inertia.mass)
    }
}

/// Builds and validates a [`Model`].
///
/// ```
/// use kernel::model::{Inertia, JointDrive, JointKind, ModelBuilder, Placement};
/// use nalgebra::{Vector3, Unit};
/// // A pendulum: one revolute joint about y, 1 kg at 0.5 m.
/// let mut b = ModelBuilder::<f64, 1, 1, 1>::new(Vector3::new(0.0, 0.0, -9.81));
/// let link = b.add_body(None, Placement::identity(),
///     JointKind::Revolute { axis: Unit::new_normalize(Vector3::y()) }, JointDrive::actuated(0),
///     Inertia::point_mass(1.0, Vector3::new(0.0, 0.0, -0.5))).unwrap();
/// b.add_frame(Some(link), Placement::translation(0.0, 0.0, -0.5)).unwrap();
/// let model = b.try_build().unwrap();
/// assert_eq!(model.total_mass(), 1.0);
/// ```
#[derive(Clone, Debug)]
pub struct ModelBuilder<T: RealField, const N: usize, const B: usize, const F: usize> {
    model: Model<T, N, B, F>,
}

impl<T: RealField + Copy, const N: usize, const B: usize, const F: usize> ModelBuilder<T, N, B, F> {
    const SIZES_OK: () = assert!(B >= N && N > 0, "a model needs B >= N > 0");

    /// An empty model under gravity `gravity` (m/s², world frame), without limits.
    pub fn new(gravity: Vector3<T>) -> Self {
        let () = Self::SIZES_OK;
        Self { model: Model { bodies: Vec::new(), frames: Vec::new(), gravity, limits: JointLimits::unlimited() } }
    }

    /// Appends a body; its parent must already exist. Returns its id.
    pub fn add_body(
        &mut self,
        parent: Option<BodyId>,
        joint_placement: Placement<T>,
        joint: JointKind<T>,
        drive: JointDrive<T>,
        inertia: Inertia<T>,
    ) -> Result<BodyId, ModelError> {
        let id = BodyId(self.model.bodies.len());
        if parent.is_some_and(|p| p.0 >= id.0) {
            return Err(ModelError::ParentNotBefore { body: id.0 });
        }
        if !inertia.is_physical() {
            return Err(ModelError::NonPhysicalInertia { body: id.0 });
        }
        if !placement_is_finite(&joint_placement) || !joint.axis().iter().all(|x| x.is_finite()) {
            return Err(ModelError::NonFinite { what: "joint placement or axis" });
        }
        if drive.terms().is_empty() {
            return Err(ModelError::UndrivenJoint { body: id.0 });
        }
        for term in drive.terms() {
            if term.coordinate >= N {
                return Err(ModelError::CoordinateOutOfRange { body: id.0, coordinate: term.coordinate });
            }
            if !term.coefficient.is_finite() {
                return Err(ModelError::NonFinite { what: "drive coefficient" });
            }
        }
        if !drive.offset().is_finite() {
            return Err(ModelError::NonFinite { what: "drive offset" });
        }
        let body = Body { parent, joint_placement, joint, drive, inertia };
        self.model.bodies.push(body).map_err(|_| ModelError::TooManyBodies { capacity: B })?;
        Ok(id)
    }

    /// Appends a fixed frame attached to `parent` (or to the world). Returns its id.
    pub fn add_frame(&mut self, parent: Option<BodyId>, placement: Placement<T>) -> Result<FrameId, ModelError> {
        if parent.is_some_and(|p| p.0 >= self.model.bodies.len()) {
            return Err(ModelError::UnknownBody { body: parent.map_or(0, |p| p.0) });
        }
        if !placement_is_finite(&placement) {
            return Err(ModelError::NonFinite { what: "frame placement" });
        }
        let id = FrameId(self.model.frames.len());
        self.model.frames.push(Frame { parent, placement }).map_err(|_| ModelError::TooManyFrames { capacity: F })?;
        Ok(id)
    }

    /// Sets the joint limits.
    pub fn limits(&mut self, limits: JointLimits<T, N>) -> &mut Self {
        self.model.limits = limits;
        self
    }

    /// Validates the whole model and returns it.
    ///
    /// Checks: every coordinate drives at least one joint (otherwise `M(q)` is singular),
    /// limits are ordered and non-negative (NaN fails every check), gravity is finite.
    pub fn try_build(self) -> Result<Model<T, N, B, F>, ModelError> {
        let model = self.model;
        for coordinate in 0..N {
            let driven = model
                .bodies
                .iter()
                .any(|b| b.drive.terms().iter().any(|t| t.coordinate == coordinate && t.coefficient != T::zero()));
            if !driven {
                return Err(ModelError::UndrivenCoordinate { coordinate });
            }
        }
        let l = &model.limits;
        for i in 0..N {
            let ordered =
                matches!((l.position_lower.get(i), l.position_upper.get(i)), (Some(lo), Some(hi)) if lo <= hi);
            let positive = matches!((l.velocity.get(i), l.effort.get(i)), (Some(v), Some(e)) if *v >= T::zero() && *e >= T::zero());
            if !ordered || !positive {
                return Err(ModelError::InvalidLimits { coordinate: i });
            }
        }
        if !model.gravity.iter().all(|g| g.is_finite()) {
            return Err(ModelError::NonFinite { what: "gravity" });
        }
        Ok(model)
    }
}

fn placement_is_finite<T: RealField + Copy>(p: &Placement<T>) -> bool {
    p.rotation.matrix().iter().chain(p.translation.vector.iter()).all(|x| x.is_finite())
}
