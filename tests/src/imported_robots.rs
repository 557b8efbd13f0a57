//! Robots imported by `host-sim import` (`fixtures/robots/`): the checked-in files are what
//! the import writes today, the model is the URDF's with the off-chain joints frozen, and the
//! collision volumes contain the URDF's collision primitives. The Panda's dynamics against
//! Pinocchio: `dynamics::pinocchio::imported_panda_matches_pinocchio`.
//!
//! After changing the import or a robot's URDF, re-run the command in the robot's `README.md`
//! (or `UPDATE_GENERATED=1 cargo test -p thesis-tests imported_files`).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "test code")]

use std::path::PathBuf;

use fixtures::robots::panda;
use host_sim::import::collision::primitive_points;
use host_sim::import::{generate, robots_index, ImportOptions, ROBOTS_DIR};
use kernel::tasks::collision::SweptSphere;
use nalgebra::Vector3;

fn repository() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The import of the Panda as its README states it.
fn panda_import() -> ImportOptions {
    ImportOptions {
        root: repository(),
        urdf: "fixtures/urdf/panda.urdf".to_owned(),
        name: "panda".to_owned(),
        tcps: vec!["panda_hand_tcp".to_owned()],
        planar_base: false,
        package_path: Some("fixtures/urdf/packages".to_owned()),
    }
}

#[test]
fn imported_files_are_up_to_date() {
    let options = panda_import();
    for (name, generated) in generate(&options).unwrap() {
        let path = options.directory().join(&name);
        if std::env::var("UPDATE_GENERATED").is_ok_and(|v| v == "1") {
            std::fs::write(&path, &generated).unwrap();
            continue;
        }
        let checked_in = std::fs::read_to_string(&path).unwrap_or_default();
        assert!(
            checked_in == generated,
            "{} is out of date; regenerate with:\n    {}",
            path.display(),
            options.command()
        );
    }
    let index = std::fs::read_to_string(repository().join(ROBOTS_DIR).join("mod.rs")).unwrap();
    assert_eq!(index, robots_index(&repository().join(ROBOTS_DIR)).unwrap());
}

#[test]
fn the_panda_controls_its_arm_and_freezes_its_fingers() {
    assert_eq!(panda::N, 7);
    assert_eq!(
        panda::JOINT_NAMES,
        [
            "panda_joint1",
            "panda_joint2",
            "panda_joint3",
            "panda_joint4",
            "panda_joint5",
            "panda_joint6",
            "panda_joint7"
        ]
    );
    assert_eq!(panda::FROZEN_JOINTS, ["panda_finger_joint1", "panda_finger_joint2"]);
    assert_eq!(panda::TCPS, [panda::PANDA_HAND_TCP]);
    let model = panda::model::<f64>().unwrap();
    // 18.4 kg in the URDF; the root link's 0.63 kg is welded to the world.
    let urdf_mass =
        0.629769 + 4.970684 + 0.646926 + 3.228604 + 3.587895 + 1.225946 + 1.666555 + 0.735522 + 0.73 + 2.0 * 0.015;
    assert!((model.total_mass() - (urdf_mass - 0.629769)).abs() < 1e-12, "{}", model.total_mass());
    // The fingers hang from the last body.
    assert_eq!(model.frames()[panda::PANDA_LEFTFINGER.0].parent, model.frames()[panda::PANDA_HAND_TCP.0].parent);
    assert!(panda::model::<f32>().is_ok());
}

/// The volumes of one link parsed from the collision file (the file format of
/// `fixtures/collision/justin.collision`).
fn volumes_of(file: &str, link: &str) -> Vec<SweptSphere<f64>> {
    file.lines()
        .filter_map(|line| {
            let fields: Vec<&str> = line.split_whitespace().collect();
            if fields.len() < 5 || fields[3] != link {
                return None;
            }
            let numbers: Vec<f64> = fields[4..].iter().map(|x| x.parse().unwrap()).collect();
            let p = |k: usize| Vector3::new(numbers[1 + 3 * k], numbers[2 + 3 * k], numbers[3 + 3 * k]);
            match fields[0] {
                "sphere" => Some(SweptSphere::sphere(p(0), numbers[0])),
                "capsule" => Some(SweptSphere::capsule(p(0), p(1), numbers[0])),
                "triangle" => Some(SweptSphere::swept_triangle(p(0), p(1), p(2), numbers[0])),
                _ => None,
            }
        })
        .collect()
}

#[test]
fn the_collision_volumes_contain_the_urdf_primitives() {
    let options = panda_import();
    let file = std::fs::read_to_string(options.directory().join("panda.collision")).unwrap();
    let urdf = std::fs::read_to_string(repository().join(&options.urdf)).unwrap();
    let packages = repository().join("fixtures/urdf/packages");
    let primitives = primitive_points(&urdf, Some(&packages)).unwrap();
    assert_eq!(primitives.len(), 17, "9 meshes (links 0 to 7, hand) and 2 x 4 finger boxes");
    let mut worst = f64::NEG_INFINITY;
    let mut points = 0;
    for (link, surface) in &primitives {
        let volumes = volumes_of(&file, link);
        assert!(!volumes.is_empty(), "no volume on link {link}");
        for p in surface {
            let inside = volumes.iter().map(|v| v.signed_distance_to(p)).fold(f64::INFINITY, f64::min);
            worst = worst.max(inside);
            points += 1;
        }
    }
    println!("{points} primitive points, largest signed distance to the volumes {worst:.2e} m");
    assert!(points > 1000);
    assert!(worst <= 1e-12, "a point of a collision primitive lies {worst} m outside its volumes");
}
