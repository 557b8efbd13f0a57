//! `wipe_window`: "Wipe the window!" of Table 7.1 (Sec. 7.3, Fig. 7.3) on the simulated Justin
//! under the whole-body controller, with a compliant window from [`crate::sim::Surface`].
//!
//! Setup: the rig of [`crate::wbc`] starts with the Ch. 6 hierarchy (Fig. 6.3, right TCP); at
//! the first cycle the planner commands switch to the tool: `SetCartesian` with the Table 7.1
//! parameters of [`WIPE_WINDOW`] (`(100, 500, 1000)` N/m, `(500, 10, 10)` Nm/rad, force limit
//! `−∞/+10 N` along the tool x axis, in the axes of the desired TCP frame) and `SetHierarchy`
//! with its hierarchy (Cartesian impedance > self-collision avoidance > singularity avoidance >
//! joint impedance; blended over the configured 1 s). The right TCP's reference is streamed as
//! `TcpSample`s: the tool orientation (the smallest rotation of the start orientation that
//! puts the TCP x axis on the world x axis, i.e. on the window's inward normal) is reached
//! during the approach, the reference is placed [`BEHIND_M`] behind the window ("The reference
//! values of the tools are deliberately placed behind the surface to be cleaned") and then
//! wipes [`STROKES`] horizontal strokes of ±[`STROKE_HALF_WIDTH_M`] in the window plane,
//! stepping down between them, and retracts.
//!
//! The window (all **chosen**): a vertical plane [`WINDOW_GAP_M`] in front of the start TCP,
//! normal −x (towards the robot), stiffness [`WINDOW_STIFFNESS_N_M`], damping
//! [`WINDOW_DAMPING_NS_M`], friction [`WINDOW_FRICTION`]. It is not a collision volume: the
//! collision avoidance of Table 7.1 is a *self*-collision avoidance. The base is free (the
//! admittance of [`whole_body::controller_config`]), as the table's "Actuators" row says.
//!
//! The approach ([`press_path`]) brings the reference onto the window plane, the last
//! [`CLEARANCE_M`] slowly, so that the TCP touches at rest; the reference then moves behind it.
//!
//! Claims: the contact force along the tool x axis (the window's normal force) never exceeds
//! the +10 N limit of Table 7.1 over the whole run; with the reference at rest behind the
//! window it is within the limit and at least 80 % of it, and so is its mean during the strokes
//! ([`force_claims`]); the force limit is active while wiping; the contact is kept during the
//! strokes; the strokes are executed in the window plane; no fault; no self-collision. What
//! keeps the force under the limit while the TCP moves is the controller's contact-force
//! limiter ([`kernel::controller::force_limit`]). On the realistic plant the run-peak and
//! static bounds widen by the joint friction's bound of each cycle ([`force_claims`]).
//!
//! The module also holds the machinery the three Table 7.1 scenarios share ([`run_tool`]).

use fixtures::justin::whole_body::{ServiceTask, WIPE_WINDOW};
use fixtures::justin::{self, whole_body};
use kernel::controller::config::{ArmId, CartesianParameters, JointGroup, TaskKind, TaskSpec};
use kernel::controller::messages::{Command, Pose};
use kernel::model::Placement;
use nalgebra::{Rotation3, SVector, Unit, UnitQuaternion, Vector3};

use super::{Outcome, RunOptions};
use crate::output::{Figure, Line, Panel, Span, Summary, TimeSeries};
use crate::plant::PlantKind;
use crate::sim::Surface;
use crate::wbc::{self, ConfigChanges, Rig};

/// Registry name.
pub const NAME: &str = "wipe_window";
/// One-line description.
pub const DESCRIPTION: &str =
    "Table 7.1 \"Wipe the window!\": right TCP wipes a compliant window, reference 10 cm behind it, +10 N limit in tool x (Fig. 7.3)";
/// Simulated time (s).
pub const DURATION_S: f64 = 14.5;
/// Distance of the window in front of the start TCP (m); chosen.
pub const WINDOW_GAP_M: f64 = 0.12;
/// Distance of the reference behind the window (m); chosen within the brief's 5–10 cm.
pub const BEHIND_M: f64 = 0.10;
/// Window stiffness (N/m); chosen: a pane in a frame with a compliant wiper pad.
pub const WINDOW_STIFFNESS_N_M: f64 = 1.0e4;
/// Window damping (Ns/m); chosen.
pub const WINDOW_DAMPING_NS_M: f64 = 50.0;
/// Friction coefficient wiper–glass; chosen.
pub const WINDOW_FRICTION: f64 = 0.2;
/// Number of horizontal strokes.
pub const STROKES: usize = 4;
/// Half width of a stroke (m).
pub const STROKE_HALF_WIDTH_M: f64 = 0.12;
/// Height step between strokes (m).
pub const STROKE_STEP_M: f64 = 0.04;
/// Time after the first touch excluded from the static force claim (s): the impact transient.
pub const SETTLE_S: f64 = 0.5;
/// Normal force above which a surface counts as touched (N).
pub const CONTACT_THRESHOLD_N: f64 = 0.5;
/// Window of the strokes (s).
pub const STROKES_S: (f64, f64) = (5.0, 12.5);
/// Distance before the surface where the approach of [`press_path`] slows down (m); chosen.
pub const CLEARANCE_M: f64 = 0.02;
/// When the reference reaches the window plane, the TCP at rest on it (s).
pub const TOUCH_S: f64 = 3.0;
/// Rest of the pressed reference before the motion starts (s): the static part of the claims.
pub const HOLD_S: f64 = 1.0;
/// Part of the hold over which the static contact force is averaged (s, its end).
pub const STATIC_S: f64 = 0.3;

/// The platform's joint impedance next to Table 7.1's "joint impedance" (level 3): see the
/// module docs.
pub const PLATFORM_IMPEDANCE: [TaskSpec; 1] =
    [TaskSpec { kind: TaskKind::JointImpedance(JointGroup::Platform), level: 3 }];

/// The quintic (minimum-jerk) blend `s(u)`, `s'(u)` on `u ∈ [0, 1]`, clamped outside.
pub fn quintic(u: f64) -> (f64, f64) {
    if u <= 0.0 {
        return (0.0, 0.0);
    }
    if u >= 1.0 {
        return (1.0, 0.0);
    }
    let (u2, u3) = (u * u, u * u * u);
    (u3 * (10.0 - 15.0 * u + 6.0 * u2), 30.0 * u2 * (1.0 - 2.0 * u + u2))
}

/// A rest-to-rest path through timed waypoints `(t, p)` (quintic blends), held outside.
#[derive(Clone, Debug, PartialEq)]
pub struct Waypoints(pub Vec<(f64, Vector3<f64>)>);

impl Waypoints {
    /// Position and velocity at `t`.
    pub fn at(&self, t: f64) -> (Vector3<f64>, Vector3<f64>) {
        let points = &self.0;
        let Some(first) = points.first() else {
            return (Vector3::zeros(), Vector3::zeros());
        };
        if t <= first.0 {
            return (first.1, Vector3::zeros());
        }
        for pair in points.windows(2) {
            if let [(t0, p0), (t1, p1)] = pair {
                if t < *t1 && t1 > t0 {
                    let (s, ds) = quintic((t - t0) / (t1 - t0));
                    return (p0 + (p1 - p0) * s, (p1 - p0) * (ds / (t1 - t0)));
                }
            }
        }
        (points.last().map_or(first.1, |p| p.1), Vector3::zeros())
    }
}

/// The smallest rotation of `start` that turns its axis `axis` (0 = x, 1 = y, 2 = z) onto the
/// world direction `direction`: the tool frame of a TCP.
pub fn tool_orientation(start: &Rotation3<f64>, axis: usize, direction: &Vector3<f64>) -> Rotation3<f64> {
    let current = start.matrix().column(axis).into_owned();
    Rotation3::rotation_between(&current, direction).unwrap_or_else(|| {
        // Antiparallel: half a turn about any axis normal to it.
        let normal = current
            .cross(&Vector3::x())
            .try_normalize(1e-6)
            .unwrap_or_else(|| current.cross(&Vector3::y()).normalize());
        Rotation3::from_axis_angle(&Unit::new_unchecked(normal), core::f64::consts::PI)
    }) * start
}

/// The reference of one TCP: the orientation turns from the start to the tool orientation
/// during `turn_s` (quintic slerp), the position follows `path`.
#[derive(Clone, Debug, PartialEq)]
pub struct ToolReference {
    /// Which TCP.
    pub hand: ArmId,
    /// Start orientation (measured).
    pub start: Rotation3<f64>,
    /// Tool orientation (the desired TCP frame during the task).
    pub tool: Rotation3<f64>,
    /// Time window of the turn (s).
    pub turn_s: (f64, f64),
    /// Position path (world frame).
    pub path: Waypoints,
    /// Circles added to the path (a brush scrubbing), if any.
    pub circles: Option<Circles>,
}

/// Circles in the plane of the unit vectors `u`, `v`, added to a path: the offset
/// `r (sin θ u + (1 − cos θ) v)` with `θ = 2π turns s((t − t₀)/(t₁ − t₀))`, `s` the quintic, so
/// the motion starts and ends at rest and is smooth in between (no stop per segment).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Circles {
    /// First in-plane direction (the start tangent).
    pub u: Vector3<f64>,
    /// Second in-plane direction (towards the circle centre at the start).
    pub v: Vector3<f64>,
    /// Radius (m).
    pub radius_m: f64,
    /// Number of turns.
    pub turns: f64,
    /// Time window `(t₀, t₁)` (s).
    pub window_s: (f64, f64),
}

impl Circles {
    /// Offset and its velocity at `t`.
    pub fn at(&self, t: f64) -> (Vector3<f64>, Vector3<f64>) {
        let span = (self.window_s.1 - self.window_s.0).max(1e-9);
        let (s, ds) = quintic((t - self.window_s.0) / span);
        let scale = core::f64::consts::TAU * self.turns;
        let (angle, rate) = (scale * s, scale * ds / span);
        let offset = (self.u * angle.sin() + self.v * (1.0 - angle.cos())) * self.radius_m;
        let velocity = (self.u * angle.cos() + self.v * angle.sin()) * (self.radius_m * rate);
        (offset, velocity)
    }
}

/// The path of a tool pressing on a surface along the unit direction `press`: at rest at `start`
/// until `times.0`; by `times.1` [`CLEARANCE_M`] before `touch` (the surface point ahead of the
/// TCP), by `times.2` at `touch`, slowly, so that the TCP arrives there at rest (the tracking
/// error of the fast part stays clear of the surface); by `times.3` at `pressed` (the reference
/// behind the surface, Sec. 7.3). Touching at rest keeps the impact out of the contact force:
/// the force grows with the reference's depth.
pub fn press_path(
    start: Vector3<f64>,
    touch: Vector3<f64>,
    pressed: Vector3<f64>,
    press: &Vector3<f64>,
    times: (f64, f64, f64, f64),
) -> Vec<(f64, Vector3<f64>)> {
    vec![(0.0, start), (times.0, start), (times.1, touch - press * CLEARANCE_M), (times.2, touch), (times.3, pressed)]
}

impl ToolReference {
    /// Desired pose, linear and angular velocity (world frame) at `t`.
    pub fn at(&self, t: f64) -> (Placement<f64>, Vector3<f64>, Vector3<f64>) {
        let (path, path_velocity) = self.path.at(t);
        let (offset, offset_velocity) = self.circles.map_or((Vector3::zeros(), Vector3::zeros()), |c| c.at(t));
        let (position, velocity) = (path + offset, path_velocity + offset_velocity);
        let span = (self.turn_s.1 - self.turn_s.0).max(1e-9);
        let (s, ds) = quintic((t - self.turn_s.0) / span);
        let relative = (self.tool * self.start.inverse()).scaled_axis();
        let rotation = Rotation3::from_scaled_axis(relative * s) * self.start;
        let omega = relative * (ds / span);
        (Placement::from_parts(position.into(), rotation), velocity, omega)
    }

    fn command(&self, t: f64) -> Command<f64> {
        let (pose, v, w) = self.at(t);
        let q = UnitQuaternion::from_rotation_matrix(&pose.rotation);
        let p = pose.translation.vector;
        Command::TcpSample {
            hand: self.hand,
            pose: Pose { position: [p.x, p.y, p.z], orientation: [q.w, q.i, q.j, q.k] },
            linear_velocity: [v.x, v.y, v.z],
            angular_velocity: [w.x, w.y, w.z],
        }
    }
}

/// A contact surface and the TCP it belongs to.
#[derive(Clone, Debug, PartialEq)]
pub struct Contact {
    /// Short label for the columns (`window`, `floor_right`, …).
    pub label: &'static str,
    /// The TCP that touches it.
    pub hand: ArmId,
    /// The surface.
    pub surface: Surface,
}

/// What the scenario sets up from the measured start poses `[right, left]`.
pub struct ToolPlan {
    /// References of the tool TCPs.
    pub references: Vec<ToolReference>,
    /// The surfaces.
    pub contacts: Vec<Contact>,
    /// Cartesian parameters replacing the task's [`ServiceTask::cartesian`] (the same limits
    /// expressed in a TCP frame turned against the table's tool frame), if any.
    pub cartesian: Option<CartesianParameters<f64>>,
}

/// One recorded control cycle beyond the rig's columns.
#[derive(Clone, Debug, PartialEq)]
pub struct ToolSample {
    /// Time (s).
    pub t: f64,
    /// Normal force per contact (N).
    pub normal_n: Vec<f64>,
    /// Penetration per contact (m).
    pub depth_m: Vec<f64>,
    /// The joint friction's share of the normal force and its bound per contact
    /// ([`wbc::friction_contact_shares`]; zero on the ideal plant).
    pub friction: Vec<wbc::FrictionShare>,
    /// Reference position per reference (m).
    pub reference: Vec<Vector3<f64>>,
    /// Measured TCP position per reference (m).
    pub measured: Vec<Vector3<f64>>,
    /// Any force limit of the reference's TCP active.
    pub limited: Vec<bool>,
    /// The controller's estimate of the force the reference's TCP applies (N, desired-frame
    /// axes, [`kernel::controller::force_limit`]).
    pub estimate: Vec<Vector3<f64>>,
    /// The contact-force governor's correction of the force bounds per axis (N).
    pub correction: Vec<Vector3<f64>>,
    /// The controller's TCP position error `p − p_des` per reference (m, desired-frame axes,
    /// telemetry).
    pub error: Vec<Vector3<f64>>,
    /// Base pose `(x, y, θ)`.
    pub base: [f64; 3],
}

/// The result of [`run_tool`].
pub struct ToolRun {
    /// The scenario's summary, begun with the controller that drove the robot
    /// ([`Rig::describe_controller`]).
    pub summary: Summary,
    /// Rig series extended by the tool columns.
    pub series: TimeSeries,
    /// The tool samples, one per control cycle.
    pub samples: Vec<ToolSample>,
    /// Contacts (labels, hands).
    pub contacts: Vec<Contact>,
    /// References.
    pub references: Vec<ToolReference>,
    /// Cycles with a safe output.
    pub faulty_cycles: u64,
    /// Smallest self-collision distance (m), `∞` without a collision task.
    pub min_distance_m: f64,
    /// Whether any sample was non-finite.
    pub finite: bool,
    /// The first fault the controller reported (`Debug` text) and its time (s).
    pub first_fault: Option<(f64, String)>,
    /// What the plan's contact gate did, if it has one.
    pub gate: Option<GateRecord>,
}

/// A contact-waiting phase in the tool sequence (the planner of Ch. 7 reacting to the robot's
/// telemetry): the plan's clock stops at `at_s` (plan time, the references at rest pressed behind
/// the surface) until `touched` reports contact at every tool TCP, at most `timeout_s`; the rest of
/// the plan runs that much later.
#[derive(Clone, Copy, Debug)]
pub struct ContactGate {
    /// Plan time at which the clock waits (s).
    pub at_s: f64,
    /// Longest wait (s); the plan goes on without the contact after it.
    pub timeout_s: f64,
    /// The planner's contact signal, from what a cycle's sample holds.
    pub touched: fn(&ToolSample) -> bool,
}

/// What a [`ContactGate`] did in a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GateRecord {
    /// How long the plan waited (s).
    pub waited_s: f64,
    /// Whether the contact came before the timeout.
    pub touched: bool,
}

/// The plan's clock: run time less the time spent waiting at a [`ContactGate`].
struct PlanClock {
    gate: Option<ContactGate>,
    waited_s: f64,
    released: Option<bool>,
}

impl PlanClock {
    /// Plan time of the cycle at run time `t` (s), with the planner's contact signal of the cycle.
    fn plan_time(&mut self, t: f64, touched: bool) -> f64 {
        let Some(gate) = self.gate.filter(|_| self.released.is_none()) else { return t - self.waited_s };
        if t - self.waited_s < gate.at_s {
            return t - self.waited_s;
        }
        if touched || self.waited_s >= gate.timeout_s {
            self.released = Some(touched);
            return t - self.waited_s;
        }
        self.waited_s = t - gate.at_s;
        gate.at_s
    }

    fn record(&self) -> Option<GateRecord> {
        self.gate.map(|_| GateRecord { waited_s: self.waited_s, touched: self.released.unwrap_or(false) })
    }
}

/// Runs a Table 7.1 tool: rig at `q0` with the configuration of Ch. 6 with `changes` and the
/// Ch. 6 hierarchy, switches to the tool's Cartesian parameters and hierarchy at the first
/// cycle, streams the references of `plan` (built from the measured start TCP poses
/// `[right, left]`) and records the contacts.
#[allow(clippy::too_many_arguments, reason = "one call per scenario, every argument differs")]
pub fn run_tool(
    name: &str,
    task: &ServiceTask,
    extra_tasks: &[TaskSpec],
    q0: &SVector<f64, { justin::N }>,
    changes: ConfigChanges,
    duration_s: f64,
    plan: impl FnOnce([Placement<f64>; 2]) -> ToolPlan,
    options: &RunOptions,
) -> Result<ToolRun, String> {
    run_tool_gated(name, task, extra_tasks, q0, changes, (duration_s, None), plan, options)
}

/// [`run_tool`] with the plan's clock held at `timing.1`, a [`ContactGate`], if any: the run
/// lasts up to `timing.0` of plan time and the gate's timeout (the samples and the series end
/// where the plan ends; the fault count and the smallest distance cover the whole run).
#[allow(clippy::too_many_arguments, reason = "one call per scenario, every argument differs")]
pub fn run_tool_gated(
    name: &str,
    task: &ServiceTask,
    extra_tasks: &[TaskSpec],
    q0: &SVector<f64, { justin::N }>,
    changes: ConfigChanges,
    timing: (f64, Option<ContactGate>),
    plan: impl FnOnce([Placement<f64>; 2]) -> ToolPlan,
    options: &RunOptions,
) -> Result<ToolRun, String> {
    let (duration_s, gate) = timing;
    let mut clock = PlanClock { gate, waited_s: 0.0, released: None };
    let run_s = duration_s + gate.map_or(0.0, |g| g.timeout_s);
    let mut rig = wbc::rig(q0, &[], changes, &whole_body::fig_6_3_hierarchy(ArmId::RIGHT), options)?;
    let start = [
        rig.sim.frame_placement(justin::RIGHT_TCP).map_err(|e| e.to_string())?,
        rig.sim.frame_placement(justin::LEFT_TCP).map_err(|e| e.to_string())?,
    ];
    let ToolPlan { references, contacts, cartesian } = plan(start);
    let parameters = cartesian.unwrap_or_else(|| task.cartesian());
    for c in &contacts {
        rig.sim.add_surface(c.surface).map_err(|e| format!("surface {}: {e}", c.label))?;
    }
    let mut samples: Vec<ToolSample> = Vec::new();
    let mut first_fault = None;
    let series = rig.run(run_s, |rig: &mut Rig, info| {
        if info.cycle == 0 {
            for hand in task.hands {
                rig.apply(&Command::SetCartesian { hand: *hand, parameters })
                    .map_err(|e| format!("SetCartesian: {e}"))?;
            }
            rig.apply(&Command::SetHierarchy(task.hierarchy.iter().chain(extra_tasks.iter()).copied().collect()))
                .map_err(|e| format!("SetHierarchy: {e}"))?;
        }
        let mut sample = ToolSample {
            t: info.time_s,
            normal_n: Vec::new(),
            depth_m: Vec::new(),
            friction: Vec::new(),
            reference: Vec::new(),
            measured: Vec::new(),
            limited: Vec::new(),
            estimate: Vec::new(),
            correction: Vec::new(),
            error: Vec::new(),
            base: [rig.sim.q()[0], rig.sim.q()[1], rig.sim.q()[2]],
        };
        for index in 0..contacts.len() {
            let contact = rig.sim.surface_force(index).map_err(|e| e.to_string())?.ok_or("surface index")?;
            sample.normal_n.push(contact.normal_force_n);
            sample.depth_m.push(contact.penetration_m);
        }
        let pressed: Vec<_> = contacts
            .iter()
            .zip(sample.normal_n.iter())
            .map(|(c, f)| (c.surface.frame, -c.surface.normal.into_inner(), *f > 0.0))
            .collect();
        sample.friction = wbc::friction_contact_shares(&rig.sim, &pressed)?;
        let telemetry = rig.controller.telemetry();
        let (limited, applied, corrections, errors) = (
            telemetry.tcp_force_limited,
            telemetry.contact_wrench,
            telemetry.force_limit_correction,
            telemetry.tcp_error,
        );
        for reference in &references {
            let frame = if reference.hand == ArmId::RIGHT { justin::RIGHT_TCP } else { justin::LEFT_TCP };
            sample.measured.push(rig.sim.frame_placement(frame).map_err(|e| e.to_string())?.translation.vector);
            sample.limited.push(limited.get(reference.hand.index()).is_some_and(|l| l.iter().any(|x| *x)));
            let linear = |w: &[nalgebra::Vector6<f64>; 2]| {
                w.get(reference.hand.index()).map_or_else(Vector3::zeros, |w| w.fixed_rows::<3>(0).into_owned())
            };
            sample.estimate.push(linear(&applied));
            sample.correction.push(linear(&corrections));
            sample.error.push(linear(&errors));
        }
        let plan_s = clock.plan_time(info.time_s, gate.is_some_and(|g| (g.touched)(&sample)));
        if plan_s >= duration_s {
            return Ok(());
        }
        for reference in &references {
            sample.reference.push(reference.at(plan_s).0.translation.vector);
            rig.apply(&reference.command(plan_s)).map_err(|e| format!("TcpSample: {e}"))?;
        }
        samples.push(sample);
        if first_fault.is_none() {
            first_fault = rig.controller.telemetry().fault.map(|f| (info.time_s, format!("{f:?}")));
        }
        if info.cycle % 100 == 0 {
            options.progress.report(name, plan_s, duration_s);
        }
        Ok(())
    })?;
    options.progress.finish();
    let finite = series.rows().iter().all(|r| r.iter().all(|x| x.is_finite() || x.is_nan()))
        && samples.iter().all(|s| s.normal_n.iter().chain(s.base.iter()).all(|x| x.is_finite()));
    let series = extend_series(&series, &samples, &contacts, &references)?;
    let mut summary = Summary::new(name);
    rig.describe_controller(&mut summary);
    Ok(ToolRun {
        summary,
        series,
        samples,
        contacts,
        references,
        faulty_cycles: rig.faulty_cycles,
        min_distance_m: rig.min_distance_m,
        finite,
        first_fault,
        gate: clock.record(),
    })
}

/// The rig's columns, then per contact `contact.<label>.force`, `.depth`, `.friction`, `.friction_bound`, per reference
/// `ref.<hand>.x/y/z`, `limited.<hand>`, the estimated applied force `est.<hand>.x/y/z` and the
/// governor's correction `corr.<hand>.x/y/z` (desired-frame axes).
fn extend_series(
    rig: &TimeSeries,
    samples: &[ToolSample],
    contacts: &[Contact],
    references: &[ToolReference],
) -> Result<TimeSeries, String> {
    let mut columns = rig.columns().to_vec();
    for c in contacts {
        columns.push(format!("contact.{}.force", c.label));
        columns.push(format!("contact.{}.depth", c.label));
        columns.push(format!("contact.{}.friction", c.label));
        columns.push(format!("contact.{}.friction_bound", c.label));
    }
    for r in references {
        let h = r.hand.name();
        columns.extend(["x", "y", "z"].iter().map(|a| format!("ref.{h}.{a}")));
        columns.push(format!("limited.{h}"));
        columns.extend(["x", "y", "z"].iter().map(|a| format!("est.{h}.{a}")));
        columns.extend(["x", "y", "z"].iter().map(|a| format!("corr.{h}.{a}")));
    }
    let mut series = TimeSeries::new(columns);
    for (row, s) in rig.rows().iter().zip(samples.iter()) {
        let mut row = row.clone();
        for ((f, d), r) in s.normal_n.iter().zip(s.depth_m.iter()).zip(s.friction.iter()) {
            row.extend([*f, *d, r.share_n, r.bound_n]);
        }
        for (((p, l), e), c) in s.reference.iter().zip(s.limited.iter()).zip(s.estimate.iter()).zip(s.correction.iter())
        {
            row.extend(p.iter());
            row.push(f64::from(u8::from(*l)));
            row.extend(e.iter().chain(c.iter()));
        }
        series.push(row)?;
    }
    Ok(series)
}

/// Contact metrics of one surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactMetrics {
    /// First time the normal force exceeded [`CONTACT_THRESHOLD_N`] (s), `NaN` if never.
    pub first_touch_s: f64,
    /// Largest normal force over the run (N).
    pub peak_n: f64,
    /// Largest normal force from [`SETTLE_S`] after the first touch on (N).
    pub settled_peak_n: f64,
    /// Mean normal force over `window` (N).
    pub mean_n: f64,
    /// Largest normal force inside `window` (N).
    pub window_peak_n: f64,
    /// Mean normal force over the static part `[window.0 − STATIC_S, window.0]` (N): the
    /// reference at rest behind the surface.
    pub static_n: f64,
    /// Share of the cycles in `window` with the surface touched.
    pub contact_share: f64,
    /// The joint friction ([`wbc::FrictionShare`]) at the cycle of [`Self::peak_n`]: its share
    /// and its bound (N; zero on the ideal plant).
    pub friction_at_peak: wbc::FrictionShare,
    /// Largest normal force less the friction bound of its cycle over the run, `max (F − B_f)`
    /// (N; [`Self::peak_n`] on the ideal plant).
    pub peak_beyond_friction_n: f64,
    /// Mean friction bound over the static part (N).
    pub static_friction_bound_n: f64,
}

/// Metrics of contact `index` with the claim window `window` (s).
pub fn contact_metrics(samples: &[ToolSample], index: usize, window: (f64, f64)) -> ContactMetrics {
    let force = |s: &ToolSample| s.normal_n.get(index).copied().unwrap_or(0.0);
    let first_touch_s = samples.iter().find(|s| force(s) > CONTACT_THRESHOLD_N).map_or(f64::NAN, |s| s.t);
    let peak_n = samples.iter().map(force).fold(0.0, f64::max);
    let friction = |s: &ToolSample| s.friction.get(index).copied().unwrap_or_default();
    let friction_at_peak = samples.iter().find(|s| force(s) == peak_n).map(friction).unwrap_or_default();
    let peak_beyond_friction_n = samples.iter().map(|s| force(s) - friction(s).bound_n).fold(0.0, f64::max);
    let settled_peak_n = samples.iter().filter(|s| s.t >= first_touch_s + SETTLE_S).map(force).fold(0.0, f64::max);
    let inside: Vec<f64> = samples.iter().filter(|s| s.t >= window.0 && s.t <= window.1).map(force).collect();
    #[allow(clippy::cast_precision_loss, reason = "a few thousand samples")]
    let count = inside.len().max(1) as f64;
    let mean_n = inside.iter().sum::<f64>() / count;
    let window_peak_n = inside.iter().copied().fold(0.0, f64::max);
    let resting: Vec<&ToolSample> = samples.iter().filter(|s| s.t >= window.0 - STATIC_S && s.t < window.0).collect();
    #[allow(clippy::cast_precision_loss, reason = "a few hundred samples")]
    let resting_mean = |value: &dyn Fn(&ToolSample) -> f64| {
        resting.iter().map(|s| value(s)).sum::<f64>() / resting.len().max(1) as f64
    };
    let (static_n, static_friction_bound_n) = (resting_mean(&force), resting_mean(&|s| friction(s).bound_n));
    #[allow(clippy::cast_precision_loss, reason = "a few thousand samples")]
    let touched = inside.iter().filter(|f| **f > CONTACT_THRESHOLD_N).count() as f64;
    ContactMetrics {
        first_touch_s,
        peak_n,
        settled_peak_n,
        mean_n,
        window_peak_n,
        static_n,
        contact_share: touched / count,
        friction_at_peak,
        peak_beyond_friction_n,
        static_friction_bound_n,
    }
}

/// [`contact_metrics`] of every contact of `run` over `window`, each recorded in `summary` under
/// its label: `<label>_first_touch_s`, `_peak_force_n`, `_settled_peak_force_n`,
/// `_mean_force_n`, `_contact_share` and `_force_limited_share` (of the reference with the same
/// index).
pub fn labelled_contact_metrics(summary: &mut Summary, run: &ToolRun, window: (f64, f64)) -> Vec<ContactMetrics> {
    let mut all = Vec::new();
    for (i, c) in run.contacts.iter().enumerate() {
        let m = contact_metrics(&run.samples, i, window);
        summary
            .metric(&format!("{}_first_touch_s", c.label), m.first_touch_s)
            .metric(&format!("{}_peak_force_n", c.label), m.peak_n)
            .metric(&format!("{}_settled_peak_force_n", c.label), m.settled_peak_n)
            .metric(&format!("{}_mean_force_n", c.label), m.mean_n)
            .metric(&format!("{}_contact_share", c.label), m.contact_share)
            .metric(&format!("{}_force_limited_share", c.label), limited_share(&run.samples, i, window));
        all.push(m);
    }
    all
}

/// The force claims of a Table 7.1 tool on the largest values over its contacts, without any
/// tolerance on the ideal plant: the contact force never exceeds `limit` over the whole run
/// (approach, pressing, motion, retreat: `run_peak_force_n`); the static force (reference at
/// rest behind the surface) is within the limit and at least 80 % of it (the limit, not the
/// spring, sets it); the mean during the motion is within the limit. The largest force during
/// the motion is reported as `motion_peak_force_n`.
///
/// On the realistic plant the first two bounds widen by the joint friction's bound `B_f`
/// ([`wbc::friction_contact_shares`], from the plant's friction magnitudes at each cycle's
/// velocities): what the controller bounds is the force it commands (Table 7.1 limits the
/// Cartesian impedance's force, Sec. 7.3), and friction the torque sensors do not see can add
/// or hold back up to `B_f` of it (README `--plant`). So `F − B_f ≤ limit` at every cycle
/// (`run_peak_beyond_friction_n`) and the static force in `[0.8 limit − B_f, limit + B_f]`
/// with `B_f` its mean over the static part.
pub fn force_claims(summary: &mut Summary, metrics: &[ContactMetrics], limit: f64, plant: PlantKind) {
    let static_n = metrics.iter().map(|m| m.static_n).fold(0.0, f64::max);
    let static_min = metrics.iter().map(|m| m.static_n).fold(f64::INFINITY, f64::min);
    let motion_n = metrics.iter().map(|m| m.window_peak_n).fold(0.0, f64::max);
    let run_n = metrics.iter().map(|m| m.peak_n).fold(0.0, f64::max);
    let mean_n = metrics.iter().map(|m| m.mean_n).fold(0.0, f64::max);
    summary
        .metric("static_force_n", static_n)
        .metric("motion_peak_force_n", motion_n)
        .metric("run_peak_force_n", run_n)
        .metric("motion_mean_force_n", mean_n);
    match plant {
        PlantKind::Ideal => {
            summary.claim(
                &format!("the contact force never exceeds the Table 7.1 limit: largest over the whole run {run_n:.2} N ≤ {limit} N (during the motion {motion_n:.2} N)"),
                run_n <= limit,
            );
            summary.claim(
                &format!(
                    "static contact force (reference at rest behind the surface, last {STATIC_S} s before the motion) within the Table 7.1 limit: {static_min:.2}…{static_n:.2} N ≤ {limit} N, and ≥ 80 % of it (the limit, not the spring, sets it)"
                ),
                static_n <= limit && static_min >= 0.8 * limit,
            );
        }
        PlantKind::Realistic => friction_widened_claims(summary, metrics, limit),
    }
    summary.claim(
        &format!("mean contact force during the motion within the limit: {mean_n:.2} N ≤ {limit} N"),
        mean_n <= limit,
    );
}

/// The run-peak and static claims of [`force_claims`] on the realistic plant.
fn friction_widened_claims(summary: &mut Summary, metrics: &[ContactMetrics], limit: f64) {
    let beyond = metrics.iter().map(|m| m.peak_beyond_friction_n).fold(0.0, f64::max);
    let Some(peak) = metrics.iter().copied().max_by(|a, b| a.peak_n.total_cmp(&b.peak_n)) else { return };
    summary
        .metric("run_peak_beyond_friction_n", beyond)
        .metric("friction_bound_at_run_peak_n", peak.friction_at_peak.bound_n)
        .metric("friction_share_at_run_peak_n", peak.friction_at_peak.share_n);
    summary.claim(
        &format!(
            "the contact force never exceeds the Table 7.1 limit plus the joint friction's bound B_f of its cycle: largest F − B_f over the whole run {beyond:.2} N ≤ {limit} N (peak {:.2} N with B_f {:.2} N, the friction's own share {:.2} N)",
            peak.peak_n, peak.friction_at_peak.bound_n, peak.friction_at_peak.share_n
        ),
        beyond <= limit,
    );
    let within = metrics.iter().all(|m| {
        m.static_n <= limit + m.static_friction_bound_n && m.static_n >= 0.8 * limit - m.static_friction_bound_n
    });
    let bands: Vec<String> = metrics
        .iter()
        .map(|m| {
            let b = m.static_friction_bound_n;
            format!("{:.2} N in [{:.2}, {:.2}] N", m.static_n, 0.8 * limit - b, limit + b)
        })
        .collect();
    summary.claim(
        &format!(
            "static contact force (reference at rest behind the surface, last {STATIC_S} s before the motion) within 80…100 % of the Table 7.1 limit widened by the friction bound B_f: {}",
            bands.join(", ")
        ),
        within,
    );
}

/// Share of the samples in `window` with reference `index`'s force limit active.
pub fn limited_share(samples: &[ToolSample], index: usize, window: (f64, f64)) -> f64 {
    let inside: Vec<bool> = samples
        .iter()
        .filter(|s| s.t >= window.0 && s.t <= window.1)
        .map(|s| s.limited.get(index).copied().unwrap_or(false))
        .collect();
    #[allow(clippy::cast_precision_loss, reason = "a few thousand samples")]
    let share = inside.iter().filter(|l| **l).count() as f64 / inside.len().max(1) as f64;
    share
}

/// Range (max − min) of the measured TCP position of reference `index` along `direction`
/// over `window`.
pub fn measured_range(samples: &[ToolSample], index: usize, direction: &Vector3<f64>, window: (f64, f64)) -> f64 {
    let values: Vec<f64> = samples
        .iter()
        .filter(|s| s.t >= window.0 && s.t <= window.1)
        .filter_map(|s| s.measured.get(index).map(|p| p.dot(direction)))
        .collect();
    values.iter().copied().fold(f64::NEG_INFINITY, f64::max) - values.iter().copied().fold(f64::INFINITY, f64::min)
}

/// Largest base displacement from the start (m, planar).
pub fn base_travel(samples: &[ToolSample]) -> f64 {
    let Some(first) = samples.first() else { return 0.0 };
    samples.iter().map(|s| (s.base[0] - first.base[0]).hypot(s.base[1] - first.base[1])).fold(0.0, f64::max)
}

/// Figures: contact force vs limit per contact; TCP commanded vs measured per reference
/// (components along `axes`, labelled), as Fig. 7.2–7.4.
pub fn tool_figures(
    name: &str,
    run: &ToolRun,
    limit_n: f64,
    axes: &[(&str, Vector3<f64>)],
    spans: &[Span],
) -> Vec<(&'static str, Figure)> {
    let force_panels = run
        .contacts
        .iter()
        .enumerate()
        .map(|(i, c)| Panel {
            title: format!("normal contact force on {} ({} TCP)", c.label, c.hand.name()),
            y_label: "force (N)".into(),
            lines: vec![
                Line::new(
                    "simulated contact force",
                    run.samples.iter().map(|s| (s.t, s.normal_n.get(i).copied().unwrap_or(f64::NAN))).collect(),
                ),
                Line::dashed(
                    format!("Table 7.1 limit {limit_n} N"),
                    run.samples.iter().map(|s| (s.t, limit_n)).collect(),
                ),
            ],
            spans: spans.to_vec(),
        })
        .collect();
    let mut tcp_panels = Vec::new();
    for (i, r) in run.references.iter().enumerate() {
        for (label, axis) in axes {
            let mut lines = vec![
                Line::new(
                    "measured",
                    run.samples.iter().filter_map(|s| s.measured.get(i).map(|p| (s.t, p.dot(axis)))).collect(),
                ),
                Line::dashed(
                    "commanded",
                    run.samples.iter().filter_map(|s| s.reference.get(i).map(|p| (s.t, p.dot(axis)))).collect(),
                ),
            ];
            lines.extend(surface_lines(run, r.hand, axis));
            tcp_panels.push(Panel {
                title: format!("{} TCP, {label}", r.hand.name()),
                y_label: "position (m)".into(),
                lines,
                spans: spans.to_vec(),
            });
        }
    }
    vec![
        (
            "contact_force.svg",
            Figure {
                title: format!("{name}: contact force vs Table 7.1 limit"),
                x_label: "time (s)".into(),
                panels: force_panels,
            },
        ),
        (
            "tcp.svg",
            Figure {
                title: format!("{name}: TCP commanded vs measured (cf. Fig. 7.2–7.4)"),
                x_label: "time (s)".into(),
                panels: tcp_panels,
            },
        ),
    ]
}

/// The contact surfaces of `hand` whose normal is along `axis`, as lines at their position along
/// it over the run.
fn surface_lines<'a>(run: &'a ToolRun, hand: ArmId, axis: &'a Vector3<f64>) -> impl Iterator<Item = Line> + 'a {
    let span = [run.samples.first(), run.samples.last()];
    run.contacts.iter().filter(move |c| c.hand == hand && c.surface.normal.dot(axis).abs() > 0.99).map(move |c| {
        let at = c.surface.point.dot(axis);
        Line::new(format!("{} (contact surface)", c.label), span.iter().flatten().map(|s| (s.t, at)).collect())
    })
}

/// The window run.
pub fn run(options: &RunOptions) -> Result<ToolRun, String> {
    let changes = ConfigChanges::NONE;
    run_tool(NAME, &WIPE_WINDOW, &PLATFORM_IMPEDANCE, &justin::home_configuration(), changes, DURATION_S, plan, options)
}

fn plan(start: [Placement<f64>; 2]) -> ToolPlan {
    let [right, _] = start;
    let p0 = right.translation.vector;
    let window_x = p0.x + WINDOW_GAP_M;
    let tool = tool_orientation(&right.rotation, 0, &Vector3::x());
    let reference_x = window_x + BEHIND_M;
    let pressed = Vector3::new(reference_x, p0.y, p0.z);
    let touch = Vector3::new(window_x, p0.y, p0.z);
    let mut points = press_path(p0, touch, pressed, &Vector3::x(), (1.5, TOUCH_S - 0.5, TOUCH_S, STROKES_S.0 - HOLD_S));
    points.push((STROKES_S.0, pressed));
    #[allow(clippy::cast_precision_loss, reason = "a handful of strokes")]
    let stroke_s = (STROKES_S.1 - STROKES_S.0) / STROKES as f64;
    for k in 0..STROKES {
        #[allow(clippy::cast_precision_loss, reason = "a handful of strokes")]
        let kf = k as f64;
        let z = p0.z - STROKE_STEP_M * kf;
        let side = if k % 2 == 0 { 1.0 } else { -1.0 };
        let t0 = STROKES_S.0 + stroke_s * kf;
        points.push((t0 + 0.5 * stroke_s, Vector3::new(reference_x, p0.y + side * STROKE_HALF_WIDTH_M, z)));
        points.push((t0 + stroke_s, Vector3::new(reference_x, p0.y, z - 0.5 * STROKE_STEP_M)));
    }
    points.push((DURATION_S - 0.5, Vector3::new(p0.x, p0.y, p0.z)));
    let window = Surface {
        frame: justin::RIGHT_TCP,
        point: Vector3::new(window_x, p0.y, p0.z),
        normal: Unit::new_normalize(-Vector3::x()),
        stiffness_n_m: WINDOW_STIFFNESS_N_M,
        damping_ns_m: WINDOW_DAMPING_NS_M,
        friction: WINDOW_FRICTION,
    };
    ToolPlan {
        references: vec![ToolReference {
            hand: ArmId::RIGHT,
            start: right.rotation,
            tool,
            turn_s: (1.5, STROKES_S.0 - HOLD_S),
            path: Waypoints(points),
            circles: None,
        }],
        contacts: vec![Contact { label: "window", hand: ArmId::RIGHT, surface: window }],
        cartesian: None,
    }
}

/// The phases the replay names: tool switch, approach, pressing, strokes, retreat.
pub fn phases() -> Vec<(f64, String)> {
    vec![
        (0.0, "the planner switches to the tool: Table 7.1 stiffness, +10 N limit, its hierarchy".into()),
        (1.5, format!("the right hand approaches the window, the last {:.0} cm slowly", CLEARANCE_M * 100.0)),
        (TOUCH_S, format!("the hand touches; its reference moves {:.0} cm behind the window", BEHIND_M * 100.0)),
        (STROKES_S.0, format!("{STROKES} horizontal strokes on the window, pressing at most 10 N")),
        (STROKES_S.1, "the strokes end; the hand retracts".into()),
    ]
}

/// Simulates and checks the claims (module docs).
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    let run = run(options)?;
    let limit = WIPE_WINDOW.force_upper[0];
    let m = contact_metrics(&run.samples, 0, STROKES_S);
    let limited = limited_share(&run.samples, 0, STROKES_S);
    let stroke_range = measured_range(&run.samples, 0, &Vector3::y(), STROKES_S);
    let travel = base_travel(&run.samples);
    let mut summary = run.summary.clone();
    summary
        .metric("first_touch_s", m.first_touch_s)
        .metric("settled_peak_contact_force_n", m.settled_peak_n)
        .metric("mean_contact_force_strokes_n", m.mean_n)
        .metric("contact_share_strokes", m.contact_share)
        .metric("force_limited_share_strokes", limited)
        .metric("stroke_range_y_m", stroke_range)
        .metric("base_travel_m", travel)
        .metric("min_self_collision_distance_m", run.min_distance_m)
        .value("faulty_cycles", run.faulty_cycles);
    force_claims(&mut summary, &[m], limit, options.plant);
    summary.claim(
        &format!(
            "contact maintained during the strokes: touched in {:.1} % of the cycles, mean force {:.2} N",
            m.contact_share * 100.0,
            m.mean_n
        ),
        m.contact_share > 0.99 && m.mean_n > 0.5 * limit,
    );
    summary.claim(
        &format!(
            "the +10 N force limit is what bounds the pressing: active in {:.0} % of the stroke cycles",
            limited * 100.0
        ),
        limited > 0.5,
    );
    summary.claim(
        &format!(
            "strokes executed in the window plane: measured lateral range {:.3} m of the commanded {:.3} m",
            stroke_range,
            2.0 * STROKE_HALF_WIDTH_M
        ),
        stroke_range > 0.8 * 2.0 * STROKE_HALF_WIDTH_M,
    );
    summary.claim(
        &format!(
            "no fault, no self-collision: {} faulty cycles, smallest distance {:.3} m",
            run.faulty_cycles, run.min_distance_m
        ),
        run.faulty_cycles == 0 && run.min_distance_m > 0.0,
    );
    summary.claim("no NaN or infinite value", run.finite);
    let spans = [Span { label: "strokes".into(), from: STROKES_S.0, to: STROKES_S.1 }];
    let figures = tool_figures(
        NAME,
        &run,
        limit,
        &[("x (window normal)", Vector3::x()), ("y (stroke)", Vector3::y()), ("z", Vector3::z())],
        &spans,
    );
    Ok(Outcome { summary, series: run.series, figures })
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "test code: failures should panic")]
mod tests {
    use super::*;

    #[test]
    fn quintic_and_waypoints_are_smooth() {
        assert_eq!(quintic(0.0), (0.0, 0.0));
        assert_eq!(quintic(1.0), (1.0, 0.0));
        assert!((quintic(0.5).0 - 0.5).abs() < 1e-12);
        let path = Waypoints(vec![(0.0, Vector3::zeros()), (1.0, Vector3::x())]);
        assert!((path.at(0.5).0.x - 0.5).abs() < 1e-12);
        assert_eq!(path.at(2.0).0, Vector3::x());
        let start = Rotation3::from_euler_angles(0.3, -0.2, 1.0);
        let tool = tool_orientation(&start, 0, &Vector3::x());
        assert!((tool.matrix().column(0) - Vector3::x()).norm() < 1e-12);
    }

    /// The plan's clock runs with the run until the gate, stands while the contact is missing,
    /// then runs on shifted by the wait; without the contact it gives up after the timeout.
    #[test]
    fn plan_clock_waits_at_the_gate_until_the_contact_or_the_timeout() {
        let gate = ContactGate { at_s: 1.0, timeout_s: 0.5, touched: |_| false };
        let mut clock = PlanClock { gate: Some(gate), waited_s: 0.0, released: None };
        assert_eq!(clock.plan_time(0.5, false), 0.5);
        assert_eq!(clock.plan_time(1.0, false), 1.0);
        assert_eq!(clock.plan_time(1.2, false), 1.0);
        // The contact: the clock runs on from where it stood, one cycle later.
        assert!((clock.plan_time(1.3, true) - 1.1).abs() < 1e-12);
        assert!((clock.plan_time(2.0, false) - 1.8).abs() < 1e-12, "released: no further wait");
        let record = clock.record().unwrap();
        assert!(record.touched && (record.waited_s - 0.2).abs() < 1e-12, "{record:?}");
        let mut clock = PlanClock { gate: Some(gate), waited_s: 0.0, released: None };
        for t in [1.0, 1.2, 1.4, 1.5, 1.6] {
            clock.plan_time(t, false);
        }
        assert_eq!(clock.record(), Some(GateRecord { waited_s: 0.5, touched: false }));
        assert!((clock.plan_time(2.0, false) - 1.5).abs() < 1e-12);
    }

    /// Samples of one contact at `t = 0, 0.1, …` with the normal forces `forces` and the
    /// friction bounds `bounds`.
    fn samples(forces: &[f64], bounds: &[f64]) -> Vec<ToolSample> {
        forces
            .iter()
            .zip(bounds.iter())
            .enumerate()
            .map(|(k, (f, b))| ToolSample {
                t: 0.1 * k as f64,
                normal_n: vec![*f],
                depth_m: vec![0.0],
                friction: vec![wbc::FrictionShare { share_n: 0.5 * b, bound_n: *b }],
                reference: Vec::new(),
                measured: Vec::new(),
                limited: Vec::new(),
                estimate: Vec::new(),
                correction: Vec::new(),
                error: Vec::new(),
                base: [0.0; 3],
            })
            .collect()
    }

    /// On the realistic plant a force above the limit passes where the friction bound of its
    /// own cycle covers the excess, and fails where it does not (a larger bound in another
    /// cycle does not count); the static force is checked against its widened band.
    #[test]
    fn realistic_force_claims_subtract_the_friction_bound_of_each_cycle() {
        let claims = |forces: &[f64], bounds: &[f64]| {
            let m = contact_metrics(&samples(forces, bounds), 0, (0.45, 0.6));
            let mut summary = Summary::new("test");
            force_claims(&mut summary, &[m], 10.0, PlantKind::Realistic);
            (m, summary.failed_claims().len())
        };
        // Static part [0.15, 0.45): 6 N with bounds 3 N → band [5, 13] N.
        let (m, failed) = claims(&[0.0, 2.0, 6.0, 6.0, 6.0, 9.0, 13.0], &[0.0, 1.0, 3.0, 3.0, 3.0, 1.0, 4.0]);
        assert_eq!((m.peak_beyond_friction_n, m.friction_at_peak.bound_n, m.static_friction_bound_n), (9.0, 4.0, 3.0));
        assert_eq!(failed, 0);
        // The 13 N peak with a 2 N bound: 11 N beyond it; the 4 N bound elsewhere does not help.
        let (m, failed) = claims(&[0.0, 2.0, 6.0, 6.0, 6.0, 9.0, 13.0], &[0.0, 4.0, 3.0, 3.0, 3.0, 1.0, 2.0]);
        assert_eq!((m.peak_beyond_friction_n, failed), (11.0, 1));
        // Static 4 N below 8 − 3 N.
        let (_, failed) = claims(&[0.0, 2.0, 4.0, 4.0, 4.0, 9.0, 9.0], &[0.0, 1.0, 3.0, 3.0, 3.0, 1.0, 1.0]);
        assert_eq!(failed, 1);
    }

    #[test]
    fn wipe_window_claims_hold() {
        let outcome = simulate(&RunOptions::default()).unwrap();
        let s = &outcome.summary;
        assert!(s.failed_claims().is_empty(), "{:?}", s.failed_claims());
        assert!(s.get("run_peak_force_n").unwrap() <= 10.0, "Table 7.1: +10 N, never exceeded");
        assert!(s.get("static_force_n").unwrap() <= 10.0);
        assert!(s.get("motion_mean_force_n").unwrap() <= 10.0);
        assert!(s.get("contact_share_strokes").unwrap() > 0.99);
    }
}
