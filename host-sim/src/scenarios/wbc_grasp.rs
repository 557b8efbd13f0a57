//! `wbc_grasp`: Rollin' Justin reaches with the left hand for an object on a table, driving up
//! to the table with the whole-body impedance and backing off again (Sec. 6.2, Fig. 6.8).
//!
//! Setup: the rig of [`crate::wbc::rig`] with the Fig. 6.3 hierarchy for the **left** TCP and a
//! table as four environment volumes (world frame, chosen): the top, a 5 cm slab at
//! [`TABLE_HEIGHT_M`] spanning `x ∈ [TABLE_EDGE_X_M, TABLE_EDGE_X_M + TABLE_DEPTH_M]`, and a
//! front panel (the table's apron and legs, down to 5 cm above the floor) at the front edge, each a
//! pair of swept triangles. They are paired with every robot volume, so the collision avoidance
//! repels the platform, torso and arms from the table. The object stands
//! [`OBJECT_BEYOND_EDGE_M`] behind the front edge, [`OBJECT_LATERAL_M`] to the left of the hand's
//! start, grasped [`GRASP_HEIGHT_M`] above the table top with the hand turned by
//! [`GRASP_YAW_RAD`] about the vertical: out of
//! the arm's reach from the start, so the platform has to drive towards the table.
//!
//! The left hand moves to the object along the controller's 6-DOF cubic in [`REACH_S`]
//! (`TcpGoal`), stays there for [`HOLD_S`], and returns to its start pose in
//! [`REACH_S`].
//!
//! Claims: the goal is reached (TCP within 2 cm at the end of the hold); the platform drives
//! towards the table (> 0.2 m) and stops short of it (platform–table distance > 0, the front of
//! the platform box before the edge); the hand returns to its start within 2 cm; no collision
//! (every pair distance > 0); no fault.

use fixtures::justin::{self, whole_body};
use kernel::controller::config::ArmId;
use kernel::controller::messages::Command;
use kernel::tasks::collision::SweptSphere;
use nalgebra::{Rotation3, Vector3};

use super::wbc_step::{col, common_claims, distance_to, line, points, pose_of, tcp_columns};
use super::{Outcome, RunOptions};
use crate::output::{Figure, Line, Panel, Span, Summary, TimeSeries};
use crate::wbc::{self, ConfigChanges};

/// Registry name.
pub const NAME: &str = "wbc_grasp";
/// One-line description.
pub const DESCRIPTION: &str =
    "Justin whole-body impedance: left hand reaches an object on a table, the base drives up to the table and stops short, then returns (Fig. 6.8)";
/// Height of the table top (m).
pub const TABLE_HEIGHT_M: f64 = 0.75;
/// Front edge of the table (world x, m); the robot starts at the origin facing +x.
pub const TABLE_EDGE_X_M: f64 = 1.0;
/// Depth of the table (m).
pub const TABLE_DEPTH_M: f64 = 0.8;
/// Lateral extent of the table (world y, m).
pub const TABLE_Y_M: (f64, f64) = (-0.6, 0.9);
/// Half thickness of the table's volumes (m).
pub const TABLE_RADIUS_M: f64 = 0.025;
/// The object's distance behind the front edge (world x, m).
pub const OBJECT_BEYOND_EDGE_M: f64 = 0.4;
/// Height of the grasp point (the top of the object) above the table (m).
pub const GRASP_HEIGHT_M: f64 = 0.15;
/// Lateral offset of the object from the hand's start (world y, m).
pub const OBJECT_LATERAL_M: f64 = 0.1;
/// Rotation of the grasp orientation about the world vertical (rad): 20°, so the reach is a
/// 6-DOF motion.
pub const GRASP_YAW_RAD: f64 = -20.0 * core::f64::consts::PI / 180.0;
/// Start of the reach (s).
pub const REACH_AT_S: f64 = 0.5;
/// Duration of the reach and of the return (s).
pub const REACH_S: f64 = 6.0;
/// Hold at the object (s).
pub const HOLD_S: f64 = 2.0;
/// Start of the return (s).
pub const RETURN_AT_S: f64 = REACH_AT_S + REACH_S + HOLD_S;
/// Simulated time (s).
pub const DURATION_S: f64 = RETURN_AT_S + REACH_S + 2.0;
/// Goal tolerance (m).
pub const GOAL_TOLERANCE_M: f64 = 0.02;
/// Front of the platform's collision box from the base origin (m): `0.35 + 0.125`.
pub const PLATFORM_FRONT_M: f64 = 0.475;

/// The table's four volumes: the top (two triangles) and the front panel (two triangles).
pub fn table() -> [SweptSphere<f64>; 4] {
    let (x0, x1) = (TABLE_EDGE_X_M, TABLE_EDGE_X_M + TABLE_DEPTH_M);
    let (y0, y1) = TABLE_Y_M;
    let z = TABLE_HEIGHT_M - TABLE_RADIUS_M;
    let r = TABLE_RADIUS_M;
    let (a, b, c, d) =
        (Vector3::new(x0, y0, z), Vector3::new(x1, y0, z), Vector3::new(x1, y1, z), Vector3::new(x0, y1, z));
    let (e, f) = (Vector3::new(x0, y0, 0.05 + r), Vector3::new(x0, y1, 0.05 + r));
    [
        SweptSphere::swept_triangle(a, b, c, r),
        SweptSphere::swept_triangle(a, c, d, r),
        SweptSphere::swept_triangle(a, d, f, r),
        SweptSphere::swept_triangle(a, f, e, r),
    ]
}

/// The phases the replay names: reach, hold, return.
pub fn phases() -> Vec<(f64, String)> {
    vec![
        (
            REACH_AT_S,
            format!("the left hand starts reaching for the object on the table ({REACH_S:.0} s, 6-DOF cubic)"),
        ),
        (REACH_AT_S + REACH_S, format!("the left hand's goal is at the object: hold for {HOLD_S:.0} s")),
        (RETURN_AT_S, "the left hand returns to its start pose".into()),
        (RETURN_AT_S + REACH_S, "the goal is back at the start".into()),
    ]
}

/// Runs the scenario: setup, run, measures, claims, figures.
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    let mut rig = setup(options)?;
    let (series, start, goal) = run(&mut rig, options)?;
    let measures = Measures::new(&series, &start, &goal)?;
    let summary = claims(&measures, &goal, &rig, &series)?;
    let figures = vec![
        ("grasp_top_view.svg", top_view(&measures, &goal)),
        ("grasp_time.svg", time_histories(&measures, &series)?),
    ];
    Ok(Outcome { summary, series, figures })
}

/// The rig with the table and the Fig. 6.3 hierarchy for the left hand.
fn setup(options: &RunOptions) -> Result<wbc::Rig, String> {
    let hierarchy = whole_body::fig_6_3_hierarchy(ArmId::LEFT);
    wbc::rig(&justin::home_configuration(), &table(), ConfigChanges::NONE, &hierarchy, options)
}

/// Runs [`DURATION_S`] with the reach and the return; returns the series, the left TCP's start
/// position and the object's position.
fn run(rig: &mut wbc::Rig, options: &RunOptions) -> Result<(TimeSeries, Vector3<f64>, Vector3<f64>), String> {
    let mut start = None;
    let mut goal = None;
    let series = rig.run(DURATION_S, |rig, info| {
        if info.cycle % 100 == 0 {
            options.progress.report(NAME, info.time_s, DURATION_S);
        }
        let begin = *start.get_or_insert(rig.tcp_target(ArmId::LEFT)?.pose);
        let mut object = begin;
        object.translation.vector.x = TABLE_EDGE_X_M + OBJECT_BEYOND_EDGE_M;
        object.translation.vector.y += OBJECT_LATERAL_M;
        object.translation.vector.z = TABLE_HEIGHT_M + GRASP_HEIGHT_M;
        object.rotation = Rotation3::from_axis_angle(&Vector3::z_axis(), GRASP_YAW_RAD) * begin.rotation;
        goal.get_or_insert(object.translation.vector);
        let near = |t: f64| (info.time_s - t).abs() < 0.5 * crate::sim::CONTROL_PERIOD_S;
        for (at, target) in [(REACH_AT_S, object), (RETURN_AT_S, begin)] {
            if near(at) {
                let command = Command::TcpGoal { hand: ArmId::LEFT, pose: pose_of(&target), duration_s: REACH_S };
                rig.apply(&command).map_err(|e| format!("goal: {e}"))?;
            }
        }
        Ok(())
    })?;
    options.progress.finish();
    Ok((series, start.ok_or("no cycle ran")?.translation.vector, goal.ok_or("no cycle ran")?))
}

/// The signals and numbers the claims and the figures share.
struct Measures {
    /// Time (s).
    t: Vec<f64>,
    /// Left TCP position, world x, y, z (m).
    tcp: [Vec<f64>; 3],
    /// Left TCP distance to the object and to its start (m).
    to_goal: Vec<f64>,
    to_start: Vec<f64>,
    /// Platform position x, y (m) and yaw (rad).
    bx: Vec<f64>,
    by: Vec<f64>,
    yaw: Vec<f64>,
    /// Position and orientation error at the end of the hold (m, rad).
    goal_error: f64,
    orientation_error: f64,
    /// Distance to the start at the end (m).
    return_error: f64,
    /// Largest platform x (m) and the gap of its front to the table then (m).
    base_peak: f64,
    front_gap: f64,
}

impl Measures {
    fn new(series: &TimeSeries, start: &Vector3<f64>, goal: &Vector3<f64>) -> Result<Self, String> {
        let t = col(series, "t")?;
        let tcp = tcp_columns(series, ArmId::LEFT)?;
        let to_goal = distance_to(&tcp, goal);
        let to_start = distance_to(&tcp, start);
        let at = |values: &[f64], time: f64| {
            t.iter().zip(values.iter()).find(|(t, _)| **t >= time).map_or(f64::NAN, |(_, v)| *v)
        };
        let goal_error = at(&to_goal, RETURN_AT_S - 0.01);
        let orientation_error = ["e1.rx", "e1.ry", "e1.rz"]
            .iter()
            .map(|c| col(series, c).map(|v| at(&v, RETURN_AT_S - 0.01)))
            .collect::<Result<Vec<f64>, String>>()?
            .iter()
            .map(|x| x * x)
            .sum::<f64>()
            .sqrt();
        let return_error = to_start.last().copied().unwrap_or(f64::NAN);
        let (bx, by, yaw) = (col(series, "q.base_x")?, col(series, "q.base_y")?, col(series, "q.base_theta")?);
        let base_peak = bx.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let front_gap = TABLE_EDGE_X_M - TABLE_RADIUS_M - (base_peak + PLATFORM_FRONT_M);
        Ok(Self {
            t,
            tcp,
            to_goal,
            to_start,
            bx,
            by,
            yaw,
            goal_error,
            orientation_error,
            return_error,
            base_peak,
            front_gap,
        })
    }
}

/// Metrics and claims (module docs).
fn claims(m: &Measures, goal: &Vector3<f64>, rig: &wbc::Rig, series: &TimeSeries) -> Result<Summary, String> {
    let Measures { goal_error, orientation_error, return_error, base_peak, front_gap, .. } = *m;
    let mut summary = Summary::new(NAME);
    summary
        .metric("goal_error_m", goal_error)
        .metric("goal_orientation_error_rad", orientation_error)
        .metric("return_error_m", return_error)
        .metric("base_peak_x_m", base_peak)
        .metric("platform_front_to_table_m", front_gap)
        .metric("object_x_m", goal.x)
        .metric("object_z_m", goal.z);
    summary.claim(
        &format!(
            "the left hand reaches the object: {:.1} mm < {:.0} mm at the end of the hold",
            goal_error * 1e3,
            GOAL_TOLERANCE_M * 1e3
        ),
        goal_error < GOAL_TOLERANCE_M,
    );
    summary.claim(
        &format!(
            "the platform drives towards the table ({base_peak:.2} m > 0.2 m) and stops short: its front stays {:.0} mm before the table",
            front_gap * 1e3
        ),
        base_peak > 0.2 && front_gap > 0.0,
    );
    summary.claim(
        &format!("the hand returns to its start pose: {:.1} mm < {:.0} mm", return_error * 1e3, GOAL_TOLERANCE_M * 1e3),
        return_error < GOAL_TOLERANCE_M,
    );
    common_claims(&mut summary, rig, series)?;
    Ok(summary)
}

/// The main figure: top view and side view (shared world x).
fn top_view(m: &Measures, goal: &Vector3<f64>) -> Figure {
    let Measures { tcp, bx, by, yaw, goal_error, front_gap, .. } = m;
    let xy = |x: &[f64], y: &[f64]| x.iter().zip(y.iter()).step_by(20).map(|(x, y)| (*x, *y)).collect::<Vec<_>>();
    let (x0, x1) = (TABLE_EDGE_X_M, TABLE_EDGE_X_M + TABLE_DEPTH_M);
    let (y0, y1) = TABLE_Y_M;
    let outline = vec![(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)];
    // The platform's footprint at row `i`: its rectangle turned by its yaw.
    let footprint = |i: usize| {
        let (fx, fy) = (PLATFORM_FRONT_M, 0.3 + 0.125);
        let at = |v: &[f64]| v.get(i).copied().unwrap_or(f64::NAN);
        let (x, y, (sin, cos)) = (at(bx), at(by), at(yaw).sin_cos());
        [(-fx, -fy), (fx, -fy), (fx, fy), (-fx, fy), (-fx, -fy)]
            .map(|(u, v)| (x + cos * u - sin * v, y + sin * u + cos * v))
            .to_vec()
    };
    let (closest_row, closest_x) =
        bx.iter().enumerate().fold((0, f64::NEG_INFINITY), |best, (i, x)| if *x > best.1 { (i, *x) } else { best });
    let marker =
        |p: &Vector3<f64>, s: f64| vec![(p.x - s, p.y), (p.x + s, p.y), (p.x, p.y), (p.x, p.y - s), (p.x, p.y + s)];
    let top = Panel {
        title: "top view: platform centre path, left hand path, table and object".into(),
        y_label: "world y (m)".into(),
        lines: vec![
            Line::new("platform centre", xy(bx, by)),
            Line::new("left hand (TCP)", xy(&tcp[0], &tcp[1])),
            Line::new("platform footprint at its closest", footprint(closest_row)),
            Line::dashed("table", outline),
            Line::new("object (goal)", marker(goal, 0.04)),
            Line::dashed("platform footprint at the start", footprint(0)),
        ],
        spans: vec![],
    };
    let side = Panel {
        title: "side view: left hand height over the table".into(),
        y_label: "world z (m)".into(),
        lines: vec![
            Line::new("left hand (TCP)", xy(&tcp[0], &tcp[2])),
            Line::new("platform box at its closest", {
                let (b, f) = (closest_x, PLATFORM_FRONT_M);
                vec![(b - f, 0.05), (b + f, 0.05), (b + f, 0.55 + 0.125), (b - f, 0.55 + 0.125), (b - f, 0.05)]
            }),
            Line::dashed(
                "table",
                vec![(x0, TABLE_HEIGHT_M), (x1, TABLE_HEIGHT_M), (x1, 0.0), (x0, 0.0), (x0, TABLE_HEIGHT_M)],
            ),
            Line::new(
                "object (goal)",
                vec![
                    (goal.x - 0.04, goal.z),
                    (goal.x + 0.04, goal.z),
                    (goal.x, goal.z),
                    (goal.x, goal.z - 0.04),
                    (goal.x, goal.z + 0.04),
                ],
            ),
        ],
        spans: vec![],
    };
    Figure {
        title: format!(
            "wbc_grasp (cf. Fig. 6.8): object reached within {:.0} mm; platform stops {:.0} mm before the table",
            goal_error * 1e3,
            front_gap * 1e3
        ),
        x_label: "world x (m)".into(),
        panels: vec![top, side],
    }
}

/// The time histories: distances of the hand, the platform, the collision distance.
fn time_histories(m: &Measures, series: &TimeSeries) -> Result<Figure, String> {
    let Measures { t, to_goal, to_start, .. } = m;
    let spans = || {
        vec![
            Span { label: "reach".into(), from: REACH_AT_S, to: REACH_AT_S + REACH_S },
            Span { label: "return".into(), from: RETURN_AT_S, to: RETURN_AT_S + REACH_S },
        ]
    };
    Ok(Figure {
        title: "wbc_grasp: time histories".into(),
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: "left hand distance to the object and to its start".into(),
                y_label: "distance (m)".into(),
                lines: vec![
                    Line::new("to the object", points(t, to_goal, 10, 1.0)),
                    Line::new("to the start", points(t, to_start, 10, 1.0)),
                ],
                spans: spans(),
            },
            Panel {
                title: "platform position".into(),
                y_label: "position (m)".into(),
                lines: vec![
                    line(series, "base x", "q.base_x", 1.0)?,
                    line(series, "base y", "q.base_y", 1.0)?,
                    Line::dashed(
                        "table edge − platform front",
                        points(t, &vec![TABLE_EDGE_X_M - PLATFORM_FRONT_M; t.len()], 100, 1.0),
                    ),
                ],
                spans: spans(),
            },
            Panel {
                title: "platform velocity command".into(),
                y_label: "velocity (m/s)".into(),
                lines: vec![line(series, "commanded v_x", "vcmd.x", 1.0)?],
                spans: spans(),
            },
            Panel {
                title: "smallest collision distance (robot–robot and robot–table)".into(),
                y_label: "distance (mm)".into(),
                lines: vec![line(series, "min pair distance", "min_distance", 1e3)?],
                spans: spans(),
            },
        ],
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;

    #[test]
    fn wbc_grasp_reaches_the_object_and_the_base_stops_short() {
        let outcome = simulate(&RunOptions::default()).unwrap();
        let s = &outcome.summary;
        assert!(s.failed_claims().is_empty(), "failed: {:?}", s.failed_claims());
        assert!(s.get("goal_error_m").unwrap() < GOAL_TOLERANCE_M);
        assert!(s.get("platform_front_to_table_m").unwrap() > 0.0);
        assert!(s.get("min_collision_distance_m").unwrap() > 0.0);
    }
}
