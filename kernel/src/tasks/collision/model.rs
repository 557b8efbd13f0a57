//! The geometric collision model (Sec. 3.1.1): swept-sphere volumes attached to bodies (or to
//! the world), the list of pairs that can collide, and the per-cycle world update and distance
//! computation.
//!
//! [`CollisionModel`] is constant (capacities `V` volumes and `P` pairs, validated once by
//! [`CollisionModelBuilder::try_build`]); [`CollisionData`] is its preallocated workspace.

use core::fmt;

use heapless::Vec;
use nalgebra::{RealField, Vector3};

use super::volumes::{proximity_framed, Core, Proximity, SweptSphere, TriangleFrame};
use crate::math::sqrt;
use crate::model::{BodyId, Data, Model};

/// Index of a volume in [`CollisionModel::volumes`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct VolumeId(pub usize);

/// One bounding volume.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Volume<T: RealField> {
    /// Body the volume moves with; `None` for an environment volume fixed in the world
    /// (floor, table, wall).
    pub body: Option<BodyId>,
    /// The volume in the body frame (in the world frame if `body` is `None`), m.
    pub shape: SweptSphere<T>,
}

/// A pair of volumes that can collide; `first < second`. The collision direction `e` of (3.5)
/// points from `first` (`i`) to `second` (`j`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CollisionPair {
    /// Volume `i`.
    pub first: VolumeId,
    /// Volume `j`.
    pub second: VolumeId,
}

/// Why a pair of volumes is not checked ([`exclusion_rule`], or listed by the author).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Exclusion {
    /// Both volumes are on the same rigid body (or both fixed in the world): their distance
    /// never changes.
    SameBody,
    /// The bodies are joined by one joint, or by two joints whose axes intersect in a body of
    /// zero length (the middle body's child joint sits at its origin, like a pitch-pitch
    /// wrist): neighbouring link volumes overlap at the joint by design.
    Adjacent,
    /// Excluded by the model's author: the kinematics cannot bring the volumes together (or
    /// their distance cannot change), documented with the model.
    Listed,
}

/// Why a collision model was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CollisionError {
    /// More than `V` volumes.
    TooManyVolumes {
        /// The capacity `V`.
        capacity: usize,
    },
    /// More than `P` pairs remain after the exclusions.
    TooManyPairs {
        /// The capacity `P`.
        capacity: usize,
    },
    /// A volume refers to a body that is not in the model.
    UnknownBody {
        /// The volume.
        volume: usize,
    },
    /// An exclusion refers to a volume that does not exist.
    UnknownVolume {
        /// The index given.
        volume: usize,
    },
    /// A volume has a negative or non-finite radius or a non-finite point.
    InvalidVolume {
        /// The volume.
        volume: usize,
    },
}

impl fmt::Display for CollisionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooManyVolumes { capacity } => write!(f, "more than {capacity} collision volumes"),
            Self::TooManyPairs { capacity } => write!(f, "more than {capacity} collision pairs"),
            Self::UnknownBody { volume } => write!(f, "collision volume {volume} is on an unknown body"),
            Self::UnknownVolume { volume } => write!(f, "unknown collision volume {volume}"),
            Self::InvalidVolume { volume } => write!(f, "collision volume {volume} has a bad radius or point"),
        }
    }
}

impl core::error::Error for CollisionError {}

/// Volumes and enabled pairs. Build it with [`CollisionModelBuilder`].
#[derive(Clone, Debug, PartialEq)]
pub struct CollisionModel<T: RealField, const V: usize, const P: usize> {
    volumes: Vec<Volume<T>, V>,
    /// [`SweptSphere::bounding_sphere`] of each volume in its body frame (world frame for an
    /// environment volume): a rigid motion maps it onto a bounding sphere of the moved volume.
    bounds: Vec<(Vector3<T>, T), V>,
    pairs: Vec<CollisionPair, P>,
}

impl<T: RealField + Copy, const V: usize, const P: usize> CollisionModel<T, V, P> {
    /// The volumes.
    pub fn volumes(&self) -> &[Volume<T>] {
        &self.volumes
    }

    /// The enabled pairs, in lexicographic order of `(first, second)`.
    pub fn pairs(&self) -> &[CollisionPair] {
        &self.pairs
    }

    /// A volume by id.
    pub fn volume(&self, id: VolumeId) -> Option<&Volume<T>> {
        self.volumes.get(id.0)
    }

    /// [`Self::update_world`] then [`Self::compute_distances`]: the per-cycle geometric update
    /// of Sec. 3.1.1 ("All volumes are transformed into the world frame and the distances as
    /// well as the contact points are determined").
    pub fn update<const N: usize, const B: usize, const F: usize>(
        &self,
        data: &Data<T, N, B, F>,
        collision: &mut CollisionData<T, V, P>,
    ) {
        self.update_world(data, collision);
        self.compute_distances(collision);
    }

    /// Transforms every volume and its bounding sphere into the world frame with the body
    /// placements of the last [`crate::dynamics::forward_kinematics`]: writes
    /// `collision.world_volumes` and `collision.bounding_spheres`. Cost O(V).
    pub fn update_world<const N: usize, const B: usize, const F: usize>(
        &self,
        data: &Data<T, N, B, F>,
        collision: &mut CollisionData<T, V, P>,
    ) {
        let world = collision.world_volumes.iter_mut().zip(collision.bounding_spheres.iter_mut());
        for ((volume, (center, radius)), (slot, bound)) in self.volumes.iter().zip(&self.bounds).zip(world) {
            let placement = volume.body.and_then(|b| data.body_placements.get(b.0));
            (*slot, *bound) = match placement {
                Some(p) => (volume.shape.transformed(p), (p.rotation * center + p.translation.vector, *radius)),
                None => (volume.shape, (*center, *radius)),
            };
        }
    }

    /// Distance and closest points of every enabled pair from `collision.world_volumes`:
    /// writes `collision.proximities`. Cost O(P), bounded per pair kind.
    ///
    /// With `collision.exact_within = Some(d)` (broad phase), a pair whose bounding spheres are
    /// more than `d` apart, or one of whose triangles has the other's bounding sphere more than
    /// `d` beyond the slab the triangle's volume lies in, gets that gap as its distance —
    /// a lower bound of the true distance, larger than `d` — with the sphere centres as "closest
    /// points" and no direction, without the exact narrow-phase computation. Every pair closer than `d` is exact. A task that emits
    /// rows below `d` ([`super::CollisionParameters::emit_distance`]) gets the same rows.
    /// When every two bounding centres lie within `d` of each other (checked once, on the box
    /// of the centres) no pair can be culled, and the per-pair tests are skipped.
    pub fn compute_distances(&self, collision: &mut CollisionData<T, V, P>) {
        let CollisionData { world_volumes, bounding_spheres, proximities, exact_within, triangle_frames } = collision;
        // Each triangle's frame and each segment's direction once per call, shared by all its
        // pairs.
        for (frame, volume) in triangle_frames.iter_mut().zip(world_volumes.iter()) {
            volume.core.update_frame(frame);
        }
        // No pair is culled when all bounding centres lie within `limit` of each other.
        let cull_beyond = exact_within.filter(|&limit| !centres_within(bounding_spheres, limit));
        for (pair, slot) in self.pairs.iter().zip(proximities.iter_mut()) {
            let (Some(a), Some(b)) = (world_volumes.get(pair.first.0), world_volumes.get(pair.second.0)) else {
                continue;
            };
            let (Some(fa), Some(fb)) = (triangle_frames.get(pair.first.0), triangle_frames.get(pair.second.0)) else {
                continue;
            };
            if let (Some(limit), Some((ca, ra)), Some((cb, rb))) =
                (cull_beyond, bounding_spheres.get(pair.first.0), bounding_spheres.get(pair.second.0))
            {
                // Squared comparison first: the square root only for the pairs that may be far.
                let (separation2, reach) = ((ca - cb).norm_squared(), limit + *ra + *rb);
                if reach <= T::zero() || separation2 > reach * reach {
                    let gap = sqrt(separation2) - *ra - *rb;
                    if gap > limit {
                        *slot = Proximity { distance: gap, core_first: *ca, core_second: *cb, direction: None };
                        continue;
                    }
                }
                // A triangle's plane separates it from the other volume's bounding sphere. The
                // triangle's bounding centre (its centroid) lies in its plane, so the sphere's
                // height above the plane is at most the centres' separation: only pairs whose
                // separation exceeds what the slab needs are tested.
                let slab = |frame: &TriangleFrame<T>, volume: &SweptSphere<T>, center, ball_radius: T| {
                    let Core::Triangle(_) = volume.core else { return None };
                    let needed = limit + volume.radius + ball_radius;
                    if needed > T::zero() && separation2 > needed * needed {
                        frame.slab_gap(volume.radius, center, ball_radius, limit)
                    } else {
                        None
                    }
                };
                if let Some(gap) = slab(fa, a, cb, *rb).or_else(|| slab(fb, b, ca, *ra)) {
                    *slot = Proximity { distance: gap, core_first: *ca, core_second: *cb, direction: None };
                    continue;
                }
            }
            *slot = proximity_framed(a, fa, b, fb);
        }
    }
}

/// `true` if `limit > 0` and the box of the sphere centres has a diagonal of at most `limit`
/// (squared, rounded as the broad phase rounds), so no two centres are more than `limit`
/// apart. Then the broad phase of [`CollisionModel::compute_distances`] culls no pair: each
/// component of `cₐ − c_b` is at most the box's extent in magnitude, and rounding is monotone,
/// so the computed `‖cₐ − c_b‖²` is at most the computed diagonal², at most `limit²`, at most
/// every `(limit + rₐ + r_b)²` and `(limit + r + r_ball)²` the sphere and slab tests compare
/// it with (radii `≥ 0`). Cost O(V), once per call instead of the per-pair tests.
fn centres_within<T: RealField + Copy>(spheres: &[(Vector3<T>, T)], limit: T) -> bool {
    let Some(((first, _), rest)) = spheres.split_first() else {
        return false;
    };
    let (mut lo, mut hi) = (*first, *first);
    for (center, _) in rest {
        for ((l, h), &x) in lo.iter_mut().zip(hi.iter_mut()).zip(center.iter()) {
            // A NaN centre leaves the box as it is: its pairs are exact either way (every
            // comparison with a NaN separation fails).
            if x < *l {
                *l = x;
            }
            if x > *h {
                *h = x;
            }
        }
    }
    limit > T::zero() && (hi - lo).norm_squared() <= limit * limit
}

/// Preallocated workspace of a [`CollisionModel`].
#[derive(Clone, Debug)]
pub struct CollisionData<T: RealField, const V: usize, const P: usize> {
    /// Every volume in the world frame ([`CollisionModel::update_world`]).
    pub world_volumes: [SweptSphere<T>; V],
    /// Bounding sphere `(center, radius)` of each world volume (m).
    pub bounding_spheres: [(Vector3<T>, T); V],
    /// Distance, closest points and direction of each enabled pair, in the order of
    /// [`CollisionModel::pairs`] ([`CollisionModel::compute_distances`]).
    pub proximities: [Proximity<T>; P],
    /// Broad phase: pairs farther apart than this (m) get a lower bound instead of their exact
    /// distance ([`CollisionModel::compute_distances`]); `None` (the default) computes every
    /// pair exactly.
    pub exact_within: Option<T>,
    /// The frame of each world volume with a triangle core (edges, normal, edge normals) or a
    /// segment core (start, direction), written by [`CollisionModel::compute_distances`] for
    /// its pairs.
    triangle_frames: [TriangleFrame<T>; V],
}

impl<T: RealField + Copy, const V: usize, const P: usize> CollisionData<T, V, P> {
    /// A zeroed workspace for `model`.
    pub fn new(_model: &CollisionModel<T, V, P>) -> Self {
        let origin = Vector3::zeros();
        Self {
            world_volumes: [SweptSphere { core: Core::Point(origin), radius: T::zero() }; V],
            bounding_spheres: [(origin, T::zero()); V],
            proximities: [Proximity { distance: T::zero(), core_first: origin, core_second: origin, direction: None };
                P],
            exact_within: None,
            triangle_frames: [TriangleFrame::placeholder(); V],
        }
    }
}

/// Builds and validates a [`CollisionModel`].
///
/// ```
/// use kernel::tasks::collision::{CollisionModelBuilder, SweptSphere, VolumeId};
/// use kernel::model::{Inertia, JointDrive, JointKind, ModelBuilder, Placement};
/// use nalgebra::{Unit, Vector3};
/// // A slider on x carrying a sphere, above a world-fixed floor triangle.
/// let mut b = ModelBuilder::<f64, 1, 1, 1>::new(Vector3::new(0.0, 0.0, -9.81));
/// let slider = b.add_body(None, Placement::identity(),
///     JointKind::Prismatic { axis: Unit::new_normalize(Vector3::x()) }, JointDrive::actuated(0),
///     Inertia::point_mass(2.0, Vector3::zeros())).unwrap();
/// let robot = b.try_build().unwrap();
/// let mut c = CollisionModelBuilder::<f64, 3, 2>::new();
/// let ball = c.add_volume(Some(slider), SweptSphere::sphere(Vector3::new(0.0, 0.0, 0.5), 0.1)).unwrap();
/// let floor = c.add_volume(None, SweptSphere::swept_triangle(Vector3::new(-10.0, -10.0, 0.0),
///     Vector3::new(30.0, -10.0, 0.0), Vector3::new(-10.0, 30.0, 0.0), 0.0)).unwrap();
/// c.add_volume(None, SweptSphere::sphere(Vector3::new(5.0, 0.0, 0.5), 0.2)).unwrap();
/// let model = c.try_build(&robot, &[(ball, floor)]).unwrap();
/// // Floor–wall share the world (same body); ball–floor is listed: one pair remains.
/// assert_eq!(model.pairs().len(), 1);
/// assert_eq!(model.pairs()[0].second, VolumeId(2));
/// ```
#[derive(Clone, Debug)]
pub struct CollisionModelBuilder<T: RealField, const V: usize, const P: usize> {
    volumes: Vec<Volume<T>, V>,
}

impl<T: RealField + Copy, const V: usize, const P: usize> Default for CollisionModelBuilder<T, V, P> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: RealField + Copy, const V: usize, const P: usize> CollisionModelBuilder<T, V, P> {
    /// No volumes yet.
    pub const fn new() -> Self {
        Self { volumes: Vec::new() }
    }

    /// Appends a volume attached to `body` (`None`: fixed in the world); `shape` is given in
    /// the body frame (world frame). Returns its id.
    pub fn add_volume(&mut self, body: Option<BodyId>, shape: SweptSphere<T>) -> Result<VolumeId, CollisionError> {
        let id = self.volumes.len();
        if !(shape.core.is_finite() && shape.radius.is_finite() && shape.radius >= T::zero()) {
            return Err(CollisionError::InvalidVolume { volume: id });
        }
        self.volumes.push(Volume { body, shape }).map_err(|_| CollisionError::TooManyVolumes { capacity: V })?;
        Ok(VolumeId(id))
    }

    /// Validates the volumes against `model` and enables every pair except those excluded by
    /// the rules ([`Exclusion::SameBody`], [`Exclusion::Adjacent`]) or listed in `excluded`
    /// (in either order).
    pub fn try_build<const N: usize, const B: usize, const F: usize>(
        self,
        model: &Model<T, N, B, F>,
        excluded: &[(VolumeId, VolumeId)],
    ) -> Result<CollisionModel<T, V, P>, CollisionError> {
        for (index, volume) in self.volumes.iter().enumerate() {
            if volume.body.is_some_and(|b| model.body(b).is_none()) {
                return Err(CollisionError::UnknownBody { volume: index });
            }
        }
        if let Some(&(a, b)) = excluded.iter().find(|(a, b)| a.0 >= self.volumes.len() || b.0 >= self.volumes.len()) {
            return Err(CollisionError::UnknownVolume { volume: a.0.max(b.0) });
        }
        let mut pairs = Vec::new();
        for (i, a) in self.volumes.iter().enumerate() {
            for (j, b) in self.volumes.iter().enumerate().skip(i + 1) {
                let listed = excluded.iter().any(|&(x, y)| (x.0, y.0) == (i, j) || (x.0, y.0) == (j, i));
                if listed || exclusion_rule(model, a.body, b.body).is_some() {
                    continue;
                }
                pairs
                    .push(CollisionPair { first: VolumeId(i), second: VolumeId(j) })
                    .map_err(|_| CollisionError::TooManyPairs { capacity: P })?;
            }
        }
        let mut bounds = Vec::new();
        for volume in &self.volumes {
            bounds.push(volume.shape.bounding_sphere()).map_err(|_| CollisionError::TooManyVolumes { capacity: V })?;
        }
        Ok(CollisionModel { volumes: self.volumes, bounds, pairs })
    }
}

/// Why the automatic rules exclude a pair of volumes on `a` and `b` (`None`: world-fixed):
/// [`Exclusion::SameBody`] or [`Exclusion::Adjacent`]; `None` if the rules keep the pair (an
/// author's list may still exclude it). The world is not a link: an environment volume is
/// adjacent to no body.
pub fn exclusion_rule<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    a: Option<BodyId>,
    b: Option<BodyId>,
) -> Option<Exclusion> {
    if a == b {
        return Some(Exclusion::SameBody);
    }
    let (Some(a), Some(b)) = (a, b) else {
        return None;
    };
    let parent = |x: BodyId| model.body(x).and_then(|body| body.parent);
    // The body sits at its parent's origin: a zero-length parent link.
    let at_parent_origin =
        |x: BodyId| model.body(x).is_some_and(|body| body.joint_placement.translation.vector == Vector3::zeros());
    let adjacent = |child: BodyId, ancestor: BodyId| {
        parent(child) == Some(ancestor) || (at_parent_origin(child) && parent(child).and_then(parent) == Some(ancestor))
    };
    (adjacent(a, b) || adjacent(b, a)).then_some(Exclusion::Adjacent)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use nalgebra::{convert, RealField, SVector, Vector3};

    use super::*;
    use crate::dynamics::forward_kinematics;
    use crate::tasks::collision::proximity;
    use crate::test_models::{branched, state, Branched};

    fn v3<T: RealField + Copy>(x: f64, y: f64, z: f64) -> Vector3<T> {
        Vector3::new(convert(x), convert(y), convert(z))
    }

    /// Capsules, swept triangles and spheres on the branches of the test tree and in the world
    /// (a floor triangle, a wall triangle standing on it, a sphere), overlapping at many states.
    fn model<T: RealField + Copy>(robot: &Branched<T>) -> CollisionModel<T, 8, 28> {
        let mut c = CollisionModelBuilder::<T, 8, 28>::new();
        let r = |x: f64| convert::<f64, T>(x);
        let body = |k| Some(BodyId(k));
        c.add_volume(body(4), SweptSphere::capsule(v3(0.0, 0.0, 0.0), v3(0.15, 0.02, 0.0), r(0.05))).unwrap();
        let fingers = SweptSphere::swept_triangle(v3(0.0, 0.0, 0.0), v3(0.1, 0.0, 0.05), v3(0.0, 0.12, 0.1), r(0.03));
        c.add_volume(body(6), fingers).unwrap();
        c.add_volume(body(5), SweptSphere::sphere(v3(0.05, -0.02, 0.1), r(0.06))).unwrap();
        c.add_volume(body(2), SweptSphere::capsule(v3(0.05, 0.0, 0.0), v3(0.25, 0.0, 0.0), r(0.04))).unwrap();
        let plate = SweptSphere::swept_triangle(v3(0.0, -0.1, 0.0), v3(0.2, 0.1, 0.0), v3(0.0, 0.1, 0.0), r(0.02));
        c.add_volume(body(3), plate).unwrap();
        let floor =
            SweptSphere::swept_triangle(v3(-5.0, -5.0, -0.2), v3(10.0, -5.0, -0.2), v3(-5.0, 10.0, -0.2), r(0.0));
        c.add_volume(None, floor).unwrap();
        c.add_volume(
            None,
            SweptSphere::swept_triangle(v3(0.3, -1.0, -0.2), v3(0.3, 1.0, -0.2), v3(0.3, 0.0, 1.0), r(0.01)),
        )
        .unwrap();
        c.add_volume(None, SweptSphere::sphere(v3(0.4, 0.3, 0.5), r(0.1))).unwrap();
        c.try_build(robot, &[]).unwrap()
    }

    /// The broad phase as a plain per-pair evaluation: the bounding-sphere gap, then each
    /// triangle's slab, each test on its own, else the exact proximity.
    fn reference<T: RealField + Copy>(
        cm: &CollisionModel<T, 8, 28>,
        cd: &CollisionData<T, 8, 28>,
    ) -> std::vec::Vec<Proximity<T>> {
        let mut out = std::vec::Vec::new();
        for pair in cm.pairs() {
            let (a, b) = (&cd.world_volumes[pair.first.0], &cd.world_volumes[pair.second.0]);
            let ((ca, ra), (cb, rb)) = (cd.bounding_spheres[pair.first.0], cd.bounding_spheres[pair.second.0]);
            let culled = |distance| Proximity { distance, core_first: ca, core_second: cb, direction: None };
            let mut result = None;
            if let Some(limit) = cd.exact_within {
                let (separation2, reach) = ((ca - cb).norm_squared(), limit + ra + rb);
                if reach <= T::zero() || separation2 > reach * reach {
                    let gap = sqrt(separation2) - ra - rb;
                    if gap > limit {
                        result = Some(culled(gap));
                    }
                }
                for (volume, center, ball) in [(a, cb, rb), (b, ca, ra)] {
                    let needed = limit + volume.radius + ball;
                    let frame = volume.core.triangle_frame();
                    let slab = if let Core::Triangle(_) = volume.core {
                        (needed > T::zero() && separation2 > needed * needed)
                            .then(|| frame.slab_gap(volume.radius, &center, ball, limit))
                            .flatten()
                    } else {
                        None
                    };
                    result = result.or(slab.map(culled));
                }
            }
            out.push(result.unwrap_or_else(|| proximity(a, b)));
        }
        out
    }

    /// `compute_distances` (squared bounding-sphere test first, triangle frames shared by all
    /// pairs of a volume) equals the plain per-pair broad phase bit for bit at random states (touching,
    /// penetrating and distant volumes, a wall perpendicular and a floor parallel to other
    /// triangles) for negative, zero, small and large cull distances and without one; both
    /// kinds of cull and exact pairs occur.
    fn broad_phase_matches_the_plain_evaluation<T: RealField + Copy>() {
        let robot = branched::<T>();
        let cm = model(&robot);
        let mut cd = CollisionData::new(&cm);
        let mut data = Data::new(&robot);
        let (mut exact, mut culled, mut touching) = (0, 0, 0);
        for seed in 0..200 {
            forward_kinematics(&robot, &mut data, &state(seed, 1.5).cast::<T>(), &SVector::zeros()).unwrap();
            for limit in [None, Some(-0.05), Some(0.0), Some(0.02), Some(0.1), Some(0.4), Some(10.0)] {
                cd.exact_within = limit.map(convert::<f64, T>);
                cm.update(&data, &mut cd);
                let plain = reference(&cm, &cd);
                for (fast, plain) in cd.proximities.iter().zip(&plain) {
                    assert_eq!(fast, plain, "seed {seed}, limit {limit:?}");
                    exact += usize::from(fast.direction.is_some());
                    culled += usize::from(fast.direction.is_none() && fast.distance > T::zero());
                    touching += usize::from(fast.distance <= T::zero());
                }
            }
        }
        assert!(exact > 5000 && culled > 5000 && touching > 500, "{exact} exact, {culled} culled, {touching} touching");
    }

    /// The broad phase without its per-pair tests ([`centres_within`]) equals the plain
    /// per-pair evaluation bit for bit at cull distances around the largest centre separation:
    /// at random states, `d` at the computed box diagonal `D` and one, two and 64 ulps-ish
    /// steps (`D (1 ± k ε)`) on either side, and at the largest pair separation itself; the
    /// shortcut is taken and not taken, and the box never claims a pair farther apart than
    /// `d` (every pair's squared separation is at most `d²` when it is taken).
    fn shortcut_matches_the_plain_evaluation_at_its_threshold<T: RealField + Copy>() {
        let robot = branched::<T>();
        let cm = model(&robot);
        let mut cd = CollisionData::new(&cm);
        let mut data = Data::new(&robot);
        let (mut taken, mut not_taken) = (0, 0);
        for seed in 0..200 {
            forward_kinematics(&robot, &mut data, &state(seed, 1.5).cast::<T>(), &SVector::zeros()).unwrap();
            cd.exact_within = None;
            cm.update(&data, &mut cd);
            let centres = cd.bounding_spheres;
            let mut widest = T::zero();
            for (a, _) in &centres {
                for (b, _) in &centres {
                    widest = widest.max((a - b).norm_squared());
                }
            }
            let (lo, hi) = centres.iter().fold((centres[0].0, centres[0].0), |(lo, hi), (c, _)| (lo.inf(c), hi.sup(c)));
            let diagonal = sqrt((hi - lo).norm_squared());
            let eps = T::default_epsilon();
            let mut limits = std::vec![sqrt(widest)];
            for k in [0.0, 1.0, 2.0, 64.0, -1.0, -2.0, -64.0] {
                limits.push(diagonal * (T::one() + convert::<f64, T>(k) * eps));
            }
            for limit in limits {
                let within = centres_within(&centres, limit);
                if within {
                    taken += 1;
                    assert!(widest <= limit * limit, "seed {seed}: {widest} beyond {limit}");
                } else {
                    not_taken += 1;
                }
                cd.exact_within = Some(limit);
                cm.compute_distances(&mut cd);
                let plain = reference(&cm, &cd);
                for (fast, plain) in cd.proximities.iter().zip(&plain) {
                    assert_eq!(fast, plain, "seed {seed}, limit {limit}");
                }
            }
        }
        assert!(taken > 400 && not_taken > 400, "{taken} taken, {not_taken} not");
    }

    #[test]
    fn shortcut_matches_the_plain_evaluation_at_its_threshold_f64() {
        shortcut_matches_the_plain_evaluation_at_its_threshold::<f64>();
    }

    #[test]
    fn shortcut_matches_the_plain_evaluation_at_its_threshold_f32() {
        shortcut_matches_the_plain_evaluation_at_its_threshold::<f32>();
    }

    #[test]
    fn broad_phase_matches_the_plain_evaluation_f64() {
        broad_phase_matches_the_plain_evaluation::<f64>();
    }

    #[test]
    fn broad_phase_matches_the_plain_evaluation_f32() {
        broad_phase_matches_the_plain_evaluation::<f32>();
    }
}
