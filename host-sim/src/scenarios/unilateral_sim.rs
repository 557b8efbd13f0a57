//! `unilateral_sim`: a unilateral constraint on top of the hierarchy, switched on continuously
//! (Sec. 4.4.3, Figs. 4.11–4.14).
//!
//! # Setup
//! - Robot: the kinematics of [`fixtures::planar::three_dof`] (three 0.5 m links; the thesis
//!   prints no numbers for this arm). "Viscous joint friction is modeled and the masses are
//!   decoupled" (L4327): the simulated plant ([`decoupled_plant`]) has the constant diagonal
//!   inertia `M = 0.5 I kg m²`, no Coriolis terms, no gravity, and viscous joint friction
//!   [`FRICTION`] (low, "to provoke several penetrations of the transition area"). With
//!   `M ∝ I` the static projector (4.72) is also dynamically consistent, so a torque it removes
//!   from the constraint direction cannot accelerate `m_kin` through inertial coupling. (In our
//!   trials with the coupled point-mass inertia of the fixture, the Cartesian torque orthogonal
//!   to `ĵ` kept driving `m_kin` down through `J₁M⁻¹` once the constraint was fully active, and
//!   the arm came close to the singularity, `m_kin ≈ 0.01`.) The
//!   controller evaluates the kinematics on its own [`three_dof`] model and designs the
//!   Cartesian damping with the plant's inertia.
//! - Level 1 (top): manipulator singularity avoidance ([`kernel::tasks::manipulability`]) on the
//!   TCP position Jacobian (2×3), `m_kin = √det(J Jᵀ)`: the potential (3.56) starts at
//!   `ϑ₂ = m₀ = 0.23`; the activation `a(ϑ)`, `ϑ = m_kin`, follows (4.68) with `N'_max = 30`,
//!   hence `ϑ₁ = 0.18` ([`kernel::math::switching::band_start_for_max_slope`]). Gains
//!   [`MSA_STIFFNESS`], [`MSA_DAMPING`] (ours).
//! - Level 2: Cartesian impedance of the TCP position ([`kernel::tasks::cartesian_impedance`],
//!   world x and y, stiffness [`CARTESIAN_STIFFNESS`], damping ratio [`DAMPING_RATIO`]; ours)
//!   along a quintic straight-line reference from the initial TCP to the TCP of the stretched
//!   (singular) configuration [`SINGULAR_CONFIGURATION`] in [`TRAJECTORY_S`].
//! - Control law `τ = τ₁ + N τ₂` with the (1×n) projector (4.72) `N = I − ĵᵀ a ĵ`,
//!   `ĵ = J₁/‖J₁‖` (augmented, `W = I`, the kernel's row recursion), and for comparison the
//!   classical discontinuous projector (4.62): `N = I − ĵᵀĵ` as soon as the constraint is
//!   active (`m_kin < m₀`), `N = I` otherwise.
//! - Start at rest in [`INITIAL_CONFIGURATION`]; 6 s (the time axis of Figs. 4.12–4.14);
//!   1 kHz control, RK4 at 1/6000 s.
//!
//! The arm, the trajectory and the gains are ours (the thesis gives none); they are tuned so that
//! the constraint first activates at about 1.8 s, as in Fig. 4.12, and is penetrated repeatedly.
//!
//! # Claims
//! 1. Continuous projection: no torque jump. At every 1 ms control cycle
//!    `|Δτ| ≤ |Δτ₁| + |Δτ₂| + N'_max |Δϑ| |τ₂| + 2 |Δĵ| |τ₂|` (the (4.69) design bound for the
//!    activation plus the rates of the task torques and of the constraint direction), and the
//!    largest `|Δτ|` is small (below [`SMOOTH_STEP_NM`]).
//! 2. Classical projection: the torque jumps at every switch of the constraint (the number of
//!    switches, their times and the jump sizes are reported): at each switch `|Δτ|` exceeds its
//!    smooth part `|Δτ₁| + |Δτ₂| + 2|Δĵ||τ₂|` (the excess is the switched component `|ĵᵀτ₂|`),
//!    and the largest jump is more than 10 times the largest step of the continuous projection.
//! 3. While the constraint is fully active (`a = 1`), no Cartesian torque passes in the
//!    constraint direction: `|J₁^{+T} τ₂^p| < 1e-9` (Fig. 4.13), and the activation does reach 1.
//! 4. The constraint activates first at about 1.8 s (within ±0.1 s) and is entered repeatedly
//!    (at least two penetrations of the transition band).
//! 5. Final configuration: `ϑ` a little below `ϑ₂` and above `ϑ₁` (steady state in the band,
//!    no full activation at the end).
//!
//! # Time series
//! The continuous run in the standard columns (`q.i`, `dq.i`, `tau.i`, `e1.m` = `m_kin − m₀`,
//! `e2.x`, `e2.y` TCP error to the reference, `a.1` activation of the constraint row), then
//! `theta` (`= m_kin`), `n_des` (`= 1 − a`), `tau1.i`, `tau2.i`, `tau2p.i` (`= N τ₂`),
//! `j1pinv_tau2p` (`J₁^{+T} τ₂^p`, N/m with `m_kin` in m²), `jhat_tau2` (`ĵᵀτ₂`, Nm),
//! `x_des.x`, `x_des.y`, `dtau_nm` (`|τ(k) − τ(k−1)|`), `dtau_smooth_nm` and `dtau_bound_nm`
//! (claim 1); the classical run in the same columns prefixed `discontinuous.`.

use fixtures::planar::{three_dof, Planar3, PLANAR3_TCP};
use kernel::dynamics::forward_kinematics;
use kernel::hierarchy::{project, HierarchyConfig, HierarchyData, Recursion, Shaping, Stack, Weighting};
use kernel::math::switching::band_start_for_max_slope;
use kernel::model::{Data, Inertia, JointDrive, JointKind, ModelBuilder, Placement};
use kernel::tasks::cartesian_impedance::{
    cartesian_impedance, AxisMask, CartesianImpedance, CartesianImpedanceConfig, CartesianTarget, StiffnessFrame,
};
use kernel::tasks::manipulability::{manipulability_avoidance, Manipulability, ManipulabilityConfig};
use kernel::tasks::TaskRows;
use nalgebra::{Matrix3, SVector, Vector3, Vector6};

use super::hierarchy_common::{column, control_cycle, max_abs, points, prefixed, series_with_time};
use super::{joint_columns, Outcome, RunOptions};
use crate::output::{Figure, Line, Panel, Span, Summary, TimeSeries};
use crate::sim::{run_loop, PassiveJoints, SimConfig, Simulator, CONTROL_PERIOD_S};

/// Registry name.
pub const NAME: &str = "unilateral_sim";
/// One-line description.
pub const DESCRIPTION: &str =
    "planar 3-DOF arm, manipulability constraint above a Cartesian impedance (Fig. 4.11-4.14): continuous vs classical projection, 6 s";
/// Simulated time (s).
pub const DURATION_S: f64 = 6.0;
/// `m₀ = ϑ₂`: the constraint starts (Fig. 4.12 caption).
pub const THRESHOLD: f64 = 0.23;
/// `N'_max` of the transition (4.69) (Fig. 4.12).
pub const MAX_SLOPE: f64 = 30.0;
/// Initial configuration (rad); ours.
pub const INITIAL_CONFIGURATION: [f64; 3] = [-0.3, -1.2, -1.0];
/// The stretched configuration whose TCP is the goal (rad); ours.
pub const SINGULAR_CONFIGURATION: [f64; 3] = [-1.3, 0.0, 0.0];
/// Duration of the reference trajectory (s); ours.
pub const TRAJECTORY_S: f64 = 2.2;
/// Translational stiffness of the Cartesian impedance (N/m); ours.
pub const CARTESIAN_STIFFNESS: f64 = 150.0;
/// Damping ratio of the Cartesian impedance; ours (low, see the module docs).
pub const DAMPING_RATIO: f64 = 0.3;
/// `k_msa` of (3.56) (J/m⁴, `m_kin` in m²); ours.
pub const MSA_STIFFNESS: f64 = 30.0;
/// Damping along the constraint row (J s/m⁴); ours.
pub const MSA_DAMPING: f64 = 0.5;
/// Viscous joint friction (Nms/rad); ours.
pub const FRICTION: f64 = 0.1;
/// Upper bound claimed for the largest torque step of the continuous projection (Nm per 1 ms).
pub const SMOOTH_STEP_NM: f64 = 0.1;

type Sim = Simulator<3, 3, 1, 3>;

/// Inertia of every decoupled joint (kg m²); ours.
pub const JOINT_INERTIA: f64 = 0.5;

/// The simulated plant: "the masses are decoupled" (L4327) read as a constant diagonal inertia
/// `M = diag(JOINT_INERTIA)` without Coriolis terms or gravity: three independent rotors about
/// world z (a 2 kg point mass 0.5 m from each axis). The arm's kinematics (TCP, `m_kin`) are
/// those of [`three_dof`], which only the controller evaluates.
pub fn decoupled_plant() -> Result<kernel::Model<f64, 3, 3, 1>, String> {
    let mut builder = ModelBuilder::<f64, 3, 3, 1>::new(Vector3::zeros());
    let radius = 0.5;
    for k in 0..3 {
        builder
            .add_body(
                None,
                Placement::identity(),
                JointKind::Revolute { axis: Vector3::z_axis() },
                JointDrive::actuated(k),
                Inertia::point_mass(JOINT_INERTIA / (radius * radius), Vector3::new(radius, 0.0, 0.0)),
            )
            .map_err(|e| e.to_string())?;
    }
    builder.try_build().map_err(|e| e.to_string())
}

/// Which projection a run uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Projection {
    /// Transition shaping (4.65)–(4.72).
    Continuous,
    /// Classical (4.62).
    Discontinuous,
}

impl Projection {
    fn shaping(self) -> Shaping<f64> {
        match self {
            // The band on the projected-row norm ratio only matters for dependent rows; the
            // constraint row is alone on its level (ratio 1).
            Self::Continuous => Shaping::Continuous { singular_full: 0.02, singular_start: 0.05 },
            Self::Discontinuous => Shaping::Discontinuous { singular_threshold: 1e-6 },
        }
    }
}

fn signal_columns() -> Vec<String> {
    let mut names = joint_columns(&["1", "2", "3"]);
    names.extend(["e1.m", "e2.x", "e2.y", "a.1", "theta", "n_des"].map(String::from));
    for prefix in ["tau1", "tau2", "tau2p"] {
        names.extend((1..=3).map(|k| format!("{prefix}.{k}")));
    }
    names.extend(
        ["j1pinv_tau2p", "jhat_tau2", "x_des.x", "x_des.y", "dtau_nm", "dtau_smooth_nm", "dtau_bound_nm"]
            .map(String::from),
    );
    names
}

/// Quintic straight-line reference: position and velocity at `t`.
fn reference(t: f64, from: &Vector3<f64>, to: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let s = (t / TRAJECTORY_S).clamp(0.0, 1.0);
    let shape = s * s * s * (10.0 - 15.0 * s + 6.0 * s * s);
    let rate = if t < TRAJECTORY_S { 30.0 * s * s * (1.0 - s) * (1.0 - s) / TRAJECTORY_S } else { 0.0 };
    (from + (to - from) * shape, (to - from) * rate)
}

struct Controller {
    model: Planar3<f64>,
    data: Data<f64, 3, 3, 4>,
    constraint: Manipulability<f64, 3>,
    cartesian: CartesianImpedance<f64>,
    from: Vector3<f64>,
    to: Vector3<f64>,
    projection: Projection,
    hierarchy: HierarchyData<f64, 3, 3, 2>,
}

/// What one control step produced.
#[derive(Clone, Copy)]
struct Step {
    tau: SVector<f64, 3>,
    tau1: SVector<f64, 3>,
    tau2: SVector<f64, 3>,
    tau2p: SVector<f64, 3>,
    direction: SVector<f64, 3>,
    theta: f64,
    activation: f64,
    constraint_force: f64,
    error: Vector6<f64>,
    desired: Vector3<f64>,
}

impl Controller {
    fn step(&mut self, t: f64, q: &SVector<f64, 3>, v: &SVector<f64, 3>) -> Result<Step, String> {
        let err = |e: &dyn std::fmt::Display| e.to_string();
        forward_kinematics(&self.model, &mut self.data, q, v).map_err(|e| err(&e))?;
        // The plant's (decoupled) inertia, for the Cartesian damping design.
        self.data.mass_matrix = nalgebra::Matrix3::identity() * JOINT_INERTIA;
        let mut top = TaskRows::<f64, 3, 1>::new();
        let report =
            manipulability_avoidance(&self.model, &self.data, &self.constraint, &mut top).map_err(|e| err(&e))?;
        let (desired, velocity) = reference(t, &self.from, &self.to);
        let target = CartesianTarget {
            pose: Placement::translation(desired.x, desired.y, desired.z),
            linear_velocity: velocity,
            angular_velocity: Vector3::zeros(),
        };
        let mut cartesian = TaskRows::<f64, 3, 2>::new();
        let tracking = cartesian_impedance(&self.model, &self.data, &self.cartesian, &target, &mut cartesian)
            .map_err(|e| err(&e))?;
        let mut stack = Stack::<f64, 3, 3>::new();
        stack.push_rows(0, &top).map_err(|e| err(&e))?;
        stack.push_rows(1, &cartesian).map_err(|e| err(&e))?;
        let config = HierarchyConfig {
            recursion: Recursion::Augmented,
            weighting: Weighting::Identity,
            shaping: self.projection.shaping(),
            diagnose_last_level: true,
        };
        let tau = *project(&config, &stack, &mut self.hierarchy).map_err(|e| err(&e))?;
        let tau1 = top.torque();
        let tau2 = cartesian.torque();
        let tau2p = tau - tau1;
        let row = top.rows().first().ok_or("no constraint row")?;
        let gradient = row.jacobian.transpose();
        let squared = gradient.norm_squared();
        let (direction, constraint_force) = if squared > 0.0 {
            (gradient / squared.sqrt(), gradient.dot(&tau2p) / squared)
        } else {
            (SVector::zeros(), 0.0)
        };
        Ok(Step {
            tau,
            tau1,
            tau2,
            tau2p,
            direction,
            theta: report.manipulability,
            activation: self.hierarchy.rows.first().map_or(0.0, |r| r.activation),
            constraint_force,
            error: tracking.error,
            desired,
        })
    }
}

/// One simulated projection.
pub struct Run {
    /// The projection.
    pub projection: Projection,
    /// `t` and the signals.
    pub series: TimeSeries,
}

fn tcp_of(q: [f64; 3]) -> Vector3<f64> {
    let (x, y) = fixtures::planar::tcp_position(&SVector::<f64, 3>::from(q));
    Vector3::new(x, y, 0.0)
}

/// `ϑ₁` of the band: `ϑ₂ − 1.5 / N'_max` (Table 4.4).
pub fn full_activation() -> f64 {
    band_start_for_max_slope(THRESHOLD, MAX_SLOPE).unwrap_or(THRESHOLD)
}

/// Simulates one projection for `duration_s`.
pub fn run(projection: Projection, duration_s: f64, options: &RunOptions) -> Result<Run, String> {
    let mut model = three_dof::<f64>().map_err(|e| format!("planar model: {e}"))?;
    model.gravity = Vector3::zeros();
    let mut sim: Sim = options.simulator(decoupled_plant()?, SimConfig::default())?;
    sim.set_passive_joints(PassiveJoints { damping: SVector::repeat(FRICTION), ..PassiveJoints::none() })
        .map_err(|e| e.to_string())?;
    sim.set_state(SVector::from(INITIAL_CONFIGURATION), SVector::zeros()).map_err(|e| e.to_string())?;
    let constraint = Manipulability::try_new(ManipulabilityConfig {
        frame: PLANAR3_TCP,
        rows: AxisMask::new([true, true, false, false, false, false]),
        coordinates: [true; 3],
        threshold: THRESHOLD,
        full_activation: full_activation(),
        stiffness: MSA_STIFFNESS,
        damping: MSA_DAMPING,
    })
    .map_err(|e| e.to_string())?;
    let cartesian = CartesianImpedance::try_new(CartesianImpedanceConfig {
        frame: PLANAR3_TCP,
        axes: AxisMask::new([true, true, false, false, false, false]),
        stiffness_frame: StiffnessFrame::World,
        translational_stiffness: Matrix3::identity() * CARTESIAN_STIFFNESS,
        rotational_stiffness: Matrix3::zeros(),
        damping_ratio: DAMPING_RATIO,
        force_lower: Vector6::repeat(f64::NEG_INFINITY),
        force_upper: Vector6::repeat(f64::INFINITY),
        fallback_damping: Vector6::repeat(5.0),
    })
    .map_err(|e| e.to_string())?;
    let mut controller = Controller {
        data: Data::new(&model),
        model,
        constraint,
        cartesian,
        from: tcp_of(INITIAL_CONFIGURATION),
        to: tcp_of(SINGULAR_CONFIGURATION),
        projection,
        hierarchy: HierarchyData::default(),
    };
    let mut series = series_with_time(signal_columns());
    let mut previous: Option<Step> = None;
    run_loop(&mut sim, duration_s, CONTROL_PERIOD_S, |sim, info| -> Result<(), String> {
        let row = control_cycle(sim, info.time_s, |q, v| {
            let step = controller.step(info.time_s, q, v)?;
            let signals = signals(&step, previous.as_ref());
            previous = Some(step);
            Ok((step.tau, signals))
        })?;
        series.push(row)
    })?;
    Ok(Run { projection, series })
}

/// The row's signals of `step` after `previous` (columns of [`signal_columns`] after the joints).
fn signals(step: &Step, previous: Option<&Step>) -> Vec<f64> {
    // |Δτ| ≤ |Δτ₁| + |Δτ₂| + 2|Δĵ||τ₂| (smooth part) + N'max|Δϑ||τ₂| (activation), from
    // τ = τ₁ + (I − a ĵĵᵀ)τ₂ with |∂a/∂ϑ| ≤ N'max, ‖I − a ĵĵᵀ‖ ≤ 1.
    let (dtau, smooth, bound) = previous.map_or((0.0, 0.0, 0.0), |p| {
        let turn = (step.direction - p.direction).norm().min((step.direction + p.direction).norm());
        let tau2 = p.tau2.norm();
        let smooth = (step.tau1 - p.tau1).norm() + (step.tau2 - p.tau2).norm() + 2.0 * turn * tau2;
        ((step.tau - p.tau).norm(), smooth, smooth + MAX_SLOPE * (step.theta - p.theta).abs() * tau2)
    });
    let mut row =
        vec![step.theta - THRESHOLD, step.error.x, step.error.y, step.activation, step.theta, 1.0 - step.activation];
    row.extend(step.tau1.iter().chain(step.tau2.iter()).chain(step.tau2p.iter()));
    row.extend([
        step.constraint_force,
        step.direction.dot(&step.tau2),
        step.desired.x,
        step.desired.y,
        dtau,
        smooth,
        bound,
    ]);
    row
}

/// Runs the scenario with the full duration.
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    simulate_for(DURATION_S, options)
}

/// Runs both projections for `duration_s` and evaluates the claims.
pub fn simulate_for(duration_s: f64, options: &RunOptions) -> Result<Outcome, String> {
    options.progress.report(NAME, 0.0, duration_s);
    let continuous = run(Projection::Continuous, duration_s, options)?;
    options.progress.report(NAME, 0.5 * duration_s, duration_s);
    let classical = run(Projection::Discontinuous, duration_s, options)?;
    options.progress.finish();
    let summary = summarize(&continuous, &classical, duration_s)?;
    let series = combine(&continuous, &classical)?;
    let figures = figures(&continuous, &classical)?;
    Ok(Outcome { summary, series, figures })
}

/// Entries of the activation into the band (`a` rising from 0) and switches of a run.
struct Events {
    /// Times at which `a` leaves 0 (the constraint starts acting).
    entries: Vec<f64>,
    /// Times at which `a` changes between 0 and non-zero (either direction).
    switches: Vec<f64>,
    /// `|Δτ|` at each switch (Nm).
    switch_steps: Vec<f64>,
    /// `|Δτ|` minus its smooth part `|Δτ₁| + |Δτ₂| + 2|Δĵ||τ₂|` at each switch (Nm): the jump.
    switch_excess: Vec<f64>,
}

fn events(series: &TimeSeries) -> Result<Events, String> {
    let (t, a) = (column(series, "t")?, column(series, "a.1")?);
    let (dtau, smooth) = (column(series, "dtau_nm")?, column(series, "dtau_smooth_nm")?);
    let mut out = Events { entries: vec![], switches: vec![], switch_steps: vec![], switch_excess: vec![] };
    for k in 1..t.len() {
        let (before, now) = (a.get(k - 1).copied().unwrap_or(0.0), a.get(k).copied().unwrap_or(0.0));
        let time = t.get(k).copied().unwrap_or(f64::NAN);
        if before == 0.0 && now > 0.0 {
            out.entries.push(time);
        }
        if (before == 0.0) != (now == 0.0) {
            let step = dtau.get(k).copied().unwrap_or(f64::NAN);
            out.switches.push(time);
            out.switch_steps.push(step);
            out.switch_excess.push(step - smooth.get(k).copied().unwrap_or(f64::NAN));
        }
    }
    Ok(out)
}

fn list(values: &[f64], digits: usize) -> String {
    values.iter().map(|x| format!("{x:.digits$}")).collect::<Vec<_>>().join(",")
}

fn summarize(continuous: &Run, classical: &Run, duration_s: f64) -> Result<Summary, String> {
    let mut summary = Summary::new(NAME);
    let full = full_activation();
    summary
        .metric("duration_s", duration_s)
        .metric("theta2_threshold", THRESHOLD)
        .metric("theta1_full_activation", full)
        .metric("max_slope", MAX_SLOPE);
    let series = &continuous.series;
    let (t, a, theta) = (column(series, "t")?, column(series, "a.1")?, column(series, "theta")?);
    let (dtau, bound) = (column(series, "dtau_nm")?, column(series, "dtau_bound_nm")?);
    let max_step = max_abs(&dtau);
    let violations = dtau.iter().zip(&bound).filter(|(d, b)| **d > **b + 1e-12).count();
    let worst_ratio = dtau.iter().zip(&bound).filter(|(_, b)| **b > 1e-9).map(|(d, b)| d / b).fold(0.0_f64, f64::max);
    summary
        .metric("max_dtau_per_cycle_nm_continuous", max_step)
        .metric("max_dtau_over_bound_continuous", worst_ratio)
        .value("bound_violations_continuous", violations);
    summary.claim(
        &format!("continuous projection: |dtau| per 1 ms cycle within the (4.69)-type bound at every cycle (max ratio {worst_ratio:.2}), largest step {max_step:.4} Nm < {SMOOTH_STEP_NM} Nm"),
        violations == 0 && max_step < SMOOTH_STEP_NM,
    );

    let jumps = events(&classical.series)?;
    let largest_jump = max_abs(&jumps.switch_steps);
    let smallest_excess = jumps.switch_excess.iter().copied().fold(f64::INFINITY, f64::min);
    summary
        .value("jumps_discontinuous", jumps.switches.len())
        .value("jump_times_s_discontinuous", list(&jumps.switches, 3))
        .value("jump_sizes_nm_discontinuous", list(&jumps.switch_steps, 3))
        .metric("max_jump_nm_discontinuous", largest_jump)
        .metric("min_jump_excess_nm_discontinuous", smallest_excess)
        .metric("max_dtau_per_cycle_nm_discontinuous", max_abs(&column(&classical.series, "dtau_nm")?));
    summary.claim(
        &format!(
            "classical projection: the torque jumps at each of its {} switches (t = {} s; |dtau| = {} Nm, each above its smooth part |dtau1| + |dtau2| + 2|djhat||tau2|), the largest {largest_jump:.2} Nm = {:.0}x the largest continuous step",
            jumps.switches.len(),
            list(&jumps.switches, 2),
            list(&jumps.switch_steps, 2),
            largest_jump / max_step
        ),
        jumps.switches.len() >= 2 && smallest_excess > 0.0 && largest_jump > 10.0 * max_step,
    );

    let force = column(series, "j1pinv_tau2p")?;
    let locked: Vec<f64> = a.iter().zip(&force).filter(|(a, _)| **a >= 1.0).map(|(_, f)| *f).collect();
    let leaked = max_abs(&locked);
    let free = max_abs(&force);
    #[allow(clippy::cast_precision_loss, reason = "a few thousand samples")]
    let locked_time = locked.len() as f64 * CONTROL_PERIOD_S;
    summary
        .metric("fully_active_time_s", locked_time)
        .metric("max_abs_j1pinv_tau2p_fully_active", leaked)
        .metric("max_abs_j1pinv_tau2p", free);
    summary.claim(
        &format!("no Cartesian torque in the constraint direction while fully active ({locked_time:.3} s with a = 1): max |J1+T tau2p| = {leaked:.1e} < 1e-9 (elsewhere up to {free:.2})"),
        locked_time > 0.0 && leaked < 1e-9,
    );

    let entries = events(series)?.entries;
    let first = entries.first().copied().unwrap_or(f64::NAN);
    summary
        .metric("first_activation_s", first)
        .value("band_entries_continuous", entries.len())
        .value("band_entry_times_s_continuous", list(&entries, 3));
    summary.claim(
        &format!(
            "the constraint first activates at {first:.3} s (Fig. 4.12: 1.8 s, +-0.1 s) and is entered {} times",
            entries.len()
        ),
        (first - 1.8).abs() <= 0.1 && entries.len() >= 2,
    );

    let final_theta = theta.last().copied().unwrap_or(f64::NAN);
    let final_a = a.last().copied().unwrap_or(f64::NAN);
    let settled_from = t.last().copied().unwrap_or(0.0) - 0.5;
    let late_full = t.iter().zip(&a).any(|(ti, ai)| *ti >= settled_from && *ai >= 1.0);
    summary.metric("final_theta", final_theta).metric("final_activation", final_a);
    summary.claim(
        &format!("final configuration: theta = {final_theta:.4}, a little below theta2 = {THRESHOLD} and above theta1 = {full:.2}, no full activation in the last 0.5 s"),
        final_theta < THRESHOLD && final_theta > full && !late_full,
    );
    Ok(summary)
}

fn combine(continuous: &Run, classical: &Run) -> Result<TimeSeries, String> {
    let names = signal_columns();
    let mut columns = vec!["t".to_owned()];
    columns.extend(names.iter().cloned());
    columns.extend(prefixed("discontinuous.", &names));
    let mut series = TimeSeries::new(columns);
    for (k, first) in continuous.series.rows().iter().enumerate() {
        let mut row = first.clone();
        row.extend(classical.series.rows().get(k).ok_or("runs of different length")?.iter().skip(1));
        series.push(row)?;
    }
    Ok(series)
}

/// Shaded intervals where `a = 1`.
fn full_spans(t: &[f64], a: &[f64]) -> Vec<Span> {
    let mut spans = Vec::new();
    let mut start: Option<f64> = None;
    for (ti, ai) in t.iter().zip(a) {
        match (start, *ai >= 1.0) {
            (None, true) => start = Some(*ti),
            (Some(s), false) => {
                spans.push(Span {
                    label: if spans.is_empty() { "fully active (a = 1)".into() } else { String::new() },
                    from: s,
                    to: *ti,
                });
                start = None;
            }
            _ => {}
        }
    }
    if let (Some(s), Some(end)) = (start, t.last()) {
        spans.push(Span {
            label: if spans.is_empty() { "fully active (a = 1)".into() } else { String::new() },
            from: s,
            to: *end,
        });
    }
    spans
}

fn figures(continuous: &Run, classical: &Run) -> Result<Vec<(&'static str, Figure)>, String> {
    let s = &continuous.series;
    let t = column(s, "t")?;
    let a = column(s, "a.1")?;
    let spans = full_spans(&t, &a);
    let joints = |series: &TimeSeries, prefix: &str| -> Result<Vec<Line>, String> {
        (1..=3)
            .map(|k| Ok(Line::new(format!("joint {k}"), points(&t, &column(series, &format!("{prefix}.{k}"))?))))
            .collect()
    };
    let horizontal = |label: &str, y: f64| Line::dashed(label, vec![(0.0, y), (t.last().copied().unwrap_or(1.0), y)]);
    let fig_4_12 = Figure {
        title: "unilateral_sim: Fig. 4.12, manipulability constraint with N'max = 30 (continuous projection)".into(),
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: "activation variable theta = m_kin".into(),
                y_label: "theta (m^2)".into(),
                lines: vec![
                    Line::new("theta", points(&t, &column(s, "theta")?)),
                    horizontal("theta2 = m0 = 0.23", THRESHOLD),
                    horizontal("theta1 = 0.18", full_activation()),
                ],
                spans: spans.clone(),
            },
            Panel {
                title: "N_des = 1 - a".into(),
                y_label: "N_des".into(),
                lines: vec![Line::new("N_des", points(&t, &column(s, "n_des")?))],
                spans: spans.clone(),
            },
            Panel {
                title: "primary task torque tau1".into(),
                y_label: "tau1 (Nm)".into(),
                lines: joints(s, "tau1")?,
                spans: spans.clone(),
            },
            Panel {
                title: "Cartesian impedance torque tau2".into(),
                y_label: "tau2 (Nm)".into(),
                lines: joints(s, "tau2")?,
                spans: spans.clone(),
            },
            Panel {
                title: "projected torque tau2p = N tau2".into(),
                y_label: "tau2p (Nm)".into(),
                lines: joints(s, "tau2p")?,
                spans: spans.clone(),
            },
        ],
    };
    let fig_4_13 = Figure {
        title: "unilateral_sim: Fig. 4.13, projected Cartesian torque in the constraint space".into(),
        x_label: "time (s)".into(),
        panels: vec![Panel {
            title: "J1+T tau2p (zero while a = 1)".into(),
            y_label: "J1+T tau2p (N/m)".into(),
            lines: vec![Line::new("J1+T tau2p", points(&t, &column(s, "j1pinv_tau2p")?))],
            spans: spans.clone(),
        }],
    };
    let c = &classical.series;
    let fig_4_14 = Figure {
        title: "unilateral_sim: Fig. 4.14, control inputs tau = tau1 + N tau2".into(),
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: "continuous null space projection".into(),
                y_label: "tau (Nm)".into(),
                lines: joints(s, "tau")?,
                spans,
            },
            Panel {
                title: "discontinuous (classical) null space projection".into(),
                y_label: "tau (Nm)".into(),
                lines: joints(c, "tau")?,
                spans: vec![],
            },
            Panel {
                title: "torque step per 1 ms control cycle".into(),
                y_label: "|dtau| (Nm)".into(),
                lines: vec![
                    Line::new("continuous", points(&t, &column(s, "dtau_nm")?)),
                    Line::new("discontinuous", points(&t, &column(c, "dtau_nm")?)),
                ],
                spans: vec![],
            },
        ],
    };
    Ok(vec![("activation.svg", fig_4_12), ("constraint_space.svg", fig_4_13), ("torques.svg", fig_4_14)])
}
