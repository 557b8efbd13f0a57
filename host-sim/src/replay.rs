//! `replay.html`: a self-contained page that replays a run of a simulated robot in 3-D.
//!
//! One mechanism for every robot scenario; the [`Robot`] parameter says which robot the run
//! drove and where its joint values are in the time series. [`write()`] computes the world
//! placement of every body at a reduced rate ([`REPLAY_RATE_HZ`]) and writes one HTML file
//! holding
//! - the scene: the robot's volumes in their body frames (Justin's swept-sphere collision
//!   volumes, the planar arms' links as capsules, the platform's wheels) and the world-fixed
//!   environment volumes (tables, walls), each with its part;
//! - the frames: time and the body placements (position and unit quaternion);
//! - the hands (TCPs) with their path, goal and force columns, and the platform path;
//! - the signals the page reads: TCP errors, storage per level, external forces on the TCPs,
//!   contact, smallest collision distance, output mode, platform pose ([`SIGNAL_PREFIXES`]),
//!   non-finite values as `null`, under the names of the Justin runs ([`Robot::Justin`]'s
//!   aliases rename a run's own columns);
//! - the story: the scenario's description, its phases (given by the scenario) and the events
//!   found in the signals (forces on the hands, contact, goal steps, platform motion), shown as
//!   marks on the time slider, as a caption and as a list;
//! - the claims of the summary;
//! - the page script `replay/dist/replay.js` (the page code and three.js, bundled by esbuild
//!   from the pinned npm packages in `replay/`, see `replay/README.md`), inlined, so the page
//!   opens from disk without a network.
//!
//! Scenarios whose output is a map over parameters (`torso_workspace`, `stability_map`) are not
//! time series and have no replay.

use std::fs;
use std::path::Path;

use fixtures::justin::{self, collision};
use kernel::dynamics::forward_kinematics;
use kernel::model::Data;
use kernel::tasks::collision::SweptSphere;
use nalgebra::{Isometry3, Point3, SVector, Translation3, UnitQuaternion, Vector3};
use serde_json::{json, Value};

use crate::output::{Summary, TimeSeries};
use crate::wbc::{PAIRS, VOLUMES};

/// Frames per second of simulated time in the replay.
pub const REPLAY_RATE_HZ: f64 = 50.0;

/// Columns copied into the replay (every column whose name starts with one of these).
pub const SIGNAL_PREFIXES: [&str; 8] = ["e0.", "e1.", "S", "force.", "min_distance", "mode", "contact", "q.base_"];

/// The page template; `/*REPLAY_DATA*/` and `/*REPLAY_SCRIPT*/` are replaced.
const TEMPLATE: &str = include_str!("../../replay/page.html");
/// The bundled page script (page code and three.js).
const SCRIPT: &str = include_str!("../../replay/dist/replay.js");

/// Radius of a planar arm's links as drawn (m).
const PLANAR_LINK_RADIUS_M: f64 = 0.03;

/// The robot a replay draws and where its joint values are in the time series.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Robot {
    /// The Justin-like robot of `fixtures::justin` with its wheels: joint `j` from column
    /// `q.<j>`, the length of leg `i` (from 0) from `leg_length.<i>` (m). `aliases` name a run's
    /// own column for such a name, `(name, column)`; a joint without a column stays at the home
    /// configuration, a leg at its nominal length.
    Justin {
        /// `(name the replay reads, column of the run)` pairs.
        aliases: &'static [(&'static str, &'static str)],
        /// The prefixes of the right and the left TCP's position error columns
        /// (`<prefix>.x, .y, .z`, TCP minus goal; empty: the run has none).
        tcp_errors: [&'static str; 2],
    },
    /// A planar arm of `fixtures::planar` with `links` links of `LINK_LENGTH`, joint `k` (from 1)
    /// from column `q.<k>`. Drawn standing, its base above the floor by its reach: the arm's plane
    /// (x, y) is the world's (x, z), so its gravity (−y) points down.
    PlanarArm {
        /// Number of links (and joints).
        links: usize,
        /// The columns of the TCP's position error in the arm's plane, x and y (TCP minus
        /// goal, m; empty: the run has none).
        tcp_error: [&'static str; 2],
    },
}

impl Robot {
    /// Justin with every joint in its `q.<joint>` column.
    pub const JUSTIN: Self = Self::Justin { aliases: &[], tcp_errors: ["e0", "e1"] };

    /// Justin moving its right hand alone, whose error is the first level's (`e1.*`), with the
    /// run's own columns for `aliases`.
    pub const fn right_hand_at_level_1(aliases: &'static [(&'static str, &'static str)]) -> Self {
        Self::Justin { aliases, tcp_errors: ["e1", ""] }
    }

    /// The values of the column the replay reads for `name` in `rows`, if the run has it.
    fn column_values(self, series: &TimeSeries, rows: &[usize], name: &str) -> Option<Vec<f64>> {
        let column = self.column(series, name)?;
        Some(
            rows.iter()
                .map(|&r| series.rows().get(r).and_then(|v| v.get(column)).copied().unwrap_or(f64::NAN))
                .collect(),
        )
    }

    /// Index of the column the replay reads for `name`, if the run has it.
    fn column(self, series: &TimeSeries, name: &str) -> Option<usize> {
        let aliased = match self {
            Self::Justin { aliases, .. } => aliases.iter().find(|(from, _)| *from == name).map(|(_, to)| *to),
            Self::PlanarArm { .. } => None,
        };
        let name = aliased.unwrap_or(name);
        series.columns().iter().position(|c| c == name)
    }

    /// The world placement of every body in `row` (Justin's bodies, then its wheels; the arm's
    /// links) and the world position of every hand.
    fn pose(self, series: &TimeSeries, row: usize) -> Result<Pose, String> {
        let values = series.rows().get(row).ok_or("row out of range")?;
        let value = |name: &str| self.column(series, name).and_then(|c| values.get(c).copied());
        match self {
            Self::Justin { .. } => justin_pose(&value),
            Self::PlanarArm { links, .. } => Ok(planar_pose(links, &value)),
        }
    }
}

/// Body placements, hand positions and the platform's position at one instant.
struct Pose {
    bodies: Vec<Isometry3<f64>>,
    hands: Vec<Point3<f64>>,
    platform: Option<Point3<f64>>,
}

/// The hands of Justin with the prefix of their force columns (`<prefix>.x, .y, .z`).
const JUSTIN_HANDS: [(&str, &str); 2] = [("right hand", "force.right"), ("left hand", "force.left")];

fn justin_pose(value: &dyn Fn(&str) -> Option<f64>) -> Result<Pose, String> {
    let model = justin::model::<f64>().map_err(|e| format!("model: {e}"))?;
    let mut data = Data::new(&model);
    let home = justin::home_configuration::<f64>();
    let q = SVector::<f64, { justin::N }>::from_iterator(
        justin::JOINT_NAMES.iter().zip(home.iter()).map(|(j, h)| value(&format!("q.{j}")).unwrap_or(*h)),
    );
    forward_kinematics(&model, &mut data, &q, &SVector::zeros()).map_err(|e| format!("kinematics: {e}"))?;
    let mut bodies: Vec<Isometry3<f64>> = data.body_placements.iter().map(isometry).collect();
    let base = data.frame_placements.get(justin::BASE.0).map(isometry).ok_or("no base frame")?;
    for (i, psi) in justin::LEG_DIRECTIONS.iter().enumerate() {
        let length = value(&format!("leg_length.{i}")).unwrap_or(justin::LEG_LENGTH_NOMINAL);
        let yaw = base.rotation * UnitQuaternion::from_euler_angles(0.0, 0.0, *psi);
        let mut wheel = base.translation.vector + yaw * Vector3::new(length, 0.0, 0.0);
        wheel.z = justin::WHEEL_RADIUS;
        bodies.push(Isometry3::from_parts(Translation3::from(wheel), yaw));
    }
    let hands = [justin::RIGHT_TCP, justin::LEFT_TCP]
        .iter()
        .map(|f| data.frame_placements.get(f.0).map(|p| Point3::from(p.translation.vector)).ok_or("no TCP frame"))
        .collect::<Result<_, _>>()?;
    Ok(Pose { bodies, hands, platform: Some(Point3::from(base.translation.vector)) })
}

fn isometry(placement: &kernel::math::Placement<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(placement.translation.vector),
        UnitQuaternion::from_rotation_matrix(&placement.rotation),
    )
}

/// The planar arm's plane (x, y) turned into the world's (x, z), lifted by its reach.
fn planar_view(links: usize) -> Isometry3<f64> {
    #[allow(clippy::cast_precision_loss, reason = "a handful of links")]
    let height = links as f64 * fixtures::planar::LINK_LENGTH + 0.1;
    Isometry3::from_parts(
        Translation3::new(0.0, 0.0, height),
        UnitQuaternion::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
    )
}

fn planar_pose(links: usize, value: &dyn Fn(&str) -> Option<f64>) -> Pose {
    let view = planar_view(links);
    let length = fixtures::planar::LINK_LENGTH;
    let mut bodies = Vec::with_capacity(links);
    let (mut phi, mut joint) = (0.0, Vector3::zeros());
    for k in 1..=links {
        phi += value(&format!("q.{k}")).unwrap_or(f64::NAN);
        let link = Isometry3::from_parts(Translation3::from(joint), UnitQuaternion::from_euler_angles(0.0, 0.0, phi));
        bodies.push(view * link);
        joint += Vector3::new(-length * phi.sin(), length * phi.cos(), 0.0);
    }
    Pose { bodies, hands: vec![view * Point3::from(joint)], platform: None }
}

/// What a scenario tells about its run besides the time series: its one-line description, its
/// phases `(start time, caption)`, the world-fixed environment volumes and, if it chooses, the
/// direction the camera looks from.
#[derive(Clone, Debug, Default)]
pub struct Story<'a> {
    /// One line: what the scenario does.
    pub description: &'a str,
    /// The phases of the run: when each begins (s) and what happens.
    pub phases: Vec<(f64, String)>,
    /// World-fixed volumes (tables, walls).
    pub environment: Vec<SweptSphere<f64>>,
    /// World-fixed objects the hands work on that the simulator models by their contact surfaces
    /// only (the mug), drawn opaque.
    pub objects: Vec<SweptSphere<f64>>,
    /// Where the camera stands: the world vector from the centre of the scene's work to the
    /// camera, m (`None`: far enough to see everything, from the front, on the side of the hand
    /// that travels further).
    pub view: Option<[f64; 3]>,
}

/// Writes `replay.html` of `series` (a run of `robot`) into `dir` with the `story` and the
/// claims of `summary`.
pub fn write(dir: &Path, robot: Robot, series: &TimeSeries, summary: &Summary, story: &Story) -> Result<(), String> {
    let data = replay_data(robot, series, summary, story)?;
    let data = serde_json::to_string(&data).map_err(|e| e.to_string())?;
    // `</` inside a script element would end it early.
    let data = data.replace("</", "<\\/");
    let page = TEMPLATE.replacen("/*REPLAY_DATA*/", &data, 1).replacen("/*REPLAY_SCRIPT*/", SCRIPT, 1);
    let path = dir.join("replay.html");
    fs::write(&path, page).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// The JSON object the page reads (see the module docs).
pub fn replay_data(robot: Robot, series: &TimeSeries, summary: &Summary, story: &Story) -> Result<Value, String> {
    let rows = replay_rows(series)?;
    let poses = rows.iter().map(|&r| robot.pose(series, r)).collect::<Result<Vec<_>, _>>()?;
    let times: Vec<f64> =
        rows.iter().map(|&r| series.rows().get(r).and_then(|v| v.first()).copied().unwrap_or(f64::NAN)).collect();
    let signals = signals(robot, series, &rows);
    let hands = hand_tracks(robot, series, &rows, &poses, &signals);
    let platform: Vec<Point3<f64>> = poses.iter().filter_map(|p| p.platform).collect();
    let platform_moves = platform.iter().any(|p| platform.first().is_some_and(|first| (p - first).norm() > 1e-3));
    Ok(json!({
        "scenario": summary.to_json().get("scenario").cloned().unwrap_or(Value::Null),
        "description": story.description,
        "passed_claims": summary.passed_claims(),
        "failed_claims": summary.failed_claims(),
        "volumes": volumes(robot, story)?,
        "parents": parents(robot)?,
        "t": times.iter().map(|&t| rounded(t)).collect::<Vec<_>>(),
        "bodies": poses.iter().map(|p| p.bodies.iter().flat_map(placement_values).collect()).collect::<Vec<Vec<Value>>>(),
        "hands": hands.iter().map(HandTrack::to_json).collect::<Vec<_>>(),
        "platform": if platform_moves { points_json(&platform) } else { Value::Null },
        "signals": signals
            .iter()
            .map(|(name, values)| (name.clone(), values.iter().map(|&x| rounded(x)).collect()))
            .collect::<serde_json::Map<String, Value>>(),
        "events": story_events(&story.phases, events(&times, &signals, &hands, &platform)),
        "view": story.view,
    }))
}

/// The scenario's `phases` and the `found` events in time order (a phase before an event at the
/// same time): `{ t, text, phase }`.
fn story_events(phases: &[(f64, String)], found: Vec<(f64, String)>) -> Vec<Value> {
    let mut events: Vec<(f64, String, bool)> = phases.iter().map(|(t, text)| (*t, text.clone(), true)).collect();
    events.extend(found.into_iter().map(|(t, text)| (t, text, false)));
    events.sort_by(|a, b| a.0.total_cmp(&b.0));
    events.into_iter().map(|(t, text, phase)| json!({ "t": rounded(t), "text": text, "phase": phase })).collect()
}

/// The indices of the rows kept: the first row, then one per `1 / REPLAY_RATE_HZ` of time.
fn replay_rows(series: &TimeSeries) -> Result<Vec<usize>, String> {
    let mut kept = Vec::new();
    let mut next = f64::NEG_INFINITY;
    for (index, row) in series.rows().iter().enumerate() {
        let t = row.first().copied().ok_or("empty row")?;
        if t >= next - 1e-9 {
            kept.push(index);
            next = t + 1.0 / REPLAY_RATE_HZ;
        }
    }
    Ok(kept)
}

/// `x` rounded to 0.1 mm / 0.1 mrad, `null` if not finite.
fn rounded(x: f64) -> Value {
    serde_json::Number::from_f64((x * 1e4).round() / 1e4).map_or(Value::Null, Value::Number)
}

/// `[x, y, z, qx, qy, qz, qw]` of a placement.
fn placement_values(p: &Isometry3<f64>) -> [Value; 7] {
    let (t, r) = (p.translation.vector, p.rotation);
    [t.x, t.y, t.z, r.i, r.j, r.k, r.w].map(rounded)
}

/// Points as three coordinate arrays `[[x…], [y…], [z…]]`.
fn points_json(points: &[Point3<f64>]) -> Value {
    Value::Array(
        (0..3)
            .map(|a| points.iter().map(|p| rounded(p.coords.get(a).copied().unwrap_or(f64::NAN))).collect())
            .collect(),
    )
}

/// The parent of every body the page draws (−1: world).
fn parents(robot: Robot) -> Result<Vec<i64>, String> {
    Ok(match robot {
        Robot::Justin { .. } => {
            let model = justin::model::<f64>().map_err(|e| format!("model: {e}"))?;
            let base =
                model.frame(justin::BASE).and_then(|f| f.parent).map_or(-1, |b| i64::try_from(b.0).unwrap_or(-1));
            let mut parents: Vec<i64> =
                model.bodies().iter().map(|b| b.parent.map_or(-1, |p| i64::try_from(p.0).unwrap_or(-1))).collect();
            parents.extend([base; justin::LEG_DIRECTIONS.len()]);
            parents
        }
        Robot::PlanarArm { links, .. } => (0..links).map(|k| i64::try_from(k).unwrap_or(0) - 1).collect(),
    })
}

/// The robot's volumes in their body frames, the environment's and the story's objects in the
/// world frame: `{ body (−1: world), part, radius, points }`.
fn volumes(robot: Robot, story: &Story) -> Result<Vec<Value>, String> {
    let mut volumes = robot_volumes(robot, &story.environment)?;
    volumes.extend(story.objects.iter().map(|o| volume(-1, "object", o.radius, o.core.points())));
    Ok(volumes)
}

/// One volume of [`volumes`].
fn volume(body: i64, part: &str, radius: f64, points: &[Vector3<f64>]) -> Value {
    let points: Vec<Vec<Value>> = points.iter().map(|p| p.iter().map(|x| rounded(*x)).collect()).collect();
    json!({ "body": body, "part": part, "radius": rounded(radius), "points": points })
}

/// The robot's volumes and the world-fixed `environment` (see [`volumes`]).
fn robot_volumes(robot: Robot, environment: &[SweptSphere<f64>]) -> Result<Vec<Value>, String> {
    match robot {
        Robot::Justin { .. } => {
            let model = justin::model::<f64>().map_err(|e| format!("model: {e}"))?;
            let collision = collision::collision_model_with_environment::<f64, VOLUMES, PAIRS>(&model, environment)
                .map_err(|e| format!("collision model: {e}"))?;
            let mut volumes: Vec<Value> = collision
                .volumes()
                .iter()
                .enumerate()
                .map(|(index, v)| {
                    let part = collision::VOLUME_SPECS.get(index).map_or("environment", |s| s.group.name());
                    let body = v.body.map_or(-1, |b| i64::try_from(b.0).unwrap_or(-1));
                    volume(body, part, v.shape.radius, v.shape.core.points())
                })
                .collect();
            let first_wheel = i64::try_from(justin::BODIES).unwrap_or(0);
            volumes.extend((0..justin::LEG_DIRECTIONS.len()).map(|i| {
                volume(first_wheel + i64::try_from(i).unwrap_or(0), "wheel", justin::WHEEL_RADIUS, &[Vector3::zeros()])
            }));
            Ok(volumes)
        }
        Robot::PlanarArm { links, .. } => {
            let tip = Vector3::new(0.0, fixtures::planar::LINK_LENGTH, 0.0);
            let mut volumes: Vec<Value> = (0..links)
                .map(|k| volume(i64::try_from(k).unwrap_or(0), "link", PLANAR_LINK_RADIUS_M, &[Vector3::zeros(), tip]))
                .collect();
            let base = planar_view(links).translation.vector;
            volumes.push(volume(
                -1,
                "pedestal",
                2.0 * PLANAR_LINK_RADIUS_M,
                &[base, Vector3::new(base.x, base.y, 0.0)],
            ));
            Ok(volumes)
        }
    }
}

/// The kept rows of every column the replay reads whose name starts with one of
/// [`SIGNAL_PREFIXES`], under the name the replay reads (see [`Robot::Justin`]'s aliases).
fn signals(robot: Robot, series: &TimeSeries, rows: &[usize]) -> Vec<(String, Vec<f64>)> {
    let aliases: &[(&str, &str)] = match robot {
        Robot::Justin { aliases, .. } => aliases,
        Robot::PlanarArm { .. } => &[],
    };
    let names = series.columns().iter().map(String::as_str).filter(|c| !aliases.iter().any(|(from, _)| from == c));
    let names: Vec<&str> = names.chain(aliases.iter().map(|(from, _)| *from)).collect();
    names
        .into_iter()
        .filter(|name| SIGNAL_PREFIXES.iter().any(|p| name.starts_with(p)))
        .filter_map(|name| Some((name.to_owned(), robot.column_values(series, rows, name)?)))
        .collect()
}

/// A hand's path, goal path and external force over the kept rows.
struct HandTrack {
    label: &'static str,
    path: Vec<Point3<f64>>,
    goal: Option<Vec<Point3<f64>>>,
    force: Option<Vec<Vector3<f64>>>,
}

impl HandTrack {
    fn to_json(&self) -> Value {
        json!({
            "label": self.label,
            "path": points_json(&self.path),
            "goal": self.goal.as_deref().map_or(Value::Null, points_json),
            "force": self.force.as_ref().map_or(Value::Null, |f| {
                points_json(&f.iter().map(|v| Point3::from(*v)).collect::<Vec<_>>())
            }),
        })
    }
}

/// The signal vector `<prefix>.x, .y, .z` over the kept rows, if the replay has it.
fn vector_signal(signals: &[(String, Vec<f64>)], prefix: &str) -> Option<Vec<Vector3<f64>>> {
    let axis = |a: &str| signals.iter().find(|(n, _)| *n == format!("{prefix}.{a}")).map(|(_, v)| v);
    let (x, y, z) = (axis("x")?, axis("y")?, axis("z")?);
    Some(x.iter().zip(y).zip(z).map(|((x, y), z)| Vector3::new(*x, *y, *z)).collect())
}

/// The hands the page draws: the planar arm's TCP; a Justin hand with a goal error or a force.
fn hand_tracks(
    robot: Robot,
    series: &TimeSeries,
    rows: &[usize],
    poses: &[Pose],
    signals: &[(String, Vec<f64>)],
) -> Vec<HandTrack> {
    let path = |k: usize| poses.iter().map(|p| p.hands.get(k).copied().unwrap_or(Point3::origin())).collect();
    match robot {
        Robot::Justin { tcp_errors, .. } => JUSTIN_HANDS
            .iter()
            .zip(tcp_errors)
            .enumerate()
            .filter_map(|(k, ((label, force), error))| {
                let path: Vec<Point3<f64>> = path(k);
                let goal = vector_signal(signals, error).map(|e| path.iter().zip(e).map(|(p, e)| p - e).collect());
                let force = vector_signal(signals, force);
                (goal.is_some() || force.is_some()).then_some(HandTrack { label, path, goal, force })
            })
            .collect(),
        Robot::PlanarArm { links, tcp_error: [x, y] } => {
            let path: Vec<Point3<f64>> = path(0);
            let view = planar_view(links);
            let error = robot.column_values(series, rows, x).zip(robot.column_values(series, rows, y));
            let goal = error.map(|(ex, ey)| {
                let plane = path.iter().map(|p| view.inverse_transform_point(p));
                plane.zip(ex.iter().zip(&ey)).map(|(p, (ex, ey))| view * (p - Vector3::new(*ex, *ey, 0.0))).collect()
            });
            vec![HandTrack { label: "TCP", path, goal, force: None }]
        }
    }
}

/// A state change counts as an event once the new state lasts this long (s).
const EVENT_HOLD_S: f64 = 0.25;
/// A hand's force counts as a push or contact above this magnitude (N).
const FORCE_EVENT_N: f64 = 5.0;
/// The platform counts as moving above this speed (m/s).
const MOTION_EVENT_M_S: f64 = 0.01;
/// A goal that moves this far between two frames steps (m).
const GOAL_STEP_M: f64 = 0.02;

/// The rows at which `state` (false before the first row) changes and then keeps its new value
/// for [`EVENT_HOLD_S`], with the new value.
fn transitions(times: &[f64], state: &[bool]) -> Vec<(usize, bool)> {
    let mut current = false;
    let mut changes = Vec::new();
    for (i, (&t, &s)) in times.iter().zip(state).enumerate() {
        let lasts = times.iter().zip(state).skip(i).take_while(|(&u, _)| u < t + EVENT_HOLD_S).all(|(_, &v)| v == s);
        if s != current && lasts {
            changes.push((i, s));
            current = s;
        }
    }
    changes
}

/// Speeds (per second) of a sampled path; the first is 0.
fn speeds(times: &[f64], points: &[Point3<f64>]) -> Vec<f64> {
    let mut speeds = vec![0.0];
    speeds.extend(points.windows(2).zip(times.windows(2)).map(|(p, t)| match (p, t) {
        ([a, b], [s, u]) if u > s => (b - a).norm() / (u - s),
        _ => 0.0,
    }));
    speeds
}

/// The events of the run found in its signals, `(time, caption)` in time order: forces on the
/// hands begin and end (with their peak), the controller detects contact, a hand's goal steps,
/// the platform starts or stops moving.
fn events(
    times: &[f64],
    signals: &[(String, Vec<f64>)],
    hands: &[HandTrack],
    platform: &[Point3<f64>],
) -> Vec<(f64, String)> {
    let at = |i: usize| times.get(i).copied().unwrap_or(f64::NAN);
    let mut events = Vec::new();
    for hand in hands {
        if let Some(force) = &hand.force {
            let norms: Vec<f64> = force.iter().map(|f| if f.norm().is_finite() { f.norm() } else { 0.0 }).collect();
            let on: Vec<bool> = norms.iter().map(|&f| f > FORCE_EVENT_N).collect();
            for (i, rises) in transitions(times, &on) {
                let text = if rises {
                    let peak = norms
                        .iter()
                        .skip(i)
                        .zip(on.iter().skip(i))
                        .take_while(|(_, &o)| o)
                        .fold(0.0, |m, (f, _)| f.max(m));
                    format!("a force acts on the {} (peak {peak:.0} N)", hand.label)
                } else {
                    format!("the force on the {} ends", hand.label)
                };
                events.push((at(i), text));
            }
        }
        if let Some(goal) = &hand.goal {
            let step = |i: usize| {
                goal.get(i).zip(i.checked_sub(1).and_then(|j| goal.get(j))).map_or(0.0, |(b, a)| (b - a).norm())
            };
            for i in (1..goal.len()).filter(|&i| step(i) > GOAL_STEP_M) {
                events.push((at(i), format!("the {} goal steps by {:.2} m", hand.label, step(i))));
            }
        }
    }
    if let Some((_, contact)) = signals.iter().find(|(n, _)| n == "contact") {
        let on: Vec<bool> = contact.iter().map(|&c| c > 0.5).collect();
        for (i, detected) in transitions(times, &on) {
            let text = if detected { "the controller detects a contact" } else { "the contact is over" };
            events.push((at(i), text.to_owned()));
        }
    }
    let moving: Vec<bool> = speeds(times, platform).iter().map(|&v| v > MOTION_EVENT_M_S).collect();
    for (i, starts) in transitions(times, &moving) {
        events.push((at(i), if starts { "the platform starts moving" } else { "the platform stops" }.to_owned()));
    }
    events.sort_by(|a, b| a.0.total_cmp(&b.0));
    events
}

#[cfg(test)]
mod tests {
    #![allow(
        clippy::unwrap_used,
        clippy::indexing_slicing,
        clippy::cast_precision_loss,
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "tests"
    )]
    use super::*;

    /// `seconds` of a run at 1 kHz with the columns `names` and the row `row(t)`.
    fn run(seconds: f64, names: Vec<String>, row: impl Fn(f64) -> Vec<f64>) -> TimeSeries {
        let mut columns = vec!["t".to_string()];
        columns.extend(names);
        let mut series = TimeSeries::new(columns);
        for k in 0..=(seconds * 1000.0).round() as usize {
            let t = k as f64 * 1e-3;
            let mut values = vec![t];
            values.extend(row(t));
            series.push(values).unwrap();
        }
        series
    }

    fn still_justin(seconds: f64) -> TimeSeries {
        let mut names: Vec<String> = justin::JOINT_NAMES.iter().map(|j| format!("q.{j}")).collect();
        names.push("min_distance".into());
        let q = justin::home_configuration::<f64>();
        run(seconds, names, |t| q.iter().copied().chain([if t == 0.0 { f64::NAN } else { 0.1 }]).collect())
    }

    fn data(robot: Robot, series: &TimeSeries) -> Value {
        let phases = vec![(1.0, "a push".into()), (0.5, "a phase".into())];
        let story = Story { description: "a test run", phases, ..Story::default() };
        replay_data(robot, series, &Summary::new("test"), &story).unwrap()
    }

    #[test]
    fn the_replay_keeps_fifty_frames_per_second_and_every_body() {
        let data = data(Robot::JUSTIN, &still_justin(2.0));
        let t = data["t"].as_array().unwrap();
        assert_eq!(t.len(), 101);
        assert_eq!(t[1].as_f64().unwrap(), 0.02);
        let wheels = justin::LEG_DIRECTIONS.len();
        assert_eq!(data["bodies"][0].as_array().unwrap().len(), 7 * (justin::BODIES + wheels));
        assert_eq!(data["volumes"].as_array().unwrap().len(), collision::VOLUMES + wheels);
        assert_eq!(data["parents"].as_array().unwrap().len(), justin::BODIES + wheels);
        assert_eq!(data["description"], "a test run");
    }

    #[test]
    fn a_non_finite_signal_is_null_in_the_replay() {
        let data = data(Robot::JUSTIN, &still_justin(0.1));
        assert!(data["signals"]["min_distance"][0].is_null());
        assert_eq!(data["signals"]["min_distance"][1].as_f64().unwrap(), 0.1);
    }

    #[test]
    fn a_planar_arm_stands_in_the_x_z_plane_and_its_tcp_is_the_tip() {
        // q = (π/2, 0, 0, 0): the arm lies along −x of its plane, 2 m long; its goal 0.1 m further.
        let mut names: Vec<String> = (1..=4).map(|k| format!("q.{k}")).collect();
        names.extend(["ex".into(), "ey".into()]);
        let series = run(0.1, names, |_| vec![std::f64::consts::FRAC_PI_2, 0.0, 0.0, 0.0, 0.1, 0.0]);
        let data = data(Robot::PlanarArm { links: 4, tcp_error: ["ex", "ey"] }, &series);
        let base_height = 4.0 * fixtures::planar::LINK_LENGTH + 0.1;
        let at = |path: &Value| [0, 1, 2].map(|a| path[a][0].as_f64().unwrap());
        assert_eq!(at(&data["hands"][0]["path"]), [-2.0, 0.0, base_height]);
        assert_eq!(at(&data["hands"][0]["goal"]), [-2.1, 0.0, base_height]);
        // Link 3 starts 1 m from the base.
        let link3 = &data["bodies"][0].as_array().unwrap()[14..17];
        assert_eq!(link3.iter().map(|v| v.as_f64().unwrap()).collect::<Vec<_>>(), [-1.0, 0.0, base_height]);
        assert_eq!(data["parents"], json!([-1, 0, 1, 2]));
    }

    #[test]
    fn aliases_move_the_platform_and_a_leg_and_level_1_is_the_right_hand() {
        const ROBOT: Robot = Robot::right_hand_at_level_1(&[("q.base_x", "x"), ("leg_length.0", "leg")]);
        let names = ["x", "leg", "e1.x", "e1.y", "e1.z"].map(String::from).to_vec();
        let series = run(1.0, names, |t| vec![t, 0.6, 0.1, 0.0, 0.0]);
        let data = data(ROBOT, &series);
        assert_eq!(data["platform"][0][50].as_f64().unwrap(), 1.0);
        assert_eq!(data["signals"]["q.base_x"][25].as_f64().unwrap(), 0.5);
        // One hand, the right, its goal 0.1 m behind it in x.
        let hands = data["hands"].as_array().unwrap();
        assert_eq!(hands.len(), 1);
        assert_eq!(hands[0]["label"], "right hand");
        let (x, goal_x) = (hands[0]["path"][0][0].as_f64().unwrap(), hands[0]["goal"][0][0].as_f64().unwrap());
        assert!((x - goal_x - 0.1).abs() < 1e-3, "{x} {goal_x}");
        // Wheel 0 (the first body after Justin's) at 0.6 m from the platform's centre.
        let wheel = &data["bodies"][50].as_array().unwrap()[7 * justin::BODIES..7 * justin::BODIES + 2];
        let offset = (wheel[0].as_f64().unwrap() - 1.0).hypot(wheel[1].as_f64().unwrap());
        assert!((offset - 0.6).abs() < 1e-3, "{offset}");
    }

    #[test]
    fn a_push_and_a_goal_step_are_events_with_their_times_and_peak() {
        let mut names: Vec<String> = justin::JOINT_NAMES.iter().map(|j| format!("q.{j}")).collect();
        names.extend(["force.right.x", "force.right.y", "force.right.z", "e0.x", "e0.y", "e0.z"].map(String::from));
        let q = justin::home_configuration::<f64>();
        let series = run(3.0, names, |t| {
            let push = if (1.0..1.5).contains(&t) { 40.0 } else { 0.0 };
            let step = if t >= 2.0 { -0.2 } else { 0.0 };
            q.iter().copied().chain([push, 0.0, 0.0, step, 0.0, 0.0]).collect()
        });
        let events = data(Robot::JUSTIN, &series)["events"].clone();
        assert_eq!(
            events,
            json!([
                { "t": 0.5, "text": "a phase", "phase": true },
                { "t": 1.0, "text": "a push", "phase": true },
                { "t": 1.0, "text": "a force acts on the right hand (peak 40 N)", "phase": false },
                { "t": 1.5, "text": "the force on the right hand ends", "phase": false },
                { "t": 2.0, "text": "the right hand goal steps by 0.20 m", "phase": false },
            ])
        );
    }
}
