//! `limits` on an imported robot (`--robot`): a TCP goal outside the reachable set; the end stops
//! and the singularity avoidance keep the robot inside its limits without a fault.
//!
//! Setup: the rig of [`super::GenericRig`] at the robot's home posture. At [`MOVE_AT_S`] arm 0's
//! goal starts to move `D` straight up (world `z`, orientation kept) along the kernel's cubic of
//! [`MOVE_S`] (peak speed `1.5 D / T`). One rule makes the goal unreachable on every robot: `D`
//! puts it [`BEYOND_REACH_M`] beyond the chain's length `L` from the chain's first joint after a
//! planar base (`chain_reach`: the sum of the joint placements' offsets from that joint to the TCP,
//! the TCP's offset and each prismatic joint's largest travel, an upper bound of the TCP's distance
//! from that joint in any posture), so every posture's TCP is at least that far from it (Panda
//! `L` = 1.090 m, `D` = 1.356 m; TIAGo++ 1.564 m, 1.582 m; Justin 2.385 m, 2.480 m). The Cartesian
//! spring stretches the arm toward its workspace boundary, where the shaping fades the singular
//! direction out of the Cartesian level, the singularity avoidance takes it over below its
//! threshold `m₀`, and the end stops guard every joint's range. The goal then holds for
//! [`HOLD_S`].
//!
//! The scenario builds the robot's Fig. 6.3 hierarchy with the end stops on a new top level
//! (`end_stops_on_top`, every other task one level down; built into the controller, not commanded,
//! so no transition doubles the rows) and caps arm 0's translational spring force at
//! `K · BEYOND_REACH_M` per axis (Table 7.1's force limits; Panda 233 N, TIAGo++ 370 N, Justin
//! 250 N): an unreachable goal's spring force grows with the distance without bound. With the
//! file's hierarchy (end stops below the Cartesian level) the projection removed the stop's torque
//! along the Cartesian task and TIAGo++'s arm joint 2 went 1.6 mrad past its stop; on top, the
//! stop's row removes the Cartesian torque along the joint in proportion to its activation (0 at
//! the margin, 1 at the stop), and what leaks through at the stop grows with the pull: uncapped
//! (740 N/m × ~1 m) 0.08 mrad past, capped 1.3 mrad clear. A smaller cap (the thesis' ±20 N)
//! leaves the TCP short of the bracket and slow: TIAGo++ 1183.7 mm from the goal, settling
//! 0.840 s for 0.351 s.
//!
//! The platform, if the robot has one, is held: every axis of its admittance locked
//! (`free_axes = [false; 3]`, `ṙ_des = 0`). A mobile robot's reachable set is unbounded while its
//! platform moves (on Justin the horizontal rest of the capped pull turned the free platform by
//! 0.75 rad and moved it up to 0.56 m), so the claim on the nearest reachable point holds the
//! platform coordinates at home (they do not move in the search).
//!
//! Claims:
//! - **position limits**: every actuated joint stays within `[q_min, q_max]` over the whole run
//!   (the deepest entry into the end stops' margin band is reported, with its joint and time);
//! - **velocity limits**: every actuated joint's `|q̇| ≤ q̇_max` (the URDF's);
//! - **torques within limits**: every applied torque `|τ| ≤ τ_max`;
//! - **no fault, no NaN** over the whole run;
//! - **nearest reachable point**: at the end the TCP's distance to the goal lies between
//!   `d_range`, the smallest distance of any posture within the joint ranges (position only),
//!   and `d_free`, the smallest distance of any posture where no avoidance acts (manipulability
//!   `m ≥ m₀` and every joint outside the end stops' margin band) with the hand's home
//!   orientation held (the goal's orientation). The Cartesian impedance is 6-D (the config's
//!   `K_t`, `K_r`): the controller settles at a minimum of `½ Δxᵀ K_t Δx + ½ θᵀ K_r θ`; the posture
//!   of `d_free` has `θ = 0` and potential `½ K_t d_free²`, so if the controller settles no higher
//!   than that (the premise: its minimum is not a worse local one), `|Δx| ≤ d_free` (with the
//!   per-axis force cap the translational potential is monotone in `|Δx|` along one axis, as
//!   here, where the error points mostly along `z`). The upper end is loose where the rotational
//!   stiffness is small against the translational one (the Panda: 3.59 Nm/rad). The bracket assumes that no other task pulls the end posture: on Justin the
//!   torso's workspace rows are not in the search (they act at home). The orientation weighs
//!   [`HELD_ORIENTATION_WEIGHT_M`]; a search that gives up a little orientation finds a slightly
//!   smaller `d_free` (a tighter claim). Measured (f64): Panda 643.5 mm for [642.2, 1035.9] mm,
//!   TIAGo++ 1074.8 mm for [995.7, 1128.8] mm, Justin 1087.3 mm for [786.9, 1379.1] mm (position
//!   only, Justin's `d_free` was 791.8 mm, below where the 6-D impedance settles). Both are
//!   found by [`NearestPosture`] over the robot's plant model with every coordinate but the
//!   platform's moving (`d_range`: the TCP position over the ranges; `d_free`: position and
//!   orientation, ranges narrowed by the margin, steps kept at `m ≥ m₀`), a local search seeded at home
//!   and at the run's end posture (the smaller distance; from home alone TIAGo++'s search stops
//!   in a local minimum 53 mm farther);
//!   [`NEAREST_ALLOWANCE_M`] absorbs their convergence;
//! - **settling**: from the end of the goal's motion the TCP enters and stays within 5 % of its
//!   total motion around its final position within `ln(1 / (0.05 √(1 − ξ²))) / (ξ ω)`, the 5 %
//!   settling time of the Cartesian impedance (`ξ` the configuration's damping ratio,
//!   `ω = √(K / λ_max)` with `λ_max` the largest eigenvalue of the TCP's translational reflected
//!   inertia at home: the slowest Cartesian direction); the end stops (`ω_k ≥ 3 Hz`) and the
//!   singularity row are faster by the import's rule.

use kernel::controller::config::{ArmId, JointGroup, TaskKind, TaskSpec};
use kernel::dynamics::{crba, forward_kinematics, frame_jacobian};
use kernel::model::{Body, BodyId, Data, FrameId, JointKind, Model, Placement};
use nalgebra::{convert, RealField, SMatrix, SVector, Vector3};

use super::nearest_posture::NearestPosture;
use super::{record, GenericRig, RigParts, RobotSpec, Scenario};
use crate::output::{Figure, Line, Panel, Span, Summary, TimeSeries};
use crate::scenarios::{Outcome, RunOptions};
use crate::sim::{run_loop, CONTROL_PERIOD_S};

/// Registry name.
pub const NAME: &str = "limits";
/// One-line description.
pub const DESCRIPTION: &str = "imported robot (--robot): TCP goal straight up, 0.5 m beyond the chain's length (end \
                               stops, singularity avoidance: joints within their limits, no fault, nearest reachable point)";
/// Start of the goal's motion (s).
pub const MOVE_AT_S: f64 = 0.5;
/// How far the goal lies beyond the chain's length from its first joint (m): every posture's
/// TCP is at least this far from it.
pub const BEYOND_REACH_M: f64 = 0.5;
/// Duration of the goal's cubic (s): peak speed `1.5 D / T` for the goal's motion `D`.
pub const MOVE_S: f64 = 3.0;
/// The hold at the final goal (s).
pub const HOLD_S: f64 = 1.5;
/// Simulated time (s).
pub const DURATION_S: f64 = MOVE_AT_S + MOVE_S + HOLD_S;
/// Weight (m/rad) of the orientation error in the search for the bracket's upper end: the hand's
/// home orientation held (a mrad counts as 0.1 m).
pub const HELD_ORIENTATION_WEIGHT_M: f64 = 100.0;
/// Allowance of the nearest-reachable-point bounds for the search's convergence (m).
pub const NEAREST_ALLOWANCE_M: f64 = 1e-3;

/// The anchor and the length of the kinematic chain from the root (after a planar base) to the
/// TCP: the world position (m) of the first joint after the `platform` coordinates at the
/// placements `data` holds, and an upper bound (m) of the TCP's distance from it in any posture
/// within the ranges: the sum of the joint placements' offsets below it, the TCP's offset in its
/// body and each prismatic joint's largest travel from zero.
fn chain_reach<const N: usize, const B: usize, const F: usize>(
    model: &Model<f64, N, B, F>,
    data: &Data<f64, N, B, F>,
    tcp: FrameId,
    platform: &[bool; N],
) -> Result<(Vector3<f64>, f64), String> {
    let frame = model.frame(tcp).ok_or("no TCP frame")?;
    let on_platform = |body: &Body<f64>| body.drive.terms().iter().any(|t| platform.get(t.coordinate) == Some(&true));
    let chain: Vec<BodyId> = match frame.parent {
        Some(id) => model.support(id).take_while(|id| model.body(*id).is_some_and(|b| !on_platform(b))).collect(),
        None => Vec::new(),
    };
    let limits = &model.limits;
    let travel = |body: &Body<f64>| match body.joint {
        JointKind::Prismatic { .. } => body.drive.terms().iter().fold(body.drive.offset().abs(), |sum, t| {
            let lower = limits.position_lower.get(t.coordinate).map_or(f64::INFINITY, |x| x.abs());
            let upper = limits.position_upper.get(t.coordinate).map_or(f64::INFINITY, |x| x.abs());
            sum + t.coefficient.abs() * lower.max(upper)
        }),
        JointKind::Revolute { .. } => 0.0,
    };
    let mut length = frame.placement.translation.vector.norm();
    for (k, id) in chain.iter().enumerate() {
        let body = model.body(*id).ok_or("no body")?;
        length += travel(body);
        if k + 1 < chain.len() {
            length += body.joint_placement.translation.vector.norm();
        }
    }
    let anchor = match chain.last().and_then(|id| model.body(*id)) {
        Some(top) => {
            let parent =
                top.parent.and_then(|p| data.body_placements.get(p.0)).copied().unwrap_or_else(Placement::identity);
            (parent * top.joint_placement).translation.vector
        }
        None => data.frame_placements.get(tcp.0).ok_or("no TCP")?.translation.vector,
    };
    Ok((anchor, length))
}

/// The goal's motion `D` (m) straight up from the TCP at `start` that puts the goal
/// [`BEYOND_REACH_M`] beyond the chain's `length` from its `anchor` ([`chain_reach`]):
/// `|start + D ẑ − anchor| = length + BEYOND_REACH_M`.
fn goal_offset(start: &Vector3<f64>, anchor: &Vector3<f64>, length: f64) -> f64 {
    let d = start - anchor;
    let radius = length + BEYOND_REACH_M;
    -d.z + (radius * radius - d.x * d.x - d.y * d.y).max(0.0).sqrt()
}

/// `hierarchy` with the end stops on a new top level and every other task one level down: the
/// Cartesian task below them can no longer drive a joint along an active stop's row.
fn end_stops_on_top(hierarchy: &[TaskSpec]) -> Vec<TaskSpec> {
    hierarchy
        .iter()
        .copied()
        .map(|task| match task.kind {
            TaskKind::EndStops => TaskSpec { level: 0, ..task },
            _ => TaskSpec { level: task.level + 1, ..task },
        })
        .collect()
}

/// The 5 % settling time (s) of the Cartesian impedance of stiffness `stiffness` and damping
/// ratio `ratio` along the heaviest translational direction of the TCP at `q` (module docs).
fn settling_bound<const N: usize, const B: usize, const F: usize>(
    model: &Model<f64, N, B, F>,
    tcp: FrameId,
    q: &SVector<f64, N>,
    stiffness: f64,
    ratio: f64,
) -> Result<f64, String> {
    let mut data = Data::new(model);
    forward_kinematics(model, &mut data, q, &SVector::zeros()).map_err(|e| e.to_string())?;
    let inverse = crba(model, &mut data).try_inverse().ok_or("singular mass matrix")?;
    let mut jacobian = SMatrix::<f64, 6, N>::zeros();
    frame_jacobian(model, &data, tcp, &mut jacobian).map_err(|e| e.to_string())?;
    let j = jacobian.fixed_rows::<3>(0);
    let reflected = (j * inverse * j.transpose()).try_inverse().ok_or("singular TCP at home")?;
    let omega = (stiffness / reflected.symmetric_eigenvalues().max()).sqrt();
    Ok((1.0 / (0.05 * (1.0 - ratio * ratio).sqrt())).ln() / (ratio * omega))
}

/// What one run measured over the actuated joints.
#[derive(Clone, Copy, Debug, Default)]
struct Extremes {
    /// Smallest distance of any joint to its nearer stop (rad, m; negative: past it).
    stop_clearance: f64,
    /// The coordinate of that smallest distance and when (s).
    closest: (usize, f64),
    /// Largest `|q̇| / q̇_max`.
    velocity_ratio: f64,
    /// Largest `|τ| / τ_max`.
    torque_ratio: f64,
}

/// The scenario.
pub struct Limits;

impl Scenario for Limits {
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
        let mut parts = parts()?;
        parts.hierarchy = end_stops_on_top(&parts.hierarchy);
        // Arm 0's translational spring force capped at ±K · BEYOND_REACH_M per axis (module docs).
        let cartesian = parts.config.cartesian.first_mut().ok_or("no arm")?;
        let cap = cartesian.translational_stiffness[2] * convert(BEYOND_REACH_M);
        for (lower, upper) in cartesian.force_lower.iter_mut().zip(cartesian.force_upper.iter_mut()).take(3) {
            (*lower, *upper) = (-cap, cap);
        }
        // The platform held (every admittance axis locked): its coordinates stay at home.
        parts.config.platform.admittance.free_axes = [false; 3];
        let mut rig = GenericRig::new(spec, parts, options)?;
        let tcp = *spec.tcps.first().ok_or("no arm")?;
        let config = rig.controller.config();
        let arm = config.layout.coordinates(JointGroup::Arm(ArmId::all::<A>().first().copied().ok_or("no arm")?));
        let singularity = (config.singularity.rows, arm, config.singularity.threshold.into());
        let platform = config.layout.coordinates(JointGroup::Platform);
        let margin: f64 = config.end_stops.margin.into();
        let ratio: f64 = config.cartesian.first().ok_or("no arm")?.damping_ratio.into();
        let stiffness = rig.translational_stiffness(0)?;
        let home = SVector::from((spec.home)());
        let start = rig.tcp_position(spec, 0)?;
        let model = rig.sim.model().clone();
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &home, &SVector::zeros()).map_err(|e| e.to_string())?;
        let (anchor, length) = chain_reach(&model, &data, tcp, &platform)?;
        let home_rotation = data.frame_placements.get(tcp.0).ok_or("no TCP")?.rotation;
        let offset = Vector3::new(0.0, 0.0, goal_offset(&start, &anchor, length));
        let goal = start + offset;
        let bound = settling_bound(&model, tcp, &home, stiffness, ratio)?;
        let limits = &model.limits;
        let mut extremes = Extremes { stop_clearance: f64::INFINITY, ..Extremes::default() };
        let mut series = TimeSeries::new(super::columns::<N, U, A>(spec));
        run_loop(&mut rig, DURATION_S, CONTROL_PERIOD_S, |rig, info| {
            options.progress.report(NAME, info.time_s, DURATION_S);
            if info.cycle == (MOVE_AT_S / CONTROL_PERIOD_S).round() as u64 {
                rig.move_goal(0, offset, MOVE_S)?;
            }
            rig.cycle(info)?;
            let (q, v, tau) = (rig.sim.q(), rig.sim.v(), rig.sim.applied_torque());
            let bounds = limits.position_lower.iter().zip(limits.position_upper.iter());
            let joints = q.iter().zip(v.iter()).zip(bounds).zip(limits.velocity.iter()).skip(N - U);
            for (k, (((q, v), (lower, upper)), speed)) in joints.enumerate() {
                let clearance = (q - lower).min(upper - q);
                if clearance < extremes.stop_clearance {
                    (extremes.stop_clearance, extremes.closest) = (clearance, (N - U + k, info.time_s));
                }
                extremes.velocity_ratio = extremes.velocity_ratio.max(v.abs() / speed);
            }
            let ratios = tau.iter().zip(limits.effort.iter().skip(N - U)).map(|(tau, limit)| tau.abs() / limit);
            extremes.torque_ratio = ratios.fold(extremes.torque_ratio, f64::max);
            record(rig, spec, info.time_s, &mut series)
        })?;
        options.progress.finish();
        // The search is local: seeded at home and at the run's end posture (its platform
        // coordinates at home).
        let end_posture = SVector::from_fn(|k, _| match platform.get(k) {
            Some(true) => home.get(k).copied().unwrap_or(f64::NAN),
            _ => rig.sim.q().get(k).copied().unwrap_or(f64::NAN),
        });
        let moves = platform.map(|held| !held);
        let nearest = |search: NearestPosture<N, B, F>| -> Result<f64, String> {
            let distance = |seed| -> Result<Option<f64>, String> {
                Ok(search.search(seed, &goal)?.map(|(_, tcp)| (goal - tcp.translation.vector).norm()))
            };
            let from_home = distance(&home)?.ok_or("home posture below the manipulability bound")?;
            Ok(distance(&end_posture)?.map_or(from_home, |d| d.min(from_home)))
        };
        let nearest_in_range = nearest(NearestPosture {
            model: &model,
            tcp,
            moves,
            margin: 0.0,
            orientation: None,
            manipulability: None,
        })?;
        let nearest_unguarded = nearest(NearestPosture {
            model: &model,
            tcp,
            moves,
            margin,
            orientation: Some((home_rotation, HELD_ORIENTATION_WEIGHT_M)),
            manipulability: Some(singularity),
        })?;

        let t = series.column("t").ok_or("no t")?;
        let xyz = ["x", "y", "z"].map(|axis| series.column(&format!("tcp0.{axis}")));
        let [Some(x), Some(y), Some(z)] = xyz else { return Err("no TCP columns".into()) };
        let path: Vec<Vector3<f64>> = x.iter().zip(&y).zip(&z).map(|((x, y), z)| Vector3::new(*x, *y, *z)).collect();
        let end = *path.last().ok_or("no samples")?;
        let band = 0.05 * (end - start).norm();
        let goal_stops = MOVE_AT_S + MOVE_S;
        let settled_at = t
            .iter()
            .zip(&path)
            .filter(|(t, p)| **t >= goal_stops && (*p - end).norm() > band)
            .map(|(t, _)| t + CONTROL_PERIOD_S)
            .fold(goal_stops, f64::max);
        let settling_s = settled_at - goal_stops;
        let final_distance = (goal - end).norm();

        let mut summary = Summary::new(NAME);
        let closest_joint = spec.joint_names.get(extremes.closest.0).copied().unwrap_or("none");
        summary.value("robot", spec.name).value("controller", format!("host {}", options.scalar.name()));
        summary.value("closest_joint", closest_joint);
        summary
            .metric("chain_length_m", length)
            .metric("goal_offset_m", offset.z)
            .metric("stop_clearance_rad", extremes.stop_clearance)
            .metric("closest_at_s", extremes.closest.1)
            .metric("end_stop_margin_rad", margin)
            .metric("largest_velocity_ratio", extremes.velocity_ratio)
            .metric("largest_torque_ratio", extremes.torque_ratio)
            .metric("final_goal_distance_m", final_distance)
            .metric("nearest_in_range_m", nearest_in_range)
            .metric("nearest_unguarded_m", nearest_unguarded)
            .metric("settling_time_s", settling_s)
            .metric("settling_bound_s", bound)
            .metric("faulty_cycles", rig.faulty_cycles as f64)
            .metric("non_finite_cycles", rig.non_finite_cycles as f64);
        summary.claim(
            &format!(
                "joints within their ranges: closest {:.4} to a stop (≥ 0; margin band from {margin})",
                extremes.stop_clearance
            ),
            extremes.stop_clearance >= 0.0,
        );
        summary.claim(
            &format!("joint speeds within limits: largest |q̇|/q̇_max = {:.2}", extremes.velocity_ratio),
            extremes.velocity_ratio <= 1.0,
        );
        summary.claim(
            &format!("torques within limits: largest |τ|/τ_max = {:.2}", extremes.torque_ratio),
            extremes.torque_ratio <= 1.0,
        );
        summary.claim(
            &format!("no fault ({} cycles), no NaN ({} cycles)", rig.faulty_cycles, rig.non_finite_cycles),
            rig.faulty_cycles == 0 && rig.non_finite_cycles == 0,
        );
        summary.claim(
            &format!(
                "nearest reachable point: {:.1} mm from the goal, within [{:.1}, {:.1}] mm (ranges, no avoidance acting) ± {:.0} mm",
                final_distance * 1e3,
                nearest_in_range * 1e3,
                nearest_unguarded * 1e3,
                NEAREST_ALLOWANCE_M * 1e3
            ),
            final_distance >= nearest_in_range - NEAREST_ALLOWANCE_M
                && final_distance <= nearest_unguarded + NEAREST_ALLOWANCE_M,
        );
        summary.claim(
            &format!("TCP settles into 5 % of its motion {settling_s:.3} s after the goal stops ≤ {bound:.3} s"),
            settling_s <= bound,
        );
        let figure = figure(spec.name, &t, &z, goal.z);
        Ok(Outcome { summary, series, figures: vec![("limits_tcp_height.svg", figure)] })
    }
}

/// The TCP height over time with the goal's height and the motion marked.
fn figure(robot: &str, t: &[f64], z: &[f64], goal: f64) -> Figure {
    Figure {
        title: format!("limits on {robot}: TCP height toward an unreachable goal"),
        x_label: "time (s)".into(),
        panels: vec![Panel {
            title: "arm 0 TCP height".into(),
            y_label: "z (m)".into(),
            lines: vec![
                Line::new("TCP z", t.iter().zip(z).map(|(t, z)| (*t, *z)).collect()),
                Line::dashed("goal", vec![(MOVE_AT_S + MOVE_S, goal), (DURATION_S, goal)]),
            ],
            spans: vec![Span { label: "goal moves".into(), from: MOVE_AT_S, to: MOVE_AT_S + MOVE_S }],
        }],
    }
}

/// `host-sim run limits`.
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    super::simulate::<Limits>(options)
}
