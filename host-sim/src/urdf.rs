//! URDF → kernel [`Model`]: the host-side loader of robot descriptions.
//!
//! The URDF is parsed with `urdf-rs`; the kinematic tree is walked depth-first from the root
//! link (the one link that is no joint's child), children in the order their joints appear in
//! the file. Each movable joint (revolute, prismatic, continuous = revolute without position
//! limits) becomes a body, in that order. **Fixed joints are merged**: the child link's inertia
//! is transformed into the parent body's frame and combined with it (links fixed to the root
//! link belong to the world and their inertia is dropped). Every link, including the root
//! link, becomes a frame at the link origin (world-fixed for the root group), so any link can
//! be named as a task or Jacobian frame. This is what Pinocchio's `buildModelFromUrdf` does for
//! a fixed base.
//!
//! Conventions: origin rotation `R = Rz(yaw) · Ry(pitch) · Rx(roll)`; the `<inertial>` origin
//! (including its `rpy`) places the inertia tensor, given about the centre of mass; links
//! without `<inertial>` are massless; the joint axis defaults to `(1, 0, 0)` and is
//! normalized; a missing `velocity` or `effort` limit is infinite; gravity is [`GRAVITY`].
//!
//! ## Coupled joints
//! With [`Coupling::Independent`] every movable joint is a generalized coordinate (Pinocchio's
//! default). With [`Coupling::Coupled`], URDF `<mimic>` joints and the joints named by the
//! project's `<coupling>` extension follow other coordinates through
//! [`kernel::model::JointDrive::coupled`] and get no coordinate of their own. The extension is
//! a top-level element of `<robot>` for a joint driven by several coordinates, e.g. the passive
//! torso joint of Rollin' Justin, `q_t4 = −(q_t2 + q_t3)` (3.41):
//!
//! ```xml
//! <coupling joint="torso_joint4" offset="0">
//!   <term joint="torso_joint2" multiplier="-1"/>
//!   <term joint="torso_joint3" multiplier="-1"/>
//! </coupling>
//! ```
//!
//! `urdf-rs` (like other URDF tools) ignores unknown top-level elements; this module reads the
//! `<coupling>` elements itself from the same text.
//!
//! Every error is a one-line message naming the problem; nothing here panics.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use kernel::model::{
    BodyId, Inertia, JointDrive, JointKind, JointLimits, ModelBuilder, ModelError, Placement, MAX_DRIVE_TERMS,
};
use kernel::{FrameId, Model};
use nalgebra::{Matrix3, Rotation3, Translation3, Unit, Vector3};
use urdf_rs::JointType;

/// Gravitational acceleration of every model loaded from a URDF (m/s², world frame): standard
/// gravity 9.81 m/s² along −z, as in Pinocchio and ROS.
pub const GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];

/// Whether `<mimic>` and `<coupling>` joints are coupled or get their own coordinate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Coupling {
    /// Every movable joint is its own coordinate; `<mimic>` and `<coupling>` are ignored (they
    /// are still checked to name existing joints). What Pinocchio does by default.
    Independent,
    /// `<mimic>` and `<coupling>` joints follow other coordinates and have none of their own.
    Coupled,
}

/// A robot loaded from a URDF: the kernel model plus the names the model itself does not keep.
#[derive(Clone, Debug)]
pub struct UrdfRobot<const N: usize, const B: usize, const F: usize> {
    /// The validated kernel model (gravity [`GRAVITY`]).
    pub model: Model<f64, N, B, F>,
    /// Name of the URDF joint of each generalized coordinate: `joint_names[k]` drives `q[k]`.
    pub joint_names: Vec<String>,
    /// Link name of each frame: `frame_names[i]` is the link at `FrameId(i)`'s origin.
    pub frame_names: Vec<String>,
    /// Link name of each body (the child link of the body's movable joint).
    pub body_names: Vec<String>,
}

impl<const N: usize, const B: usize, const F: usize> UrdfRobot<N, B, F> {
    /// The frame at the origin of link `link`, if the URDF has such a link.
    pub fn frame(&self, link: &str) -> Option<FrameId> {
        self.frame_names.iter().position(|name| name == link).map(FrameId)
    }

    /// The coordinate driven by joint `joint`, if it is one (not fixed, not coupled).
    pub fn coordinate(&self, joint: &str) -> Option<usize> {
        self.joint_names.iter().position(|name| name == joint)
    }
}

/// Loads the URDF file `path` as a model with `N` coordinates, at most `B` bodies and at most
/// `F` frames.
///
/// Errors (one line each): unreadable file, malformed XML or URDF, no single root link or a
/// kinematic loop, an unsupported joint type, a mimic or coupling naming an unknown joint, a
/// coordinate count other than `N`, more bodies than `B` or links than `F`, and every check of
/// [`ModelBuilder::try_build`] (reported with the link or joint name).
pub fn load<const N: usize, const B: usize, const F: usize>(
    path: &Path,
    coupling: Coupling,
) -> Result<UrdfRobot<N, B, F>, String> {
    build(&describe_file(path, coupling)?)
}

/// [`load`] from URDF text instead of a file.
///
/// ```
/// use host_sim::urdf::{load_str, Coupling};
/// // A 2 kg link on a revolute joint, with a 0.5 kg tool fixed to it (merged into the body).
/// let urdf = r#"<robot name="r">
///   <link name="base"/>
///   <link name="arm"><inertial><mass value="2"/>
///     <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
///   <link name="tool"><inertial><mass value="0.5"/>
///     <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
///   <joint name="shoulder" type="continuous">
///     <parent link="base"/><child link="arm"/><axis xyz="0 0 1"/></joint>
///   <joint name="flange" type="fixed">
///     <parent link="arm"/><child link="tool"/><origin xyz="0.4 0 0"/></joint>
/// </robot>"#;
/// let robot = load_str::<1, 1, 3>(urdf, Coupling::Independent).unwrap();
/// assert_eq!(robot.joint_names, ["shoulder"]);
/// assert_eq!(robot.model.bodies().len(), 1);
/// assert_eq!(robot.model.total_mass(), 2.5);
/// assert!(robot.frame("tool").is_some());
/// ```
pub fn load_str<const N: usize, const B: usize, const F: usize>(
    urdf: &str,
    coupling: Coupling,
) -> Result<UrdfRobot<N, B, F>, String> {
    build(&describe(urdf, coupling)?)
}

/// Number of generalized coordinates the URDF file has under `coupling`: the `N` to load it
/// with. Same errors as [`load`] except the size checks.
pub fn coordinate_count(path: &Path, coupling: Coupling) -> Result<usize, String> {
    Ok(describe_file(path, coupling)?.coordinates.len())
}

/// A size-independent description of the robot, the step between the URDF and a [`Model`].
#[derive(Clone, Debug)]
pub(crate) struct Description {
    pub(crate) bodies: Vec<BodySpec>,
    pub(crate) frames: Vec<FrameSpec>,
    pub(crate) coordinates: Vec<CoordinateSpec>,
}

impl Description {
    /// Number of generalized coordinates.
    pub(crate) fn coordinate_count(&self) -> usize {
        self.coordinates.len()
    }

    /// Link names of the frames, in frame order.
    pub(crate) fn frame_names(&self) -> impl Iterator<Item = &str> {
        self.frames.iter().map(|f| f.link.as_str())
    }
}

#[derive(Clone, Debug)]
pub(crate) struct BodySpec {
    pub(crate) link: String,
    pub(crate) joint: String,
    pub(crate) parent: Option<usize>,
    pub(crate) joint_placement: Placement<f64>,
    pub(crate) kind: JointKind<f64>,
    pub(crate) inertia: Inertia<f64>,
    /// `(coordinate, coefficient)` terms and offset of the joint's drive.
    pub(crate) terms: Vec<(usize, f64)>,
    pub(crate) offset: f64,
}

#[derive(Clone, Debug)]
pub(crate) struct FrameSpec {
    pub(crate) link: String,
    pub(crate) parent: Option<usize>,
    pub(crate) placement: Placement<f64>,
}

#[derive(Clone, Debug)]
pub(crate) struct CoordinateSpec {
    pub(crate) joint: String,
    pub(crate) lower: f64,
    pub(crate) upper: f64,
    pub(crate) velocity: f64,
    pub(crate) effort: f64,
}

/// One `<coupling>` element (or a `<mimic>`): `q_joint = Σ multiplier · q_term + offset`.
#[derive(Clone, Debug)]
struct CouplingSpec {
    terms: Vec<(String, f64)>,
    offset: f64,
    /// Where it came from, for error messages.
    source: &'static str,
}

/// Reads and describes a URDF file.
pub(crate) fn describe_file(path: &Path, coupling: Coupling) -> Result<Description, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read URDF {}: {e}", path.display()))?;
    describe(&text, coupling).map_err(|e| format!("{}: {e}", path.display()))
}

/// Parses URDF text into a [`Description`].
pub(crate) fn describe(text: &str, coupling: Coupling) -> Result<Description, String> {
    let pre = preprocess(text)?;
    let robot =
        urdf_rs::read_from_string(&pre.text).map_err(|e| format!("malformed URDF: {}", one_line(&e.to_string())))?;
    Tree::new(&robot)?.describe(&robot, &pre, coupling)
}

/// Builds the kernel model of a description.
pub(crate) fn build<const N: usize, const B: usize, const F: usize>(
    d: &Description,
) -> Result<UrdfRobot<N, B, F>, String> {
    if d.coordinates.len() != N {
        return Err(format!(
            "the URDF has {} generalized coordinates but the model is built for N = {N}",
            d.coordinates.len()
        ));
    }
    if d.bodies.len() > B {
        return Err(format!("the URDF has {} movable joints, more than the body capacity B = {B}", d.bodies.len()));
    }
    if d.frames.len() > F {
        return Err(format!("the URDF has {} links, more than the frame capacity F = {F}", d.frames.len()));
    }
    let [gx, gy, gz] = GRAVITY;
    let mut builder = ModelBuilder::<f64, N, B, F>::new(Vector3::new(gx, gy, gz));
    let model_error = |e: ModelError| describe_model_error(d, e);
    for body in &d.bodies {
        let drive = JointDrive::coupled(&body.terms, body.offset)
            .ok_or_else(|| format!("joint {} depends on more than {MAX_DRIVE_TERMS} coordinates", body.joint))?;
        builder
            .add_body(body.parent.map(BodyId), body.joint_placement, body.kind, drive, body.inertia)
            .map_err(model_error)?;
    }
    for frame in &d.frames {
        builder.add_frame(frame.parent.map(BodyId), frame.placement).map_err(model_error)?;
    }
    let mut limits = JointLimits::<f64, N>::unlimited();
    for (k, c) in d.coordinates.iter().enumerate() {
        let slots = (
            limits.position_lower.get_mut(k),
            limits.position_upper.get_mut(k),
            limits.velocity.get_mut(k),
            limits.effort.get_mut(k),
        );
        if let (Some(lower), Some(upper), Some(velocity), Some(effort)) = slots {
            (*lower, *upper, *velocity, *effort) = (c.lower, c.upper, c.velocity, c.effort);
        }
    }
    builder.limits(limits);
    let model = builder.try_build().map_err(model_error)?;
    Ok(UrdfRobot {
        model,
        joint_names: d.coordinates.iter().map(|c| c.joint.clone()).collect(),
        frame_names: d.frames.iter().map(|f| f.link.clone()).collect(),
        body_names: d.bodies.iter().map(|b| b.link.clone()).collect(),
    })
}

/// A kernel model error with the URDF names of the body or coordinate it refers to.
fn describe_model_error(d: &Description, e: ModelError) -> String {
    let body = |i: usize| {
        d.bodies.get(i).map_or_else(|| format!("body {i}"), |b| format!("link {} (joint {})", b.link, b.joint))
    };
    let coordinate =
        |k: usize| d.coordinates.get(k).map_or_else(|| format!("coordinate {k}"), |c| format!("joint {}", c.joint));
    match e {
        ModelError::NonPhysicalInertia { body: i } => format!("{}: inertia is not physical", body(i)),
        ModelError::UndrivenJoint { body: i } => format!("{}: joint driven by no coordinate", body(i)),
        ModelError::CoordinateOutOfRange { body: i, coordinate: k } => {
            format!("{}: coordinate {k} out of range", body(i))
        }
        ModelError::UndrivenCoordinate { coordinate: k } => {
            format!("{}: coordinate drives no joint (all coupling coefficients zero?)", coordinate(k))
        }
        ModelError::InvalidLimits { coordinate: k } => {
            format!("{}: invalid limits (lower > upper, negative velocity/effort, or NaN)", coordinate(k))
        }
        other => format!("invalid model: {other}"),
    }
}

/// The URDF text with the `<coupling>` elements read out and missing limits filled in.
struct Preprocessed {
    /// Text handed to `urdf-rs`.
    text: String,
    /// `<coupling>` elements by coupled joint name, in file order.
    couplings: Vec<(String, CouplingSpec)>,
    /// Joints that have a `<limit>` element.
    joints_with_limit: HashSet<String>,
}

/// Reads the project extensions from the raw XML and normalizes `<limit>` elements (a missing
/// `velocity` or `effort` becomes `inf`, which `urdf-rs` would otherwise reject or read as 0).
fn preprocess(text: &str) -> Result<Preprocessed, String> {
    let mut root: xml::Element = text.parse().map_err(|e| format!("malformed XML: {}", one_line(&format!("{e}"))))?;
    if root.name != "robot" {
        return Err(format!("malformed URDF: the root element is <{}>, expected <robot>", root.name));
    }
    drop_namespaces(&mut root)?;
    let mut couplings = Vec::new();
    let mut joints_with_limit = HashSet::new();
    for child in &mut root.children {
        let xml::Xml::ElementNode(element) = child else { continue };
        match element.name.as_str() {
            "coupling" => couplings.push(parse_coupling(element)?),
            "joint" => {
                let name = element.get_attribute("name", None).unwrap_or_default().to_owned();
                for limit in element.children.iter_mut() {
                    let xml::Xml::ElementNode(limit) = limit else { continue };
                    if limit.name != "limit" {
                        continue;
                    }
                    for attribute in ["velocity", "effort"] {
                        if limit.get_attribute(attribute, None).is_none() {
                            limit.set_attribute(attribute.to_owned(), None, "inf".to_owned());
                        }
                    }
                    joints_with_limit.insert(name.clone());
                }
            }
            _ => {}
        }
    }
    Ok(Preprocessed { text: root.to_string(), couplings, joints_with_limit })
}

/// The namespace of xacro's macros: a `.xacro` file still to be expanded.
const XACRO: &str = "http://www.ros.org/wiki/xacro";

/// Drops every namespaced attribute and element below the root: the namespace declarations
/// (xacro output still declares `xmlns:xacro`) and the simulators' extensions, which URDF
/// parsers ignore (Drake's `drake:acceleration` on `<limit>`, `<drake:joint>`), so that the
/// normalized text written back for `urdf-rs` names no namespace (`xml`'s writer panics on one
/// it cannot name, e.g. after a mangled `xmlns:` declaration). Refuses a root in a namespace and
/// an element of xacro's (a macro left unexpanded).
fn drop_namespaces(element: &mut xml::Element) -> Result<(), String> {
    if let Some(ns) = &element.ns {
        return Err(format!("malformed URDF: <{}> is in the XML namespace \"{ns}\" (URDF uses none)", element.name));
    }
    element.attributes.retain(|(_, ns), _| ns.is_none());
    let in_namespace = |child: &xml::Xml, namespace: Option<&str>| match child {
        xml::Xml::ElementNode(child) => child.ns.is_some() && (namespace.is_none() || child.ns.as_deref() == namespace),
        _ => false,
    };
    if let Some(xml::Xml::ElementNode(macro_element)) = element.children.iter().find(|c| in_namespace(c, Some(XACRO))) {
        return Err(format!(
            "malformed URDF: <xacro:{}> in the file: expand the .xacro to URDF first",
            macro_element.name
        ));
    }
    element.children.retain(|child| !in_namespace(child, None));
    element.children.iter_mut().try_for_each(|child| match child {
        xml::Xml::ElementNode(child) => drop_namespaces(child),
        _ => Ok(()),
    })
}

/// Parses `<coupling joint=".." offset=".."><term joint=".." multiplier=".."/>..</coupling>`.
fn parse_coupling(element: &xml::Element) -> Result<(String, CouplingSpec), String> {
    let joint = element.get_attribute("joint", None).ok_or("<coupling> element without a joint attribute")?.to_owned();
    let number = |e: &xml::Element, attribute: &str, default: f64| -> Result<f64, String> {
        match e.get_attribute(attribute, None) {
            None => Ok(default),
            Some(text) => match text.trim().parse::<f64>() {
                Ok(value) if value.is_finite() => Ok(value),
                _ => Err(format!("<coupling joint=\"{joint}\">: {attribute}=\"{text}\" is not a finite number")),
            },
        }
    };
    let offset = number(element, "offset", 0.0)?;
    let mut terms = Vec::new();
    for term in element.get_children("term", None) {
        let name = term
            .get_attribute("joint", None)
            .ok_or_else(|| format!("<coupling joint=\"{joint}\">: <term> without a joint attribute"))?;
        terms.push((name.to_owned(), number(term, "multiplier", 1.0)?));
    }
    if terms.is_empty() {
        return Err(format!("<coupling joint=\"{joint}\"> has no <term> elements"));
    }
    Ok((joint, CouplingSpec { terms, offset, source: "<coupling>" }))
}

/// Connectivity of the URDF: link and joint indices, child joints per link, the root.
struct Tree {
    joint_index: HashMap<String, usize>,
    /// `(parent link, child link)` of each joint.
    joint_links: Vec<(usize, usize)>,
    /// Child joints of each link, in file order.
    children: Vec<Vec<usize>>,
    root: usize,
}

impl Tree {
    fn new(robot: &urdf_rs::Robot) -> Result<Self, String> {
        let mut link_index = HashMap::new();
        for (i, link) in robot.links.iter().enumerate() {
            if link_index.insert(link.name.clone(), i).is_some() {
                return Err(format!("two links are named {}", link.name));
            }
        }
        let mut joint_index = HashMap::new();
        let mut joint_links = Vec::new();
        let mut children = vec![Vec::new(); robot.links.len()];
        let mut parent_joint: Vec<Option<usize>> = vec![None; robot.links.len()];
        for (j, joint) in robot.joints.iter().enumerate() {
            if joint_index.insert(joint.name.clone(), j).is_some() {
                return Err(format!("two joints are named {}", joint.name));
            }
            let find = |link: &str, role: &str| {
                link_index.get(link).copied().ok_or_else(|| format!("joint {}: unknown {role} link {link}", joint.name))
            };
            let (parent, child) = (find(&joint.parent.link, "parent")?, find(&joint.child.link, "child")?);
            let slot = parent_joint.get_mut(child).ok_or("internal: link index out of range")?;
            if let Some(other) = slot.replace(j) {
                let other = robot.joints.get(other).map_or("?", |o| o.name.as_str());
                return Err(format!(
                    "link {} is the child of two joints ({other} and {})",
                    joint.child.link, joint.name
                ));
            }
            children.get_mut(parent).ok_or("internal: link index out of range")?.push(j);
            joint_links.push((parent, child));
        }
        let roots: Vec<usize> = (0..robot.links.len()).filter(|&i| parent_joint.get(i) == Some(&None)).collect();
        let link_name = |i: usize| robot.links.get(i).map_or("?", |l| l.name.as_str());
        let root = match roots.as_slice() {
            [root] => *root,
            [] if robot.links.is_empty() => return Err("the URDF has no links".to_owned()),
            [] => return Err("no root link: every link is a joint's child (kinematic loop)".to_owned()),
            several => {
                let names: Vec<&str> = several.iter().map(|&i| link_name(i)).collect();
                return Err(format!("several root links (links that are no joint's child): {}", names.join(", ")));
            }
        };
        Ok(Self { joint_index, joint_links, children, root })
    }

    /// Walks the tree and produces the description.
    fn describe(&self, robot: &urdf_rs::Robot, pre: &Preprocessed, coupling: Coupling) -> Result<Description, String> {
        let link = |i: usize| robot.links.get(i).ok_or("internal: link index out of range");
        let joint = |j: usize| robot.joints.get(j).ok_or("internal: joint index out of range");
        let children = |i: usize| self.children.get(i).map_or(&[][..], Vec::as_slice);

        // Where each visited link sits: (body it is rigidly attached to, placement in it).
        let mut places: Vec<Option<(Option<usize>, Placement<f64>)>> = vec![None; robot.links.len()];
        let mut bodies: Vec<BodySpec> = Vec::new();
        let mut movable: Vec<usize> = Vec::new();
        let root = link(self.root)?;
        let mut frames = vec![FrameSpec { link: root.name.clone(), parent: None, placement: Placement::identity() }];
        if let Some(slot) = places.get_mut(self.root) {
            *slot = Some((None, Placement::identity()));
        }
        let mut stack: Vec<usize> = children(self.root).iter().rev().copied().collect();
        while let Some(j) = stack.pop() {
            let urdf_joint = joint(j)?;
            let &(parent, child) = self.joint_links.get(j).ok_or("internal: joint index out of range")?;
            let (body, in_body) = places
                .get(parent)
                .copied()
                .flatten()
                .ok_or_else(|| format!("joint {}: parent link not reached (kinematic loop)", urdf_joint.name))?;
            let child_link = link(child)?;
            let placement = in_body * pose(&urdf_joint.origin, &format!("joint {}", urdf_joint.name))?;
            let inertia = link_inertia(child_link)?;
            let axis = || joint_axis(urdf_joint);
            let kind = match urdf_joint.joint_type {
                JointType::Fixed => None,
                JointType::Revolute | JointType::Continuous => Some(JointKind::Revolute { axis: axis()? }),
                JointType::Prismatic => Some(JointKind::Prismatic { axis: axis()? }),
                ref other => {
                    return Err(format!(
                        "joint {}: unsupported joint type {other:?} (only revolute, continuous, prismatic and fixed)",
                        urdf_joint.name
                    ))
                }
            };
            let place = match kind {
                None => {
                    // Fixed joint: lump the child link into the parent body (or the world).
                    if let Some(b) = body.and_then(|b| bodies.get_mut(b)) {
                        b.inertia = b.inertia.combined(&inertia.transformed(&placement));
                    }
                    (body, placement)
                }
                Some(kind) => {
                    bodies.push(BodySpec {
                        link: child_link.name.clone(),
                        joint: urdf_joint.name.clone(),
                        parent: body,
                        joint_placement: placement,
                        kind,
                        inertia,
                        terms: Vec::new(),
                        offset: 0.0,
                    });
                    movable.push(j);
                    (Some(bodies.len() - 1), Placement::identity())
                }
            };
            frames.push(FrameSpec { link: child_link.name.clone(), parent: place.0, placement: place.1 });
            if let Some(slot) = places.get_mut(child) {
                *slot = Some(place);
            }
            stack.extend(children(child).iter().rev());
        }
        let unreached: Vec<&str> =
            robot.links.iter().zip(places.iter()).filter(|(_, p)| p.is_none()).map(|(l, _)| l.name.as_str()).collect();
        if !unreached.is_empty() {
            return Err(format!("links not connected to the root link (kinematic loop): {}", unreached.join(", ")));
        }

        let specs = self.coupling_specs(robot, pre)?;
        let coupled = |name: &str| coupling == Coupling::Coupled && specs.contains_key(name);
        let mut coordinates = Vec::new();
        let mut coordinate_of: HashMap<&str, usize> = HashMap::new();
        for &j in &movable {
            let urdf_joint = joint(j)?;
            if coupled(&urdf_joint.name) {
                continue;
            }
            let has_limit = pre.joints_with_limit.contains(&urdf_joint.name);
            let l = &urdf_joint.limit;
            let (lower, upper) = match urdf_joint.joint_type {
                JointType::Continuous => (f64::NEG_INFINITY, f64::INFINITY),
                _ if has_limit => (l.lower, l.upper),
                _ => {
                    let name = &urdf_joint.name;
                    return Err(format!("joint {name}: a revolute or prismatic joint needs a <limit> element"));
                }
            };
            let (velocity, effort) = if has_limit { (l.velocity, l.effort) } else { (f64::INFINITY, f64::INFINITY) };
            coordinate_of.insert(urdf_joint.name.as_str(), coordinates.len());
            coordinates.push(CoordinateSpec { joint: urdf_joint.name.clone(), lower, upper, velocity, effort });
        }
        for body in &mut bodies {
            let (terms, offset) = if coupled(&body.joint) {
                expand(&body.joint, &specs, &coordinate_of, robot.joints.len())?
            } else {
                let k = coordinate_of.get(body.joint.as_str()).copied().ok_or("internal: joint without coordinate")?;
                (vec![(k, 1.0)], 0.0)
            };
            body.terms = terms;
            body.offset = offset;
        }
        Ok(Description { bodies, frames, coordinates })
    }

    /// The `<mimic>` and `<coupling>` relations by coupled joint name, checked to name
    /// existing movable joints, at most one per joint.
    fn coupling_specs<'r>(
        &self,
        robot: &'r urdf_rs::Robot,
        pre: &Preprocessed,
    ) -> Result<HashMap<&'r str, CouplingSpec>, String> {
        let movable = |name: &str, context: &str| -> Result<&'r str, String> {
            let j = self.joint_index.get(name).ok_or_else(|| format!("{context}: unknown joint {name}"))?;
            let joint = robot.joints.get(*j).ok_or("internal: joint index out of range")?;
            if joint.joint_type == JointType::Fixed {
                return Err(format!("{context}: joint {name} is fixed"));
            }
            Ok(joint.name.as_str())
        };
        let mut specs: HashMap<&'r str, CouplingSpec> = HashMap::new();
        let mimics = robot.joints.iter().filter_map(|j| {
            let mimic = j.mimic.as_ref()?;
            let spec = CouplingSpec {
                terms: vec![(mimic.joint.clone(), mimic.multiplier.unwrap_or(1.0))],
                offset: mimic.offset.unwrap_or(0.0),
                source: "<mimic>",
            };
            Some((j.name.clone(), spec))
        });
        for (name, spec) in mimics.chain(pre.couplings.iter().cloned()) {
            let context = format!("{} of joint {name}", spec.source);
            let joint = movable(&name, &context)?;
            for (term, multiplier) in &spec.terms {
                movable(term, &context)?;
                if !multiplier.is_finite() {
                    return Err(format!("{context}: multiplier of {term} is not finite"));
                }
            }
            if !spec.offset.is_finite() {
                return Err(format!("{context}: offset is not finite"));
            }
            if let Some(previous) = specs.insert(joint, spec) {
                return Err(format!("joint {name} is coupled twice ({} and {})", previous.source, context));
            }
        }
        Ok(specs)
    }
}

/// The drive of coupled joint `joint` in coordinates: mimics of mimics are substituted.
fn expand(
    joint: &str,
    specs: &HashMap<&str, CouplingSpec>,
    coordinate_of: &HashMap<&str, usize>,
    max_depth: usize,
) -> Result<(Vec<(usize, f64)>, f64), String> {
    let spec = specs.get(joint).ok_or("internal: joint is not coupled")?;
    let mut terms: Vec<(usize, f64)> = Vec::new();
    let mut offset = spec.offset;
    for (name, multiplier) in &spec.terms {
        let (sub_terms, sub_offset) = match coordinate_of.get(name.as_str()) {
            Some(&k) => (vec![(k, 1.0)], 0.0),
            None if max_depth == 0 => return Err(format!("coupling cycle through joint {joint}")),
            None => expand(name, specs, coordinate_of, max_depth - 1)?,
        };
        offset += multiplier * sub_offset;
        for (k, c) in sub_terms {
            match terms.iter_mut().find(|(existing, _)| *existing == k) {
                Some((_, coefficient)) => *coefficient += multiplier * c,
                None => terms.push((k, multiplier * c)),
            }
        }
    }
    Ok((terms, offset))
}

/// Rotation of a URDF `rpy` triple: `Rz(yaw) · Ry(pitch) · Rx(roll)`.
fn rotation_rpy([roll, pitch, yaw]: [f64; 3]) -> Rotation3<f64> {
    Rotation3::from_axis_angle(&Vector3::z_axis(), yaw)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), pitch)
        * Rotation3::from_axis_angle(&Vector3::x_axis(), roll)
}

/// Placement of a URDF `<origin>`; `context` names its element for errors.
pub(crate) fn pose(origin: &urdf_rs::Pose, context: &str) -> Result<Placement<f64>, String> {
    let (xyz, rpy) = (origin.xyz.0, origin.rpy.0);
    if !xyz.iter().chain(rpy.iter()).all(|x| x.is_finite()) {
        return Err(format!("{context}: origin is not finite"));
    }
    let [x, y, z] = xyz;
    Ok(Placement::from_parts(Translation3::new(x, y, z), rotation_rpy(rpy)))
}

/// Unit joint axis (default `(1, 0, 0)`).
fn joint_axis(joint: &urdf_rs::Joint) -> Result<Unit<Vector3<f64>>, String> {
    let [x, y, z] = joint.axis.xyz.0;
    let axis = Vector3::new(x, y, z);
    let norm = axis.norm();
    if !norm.is_finite() || norm < 1e-12 {
        return Err(format!("joint {}: axis ({x} {y} {z}) is zero or not finite", joint.name));
    }
    Ok(Unit::new_unchecked(axis / norm))
}

/// Inertia of a link in the link frame (zero without `<inertial>`).
fn link_inertia(link: &urdf_rs::Link) -> Result<Inertia<f64>, String> {
    let i = &link.inertial.inertia;
    let rotational = Matrix3::new(i.ixx, i.ixy, i.ixz, i.ixy, i.iyy, i.iyz, i.ixz, i.iyz, i.izz);
    let about_com = Inertia { mass: link.inertial.mass.value, com: Vector3::zeros(), rotational };
    let inertia = about_com.transformed(&pose(&link.inertial.origin, &format!("link {} <inertial>", link.name))?);
    if !inertia.is_physical() {
        return Err(format!(
            "link {}: inertia is not physical (negative or non-finite mass, or principal moments violating \
             the triangle inequality; mass {} kg): correct its <inertial> in the URDF",
            link.name, link.inertial.mass.value
        ));
    }
    Ok(inertia)
}

/// Joins a possibly multi-line message into one line.
fn one_line(message: &str) -> String {
    message.split_whitespace().collect::<Vec<_>>().join(" ")
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "test code: failures should panic")]
mod tests {
    use super::*;
    use kernel::dynamics::{crba, forward_kinematics, frame_jacobian, gravity};
    use kernel::model::Data;
    use nalgebra::{SMatrix, SVector};

    const G: f64 = 9.81;

    /// Planar 2-link arm in the x–z plane: joints about y, point masses at the link ends.
    fn two_link(m1: f64, l1: f64, m2: f64, l2: f64) -> String {
        format!(
            r#"<?xml version="1.0"?>
            <robot name="arm">
              <link name="base"/>
              <link name="upper">
                <inertial><origin xyz="{l1} 0 0"/><mass value="{m1}"/>
                  <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>
              </link>
              <link name="fore">
                <inertial><origin xyz="{l2} 0 0"/><mass value="{m2}"/>
                  <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>
              </link>
              <joint name="shoulder" type="revolute">
                <parent link="base"/><child link="upper"/><axis xyz="0 2 0"/>
                <limit lower="-1.5" upper="2" effort="30" velocity="3"/>
              </joint>
              <joint name="elbow" type="continuous">
                <parent link="upper"/><child link="fore"/><origin xyz="{l1} 0 0"/><axis xyz="0 1 0"/>
              </joint>
            </robot>"#
        )
    }

    #[test]
    fn simulator_extensions_in_a_namespace_are_ignored() {
        // Drake's URDFs (e.g. the iiwa's) carry `drake:acceleration` on `<limit>` and `<drake:*>`
        // elements; URDF parsers ignore them.
        let plain = two_link(2.0, 0.7, 1.5, 0.4);
        let drake = plain
            .replace("<robot name=\"arm\">", "<robot name=\"arm\" xmlns:drake=\"http://drake.mit.edu\">")
            .replace("<limit lower", "<limit drake:acceleration=\"8.57\" lower")
            .replace("</robot>", "<drake:collision_filter_group name=\"g\"/></robot>");
        assert_ne!(drake, plain);
        let (a, b) = (
            load_str::<2, 2, 3>(&plain, Coupling::Independent).unwrap(),
            load_str::<2, 2, 3>(&drake, Coupling::Independent).unwrap(),
        );
        assert_eq!(a.frame_names, b.frame_names);
        assert_eq!(a.model.limits.velocity, b.model.limits.velocity);
        assert_eq!(a.model.limits.position_upper, b.model.limits.position_upper);
    }

    #[test]
    fn two_link_arm_matches_the_textbook_dynamics() {
        let (m1, l1, m2, l2) = (2.0, 0.7, 1.5, 0.4);
        let robot = load_str::<2, 2, 3>(&two_link(m1, l1, m2, l2), Coupling::Independent).unwrap();
        assert_eq!(robot.joint_names, ["shoulder", "elbow"]);
        assert_eq!(robot.frame_names, ["base", "upper", "fore"]);
        assert_eq!(robot.body_names, ["upper", "fore"]);
        assert_eq!(robot.frame("fore"), Some(FrameId(2)));
        assert_eq!(robot.frame("nope"), None);
        let limits = &robot.model.limits;
        assert_eq!((limits.position_lower[0], limits.position_upper[0]), (-1.5, 2.0));
        assert_eq!((limits.velocity[0], limits.effort[0]), (3.0, 30.0));
        assert_eq!((limits.position_lower[1], limits.position_upper[1]), (f64::NEG_INFINITY, f64::INFINITY));
        assert_eq!((limits.velocity[1], limits.effort[1]), (f64::INFINITY, f64::INFINITY));
        assert_eq!(robot.model.gravity, Vector3::new(0.0, 0.0, -G));

        let q = SVector::<f64, 2>::new(0.4, -1.1);
        let mut data = Data::new(&robot.model);
        forward_kinematics(&robot.model, &mut data, &q, &SVector::zeros()).unwrap();
        let m = *crba(&robot.model, &mut data);
        let g = *gravity(&robot.model, &mut data);
        let (c1, c2, c12) = (q[0].cos(), q[1].cos(), (q[0] + q[1]).cos());
        let m11 = m1 * l1 * l1 + m2 * (l1 * l1 + l2 * l2 + 2.0 * l1 * l2 * c2);
        let m12 = m2 * (l2 * l2 + l1 * l2 * c2);
        let expected_m = SMatrix::<f64, 2, 2>::new(m11, m12, m12, m2 * l2 * l2);
        assert!((m - expected_m).norm() < 1e-12, "M = {m}");
        // Rotation about +y takes x to −z: z1 = −l1 sin q1, z2 = z1 − l2 sin(q1 + q2); g = ∂V/∂q.
        let expected_g = SVector::<f64, 2>::new(-G * (m1 * l1 * c1 + m2 * (l1 * c1 + l2 * c12)), -G * m2 * l2 * c12);
        assert!((g - expected_g).norm() < 1e-12, "g = {g}");
        // The forearm frame sits at the elbow: its Jacobian column 1 is zero in translation.
        let mut j = SMatrix::<f64, 6, 2>::zeros();
        frame_jacobian(&robot.model, &data, robot.frame("fore").unwrap(), &mut j).unwrap();
        let expected_j0 = [-l1 * q[0].sin(), 0.0, -l1 * c1, 0.0, 1.0, 0.0];
        for (a, b) in j.column(0).iter().zip(expected_j0) {
            assert!((a - b).abs() < 1e-12, "J = {j}");
        }
        assert!(j.fixed_view::<3, 1>(0, 1).norm() < 1e-12);
    }

    #[test]
    fn origin_rpy_is_z_y_x() {
        let (r, p, y) = (0.3_f64, -0.7_f64, 1.9_f64);
        let text = format!(
            r#"<robot name="r"><link name="a"/><link name="b"/>
            <joint name="j" type="prismatic"><parent link="a"/><child link="b"/>
              <origin xyz="1 2 3" rpy="{r} {p} {y}"/><axis xyz="0 0 1"/>
              <limit lower="0" upper="1" effort="1" velocity="1"/></joint></robot>"#
        );
        let robot = load_str::<1, 1, 2>(&text, Coupling::Independent).unwrap();
        let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, r.cos(), -r.sin(), 0.0, r.sin(), r.cos());
        let ry = Matrix3::new(p.cos(), 0.0, p.sin(), 0.0, 1.0, 0.0, -p.sin(), 0.0, p.cos());
        let rz = Matrix3::new(y.cos(), -y.sin(), 0.0, y.sin(), y.cos(), 0.0, 0.0, 0.0, 1.0);
        let placement = robot.model.bodies()[0].joint_placement;
        assert!((placement.rotation.matrix() - rz * ry * rx).norm() < 1e-15);
        assert_eq!(placement.translation.vector, Vector3::new(1.0, 2.0, 3.0));
    }

    #[test]
    fn fixed_joints_are_merged_into_the_parent_body() {
        // `link` (2 kg at (0.2, 0, 0), diag(1, 2, 3)) carries `tool` through a fixed joint at
        // (0.5, 0, 0) turned 90° about z; the tool's inertial frame is at (0.1, 0, 0) in the
        // tool frame, rolled 90° about x, with 1 kg and diag(4, 5, 6) about its centre of mass.
        let text = format!(
            r#"<robot name="merge">
              <link name="world"/>
              <link name="mount"><inertial><mass value="9"/>
                <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
              <link name="link"><inertial><origin xyz="0.2 0 0"/><mass value="2"/>
                <inertia ixx="1" ixy="0" ixz="0" iyy="2" iyz="0" izz="3"/></inertial></link>
              <link name="tool"><inertial><origin xyz="0.1 0 0" rpy="{half_pi} 0 0"/><mass value="1"/>
                <inertia ixx="4" ixy="0" ixz="0" iyy="5" iyz="0" izz="6"/></inertial></link>
              <joint name="to_mount" type="fixed"><parent link="world"/><child link="mount"/>
                <origin xyz="0 0 1"/></joint>
              <joint name="j" type="revolute"><parent link="mount"/><child link="link"/>
                <origin xyz="0 0 0.5"/><axis xyz="0 0 1"/>
                <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
              <joint name="to_tool" type="fixed"><parent link="link"/><child link="tool"/>
                <origin xyz="0.5 0 0" rpy="0 0 {half_pi}"/></joint>
            </robot>"#,
            half_pi = core::f64::consts::FRAC_PI_2
        );
        let robot = load_str::<1, 1, 4>(&text, Coupling::Independent).unwrap();
        assert_eq!(robot.frame_names, ["world", "mount", "link", "tool"]);
        let body = &robot.model.bodies()[0];
        // The mount is fixed to the world: its 9 kg are dropped, its offset is composed.
        assert_eq!(body.parent, None);
        assert!((body.joint_placement.translation.vector - Vector3::new(0.0, 0.0, 1.5)).norm() < 1e-15);
        let inertia = body.inertia;
        assert!((inertia.mass - 3.0).abs() < 1e-15);
        // Tool com in the link frame: (0.5, 0, 0) + Rz(90°)(0.1, 0, 0) = (0.5, 0.1, 0).
        let (c_link, c_tool) = (Vector3::new(0.2, 0.0, 0.0), Vector3::new(0.5, 0.1, 0.0));
        let com = (c_link * 2.0 + c_tool) / 3.0;
        assert!((inertia.com - com).norm() < 1e-15, "com = {}", inertia.com);
        // Tool tensor: Rx(90°) diag(4, 5, 6) Rx(90°)ᵀ = diag(4, 6, 5), then Rz(90°): diag(6, 4, 5).
        let shift = |m: f64, d: Vector3<f64>| (Matrix3::identity() * d.norm_squared() - d * d.transpose()) * m;
        let expected = Matrix3::from_diagonal(&Vector3::new(1.0, 2.0, 3.0))
            + shift(2.0, c_link - com)
            + Matrix3::from_diagonal(&Vector3::new(6.0, 4.0, 5.0))
            + shift(1.0, c_tool - com);
        assert!((inertia.rotational - expected).norm() < 1e-14, "I = {}", inertia.rotational);
        // Frames: mount world-fixed at z = 1, tool on the body at (0.5, 0, 0).
        let mount = robot.model.frame(robot.frame("mount").unwrap()).unwrap();
        assert_eq!(mount.parent, None);
        assert!((mount.placement.translation.vector - Vector3::new(0.0, 0.0, 1.0)).norm() < 1e-15);
        let tool = robot.model.frame(robot.frame("tool").unwrap()).unwrap();
        assert_eq!(tool.parent, Some(BodyId(0)));
        assert!((tool.placement.translation.vector - Vector3::new(0.5, 0.0, 0.0)).norm() < 1e-15);
    }

    fn gripper(extra: &str) -> String {
        format!(
            r#"<robot name="gripper">
              <link name="palm"/>
              <link name="left"><inertial><mass value="0.1"/>
                <inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/></inertial></link>
              <link name="right"><inertial><mass value="0.1"/>
                <inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/></inertial></link>
              <joint name="finger_right" type="prismatic"><parent link="palm"/><child link="right"/>
                <axis xyz="0 -1 0"/><limit lower="0" upper="0.04" effort="20" velocity="0.2"/>
                <mimic joint="finger_left" multiplier="2" offset="0.01"/></joint>
              <joint name="finger_left" type="prismatic"><parent link="palm"/><child link="left"/>
                <axis xyz="0 1 0"/><limit lower="0" upper="0.04" effort="20" velocity="0.2"/></joint>
              {extra}
            </robot>"#
        )
    }

    #[test]
    fn mimic_joints_are_coordinates_or_coupled() {
        let text = gripper("");
        let independent = load_str::<2, 2, 3>(&text, Coupling::Independent).unwrap();
        assert_eq!(independent.joint_names, ["finger_right", "finger_left"]);
        assert_eq!(independent.model.bodies()[0].drive, JointDrive::actuated(0));

        let coupled = load_str::<1, 2, 3>(&text, Coupling::Coupled).unwrap();
        assert_eq!(coupled.joint_names, ["finger_left"]);
        assert_eq!(coupled.body_names, ["right", "left"]);
        let drive = &coupled.model.bodies()[0].drive;
        assert_eq!(drive, &JointDrive::coupled(&[(0, 2.0)], 0.01).unwrap());
        // M = Gᵀ M_tree G with G = (2, 1)ᵀ: 0.1 · 2² + 0.1.
        let mut data = Data::new(&coupled.model);
        let q = SVector::<f64, 1>::new(0.02);
        forward_kinematics(&coupled.model, &mut data, &q, &SVector::zeros()).unwrap();
        assert!((crba(&coupled.model, &mut data)[0] - 0.5).abs() < 1e-15);
        let right = data.frame_placements[coupled.frame("right").unwrap().0].translation.vector;
        assert!((right - Vector3::new(0.0, -0.05, 0.0)).norm() < 1e-15, "{right}");

        let path = std::env::temp_dir().join(format!("host-sim-urdf-{}-gripper.urdf", std::process::id()));
        std::fs::write(&path, &text).unwrap();
        assert_eq!(coordinate_count(&path, Coupling::Independent), Ok(2));
        assert_eq!(coordinate_count(&path, Coupling::Coupled), Ok(1));
        let _ = std::fs::remove_file(&path);
    }

    /// Torso of Fig. 3.16: four pitch joints, the fourth passive with q4 = −(q2 + q3) (3.41).
    fn torso(extension: &str) -> String {
        let link = |name: &str| {
            format!(
                r#"<link name="{name}"><inertial><origin xyz="0 0 0.15"/><mass value="5"/>
                <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.02"/></inertial></link>"#
            )
        };
        let joint = |name: &str, parent: &str, child: &str, axis: &str, z: f64| {
            format!(
                r#"<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>
                <origin xyz="0 0 {z}"/><axis xyz="{axis}"/>
                <limit lower="-2" upper="2" effort="230" velocity="1"/></joint>"#
            )
        };
        format!(
            r#"<robot name="torso">
              {extension}
              <link name="base"/>{}{}{}{}
              {}{}{}{}
            </robot>"#,
            link("t1"),
            link("t2"),
            link("t3"),
            link("t4"),
            joint("torso_joint1", "base", "t1", "0 0 1", 0.5),
            joint("torso_joint2", "t1", "t2", "0 1 0", 0.1),
            joint("torso_joint3", "t2", "t3", "0 1 0", 0.3),
            joint("torso_joint4", "t3", "t4", "0 1 0", 0.3),
        )
    }

    const TORSO_COUPLING: &str = r#"<coupling joint="torso_joint4" offset="0">
        <term joint="torso_joint2" multiplier="-1"/><term joint="torso_joint3" multiplier="-1"/>
      </coupling>"#;

    #[test]
    fn coupling_extension_drives_a_joint_from_several_coordinates() {
        let text = torso(TORSO_COUPLING);
        let independent = load_str::<4, 4, 5>(&text, Coupling::Independent).unwrap();
        assert_eq!(independent.joint_names.len(), 4);

        let coupled = load_str::<3, 4, 5>(&text, Coupling::Coupled).unwrap();
        assert_eq!(coupled.joint_names, ["torso_joint1", "torso_joint2", "torso_joint3"]);
        let drive = &coupled.model.bodies()[3].drive;
        assert_eq!(drive, &JointDrive::coupled(&[(1, -1.0), (2, -1.0)], 0.0).unwrap());
        // The passive joint keeps the top of the torso upright for any q2, q3.
        let mut data = Data::new(&coupled.model);
        let q = SVector::<f64, 3>::new(0.3, 0.8, -0.2);
        forward_kinematics(&coupled.model, &mut data, &q, &SVector::zeros()).unwrap();
        let top = data.frame_placements[coupled.frame("t4").unwrap().0];
        let upright = top.rotation * Vector3::z();
        assert!((upright - Vector3::z()).norm() < 1e-15, "{upright}");
    }

    fn error_of<const N: usize>(text: &str, coupling: Coupling) -> String {
        match load_str::<N, 8, 8>(text, coupling) {
            Ok(_) => panic!("loading succeeded"),
            Err(e) => {
                assert!(!e.contains('\n'), "not one line: {e}");
                e
            }
        }
    }

    #[test]
    fn bad_files_are_rejected_with_a_one_line_message() {
        let missing = load::<1, 1, 1>(Path::new("/nonexistent/robot.urdf"), Coupling::Independent).unwrap_err();
        assert!(missing.contains("cannot read URDF") && missing.contains("/nonexistent/robot.urdf"), "{missing}");
        assert!(error_of::<1>("<robot name='x'><link name='a'>", Coupling::Independent).contains("malformed XML"));
        assert!(error_of::<1>("<model/>", Coupling::Independent).contains("expected <robot>"));
        // Found by the host_parsers fuzz target: `xml` panicked writing a namespace back.
        let mangled = "<robot name='x' xmlns:xmlns='urn:x'><link name='a'/></robot>";
        let prefixed = "<robot name='x' xmlns:p='urn:x'><link name='a' p:colour='red'/><p:a/></robot>";
        for text in [mangled, prefixed] {
            let written = preprocess(text).unwrap().text;
            assert_eq!(written.replace(['"', '\''], ""), "<robot name=x><link name=a/></robot>", "{text}");
        }
        let namespaced_root = "<p:robot xmlns:p='urn:x'><link name='a'/></p:robot>";
        let e = error_of::<1>(namespaced_root, Coupling::Independent);
        assert!(e.contains("<robot> is in the XML namespace \"urn:x\""), "{e}");
        let xacro = "<robot name='x' xmlns:xacro='http://www.ros.org/wiki/xacro'><xacro:include filename='a'/></robot>";
        let e = error_of::<1>(xacro, Coupling::Independent);
        assert!(e.contains("<xacro:include> in the file: expand the .xacro to URDF first"), "{e}");
        let no_child =
            "<robot name='x'><link name='a'/><joint name='j' type='fixed'><parent link='a'/></joint></robot>";
        assert!(error_of::<1>(no_child, Coupling::Independent).contains("malformed URDF"));

        let arm = two_link(1.0, 1.0, 1.0, 1.0);
        assert!(error_of::<3>(&arm, Coupling::Independent)
            .contains("2 generalized coordinates but the model is built for N = 3"));
        let few_frames = load_str::<2, 2, 2>(&arm, Coupling::Independent).unwrap_err();
        assert!(few_frames.contains("3 links, more than the frame capacity F = 2"), "{few_frames}");
        let few_bodies = load_str::<1, 1, 3>(&gripper(""), Coupling::Coupled).unwrap_err();
        assert!(few_bodies.contains("2 movable joints, more than the body capacity B = 1"), "{few_bodies}");

        let cycle = "<robot name='x'><link name='a'/><link name='b'/><link name='c'/>
            <joint name='ab' type='fixed'><parent link='a'/><child link='b'/></joint>
            <joint name='bc' type='fixed'><parent link='b'/><child link='c'/></joint>
            <joint name='cb' type='fixed'><parent link='c'/><child link='b'/></joint></robot>";
        assert!(error_of::<1>(cycle, Coupling::Independent).contains("child of two joints"));
        let loop_ = "<robot name='x'><link name='a'/><link name='b'/><link name='c'/>
            <joint name='ab' type='fixed'><parent link='a'/><child link='b'/></joint>
            <joint name='bc' type='fixed'><parent link='b'/><child link='c'/></joint>
            <joint name='ca' type='fixed'><parent link='c'/><child link='a'/></joint></robot>";
        assert!(error_of::<1>(loop_, Coupling::Independent).contains("kinematic loop"));
        let two_roots = "<robot name='x'><link name='a'/><link name='b'/><link name='c'/>
            <joint name='ab' type='fixed'><parent link='a'/><child link='b'/></joint></robot>";
        assert!(error_of::<1>(two_roots, Coupling::Independent)
            .contains("several root links (links that are no joint's child): a, c"));
        let unknown_link = "<robot name='x'><link name='a'/>
            <joint name='ab' type='fixed'><parent link='a'/><child link='b'/></joint></robot>";
        assert!(error_of::<1>(unknown_link, Coupling::Independent).contains("joint ab: unknown child link b"));

        let bad_mimic = gripper("").replace("mimic joint=\"finger_left\"", "mimic joint=\"thumb\"");
        for coupling in [Coupling::Independent, Coupling::Coupled] {
            let e = error_of::<1>(&bad_mimic, coupling);
            assert!(e.contains("<mimic> of joint finger_right: unknown joint thumb"), "{e}");
        }
        let bad_term = torso(&TORSO_COUPLING.replace("torso_joint3\"", "torso_joint9\""));
        assert!(error_of::<3>(&bad_term, Coupling::Coupled)
            .contains("<coupling> of joint torso_joint4: unknown joint torso_joint9"));
        let twice = torso(&format!("{TORSO_COUPLING}{TORSO_COUPLING}"));
        assert!(error_of::<3>(&twice, Coupling::Coupled).contains("coupled twice"));
        let empty = torso("<coupling joint='torso_joint4'/>");
        assert!(error_of::<3>(&empty, Coupling::Coupled).contains("no <term> elements"));
        let cyclic = gripper("<coupling joint='finger_left'><term joint='finger_right' multiplier='1'/></coupling>");
        assert!(error_of::<1>(&cyclic, Coupling::Coupled).contains("coupling cycle"));

        let floating = arm.replace("type=\"continuous\"", "type=\"floating\"");
        assert!(error_of::<2>(&floating, Coupling::Independent).contains("unsupported joint type"));
        let no_limit = arm.replace(r#"<limit lower="-1.5" upper="2" effort="30" velocity="3"/>"#, "");
        assert!(error_of::<2>(&no_limit, Coupling::Independent)
            .contains("joint shoulder: a revolute or prismatic joint needs a <limit>"));
        let zero_axis = arm.replace("axis xyz=\"0 2 0\"", "axis xyz=\"0 0 0\"");
        assert!(error_of::<2>(&zero_axis, Coupling::Independent).contains("joint shoulder: axis (0 0 0) is zero"));
        let bad_limits = arm.replace("lower=\"-1.5\"", "lower=\"3\"");
        assert!(error_of::<2>(&bad_limits, Coupling::Independent).contains("joint shoulder: invalid limits"));
        let negative_mass = arm.replace("<mass value=\"1\"/>", "<mass value=\"-1\"/>");
        assert!(error_of::<2>(&negative_mass, Coupling::Independent).contains("link upper: inertia is not physical"));
        let nan_origin = arm.replace("<origin xyz=\"1 0 0\"/><axis", "<origin xyz=\"nan 0 0\"/><axis");
        assert!(error_of::<2>(&nan_origin, Coupling::Independent).contains("joint elbow: origin is not finite"));
    }
}
