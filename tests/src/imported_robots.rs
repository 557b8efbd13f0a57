//! Robots imported by `host-sim import` (`fixtures/robots/`): the checked-in files are what
//! the import writes today, the model is the URDF's with the off-chain joints frozen, and the
//! collision volumes of each body contain the URDF's collision primitives on it, for the Panda and
//! TIAGo++. Their dynamics against Pinocchio: `dynamics::pinocchio::imported_panda_matches_pinocchio` and
//! `imported_tiago_dual_matches_pinocchio`.
//!
//! After changing the import or a robot's URDF, re-run the command in the robot's `README.md`
//! (or `UPDATE_GENERATED=1 cargo test -p thesis-tests imported_files`).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "test code")]

use std::path::PathBuf;

use fixtures::robots::{panda, tiago_dual};
use host_sim::import::collision::primitive_points;
use host_sim::import::layout::derive_file;
use host_sim::import::{collision_model, generate, robots_index, ImportOptions, ROBOTS_DIR};
use kernel::model::Frame;
use kernel::tasks::collision::{CollisionModel, Core, SweptSphere};
use kernel::BodyId;
use nalgebra::{Point3, RealField, Vector3};

fn repository() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The fixed-base import of `name` from `fixtures/urdf/<name>.urdf` with the vendored meshes, as
/// the robot's README states it.
fn import(name: &str, tcps: &[&str], scenario_home: &[f64]) -> ImportOptions {
    ImportOptions {
        root: repository(),
        urdf: format!("fixtures/urdf/{name}.urdf"),
        name: name.to_owned(),
        tcps: tcps.iter().map(|t| (*t).to_owned()).collect(),
        planar_base: false,
        package_path: Some("fixtures/urdf/packages".to_owned()),
        home: None,
        scenario_home: Some(scenario_home.to_vec()),
    }
}

fn panda_import() -> ImportOptions {
    import("panda", &["panda_hand_tcp"], &[0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
}

/// TIAGo++ with the grasping frames of its Hey5 hands as TCPs: with the hands frozen, the point
/// between the fingers the hand grasps at (0.13 m ahead of the wrist's tool flange
/// `arm_*_tool_link`), as `panda_hand_tcp` is the Panda's.
fn tiago_dual_import() -> ImportOptions {
    import(
        "tiago_dual",
        &["hand_left_grasping_frame", "hand_right_grasping_frame"],
        &[0.15, 0.4, 0.3, 0.0, 1.5, 0.0, 0.5, 0.0, 0.4, 0.3, 0.0, 1.5, 0.0, 0.5, 0.0],
    )
}

#[test]
fn imported_files_are_up_to_date() {
    for options in [panda_import(), tiago_dual_import()] {
        check_files(&options);
    }
    let index = std::fs::read_to_string(repository().join(ROBOTS_DIR).join("mod.rs")).unwrap();
    assert_eq!(index, robots_index(&repository().join(ROBOTS_DIR)).unwrap());
}

/// The checked-in files of an import are what it generates today.
fn check_files(options: &ImportOptions) {
    for (name, generated) in generate(options).unwrap() {
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

#[test]
fn tiago_dual_controls_its_torso_lift_and_arms_and_freezes_the_rest() {
    assert_eq!(tiago_dual::N, 15);
    let arm = |side: &'static str| (1..=7).map(move |k| format!("arm_{side}_{k}_joint"));
    let controlled: Vec<String> =
        std::iter::once("torso_lift_joint".to_owned()).chain(arm("left")).chain(arm("right")).collect();
    assert_eq!(tiago_dual::JOINT_NAMES.to_vec(), controlled);
    // 129 joints: 28 fixed, 15 controlled, 86 frozen (head 2, wheels and suspensions 4, casters 8,
    // hands 2 x 36).
    assert_eq!(tiago_dual::FROZEN_JOINTS.len(), 86);
    let frozen = |prefix: &str| tiago_dual::FROZEN_JOINTS.iter().filter(|j| j.starts_with(prefix)).count();
    assert_eq!([frozen("head_"), frozen("wheel_") + frozen("suspension_"), frozen("caster_")], [2, 4, 8]);
    assert_eq!([frozen("hand_left_"), frozen("hand_right_")], [36, 36]);
    assert_eq!(tiago_dual::TCPS, [tiago_dual::HAND_LEFT_GRASPING_FRAME, tiago_dual::HAND_RIGHT_GRASPING_FRAME]);
    let model = tiago_dual::model::<f64>().unwrap();
    // The URDF's 98.05 kg less the base, wheels, casters and fixed torso column welded to the world:
    // what Pinocchio's model with the same joints locked moves (`fixtures/pinocchio/tiago_dual.json`).
    assert!((model.total_mass() - 31.280055).abs() < 1e-9, "{}", model.total_mass());
    // The frozen hand hangs from the last arm body; the frozen head from the torso lift.
    let parent = |frame: kernel::FrameId| model.frames()[frame.0].parent;
    assert_eq!(parent(tiago_dual::HAND_LEFT_INDEX_FLEX_3_LINK), parent(tiago_dual::ARM_LEFT_7_LINK));
    assert_eq!(parent(tiago_dual::HEAD_2_LINK), parent(tiago_dual::TORSO_LIFT_LINK));
    // `arm_*_1_link` sits on the triangle inequality's edge (margin 1.5e-12 kg m²): physical in
    // f32 too, within the scalar's rounding.
    assert!(tiago_dual::model::<f32>().is_ok());
}

/// The `no_std` constructors `fixtures::robots::<name>::collision::collision_model` (compiled from
/// the `.collision` files by `fixtures/build.rs`) build the import's fit: every volume on its body
/// with its end points and radius (the file's 0.1 mm resolution, to the scalar's rounding), and
/// exactly the pairs the survey and the kernel's rules leave, in f64 and f32.
#[test]
fn the_collision_constructors_build_the_imports_fit() {
    let fit = collision_model(&panda_import()).unwrap();
    assert_eq!((fit.volumes.len(), fit.pairs.len()), (21, 80));
    let build = |model| panda::collision::collision_model(&model).unwrap();
    equals_the_fit(&fit, &build(panda::model::<f64>().unwrap()), 1e-12);
    equals_the_fit(&fit, &panda::collision::collision_model(&panda::model::<f32>().unwrap()).unwrap(), 2e-6);
    let fit = collision_model(&tiago_dual_import()).unwrap();
    assert_eq!((fit.volumes.len(), fit.pairs.len()), (35, 340));
    let tiago = |model| tiago_dual::collision::collision_model(&model).unwrap();
    equals_the_fit(&fit, &tiago(tiago_dual::model::<f64>().unwrap()), 1e-12);
    equals_the_fit(&fit, &tiago_dual::collision::collision_model(&tiago_dual::model::<f32>().unwrap()).unwrap(), 2e-6);
}

/// `built` has the volumes (bodies, points and radii within `tolerance`, m) and pairs of `fit`.
fn equals_the_fit<T, const V: usize, const P: usize>(
    fit: &host_sim::import::collision::Imported,
    built: &CollisionModel<T, V, P>,
    tolerance: f64,
) where
    T: RealField + Copy + Into<f64>,
{
    assert_eq!(built.volumes().len(), fit.volumes.len());
    for ((volume, (body, shape)), name) in built.volumes().iter().zip(&fit.volumes).zip(&fit.names) {
        assert_eq!(volume.body.map(|b| b.0), *body, "{name}");
        assert!((volume.shape.radius.into() - shape.radius).abs() <= tolerance, "{name}");
        let corners = |core: &Core<f64>| match core {
            Core::Point(p) => vec![*p],
            Core::Segment(points) => points.to_vec(),
            Core::Triangle(points) => points.to_vec(),
        };
        let built_core = match &volume.shape.core {
            Core::Point(p) => Core::Point(p.map(Into::into)),
            Core::Segment([a, b]) => Core::Segment([a.map(Into::into), b.map(Into::into)]),
            Core::Triangle([a, b, c]) => Core::Triangle([a.map(Into::into), b.map(Into::into), c.map(Into::into)]),
        };
        let (expected, got) = (corners(&shape.core), corners(&built_core));
        assert_eq!(expected.len(), got.len(), "{name}: another shape");
        for (e, g) in expected.iter().zip(&got) {
            assert!((e - g).amax() <= tolerance, "{name}: {g} != {e}");
        }
    }
    let pairs: Vec<(usize, usize)> = built.pairs().iter().map(|p| (p.first.0, p.second.0)).collect();
    assert_eq!(pairs, fit.pairs);
    assert_eq!(pairs.len(), P, "the capacity is the enabled pairs");
}

/// The volumes of the collision file (the file format of `fixtures/collision/justin.collision`),
/// each with its link, in the link's frame.
fn volumes(file: &str) -> Vec<(String, SweptSphere<f64>)> {
    file.lines()
        .filter_map(|line| {
            let fields: Vec<&str> = line.split_whitespace().collect();
            if fields.len() < 5 || !["sphere", "capsule", "triangle"].contains(&fields[0]) {
                return None;
            }
            let numbers: Vec<f64> = fields[4..].iter().map(|x| x.parse().unwrap()).collect();
            let p = |k: usize| Vector3::new(numbers[1 + 3 * k], numbers[2 + 3 * k], numbers[3 + 3 * k]);
            let shape = match fields[0] {
                "sphere" => SweptSphere::sphere(p(0), numbers[0]),
                "capsule" => SweptSphere::capsule(p(0), p(1), numbers[0]),
                "triangle" => SweptSphere::swept_triangle(p(0), p(1), p(2), numbers[0]),
                _ => return None,
            };
            Some((fields[3].to_owned(), shape))
        })
        .collect()
}

#[test]
fn the_collision_volumes_contain_the_urdf_primitives() {
    // Panda: 9 meshes (links 0 to 7, hand) and 2 x 4 finger boxes.
    let panda_model = panda::model::<f64>().unwrap();
    contains_the_primitives(&panda_import(), 17, panda_model.frames(), &panda::FRAME_NAMES);
    // TIAGo++: 59 meshes (base, torso 4, head 2, arms 2 x 6, hands 2 x 20), 33 boxes (torso 3,
    // hands 2 x 15), 12 spheres, 8 cylinders.
    let tiago_model = tiago_dual::model::<f64>().unwrap();
    contains_the_primitives(&tiago_dual_import(), 112, tiago_model.frames(), &tiago_dual::FRAME_NAMES);
}

/// Every point of every `<collision>` primitive of the robot (`count` of them) lies in the
/// volumes of its body (the import drops a volume inside another one of the same body); `frames`
/// and `names` are the generated model's frames and their links.
fn contains_the_primitives(options: &ImportOptions, count: usize, frames: &[Frame<f64>], names: &[&str]) {
    let frame_of = |link: &str| &frames[names.iter().position(|n| *n == link).unwrap()];
    let file = std::fs::read_to_string(options.directory().join(format!("{}.collision", options.name))).unwrap();
    let volumes: Vec<(Option<BodyId>, SweptSphere<f64>)> = volumes(&file)
        .iter()
        .map(|(link, shape)| (frame_of(link).parent, shape.transformed(&frame_of(link).placement)))
        .collect();
    let urdf = std::fs::read_to_string(repository().join(&options.urdf)).unwrap();
    let packages = repository().join("fixtures/urdf/packages");
    let primitives = primitive_points(&urdf, Some(&packages)).unwrap();
    assert_eq!(primitives.len(), count, "{}", options.name);
    let mut worst = f64::NEG_INFINITY;
    let mut points = 0;
    for (link, surface) in &primitives {
        let frame = frame_of(link);
        let body: Vec<&SweptSphere<f64>> = volumes.iter().filter(|(b, _)| *b == frame.parent).map(|(_, v)| v).collect();
        assert!(!body.is_empty(), "no volume on the body of link {link}");
        for p in surface {
            let p = (frame.placement * Point3::from(*p)).coords;
            let inside = body.iter().map(|v| v.signed_distance_to(&p)).fold(f64::INFINITY, f64::min);
            worst = worst.max(inside);
            points += 1;
        }
    }
    println!("{}: {points} primitive points, largest signed distance to the volumes {worst:.2e} m", options.name);
    assert!(points > 1000);
    assert!(worst <= 1e-12, "a point of a collision primitive lies {worst} m outside its volumes");
}

/// The import's layout rule (`host_sim::import::layout`) applied to Justin's URDF and TCPs gives
/// the layout Justin's controller is written with: platform 0..3, torso 3..6, right arm 6..13,
/// left arm 13..20.
#[test]
fn the_derived_layout_of_justin_is_its_controllers() {
    use fixtures::justin;
    let tcps = [justin::FRAME_NAMES[justin::RIGHT_TCP.0], justin::FRAME_NAMES[justin::LEFT_TCP.0]];
    let tcps: Vec<String> = tcps.iter().map(|t| (*t).to_owned()).collect();
    let derived = derive_file(&repository().join("fixtures/urdf/justin.urdf"), &tcps, true).unwrap();
    let expected = justin::whole_body::controller_config::<f64>().unwrap().layout;
    let arms: Vec<Vec<bool>> = expected.arms.iter().map(|arm| arm.to_vec()).collect();
    assert_eq!(derived.arms, arms);
    assert_eq!(derived.torso, expected.torso.map(|torso| torso.to_vec()));
    assert_eq!(derived.torso.as_ref().map(|t| t.iter().filter(|c| **c).count()), Some(3));
    let platform: Vec<bool> = (0..justin::N).map(|k| expected.platform.is_platform(k)).collect();
    assert_eq!(platform[..3], [true; 3]);
    assert!(derived.planar_base && !platform[3..].contains(&true));
}

/// The generated `layout()` of the imported robots: the Panda one arm of all 7 coordinates, no
/// torso; TIAGo++ the lift as torso and two arms of 7.
#[test]
fn imported_layouts_follow_the_chains() {
    let panda = panda::layout().unwrap();
    assert_eq!((panda.arms, panda.torso, panda.tcp), ([[true; 7]], None, panda::TCPS));
    let tiago = tiago_dual::layout().unwrap();
    let torso: Vec<&str> =
        (0..tiago_dual::N).filter(|k| tiago.torso.is_some_and(|t| t[*k])).map(|k| tiago_dual::JOINT_NAMES[k]).collect();
    assert_eq!(torso, ["torso_lift_joint"]);
    for (arm, side) in tiago.arms.iter().zip(["left", "right"]) {
        let joints: Vec<&str> = (0..tiago_dual::N).filter(|k| arm[*k]).map(|k| tiago_dual::JOINT_NAMES[k]).collect();
        assert_eq!(joints.len(), 7, "{side}: {joints:?}");
        assert!(joints.iter().all(|joint| joint.starts_with(&format!("arm_{side}_"))), "{joints:?}");
    }
    assert!(tiago.platform.axes().iter().all(|axis| axis.coordinate().is_none()));
}

/// The import's default configuration is compiled in (`fixtures/build.rs`) with the rule of
/// `host_sim::import::config`: joint stiffness `ω_j² M_kk` and damping `2 ξ ω_j M_kk` (their ratio
/// `2 ξ / ω_j`), torque rate 100 times the effort limit per second; the parts are the layout's
/// (no platform or torso values on the Panda).
#[test]
fn imported_configurations_follow_the_default_rule() {
    use fixtures::robots::panda::config as panda_config;
    use host_sim::import::config::{DAMPING_RATIO, JOINT_FREQUENCY_RAD_S};
    let effort = panda::model::<f64>().unwrap().limits.effort;
    assert_eq!(panda_config::robot::ARMS, ["arm_0"]);
    assert_eq!(panda_config::robot::ARM_JOINTS, 7);
    assert_eq!((panda_config::robot::TORSO, panda_config::robot::PLATFORM), (false, false));
    for (damping, stiffness) in panda_config::joint::damping::ARM.iter().zip(panda_config::joint::stiffness::ARM) {
        let ratio = 2.0 * DAMPING_RATIO / JOINT_FREQUENCY_RAD_S;
        assert!((damping / stiffness - ratio).abs() < 1e-12 * ratio, "{damping} / {stiffness}");
    }
    let torque_rate: Vec<f64> = effort.iter().map(|e| 100.0 * e).collect();
    assert_eq!(panda_config::output_limits::torque_rate::ARM.to_vec(), torque_rate);
    use fixtures::robots::tiago_dual::config as tiago_config;
    assert_eq!(tiago_config::robot::ARMS, ["arm_0", "arm_1"]);
    assert_eq!((tiago_config::robot::TORSO, tiago_config::robot::PLATFORM), (true, false));
    assert_eq!(tiago_config::hierarchy::fig_6_3::LEVELS.len(), 8);
}
