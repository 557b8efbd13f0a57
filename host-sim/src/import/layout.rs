//! The robot's layout (docs/LAYOUT.md, step 6) derived from its kinematic tree: which
//! coordinates are an arm, the torso and the platform.
//!
//! - **Arms**: one per TCP, in the order of the `--tcp` options. An arm's coordinates are those
//!   on the chain from the root to its TCP that no other TCP's chain drives.
//! - **Torso**: the coordinates on two or more chains that are not platform coordinates; none if
//!   there are no such coordinates (one TCP, or chains that part at the platform).
//! - **Platform**: with `--base planar`, coordinates 0, 1 and 2 (`base_x`, `base_y`,
//!   `base_theta`), admitted; otherwise none (a fixed base).
//!
//! A chain's coordinates are those its bodies' drives name, so a coupled joint (Justin's passive
//! torso joint, (3.41)) counts with the coordinates it follows.
//!
//! - **Elbow** (where the generic scenario `posture_push` pushes): the link of the body driven
//!   by the middle coordinate of arm 0 (index `len / 2` of its coordinates in order: the Panda's
//!   `panda_link4`, TIAGo++'s `arm_left_4_link`).

use crate::urdf::{self, Coupling, Description};

/// Coordinates of the planar platform the import adds first: `base_x`, `base_y`, `base_theta`.
pub const PLATFORM_COORDINATES: usize = 3;

/// The coordinates of each part of a robot (`true` where the coordinate belongs to it).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Layout {
    /// Per TCP, the arm's coordinates.
    pub arms: Vec<Vec<bool>>,
    /// The torso's coordinates, `None` without a torso.
    pub torso: Option<Vec<bool>>,
    /// `true` if coordinates 0 to 2 are the admitted planar platform.
    pub planar_base: bool,
}

/// The layout of the URDF file `path` with the TCP links `tcps` (errors: the loader's, an unknown
/// TCP link). `planar_base`: the file's first three coordinates are the platform's, as the
/// import's `--base planar` writes them (Justin's URDF has them).
pub fn derive_file(path: &std::path::Path, tcps: &[String], planar_base: bool) -> Result<Layout, String> {
    derive(&urdf::describe_file(path, Coupling::Coupled)?, tcps, planar_base)
}

/// The layout of `description` with the TCP links `tcps` (module docs).
pub(crate) fn derive(description: &Description, tcps: &[String], planar_base: bool) -> Result<Layout, String> {
    let n = description.coordinate_count();
    let chains = tcps.iter().map(|tcp| chain(description, tcp)).collect::<Result<Vec<_>, _>>()?;
    let platform = |k: usize| planar_base && k < PLATFORM_COORDINATES;
    let sharing = |k: usize| chains.iter().filter(|chain| chain.get(k) == Some(&true)).count();
    let arms = chains
        .iter()
        .map(|chain| chain.iter().enumerate().map(|(k, on)| *on && sharing(k) == 1 && !platform(k)).collect())
        .collect();
    let torso: Vec<bool> = (0..n).map(|k| sharing(k) > 1 && !platform(k)).collect();
    Ok(Layout { arms, torso: torso.contains(&true).then_some(torso), planar_base })
}

/// The elbow of `layout` (module docs): the link of the first body the middle coordinate of arm
/// 0 drives.
pub(crate) fn elbow<'a>(description: &'a Description, layout: &Layout) -> Result<&'a str, String> {
    let arm: Vec<usize> = layout
        .arms
        .first()
        .map(|arm| arm.iter().enumerate().filter(|(_, on)| **on).map(|(k, _)| k).collect())
        .unwrap_or_default();
    let middle = arm.get(arm.len() / 2).ok_or("arm 0 has no coordinates of its own: no elbow for posture_push")?;
    description
        .bodies
        .iter()
        .find(|body| body.terms.iter().any(|(coordinate, _)| coordinate == middle))
        .map(|body| body.link.as_str())
        .ok_or_else(|| format!("no body is driven by coordinate {middle}"))
}

/// The coordinates that drive the bodies from the root to the link `tcp`.
fn chain(description: &Description, tcp: &str) -> Result<Vec<bool>, String> {
    let frame = description
        .frames
        .iter()
        .find(|frame| frame.link == tcp)
        .ok_or_else(|| format!("unknown TCP frame {tcp}: the model has no link of that name"))?;
    let mut on_chain = vec![false; description.coordinate_count()];
    let mut body = frame.parent;
    while let Some(b) = body.and_then(|b| description.bodies.get(b)) {
        for (coordinate, _) in &b.terms {
            if let Some(slot) = on_chain.get_mut(*coordinate) {
                *slot = true;
            }
        }
        body = b.parent;
    }
    Ok(on_chain)
}

/// The Rust items of `layout` in a robot's generated module (after `N`, `TCPS` and the imports
/// of [`crate::codegen`]): `JOINTS`, `ARMS`, `ARM_COORDINATES`, `TORSO_COORDINATES` and `layout()`.
pub(crate) fn source(layout: &Layout) -> String {
    let mask =
        |coordinates: &[bool]| format!("[{}]", coordinates.iter().map(bool::to_string).collect::<Vec<_>>().join(", "));
    let arms: Vec<String> = layout.arms.iter().map(|arm| mask(arm)).collect();
    let torso = layout.torso.as_deref().map_or("None".to_owned(), |torso| format!("Some({})", mask(torso)));
    let axes = if layout.planar_base {
        "[Axis::Admitted(0), Axis::Admitted(1), Axis::Admitted(2)]"
    } else {
        "[Axis::Absent; 3]"
    };
    let (platform_doc, joints) = if layout.planar_base {
        ("the planar platform `base_x`, `base_y`, `base_theta` (coordinates 0 to 2), admitted", "N - 3")
    } else {
        ("none (a fixed base)", "N")
    };
    format!(
        "\n/// Torque-controlled joints (the controller's `U`): the coordinates after the platform's.\n\
         pub const JOINTS: usize = {joints};\n\
         /// Number of arms: one per TCP, in the order of [`TCPS`].\n\
         pub const ARMS: usize = {arms_len};\n\
         /// Coordinates of each arm: those on the chain from the root to its TCP that no other TCP's chain drives.\n\
         pub const ARM_COORDINATES: [[bool; N]; ARMS] = [{arms}];\n\
         /// Torso coordinates: those on two or more TCP chains that are not the platform's (`None`: no torso).\n\
         pub const TORSO_COORDINATES: Option<[bool; N]> = {torso};\n\n\
         /// The robot's layout: one arm per TCP ([`ARM_COORDINATES`]), the torso ([`TORSO_COORDINATES`]), platform: {platform_doc}.\n\
         pub fn layout() -> Result<kernel::controller::config::RobotLayout<N, ARMS>, kernel::platform::PlatformError> {{\n    \
         use kernel::platform::{{PlatformAxis as Axis, PlatformLayout}};\n    \
         let platform = PlatformLayout::try_new::<N>({axes})?;\n    \
         Ok(kernel::controller::config::RobotLayout {{ tcp: TCPS, platform, torso: TORSO_COORDINATES, arms: ARM_COORDINATES }})\n}}\n",
        arms_len = layout.arms.len(),
        arms = arms.join(", "),
    )
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;

    /// A trunk joint `t` and two branches `a` → TCP `ta`, `b` → TCP `tb`.
    const TREE: &str = r#"<robot name="y">
      <link name="base"/><link name="trunk"/><link name="a"/><link name="b"/><link name="ta"/><link name="tb"/>
      <joint name="t" type="revolute"><parent link="base"/><child link="trunk"/><axis xyz="0 0 1"/>
        <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
      <joint name="ja" type="revolute"><parent link="trunk"/><child link="a"/><axis xyz="0 1 0"/>
        <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
      <joint name="jb" type="revolute"><parent link="trunk"/><child link="b"/><axis xyz="0 1 0"/>
        <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
      <joint name="fa" type="fixed"><parent link="a"/><child link="ta"/></joint>
      <joint name="fb" type="fixed"><parent link="b"/><child link="tb"/></joint>
    </robot>"#;

    fn layout_of(tcps: &[&str]) -> Layout {
        let description = urdf::describe(TREE, Coupling::Coupled).unwrap();
        derive(&description, &tcps.iter().map(|t| (*t).to_owned()).collect::<Vec<_>>(), false).unwrap()
    }

    #[test]
    fn shared_coordinates_are_the_torso_the_rest_are_arms() {
        let two = layout_of(&["ta", "tb"]);
        assert_eq!(two.arms, [vec![false, true, false], vec![false, false, true]]);
        assert_eq!(two.torso, Some(vec![true, false, false]));
        let one = layout_of(&["ta"]);
        assert_eq!(one.arms, [vec![true, true, false]]);
        assert_eq!(one.torso, None);
    }

    #[test]
    fn the_elbow_is_the_body_of_arm_0s_middle_coordinate() {
        let description = urdf::describe(TREE, Coupling::Coupled).unwrap();
        assert_eq!(elbow(&description, &layout_of(&["ta", "tb"])).unwrap(), "a");
        assert_eq!(elbow(&description, &layout_of(&["ta"])).unwrap(), "a");
    }

    #[test]
    fn a_planar_base_leaves_the_controller_the_joints_after_its_three_coordinates() {
        let fixed = layout_of(&["ta"]);
        assert!(source(&fixed).contains("pub const JOINTS: usize = N;"));
        assert!(source(&fixed).contains("[Axis::Absent; 3]"));
        let planar = Layout { planar_base: true, ..fixed };
        assert!(source(&planar).contains("pub const JOINTS: usize = N - 3;"));
        assert!(source(&planar).contains("[Axis::Admitted(0), Axis::Admitted(1), Axis::Admitted(2)]"));
    }

    #[test]
    fn an_unknown_tcp_is_an_error() {
        let description = urdf::describe(TREE, Coupling::Coupled).unwrap();
        let error = derive(&description, &["nope".to_owned()], false).unwrap_err();
        assert_eq!(error, "unknown TCP frame nope: the model has no link of that name");
    }
}
