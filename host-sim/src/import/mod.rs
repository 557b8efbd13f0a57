//! `host-sim import`: a robot's URDF → everything the repository keeps for it under
//! `fixtures/robots/<name>/`.
//!
//! 1. **Controlled joints.** The joints on the chains from the root link to the TCP links are the
//!    robot's coordinates. Every other movable joint (head, wheels, casters, grippers) is frozen:
//!    its `type` becomes `fixed` (at zero, so its `<origin>` is the placement), its `<mimic>` and
//!    `<coupling>` are dropped, and its child link is merged into the controlled body like any
//!    fixed link. On a fixed base the links welded to the world (the root and the links fixed
//!    to it) lose their `<inertial>`: it never enters the dynamics. `--base planar` adds the
//!    platform coordinates `base_x`, `base_y` (prismatic) and `base_theta` (continuous) between
//!    a new root link `world` and the URDF's root.
//! 2. **Model.** The prepared URDF goes through the same loader ([`crate::urdf`]) and the same
//!    code generator ([`crate::codegen`]) as Justin's, into `mod.rs`, a module of
//!    `fixtures::robots` (the index `fixtures/robots/mod.rs` is rewritten to list every robot).
//! 3. **Collision model** ([`collision`]): swept-sphere volumes fitted to the URDF's
//!    `<collision>` geometry, less those inside another volume of their body, and the pair survey, written to `<name>.collision` in the format of
//!    `fixtures/collision/justin.collision` with a `capacity` line; `mod.rs` gets the module
//!    `collision`, which `fixtures/build.rs` compiles from that file (`collision_model::<T>(&model)`).
//!    [`collision_model`] gives the same fit on the bodies, for the constructor's test.
//! 4. **Layout** ([`layout`]): one arm per TCP, the torso and the platform, derived from the
//!    chains to the TCPs, as `JOINTS`, `ARMS`, `ARM_COORDINATES`, `TORSO_COORDINATES` and
//!    `layout()` in `mod.rs`.
//! 5. **Configuration** ([`config`]): the default `config.toml` (the rule from the model is in
//!    its module docs), validated by `robot-config`; `fixtures/build.rs` compiles it into the
//!    module `config` of `mod.rs`.
//! 6. **Scenario entries**: `HOME` (the posture the generic scenarios start from: `--scenario-home`,
//!    else `--home`, else the gain rule's mid-range posture) and `ELBOW` (the frame of
//!    `layout::elbow`) in `mod.rs`; the index lists every robot in the macro
//!    `fixtures::for_each_imported_robot!`, from which `host-sim`'s `--robot` values and dispatch
//!    are built, so an imported robot runs the generic scenarios after a rebuild, with no Rust edit.
//! 7. **`README.md`**: the command, the controlled, frozen and TCP frames, the collision model.
//!
//! [`generate`] computes the files without writing them (the tests compare them with the
//! checked-in copies); [`run`] writes them.

pub mod collision;
pub mod config;
pub mod layout;

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use crate::codegen::{self, Module, RobotModule};
use crate::urdf::{self, Coupling, Description};

/// Repository-relative directory of the imported robots.
pub const ROBOTS_DIR: &str = "fixtures/robots";

/// Platform limits `--base planar` gives its coordinates: position (m), velocity (m/s, rad/s)
/// and effort (N, Nm) of `base_x`/`base_y` and of `base_theta`. Justin's platform values
/// (`fixtures/JUSTIN.md` §4).
const PLANAR_LIMITS: [(&str, &str, &str, f64, f64); 3] = [
    ("base_x", "prismatic", "1 0 0", 1.1, 1000.0),
    ("base_y", "prismatic", "0 1 0", 1.1, 1000.0),
    ("base_theta", "continuous", "0 0 1", 2.1, 500.0),
];
/// Position range of the planar translations (m): a room-sized floor.
const PLANAR_RANGE_M: f64 = 100.0;
/// The massless links `--base planar` adds between `world` and the URDF's root, moved by
/// `base_x` and `base_y`.
const PLANAR_TRANSLATION_LINKS: [&str; 2] = ["base_x_link", "base_y_link"];

/// What to import.
#[derive(Clone, Debug)]
pub struct ImportOptions {
    /// Repository root: the paths below are relative to it.
    pub root: PathBuf,
    /// The URDF file, as given on the command line.
    pub urdf: String,
    /// Robot name: the directory under [`ROBOTS_DIR`] and the Rust module (a lower-case identifier).
    pub name: String,
    /// TCP links, at least one.
    pub tcps: Vec<String>,
    /// Add the planar platform coordinates `x, y, θ`.
    pub planar_base: bool,
    /// Directory that holds the ROS packages `package://` mesh URIs name (`<dir>/<package>/…`).
    pub package_path: Option<String>,
    /// The posture of the gain rule (one value per coordinate, rad or m, inside the limits);
    /// `None`: the middle of every joint's range ([`config`]).
    pub home: Option<Vec<f64>>,
    /// The posture the generic scenarios start from (`HOME` in `mod.rs`, one value per
    /// coordinate, inside the limits); `None`: [`Self::home`], else the gain rule's posture.
    /// It leaves the gains alone.
    pub scenario_home: Option<Vec<f64>>,
}

impl ImportOptions {
    /// The command line that reproduces this import (written into the generated files).
    pub fn command(&self) -> String {
        let mut command =
            format!("cargo run -p host-sim --release -- import --urdf {} --name {}", self.urdf, self.name);
        for tcp in &self.tcps {
            command.push_str(&format!(" --tcp {tcp}"));
        }
        if self.planar_base {
            command.push_str(" --base planar");
        }
        if let Some(dir) = &self.package_path {
            command.push_str(&format!(" --package-path {dir}"));
        }
        for (option, home) in self.postures() {
            let values: Vec<String> = home.iter().map(f64::to_string).collect();
            command.push_str(&format!(" {option}={}", values.join(",")));
        }
        command
    }

    /// The postures given on the command line, with their options: `--home`, `--scenario-home`.
    fn postures(&self) -> impl Iterator<Item = (&'static str, &[f64])> {
        [("--home", &self.home), ("--scenario-home", &self.scenario_home)]
            .into_iter()
            .filter_map(|(option, home)| home.as_deref().map(|home| (option, home)))
    }

    /// The robot's directory.
    pub fn directory(&self) -> PathBuf {
        self.root.join(ROBOTS_DIR).join(&self.name)
    }
}

/// The generated files of one robot: `(file name, contents)` in its directory.
pub type Files = Vec<(String, String)>;

/// Generates the files of the robot without writing them.
///
/// Errors (one line each): unreadable or malformed URDF (every loader error of
/// [`crate::urdf::load`], a kinematic loop among them), an invalid name, no or an unknown TCP
/// link, a floating or planar joint on a controlled chain, a controlled joint coupled to a frozen
/// one, a negative mass, a controlled body without mass, a link name that is no Rust identifier
/// or clashes with a generated constant, a mesh that cannot be read.
pub fn generate(options: &ImportOptions) -> Result<Files, String> {
    check_identifier(&options.name, "robot name")?;
    if options.name.chars().any(|c| c.is_ascii_uppercase()) {
        return Err(format!("robot name {}: use lower case (it is a Rust module name)", options.name));
    }
    if options.name == "justin" {
        return Err(
            "robot name justin is taken: `--robot justin` is the Justin-like robot of fixtures::justin".to_owned()
        );
    }
    if options.tcps.is_empty() {
        return Err("no TCP frame: give at least one --tcp <link>".to_owned());
    }
    let (prepared, description) = described(options)?;
    let module = RobotModule {
        command: options.command(),
        frozen_joints: prepared.frozen.clone(),
        tcps: options.tcps.clone(),
        planar_base: options.planar_base,
    };
    let robot_layout = layout::derive(&description, &options.tcps, options.planar_base)?;
    for (option, home) in options.postures() {
        check_home(&description, option, home)?;
    }
    let scenario_home = options
        .scenario_home
        .clone()
        .or_else(|| options.home.clone())
        .unwrap_or_else(|| config::mid_range(&description));
    let config_file =
        config::default_file(&options.name, &description, &robot_layout, &options.tcps, options.home.as_deref())?;
    let source = codegen::model_source(&description, &options.urdf, &Module::Robot(&module))
        + &layout::source(&robot_layout)
        + &scenario_source(&scenario_home, layout::elbow(&description, &robot_layout)?)
        + &config::module_source(&options.name, &robot_layout)
        + &collision::module_source(&options.name);
    let (fitted, survey) = fitted_collision(options, &prepared, &description)?;
    let collision_file = collision::file(options, &description, &fitted, &survey)?;
    let readme = readme(options, &description, &module, &prepared.welded, &fitted, &survey);
    Ok(vec![
        ("mod.rs".to_owned(), source),
        (format!("{}.collision", options.name), collision_file),
        ("README.md".to_owned(), readme),
        ("config.toml".to_owned(), config_file),
    ])
}

/// The collision model the import fits to the robot of `options` (what `<name>.collision` holds).
pub fn collision_model(options: &ImportOptions) -> Result<collision::Imported, String> {
    let (prepared, description) = described(options)?;
    let (fitted, survey) = fitted_collision(options, &prepared, &description)?;
    collision::imported(&description, &fitted, &survey)
}

/// The generated `HOME` and `ELBOW` (module docs, step 6).
fn scenario_source(home: &[f64], elbow: &str) -> String {
    let values: Vec<String> = home.iter().map(|q| format!("{q:?}")).collect();
    format!(
        "\n/// The posture the generic scenarios start from (rad, m; `--scenario-home`, else `--home`, else mid-range).\n\
         pub const HOME: [f64; N] = [{}];\n\
         /// Where the generic scenario `posture_push` pushes: link `{elbow}`, the body of arm 0's middle coordinate.\n\
         pub const ELBOW: FrameId = {};\n",
        values.join(", "),
        elbow.to_uppercase()
    )
}

/// A posture drawn uniformly within every coordinate's limits (±π where a limit is infinite):
/// the sampled surveys of the collision pairs and of the singularity rule.
pub(crate) fn random_posture(description: &Description, rng: &mut rand::rngs::Xoshiro256PlusPlus) -> Vec<f64> {
    use rand::RngExt;
    description
        .coordinates
        .iter()
        .map(|c| {
            let (lo, hi) = if c.lower.is_finite() && c.upper.is_finite() {
                (c.lower, c.upper)
            } else {
                (-std::f64::consts::PI, std::f64::consts::PI)
            };
            rng.random_range(lo..=hi)
        })
        .collect()
}

/// `--home` or `--scenario-home` (`option`): one value per coordinate, each inside its joint's
/// limits.
fn check_home(description: &Description, option: &str, home: &[f64]) -> Result<(), String> {
    let coordinates = &description.coordinates;
    if home.len() != coordinates.len() {
        let names: Vec<&str> = coordinates.iter().map(|c| c.joint.as_str()).collect();
        return Err(format!(
            "{option}: {} values for the {} coordinates ({})",
            home.len(),
            coordinates.len(),
            names.join(", ")
        ));
    }
    for (c, q) in coordinates.iter().zip(home) {
        if !(c.lower..=c.upper).contains(q) {
            return Err(format!("{option}: {} = {q} is outside its limits [{}, {}]", c.joint, c.lower, c.upper));
        }
    }
    Ok(())
}

/// The URDF of `options`, prepared and described.
fn described(options: &ImportOptions) -> Result<(Prepared, Description), String> {
    let path = options.root.join(&options.urdf);
    let text = std::fs::read_to_string(&path).map_err(|e| format!("cannot read URDF {}: {e}", path.display()))?;
    describe(&text, &options.tcps, options.planar_base).map_err(|e| format!("{}: {e}", options.urdf))
}

/// The fitted volumes (less the contained ones) and the pair survey.
fn fitted_collision(
    options: &ImportOptions,
    prepared: &Prepared,
    description: &Description,
) -> Result<(collision::Fitted, collision::Survey), String> {
    let packages = options.package_path.as_ref().map(|dir| options.root.join(dir));
    let robot = urdf_rs::read_from_string(&prepared.text).map_err(|e| format!("{}: {e}", options.urdf))?;
    let fitted = collision::without_contained(description, collision::fit(&robot, packages.as_deref())?)?;
    let survey = collision::survey(description, &fitted.volumes)?;
    Ok((fitted, survey))
}

/// Imports the robot: writes its files and rewrites the index `fixtures/robots/mod.rs`.
pub fn run(options: &ImportOptions) -> Result<(), String> {
    let files = generate(options)?;
    let directory = options.directory();
    std::fs::create_dir_all(&directory).map_err(|e| format!("cannot create {}: {e}", directory.display()))?;
    for (name, contents) in &files {
        let path = directory.join(name);
        std::fs::write(&path, contents).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        println!("wrote {}", path.display());
    }
    let index = options.root.join(ROBOTS_DIR).join("mod.rs");
    let contents = robots_index(&options.root.join(ROBOTS_DIR))?;
    std::fs::write(&index, contents).map_err(|e| format!("cannot write {}: {e}", index.display()))?;
    println!("wrote {}; rebuild to use fixtures::robots::{}", index.display(), options.name);
    Ok(())
}

/// The index module `fixtures/robots/mod.rs`: one `pub mod` per robot directory with a `mod.rs`.
pub fn robots_index(robots_dir: &Path) -> Result<String, String> {
    let entries = std::fs::read_dir(robots_dir).map_err(|e| format!("cannot list {}: {e}", robots_dir.display()))?;
    let mut names: Vec<String> = entries
        .filter_map(Result::ok)
        .filter(|entry| entry.path().join("mod.rs").is_file())
        .filter_map(|entry| entry.file_name().into_string().ok())
        .collect();
    names.sort();
    let mut s = String::from(
        "//! Robots imported from their URDFs by `cargo run -p host-sim --release -- import`, one module\n\
         //! per directory of `fixtures/robots/`, each generated (see its `README.md`). This index is\n\
         //! rewritten by every import.\n",
    );
    for name in &names {
        s.push_str(&format!("\n#[rustfmt::skip]\npub mod {name};\n"));
    }
    let entries: Vec<String> = names.iter().map(|name| format!("{name} {}", camel_case(name))).collect();
    s.push_str(&format!(
        "\n/// Calls `$callback!` with every imported robot as `module Variant` (its module of\n\
         /// `fixtures::robots` and its name in camel case), comma-separated: `host-sim` builds its\n\
         /// `--robot` values and their dispatch from it.\n\
         #[macro_export]\n\
         macro_rules! for_each_imported_robot {{\n    \
         ($callback:ident) => {{\n        \
         $callback!({});\n    \
         }};\n\
         }}\n",
        entries.join(", ")
    ));
    Ok(s)
}

/// `tiago_dual` → `TiagoDual`.
fn camel_case(name: &str) -> String {
    name.split('_')
        .flat_map(|word| {
            let mut chars = word.chars();
            chars.next().map(|c| c.to_ascii_uppercase()).into_iter().chain(chars)
        })
        .collect()
}

/// The URDF prepared for the loader, and the joints it froze.
struct Prepared {
    text: String,
    /// Movable joints frozen at zero, in file order.
    frozen: Vec<String>,
    /// Links welded to the world (fixed base) whose `<inertial>` was dropped, in file order.
    welded: Vec<String>,
}

/// The prepared URDF and its description, checked: link names, and a mass on every controlled
/// body.
fn describe(text: &str, tcps: &[String], planar_base: bool) -> Result<(Prepared, Description), String> {
    let prepared = prepare(text, tcps, planar_base)?;
    let description = urdf::describe(&prepared.text, Coupling::Coupled)?;
    check_names(&description)?;
    // The platform's translations move massless links; the platform's mass is on `base_theta`'s.
    let added = |link: &str| planar_base && PLANAR_TRANSLATION_LINKS.contains(&link);
    if let Some(body) = description.bodies.iter().find(|b| b.inertia.mass <= 0.0 && !added(&b.link)) {
        return Err(format!(
            "link {} (joint {}) has no mass, with the links fixed to it: a controlled body needs a positive mass",
            body.link, body.joint
        ));
    }
    Ok((prepared, description))
}

/// Freezes the joints off the chains to `tcps`, drops the inertia of the links welded to the
/// world (fixed base) and adds the planar base if asked.
fn prepare(text: &str, tcps: &[String], planar_base: bool) -> Result<Prepared, String> {
    let mut root: xml::Element = text.parse().map_err(|e| format!("malformed XML: {e}"))?;
    check_masses(&root)?;
    let joints = joint_elements(&root);
    let parent_joint: HashMap<&str, &JointElement> = joints.iter().map(|j| (j.child.as_str(), j)).collect();
    let links: HashSet<String> = root.get_children("link", None).filter_map(|l| attribute(l, "name")).collect();
    let mut controlled: HashSet<String> = HashSet::new();
    for tcp in tcps {
        if !links.contains(tcp) {
            return Err(format!("unknown TCP frame {tcp}: the URDF has no link of that name"));
        }
        let mut link = tcp.as_str();
        let mut steps = 0;
        while let Some(joint) = parent_joint.get(link) {
            if matches!(joint.kind.as_str(), "floating" | "planar") {
                return Err(format!(
                    "joint {} on the chain to TCP {tcp} is {}: only revolute, continuous, prismatic and fixed \
                     joints can be controlled (use --base planar for a mobile base)",
                    joint.name, joint.kind
                ));
            }
            controlled.insert(joint.name.clone());
            link = joint.parent.as_str();
            steps += 1;
            if steps > joints.len() {
                return Err(format!("kinematic loop on the chain to TCP {tcp}"));
            }
        }
    }
    let movable = |kind: &str| kind != "fixed";
    let frozen: Vec<String> =
        joints.iter().filter(|j| movable(&j.kind) && !controlled.contains(&j.name)).map(|j| j.name.clone()).collect();
    for joint in joints.iter().filter(|j| controlled.contains(&j.name)) {
        if let Some(source) = joint.mimic.as_ref().filter(|m| frozen.contains(m)) {
            return Err(format!("controlled joint {} mimics the frozen joint {source}", joint.name));
        }
    }
    freeze(&mut root, &frozen);
    let welded = if planar_base {
        add_planar_base(&mut root, &links)?;
        Vec::new()
    } else {
        drop_welded_inertia(&mut root)
    };
    Ok(Prepared { text: root.to_string(), frozen, welded })
}

/// Refuses a link with a negative `<mass>`.
fn check_masses(root: &xml::Element) -> Result<(), String> {
    for link in root.get_children("link", None) {
        let mass = link.get_child("inertial", None).and_then(|i| child_attribute(i, "mass", "value"));
        if let Some(value) = mass.filter(|m| m.trim().parse::<f64>().is_ok_and(|m| m < 0.0)) {
            let name = attribute(link, "name").unwrap_or_default();
            return Err(format!("link {name} has a negative mass ({value} kg)"));
        }
    }
    Ok(())
}

/// Drops the `<inertial>` of every link welded to the world (the root link and the links fixed
/// to it, frozen joints included): on a fixed base their inertia never enters `M`, `C` or `g`,
/// and the loader need not read it (TIAGo++'s antennas carry a non-physical one). Returns the
/// links whose inertial was dropped.
fn drop_welded_inertia(root: &mut xml::Element) -> Vec<String> {
    let joints = joint_elements(root);
    let children: HashSet<&str> = joints.iter().map(|j| j.child.as_str()).collect();
    let mut welded: HashSet<String> = root
        .get_children("link", None)
        .filter_map(|l| attribute(l, "name"))
        .filter(|name| !children.contains(name.as_str()))
        .collect();
    loop {
        let reached: Vec<String> = joints
            .iter()
            .filter(|j| j.kind == "fixed" && welded.contains(&j.parent) && !welded.contains(&j.child))
            .map(|j| j.child.clone())
            .collect();
        if reached.is_empty() {
            break;
        }
        welded.extend(reached);
    }
    let mut dropped = Vec::new();
    for child in &mut root.children {
        let xml::Xml::ElementNode(link) = child else { continue };
        let name = attribute(link, "name").unwrap_or_default();
        if link.name != "link" || !welded.contains(&name) || link.get_child("inertial", None).is_none() {
            continue;
        }
        link.children.retain(|c| !matches!(c, xml::Xml::ElementNode(e) if e.name == "inertial"));
        dropped.push(name);
    }
    dropped
}

/// A `<joint>` element's names.
struct JointElement {
    name: String,
    kind: String,
    parent: String,
    child: String,
    mimic: Option<String>,
}

fn attribute(element: &xml::Element, name: &str) -> Option<String> {
    element.get_attribute(name, None).map(str::to_owned)
}

fn child_attribute(element: &xml::Element, child: &str, name: &str) -> Option<String> {
    element.get_child(child, None).and_then(|c| attribute(c, name))
}

fn joint_elements(root: &xml::Element) -> Vec<JointElement> {
    root.get_children("joint", None)
        .map(|j| JointElement {
            name: attribute(j, "name").unwrap_or_default(),
            kind: attribute(j, "type").unwrap_or_default(),
            parent: child_attribute(j, "parent", "link").unwrap_or_default(),
            child: child_attribute(j, "child", "link").unwrap_or_default(),
            mimic: child_attribute(j, "mimic", "joint"),
        })
        .collect()
}

/// Makes the `frozen` joints fixed (without `<mimic>`) and drops their `<coupling>` elements.
fn freeze(root: &mut xml::Element, frozen: &[String]) {
    let is_frozen = |e: &xml::Element, key: &str| attribute(e, key).is_some_and(|name| frozen.contains(&name));
    root.children.retain(|child| match child {
        xml::Xml::ElementNode(e) => !(e.name == "coupling" && is_frozen(e, "joint")),
        _ => true,
    });
    for child in &mut root.children {
        let xml::Xml::ElementNode(joint) = child else { continue };
        if joint.name != "joint" || !is_frozen(joint, "name") {
            continue;
        }
        joint.set_attribute("type".to_owned(), None, "fixed".to_owned());
        joint.children.retain(|c| !matches!(c, xml::Xml::ElementNode(e) if e.name == "mimic"));
    }
}

/// Adds `world ─base_x─ base_x_link ─base_y─ base_y_link ─base_theta─ <root link>`.
fn add_planar_base(root: &mut xml::Element, links: &HashSet<String>) -> Result<(), String> {
    let joints = joint_elements(root);
    let children: HashSet<&str> = joints.iter().map(|j| j.child.as_str()).collect();
    let mut roots = links.iter().filter(|l| !children.contains(l.as_str()));
    let (Some(robot_root), None) = (roots.next(), roots.next()) else {
        return Err("--base planar needs exactly one root link".to_owned());
    };
    let [x_link, y_link] = PLANAR_TRANSLATION_LINKS;
    let chain = ["world", x_link, y_link, robot_root.as_str()];
    if let Some(taken) = chain.iter().take(3).find(|name| links.contains(**name)) {
        return Err(format!("--base planar adds a link {taken}, but the URDF already has one"));
    }
    let mut snippet =
        format!("<robot name=\"base\"><link name=\"world\"/><link name=\"{x_link}\"/><link name=\"{y_link}\"/>");
    for (k, (name, kind, axis, velocity, effort)) in PLANAR_LIMITS.iter().enumerate() {
        let (parent, child) =
            (chain.get(k).copied().unwrap_or_default(), chain.get(k + 1).copied().unwrap_or_default());
        let range = if *kind == "prismatic" {
            format!("lower=\"-{PLANAR_RANGE_M}\" upper=\"{PLANAR_RANGE_M}\" ")
        } else {
            String::new()
        };
        snippet.push_str(&format!(
            "<joint name=\"{name}\" type=\"{kind}\"><parent link=\"{parent}\"/><child link=\"{child}\"/>\
             <axis xyz=\"{axis}\"/><limit {range}velocity=\"{velocity}\" effort=\"{effort}\"/></joint>"
        ));
    }
    snippet.push_str("</robot>");
    let base: xml::Element = snippet.parse().map_err(|e| format!("internal: planar base XML: {e}"))?;
    root.children.extend(base.children);
    Ok(())
}

/// Checks that `name` is a Rust identifier (letters, digits, underscores; not starting with a digit).
fn check_identifier(name: &str, what: &str) -> Result<(), String> {
    let mut chars = name.chars();
    let first_ok = chars.next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_');
    if first_ok && chars.all(|c| c.is_ascii_alphanumeric() || c == '_') {
        Ok(())
    } else {
        Err(format!("{what} {name:?} is not a Rust identifier (letters, digits and underscores)"))
    }
}

/// Every link name gives a distinct constant that clashes with none the module defines.
fn check_names(d: &Description) -> Result<(), String> {
    const RESERVED: [&str; 14] = [
        "N",
        "JOINTS",
        "BODIES",
        "FRAMES",
        "FROZEN_JOINTS",
        "TCPS",
        "JOINT_NAMES",
        "FRAME_NAMES",
        "BODY_NAMES",
        "ARMS",
        "ARM_COORDINATES",
        "TORSO_COORDINATES",
        "HOME",
        "ELBOW",
    ];
    let mut seen = HashSet::new();
    for frame in &d.frames {
        check_identifier(&frame.link, "link name")?;
        let constant = frame.link.to_uppercase();
        if RESERVED.contains(&constant.as_str()) || !seen.insert(constant.clone()) {
            return Err(format!("link name {} gives the constant {constant}, which is taken", frame.link));
        }
    }
    Ok(())
}

/// `README.md` of an imported robot.
fn readme(
    options: &ImportOptions,
    d: &Description,
    module: &RobotModule,
    welded: &[String],
    fitted: &collision::Fitted,
    survey: &collision::Survey,
) -> String {
    let list = |names: &[String]| {
        if names.is_empty() {
            "none".to_owned()
        } else {
            names.iter().map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", ")
        }
    };
    let joints: Vec<String> = d.coordinates.iter().map(|c| c.joint.clone()).collect();
    let name = &options.name;
    let mut s = format!("# {name}: imported from `{}`\n\n", options.urdf);
    s.push_str("Generated by `host-sim import` (`host-sim/src/import/`); do not edit. Regenerate with:\n\n");
    s.push_str(&format!("```sh\n{}\n```\n\n", options.command()));
    s.push_str("| file | what |\n| --- | --- |\n");
    s.push_str(&format!(
        "| `mod.rs` | the `no_std` model constructor `fixtures::robots::{name}::model::<T>()` (N = {}, {} bodies, {} frames) |\n",
        d.coordinates.len(),
        d.bodies.len(),
        d.frames.len()
    ));
    s.push_str(&format!(
        "| `{name}.collision` | swept-sphere collision model ({} volumes) and its pair exclusions ({} listed, {} pairs enabled) |\n\n",
        fitted.volumes.len(),
        survey.excluded.len(),
        survey.enabled.len()
    ));
    s.push_str(&format!(
        "**Controlled joints** (the chains from the root link to the TCPs, in coordinate order): {}.\n\n",
        list(&joints)
    ));
    if module.planar_base {
        s.push_str(&format!(
            "`--base planar` added `base_x`, `base_y` (±{PLANAR_RANGE_M} m, 1.1 m/s, 1000 N) and `base_theta` \
             (continuous, 2.1 rad/s, 500 Nm): Justin's platform limits.\n\n"
        ));
    }
    s.push_str(&format!(
        "**Frozen joints** (fixed at zero; their links are merged into the controlled bodies): {}.\n\n",
        list(&module.frozen_joints)
    ));
    if !module.planar_base {
        s.push_str(&format!(
            "**Welded to the world** (fixed base: their inertia never enters the dynamics, so the import drops it): {}.\n\n",
            list(welded)
        ));
    }
    s.push_str(&format!("**TCP frames**: {}.\n\n", list(&module.tcps)));
    s.push_str(&collision::readme_section(fitted));
    s
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "test code: failures should panic")]
mod tests {
    use super::*;

    /// base ─j1─ a ─j2─ b (tcp) and a ─g─ finger (gripper), a ─h─ head on base.
    const URDF: &str = r#"<robot name="r">
        <link name="base"/><link name="a"/><link name="b"/><link name="finger"/><link name="head"/>
        <joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
          <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
        <joint name="j2" type="revolute"><parent link="a"/><child link="b"/>
          <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
        <joint name="g" type="prismatic"><parent link="b"/><child link="finger"/>
          <limit lower="0" upper="1" effort="1" velocity="1"/></joint>
        <joint name="h" type="continuous"><parent link="base"/><child link="head"/></joint>
    </robot>"#;

    #[test]
    fn joints_off_the_chains_are_frozen() {
        let prepared = prepare(URDF, &["b".to_owned()], false).unwrap();
        assert_eq!(prepared.frozen, ["g", "h"]);
        let d = urdf::describe(&prepared.text, Coupling::Coupled).unwrap();
        let joints: Vec<&str> = d.coordinates.iter().map(|c| c.joint.as_str()).collect();
        assert_eq!(joints, ["j1", "j2"]);
        assert_eq!(d.frames.len(), 5);
    }

    #[test]
    fn planar_base_adds_three_coordinates_first() {
        let prepared = prepare(URDF, &["finger".to_owned()], true).unwrap();
        assert_eq!(prepared.frozen, ["h"]);
        let d = urdf::describe(&prepared.text, Coupling::Coupled).unwrap();
        let joints: Vec<&str> = d.coordinates.iter().map(|c| c.joint.as_str()).collect();
        assert_eq!(joints, ["base_x", "base_y", "base_theta", "j1", "j2", "g"]);
        assert_eq!((d.coordinates[0].lower, d.coordinates[0].upper, d.coordinates[2].velocity), (-100.0, 100.0, 2.1));
        // The added translation links carry no mass; a massless link of the robot still fails.
        assert!(describe(&with_masses(&[]), &["finger".to_owned()], true).is_ok());
        let error = describe(&with_masses(&[("a", "0")]), &["finger".to_owned()], true).err().unwrap();
        assert!(error.contains("link a (joint j1) has no mass"), "{error}");
    }

    /// `URDF` with a point mass on every link: 1 kg, or the mass `masses` gives the link.
    fn with_masses(masses: &[(&str, &str)]) -> String {
        ["base", "a", "b", "finger", "head"].iter().fold(URDF.to_owned(), |text, link| {
            let mass = masses.iter().find(|(l, _)| l == link).map_or("1", |(_, m)| m);
            text.replace(
                &format!("<link name=\"{link}\"/>"),
                &format!(
                    "<link name=\"{link}\"><inertial><mass value=\"{mass}\"/>\
                     <inertia ixx=\"0\" ixy=\"0\" ixz=\"0\" iyy=\"0\" iyz=\"0\" izz=\"0\"/></inertial></link>"
                ),
            )
        })
    }

    /// The import's error for `text` with the TCP `b`; it is one line.
    fn error_of(text: &str) -> String {
        let error = describe(text, &["b".to_owned()], false).err().unwrap();
        assert!(!error.contains('\n'), "not one line: {error}");
        error
    }

    #[test]
    fn bad_input_gets_a_one_line_error() {
        assert!(describe(&with_masses(&[]), &["b".to_owned()], false).is_ok());
        let unknown = describe(&with_masses(&[]), &["nope".to_owned()], false).err().unwrap();
        assert_eq!(unknown, "unknown TCP frame nope: the URDF has no link of that name");
        for kind in ["floating", "planar"] {
            let text = with_masses(&[]).replace(r#"name="j2" type="revolute""#, &format!(r#"name="j2" type="{kind}""#));
            let error = error_of(&text);
            assert!(error.starts_with(&format!("joint j2 on the chain to TCP b is {kind}: only revolute")), "{error}");
        }
        let closing = r#"<joint name="back" type="revolute"><parent link="b"/><child link="a"/>
            <limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"#;
        let looped = error_of(&with_masses(&[]).replace("</robot>", closing));
        assert!(looped.contains("kinematic loop"), "{looped}");
        assert_eq!(error_of(&with_masses(&[("head", "-0.5")])), "link head has a negative mass (-0.5 kg)");
        // The frozen finger's mass counts for the last controlled body; without it the body is empty.
        assert!(describe(&with_masses(&[("b", "0")]), &["b".to_owned()], false).is_ok());
        assert_eq!(
            error_of(&with_masses(&[("b", "0"), ("finger", "0")])),
            "link b (joint j2) has no mass, with the links fixed to it: a controlled body needs a positive mass"
        );
        assert!(check_identifier("9lives", "robot name").is_err());
    }

    #[test]
    fn home_has_a_value_inside_the_limits_for_every_coordinate() {
        let prepared = prepare(&with_masses(&[]), &["b".to_owned()], false).unwrap();
        let d = urdf::describe(&prepared.text, Coupling::Coupled).unwrap();
        assert!(check_home(&d, "--home", &[0.5, -1.0]).is_ok());
        assert_eq!(check_home(&d, "--home", &[0.5]).unwrap_err(), "--home: 1 values for the 2 coordinates (j1, j2)");
        assert_eq!(
            check_home(&d, "--home", &[0.5, 1.5]).unwrap_err(),
            "--home: j2 = 1.5 is outside its limits [-1, 1]"
        );
    }

    #[test]
    fn links_welded_to_the_world_lose_their_inertia_on_a_fixed_base() {
        // The head joint h is frozen: head is welded to base; a and b move.
        let prepared = prepare(&with_masses(&[]), &["b".to_owned()], false).unwrap();
        assert_eq!(prepared.welded, ["base", "head"]);
        let d = urdf::describe(&prepared.text, Coupling::Coupled).unwrap();
        let masses: Vec<f64> = d.bodies.iter().map(|b| b.inertia.mass).collect();
        assert_eq!(masses, [1.0, 2.0], "a, then b with the frozen finger");
        // On a planar base the root moves: nothing is dropped.
        assert!(prepare(&with_masses(&[]), &["b".to_owned()], true).unwrap().welded.is_empty());
    }

    #[test]
    fn the_index_registers_every_robot_directory_for_the_generic_scenarios() {
        let dir = std::env::temp_dir().join(format!("robots_index_{}", std::process::id()));
        for robot in ["ur5", "tiago_dual", "justin"] {
            std::fs::create_dir_all(dir.join(robot)).unwrap();
        }
        std::fs::write(dir.join("ur5/mod.rs"), "").unwrap();
        std::fs::write(dir.join("tiago_dual/mod.rs"), "").unwrap();
        let index = robots_index(&dir).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(index.contains("pub mod tiago_dual;\n\n#[rustfmt::skip]\npub mod ur5;\n"), "{index}");
        assert!(index.contains("$callback!(tiago_dual TiagoDual, ur5 Ur5);"), "{index}");
        assert!(!index.contains("justin"), "a directory without mod.rs is no imported robot");
    }
}
