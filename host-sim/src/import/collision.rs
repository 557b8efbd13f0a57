//! The imported robot's swept-sphere collision model: volumes fitted to the URDF's
//! `<collision>` geometry, and the pair survey that lists the pairs the controller never needs.
//!
//! **Fitting** (each volume contains its primitive; the points are rounded to 0.1 mm and the
//! radius is rounded up with a 0.1 mm margin, so the written numbers still contain it):
//! - sphere → the sphere;
//! - cylinder of radius `r` and length `L` → the capsule between its end centres with radius `r`
//!   (exact on the mantle, the caps bulge by `r`); a URDF capsule → the same capsule;
//! - box → the rectangle in the mid-plane across its thinnest side (two triangles) swept by
//!   half that side (exact, as Justin's chest);
//! - mesh → its bounding capsule: the axis is the vertices' principal direction through their
//!   centroid, the radius the largest distance of a vertex from that axis, the end points the
//!   shortest segment on the axis that keeps every vertex inside. STL meshes are read with
//!   `stl_io`, the vertex positions of COLLADA (`.dae`) meshes with `RustyXML` (only those its
//!   triangles or other primitives index);
//!   `package://<package>/<path>` resolves to `<--package-path>/<package>/<path>`. A capsule is
//!   convex, so containing the vertices it contains the whole mesh.
//!
//! **Contained volumes.** A volume that lies inside another volume of the same body is dropped
//! (its distance to anything is never the smaller one): TIAGo++'s finger primitives lie inside the
//! safety box of its hand. A swept sphere `A` (core `a`, radius `r_a`) lies inside `B` exactly
//! when every corner `v` of `a` has `d(v, B) + r_a ≤ 0`: the distance to `B`'s convex core is
//! convex, so its largest value on `a` is at a corner.
//!
//! **Pair survey.** Pairs on one body and pairs of adjacent links are dropped by the kernel's rules
//! ([`kernel::tasks::collision::exclusion_rule`]; the same rule is applied here on the
//! description). Every other pair's distance is sampled over [`SURVEY_SAMPLES`] random
//! configurations (uniform within the joint limits, `±π` for continuous joints, seed
//! [`SURVEY_SEED`]); a pair is excluded as `constant` when its distance does not change,
//! `never_close` when it stays above the potential's activation distance
//! `d0` ([`ACTIVATION_DISTANCE_M`], Table 3.1) plus [`SURVEY_MARGIN_M`] (its potential would never act), and
//! `always_near` when it stays below `d0` (its potential would never switch off and would only
//! bias the posture), and `welded_parent` for a body and the links welded to the root its joint
//! hangs from (adjacent by the URDF; for the kernel's rule a world-fixed volume is environment:
//! TIAGo++'s lift slides inside its fixed column). This is the classification of Justin's exclusions
//! (`fixtures/collision/justin.collision`), whose survey used a grid instead of random samples.

use std::path::Path;

use kernel::model::JointKind;
use kernel::model::Placement;
use kernel::tasks::collision::{proximity, Core, SweptSphere};
use nalgebra::{Matrix3, Point3, Rotation3, SymmetricEigen, Translation3, Vector3};
use rand::rngs::Xoshiro256PlusPlus;
use rand::SeedableRng;
use urdf_rs::Geometry;

use super::ImportOptions;
use crate::urdf::{self, Description};

/// Random configurations of the pair survey.
pub const SURVEY_SAMPLES: usize = 20_000;
/// Seed of the pair survey's configurations.
pub const SURVEY_SEED: u64 = 0x5eed_c011_1510_0015;
/// The collision potential's activation distance `d0` (m), thesis Table 3.1.
pub const ACTIVATION_DISTANCE_M: f64 = 0.15;
/// Margin above `d0` a `never_close` pair keeps in every sample (m): the samples only bound the
/// true smallest distance from above.
pub const SURVEY_MARGIN_M: f64 = 0.05;
/// Distance range below which a pair counts as constant (m).
const CONSTANT_TOLERANCE_M: f64 = 1e-9;
/// Resolution of the written numbers (m).
const RESOLUTION_M: f64 = 1e-4;

/// One fitted volume, in the frame of its link.
#[derive(Clone, Debug)]
pub struct FittedVolume {
    /// Volume name: `<link>_<k>` for the link's `k`-th collision element (`_a`, `_b` for a box's
    /// two triangles).
    pub name: String,
    /// The URDF link whose frame the shape is given in.
    pub link: String,
    /// The volume.
    pub shape: SweptSphere<f64>,
    /// The primitive it was fitted to, for the file's comments.
    pub source: String,
}

/// The fitted volumes of a robot.
#[derive(Clone, Debug)]
pub struct Fitted {
    /// Every volume kept, in link and collision-element order.
    pub volumes: Vec<FittedVolume>,
    /// The volumes dropped as contained, each with the name of the volume that contains it.
    pub contained: Vec<(FittedVolume, String)>,
}

/// Fits volumes to every `<collision>` element of `robot`. `packages` resolves `package://` URIs.
pub fn fit(robot: &urdf_rs::Robot, packages: Option<&Path>) -> Result<Fitted, String> {
    let mut volumes = Vec::new();
    for link in &robot.links {
        for (k, collision) in link.collision.iter().enumerate() {
            let context = format!("link {} <collision> {k}", link.name);
            let origin = urdf::pose(&collision.origin, &context)?;
            let name = format!("{}_{k}", link.name);
            let fitted = fit_geometry(&collision.geometry, &origin, packages).map_err(|e| format!("{context}: {e}"))?;
            let suffixes = if fitted.len() > 1 { ["_a", "_b"].as_slice() } else { [""].as_slice() };
            for ((shape, source), suffix) in fitted.into_iter().zip(suffixes) {
                volumes.push(FittedVolume { name: format!("{name}{suffix}"), link: link.name.clone(), shape, source });
            }
        }
    }
    Ok(Fitted { volumes, contained: Vec::new() })
}

/// Drops every volume that lies inside another kept volume of the same body of `d` (see the
/// module docs).
pub(crate) fn without_contained(d: &Description, fitted: Fitted) -> Result<Fitted, String> {
    let attached = attach(d, &fitted.volumes)?;
    let mut kept = vec![true; fitted.volumes.len()];
    let mut contained = Vec::new();
    for (i, (body, shape)) in attached.iter().enumerate() {
        let container = attached.iter().enumerate().position(|(j, (other_body, other))| {
            j != i && kept.get(j) == Some(&true) && other_body == body && inside(shape, other)
        });
        if let (Some(j), Some(volume), Some(flag)) = (container, fitted.volumes.get(i), kept.get_mut(i)) {
            *flag = false;
            let name = fitted.volumes.get(j).map_or_else(String::new, |v| v.name.clone());
            contained.push((volume.clone(), name));
        }
    }
    let volumes = fitted.volumes.into_iter().zip(kept).filter_map(|(v, keep)| keep.then_some(v)).collect();
    Ok(Fitted { volumes, contained })
}

/// Whether `a` lies inside `b` (both in one frame).
fn inside(a: &SweptSphere<f64>, b: &SweptSphere<f64>) -> bool {
    let corners: &[Vector3<f64>] = match &a.core {
        Core::Point(p) => std::slice::from_ref(p),
        Core::Segment(points) => points,
        Core::Triangle(points) => points,
    };
    corners.iter().all(|v| b.signed_distance_to(v) + a.radius <= 0.0)
}

/// A volume's body (`None`: the world) and its shape in that body's frame.
type Attached = (Option<usize>, SweptSphere<f64>);

/// Each volume with the body it moves with and its shape in that body's frame.
fn attach(d: &Description, volumes: &[FittedVolume]) -> Result<Vec<Attached>, String> {
    volumes
        .iter()
        .map(|v| {
            let frame =
                d.frames.iter().find(|f| f.link == v.link).ok_or_else(|| format!("internal: no frame {}", v.link))?;
            Ok((frame.parent, v.shape.transformed(&frame.placement)))
        })
        .collect()
}

/// The volume(s) of one primitive placed by `origin`, each with its description.
fn fit_geometry(
    geometry: &Geometry,
    origin: &Placement<f64>,
    packages: Option<&Path>,
) -> Result<Vec<(SweptSphere<f64>, String)>, String> {
    let at = |x: f64, y: f64, z: f64| origin * Point3::new(x, y, z);
    Ok(match geometry {
        Geometry::Sphere { radius } => {
            vec![(outward(SweptSphere::sphere(at(0.0, 0.0, 0.0).coords, *radius)), format!("sphere r {radius}"))]
        }
        Geometry::Cylinder { radius, length } | Geometry::Capsule { radius, length } => {
            let (a, b) = (at(0.0, 0.0, -length / 2.0).coords, at(0.0, 0.0, length / 2.0).coords);
            vec![(outward(SweptSphere::capsule(a, b, *radius)), format!("cylinder r {radius} L {length}"))]
        }
        Geometry::Box { size } => box_triangles(size.0, origin),
        Geometry::Mesh { filename, scale } => {
            let scale = scale.as_ref().map_or([1.0; 3], |s| s.0);
            let vertices = mesh_vertices(filename, scale, packages)?;
            let points: Vec<Vector3<f64>> = vertices.iter().map(|v| (origin * Point3::from(*v)).coords).collect();
            let capsule = bounding_capsule(&points).ok_or_else(|| format!("mesh {filename} has no vertices"))?;
            vec![(outward(capsule), format!("bounding capsule of mesh {filename} ({} vertices)", points.len()))]
        }
    })
}

/// A box of `size` (m) placed by `origin`: the rectangle in the mid-plane across its thinnest
/// side, as two triangles swept by half that side.
fn box_triangles(size: [f64; 3], origin: &Placement<f64>) -> Vec<(SweptSphere<f64>, String)> {
    let extent = Vector3::from(size);
    let thin = extent.imin();
    let axes = [Vector3::x(), Vector3::y(), Vector3::z()];
    let half_side = |k: usize| axes.get(k % 3).map_or_else(Vector3::zeros, |axis| axis * extent.dot(axis) / 2.0);
    let (u, v) = (half_side(thin + 1), half_side(thin + 2));
    let corner = |su: f64, sv: f64| (origin * Point3::from(u * su + v * sv)).coords;
    let [c0, c1, c2, c3] = [corner(-1.0, -1.0), corner(1.0, -1.0), corner(1.0, 1.0), corner(-1.0, 1.0)];
    let radius = extent.min() / 2.0;
    let source = format!("box {} x {} x {}", size[0], size[1], size[2]);
    vec![
        (outward(SweptSphere::swept_triangle(c0, c1, c2, radius)), source.clone()),
        (outward(SweptSphere::swept_triangle(c0, c2, c3, radius)), source),
    ]
}

/// The vertices of the mesh `filename`, STL or COLLADA (m, mesh frame, scaled).
pub fn mesh_vertices(filename: &str, scale: [f64; 3], packages: Option<&Path>) -> Result<Vec<Vector3<f64>>, String> {
    let path = match filename.strip_prefix("package://") {
        Some(rest) => {
            let dir =
                packages.ok_or_else(|| format!("mesh {filename}: give --package-path to resolve package:// URIs"))?;
            dir.join(rest)
        }
        None => Path::new(filename.strip_prefix("file://").unwrap_or(filename)).to_path_buf(),
    };
    let extension = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
    let vertices = match extension.as_deref() {
        Some("dae") => collada_vertices(&path)?,
        None | Some("stl") => stl_vertices(&path)?,
        Some(other) => {
            return Err(format!(
                "mesh {}: the import reads STL and COLLADA .dae meshes, not .{other}: convert it to STL or take \
                 a variant of the URDF with primitive collision geometry",
                path.display()
            ))
        }
    };
    Ok(vertices.iter().map(|v| v.component_mul(&Vector3::from(scale))).collect())
}

/// The vertices of an STL file (m).
fn stl_vertices(path: &Path) -> Result<Vec<Vector3<f64>>, String> {
    let mut file = std::fs::File::open(path).map_err(|e| format!("mesh {}: {e}", path.display()))?;
    let mesh =
        stl_io::read_stl(&mut file).map_err(|e| format!("mesh {} (STL or COLLADA .dae): {e}", path.display()))?;
    Ok(mesh.vertices.iter().map(|v| Vector3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]))).collect())
}

/// The vertices of a COLLADA (`.dae`) file (m): the positions of every `<mesh>`'s `POSITION`
/// source that its primitives (`<triangles>`, `<polylist>`, …) use, scaled by the `<unit meter>` of
/// its `<asset>`. A position no primitive indexes is not on the surface: MeshLab writes the whole
/// vertex list into each part it exports (TIAGo++'s three lift meshes share 154 positions, of which
/// the neck uses 16 and a shoulder 74), and the unused ones would blow the fit up to the whole part. The coordinates are read as they stand, in the link frame, as
/// ROS and Pinocchio read a collision mesh: `<up_axis>` is ignored (MeshLab writes `Y_UP` over
/// link-frame coordinates). A `<node>` transform (`matrix`, `translate`, `rotate`, `scale`) is
/// refused, not applied.
fn collada_vertices(path: &Path) -> Result<Vec<Vector3<f64>>, String> {
    let fail = |problem: String| format!("mesh {}: {problem}", path.display());
    let text = std::fs::read_to_string(path).map_err(|e| fail(e.to_string()))?;
    let root: xml::Element = text.parse().map_err(|e| fail(format!("malformed XML: {e}")))?;
    let unit = descendants(&root, "unit").first().and_then(|u| attribute_number(u, "meter")).unwrap_or(1.0);
    let transforms = ["matrix", "translate", "rotate", "scale"];
    if let Some(node) = descendants(&root, "node").iter().find(|n| n.children.iter().any(|c| is_named(c, &transforms)))
    {
        let id = node.get_attribute("id", None).unwrap_or("without id");
        return Err(fail(format!("<node> {id} has a transform, which the import does not apply")));
    }
    let mut vertices = Vec::new();
    for mesh in descendants(&root, "mesh") {
        let source = descendants(mesh, "vertices")
            .iter()
            .flat_map(|v| descendants(v, "input"))
            .find(|input| input.get_attribute("semantic", None) == Some("POSITION"))
            .and_then(|input| input.get_attribute("source", None))
            .and_then(|id| id.strip_prefix('#'))
            .ok_or_else(|| fail("a <mesh> without a POSITION input".to_owned()))?;
        let array = descendants(mesh, "source")
            .into_iter()
            .find(|s| s.get_attribute("id", None) == Some(source))
            .and_then(|s| descendants(s, "float_array").into_iter().next())
            .ok_or_else(|| fail(format!("no <float_array> for the positions #{source}")))?;
        let numbers: Vec<f64> = array
            .content_str()
            .split_whitespace()
            .map(|x| x.parse::<f64>().map_err(|e| fail(format!("position {x:?}: {e}"))))
            .collect::<Result<_, _>>()?;
        if numbers.len() % 3 != 0 {
            return Err(fail(format!("{} position numbers, not a multiple of 3", numbers.len())));
        }
        let positions: Vec<Vector3<f64>> =
            numbers.chunks_exact(3).map(|c| Vector3::from_column_slice(c) * unit).collect();
        let mut used = vec![false; positions.len()];
        for index in primitive_vertices(mesh).map_err(fail)? {
            *used
                .get_mut(index)
                .ok_or_else(|| fail(format!("vertex index {index} of {} positions", positions.len())))? = true;
        }
        vertices.extend(positions.into_iter().zip(used).filter_map(|(p, used)| used.then_some(p)));
    }
    Ok(vertices)
}

/// The COLLADA primitives that index a `<mesh>`'s vertices.
const PRIMITIVES: [&str; 7] = ["triangles", "polylist", "polygons", "trifans", "tristrips", "lines", "linestrips"];

/// The vertex indices of every primitive of `mesh`: in each `<p>` the entries at the `VERTEX`
/// input's offset, one per `max offset + 1` entries.
fn primitive_vertices(mesh: &xml::Element) -> Result<Vec<usize>, String> {
    let mut indices = Vec::new();
    let primitives = mesh.children.iter().filter_map(|c| match c {
        xml::Xml::ElementNode(e) if PRIMITIVES.contains(&e.name.as_str()) => Some(e),
        _ => None,
    });
    for primitive in primitives {
        let inputs: Vec<(&str, usize)> = descendants(primitive, "input")
            .iter()
            .map(|input| {
                let semantic = input.get_attribute("semantic", None).unwrap_or_default();
                let offset = attribute_number(input, "offset").unwrap_or(0.0);
                (semantic, offset as usize)
            })
            .collect();
        let stride = inputs.iter().map(|(_, offset)| offset + 1).max().unwrap_or(1);
        let vertex = inputs
            .iter()
            .find(|(semantic, _)| *semantic == "VERTEX")
            .map(|(_, offset)| *offset)
            .ok_or_else(|| format!("a <{}> without a VERTEX input", primitive.name))?;
        for p in descendants(primitive, "p") {
            for entry in p.content_str().split_whitespace().skip(vertex).step_by(stride) {
                indices.push(entry.parse::<usize>().map_err(|e| format!("<p> index {entry:?}: {e}"))?);
            }
        }
    }
    Ok(indices)
}

/// Whether `node` is an element with one of `names` (any namespace).
fn is_named(node: &xml::Xml, names: &[&str]) -> bool {
    matches!(node, xml::Xml::ElementNode(e) if names.contains(&e.name.as_str()))
}

/// Every element below `element` named `name` (any namespace; COLLADA declares a default one),
/// in document order.
fn descendants<'a>(element: &'a xml::Element, name: &str) -> Vec<&'a xml::Element> {
    let mut found = Vec::new();
    for child in &element.children {
        if let xml::Xml::ElementNode(e) = child {
            if e.name == name {
                found.push(e);
            }
            found.extend(descendants(e, name));
        }
    }
    found
}

/// A numeric attribute.
fn attribute_number(element: &xml::Element, name: &str) -> Option<f64> {
    element.get_attribute(name, None).and_then(|x| x.parse().ok())
}

/// A link's name and points in its frame (m).
pub type LinkPoints = (String, Vec<Vector3<f64>>);

/// Points on the surface of every `<collision>` primitive of the URDF `text`, by link (link
/// frame, m): a mesh's vertices, a box's corners, 32 points on each rim of a cylinder (and a
/// capsule's cylinder), 26 on a sphere. The tests check that the fitted volumes contain them.
pub fn primitive_points(text: &str, packages: Option<&Path>) -> Result<Vec<LinkPoints>, String> {
    let robot = urdf_rs::read_from_string(text).map_err(|e| format!("malformed URDF: {e}"))?;
    let mut out = Vec::new();
    for link in &robot.links {
        for (k, collision) in link.collision.iter().enumerate() {
            let origin = urdf::pose(&collision.origin, &format!("link {} <collision> {k}", link.name))?;
            let local = match &collision.geometry {
                Geometry::Sphere { radius } => directions().into_iter().map(|d| d.normalize() * *radius).collect(),
                Geometry::Cylinder { radius, length } | Geometry::Capsule { radius, length } => (0..64)
                    .map(|i| {
                        let angle = f64::from(i % 32) * std::f64::consts::TAU / 32.0;
                        let z = if i < 32 { -length / 2.0 } else { length / 2.0 };
                        Vector3::new(radius * angle.cos(), radius * angle.sin(), z)
                    })
                    .collect(),
                Geometry::Box { size } => directions()
                    .into_iter()
                    .filter(|d| d.iter().all(|c| c.abs() > 0.5))
                    .map(|d| d.component_mul(&Vector3::from(size.0)) / 2.0)
                    .collect(),
                Geometry::Mesh { filename, scale } => {
                    mesh_vertices(filename, scale.as_ref().map_or([1.0; 3], |s| s.0), packages)?
                }
            };
            out.push((link.name.clone(), local.iter().map(|p| (origin * Point3::from(*p)).coords).collect()));
        }
    }
    Ok(out)
}

/// The 26 offsets of a cube's centre to its neighbours, components in `{−1, 0, 1}`.
fn directions() -> Vec<Vector3<f64>> {
    let steps = [-1.0, 0.0, 1.0];
    let mut out = Vec::new();
    for x in steps {
        for y in steps {
            for z in steps {
                let d = Vector3::new(x, y, z);
                if d != Vector3::zeros() {
                    out.push(d);
                }
            }
        }
    }
    out
}

/// The bounding capsule of `points` along their principal direction (`None` without points).
fn bounding_capsule(points: &[Vector3<f64>]) -> Option<SweptSphere<f64>> {
    let count = points.len() as f64;
    let centroid = points.iter().sum::<Vector3<f64>>() / count.max(1.0);
    let covariance = points.iter().map(|p| (p - centroid) * (p - centroid).transpose()).sum::<Matrix3<f64>>();
    let eigen = SymmetricEigen::new(covariance);
    let axis = eigen.eigenvectors.column(eigen.eigenvalues.imax()).into_owned();
    let along = |p: &Vector3<f64>| (p - centroid).dot(&axis);
    let across = |p: &Vector3<f64>| (p - centroid - axis * along(p)).norm();
    let radius = points.iter().map(across).fold(f64::NAN, f64::max);
    let reach = |p: &Vector3<f64>| (radius * radius - across(p).powi(2)).max(0.0).sqrt();
    let low = points.iter().map(|p| along(p) + reach(p)).fold(f64::INFINITY, f64::min);
    let high = points.iter().map(|p| along(p) - reach(p)).fold(f64::NEG_INFINITY, f64::max);
    radius.is_finite().then(|| {
        let (a, b) = (low.min(high), low.max(high));
        SweptSphere::capsule(centroid + axis * a, centroid + axis * b, radius)
    })
}

/// The volume with its points rounded to [`RESOLUTION_M`] and its radius grown to cover the
/// rounding: it still contains the original.
fn outward(volume: SweptSphere<f64>) -> SweptSphere<f64> {
    let round = |p: Vector3<f64>| p.map(|x| (x / RESOLUTION_M).round() * RESOLUTION_M);
    let core = match volume.core {
        Core::Point(p) => Core::Point(round(p)),
        Core::Segment([a, b]) => Core::Segment([round(a), round(b)]),
        Core::Triangle([a, b, c]) => Core::Triangle([round(a), round(b), round(c)]),
    };
    let radius = ((volume.radius + RESOLUTION_M) / RESOLUTION_M).ceil() * RESOLUTION_M;
    SweptSphere { core, radius }
}

/// Why a pair is excluded (the reasons of `justin.collision`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reason {
    /// The distance does not change.
    Constant,
    /// The distance stays above `d0` plus the margin.
    NeverClose,
    /// The distance stays below `d0`.
    AlwaysNear,
    /// A link welded to the root and a body whose joint hangs from it (or from a zero-length link
    /// on it): adjacent links, as the kernel's rule has them, except that a fixed-base import
    /// welds the parent to the world, which the kernel's rule takes for the environment.
    WeldedParent,
}

impl Reason {
    /// The name in the collision file.
    pub fn name(self) -> &'static str {
        match self {
            Self::Constant => "constant",
            Self::NeverClose => "never_close",
            Self::AlwaysNear => "always_near",
            Self::WeldedParent => "welded_parent",
        }
    }
}

/// An excluded pair with its sampled distance range (m).
#[derive(Clone, Debug)]
pub struct Exclusion {
    /// Volume indices.
    pub pair: (usize, usize),
    /// Why.
    pub reason: Reason,
    /// Smallest and largest sampled distance (m).
    pub range: (f64, f64),
}

/// The survey's result.
#[derive(Clone, Debug)]
pub struct Survey {
    /// Pairs excluded by the survey.
    pub excluded: Vec<Exclusion>,
    /// Pairs left to the controller (volume indices, first < second, in lexicographic order).
    pub enabled: Vec<(usize, usize)>,
}

/// Surveys every pair of `volumes` the kernel's rules keep (see the module docs).
pub(crate) fn survey(d: &Description, volumes: &[FittedVolume]) -> Result<Survey, String> {
    let attached = attach(d, volumes)?;
    let mut pairs = Vec::new();
    for i in 0..attached.len() {
        for j in i + 1..attached.len() {
            if let (Some((a, _)), Some((b, _))) = (attached.get(i), attached.get(j)) {
                if !excluded_by_rule(d, *a, *b) {
                    pairs.push(((i, j), (f64::INFINITY, f64::NEG_INFINITY)));
                }
            }
        }
    }
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(SURVEY_SEED);
    for _ in 0..SURVEY_SAMPLES {
        let q = super::random_posture(d, &mut rng);
        let placements = body_placements(d, &q);
        let world: Vec<SweptSphere<f64>> = attached
            .iter()
            .map(|(body, shape)| match body.and_then(|b| placements.get(b)) {
                Some(p) => shape.transformed(p),
                None => *shape,
            })
            .collect();
        for ((i, j), (lo, hi)) in &mut pairs {
            if let (Some(a), Some(b)) = (world.get(*i), world.get(*j)) {
                let distance = proximity(a, b).distance;
                (*lo, *hi) = (lo.min(distance), hi.max(distance));
            }
        }
    }
    let classify = |(i, j): (usize, usize), (lo, hi): (f64, f64)| {
        let body = |k: usize| attached.get(k).and_then(|(body, _)| *body);
        if welded_parent(d, body(i), body(j)) {
            Some(Reason::WeldedParent)
        } else if hi - lo < CONSTANT_TOLERANCE_M {
            Some(Reason::Constant)
        } else if lo > ACTIVATION_DISTANCE_M + SURVEY_MARGIN_M {
            Some(Reason::NeverClose)
        } else if hi < ACTIVATION_DISTANCE_M {
            Some(Reason::AlwaysNear)
        } else {
            None
        }
    };
    let excluded: Vec<Exclusion> = pairs
        .iter()
        .filter_map(|&(pair, range)| classify(pair, range).map(|reason| Exclusion { pair, reason, range }))
        .collect();
    let enabled =
        pairs.iter().map(|&(pair, _)| pair).filter(|pair| !excluded.iter().any(|e| e.pair == *pair)).collect();
    Ok(Survey { enabled, excluded })
}

/// The kernel's exclusion rule ([`kernel::tasks::collision::exclusion_rule`]) on the
/// description: the same body, or adjacent links (parent and child, or grandparent when the
/// child sits at its parent's origin).
fn excluded_by_rule(d: &Description, a: Option<usize>, b: Option<usize>) -> bool {
    if a == b {
        return true;
    }
    let (Some(a), Some(b)) = (a, b) else { return false };
    adjacent(d, a, Some(b)) || adjacent(d, b, Some(a))
}

/// Whether `a` and `b` are a body and the links welded to the root (`None`) its joint hangs
/// from: adjacent by the URDF, but not by the kernel's rule, for which the world is not a link
/// ([`Reason::WeldedParent`]). TIAGo++'s lift slides inside the fixed column it hangs from.
fn welded_parent(d: &Description, a: Option<usize>, b: Option<usize>) -> bool {
    match (a, b) {
        (Some(body), None) | (None, Some(body)) => adjacent(d, body, None),
        _ => false,
    }
}

/// Whether the joint of body `child` hangs from `ancestor` (`None`: the links welded to the
/// root), or from a body at `ancestor`'s origin that hangs from it (a zero-length link).
fn adjacent(d: &Description, child: usize, ancestor: Option<usize>) -> bool {
    let parent = |x: usize| d.bodies.get(x).map(|body| body.parent);
    let at_parent_origin =
        |x: usize| d.bodies.get(x).is_some_and(|body| body.joint_placement.translation.vector == Vector3::zeros());
    parent(child) == Some(ancestor)
        || (at_parent_origin(child) && parent(child).flatten().and_then(parent) == Some(ancestor))
}

/// World placement of every body at coordinates `q` (bodies come after their parents).
pub(crate) fn body_placements(d: &Description, q: &[f64]) -> Vec<Placement<f64>> {
    let mut placements: Vec<Placement<f64>> = Vec::with_capacity(d.bodies.len());
    for body in &d.bodies {
        let value = body.terms.iter().map(|&(k, c)| c * q.get(k).copied().unwrap_or(0.0)).sum::<f64>() + body.offset;
        let motion = match body.kind {
            JointKind::Revolute { axis } => {
                Placement::from_parts(Translation3::identity(), Rotation3::from_axis_angle(&axis, value))
            }
            JointKind::Prismatic { axis } => {
                Placement::from_parts(Translation3::from(axis.into_inner() * value), Rotation3::identity())
            }
        };
        let parent = body.parent.and_then(|p| placements.get(p)).copied().unwrap_or_else(Placement::identity);
        placements.push(parent * body.joint_placement * motion);
    }
    placements
}

/// A point as `x y z`.
fn point(p: &Vector3<f64>) -> String {
    format!("{} {} {}", number(p.x), number(p.y), number(p.z))
}

/// A length at [`RESOLUTION_M`] without trailing zeros (`-0` written as `0`).
fn number(x: f64) -> String {
    let text = format!("{x:.4}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".to_owned()
    } else {
        text.to_owned()
    }
}

/// The collision file `<name>.collision` (the line formats of `fixtures/collision/justin.collision`
/// with a `capacity` line; `fixtures/build.rs` compiles it into `fixtures::robots::<name>::collision`).
pub(crate) fn file(
    options: &ImportOptions,
    d: &Description,
    fitted: &Fitted,
    survey: &Survey,
) -> Result<String, String> {
    let bodies = attach(d, &fitted.volumes)?;
    let mut s = format!(
        "# Collision model of {} ({}), generated by `host-sim import`; do not edit.\n",
        options.name, options.urdf
    );
    s.push_str(&format!("# Regenerate with: {}\n#\n", options.command()));
    s.push_str("# Each volume contains the URDF <collision> primitive above it (host-sim/src/import/collision.rs:\n");
    s.push_str("# cylinder -> capsule, box -> mid-plane rectangle swept by half its thickness, mesh -> bounding\n");
    s.push_str("# capsule); points rounded to 0.1 mm, radii rounded up with a 0.1 mm margin.\n#\n");
    s.push_str("# Units: m. Points are in the frame of the named URDF link. The group is the link of the body the\n");
    s.push_str("# volume moves with (the child link of its moving joint; `world` for a link welded to the root).\n");
    s.push_str("# `capacity` gives the collision model's sizes: volumes and enabled pairs.\n#\n# Line formats:\n");
    s.push_str("#   capacity <volumes> <pairs>\n");
    s.push_str("#   sphere   <name> <group> <link> <radius> <x y z>\n");
    s.push_str("#   capsule  <name> <group> <link> <radius> <x y z> <x y z>\n");
    s.push_str("#   triangle <name> <group> <link> <radius> <x y z> <x y z> <x y z>\n");
    s.push_str("#   exclude  <volume> <volume> <reason>\n");
    s.push_str("# Pairs on the same body and pairs of adjacent links are excluded by the kernel's rules; `exclude`\n");
    s.push_str(&format!(
        "# lines list the others, from the distances over {SURVEY_SAMPLES} random configurations (seed {SURVEY_SEED:#x}):\n"
    ));
    s.push_str("#   constant:    the distance does not change;\n");
    s.push_str(&format!(
        "#   never_close: it stays above d0 + {SURVEY_MARGIN_M} m = {} m (d0 = {ACTIVATION_DISTANCE_M} m, Table 3.1);\n",
        ACTIVATION_DISTANCE_M + SURVEY_MARGIN_M
    ));
    s.push_str("#   always_near: it stays below d0;\n");
    s.push_str("#   welded_parent: a link welded to the root and a body whose joint hangs from it (adjacent\n");
    s.push_str("#                  links; the kernel's rule takes the welded links for the environment).\n\n");
    s.push_str(&format!("# Dropped as inside another volume of the same body: {}.\n\n", contained_list(fitted)));
    s.push_str(&format!("capacity {} {}\n\n", fitted.volumes.len(), survey.enabled.len()));
    s.push_str(&format!("# ---- volumes: {} ----\n", fitted.volumes.len()));
    for (v, (body, _)) in fitted.volumes.iter().zip(&bodies) {
        s.push_str(&format!("# {}\n", v.source));
        let group = body.and_then(|b| d.bodies.get(b)).map_or("world", |b| b.link.as_str());
        let r = number(v.shape.radius);
        let line = match &v.shape.core {
            Core::Point(p) => format!("sphere   {} {group} {} {r}   {}", v.name, v.link, point(p)),
            Core::Segment([a, b]) => {
                format!("capsule  {} {group} {} {r}   {}   {}", v.name, v.link, point(a), point(b))
            }
            Core::Triangle([a, b, c]) => {
                format!("triangle {} {group} {} {r}   {}   {}   {}", v.name, v.link, point(a), point(b), point(c))
            }
        };
        s.push_str(&line);
        s.push('\n');
    }
    s.push_str(&format!(
        "\n# ---- exclusions: {} pairs; {} pairs enabled ----\n",
        survey.excluded.len(),
        survey.enabled.len()
    ));
    for e in &survey.excluded {
        let name = |i: usize| fitted.volumes.get(i).map_or("?", |v| v.name.as_str());
        s.push_str(&format!(
            "exclude {} {} {}  # {:+.3} ... {:+.3}\n",
            name(e.pair.0),
            name(e.pair.1),
            e.reason.name(),
            e.range.0,
            e.range.1
        ));
    }
    Ok(s)
}

/// The module `collision` of the robot's `mod.rs`: the constructor `fixtures/build.rs` compiles
/// from its `<name>.collision`.
pub(crate) fn module_source(name: &str) -> String {
    format!(
        "\n/// The collision model of `fixtures/robots/{name}/{name}.collision`, compiled by `fixtures/build.rs`\n\
         /// (robot-config): its volumes, the listed exclusions and `collision_model::<T>(&model)`.\n\
         pub mod collision {{\n    include!(concat!(env!(\"OUT_DIR\"), \"/{name}_collision.rs\"));\n}}\n"
    )
}

/// The import's collision model: every volume on its body, and the enabled pairs.
#[derive(Clone, Debug)]
pub struct Imported {
    /// Volume names, in file order.
    pub names: Vec<String>,
    /// Each volume's body (`None`: fixed in the world) and its shape in that body's frame (m).
    pub volumes: Vec<(Option<usize>, SweptSphere<f64>)>,
    /// The pairs the survey and the kernel's rules leave enabled (first < second, lexicographic).
    pub pairs: Vec<(usize, usize)>,
}

/// The fitted volumes on their bodies, with the survey's enabled pairs.
pub(crate) fn imported(d: &Description, fitted: &Fitted, survey: &Survey) -> Result<Imported, String> {
    Ok(Imported {
        names: fitted.volumes.iter().map(|v| v.name.clone()).collect(),
        volumes: attach(d, &fitted.volumes)?,
        pairs: survey.enabled.clone(),
    })
}

/// The dropped volumes as `name (in container)`, comma-separated, or `none`.
fn contained_list(fitted: &Fitted) -> String {
    if fitted.contained.is_empty() {
        return "none".to_owned();
    }
    let names: Vec<String> =
        fitted.contained.iter().map(|(v, container)| format!("{} (in {container})", v.name)).collect();
    names.join(", ")
}

/// The README's collision section.
pub fn readme_section(fitted: &Fitted) -> String {
    let mut s = String::from("## Collision model\n\n");
    s.push_str(
        "Swept-sphere volumes fitted to the URDF's `<collision>` elements (`host-sim/src/import/collision.rs`): ",
    );
    s.push_str("a cylinder or capsule becomes a capsule, a box the rectangle in its mid-plane swept by half its ");
    s.push_str(
        "thickness, a mesh (STL or COLLADA) its bounding capsule along the vertices' principal direction. The pair ",
    );
    s.push_str(&format!(
        "exclusions come from a survey over {SURVEY_SAMPLES} random configurations (see the header of the `.collision` file).\n\n"
    ));
    s.push_str(&format!(
        "Dropped as inside another volume of the same body ({}): {}.\n\n",
        fitted.contained.len(),
        contained_list(fitted)
    ));
    s.push_str("| volume | link | fitted to |\n| --- | --- | --- |\n");
    for v in &fitted.volumes {
        s.push_str(&format!("| `{}` | `{}` | {} |\n", v.name, v.link, v.source));
    }
    s
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "test code: failures should panic")]
mod tests {
    use super::*;

    #[test]
    fn the_bounding_capsule_contains_every_point() {
        let points: Vec<Vector3<f64>> = (0..50)
            .map(f64::from)
            .map(|t| Vector3::new(0.01 * t, 0.03 * (t * 0.7).sin(), 0.02 * (t * 1.3).cos()))
            .collect();
        let capsule = outward(bounding_capsule(&points).unwrap());
        let worst = points.iter().map(|p| capsule.signed_distance_to(p)).fold(f64::NEG_INFINITY, f64::max);
        assert!(worst <= 0.0, "a point lies {worst} m outside");
        // Along x the points span 0.49 m: the capsule is not much longer.
        let Core::Segment([a, b]) = capsule.core else { panic!("not a capsule") };
        assert!((a - b).norm() + 2.0 * capsule.radius < 0.49 + 0.15, "{capsule:?}");
    }

    #[test]
    fn a_volume_is_inside_another_exactly_when_its_corners_are_deep_enough() {
        let capsule = SweptSphere::capsule(Vector3::zeros(), Vector3::new(1.0, 0.0, 0.0), 0.2);
        let segment = |y: f64, r: f64| SweptSphere::capsule(Vector3::new(0.1, y, 0.0), Vector3::new(0.9, y, 0.0), r);
        assert!(inside(&segment(0.0, 0.2), &capsule));
        assert!(inside(&segment(0.05, 0.15), &capsule));
        assert!(!inside(&segment(0.05, 0.16), &capsule), "reaches 0.21 from the axis");
        let triangle = SweptSphere::swept_triangle(
            Vector3::new(0.2, -0.1, 0.0),
            Vector3::new(0.8, -0.1, 0.0),
            Vector3::new(0.5, 0.1, 0.0),
            0.1,
        );
        assert!(inside(&triangle, &capsule));
        assert!(!inside(&capsule, &triangle));
        assert!(inside(&SweptSphere::sphere(Vector3::new(1.1, 0.0, 0.0), 0.099), &capsule));
        assert!(!inside(&SweptSphere::sphere(Vector3::new(1.1, 0.0, 0.0), 0.11), &capsule));
    }

    /// A COLLADA file with one mesh of three positions (in cm) beside a normals source, of which its
    /// one line uses the first two.
    const DAE: &str = r##"<?xml version="1.0"?>
        <COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
          <asset><unit meter="0.01"/><up_axis>Y_UP</up_axis></asset>
          <library_geometries><geometry id="g"><mesh>
            <source id="g-normals"><float_array id="n" count="3">9 9 9</float_array></source>
            <source id="g-positions"><float_array id="p" count="9">1 2 3 -4 5 -6 70 70 70</float_array></source>
            <vertices id="g-vertices"><input semantic="POSITION" source="#g-positions"/></vertices>
            <lines count="1">
              <input offset="0" semantic="VERTEX" source="#g-vertices"/>
              <input offset="1" semantic="NORMAL" source="#g-normals"/>
              <p>1 0 0 0</p>
            </lines>
          </mesh></geometry></library_geometries>
          <library_visual_scenes><visual_scene id="s">
            <node id="node"><instance_geometry url="#g"/></node>
          </visual_scene></library_visual_scenes>
        </COLLADA>"##;

    /// The vertices (or the error) of the COLLADA `text` scaled by `[1, 1, 2]`.
    fn collada(text: &str) -> Result<Vec<Vector3<f64>>, String> {
        let path = std::env::temp_dir().join(format!("host-sim-{}-mesh.dae", std::process::id()));
        std::fs::write(&path, text).unwrap();
        let vertices = mesh_vertices(path.to_str().unwrap(), [1.0, 1.0, 2.0], None);
        std::fs::remove_file(&path).unwrap();
        vertices
    }

    #[test]
    fn collada_positions_are_read_in_the_files_unit_and_only_where_a_primitive_uses_them() {
        let vertices = collada(DAE).unwrap();
        let expected = [Vector3::new(0.01, 0.02, 0.06), Vector3::new(-0.04, 0.05, -0.12)];
        assert_eq!(vertices.len(), 2);
        for (v, e) in vertices.iter().zip(expected) {
            assert!((v - e).amax() < 1e-15, "{v} != {e}");
        }
        let moved = DAE.replace(r#"<node id="node">"#, r#"<node id="node"><translate>0 0 1</translate>"#);
        let error = collada(&moved).unwrap_err();
        assert!(error.ends_with("<node> node has a transform, which the import does not apply"), "{error}");
        let beyond = DAE.replace("<p>1 0 0 0</p>", "<p>1 0 3 0</p>");
        assert!(collada(&beyond).unwrap_err().ends_with("vertex index 3 of 3 positions"));
        // Drake's iiwa names OBJ collision meshes; they were read as STL ("failed to fill whole buffer").
        let obj = mesh_vertices("package://drake_models/link_6.obj", [1.0; 3], Some(Path::new("/meshes"))).unwrap_err();
        assert!(
            obj.starts_with(
                "mesh /meshes/drake_models/link_6.obj: the import reads STL and COLLADA .dae meshes, not .obj"
            ),
            "{obj}"
        );
    }

    #[test]
    fn a_box_is_covered_by_its_mid_plane_rectangle() {
        let origin =
            Placement::from_parts(Translation3::new(0.1, 0.0, 0.2), Rotation3::from_euler_angles(0.3, 0.0, 0.5));
        let volumes = box_triangles([0.2, 0.05, 0.1], &origin);
        assert_eq!(volumes.len(), 2);
        assert!((volumes[0].0.radius - 0.0251).abs() < 1e-12);
        for corner in 0..8 {
            let sign = |bit: usize| if corner >> bit & 1 == 1 { 1.0 } else { -1.0 };
            let p = (origin * Point3::new(0.1 * sign(0), 0.025 * sign(1), 0.05 * sign(2))).coords;
            let inside = volumes.iter().map(|(v, _)| v.signed_distance_to(&p)).fold(f64::INFINITY, f64::min);
            assert!(inside <= 0.0, "corner {corner} outside by {inside}");
        }
    }
}
