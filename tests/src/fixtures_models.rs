//! The generated `no_std` Justin constructor against its source of truth, the URDF.
//!
//! 1. `host_sim::codegen` regenerates `fixtures/src/justin/generated.rs` from
//!    `fixtures/urdf/justin.urdf`; the checked-in file must be identical. After editing the URDF
//!    run `UPDATE_GENERATED=1 cargo test -p thesis-tests fixtures_models` to rewrite it.
//! 2. The generated model and the URDF-loaded model give the same `M(q)`, `g(q)` and right-TCP
//!    Jacobian (and frame placements) at random states within the joint limits.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "test code")]

use std::path::PathBuf;

use crate::support::Rng;

use fixtures::justin;
use host_sim::codegen;
use host_sim::urdf::{self, Coupling};
use kernel::dynamics::{crba, forward_kinematics, frame_jacobian, gravity};
use kernel::{Data, Model};
use nalgebra::{SMatrix, SVector};

fn repository_path(relative: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join(relative)
}

#[test]
fn generated_justin_constructor_is_up_to_date() {
    let source = codegen::justin_source(&repository_path(codegen::JUSTIN_URDF)).unwrap();
    let path = repository_path(codegen::JUSTIN_GENERATED);
    if std::env::var("UPDATE_GENERATED").is_ok_and(|v| v == "1") {
        std::fs::write(&path, &source).unwrap();
        println!("rewrote {}", path.display());
        return;
    }
    let checked_in = std::fs::read_to_string(&path).unwrap_or_default();
    if checked_in != source {
        let first_difference = checked_in
            .lines()
            .zip(source.lines())
            .position(|(a, b)| a != b)
            .map_or_else(|| "length differs".to_owned(), |i| format!("first difference at line {}", i + 1));
        panic!(
            "{} is out of date with {} ({first_difference}).\nRegenerate it with:\n    {}",
            codegen::JUSTIN_GENERATED,
            codegen::JUSTIN_URDF,
            codegen::REGENERATE_COMMAND
        );
    }
}

type Justin = Model<f64, { justin::N }, { justin::BODIES }, { justin::FRAMES }>;

fn random_state(model: &Justin, rng: &mut Rng) -> SVector<f64, { justin::N }> {
    SVector::from_fn(|k, _| {
        let (lower, upper) = (model.limits.position_lower[k], model.limits.position_upper[k]);
        if lower.is_finite() && upper.is_finite() && upper - lower < 10.0 {
            rng.uniform(lower, upper)
        } else {
            rng.uniform(-3.0, 3.0)
        }
    })
}

#[test]
fn generated_and_loaded_justin_agree() {
    let loaded = urdf::load::<{ justin::N }, { justin::BODIES }, { justin::FRAMES }>(
        &repository_path(codegen::JUSTIN_URDF),
        Coupling::Coupled,
    )
    .unwrap();
    let generated = justin::model::<f64>().unwrap();
    assert_eq!(loaded.joint_names, justin::JOINT_NAMES);
    assert_eq!(loaded.frame_names, justin::FRAME_NAMES);
    assert_eq!(loaded.body_names, justin::BODY_NAMES);
    assert_eq!(loaded.frame("right_tcp"), Some(justin::RIGHT_TCP));
    assert_eq!(generated.limits, loaded.model.limits);
    assert_eq!(generated.gravity, loaded.model.gravity);

    let (a, b) = (&generated, &loaded.model);
    let (mut da, mut db) = (Data::new(a), Data::new(b));
    let (mut ja, mut jb) = (SMatrix::<f64, 6, { justin::N }>::zeros(), SMatrix::zeros());
    let mut rng = Rng(0x5eed_1234_abcd_0001);
    for _ in 0..16 {
        let q = random_state(a, &mut rng);
        let v = SVector::from_fn(|_, _| rng.uniform(-1.0, 1.0));
        forward_kinematics(a, &mut da, &q, &v).unwrap();
        forward_kinematics(b, &mut db, &q, &v).unwrap();
        assert!((crba(a, &mut da) - crba(b, &mut db)).amax() <= 1e-12);
        assert!((gravity(a, &mut da) - gravity(b, &mut db)).amax() <= 1e-12);
        frame_jacobian(a, &da, justin::RIGHT_TCP, &mut ja).unwrap();
        frame_jacobian(b, &db, justin::RIGHT_TCP, &mut jb).unwrap();
        assert!((ja - jb).amax() <= 1e-12);
        for (pa, pb) in da.frame_placements.iter().zip(db.frame_placements.iter()) {
            assert!((pa.to_homogeneous() - pb.to_homogeneous()).amax() <= 1e-12);
        }
    }
}

#[test]
fn independent_coupling_gives_the_passive_joint_its_own_coordinate() {
    let robot = urdf::load::<21, { justin::BODIES }, { justin::FRAMES }>(
        &repository_path(codegen::JUSTIN_URDF),
        Coupling::Independent,
    )
    .unwrap();
    assert_eq!(robot.coordinate("torso_joint4"), Some(6));
    assert!((robot.model.total_mass() - 195.0).abs() < 1e-9);
}
