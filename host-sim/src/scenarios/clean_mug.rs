//! `clean_mug`: "Clean the mug!" of Table 7.1 (Sec. 7.3, Fig. 7.2) on the simulated Justin
//! under the whole-body controller: both arms and torso, no base motion, with compliant contact
//! surfaces ([`crate::sim::Surface`]).
//!
//! Setup (shared machinery in [`super::wipe_window::run_tool`]): at the first cycle the planner
//! switches both TCPs to the Table 7.1 parameters of [`CLEAN_MUG`] (`(400, 400, 800)` N/m,
//! `(30, 30, 60)` Nm/rad, `±20 N` on every tool axis, in the axes of the desired TCP frame) and
//! its hierarchy (Cartesian impedances > joint impedance > end stop avoidance > singularity
//! avoidance). The mug is modelled as a block [`MUG_WIDTH_M`] wide between the hands, fixed
//! in the world: the left TCP (holding the mug) presses on its left face, the right TCP (the
//! brush) on its right face and scrubs [`CIRCLES`] circles of radius [`CIRCLE_RADIUS_M`] on it.
//! The simulator has no object dynamics, so the mug cannot move between the hands: the two
//! contacts are two world-fixed half-spaces. Each tool's z axis (the stiffest, 800 N/m) is
//! turned onto its pressing direction (smallest rotation of the start orientation), and the
//! references are placed [`BEHIND_M`] behind the faces (40 N of spring force, limited to 20 N).
//!
//! No base motion (Table 7.1: "both arms, torso"): the platform admittance is locked
//! (`free_base_axes = [false; 3]` in the rig's [`crate::wbc::ConfigChanges`]), so
//! the base is held at rest (`ṙ_des = 0`) like a braked platform. A joint impedance of the
//! platform would still let the contact forces move the base by `F/k`.
//!
//! The approach ([`super::wipe_window::press_path`]) brings both TCPs onto the faces, the last
//! centimetres slowly, so that they touch at rest. The brush circles are one smooth motion
//! ([`super::wipe_window::Circles`]: the angle follows a quintic over the scrubbing), not a
//! chain of rest-to-rest segments: stopping twelve times per circle made the brush chatter on
//! the face (≈ 9 Hz, ±2.5 N).
//!
//! Claims ([`super::wipe_window::force_claims`]): the contact forces never exceed 20 N over the
//! whole run, and the static and mean forces stay within it; contact kept during the scrubbing;
//! the brush circles are executed; the base does not move; no fault. On the realistic plant the
//! force bounds widen by the joint friction's bound (`force_claims`).

use fixtures::justin;
use fixtures::justin::whole_body::CLEAN_MUG;
use kernel::controller::config::ArmId;
use kernel::dynamics::forward_kinematics;
use kernel::model::{Data, FrameId, Placement};
use kernel::tasks::collision::SweptSphere;
use nalgebra::{SVector, Unit, Vector3};

use super::wipe_window::{
    base_travel, force_claims, labelled_contact_metrics, measured_range, press_path, run_tool, tool_figures,
    tool_orientation, Circles, Contact, ToolPlan, ToolReference, Waypoints, HOLD_S,
};
use super::{Outcome, RunOptions};
use crate::output::Span;
use crate::sim::Surface;
use crate::wbc::ConfigChanges;

/// Registry name.
pub const NAME: &str = "clean_mug";
/// One-line description.
pub const DESCRIPTION: &str =
    "Table 7.1 \"Clean the mug!\": left TCP holds, right TCP scrubs a mug between the hands, references 5 cm inside, ±20 N limits, base locked (Fig. 7.2)";
/// Simulated time (s).
pub const DURATION_S: f64 = 13.0;
/// Width of the mug block between the hands (m); chosen.
pub const MUG_WIDTH_M: f64 = 0.10;
/// Distance of the references behind the faces (m); chosen.
pub const BEHIND_M: f64 = 0.05;
/// Face stiffness (N/m); chosen (ceramic behind a sponge/brush).
pub const FACE_STIFFNESS_N_M: f64 = 1.0e4;
/// Face damping (Ns/m); chosen.
pub const FACE_DAMPING_NS_M: f64 = 50.0;
/// Friction of the brush on the mug; chosen.
pub const FACE_FRICTION: f64 = 0.2;
/// Brush circles.
pub const CIRCLES: usize = 3;
/// Circle radius (m).
pub const CIRCLE_RADIUS_M: f64 = 0.04;
/// When the references reach the faces, the TCPs at rest on them (s).
pub const TOUCH_S: f64 = 2.5;
/// Window of the scrubbing (s).
pub const SCRUB_S: (f64, f64) = (5.0, 11.0);
/// Largest base travel the claim allows (m).
pub const MAX_BASE_TRAVEL_M: f64 = 1e-6;

fn plan(start: [Placement<f64>; 2]) -> ToolPlan {
    let mut references = Vec::new();
    let mut contacts = Vec::new();
    let centre_y = 0.5 * (start[0].translation.vector.y + start[1].translation.vector.y);
    for (hand, placement, label, frame, side) in [
        (ArmId::RIGHT, start[0], "mug_right_face", justin::RIGHT_TCP, -1.0),
        (ArmId::LEFT, start[1], "mug_left_face", justin::LEFT_TCP, 1.0),
    ] {
        let p0 = placement.translation.vector;
        let face_y = centre_y + side * 0.5 * MUG_WIDTH_M;
        // Pressing direction: from the hand towards the mug centre.
        let press = Vector3::new(0.0, -side, 0.0);
        let touch = Vector3::new(p0.x, face_y, p0.z);
        let pressed = touch + press * BEHIND_M;
        let mut points = press_path(p0, touch, pressed, &press, (1.0, TOUCH_S - 0.5, TOUCH_S, SCRUB_S.0 - HOLD_S));
        points.extend([(SCRUB_S.1, pressed), (DURATION_S - 0.3, p0)]);
        #[allow(clippy::cast_precision_loss, reason = "a handful of circles")]
        let circles = (hand == ArmId::RIGHT).then_some(Circles {
            u: Vector3::x(),
            v: Vector3::z(),
            radius_m: CIRCLE_RADIUS_M,
            turns: CIRCLES as f64,
            window_s: SCRUB_S,
        });
        references.push(ToolReference {
            hand,
            start: placement.rotation,
            tool: tool_orientation(&placement.rotation, 2, &press),
            turn_s: (1.0, SCRUB_S.0 - HOLD_S),
            path: Waypoints(points),
            circles,
        });
        contacts.push(Contact {
            label,
            hand,
            surface: Surface {
                frame,
                point: Vector3::new(p0.x, face_y, p0.z),
                normal: Unit::new_normalize(-press),
                stiffness_n_m: FACE_STIFFNESS_N_M,
                damping_ns_m: FACE_DAMPING_NS_M,
                friction: FACE_FRICTION,
            },
        });
    }
    ToolPlan { references, contacts, cartesian: None }
}

/// Where the replay's camera stands, from the scene's centre (m): 2.5 m in front of the robot, a
/// little to its right and above, looking at the mug between the hands.
pub const VIEW: [f64; 3] = [2.1, -0.9, 1.1];

/// Half the height of the mug's core segment as the replay draws it (m); chosen.
const MUG_HALF_CORE_M: f64 = 0.035;

/// The mug as the replay draws it (the simulator only has its two faces): a vertical capsule
/// [`MUG_WIDTH_M`] wide, centred between the hands' start positions at the home configuration,
/// so that its sides are the faces the hands press on (the faces of `plan`). Empty if the model fails.
pub fn mug() -> Vec<SweptSphere<f64>> {
    let Ok(model) = justin::model::<f64>() else { return Vec::new() };
    let mut data = Data::new(&model);
    let home = justin::home_configuration::<f64>();
    if forward_kinematics(&model, &mut data, &home, &SVector::zeros()).is_err() {
        return Vec::new();
    }
    let position = |frame: FrameId| data.frame_placements.get(frame.0).map(|p| p.translation.vector);
    let (Some(right), Some(left)) = (position(justin::RIGHT_TCP), position(justin::LEFT_TCP)) else {
        return Vec::new();
    };
    let centre = 0.5 * (right + left);
    let half = Vector3::new(0.0, 0.0, MUG_HALF_CORE_M);
    vec![SweptSphere::capsule(centre - half, centre + half, 0.5 * MUG_WIDTH_M)]
}

/// The phases the replay names: approach, touch, scrub, release.
pub fn phases() -> Vec<(f64, String)> {
    vec![
        (1.0, "both hands move towards the faces of the mug between them".into()),
        (TOUCH_S, format!("the hands touch the faces; their goals lie {:.0} cm inside the mug", BEHIND_M * 100.0)),
        (SCRUB_S.0, format!("the right hand brushes {CIRCLES} circles on its face, the left hand holds")),
        (SCRUB_S.1, "scrubbing ends: the hands let go and return".into()),
    ]
}

/// Simulates and checks the claims (module docs).
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    let changes = ConfigChanges { free_base_axes: [false; 3] };
    let run = run_tool(NAME, &CLEAN_MUG, &[], &justin::home_configuration(), changes, DURATION_S, plan, options)?;
    let limit = CLEAN_MUG.force_upper[2];
    let travel = base_travel(&run.samples);
    let mut summary = run.summary.clone();
    let all = labelled_contact_metrics(&mut summary, &run, SCRUB_S);
    let share = all.iter().map(|m| m.contact_share).fold(1.0_f64, f64::min);
    let circle_x = measured_range(&run.samples, 0, &Vector3::x(), SCRUB_S);
    let circle_z = measured_range(&run.samples, 0, &Vector3::z(), SCRUB_S);
    summary
        .metric("brush_range_x_m", circle_x)
        .metric("brush_range_z_m", circle_z)
        .metric("base_travel_m", travel)
        .value("faulty_cycles", run.faulty_cycles);
    force_claims(&mut summary, &all, limit, options.plant);
    summary.claim(
        &format!("contact kept while scrubbing: both faces touched in ≥ {:.1} % of the cycles", share * 100.0),
        share > 0.95,
    );
    summary.claim(
        &format!(
            "brush circles done: measured range {circle_x:.3} m (x), {circle_z:.3} m (z) of the commanded {:.3} m",
            2.0 * CIRCLE_RADIUS_M
        ),
        circle_x > 0.6 * 2.0 * CIRCLE_RADIUS_M && circle_z > 0.6 * 2.0 * CIRCLE_RADIUS_M,
    );
    summary.claim(&format!("the base does not move: largest travel {travel:.2e} m"), travel <= MAX_BASE_TRAVEL_M);
    summary.claim(&format!("no fault: {} faulty cycles", run.faulty_cycles), run.faulty_cycles == 0);
    summary.claim("no NaN or infinite value", run.finite);
    let spans = [Span { label: "scrubbing".into(), from: SCRUB_S.0, to: SCRUB_S.1 }];
    let figures = tool_figures(
        NAME,
        &run,
        limit,
        &[("x", Vector3::x()), ("y (pressing)", Vector3::y()), ("z", Vector3::z())],
        &spans,
    );
    Ok(Outcome { summary, series: run.series, figures })
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "test code: failures should panic")]
mod tests {
    use super::*;

    #[test]
    fn clean_mug_claims_hold() {
        let outcome = simulate(&RunOptions::default()).unwrap();
        let s = &outcome.summary;
        assert!(s.failed_claims().is_empty(), "{:?}", s.failed_claims());
        assert!(s.get("base_travel_m").unwrap() <= MAX_BASE_TRAVEL_M);
        assert!(s.get("run_peak_force_n").unwrap() <= 20.0, "Table 7.1: ±20 N, never exceeded");
        assert!(s.get("static_force_n").unwrap() <= 20.0);
        assert!(s.get("motion_mean_force_n").unwrap() <= 20.0);
    }
}
