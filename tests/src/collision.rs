//! Self-collision avoidance (Sec. 3.1): the Justin collision model against its data file and
//! the URDF, the listed exclusions, torques against the potential's gradient, and the
//! `sca_damping` scenario (Fig. 3.5, Table 3.1).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic,
    reason = "test code: a failure is a test failure"
)]

use std::path::PathBuf;

use crate::support::Rng;

use fixtures::justin::{self, collision as jc};
use kernel::dynamics::{crba, forward_kinematics, mass_matrix_cholesky, TreeFactorization};
use kernel::model::BodyId;
use kernel::tasks::collision::{
    evaluate_pair, exclusion_rule, factor_rows, inverse_reflected_mass, inverse_reflected_masses, proximity,
    self_collision_rows, CollisionData, CollisionModel, CollisionParameters, Volume, VolumeId,
};
use kernel::tasks::TaskRows;
use kernel::{Data, Model};
use nalgebra::{SVector, Translation3, UnitQuaternion, Vector3};

type Justin = Model<f64, { justin::N }, { justin::BODIES }, { justin::FRAMES }>;
type JustinData = Data<f64, { justin::N }, { justin::BODIES }, { justin::FRAMES }>;
const N: usize = justin::N;

/// Coordinates that change the relative pose of two bodies: those driving the joints on one
/// body's path to the root but not on the other's. For a world-fixed volume (the floor) the
/// platform's planar coordinates are left out: they do not change heights.
fn relevant_coordinates(model: &Justin, a: Option<BodyId>, b: Option<BodyId>) -> Vec<usize> {
    let path =
        |x: Option<BodyId>| -> Vec<usize> { x.map(|id| model.support(id).map(|s| s.0).collect()).unwrap_or_default() };
    let (pa, pb) = (path(a), path(b));
    let mut coordinates: Vec<usize> = pa
        .iter()
        .filter(|j| !pb.contains(j))
        .chain(pb.iter().filter(|j| !pa.contains(j)))
        .flat_map(|&j| model.bodies()[j].drive.terms().iter().map(|t| t.coordinate).collect::<Vec<_>>())
        .collect();
    if a.is_none() || b.is_none() {
        coordinates.retain(|&c| c >= justin::BASE_DOF);
    }
    coordinates.sort_unstable();
    coordinates.dedup();
    coordinates
}

/// Every grid configuration over `coordinates` (`n` values per coordinate between its limits,
/// the torso's coupled bound `0 ≤ q_t2 + q_t3 ≤ 135°` of Table 3.2 enforced), other
/// coordinates at home.
fn grid(model: &Justin, coordinates: &[usize], n: usize) -> Vec<SVector<f64, N>> {
    let home = justin::home_configuration::<f64>();
    let mut out = vec![home];
    for &c in coordinates {
        let (lo, hi) = (model.limits.position_lower[c], model.limits.position_upper[c]);
        let mut next = Vec::with_capacity(out.len() * n);
        for q in &out {
            for k in 0..n {
                let mut q = *q;
                q[c] = lo + (hi - lo) * k as f64 / (n - 1) as f64;
                next.push(q);
            }
        }
        out = next;
    }
    let (t2, t3) = (justin::TORSO_COORDINATES.start + 1, justin::TORSO_COORDINATES.start + 2);
    let bound = 135f64.to_radians();
    out.retain(|q| (-1e-12..=bound + 1e-12).contains(&(q[t2] + q[t3])));
    out
}

/// Smallest and largest distance of the volume pair over `configurations`.
fn distance_range(
    model: &Justin,
    data: &mut JustinData,
    collision: &jc::JustinCollisionModel<f64>,
    (a, b): (VolumeId, VolumeId),
    configurations: &[SVector<f64, N>],
) -> (f64, f64) {
    let (va, vb) = (collision.volume(a).unwrap(), collision.volume(b).unwrap());
    let mut range = (f64::INFINITY, f64::NEG_INFINITY);
    for q in configurations {
        forward_kinematics(model, data, q, &SVector::zeros()).unwrap();
        let world = |v: &Volume<f64>| match v.body {
            Some(body) => v.shape.transformed(&data.body_placements[body.0]),
            None => v.shape,
        };
        let d = proximity(&world(va), &world(vb)).distance;
        range = (range.0.min(d), range.1.max(d));
    }
    range
}

#[test]
#[ignore = "survey for choosing the exclusions; prints a table"]
fn exclusion_survey() {
    let model = justin::model::<f64>().unwrap();
    let collision = jc::collision_model(&model).unwrap();
    let mut data = Data::new(&model);
    for pair in collision.pairs() {
        let (a, b) = (collision.volume(pair.first).unwrap(), collision.volume(pair.second).unwrap());
        let coordinates = relevant_coordinates(&model, a.body, b.body);
        if coordinates.len() > 7 {
            continue;
        }
        let n = ((150_000f64).powf(1.0 / coordinates.len().max(1) as f64) as usize).clamp(3, 41);
        let configurations = grid(&model, &coordinates, n);
        let (lo, hi) = distance_range(&model, &mut data, &collision, (pair.first, pair.second), &configurations);
        println!(
            "{:>18} {:>18}  coords {:?}  min {lo:+.3}  max {hi:+.3}{}",
            jc::VOLUME_SPECS[pair.first.0].name,
            jc::VOLUME_SPECS[pair.second.0].name,
            coordinates,
            if lo > 0.0 {
                "  NEVER"
            } else if hi < 0.0 {
                "  OVERLAP"
            } else {
                ""
            }
        );
    }
}

fn repository_path(relative: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join(relative)
}

/// One volume line of `fixtures/collision/justin.collision`.
#[derive(Debug, PartialEq)]
struct FileVolume {
    kind: String,
    name: String,
    group: String,
    link: String,
    radius: f64,
    points: Vec<[f64; 3]>,
}

/// Parses the data file: volume lines and `exclude` lines (names and reason).
fn parse_collision_file() -> (Vec<FileVolume>, Vec<(String, String, String)>) {
    let text = std::fs::read_to_string(repository_path("fixtures/collision/justin.collision")).unwrap();
    let (mut volumes, mut excluded) = (Vec::new(), Vec::new());
    for (number, raw) in text.lines().enumerate() {
        let words: Vec<&str> = raw.split('#').next().unwrap().split_whitespace().collect();
        match words.first() {
            None => {}
            Some(&"exclude") => {
                assert_eq!(words.len(), 4, "line {}: {raw}", number + 1);
                excluded.push((words[1].to_owned(), words[2].to_owned(), words[3].to_owned()));
            }
            Some(kind) => {
                let count = match *kind {
                    "sphere" => 1,
                    "capsule" => 2,
                    "triangle" => 3,
                    other => panic!("line {}: unknown kind {other}", number + 1),
                };
                assert_eq!(words.len(), 5 + 3 * count, "line {}: {raw}", number + 1);
                let numbers: Vec<f64> = words[5..].iter().map(|w| w.parse().unwrap()).collect();
                volumes.push(FileVolume {
                    kind: (*kind).to_owned(),
                    name: words[1].to_owned(),
                    group: words[2].to_owned(),
                    link: words[3].to_owned(),
                    radius: words[4].parse().unwrap(),
                    points: numbers.chunks(3).map(|c| [c[0], c[1], c[2]]).collect(),
                });
            }
        }
    }
    (volumes, excluded)
}

#[test]
fn data_file_matches_the_constructor() {
    let (volumes, excluded) = parse_collision_file();
    assert_eq!(volumes.len(), jc::VOLUMES);
    for (file, spec) in volumes.iter().zip(jc::VOLUME_SPECS.iter()) {
        let (kind, points): (&str, Vec<[f64; 3]>) = match spec.shape {
            jc::Shape::Sphere(c) => ("sphere", vec![c]),
            jc::Shape::Capsule(p) => ("capsule", p.to_vec()),
            jc::Shape::Triangle(p) => ("triangle", p.to_vec()),
        };
        let from_spec = FileVolume {
            kind: kind.to_owned(),
            name: spec.name.to_owned(),
            group: spec.group.name().to_owned(),
            link: justin::FRAME_NAMES[spec.link.0].to_owned(),
            radius: spec.radius,
            points,
        };
        assert_eq!(*file, from_spec);
    }
    let name = |id: VolumeId| jc::VOLUME_SPECS[id.0].name;
    assert_eq!(excluded.len(), jc::EXCLUDED.len());
    for (file, spec) in excluded.iter().zip(jc::EXCLUDED.iter()) {
        assert_eq!(
            (file.0.as_str(), file.1.as_str(), file.2.as_str()),
            (name(spec.first), name(spec.second), spec.reason.name())
        );
    }
    // The thesis' grouping (Fig. 3.2): left arm 8, right arm 8, base 5, torso 4, head 2, floor 1.
    let count = |g: jc::Group| jc::VOLUME_SPECS.iter().filter(|v| v.group == g).count();
    assert_eq!(
        [jc::Group::LeftArm, jc::Group::RightArm, jc::Group::Base, jc::Group::Torso, jc::Group::Head, jc::Group::Floor]
            .map(count),
        [8, 8, 5, 4, 2, 1]
    );
}

#[test]
fn enabled_pairs_follow_the_rules() {
    let model = justin::model::<f64>().unwrap();
    let collision = jc::collision_model(&model).unwrap();
    assert_eq!(collision.pairs().len(), jc::PAIRS);
    let volumes = collision.volumes();
    let total = volumes.len() * (volumes.len() - 1) / 2;
    let by_rule = (0..volumes.len())
        .flat_map(|i| (i + 1..volumes.len()).map(move |j| (i, j)))
        .filter(|&(i, j)| exclusion_rule(&model, volumes[i].body, volumes[j].body).is_some())
        .count();
    // No listed pair is also excluded by a rule, and no pair is listed twice.
    for (k, e) in jc::EXCLUDED.iter().enumerate() {
        assert!(exclusion_rule(&model, volumes[e.first.0].body, volumes[e.second.0].body).is_none(), "{e:?}");
        assert!(jc::EXCLUDED[..k]
            .iter()
            .all(|f| (f.first, f.second) != (e.first, e.second) && (f.first, f.second) != (e.second, e.first)));
    }
    assert_eq!(total - by_rule - jc::EXCLUDED.len(), jc::PAIRS);
    println!(
        "Justin collision model: {} volumes, {total} pairs, {by_rule} excluded by rule (same body, adjacent), {} listed, {} enabled",
        volumes.len(),
        jc::EXCLUDED.len(),
        jc::PAIRS
    );
    // The pairs the thesis' Fig. 3.5 shows are enabled: left hand – right hand and right wrist.
    let enabled =
        |a: VolumeId, b: VolumeId| collision.pairs().iter().any(|p| (p.first, p.second) == (a.min(b), a.max(b)));
    assert!(enabled(jc::LEFT_PALM, jc::RIGHT_PALM) && enabled(jc::LEFT_FINGERS, jc::RIGHT_WRIST));
    assert!(enabled(jc::RIGHT_FINGERS, jc::FLOOR) && !enabled(jc::BASE_UPPER_A, jc::FLOOR));
}

/// A URDF `<visual>`: its link, the origin in the link frame and the surface samples of its
/// geometry in that origin's frame.
struct Visual {
    link: String,
    origin: nalgebra::Isometry3<f64>,
    samples: Vec<Vector3<f64>>,
}

fn attribute(tag: &str, name: &str) -> Vec<f64> {
    let start = tag.find(&format!("{name}=\"")).unwrap() + name.len() + 2;
    let end = start + tag[start..].find('"').unwrap();
    tag[start..end].split_whitespace().map(|w| w.parse().unwrap()).collect()
}

/// The visuals of `fixtures/urdf/justin.urdf` with points on their surfaces (boxes: faces on a
/// grid; cylinders: rims, side and caps; spheres: a latitude–longitude net).
fn urdf_visuals() -> Vec<Visual> {
    let text = std::fs::read_to_string(repository_path("fixtures/urdf/justin.urdf")).unwrap();
    let mut out = Vec::new();
    for block in text.split("<link name=\"").skip(1) {
        let link = block[..block.find('"').unwrap()].to_owned();
        let Some(at) = block.find("<visual>") else { continue };
        let visual = &block[at..block.find("</visual>").unwrap()];
        let origin_tag = &visual[visual.find("<origin").unwrap()..];
        let (xyz, rpy) = (attribute(origin_tag, "xyz"), attribute(origin_tag, "rpy"));
        let origin = nalgebra::Isometry3::from_parts(
            Translation3::new(xyz[0], xyz[1], xyz[2]),
            UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
        );
        let geometry = &visual[visual.find("<geometry>").unwrap()..];
        let n = 12;
        let t = |k: usize| k as f64 / n as f64;
        let mut samples = Vec::new();
        if let Some(b) = geometry.find("<box") {
            let size = attribute(&geometry[b..], "size");
            let h = Vector3::new(size[0], size[1], size[2]) / 2.0;
            for i in 0..=n {
                for j in 0..=n {
                    let (u, v) = (2.0 * t(i) - 1.0, 2.0 * t(j) - 1.0);
                    for s in [-1.0, 1.0] {
                        samples.push(Vector3::new(s * h.x, u * h.y, v * h.z));
                        samples.push(Vector3::new(u * h.x, s * h.y, v * h.z));
                        samples.push(Vector3::new(u * h.x, v * h.y, s * h.z));
                    }
                }
            }
        } else if let Some(c) = geometry.find("<cylinder") {
            let (r, l) = (attribute(&geometry[c..], "radius")[0], attribute(&geometry[c..], "length")[0]);
            for i in 0..=n {
                for j in 0..2 * n {
                    let a = std::f64::consts::PI * t(j);
                    let z = l * (t(i) - 0.5);
                    samples.push(Vector3::new(r * a.cos(), r * a.sin(), z));
                    samples.push(Vector3::new(r * t(i) * a.cos(), r * t(i) * a.sin(), l / 2.0));
                    samples.push(Vector3::new(r * t(i) * a.cos(), r * t(i) * a.sin(), -l / 2.0));
                }
            }
        } else if let Some(sp) = geometry.find("<sphere") {
            let r = attribute(&geometry[sp..], "radius")[0];
            for i in 0..=n {
                for j in 0..2 * n {
                    let (polar, a) = (std::f64::consts::PI * t(i), std::f64::consts::PI * t(j));
                    samples.push(r * Vector3::new(polar.sin() * a.cos(), polar.sin() * a.sin(), polar.cos()));
                }
            }
        } else {
            panic!("unknown geometry in link {link}");
        }
        out.push(Visual { link, origin, samples });
    }
    out
}

/// Every sampled point of every URDF visual lies inside a volume on the same body, at home and
/// at random configurations. Exception (documented in the data file): `torso_link1`'s cylinder
/// is covered by the platform's `torso_column`, which is rotationally symmetric about the yaw
/// axis.
#[test]
fn volumes_cover_the_urdf_visuals() {
    let model = justin::model::<f64>().unwrap();
    let collision = jc::collision_model(&model).unwrap();
    let visuals = urdf_visuals();
    assert_eq!(visuals.len(), 1 + 4 + 2 + 2 * 8, "base, torso 1-4, neck, head, 7 links and a hand per arm");
    let mut data = Data::new(&model);
    let mut cd = CollisionData::new(&collision);
    let mut rng = Rng(0xC0FF_EE00_1234_5678);
    let mut worst = f64::NEG_INFINITY;
    for trial in 0..8 {
        let q = if trial == 0 { justin::home_configuration() } else { random_state(&model, &mut rng) };
        forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
        collision.update_world(&data, &mut cd);
        for visual in &visuals {
            let frame_id = justin::FRAME_NAMES.iter().position(|f| *f == visual.link).unwrap();
            let frame = model.frame(kernel::FrameId(frame_id)).unwrap();
            let placement = data.frame_placements[frame_id];
            let allowed =
                |v: &Volume<f64>| v.body == frame.parent || (visual.link == "torso_link1" && v.body == Some(BodyId(2)));
            for p in &visual.samples {
                let world = placement * (visual.origin * nalgebra::Point3::from(*p));
                let inside = collision
                    .volumes()
                    .iter()
                    .zip(cd.world_volumes.iter())
                    .filter(|(v, _)| allowed(v))
                    .map(|(_, w)| w.signed_distance_to(&world.coords))
                    .fold(f64::INFINITY, f64::min);
                worst = worst.max(inside);
                assert!(inside <= 1e-9, "{} point {p} is {inside} m outside its volumes", visual.link);
            }
        }
    }
    println!("largest signed distance of a URDF visual sample to its volumes: {worst:.2e} m");
}

/// A random configuration within the limits (platform within ±1 m, ±π), with the torso's
/// coupled bound `0 ≤ q_t2 + q_t3 ≤ 135°` respected.
fn random_state(model: &Justin, rng: &mut Rng) -> SVector<f64, N> {
    let mut q = SVector::from_fn(|k, _| {
        let (lower, upper) = (model.limits.position_lower[k], model.limits.position_upper[k]);
        if k < justin::BASE_DOF {
            rng.uniform(-1.0, 1.0)
        } else {
            rng.uniform(lower, upper)
        }
    });
    let (t2, t3) = (justin::TORSO_COORDINATES.start + 1, justin::TORSO_COORDINATES.start + 2);
    let bound = 135f64.to_radians();
    q[t3] = rng.uniform((-q[t2]).max(0.0), (bound - q[t2]).min(bound));
    q
}

/// Pattern search from `start` over `coordinates` (within limits and the torso bound) for the
/// extreme of `distance`: the minimum if `sign = 1`, the maximum if `sign = −1`.
fn local_extreme(
    model: &Justin,
    distance: &mut dyn FnMut(&SVector<f64, N>) -> f64,
    coordinates: &[usize],
    start: SVector<f64, N>,
    mut step: f64,
    sign: f64,
) -> f64 {
    let bound = 135f64.to_radians();
    let (t2, t3) = (justin::TORSO_COORDINATES.start + 1, justin::TORSO_COORDINATES.start + 2);
    let admissible = |q: &SVector<f64, N>| {
        coordinates.iter().all(|&c| (model.limits.position_lower[c]..=model.limits.position_upper[c]).contains(&q[c]))
            && (-1e-12..=bound + 1e-12).contains(&(q[t2] + q[t3]))
    };
    let mut q = start;
    let mut best = sign * distance(&q);
    while step > 1e-4 {
        let mut improved = false;
        for &c in coordinates {
            for delta in [step, -step] {
                let mut trial = q;
                trial[c] += delta;
                if !admissible(&trial) {
                    continue;
                }
                let value = sign * distance(&trial);
                if value < best {
                    (best, q, improved) = (value, trial, true);
                }
            }
        }
        if !improved {
            step /= 2.0;
        }
    }
    sign * best
}

/// Every listed exclusion holds over a grid of the joints between the two links (about 10⁵
/// configurations per pair, each joint's limits included), refined by a pattern search from
/// the five most critical grid points: `never_close` pairs stay apart (distance > 0),
/// `always_near` pairs stay within d0 = 0.15 m, `constant` pairs do not change their distance.
#[test]
fn listed_exclusions_hold() {
    let model = justin::model::<f64>().unwrap();
    let collision = jc::collision_model(&model).unwrap();
    let mut data = Data::new(&model);
    let mut closest = f64::INFINITY;
    for e in &jc::EXCLUDED {
        let (a, b) = (collision.volume(e.first).unwrap(), collision.volume(e.second).unwrap());
        let coordinates = relevant_coordinates(&model, a.body, b.body);
        let n = ((1e5f64).powf(1.0 / coordinates.len().max(1) as f64) as usize).clamp(2, 61);
        let configurations = grid(&model, &coordinates, n);
        let pair = (e.first, e.second);
        let mut distances: Vec<(f64, usize)> = configurations
            .iter()
            .enumerate()
            .map(|(i, q)| (distance_range(&model, &mut data, &collision, pair, std::slice::from_ref(q)).0, i))
            .collect();
        distances.sort_by(|x, y| x.0.total_cmp(&y.0));
        let (lo, hi) = (distances[0].0, distances[distances.len() - 1].0);
        let step = 240f64.to_radians() / (n.max(2) - 1) as f64 / 2.0;
        let label = format!("{} – {}", jc::VOLUME_SPECS[e.first.0].name, jc::VOLUME_SPECS[e.second.0].name);
        let mut distance =
            |q: &SVector<f64, N>| distance_range(&model, &mut data, &collision, pair, std::slice::from_ref(q)).0;
        match e.reason {
            jc::ExclusionReason::NeverClose => {
                let refined = distances
                    .iter()
                    .take(5)
                    .map(|&(_, i)| local_extreme(&model, &mut distance, &coordinates, configurations[i], step, 1.0))
                    .fold(lo, f64::min);
                closest = closest.min(refined);
                assert!(refined > 0.0, "{label} touches: {refined} m");
            }
            jc::ExclusionReason::AlwaysNear => {
                let refined = distances
                    .iter()
                    .rev()
                    .take(5)
                    .map(|&(_, i)| local_extreme(&model, &mut distance, &coordinates, configurations[i], step, -1.0))
                    .fold(hi, f64::max);
                assert!(refined < 0.15, "{label} gets {refined} m apart");
            }
            jc::ExclusionReason::Constant => assert!(hi - lo < 1e-9, "{label} varies by {} m", hi - lo),
        }
    }
    println!("closest approach of a never_close exclusion: {closest:.3} m");
}

/// Total potential `Σ V(d)` of all enabled Justin pairs at `q`.
fn justin_potential(
    model: &Justin,
    data: &mut JustinData,
    collision: &jc::JustinCollisionModel<f64>,
    cd: &mut CollisionData<f64, { jc::VOLUMES }, { jc::PAIRS }>,
    parameters: &CollisionParameters<f64>,
    q: &SVector<f64, N>,
) -> f64 {
    forward_kinematics(model, data, q, &SVector::zeros()).unwrap();
    collision.update(data, cd);
    cd.proximities.iter().map(|p| parameters.potential(p.distance)).sum()
}

/// Rows capacity of the Justin tests: more than the 35 contact-point pairs of Table 3.1.
const ROWS: usize = 64;

/// On the Justin-like robot at random configurations with active pairs (Table 3.1's
/// `F_max = 25 N`, `d0 = 0.15 m`, `q̇ = 0`): the summed rows give `τ = −(∂V/∂q)ᵀ` to 1e-6
/// (central differences of the total potential over all 20 coordinates, including the coupled
/// torso joint and the platform).
#[test]
fn justin_torques_are_the_negative_potential_gradient() {
    let model = justin::model::<f64>().unwrap();
    let collision = jc::collision_model(&model).unwrap();
    let mut data = Data::new(&model);
    let mut cd = CollisionData::new(&collision);
    let parameters = CollisionParameters::try_new(25.0, 0.15, 0.7, 0.0, 0.15).unwrap();
    let mut rng = Rng(0x0DD5_EED5_0000_0001);
    let (mut checked, mut worst, mut rows_seen) = (0, 0.0_f64, 0);
    while checked < 40 {
        let q = random_state(&model, &mut rng);
        forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
        crba(&model, &mut data);
        let factor = mass_matrix_cholesky(&data).unwrap();
        let mut rows = TaskRows::<f64, N, ROWS>::new();
        let report = self_collision_rows(&collision, &mut cd, &model, &data, &factor, &parameters, &mut rows).unwrap();
        assert_eq!(report.dropped, 0);
        if rows.is_empty() || report.undefined_direction > 0 || report.min_distance.unwrap() < 0.0 {
            continue;
        }
        let tau = rows.torque();
        let h = 1e-6;
        let gradient = SVector::<f64, N>::from_fn(|k, _| {
            let mut step = SVector::<f64, N>::zeros();
            step[k] = h;
            (justin_potential(&model, &mut data, &collision, &mut cd, &parameters, &(q + step))
                - justin_potential(&model, &mut data, &collision, &mut cd, &parameters, &(q - step)))
                / (2.0 * h)
        });
        let error = (tau + gradient).amax() / tau.amax();
        assert!(
            error <= 1e-6,
            "relative error {error:.2e} with {} rows: τ = {tau}, −∂V/∂q = {}",
            rows.len(),
            -gradient
        );
        worst = worst.max(error);
        rows_seen += rows.len();
        checked += 1;
    }
    println!("Justin: τ vs −∂V/∂q over {checked} states ({rows_seen} rows): largest relative error {worst:.1e}");
}

/// The same Justin evaluation in f32 agrees with f64 (rows and torque) at configurations where
/// no pair sits at the emit distance.
#[test]
fn justin_rows_in_f32_agree_with_f64() {
    let (m64, m32) = (justin::model::<f64>().unwrap(), justin::model::<f32>().unwrap());
    let (c64, c32) = (jc::collision_model(&m64).unwrap(), jc::collision_model(&m32).unwrap());
    let (mut d64, mut d32) = (Data::new(&m64), Data::new(&m32));
    let (mut k64, mut k32) = (CollisionData::new(&c64), CollisionData::new(&c32));
    let p64 = CollisionParameters::try_new(25.0, 0.15, 0.7, 0.0, 0.15).unwrap();
    let p32 = CollisionParameters::try_new(25.0_f32, 0.15, 0.7, 0.0, 0.15).unwrap();
    let mut rng = Rng(0xF32F_64F0_1111_2222);
    let mut compared = 0;
    while compared < 20 {
        let q = random_state(&m64, &mut rng);
        let v = SVector::<f64, N>::from_fn(|_, _| rng.uniform(-0.5, 0.5));
        forward_kinematics(&m64, &mut d64, &q, &v).unwrap();
        forward_kinematics(&m32, &mut d32, &q.cast(), &v.cast()).unwrap();
        crba(&m64, &mut d64);
        crba(&m32, &mut d32);
        let (f64_, f32_) = (mass_matrix_cholesky(&d64).unwrap(), mass_matrix_cholesky(&d32).unwrap());
        let (mut r64, mut r32) = (TaskRows::<f64, N, ROWS>::new(), TaskRows::<f32, N, ROWS>::new());
        self_collision_rows(&c64, &mut k64, &m64, &d64, &f64_, &p64, &mut r64).unwrap();
        self_collision_rows(&c32, &mut k32, &m32, &d32, &f32_, &p32, &mut r32).unwrap();
        let near_edge = k64.proximities.iter().any(|p| (p.distance - 0.15).abs() < 1e-3 || p.distance < 0.0);
        if r64.is_empty() || near_edge {
            continue;
        }
        assert_eq!(r64.len(), r32.len());
        let (t64, t32) = (r64.torque(), r32.torque().cast::<f64>());
        assert!((t64 - t32).amax() <= 2e-3 * t64.amax().max(1.0), "{t64} vs {t32}");
        compared += 1;
    }
}

/// The pairs whose rows the collision task emits, in pair order: closer than the emit distance
/// and with a defined direction.
fn emitting_pairs<T: nalgebra::RealField + Copy, const V: usize, const P: usize>(
    collision: &CollisionModel<T, V, P>,
    cd: &CollisionData<T, V, P>,
    parameters: &CollisionParameters<T>,
) -> Vec<usize> {
    cd.proximities
        .iter()
        .take(collision.pairs().len())
        .enumerate()
        .filter(|(_, p)| p.distance < parameters.emit_distance() && p.direction.is_some())
        .map(|(k, _)| k)
        .collect()
}

/// Row Jacobians agree entrywise within `tolerance` relative to the reference's largest entry.
fn assert_jacobians_agree<T: nalgebra::RealField + Copy>(
    row: &nalgebra::RowSVector<T, N>,
    reference: &nalgebra::RowSVector<T, N>,
    tolerance: f64,
    pair: usize,
) {
    let f = |x: T| nalgebra::try_convert::<T, f64>(x).unwrap();
    let scale = 1.0 + f(reference.amax());
    for (a, b) in row.iter().zip(reference.iter()) {
        assert!(f((*a - *b).abs()) <= tolerance * scale, "pair {pair}: {row} vs {reference}");
    }
}

/// The fast rows of `self_collision_rows` (support-path Jacobians, one forward substitution
/// for both reflected masses, closed-form damping) against the reference `evaluate_pair` on
/// random Justin states with random velocities: Jacobian, force, potential and activation of
/// every row, and both reflected masses (3.20) of every emitted pair, relative to `tolerance`.
fn justin_fast_rows_match_reference<T: nalgebra::RealField + Copy>(tolerance: f64, seed: u64) {
    let model = justin::model::<T>().unwrap();
    let bounds = justin::model::<f64>().unwrap();
    let collision = jc::collision_model(&model).unwrap();
    let mut data = Data::new(&model);
    let mut cd = CollisionData::new(&collision);
    let c = |x: f64| nalgebra::convert::<f64, T>(x);
    let parameters = CollisionParameters::try_new(c(25.0), c(0.15), c(0.7), c(0.0), c(0.15)).unwrap();
    let f = |x: T| nalgebra::try_convert::<T, f64>(x).unwrap();
    let mut rng = Rng(seed);
    let (mut rows_compared, mut damped) = (0, 0);
    for _ in 0..60 {
        let q = random_state(&bounds, &mut rng);
        let v = SVector::<f64, N>::from_fn(|_, _| rng.uniform(-1.0, 1.0));
        forward_kinematics(&model, &mut data, &q.cast::<T>(), &v.cast::<T>()).unwrap();
        crba(&model, &mut data);
        let factor = mass_matrix_cholesky(&data).unwrap();
        let mut rows = TaskRows::<T, N, ROWS>::new();
        let report = self_collision_rows(&collision, &mut cd, &model, &data, &factor, &parameters, &mut rows).unwrap();
        assert_eq!(report.dropped, 0);
        let rows_of_l = factor_rows(&factor);
        let emitted = emitting_pairs(&collision, &cd, &parameters);
        assert_eq!(rows.len(), emitted.len());
        for (row, &pair) in rows.rows().iter().zip(&emitted) {
            let e = evaluate_pair(&collision, &cd, &model, &data, &factor, &parameters, pair).unwrap();
            assert_jacobians_agree(&row.jacobian, &e.row.jacobian, tolerance, pair);
            for (name, a, b) in [
                ("force", row.force, e.row.force),
                ("potential", row.potential, e.row.potential),
                ("activation", row.activation, e.row.activation),
            ] {
                assert!(f((a - b).abs()) <= tolerance * (1.0 + f(b.abs())), "pair {pair} {name}: {a} vs {b}");
            }
            let [wi, wj] = inverse_reflected_masses(
                &rows_of_l,
                [&e.jacobian_first.transpose().into(), &e.jacobian_second.transpose().into()],
            )
            .unwrap();
            for (fast, reference) in [(wi, e.inverse_masses.x), (wj, e.inverse_masses.y)] {
                assert!(
                    f((fast - reference).abs()) <= tolerance * f(reference.abs()),
                    "pair {pair}: 1/m {fast} vs {reference}"
                );
            }
            rows_compared += 1;
            if e.row.force != parameters.force(e.distance) {
                damped += 1;
            }
        }
    }
    assert!(rows_compared > 200 && damped > 150, "{rows_compared} rows, {damped} damped");
}

#[test]
fn justin_fast_rows_match_the_reference_f64() {
    justin_fast_rows_match_reference::<f64>(1e-12, 0xFA57_0000_0000_0064);
}

#[test]
fn justin_fast_rows_match_the_reference_f32() {
    justin_fast_rows_match_reference::<f32>(5e-4, 0xFA57_0000_0000_0032);
}

/// The rows over the tree-sparse factor (`TreeFactorization`: reflected masses along each
/// Jacobian's support path, `inverse_reflected_mass`) against the plain per-pair evaluation
/// over nalgebra's dense Cholesky factor of the same inertia, for `M` and for the closed-loop
/// `M̃` whose platform rows and columns are cleared to their diagonal (the decoupled factor of
/// the controller), at random states: every emitted row and both inverse reflected masses of
/// each pair.
fn justin_tree_rows_match_reference<T: nalgebra::RealField + Copy>(tolerance: f64, seed: u64) {
    let model = justin::model::<T>().unwrap();
    let bounds = justin::model::<f64>().unwrap();
    let collision = jc::collision_model(&model).unwrap();
    let mut data = Data::new(&model);
    let mut cd = CollisionData::new(&collision);
    let c = |x: f64| nalgebra::convert::<f64, T>(x);
    let parameters = CollisionParameters::try_new(c(25.0), c(0.15), c(0.7), c(0.0), c(0.15)).unwrap();
    let f = |x: T| nalgebra::try_convert::<T, f64>(x).unwrap();
    let mut rng = Rng(seed);
    let mut rows_compared = 0;
    for round in 0..60 {
        let q = random_state(&bounds, &mut rng);
        let v = SVector::<f64, N>::from_fn(|_, _| rng.uniform(-1.0, 1.0));
        forward_kinematics(&model, &mut data, &q.cast::<T>(), &v.cast::<T>()).unwrap();
        crba(&model, &mut data);
        let m = data.mass_matrix;
        let mut plain = TreeFactorization::new(&model);
        plain.factorize(&m).unwrap();
        let decoupled = round % 2 == 1;
        let (tree, inertia) = if decoupled {
            let mut cleared = m;
            let mut platform = [false; N];
            for k in 0..justin::BASE_DOF {
                platform[k] = true;
                let diagonal = m[(k, k)] + c(10.0);
                cleared.row_mut(k).fill(T::zero());
                cleared.column_mut(k).fill(T::zero());
                cleared[(k, k)] = diagonal;
            }
            let mut tree = plain.clone();
            tree.decouple(&platform, &cleared).unwrap();
            (tree, cleared)
        } else {
            (plain, m)
        };
        let dense = nalgebra::Cholesky::new(inertia).unwrap();
        let mut rows = TaskRows::<T, N, ROWS>::new();
        let report = self_collision_rows(&collision, &mut cd, &model, &data, &tree, &parameters, &mut rows).unwrap();
        if report.dropped > 0 {
            continue; // more candidates than rows: the selection is tested elsewhere
        }
        let emitted = emitting_pairs(&collision, &cd, &parameters);
        assert_eq!(rows.len(), emitted.len());
        for (row, &pair) in rows.rows().iter().zip(&emitted) {
            let e = evaluate_pair(&collision, &cd, &model, &data, &dense, &parameters, pair).unwrap();
            assert_jacobians_agree(&row.jacobian, &e.row.jacobian, tolerance, pair);
            assert!(
                f((row.force - e.row.force).abs()) <= tolerance * (1.0 + f(e.row.force.abs())),
                "pair {pair} decoupled {decoupled}: force {} vs {}",
                row.force,
                e.row.force
            );
            for (jacobian, reference) in
                [(e.jacobian_first, e.inverse_masses.x), (e.jacobian_second, e.inverse_masses.y)]
            {
                let fast = tree.inverse_reflected_mass(&jacobian.transpose().into());
                let dense_reference = inverse_reflected_mass(&dense, &jacobian).unwrap();
                assert_eq!(dense_reference, reference);
                assert!(
                    f((fast - reference).abs()) <= tolerance * f(reference.abs()),
                    "pair {pair} decoupled {decoupled}: 1/m {fast} vs {reference}"
                );
            }
            rows_compared += 1;
        }
    }
    assert!(rows_compared > 200, "{rows_compared} rows");
}

#[test]
fn justin_tree_rows_match_the_reference_f64() {
    justin_tree_rows_match_reference::<f64>(1e-12, 0xFA57_0000_0000_1064);
}

#[test]
fn justin_tree_rows_match_the_reference_f32() {
    justin_tree_rows_match_reference::<f32>(5e-4, 0xFA57_0000_0000_1032);
}

/// The `j M̃⁻¹ jᵀ` the collision rows carry over the tree factor
/// (`TaskRows::metric_norm_squared`: `‖x_j − x_i‖²` from both support substitutions) against
/// the dense `j M̃⁻¹ jᵀ` of the same inertia (`M`, and the closed-loop `M̃` with its platform
/// rows and columns cleared to their diagonal, the decoupled factor of the controller), on
/// random Justin states with every pair inside the field: pairs with a world-fixed volume (the
/// floor), pairs whose supports share joint coordinates (the torso: shared chains) and pairs
/// that share only the platform's coordinates (the base against the upper body: their chains
/// meet only at the platform, whose coordinates are roots after the decoupling). Then the projection of those rows with
/// `Weighting::InverseInertia(M̃⁻¹)` (`inverse_into` of the same factor) with the carried values
/// (`push_rows`) and without them (`Stack::push`, the quadratic form): the same torque, norm
/// ratios and activations to rounding.
fn justin_carried_metric_matches_the_quadratic_form<T: nalgebra::RealField + Copy>(
    tolerance: f64,
    projection_tolerance: f64,
    seed: u64,
) {
    use kernel::hierarchy::{project, HierarchyConfig, HierarchyData, Recursion, Shaping, Stack, Weighting};
    const CAPACITY: usize = 256;
    let model = justin::model::<T>().unwrap();
    let bounds = justin::model::<f64>().unwrap();
    let collision = jc::collision_model(&model).unwrap();
    let mut data = Data::new(&model);
    let mut cd = CollisionData::new(&collision);
    let c = |x: f64| nalgebra::convert::<f64, T>(x);
    // Every pair closer than 10 m emits (the capacity frames' field).
    let parameters = CollisionParameters::try_new(c(25.0), c(10.0), c(0.7), c(0.0), c(10.0)).unwrap();
    let f = |x: T| nalgebra::try_convert::<T, f64>(x).unwrap();
    let mut rng = Rng(seed);
    let (mut world, mut shared, mut disjoint) = (0, 0, 0);
    let mut projected = 0;
    for round in 0..12 {
        let q = random_state(&bounds, &mut rng);
        let v = SVector::<f64, N>::from_fn(|_, _| rng.uniform(-1.0, 1.0));
        forward_kinematics(&model, &mut data, &q.cast::<T>(), &v.cast::<T>()).unwrap();
        crba(&model, &mut data);
        let m = data.mass_matrix;
        let mut tree = TreeFactorization::new(&model);
        tree.factorize(&m).unwrap();
        let decoupled = round % 2 == 1;
        let mut inertia = m;
        if decoupled {
            let mut platform = [false; N];
            for k in 0..justin::BASE_DOF {
                platform[k] = true;
                let diagonal = m[(k, k)] + c(10.0);
                inertia.row_mut(k).fill(T::zero());
                inertia.column_mut(k).fill(T::zero());
                inertia[(k, k)] = diagonal;
            }
            tree.decouple(&platform, &inertia).unwrap();
        }
        let dense_inverse = inertia.map(f).try_inverse().unwrap();
        let dense = nalgebra::Cholesky::new(inertia).unwrap();
        let mut rows = TaskRows::<T, N, CAPACITY>::new();
        self_collision_rows(&collision, &mut cd, &model, &data, &tree, &parameters, &mut rows).unwrap();
        let emitted = emitting_pairs(&collision, &cd, &parameters);
        assert_eq!(rows.len(), emitted.len());
        assert_eq!(rows.metric_norm_squared().len(), rows.len());
        for ((row, metric), &pair) in rows.rows().iter().zip(rows.metric_norm_squared()).zip(&emitted) {
            let metric = f(metric.expect("every pair row over the tree factor carries its metric"));
            let j = SVector::<f64, N>::from_fn(|k, _| f(row.jacobian[k]));
            let reference = (j.transpose() * dense_inverse * j).x;
            assert!(
                (metric - reference).abs() <= tolerance * reference.abs(),
                "pair {pair} decoupled {decoupled}: {metric} vs {reference}"
            );
            let e = evaluate_pair(&collision, &cd, &model, &data, &dense, &parameters, pair).unwrap();
            let support = |x: &nalgebra::RowSVector<T, N>| -> Vec<bool> { x.iter().map(|v| !v.is_zero()).collect() };
            let (a, b) = (support(&e.jacobian_first), support(&e.jacobian_second));
            if !a.contains(&true) || !b.contains(&true) {
                world += 1;
            } else if a.iter().zip(&b).skip(justin::BASE_DOF).any(|(x, y)| *x && *y) {
                shared += 1;
            } else {
                disjoint += 1;
            }
        }
        // The projection with and without the carried values.
        let mut inverse = nalgebra::SMatrix::<T, N, N>::zeros();
        tree.inverse_into(&mut inverse);
        let mut carried = Stack::<T, N, CAPACITY>::new();
        carried.push_rows(0, &rows).unwrap();
        let mut plain = Stack::<T, N, CAPACITY>::new();
        for row in rows.rows() {
            plain.push(0, *row).unwrap();
        }
        assert!(carried.rows().iter().all(|r| r.metric_norm_squared.is_some()));
        assert!(plain.rows().iter().all(|r| r.metric_norm_squared.is_none()));
        for recursion in [Recursion::Augmented, Recursion::Successive] {
            let config = HierarchyConfig {
                recursion,
                weighting: Weighting::InverseInertia(&inverse),
                shaping: Shaping::Continuous { singular_full: c(0.02), singular_start: c(0.05) },
                diagnose_last_level: true,
            };
            let mut with = HierarchyData::<T, N, CAPACITY, 2>::default();
            let mut without = HierarchyData::<T, N, CAPACITY, 2>::default();
            let torque_with = *project(&config, &carried, &mut with).unwrap();
            let torque_without = *project(&config, &plain, &mut without).unwrap();
            let scale = 1.0 + f(torque_without.amax());
            for (a, b) in torque_with.iter().zip(torque_without.iter()) {
                assert!(
                    f((*a - *b).abs()) <= projection_tolerance * scale,
                    "{recursion:?}: {torque_with} vs {torque_without}"
                );
            }
            for (a, b) in with.rows.iter().zip(&without.rows).take(rows.len()) {
                assert!(f((a.projected_norm_ratio - b.projected_norm_ratio).abs()) <= projection_tolerance);
                assert!(f((a.activation - b.activation).abs()) <= projection_tolerance);
            }
            projected += 1;
        }
    }
    assert!(world > 20 && shared > 200 && disjoint > 20, "{world} world, {shared} shared, {disjoint} disjoint");
    assert_eq!(projected, 24);
}

#[test]
fn justin_carried_metric_matches_the_quadratic_form_f64() {
    justin_carried_metric_matches_the_quadratic_form::<f64>(1e-10, 1e-9, 0xFA57_0000_0000_2064);
}

#[test]
fn justin_carried_metric_matches_the_quadratic_form_f32() {
    justin_carried_metric_matches_the_quadratic_form::<f32>(2e-3, 2e-2, 0xFA57_0000_0000_2032);
}

/// Fig. 3.5 / Table 3.1 on the one-dimensional collision-direction model (`sca_damping`).
#[test]
fn sca_damping_reproduces_fig_3_5() {
    use host_sim::scenarios::{sca_damping, RunOptions};
    let outcome = sca_damping::simulate(&RunOptions::default()).unwrap();
    let s = &outcome.summary;
    assert!(s.failed_claims().is_empty(), "failed: {:?}", s.failed_claims());
    assert!(s.passed_claims().len() >= 9);
    let depth = |xi: &str| s.get(&format!("penetration_depth_m_{xi}")).unwrap();
    let depths = ["xi_0", "xi_0_7", "xi_1_0", "xi_1_3"].map(depth);
    println!("penetration depths (xi = 0, 0.7, 1.0, 1.3): {depths:?} m");
    // Monotone, and much smaller with damping ("significantly smaller while damping is active").
    assert!(depths.windows(2).all(|w| w[1] < w[0]), "{depths:?}");
    assert!(depths[1] < 0.6 * depths[0]);
    // The undamped run peaks at the 10 N of Fig. 3.5's force axis and stays clear of contact.
    assert!((s.get("peak_repulsive_force_n_xi_0").unwrap() - 10.0).abs() < 0.2);
    assert!(s.get("min_distance_m_xi_0").unwrap() > 0.0);
    // The hand's reflected mass is derived from the Justin model (left arm only).
    let mass = s.get("hand_mass_kg").unwrap();
    assert!((1.0..5.0).contains(&mass), "{mass} kg");
    // No rebound oscillation at ξ = 1.0 (and 1.3); a damped one at 0.7; none decays at 0.
    assert!(s.get("hold_overshoot_m_xi_1_0").unwrap() <= sca_damping::OVERSHOOT_TOLERANCE_M);
    assert!(s.get("hold_overshoot_m_xi_1_3").unwrap() <= sca_damping::OVERSHOOT_TOLERANCE_M);
    assert!(s.get("hold_overshoot_m_xi_0_7").unwrap() > 1e-4);
    let ratio = s.get("hold_overshoot_ratio_xi_0_7").unwrap();
    let linear = s.get("hold_overshoot_ratio_linear_xi_0_7").unwrap();
    assert!((ratio - linear).abs() < 0.3 * linear, "{ratio} vs {linear}");
    // The time series follows the output convention.
    assert_eq!(outcome.series.columns()[0], "t");
    assert!(outcome.series.columns().iter().any(|c| c == "d.throw_xi_1_0"));
}

/// Environment volumes with the same machinery: a table in front of the robot (top 0.75 m,
/// x 0.40 … 1.20 m, y ±0.6 m) and a wall 1.2 m to its right, added to the Justin model. Near the
/// home pose the hands and the platform are repelled from the table; the rows still give
/// `τ = −(∂V/∂q)ᵀ`, now including the platform coordinates.
#[test]
fn environment_volumes_repel_the_whole_body() {
    use kernel::tasks::collision::SweptSphere;
    const V: usize = jc::VOLUMES + 4;
    const P: usize = jc::PAIRS + 4 * (jc::VOLUMES - 1);
    let v = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
    let (t0, t1, t2, t3) = (v(0.40, -0.6, 0.72), v(1.20, -0.6, 0.72), v(1.20, 0.6, 0.72), v(0.40, 0.6, 0.72));
    let (w0, w1, w2, w3) = (v(-2.0, -1.2, 0.0), v(2.0, -1.2, 0.0), v(2.0, -1.2, 2.5), v(-2.0, -1.2, 2.5));
    let environment = [
        SweptSphere::swept_triangle(t0, t1, t2, 0.03),
        SweptSphere::swept_triangle(t0, t2, t3, 0.03),
        SweptSphere::swept_triangle(w0, w1, w2, 0.025),
        SweptSphere::swept_triangle(w0, w2, w3, 0.025),
    ];
    let model = justin::model::<f64>().unwrap();
    let collision = jc::collision_model_with_environment::<f64, V, P>(&model, &environment).unwrap();
    assert_eq!(collision.pairs().len(), P);
    let mut data = Data::new(&model);
    let mut cd = CollisionData::new(&collision);
    let parameters = CollisionParameters::try_new(25.0, 0.15, 0.7, 0.0, 0.15).unwrap();
    let mut rng = Rng(0x7AB1_E000_0000_0001);
    let (mut table_pairs, mut platform_pushed) = (0, false);
    for _ in 0..20 {
        let mut q = justin::home_configuration::<f64>();
        for k in 0..N {
            q[k] += rng.uniform(-0.25, 0.25) * if k < justin::BASE_DOF { 0.4 } else { 1.0 };
        }
        forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
        crba(&model, &mut data);
        let factor = mass_matrix_cholesky(&data).unwrap();
        let mut rows = TaskRows::<f64, N, ROWS>::new();
        self_collision_rows(&collision, &mut cd, &model, &data, &factor, &parameters, &mut rows).unwrap();
        let active_environment = collision
            .pairs()
            .iter()
            .zip(cd.proximities.iter())
            .filter(|(p, d)| p.second.0 >= jc::VOLUMES && d.distance < 0.15)
            .count();
        table_pairs += active_environment;
        let tau = rows.torque();
        let potential = |data: &mut JustinData, cd: &mut CollisionData<f64, V, P>, q: &SVector<f64, N>| -> f64 {
            forward_kinematics(&model, data, q, &SVector::zeros()).unwrap();
            collision.update(data, cd);
            cd.proximities.iter().map(|p| parameters.potential(p.distance)).sum()
        };
        let h = 1e-6;
        let gradient = SVector::<f64, N>::from_fn(|k, _| {
            let mut step = SVector::<f64, N>::zeros();
            step[k] = h;
            (potential(&mut data, &mut cd, &(q + step)) - potential(&mut data, &mut cd, &(q - step))) / (2.0 * h)
        });
        if tau.amax() > 0.0 {
            assert!((tau + gradient).amax() <= 1e-6 * tau.amax(), "τ = {tau}, −∂V/∂q = {}", -gradient);
        }
        platform_pushed |= tau[0] < -1e-3;
    }
    assert!(table_pairs > 20, "{table_pairs} active environment pairs");
    assert!(platform_pushed, "the table never pushed the platform back");
}

/// The broad phase (`CollisionData::exact_within`) changes no row: at random Justin states the
/// rows of a field are bit-identical with and without it, every culled pair's reported
/// distance is a lower bound of its exact distance above the cull distance, and the exact
/// pairs are unchanged. Also counts how many pairs the broad phase skips.
#[test]
fn broad_phase_keeps_every_row_and_bounds_the_skipped_distances() {
    let model = justin::model::<f64>().unwrap();
    let collision = jc::collision_model(&model).unwrap();
    let mut data = Data::new(&model);
    let (mut exact, mut culled) = (CollisionData::new(&collision), CollisionData::new(&collision));
    let parameters = CollisionParameters::try_new(25.0, 0.15, 0.7, 0.0, 0.15).unwrap();
    culled.exact_within = Some(parameters.emit_distance());
    let mut rng = Rng(0xB0AD_0FA5_E000_0001);
    let (mut skipped, mut rows_seen) = (0_usize, 0_usize);
    for _ in 0..60 {
        let q = random_state(&model, &mut rng);
        forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
        crba(&model, &mut data);
        let factor = mass_matrix_cholesky(&data).unwrap();
        let (mut a, mut b) = (TaskRows::<f64, N, ROWS>::new(), TaskRows::<f64, N, ROWS>::new());
        let ra = self_collision_rows(&collision, &mut exact, &model, &data, &factor, &parameters, &mut a).unwrap();
        let rb = self_collision_rows(&collision, &mut culled, &model, &data, &factor, &parameters, &mut b).unwrap();
        assert_eq!(a, b);
        assert_eq!((ra.rows, ra.candidates, ra.dropped), (rb.rows, rb.candidates, rb.dropped));
        for (e, c) in exact.proximities.iter().zip(culled.proximities.iter()) {
            if e.distance < parameters.emit_distance() {
                assert_eq!(e, c);
            } else if c != e {
                assert!(c.distance > parameters.emit_distance() && c.distance <= e.distance + 1e-12);
                skipped += 1;
            }
        }
        rows_seen += a.len();
    }
    assert!(skipped > 60 * 100, "the broad phase skipped only {skipped} pair evaluations");
    println!("broad phase: {skipped} of {} pair evaluations skipped, {rows_seen} rows identical", 60 * jc::PAIRS);
}

/// The per-field selection of the closest candidates (a max-heap of the kept ones) on Justin:
/// at random states with a wide field (d0 = 0.5 m, so dozens of candidates), a field with 8 free
/// rows emits exactly the rows, bit for bit and in pair order, of the 8 candidates with the
/// smallest distances among the rows of a field with room for all; f64 and f32.
fn justin_selection_keeps_the_closest<T: nalgebra::RealField + Copy>(seed: u64) {
    use kernel::tasks::collision::collision_rows_from_geometry;
    const ALL: usize = jc::PAIRS;
    let model = justin::model::<T>().unwrap();
    let bounds = justin::model::<f64>().unwrap();
    let collision = jc::collision_model(&model).unwrap();
    let mut data = Data::new(&model);
    let mut cd = CollisionData::new(&collision);
    let c = |x: f64| nalgebra::convert::<f64, T>(x);
    let parameters = CollisionParameters::try_new(c(25.0), c(0.5), c(0.7), c(0.0), c(0.5)).unwrap();
    let mut rng = Rng(seed);
    let mut dropped = 0;
    for _ in 0..20 {
        let q = random_state(&bounds, &mut rng);
        let v = SVector::<f64, N>::from_fn(|_, _| rng.uniform(-1.0, 1.0));
        forward_kinematics(&model, &mut data, &q.cast::<T>(), &v.cast::<T>()).unwrap();
        crba(&model, &mut data);
        let factor = mass_matrix_cholesky(&data).unwrap();
        let mut all = Box::new(TaskRows::<T, N, ALL>::new());
        self_collision_rows(&collision, &mut cd, &model, &data, &factor, &parameters, &mut all).unwrap();
        let mut candidates: Vec<(T, usize)> =
            emitting_pairs(&collision, &cd, &parameters).into_iter().map(|k| (cd.proximities[k].distance, k)).collect();
        let order: Vec<usize> = candidates.iter().map(|x| x.1).collect();
        candidates.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap().then(a.1.cmp(&b.1)));
        let mut few = TaskRows::<T, N, 8>::new();
        let report =
            collision_rows_from_geometry(&collision, &cd, &model, &data, &factor, &parameters, &mut few).unwrap();
        let mut closest: Vec<usize> = candidates.iter().take(8).map(|x| x.1).collect();
        closest.sort_unstable();
        assert_eq!((report.rows, few.len()), (closest.len(), closest.len()));
        for (row, pair) in few.rows().iter().zip(&closest) {
            let position = order.iter().position(|x| x == pair).unwrap();
            assert_eq!(*row, all.rows()[position], "pair {pair}");
        }
        dropped += report.dropped;
    }
    assert!(dropped > 100, "{dropped} candidates dropped");
}

#[test]
fn justin_selection_keeps_the_closest_f64() {
    justin_selection_keeps_the_closest::<f64>(0x5E1E_C700_0000_0064);
}

#[test]
fn justin_selection_keeps_the_closest_f32() {
    justin_selection_keeps_the_closest::<f32>(0x5E1E_C700_0000_0032);
}
