//! An imported robot's collision file (`fixtures/robots/<name>/<name>.collision`, written by
//! `host-sim import`): parsed and checked against the robot's frame and body names with one-line
//! errors, and turned into the Rust of its `no_std` constructor (`fixtures::robots::<name>::collision`).
//!
//! Lines (`#` starts a comment):
//! - `capacity <volumes> <pairs>`: the collision model's sizes, once, before the volumes;
//! - `sphere <name> <group> <link> <radius> <x y z>`, `capsule … <x y z> <x y z>`,
//!   `triangle … <x y z> <x y z> <x y z>`: a volume, points in the frame of URDF link `<link>`,
//!   `<group>` the link of the body it moves with (`world`: fixed in the world);
//! - `exclude <volume> <volume> <reason>`: a pair the controller does not check
//!   (`constant`, `never_close`, `always_near`, `welded_parent`).

use std::collections::HashMap;
use std::fmt::Write as _;

/// A volume's core in its link frame (m).
#[derive(Clone, Debug, PartialEq)]
pub enum CollisionShape {
    /// A sphere about the point.
    Sphere([f64; 3]),
    /// A capsule between two points.
    Capsule([[f64; 3]; 2]),
    /// A sphere swept over a triangle.
    Triangle([[f64; 3]; 3]),
}

/// One volume line.
#[derive(Clone, Debug, PartialEq)]
pub struct CollisionVolume {
    /// The volume's name.
    pub name: String,
    /// Index of its body in the body names (`None`: `world`).
    pub body: Option<usize>,
    /// Index of its link in the frame names.
    pub frame: usize,
    /// Radius (m).
    pub radius: f64,
    /// Core in the link frame (m).
    pub shape: CollisionShape,
}

/// A checked collision file.
#[derive(Clone, Debug, PartialEq)]
pub struct CollisionFile {
    /// The volumes, in file order.
    pub volumes: Vec<CollisionVolume>,
    /// The `exclude` lines as volume indices.
    pub excluded: Vec<(usize, usize)>,
    /// The pair capacity of the `capacity` line.
    pub pairs: usize,
}

/// The reasons an `exclude` line may give.
const REASONS: [&str; 4] = ["constant", "never_close", "always_near", "welded_parent"];

/// Parses the collision file `text` of a robot whose frames are at the origins of the links
/// `frames` and whose bodies are the child links `bodies`; `origin` names the file in errors,
/// `<origin>:<line>: <problem>`. Refused: an unknown keyword, a missing or extra field, a number
/// that does not parse, a negative or non-finite radius or a non-finite point, an unknown link or
/// body, a volume name twice, an exclusion of an unknown volume or with an unknown reason, and a
/// `capacity` line missing, repeated, after a volume or with another volume count.
pub fn parse_collision(text: &str, origin: &str, frames: &[&str], bodies: &[&str]) -> Result<CollisionFile, String> {
    let mut parser = Parser { frames, bodies, capacity: None, volumes: Vec::new(), index: HashMap::new() };
    let mut excluded = Vec::new();
    for (number, line) in text.lines().enumerate() {
        let fields: Vec<&str> = line.split('#').next().unwrap_or_default().split_whitespace().collect();
        let result = match fields.split_first() {
            None => Ok(()),
            Some((&"capacity", rest)) => parser.capacity(rest),
            Some((&"exclude", rest)) => parser.exclusion(rest).map(|pair| excluded.push(pair)),
            Some((keyword, rest)) => parser.volume(keyword, rest),
        };
        result.map_err(|problem| format!("{origin}:{}: {problem}", number + 1))?;
    }
    let (volumes, pairs) = parser.capacity.ok_or_else(|| format!("{origin}: no `capacity <volumes> <pairs>` line"))?;
    if volumes != parser.volumes.len() {
        return Err(format!("{origin}: capacity {volumes} volumes, but the file has {}", parser.volumes.len()));
    }
    Ok(CollisionFile { volumes: parser.volumes, excluded, pairs })
}

/// The state of [`parse_collision`].
struct Parser<'a> {
    frames: &'a [&'a str],
    bodies: &'a [&'a str],
    capacity: Option<(usize, usize)>,
    volumes: Vec<CollisionVolume>,
    index: HashMap<String, usize>,
}

impl Parser<'_> {
    fn capacity(&mut self, fields: &[&str]) -> Result<(), String> {
        let [volumes, pairs] = fields else { return Err("capacity: expected `capacity <volumes> <pairs>`".into()) };
        if self.capacity.is_some() || !self.volumes.is_empty() {
            return Err("capacity: once, before the volumes".into());
        }
        let count = |x: &str| x.parse::<usize>().map_err(|_| format!("capacity: {x} is not a count"));
        self.capacity = Some((count(volumes)?, count(pairs)?));
        Ok(())
    }

    fn volume(&mut self, keyword: &str, fields: &[&str]) -> Result<(), String> {
        let points = match keyword {
            "sphere" => 1,
            "capsule" => 2,
            "triangle" => 3,
            _ => return Err(format!("unknown line `{keyword}` (capacity, sphere, capsule, triangle or exclude)")),
        };
        let [name, group, link, radius, coordinates @ ..] = fields else {
            return Err(format!("{keyword}: expected <name> <group> <link> <radius> and {points} points"));
        };
        let context = format!("volume {name}");
        if coordinates.len() != 3 * points {
            return Err(format!(
                "{context}: a {keyword} has {points} points of x y z, found {} numbers",
                coordinates.len()
            ));
        }
        if self.capacity.is_none() {
            return Err(format!("{context}: the `capacity` line comes first"));
        }
        let frame = position(self.frames, link).ok_or_else(|| format!("{context}: unknown link {link}"))?;
        let body = match *group {
            "world" => None,
            _ => Some(position(self.bodies, group).ok_or_else(|| format!("{context}: unknown body {group}"))?),
        };
        let radius = number(radius, &context)?;
        if !(radius.is_finite() && radius >= 0.0) {
            return Err(format!("{context}: radius {radius} is not finite and non-negative"));
        }
        let values = coordinates.iter().map(|x| number(x, &context)).collect::<Result<Vec<f64>, String>>()?;
        if values.iter().any(|x| !x.is_finite()) {
            return Err(format!("{context}: a point is not finite"));
        }
        let point = |k: usize| -> [f64; 3] { core::array::from_fn(|i| values.get(3 * k + i).copied().unwrap_or(0.0)) };
        let shape = match points {
            1 => CollisionShape::Sphere(point(0)),
            2 => CollisionShape::Capsule([point(0), point(1)]),
            _ => CollisionShape::Triangle([point(0), point(1), point(2)]),
        };
        if self.index.insert((*name).to_owned(), self.volumes.len()).is_some() {
            return Err(format!("{context}: the name is taken"));
        }
        self.volumes.push(CollisionVolume { name: (*name).to_owned(), body, frame, radius, shape });
        Ok(())
    }

    fn exclusion(&self, fields: &[&str]) -> Result<(usize, usize), String> {
        let [first, second, reason] = fields else { return Err("exclude: expected <volume> <volume> <reason>".into()) };
        let volume =
            |name: &str| self.index.get(name).copied().ok_or_else(|| format!("exclude: unknown volume {name}"));
        if !REASONS.contains(reason) {
            return Err(format!("exclude: unknown reason {reason} ({})", REASONS.join(", ")));
        }
        Ok((volume(first)?, volume(second)?))
    }
}

fn position(names: &[&str], name: &str) -> Option<usize> {
    names.iter().position(|n| *n == name)
}

fn number(text: &str, context: &str) -> Result<f64, String> {
    text.parse().map_err(|_| format!("{context}: {text} is not a number"))
}

/// The Rust of the constructor module (`no_std`; included into `fixtures::robots::<name>::collision`,
/// whose parent module has the robot's `RobotModel`): `VOLUMES`, `PAIRS`, the volume table, the
/// exclusions and `collision_model`. `origin` names the file in the docs.
pub fn collision_source(file: &CollisionFile, origin: &str) -> String {
    let mut s = format!("// Generated by fixtures/build.rs from {origin}. Do not edit.\n\n");
    s.push_str("use kernel::tasks::collision::{CollisionError, CollisionModel, VolumeId};\n");
    s.push_str("use kernel::{BodyId, FrameId};\nuse nalgebra::RealField;\n\n");
    s.push_str("use crate::collision_table::{self, Shape, VolumeSpec};\n\n");
    s.push_str(&format!("/// Number of volumes.\npub const VOLUMES: usize = {};\n", file.volumes.len()));
    s.push_str(&format!(
        "/// Capacity of enabled pairs (what the kernel's rules and [`EXCLUDED`] leave).\npub const PAIRS: usize = {};\n",
        file.pairs
    ));
    s.push_str("/// The robot's collision model type.\n");
    s.push_str("pub type RobotCollisionModel<T> = CollisionModel<T, VOLUMES, PAIRS>;\n\n");
    s.push_str("/// The volumes, in [`VolumeId`] order (the file's).\n");
    s.push_str("pub const VOLUME_SPECS: [VolumeSpec; VOLUMES] = [\n");
    for v in &file.volumes {
        let body = v.body.map_or("None".to_owned(), |b| format!("Some(BodyId({b}))"));
        let _ = writeln!(
            s,
            "    VolumeSpec {{ name: {:?}, link: FrameId({}), body: {body}, radius: {:?}, shape: {} }},",
            v.name,
            v.frame,
            v.radius,
            shape_source(&v.shape)
        );
    }
    s.push_str("];\n\n");
    s.push_str(&format!(
        "/// The file's `exclude` lines.\npub const EXCLUDED: [(VolumeId, VolumeId); {}] = [\n",
        file.excluded.len()
    ));
    for (a, b) in &file.excluded {
        let _ = writeln!(s, "    (VolumeId({a}), VolumeId({b})),");
    }
    s.push_str("];\n\n");
    s.push_str("/// The collision model of `model` (`super::model`): [`VOLUME_SPECS`] on their bodies, every pair\n");
    s.push_str("/// enabled but the kernel's rules and [`EXCLUDED`].\n");
    s.push_str("pub fn collision_model<T: RealField + Copy>(\n    model: &super::RobotModel<T>,\n");
    s.push_str(") -> Result<RobotCollisionModel<T>, CollisionError> {\n");
    s.push_str("    collision_table::build(model, &VOLUME_SPECS, &EXCLUDED)\n}\n");
    s
}

fn shape_source(shape: &CollisionShape) -> String {
    match shape {
        CollisionShape::Sphere(p) => format!("Shape::Sphere({p:?})"),
        CollisionShape::Capsule(p) => format!("Shape::Capsule({p:?})"),
        CollisionShape::Triangle(p) => format!("Shape::Triangle({p:?})"),
    }
}
