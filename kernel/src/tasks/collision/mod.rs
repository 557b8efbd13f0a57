//! Self-collision and environment-collision avoidance (Sec. 3.1, (3.2)–(3.24)).
//!
//! Three layers, each in its own file:
//! 1. [`volumes`]: swept-sphere volumes (spheres, capsules, spheres swept over triangles) and
//!    the exact distance and closest points of any two of them.
//! 2. [`model`]: the collision model — volumes attached to bodies or fixed in the world
//!    (environment: floor, table, wall), the enabled pairs (pairs that cannot collide are
//!    excluded once, when the model is built) — and its per-cycle world update.
//! 3. [`pair`]: per pair, the Jacobians of the closest points along the collision direction
//!    (3.18), the reflected masses (3.20), the C² potential (3.8) and force (3.10), the damping
//!    by double diagonalisation (3.21)–(3.23), and one task row whose torque is the pair's
//!    share of (3.24).
//!
//! One cycle:
//! ```
//! use kernel::dynamics::{crba, forward_kinematics, mass_matrix_cholesky};
//! use kernel::model::{Data, Inertia, JointDrive, JointKind, ModelBuilder, Placement};
//! use kernel::tasks::collision::{self_collision_rows, CollisionData, CollisionModelBuilder,
//!     CollisionParameters, SweptSphere};
//! use kernel::tasks::TaskRows;
//! use nalgebra::{SVector, Unit, Vector3};
//! // A 2 kg slider on x carrying a 0.1 m sphere; a world-fixed 0.1 m sphere at x = 0.3 m.
//! let mut b = ModelBuilder::<f64, 1, 1, 1>::new(Vector3::zeros());
//! let slider = b.add_body(None, Placement::identity(),
//!     JointKind::Prismatic { axis: Unit::new_normalize(Vector3::x()) }, JointDrive::actuated(0),
//!     Inertia::point_mass(2.0, Vector3::zeros())).unwrap();
//! let robot = b.try_build().unwrap();
//! let mut c = CollisionModelBuilder::<f64, 2, 1>::new();
//! c.add_volume(Some(slider), SweptSphere::sphere(Vector3::zeros(), 0.1)).unwrap();
//! c.add_volume(None, SweptSphere::sphere(Vector3::new(0.3, 0.0, 0.0), 0.1)).unwrap();
//! let collision_model = c.try_build(&robot, &[]).unwrap();
//! let mut collision = CollisionData::new(&collision_model);
//! let mut data = Data::new(&robot);
//! forward_kinematics(&robot, &mut data, &SVector::zeros(), &SVector::zeros()).unwrap();
//! crba(&robot, &mut data);
//! let factor = mass_matrix_cholesky(&data).unwrap();
//! // Table 3.1: F_max = 25 N, d0 = 0.15 m.
//! let parameters = CollisionParameters::try_new(25.0, 0.15, 0.7, 0.0, 0.15).unwrap();
//! let mut rows = TaskRows::<f64, 1, 4>::new();
//! self_collision_rows(&collision_model, &mut collision, &robot, &data, &factor, &parameters,
//!     &mut rows).unwrap();
//! // d = 0.1 m: F = 25 (0.05/0.15)² N pushes the slider back (−x).
//! assert!((rows.torque()[0] + 25.0 / 9.0).abs() < 1e-12);
//! ```

pub mod model;
pub mod pair;
pub mod volumes;

pub use model::{
    exclusion_rule, CollisionData, CollisionError, CollisionModel, CollisionModelBuilder, CollisionPair, Exclusion,
    Volume, VolumeId,
};
pub use pair::{
    collision_rows_from_geometry, collision_rows_shared, evaluate_pair, factor_rows, inverse_reflected_mass,
    inverse_reflected_masses, pair_damping, self_collision_rows, CollisionParameters, CollisionReport, PairEvaluation,
    PairRowCache,
};
pub use volumes::{closest_points, proximity, Core, Proximity, SweptSphere};
