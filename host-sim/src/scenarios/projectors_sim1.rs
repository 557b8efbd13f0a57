//! `projectors_sim1`: simulation #1 of Sec. 4.3.1 — six torque-control null space projections
//! compared on the planar 4-DOF arm (Fig. 4.1, Table 4.1, Table 4.2, Fig. 4.2).
//!
//! # Setup
//! - Robot: [`fixtures::planar::four_dof`] (four 0.5 m links, 1 kg point masses at the link
//!   centres, g = 9.81 m/s² in the plane), simulated by [`Simulator`] (RK4 at 1/6000 s, no
//!   friction), controlled at 1 kHz through the `hal` traits.
//! - Hierarchy (Table 4.1), one [`Stack`] level each:
//!   1. TCP translation in x, `K₁ = 800 N/m`, `D₁ = 60 Ns/m`;
//!   2. TCP translation in y, `K₂ = 800 N/m`, `D₂ = 60 Ns/m`;
//!   3. TCP orientation about z (`Σq`), `K₃ = 150 Nm/rad`, `D₃ = 4 Nms/rad`;
//!   4. joint impedance of all four joints, `K₄ = 100 I Nm/rad`, `D₄ = 4 I Nms/rad`
//!      (Table 4.2, Sim. #1; the level-4 scalars read as multiples of `I`).
//!
//!   Each Cartesian row is `f = −K e − D ė` with the constant damping of Table 4.2 (not a
//!   damping-ratio design) and its exact Jacobian row (world x, world y, `∂Σq/∂q = (1,1,1,1)`).
//! - Control law `τ = g(q) + Σᵢ Nᵢ τᵢ` (4.7), (4.17): exact gravity compensation plus the
//!   projected task torques.
//! - Initial state and goals (the thesis prints none for Ch. 4): the Table 5.4 values for the
//!   same arm (THESIS-NUMBERS §1.4): start at rest at TCP (0.84 m, 0.96 m), `Σq = −1.37 rad`,
//!   `q₁ = 0.40 rad` (elbow branch with `q₃ < 0`), step goals `x = 0.90 m`, `y = 0.80 m`,
//!   `Σq = −1.57 rad` at `t = 0`. The initial errors (−0.06 m, +0.16 m, +0.20 rad) match the
//!   Fig. 4.2 axes. Level-4 goal [`JOINT_GOAL`] `= (0, −1.0, −0.8, 0.2)` rad (our choice): the
//!   joint-error norm starts at 1.08 and its constrained minimum on the self-motion manifold of
//!   the goal is 0.80, the 0.8…1.1 range of the Fig. 4.2 level-4 axis.
//! - Variants (legend of Fig. 4.2, [`VARIANTS`]): successive static (`W = I`), successive
//!   dynamic (`W = M`), augmented static, augmented dynamic (`W = M`), augmented
//!   acceleration-based (`W = I`, (4.38)–(4.42)), no projection. The projection is the classical
//!   one of Sec. 4.1–4.3 (no row comes near an algorithmic singularity here; the smallest
//!   projected-row norm ratio of each run is reported as `min_rho_<variant>`).
//! - Duration [`DURATION_S`] = 3 s, twice the 1.5 s of Fig. 4.2: every variant is in its
//!   steady state after 0.6 s (its errors change by less than 2e-6 after 1.5 s).
//!
//! # Metrics
//! Per variant `v` and level `l = 1…4`: `final_err_<v>_l<l>` (signed error at the end for
//! levels 1–3, in m, m, rad; the Euclidean joint-error norm `‖q − q_des‖` for level 4) and
//! `settle_time_s_<v>_l<l>`: the time after which the level's error stays within 2 % of its
//! largest excursion from its final value ([`SETTLE_FRACTION`]; see
//! [`super::hierarchy_common::settle_time`]). Relative to the final value, because the
//! successive and unprojected variants settle at non-zero errors. `latest_settle_time_s_<v>_l123`
//! is the latest of levels 1–3.
//!
//! # Claims (Fig. 4.2, L3205–L3209)
//! 1. Every augmented variant reaches zero steady-state error on levels 1–3
//!    (`|final_err| < 1e-3`).
//! 2. "The steady state is reached considerably later in case of the static null space
//!    projections" (said of the augmented methods): the latest settling time over levels 1–3 of
//!    the augmented static variant is at least 1.5 times that of each augmented dynamically
//!    consistent one. (The successive pair is reported but not claimed; in this reproduction
//!    the successive static variant is only about 1.2 times slower than the dynamic one.)
//! 3. Successive dynamic: on level 3 the steady-state error is larger than without any
//!    projection.
//! 4. The two augmented dynamically consistent variants (`W = M`, acceleration-based) are the
//!    best (smallest latest settling time over levels 1–3 of all variants with zero
//!    steady-state error), but not identical: their final level-4 error norms differ.
//! 5. (Our explanation of 4.) The augmented static and dynamic (`W = M`) variants end in the
//!    same configuration, the acceleration-based one elsewhere: at the level-4 equilibrium
//!    `N₄τ₄ = 0`, i.e. `τ₄ ∈ range(J_augᵀ)` for any projector `I − J_augᵀ(J_aug^{W+})ᵀ`, but
//!    `M⁻¹τ₄ ∈ range(J_augᵀ)` for `M N^s M⁻¹`.
//!
//! # Time series
//! `timeseries.csv` holds the augmented dynamic (`W = M`) run in the standard columns (`q.i`,
//! `dq.i`, `tau.i`, `e1.x`, `e2.y`, `e3.rz`, `e4.1…4`, `e4.norm`) and every variant's run in
//! the same columns prefixed with `<variant>.` (e.g. `succ_static.e3.rz`).

use fixtures::planar::{four_dof, four_dof_configuration, Planar4, PLANAR4_TCP};
use kernel::dynamics::{crba, forward_kinematics, frame_jacobian, gravity, mass_matrix_cholesky};
use kernel::hierarchy::{project, HierarchyConfig, HierarchyData, Recursion, Shaping, Stack, Weighting};
use kernel::model::Data;
use kernel::tasks::joint_impedance::{joint_impedance, JointImpedance, JointImpedanceConfig, JointTarget};
use kernel::tasks::{TaskRow, TaskRows};
use nalgebra::{RowSVector, SMatrix, SVector};

use super::hierarchy_common::{column, control_cycle, points, prefixed, series_with_time, settle_time};
use super::{joint_columns, Outcome, RunOptions};
use crate::output::{Figure, Line, Panel, Summary, TimeSeries};
use crate::sim::{run_loop, SimConfig, Simulator, CONTROL_PERIOD_S};

/// Registry name.
pub const NAME: &str = "projectors_sim1";
/// One-line description.
pub const DESCRIPTION: &str =
    "planar 4-DOF arm, 4-level hierarchy (Table 4.1/4.2), six null space projections (Fig. 4.2), 3 s";
/// Simulated time (s).
pub const DURATION_S: f64 = 3.0;
/// Settling band: 2 % of the largest excursion from the final value.
pub const SETTLE_FRACTION: f64 = 0.02;
/// "Zero" steady-state error on levels 1–3 (m, m, rad).
pub const ZERO_ERROR: f64 = 1e-3;
/// "Considerably later": the static/dynamic ratio of the latest settling time on levels 1–3.
pub const STATIC_SLOWDOWN: f64 = 1.5;

/// Initial task values (Table 5.4): TCP x (m), TCP y (m), `Σq` (rad), `q₁` (rad).
pub const INITIAL: [f64; 4] = [0.84, 0.96, -1.37, 0.40];
/// Goals of levels 1–3 (Table 5.4): TCP x (m), TCP y (m), `Σq` (rad).
pub const GOAL: [f64; 3] = [0.90, 0.80, -1.57];
/// Level-4 joint goal `q_des` (rad); not in the thesis, see the module docs.
pub const JOINT_GOAL: [f64; 4] = [0.0, -1.0, -0.8, 0.2];
/// Table 4.2, Sim. #1: stiffness of levels 1–4 (N/m, N/m, Nm/rad, Nm/rad).
pub const STIFFNESS: [f64; 4] = [800.0, 800.0, 150.0, 100.0];
/// Table 4.2, Sim. #1: damping of levels 1–4 (Ns/m, Ns/m, Nms/rad, Nms/rad).
pub const DAMPING: [f64; 4] = [60.0, 60.0, 4.0, 4.0];

/// Classical projection (4.62): a row locks fully unless its projected-row norm ratio is below
/// this rank threshold.
const SHAPING: Shaping<f64> = Shaping::Discontinuous { singular_threshold: 1e-6 };

/// How a variant weights its projector.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Consistency {
    /// `W = I`.
    Static,
    /// `W = M(q)`.
    Dynamic,
    /// Acceleration-based `N = M N^s M⁻¹`, `W = I` (4.38)–(4.42).
    Acceleration,
}

/// One compared projection.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Variant {
    /// Short name used in metric and column names.
    pub name: &'static str,
    /// Legend entry (Fig. 4.2).
    pub label: &'static str,
    /// Successive, augmented or none.
    pub recursion: Recursion,
    /// Weighting.
    pub consistency: Consistency,
}

/// The six curves of Fig. 4.2.
pub const VARIANTS: [Variant; 6] = [
    Variant {
        name: "succ_static",
        label: "successive, static, W=I",
        recursion: Recursion::Successive,
        consistency: Consistency::Static,
    },
    Variant {
        name: "succ_dynamic",
        label: "successive, dynamic, W=M",
        recursion: Recursion::Successive,
        consistency: Consistency::Dynamic,
    },
    Variant {
        name: "aug_static",
        label: "augmented, static, W=I",
        recursion: Recursion::Augmented,
        consistency: Consistency::Static,
    },
    Variant {
        name: "aug_dynamic",
        label: "augmented, dynamic, W=M",
        recursion: Recursion::Augmented,
        consistency: Consistency::Dynamic,
    },
    Variant {
        name: "aug_dynamic_accel",
        label: "augmented, dynamic, W=I (accel.-based)",
        recursion: Recursion::Augmented,
        consistency: Consistency::Acceleration,
    },
    Variant {
        name: "none",
        label: "no null space projection",
        recursion: Recursion::Unprojected,
        consistency: Consistency::Static,
    },
];

/// The headline variant written to the standard columns.
const HEADLINE: &str = "aug_dynamic";

type Sim = Simulator<4, 4, 5, 4>;
/// Rows of the stack: x, y, Σq, four joints.
const ROWS: usize = 7;

/// Per-variant signal names (after `t`).
fn signal_columns() -> Vec<String> {
    let mut names = joint_columns(&["1", "2", "3", "4"]);
    names.extend(["e1.x", "e2.y", "e3.rz", "e4.1", "e4.2", "e4.3", "e4.4", "e4.norm"].map(String::from));
    names
}

/// The controller of one variant: the Table 4.1 stack projected and gravity compensated.
struct Controller {
    model: Planar4<f64>,
    data: Data<f64, 4, 4, 5>,
    joints: JointImpedance<f64, 4>,
    target: JointTarget<f64, 4>,
    variant: Variant,
    hierarchy: HierarchyData<f64, 4, ROWS, 4>,
    /// Smallest projected-row norm ratio seen (rows of levels 1–3).
    min_ratio: f64,
}

/// What one control step produced.
struct Step {
    torque: SVector<f64, 4>,
    /// Task errors: e1.x, e2.y, e3.rz and the four joint errors.
    errors: [f64; 7],
}

impl Controller {
    fn new(variant: Variant) -> Result<Self, String> {
        let model = four_dof::<f64>().map_err(|e| format!("planar model: {e}"))?;
        let data = Data::new(&model);
        let joints = JointImpedance::try_new(JointImpedanceConfig {
            selected: [true; 4],
            stiffness: SVector::repeat(STIFFNESS[3]),
            damping: SVector::repeat(DAMPING[3]),
        })
        .map_err(|e| e.to_string())?;
        Ok(Self {
            model,
            data,
            joints,
            target: JointTarget::at_rest(SVector::from(JOINT_GOAL)),
            variant,
            hierarchy: HierarchyData::default(),
            min_ratio: f64::INFINITY,
        })
    }

    fn step(&mut self, q: &SVector<f64, 4>, v: &SVector<f64, 4>) -> Result<Step, String> {
        let err = |e: &dyn std::fmt::Display| e.to_string();
        forward_kinematics(&self.model, &mut self.data, q, v).map_err(|e| err(&e))?;
        crba(&self.model, &mut self.data);
        let factor = mass_matrix_cholesky(&self.data).map_err(|e| err(&e))?;
        let g = *gravity(&self.model, &mut self.data);
        let mut jacobian = SMatrix::<f64, 6, 4>::zeros();
        frame_jacobian(&self.model, &self.data, PLANAR4_TCP, &mut jacobian).map_err(|e| err(&e))?;
        let tcp = self.data.frame_placements.get(PLANAR4_TCP.0).ok_or("no TCP frame")?.translation.vector;

        let row = |axis: usize| -> RowSVector<f64, 4> { jacobian.row(axis).into_owned() };
        let (jx, jy, jz) = (row(0), row(1), row(5));
        let errors_123 = [tcp.x - GOAL[0], tcp.y - GOAL[1], q.sum() - GOAL[2]];
        let mut stack = Stack::<f64, 4, ROWS>::new();
        let gains = STIFFNESS.into_iter().zip(DAMPING);
        for (level, ((j, e), (k, d))) in [jx, jy, jz].into_iter().zip(errors_123).zip(gains).enumerate() {
            let rate = (j * v).x;
            let task = TaskRow { jacobian: j, force: -k * e - d * rate, potential: 0.5 * k * e * e, activation: 1.0 };
            stack.push(level, task).map_err(|e| err(&e))?;
        }
        let mut joint_rows = TaskRows::<f64, 4, 4>::new();
        joint_impedance(&self.joints, q, v, &self.target, None, &mut joint_rows).map_err(|e| err(&e))?;
        stack.push_rows(3, &joint_rows).map_err(|e| err(&e))?;

        let weighting = match self.variant.consistency {
            Consistency::Static => Weighting::Identity,
            Consistency::Dynamic => Weighting::Inertia(&factor),
            Consistency::Acceleration => Weighting::AccelerationBased(&factor),
        };
        let config = HierarchyConfig {
            recursion: self.variant.recursion,
            weighting,
            shaping: SHAPING,
            diagnose_last_level: true,
        };
        let projected = *project(&config, &stack, &mut self.hierarchy).map_err(|e| err(&e))?;
        for diagnostics in self.hierarchy.rows.iter().filter(|r| r.level < 3) {
            self.min_ratio = self.min_ratio.min(diagnostics.projected_norm_ratio);
        }
        let joint_errors = q - self.target.position;
        let [ex, ey, erz] = errors_123;
        let [[e1, e2, e3, e4]] = joint_errors.data.0;
        Ok(Step { torque: g + projected, errors: [ex, ey, erz, e1, e2, e3, e4] })
    }
}

/// One simulated variant.
pub struct VariantRun {
    /// The variant.
    pub variant: Variant,
    /// `t` and the signals of `signal_columns`.
    pub series: TimeSeries,
    /// Smallest projected-row norm ratio of the rows of levels 1–3.
    pub min_ratio: f64,
}

/// The Table 5.4 start configuration.
pub fn initial_configuration() -> Result<SVector<f64, 4>, String> {
    let [x, y, sum, q1] = INITIAL;
    four_dof_configuration(x, y, sum, q1, false).ok_or_else(|| "Table 5.4 start unreachable".to_owned())
}

/// Simulates one variant for `duration_s`.
pub fn run_variant(variant: Variant, duration_s: f64, options: &RunOptions) -> Result<VariantRun, String> {
    let model = four_dof::<f64>().map_err(|e| format!("planar model: {e}"))?;
    let mut sim: Sim = options.simulator(model, SimConfig::default())?;
    sim.set_state(initial_configuration()?, SVector::zeros()).map_err(|e| e.to_string())?;
    let mut controller = Controller::new(variant)?;
    let mut series = series_with_time(signal_columns());
    run_loop(&mut sim, duration_s, CONTROL_PERIOD_S, |sim, info| -> Result<(), String> {
        let row = control_cycle(sim, info.time_s, |q, v| {
            let step = controller.step(q, v)?;
            let norm = step.errors.iter().skip(3).map(|e| e * e).sum::<f64>().sqrt();
            Ok((step.torque, step.errors.into_iter().chain([norm])))
        })?;
        series.push(row)
    })?;
    Ok(VariantRun { variant, series, min_ratio: controller.min_ratio })
}

/// Error column of level `level` (1–4) used for the metrics.
fn level_column(level: usize) -> &'static str {
    match level {
        1 => "e1.x",
        2 => "e2.y",
        3 => "e3.rz",
        _ => "e4.norm",
    }
}

/// Runs the scenario with the full duration.
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    simulate_for(DURATION_S, options)
}

/// Runs all six variants for `duration_s` and evaluates the claims.
pub fn simulate_for(duration_s: f64, options: &RunOptions) -> Result<Outcome, String> {
    let mut runs = Vec::new();
    for (k, variant) in VARIANTS.iter().enumerate() {
        #[allow(clippy::cast_precision_loss, reason = "six variants")]
        options.progress.report(NAME, duration_s * k as f64 / VARIANTS.len() as f64, duration_s);
        runs.push(run_variant(*variant, duration_s, options)?);
    }
    options.progress.finish();
    let summary = summarize(&runs, duration_s)?;
    let series = combine(&runs)?;
    let figures = figures(&runs)?;
    Ok(Outcome { summary, series, figures })
}

/// Final error and settling time of a level of a run.
fn level_metrics(run: &VariantRun, level: usize) -> Result<(f64, f64), String> {
    let t = column(&run.series, "t")?;
    let e = column(&run.series, level_column(level))?;
    let last = e.last().copied().unwrap_or(f64::NAN);
    Ok((last, settle_time(&t, &e, 0.0, SETTLE_FRACTION)))
}

fn summarize(runs: &[VariantRun], duration_s: f64) -> Result<Summary, String> {
    let mut summary = Summary::new(NAME);
    summary.metric("duration_s", duration_s).metric("settle_fraction", SETTLE_FRACTION);
    // (final error, settling time) per variant name and level 1–4.
    let mut table = std::collections::BTreeMap::new();
    for run in runs {
        for level in 1..=4 {
            let (last, settle) = level_metrics(run, level)?;
            summary.metric(&format!("final_err_{}_l{level}", run.variant.name), last);
            summary.metric(&format!("settle_time_s_{}_l{level}", run.variant.name), settle);
            table.insert((run.variant.name, level), (last, settle));
        }
        summary.metric(&format!("min_rho_{}", run.variant.name), run.min_ratio);
    }
    let get = |name: &str, level: usize| table.get(&(name, level)).copied().unwrap_or((f64::NAN, f64::NAN));
    let latest = |name: &str| (1..=3).map(|l| get(name, l).1).fold(0.0_f64, f64::max);
    let zero_on_123 = |name: &str| (1..=3).all(|l| get(name, l).0.abs() < ZERO_ERROR);

    let augmented = ["aug_static", "aug_dynamic", "aug_dynamic_accel"];
    let worst_aug = augmented
        .iter()
        .flat_map(|n| (1..=3).map(move |l| (n, l)))
        .map(|(n, l)| get(n, l).0.abs())
        .fold(0.0_f64, f64::max);
    summary.metric("max_abs_final_err_augmented_l123", worst_aug);
    summary.claim(
        &format!("all augmented variants reach zero steady-state error on levels 1-3 (max |e| = {worst_aug:.1e} < {ZERO_ERROR:.0e})"),
        augmented.iter().all(|n| zero_on_123(n)),
    );

    for name in ["succ_static", "succ_dynamic", "aug_static", "aug_dynamic", "aug_dynamic_accel", "none"] {
        summary.metric(&format!("latest_settle_time_s_{name}_l123"), latest(name));
    }
    // The sentence of L3205 is about the augmented methods (the successive ones do not reach a
    // zero steady state); the successive pair is reported, not claimed.
    let slow = latest("aug_static");
    for dynamic in ["aug_dynamic", "aug_dynamic_accel"] {
        let fast = latest(dynamic);
        summary.claim(
            &format!("aug_static reaches its steady state considerably later than {dynamic} (latest settling on levels 1-3: {slow:.3} s vs {fast:.3} s, ratio {:.2} >= {STATIC_SLOWDOWN})", slow / fast),
            slow >= STATIC_SLOWDOWN * fast,
        );
    }

    let (succ_dyn_l3, none_l3) = (get("succ_dynamic", 3).0.abs(), get("none", 3).0.abs());
    summary.claim(
        &format!("successive dynamic: level-3 steady-state error larger than without projection ({succ_dyn_l3:.4} rad > {none_l3:.4} rad)"),
        succ_dyn_l3 > none_l3,
    );

    let converged: Vec<&str> = VARIANTS.iter().map(|v| v.name).filter(|n| zero_on_123(n)).collect();
    let best_two = {
        let mut ranked: Vec<(&str, f64)> = converged.iter().map(|n| (*n, latest(n))).collect();
        ranked.sort_by(|a, b| a.1.total_cmp(&b.1));
        ranked.iter().take(2).map(|(n, _)| *n).collect::<Vec<_>>()
    };
    summary.value("best_two_variants_l123", best_two.join(","));
    let (norm_m, norm_accel) = (get("aug_dynamic", 4).0, get("aug_dynamic_accel", 4).0);
    summary.metric("final_level4_norm_difference_dynamic_vs_accel", (norm_m - norm_accel).abs());
    summary.claim(
        &format!("augmented dynamic W=M and acceleration-based are the two best (fastest latest settling on levels 1-3 among the variants with zero error): {}", best_two.join(", ")),
        best_two.contains(&"aug_dynamic") && best_two.contains(&"aug_dynamic_accel"),
    );
    summary.claim(
        &format!("... but their final configurations differ: level-4 error norms {norm_m:.4} vs {norm_accel:.4}"),
        (norm_m - norm_accel).abs() > 1e-3,
    );
    // Why the two differ while aug_static ends where aug_dynamic does: the level-4 equilibrium
    // N₄τ₄ = 0 means τ₄ ∈ range(J_augᵀ) for every projector I − J_augᵀ(J_aug^{W+})ᵀ, whatever
    // W, but M⁻¹τ₄ ∈ range(J_augᵀ) for the acceleration-based one.
    let final_q = |name: &str| -> Result<SVector<f64, 4>, String> {
        let run = runs.iter().find(|r| r.variant.name == name).ok_or("missing run")?;
        let mut q = SVector::<f64, 4>::zeros();
        for (k, qk) in q.iter_mut().enumerate() {
            *qk = column(&run.series, &format!("q.{}", k + 1))?.last().copied().unwrap_or(f64::NAN);
        }
        Ok(q)
    };
    let same = (final_q("aug_static")? - final_q("aug_dynamic")?).amax();
    let accel = (final_q("aug_dynamic_accel")? - final_q("aug_dynamic")?).amax();
    summary.metric("final_q_difference_aug_static_vs_aug_dynamic_rad", same);
    summary.metric("final_q_difference_aug_dynamic_accel_vs_aug_dynamic_rad", accel);
    summary.claim(
        &format!("aug_static and aug_dynamic end in the same configuration (max |dq| = {same:.1e} rad), the acceleration-based one elsewhere ({accel:.1e} rad)"),
        same < 1e-4 && accel > 1e-3,
    );
    Ok(summary)
}

/// All runs side by side: the headline variant unprefixed, every variant prefixed.
fn combine(runs: &[VariantRun]) -> Result<TimeSeries, String> {
    let names = signal_columns();
    let headline = runs.iter().find(|r| r.variant.name == HEADLINE).ok_or("no headline run")?;
    let mut columns = vec!["t".to_owned()];
    columns.extend(names.iter().cloned());
    for run in runs {
        columns.extend(prefixed(&format!("{}.", run.variant.name), &names));
    }
    let mut series = TimeSeries::new(columns);
    for (k, head) in headline.series.rows().iter().enumerate() {
        let mut row = head.clone();
        for run in runs {
            let other = run.series.rows().get(k).ok_or("runs of different length")?;
            row.extend(other.iter().skip(1));
        }
        series.push(row)?;
    }
    Ok(series)
}

fn figures(runs: &[VariantRun]) -> Result<Vec<(&'static str, Figure)>, String> {
    let titles = [
        ("level 1: TCP translation error in x", "e_x (m)"),
        ("level 2: TCP translation error in y", "e_y (m)"),
        ("level 3: TCP orientation error about z", "e_rz (rad)"),
        ("level 4: Euclidean norm of the joint error", "||q - q_des|| (rad)"),
    ];
    let mut panels = Vec::new();
    for (level, (title, unit)) in titles.iter().enumerate() {
        let mut lines = Vec::new();
        for run in runs {
            let t = column(&run.series, "t")?;
            let e = column(&run.series, level_column(level + 1))?;
            lines.push(Line::new(run.variant.label, points(&t, &e)));
        }
        panels.push(Panel { title: (*title).into(), y_label: (*unit).into(), lines, spans: vec![] });
    }
    let figure = Figure {
        title: "projectors_sim1: Fig. 4.2, planar 4-DOF arm, Table 4.1 hierarchy, Table 4.2 gains".into(),
        x_label: "time (s)".into(),
        panels,
    };
    // The first 1.5 s, the window of Fig. 4.2.
    let zoom = Figure {
        title: "projectors_sim1: first 1.5 s (the time axis of Fig. 4.2)".into(),
        x_label: "time (s)".into(),
        panels: figure
            .panels
            .iter()
            .map(|p| Panel {
                lines: p
                    .lines
                    .iter()
                    .map(|l| Line {
                        points: l.points.iter().copied().filter(|(t, _)| *t <= 1.5).collect(),
                        ..l.clone()
                    })
                    .collect(),
                ..p.clone()
            })
            .collect(),
    };
    Ok(vec![("errors.svg", figure), ("errors_1_5s.svg", zoom)])
}
