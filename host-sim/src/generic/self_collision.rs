//! `self_collision` on a robot of the generic rig (`--robot panda|tiago_dual|justin`): TCP goals
//! that drive two links into each other, and the self-collision avoidance that keeps every pair
//! apart.
//!
//! Setup: the rig of [`super::GenericRig`] (the robot's `config.toml` and its Fig. 6.3 hierarchy
//! with both collision fields) at the robot's home posture. From [`GOAL_AT_S`] the goals move
//! along the kernel's cubic of [`GOAL_S`]: with one arm, its TCP onto the origin of its first
//! body (the Panda: the hand into its shoulder, links 1 to 3); with two or more arms, arms 0 and 1
//! each to the position nearest to their meeting point that it reaches in its home orientation.
//! The meeting point is the TCPs' midpoint moved forward (world `+x`) until it lies
//! [`MEETING_CLEARANCE_M`] outside every volume at home, ahead of the chest and the head; each
//! hand's goal is the TCP position of the posture found by damped least squares on the hand's pose
//! error over its arm's coordinates alone, within the joint ranges narrowed by the end stops'
//! margin ([`NearestPosture`]), so the goal is reachable by construction, without an end stop acting
//! (hand into hand; TIAGo++: meeting point 0.35 m ahead of the midpoint, at (0.43, 0, 1.20) m,
//! outside what the arms reach in the home orientation, goals at (0.375, ±0.13, 1.198) m, 0.14 m
//! from it, close enough for the hand boxes to collide; Justin: 0.12 m ahead, at
//! (0.58, 0, 0.96) m, reached). So that both hands follow their goals, the run's hierarchy is
//! the file's Fig. 6.3 with arm 1's joint impedance replaced by its Cartesian impedance on arm 0's
//! level (`SetHierarchy` before the first cycle). The rest is the hold.
//!
//! The pair distances are measured on [`super::RigParts::plant_collision`], the controller's
//! collision model in `f64` on the simulated robot (an imported robot's generated table,
//! Justin's `fixtures::justin::collision` with the floor).
//!
//! The same goals run a second time with the two collision tasks taken out of the hierarchy
//! (the reference): there the closest pair's volumes interpenetrate, which shows that the goals
//! would collide.
//!
//! Claims:
//! - **every pair apart**: the smallest distance of every enabled pair of the robot's collision
//!   model, measured on the simulated robot's geometry every control cycle, stays above
//!   [`MARGIN_M`]; the reference's goes below zero.
//! - **the TCP stops short of the goal by what the repulsion needs**: the reference reaches its
//!   goals (shortfall: Panda 16.8 mm, TIAGo++ 6.8 mm, Justin 0.0 mm) with the closest pair
//!   interpenetrating by `−d_ref`; with the avoidance the pairs end at `d_end > 0`. The TCPs give
//!   up the distance the pairs gain, shared by the driven arms: the mean shortfall is
//!   `(d_end − d_ref) / arms` within a factor [`SHORTFALL_FACTOR`] (the closest points lie between
//!   the shoulder and the hand, and an interpenetration is not a TCP distance: measured 1.43 on
//!   the Panda, 0.88 on TIAGo++, 1.07 on Justin).
//! - **torques within limits**: every applied joint torque within its effort limit.
//! - **no fault, no NaN**.
//!
//! Measured (f64 and f32 alike): the Panda 29.8 mm apart (link 2 – link 5; reference −59.0 mm),
//! stopping 136.8 mm short for 95.5 mm (× 1.43), largest |τ|/τ_max 0.39; TIAGo++ 21.7 mm
//! (`arm_left_4_link` – the left hand's box; reference −73.9 mm, the hand boxes), each hand
//! 49.0 mm short for 55.5 mm (× 0.88), largest |τ|/τ_max 1.00; Justin 30.4 mm (the fingers;
//! reference −100.0 mm), 70.0 mm short for 65.5 mm (× 1.07), largest |τ|/τ_max 0.22. On
//! TIAGo++ the torque *rate* binds (`arm_right_5_joint`: 3 Nm, 300 Nm/s, 0.3 Nm per cycle):
//! the guard (`kernel::controller::guard`) takes the effort box first, preserving the priorities,
//! and then meets the rate by slowing the whole change, `τ = τ_prev + α (τ_e − τ_prev)`, so the
//! collision rows keep their share of every cycle's torque.
//! The import's torque-rate rule (100 τ_max/s) is kept: libfranka's `kMaxTorqueRate` is
//! 1000 Nm/s on every Panda joint, 83 τ_max/s on its 12 Nm wrists and 11.5 τ_max/s on its 87 Nm
//! joints, so the rule is not conservative for a small wrist.

use kernel::controller::config::{ArmId, JointGroup, TaskKind, TaskSpec};
use kernel::controller::messages::Command;
use kernel::dynamics::forward_kinematics;
use kernel::model::{Data, FrameId, Model};
use kernel::tasks::collision::{CollisionData, CollisionModel};
use nalgebra::{RealField, SVector, Vector3};

use super::nearest_posture::NearestPosture;
use super::{record, GenericRig, RigParts, RobotSpec, Scenario};
use crate::output::{Figure, Line, Panel, Span, Summary, TimeSeries};
use crate::scenarios::{Outcome, RunOptions};
use crate::sim::{run_loop, CONTROL_PERIOD_S};

/// Registry name.
pub const NAME: &str = "self_collision";
/// One-line description.
pub const DESCRIPTION: &str = "generic robot (--robot): TCP goals that drive the hand into the shoulder (one arm) or \
     the hands into each other ahead of the chest (two arms); the collision avoidance keeps every pair apart";
/// Start of the goal motion (s).
pub const GOAL_AT_S: f64 = 0.5;
/// Duration of the goal motion (s).
pub const GOAL_S: f64 = 1.5;
/// Simulated time (s): the motion and 2 s to come to rest.
pub const DURATION_S: f64 = GOAL_AT_S + GOAL_S + 2.0;
/// The smallest pair distance the avoidance keeps (m).
pub const MARGIN_M: f64 = 0.005;
/// Allowed factor between the shortfall and the distance the pairs gain per driven arm.
pub const SHORTFALL_FACTOR: f64 = 2.5;
/// How far the hands' meeting point keeps from every volume at home (m): the weak field's
/// influence distance `d₀` (Table 3.1), so that the goal itself lies outside every field.
pub const MEETING_CLEARANCE_M: f64 = 0.15;
/// The step (m) and the farthest distance (m) of the search for the meeting point.
const MEETING_STEP_M: f64 = 0.01;
const MEETING_SEARCH_M: f64 = 1.0;
/// Weight (m/rad) of the orientation error in [`NearestPosture`]: a rad counts as 10 m, so the
/// hand keeps its orientation and gives up position where it cannot have both.
const ORIENTATION_WEIGHT_M: f64 = 10.0;
/// The scenario.
pub struct SelfCollision;

/// The distances of every enabled pair on the simulated robot's geometry.
struct PairDistances<const N: usize, const B: usize, const F: usize, const V: usize, const P: usize> {
    model: CollisionModel<f64, V, P>,
    collision: CollisionData<f64, V, P>,
    data: Data<f64, N, B, F>,
}

impl<const N: usize, const B: usize, const F: usize, const V: usize, const P: usize> PairDistances<N, B, F, V, P> {
    fn new(model: CollisionModel<f64, V, P>, plant: &Model<f64, N, B, F>) -> Self {
        let collision = CollisionData::new(&model);
        Self { model, collision, data: Data::new(plant) }
    }

    /// The meeting point of two hands at `q`: `middle` (m, world) moved forward (world `+x`) in
    /// [`MEETING_STEP_M`] steps until its smallest signed distance to every volume at `q` is
    /// [`MEETING_CLEARANCE_M`].
    fn meeting_point(
        &mut self,
        plant: &Model<f64, N, B, F>,
        q: &SVector<f64, N>,
        middle: Vector3<f64>,
    ) -> Result<Vector3<f64>, String> {
        forward_kinematics(plant, &mut self.data, q, &SVector::zeros()).map_err(|e| e.to_string())?;
        self.model.update_world(&self.data, &mut self.collision);
        let volumes = &self.collision.world_volumes;
        let clearance =
            |point: &Vector3<f64>| volumes.iter().map(|v| v.signed_distance_to(point)).fold(f64::INFINITY, f64::min);
        (0..=(MEETING_SEARCH_M / MEETING_STEP_M).round() as usize)
            .map(|step| middle + Vector3::x() * (step as f64 * MEETING_STEP_M))
            .find(|point| clearance(point) >= MEETING_CLEARANCE_M)
            .ok_or_else(|| {
                format!("no point within {MEETING_SEARCH_M} m ahead of the hands' midpoint is {MEETING_CLEARANCE_M} m clear")
            })
    }

    /// The world origin (m) at `q` of the body of the first coordinate of `arm` (a coordinate
    /// mask; a body per coordinate, in coordinate order, as the import builds it).
    fn shoulder(
        &mut self,
        arm: &[bool; N],
        plant: &Model<f64, N, B, F>,
        q: &SVector<f64, N>,
    ) -> Result<Vector3<f64>, String> {
        let first = arm.iter().position(|c| *c).ok_or("arm 0 has no coordinate")?;
        forward_kinematics(plant, &mut self.data, q, &SVector::zeros()).map_err(|e| e.to_string())?;
        Ok(self.data.body_placements.get(first).ok_or("no such body")?.translation.vector)
    }

    /// The smallest distance (m) and its pair's volume indices at `q`.
    fn smallest(&mut self, plant: &Model<f64, N, B, F>, q: &SVector<f64, N>) -> Result<(f64, (usize, usize)), String> {
        forward_kinematics(plant, &mut self.data, q, &SVector::zeros()).map_err(|e| e.to_string())?;
        self.model.update(&self.data, &mut self.collision);
        let distances = self.collision.proximities.iter().map(|p| p.distance);
        Ok(self
            .model
            .pairs()
            .iter()
            .zip(distances)
            .map(|(pair, d)| (d, (pair.first.0, pair.second.0)))
            .fold((f64::INFINITY, (0, 0)), |best, next| if next.0 < best.0 { next } else { best }))
    }
}

/// What one run measured.
struct Run {
    series: TimeSeries,
    /// `(t, smallest pair distance)` per control cycle (m).
    distances: Vec<(f64, f64)>,
    /// Smallest distance from the start of the goal motion on (m).
    smallest: f64,
    closest: (usize, usize),
    /// Smallest distance at home (m).
    home_distance: f64,
    final_distance: f64,
    /// Mean distance of the driven TCPs from their goals at the end (m).
    shortfall: f64,
    /// Number of arms with a goal.
    driven: usize,
    /// Largest `|τ_i| / τ_max,i`.
    torque_ratio: f64,
    faulty_cycles: u64,
    non_finite_cycles: u64,
}

/// The goal offsets (m, world) of each arm from its TCP position at home `tcps` (module docs):
/// one arm (`arms[0]`, a coordinate mask) to the origin of its first body, two arms to the TCP
/// positions nearest to their meeting point that each reaches in its home orientation
/// ([`NearestPosture`] with the end stops' `margin`; `frames`: the TCP frames).
#[allow(clippy::too_many_arguments, reason = "one plant, its hands and the end stops' margin")]
fn goal_offsets<const N: usize, const B: usize, const F: usize, const V: usize, const P: usize>(
    pairs: &mut PairDistances<N, B, F, V, P>,
    plant: &Model<f64, N, B, F>,
    q: &SVector<f64, N>,
    frames: &[FrameId],
    arms: &[[bool; N]],
    margin: f64,
    tcps: &[Vector3<f64>],
) -> Result<Vec<Vector3<f64>>, String> {
    Ok(match (tcps, arms) {
        ([only], [arm, ..]) => vec![pairs.shoulder(arm, plant, q)? - only],
        ([first, second, rest @ ..], [_, _, ..]) => {
            let meeting = pairs.meeting_point(plant, q, (first + second) / 2.0)?;
            let mut data = Data::new(plant);
            forward_kinematics(plant, &mut data, q, &SVector::zeros()).map_err(|e| e.to_string())?;
            let goal = |arm: usize| -> Result<Vector3<f64>, String> {
                let (tcp, moves) = frames.get(arm).zip(arms.get(arm)).ok_or("no such arm")?;
                let home = data.frame_placements.get(tcp.0).ok_or("no TCP frame")?.rotation;
                let search = NearestPosture {
                    model: plant,
                    tcp: *tcp,
                    moves: *moves,
                    margin,
                    orientation: Some((home, ORIENTATION_WEIGHT_M)),
                    manipulability: None,
                };
                let (_, reached) = search.search(q, &meeting)?.ok_or("no manipulability bound")?;
                Ok(reached.translation.vector)
            };
            [goal(0)? - first, goal(1)? - second].into_iter().chain(rest.iter().map(|_| Vector3::zeros())).collect()
        }
        ([], _) => Vec::new(),
        _ => return Err("a TCP without its arm's coordinates".into()),
    })
}

/// The run's hierarchy from the file's Fig. 6.3 (`file`): the joint impedance of arm 1 replaced
/// by its Cartesian impedance on the level of arm 0's (both hands driven to their goals), and
/// without the two collision tasks unless `collision_tasks`.
fn run_hierarchy(
    file: &[TaskSpec],
    collision_tasks: bool,
) -> heapless::Vec<TaskSpec, { kernel::controller::capacity::MAX_TASKS }> {
    let cartesian = |arm| TaskKind::CartesianImpedance(arm);
    let level = file.iter().find(|t| t.kind == cartesian(ArmId(0))).map_or(0, |t| t.level);
    file.iter()
        .copied()
        .filter(|t| collision_tasks || !matches!(t.kind, TaskKind::CollisionAvoidance(_)))
        .map(|t| match t.kind {
            TaskKind::JointImpedance(JointGroup::Arm(arm)) if arm == ArmId(1) => {
                TaskSpec { kind: cartesian(arm), level }
            }
            _ => t,
        })
        .collect()
}

/// Runs the goals on the controller of `parts`, with its collision tasks or without them.
fn run<
    T,
    const N: usize,
    const B: usize,
    const F: usize,
    const U: usize,
    const V: usize,
    const P: usize,
    const A: usize,
>(
    spec: &RobotSpec<N, A>,
    parts: RigParts<T, N, B, F, U, V, P, A>,
    options: &RunOptions,
    collision_tasks: bool,
) -> Result<Run, String>
where
    T: RealField + Copy + Into<f64>,
{
    let mut pairs = PairDistances::new(parts.plant_collision.clone(), &parts.plant);
    let mut rig = GenericRig::new(spec, parts, options)?;
    let file: Vec<TaskSpec> = rig.controller.hierarchy().collect();
    let hierarchy = run_hierarchy(&file, collision_tasks);
    rig.controller.apply(&Command::SetHierarchy(hierarchy)).map_err(|e| format!("SetHierarchy: {e}"))?;
    let home: Vec<Vector3<f64>> = (0..A).map(|arm| rig.tcp_position(spec, arm)).collect::<Result<_, _>>()?;
    let config = rig.controller.config();
    let (arms, margin) = (config.layout.arms, config.end_stops.margin.into());
    let offsets = goal_offsets(&mut pairs, rig.sim.model(), rig.sim.q(), &spec.tcps, &arms, margin, &home)?;
    let goals: Vec<Vector3<f64>> = home.iter().zip(&offsets).map(|(p, o)| p + o).collect();
    let effort = rig.sim.model().limits.effort.fixed_rows::<U>(N - U).into_owned();
    let mut series = TimeSeries::new(super::columns::<N, U, A>(spec));
    let mut distances = Vec::new();
    let (mut smallest, mut closest, mut torque_ratio, mut home_distance) = (f64::INFINITY, (0, 0), 0.0_f64, f64::NAN);
    run_loop(&mut rig, DURATION_S, CONTROL_PERIOD_S, |rig, info| {
        options.progress.report(NAME, info.time_s, DURATION_S);
        if info.cycle == (GOAL_AT_S / CONTROL_PERIOD_S).round() as u64 {
            for (arm, offset) in offsets.iter().enumerate() {
                rig.move_goal(arm, *offset, GOAL_S)?;
            }
        }
        rig.cycle(info)?;
        let (distance, pair) = pairs.smallest(rig.sim.model(), rig.sim.q())?;
        if info.cycle == 0 {
            home_distance = distance;
        }
        if info.time_s >= GOAL_AT_S && distance < smallest {
            (smallest, closest) = (distance, pair);
        }
        distances.push((info.time_s, distance));
        let ratio = rig.sim.applied_torque().zip_map(&effort, |tau, limit| tau.abs() / limit).max();
        torque_ratio = torque_ratio.max(ratio);
        record(rig, spec, info.time_s, &mut series)
    })?;
    options.progress.finish();
    let driven: Vec<f64> = goals
        .iter()
        .zip(&offsets)
        .enumerate()
        .filter(|(_, (_, offset))| offset.norm() > 0.0)
        .map(|(arm, (goal, _))| rig.tcp_position(spec, arm).map(|p| (goal - p).norm()))
        .collect::<Result<_, _>>()?;
    Ok(Run {
        series,
        final_distance: distances.last().map_or(f64::NAN, |(_, d)| *d),
        distances,
        smallest,
        closest,
        home_distance,
        shortfall: driven.iter().sum::<f64>() / driven.len().max(1) as f64,
        driven: driven.len(),
        torque_ratio,
        faulty_cycles: rig.faulty_cycles,
        non_finite_cycles: rig.non_finite_cycles,
    })
}

impl Scenario for SelfCollision {
    fn simulate<
        T,
        const N: usize,
        const B: usize,
        const F: usize,
        const U: usize,
        const V: usize,
        const P: usize,
        const A: usize,
    >(
        spec: &RobotSpec<N, A>,
        parts: &dyn Fn() -> Result<RigParts<T, N, B, F, U, V, P, A>, String>,
        options: &RunOptions,
    ) -> Result<Outcome, String>
    where
        T: RealField + Copy + Into<f64>,
    {
        let reference = run(spec, parts()?, options, false)?;
        let avoided = run(spec, parts()?, options, true)?;
        let predicted = (avoided.final_distance - reference.smallest) / avoided.driven.max(1) as f64;
        let name = |i: usize| (spec.volume_name)(i).unwrap_or("?");
        let (a, b) = avoided.closest;

        let mut summary = Summary::new(NAME);
        summary.value("robot", spec.name).value("controller", format!("host {}", options.scalar.name()));
        summary.value("closest_pair", format!("{} – {}", name(a), name(b)));
        summary
            .metric("smallest_distance_m", avoided.smallest)
            .metric("final_distance_m", avoided.final_distance)
            .metric("reference_smallest_distance_m", reference.smallest)
            .metric("home_distance_m", avoided.home_distance)
            .metric("shortfall_m", avoided.shortfall)
            .metric("predicted_shortfall_m", predicted)
            .metric("reference_shortfall_m", reference.shortfall)
            .metric("largest_torque_ratio", avoided.torque_ratio)
            .metric("faulty_cycles", avoided.faulty_cycles as f64)
            .metric("non_finite_cycles", avoided.non_finite_cycles as f64);
        summary.claim(
            &format!(
                "every pair apart: smallest distance {:.1} mm > {:.1} mm ({} – {}); without avoidance {:.1} mm",
                avoided.smallest * 1e3,
                MARGIN_M * 1e3,
                name(a),
                name(b),
                reference.smallest * 1e3
            ),
            avoided.smallest > MARGIN_M && reference.smallest < 0.0,
        );
        summary.claim(
            &format!(
                "TCP stops short by {:.1} mm ≈ (d_end {:.1} mm − d_ref {:.1} mm) / {} arm(s) = {:.1} mm (× {:.2}, \
                 within × {SHORTFALL_FACTOR}); reference {:.1} mm",
                avoided.shortfall * 1e3,
                avoided.final_distance * 1e3,
                reference.smallest * 1e3,
                avoided.driven,
                predicted * 1e3,
                avoided.shortfall / predicted,
                reference.shortfall * 1e3
            ),
            avoided.shortfall <= SHORTFALL_FACTOR * predicted && avoided.shortfall * SHORTFALL_FACTOR >= predicted,
        );
        summary.claim(
            &format!("torques within limits: largest |τ|/τ_max = {:.2}", avoided.torque_ratio),
            avoided.torque_ratio <= 1.0,
        );
        summary.claim(
            &format!("no fault ({} cycles), no NaN ({} cycles)", avoided.faulty_cycles, avoided.non_finite_cycles),
            avoided.faulty_cycles == 0 && avoided.non_finite_cycles == 0,
        );
        let figure = figure(spec.name, &avoided.distances, &reference.distances);
        Ok(Outcome { summary, series: avoided.series, figures: vec![("self_collision_distance.svg", figure)] })
    }
}

/// The smallest pair distance over time, with and without the avoidance.
fn figure(robot: &str, avoided: &[(f64, f64)], reference: &[(f64, f64)]) -> Figure {
    let mm = |points: &[(f64, f64)]| points.iter().map(|(t, d)| (*t, d * 1e3)).collect();
    Figure {
        title: format!("self_collision on {robot}: smallest distance of the enabled pairs"),
        x_label: "time (s)".into(),
        panels: vec![Panel {
            title: "smallest pair distance".into(),
            y_label: "distance (mm)".into(),
            lines: vec![
                Line::new("with collision avoidance", mm(avoided)),
                Line::dashed("without (reference)", mm(reference)),
                Line::dashed("margin", vec![(0.0, MARGIN_M * 1e3), (DURATION_S, MARGIN_M * 1e3)]),
            ],
            spans: vec![Span { label: "goal motion".into(), from: GOAL_AT_S, to: GOAL_AT_S + GOAL_S }],
        }],
    }
}

/// `host-sim run self_collision`.
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    super::simulate::<SelfCollision>(options)
}
