//! `stiffness_sim2`: simulation #2 of Sec. 4.3.1 — the stiffness-consistent null space
//! projector on the planar 4-DOF arm with parallel springs (Fig. 4.3, Table 4.2, Figs. 4.4/4.5).
//!
//! # Setup
//! - Robot: [`fixtures::planar::four_dof`] with the parallel springs and joint dampers of
//!   Fig. 4.3 ([`fixtures::planar::fig_4_3_springs`]: `K = diag(100, 100, 50, 50)` Nm/rad,
//!   `d_i = 15` Nms/rad), simulated as passive joint elements of the [`Simulator`]
//!   ((4.43) plus damping). The spring rest angles make [`EQUILIBRIUM`]
//!   `q₀ = (−0.2, −1.5, 1.5, −1.0)` rad (our choice, the thesis prints none; see its docs for
//!   why not the fixture's `q₀`) an equilibrium without motor torque: `k(q₀) = −g(q₀)`.
//! - The arm starts at rest at `q₀`; "the TCP starts at its desired position".
//! - Level 1: TCP position x and y (two rows of the world-aligned TCP Jacobian) with
//!   `K₁ = D₁ = 0` (Table 4.2, Sim. #2): the springs hold the TCP, the level contributes no
//!   torque, only its null space.
//! - Level 2: the virtual repulsion of the first link from an approaching obstacle, read as a
//!   joint-space task on `q₁` (Table 4.2's units and the Fig. 4.4 bottom plot of `q₁` with its
//!   reference; THESIS-NUMBERS §2.2): from `t = 0.5 s`,
//!   `τ₂ = e₁ (−200 (q₁ − q₁,ref) − 10 q̇₁ − 10 ∫_{0.5 s}^t (q₁ − q₁,ref) dt)` with
//!   [`Q1_REFERENCE`] `= −0.3 rad` (our choice inside the −0.35…−0.15 rad axis of Fig. 4.4);
//!   before 0.5 s the task is off (`τ₂ = 0`).
//! - Control law `τ = N₂ τ₂` (4.48): no active gravity compensation (the springs compensate
//!   gravity at `q₀`, which is why the thesis blames the small steady-state TCP error on
//!   "the change in the gravity torques", (4.50)) and no level-1 torque.
//! - Variants (legend of Fig. 4.4; with two levels successive = augmented): stiffness
//!   consistent `W = K(q₀)` (4.51), static `W = I`, dynamic `W = M(q)`, acceleration-based
//!   `W = I` (4.38), and no projection. The projectors use the current `J₁(q)`.
//! - Duration 4 s (the time axis of Figs. 4.4/4.5), control at 1 kHz, RK4 at 1/6000 s.
//!
//! # Metrics (per variant `v`)
//! `max_tcp_err_m_<v>` (largest Euclidean TCP position error, level 1), `rms_tcp_err_m_<v>`
//! (RMS over 0.5…4 s), `final_tcp_err_m_<v>`, `final_err_<v>_l1` (= final TCP error),
//! `final_err_<v>_l2` (`q₁ − q₁,ref` at the end), `settle_time_s_<v>_l1`, `settle_time_s_<v>_l2`
//! (from 0.5 s, 2 % band around the final value as in `projectors_sim1`), `max_abs_tau_nm_<v>`.
//!
//! # Claims (L3233–L3237)
//! 1. `W = K(q₀)` gives the best level-1 behaviour "by far": its largest TCP error is at most
//!    half that of every other variant, and so is its RMS error.
//! 2. It still shows "a small steady-state error": non-zero (> 1e-6 m) but below 10 % of the
//!    largest transient TCP error of the static `W = I` projector.
//! 3. The dynamically consistent projectors perform worse than `W = I` during the transient
//!    (larger largest TCP error), although they use the inertia matrix.
//! 4. Level 2 acts with every projection: at the end `|q₁ − q₁,ref|` is at most 60 % of the
//!    0.1 rad step and still decreasing. (The thesis adds the integral "so that no steady-state
//!    error results"; with its gains the integral's time constant is at least
//!    `K₂/K_I = 20 s`, so that steady state lies far beyond the 4 s of Fig. 4.4.)
//! 5. "The dynamically consistent redundancy resolutions compensate for the error on level two
//!    faster": their level-2 settling times are below those of `W = K` and `W = I`.
//!
//! # Time series
//! The `W = K` run in the standard columns (`q.i`, `dq.i`, `tau.i`, `e1.x`, `e1.y` TCP error,
//! `e2.q1` = `q₁ − q₁,ref`, `q1_ref`), every variant's run prefixed with `<variant>.`.

use fixtures::planar::{fig_4_3_springs, four_dof, four_dof_gravity, ParallelSprings, Planar4, PLANAR4_TCP};
use kernel::dynamics::{crba, forward_kinematics, frame_jacobian, mass_matrix_cholesky};
use kernel::hierarchy::{project, HierarchyConfig, HierarchyData, Recursion, Shaping, Stack, Weighting};
use kernel::model::Data;
use kernel::tasks::TaskRow;
use nalgebra::{Cholesky, Matrix4, RowSVector, SMatrix, SVector, Vector3};

use super::hierarchy_common::{column, control_cycle, max_abs, points, prefixed, series_with_time, settle_time};
use super::{joint_columns, Outcome, RunOptions};
use crate::output::{Figure, Line, Panel, Span, Summary, TimeSeries};
use crate::sim::{run_loop, PassiveJoints, SimConfig, Simulator, CONTROL_PERIOD_S};

/// Registry name.
pub const NAME: &str = "stiffness_sim2";
/// One-line description.
pub const DESCRIPTION: &str =
    "planar 4-DOF arm with parallel springs (Fig. 4.3): stiffness- vs static/dynamic-consistent projection, 4 s";
/// Simulated time (s).
pub const DURATION_S: f64 = 4.0;
/// Activation of the level-2 repulsion (s).
pub const ACTIVATION_S: f64 = 0.5;
/// Level-2 reference of `q₁` after the activation (rad); our choice.
pub const Q1_REFERENCE: f64 = -0.3;
/// Table 4.2, Sim. #2: level-2 stiffness (Nm/rad), damping (Nms/rad), integral gain (Nm/(rad s)).
pub const LEVEL2_GAINS: [f64; 3] = [200.0, 10.0, 10.0];
/// The equilibrium `q₀` (rad) at which the springs hold the arm and the TCP goal; ours.
///
/// Not [`fixtures::planar::FIG_4_3_EQUILIBRIUM`] `(−0.2, −0.5, −0.5, −0.4)`: there the static
/// gain of the level-2 loop through the springs, `e₁ᵀ(K + ∂g/∂q)⁻¹ N₂ e₁`, is negative for the
/// dynamically consistent projectors (−1/91 rad/Nm for `W = M`, −1/261 for the
/// acceleration-based one), so the integral action drives `q₁` away from its reference and
/// these two runs diverge. Here the gain is positive for every projector (effective joint-1
/// stiffness 174, 290, 65, 81, 74 Nm/rad for `W = K`, `I`, `M`, accel., none), and the
/// gravity change moves the TCP little under `W = K` (static TCP displacement per radian of
/// `q₁`: 0.01 m for `W = K`, 1.9 m for `W = I`). TCP at (1.16 m, 1.10 m).
pub const EQUILIBRIUM: [f64; 4] = [-0.2, -1.5, 1.5, -1.0];
/// Settling band (fraction of the largest excursion from the final value).
pub const SETTLE_FRACTION: f64 = 0.02;

/// Classical projection (no row comes near a singularity).
const SHAPING: Shaping<f64> = Shaping::Discontinuous { singular_threshold: 1e-6 };

/// Weighting of one compared projector.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Projection {
    /// `W = K(q₀)` (4.51).
    Stiffness,
    /// `W = I`.
    Static,
    /// `W = M(q)`.
    Dynamic,
    /// `M N^s M⁻¹`, `W = I` (4.38).
    Acceleration,
    /// `τ = τ₂`.
    None,
}

/// One compared variant: metric name, legend, projection.
pub const VARIANTS: [(&str, &str, Projection); 5] = [
    ("stiffness", "stiffness-consistent, W=K(q0)", Projection::Stiffness),
    ("static", "statically consistent, W=I", Projection::Static),
    ("dynamic", "dynamically consistent, W=M", Projection::Dynamic),
    ("accel", "dynamically consistent, W=I (accel.-based)", Projection::Acceleration),
    ("none", "no null space projection", Projection::None),
];

type Sim = Simulator<4, 4, 5, 4>;

fn signal_columns() -> Vec<String> {
    let mut names = joint_columns(&["1", "2", "3", "4"]);
    names.extend(["e1.x", "e1.y", "e2.q1", "q1_ref"].map(String::from));
    names
}

struct Controller {
    model: Planar4<f64>,
    data: Data<f64, 4, 4, 5>,
    projection: Projection,
    stiffness: Cholesky<f64, nalgebra::Const<4>>,
    tcp_goal: Vector3<f64>,
    integral: f64,
    hierarchy: HierarchyData<f64, 4, 3, 2>,
}

impl Controller {
    fn step(
        &mut self,
        t: f64,
        q: &SVector<f64, 4>,
        v: &SVector<f64, 4>,
    ) -> Result<(SVector<f64, 4>, [f64; 4]), String> {
        let err = |e: &dyn std::fmt::Display| e.to_string();
        forward_kinematics(&self.model, &mut self.data, q, v).map_err(|e| err(&e))?;
        crba(&self.model, &mut self.data);
        let mass = mass_matrix_cholesky(&self.data).map_err(|e| err(&e))?;
        let mut jacobian = SMatrix::<f64, 6, 4>::zeros();
        frame_jacobian(&self.model, &self.data, PLANAR4_TCP, &mut jacobian).map_err(|e| err(&e))?;
        let tcp = self.data.frame_placements.get(PLANAR4_TCP.0).ok_or("no TCP frame")?.translation.vector;
        let tcp_error = tcp - self.tcp_goal;

        let active = t >= ACTIVATION_S - 1e-9;
        let reference = if active { Q1_REFERENCE } else { EQUILIBRIUM[0] };
        let e2 = q[0] - reference;
        let [k2, d2, i2] = LEVEL2_GAINS;
        let force = if active {
            self.integral += e2 * CONTROL_PERIOD_S;
            -k2 * e2 - d2 * v[0] - i2 * self.integral
        } else {
            0.0
        };
        let mut stack = Stack::<f64, 4, 3>::new();
        for axis in 0..2 {
            // K₁ = D₁ = 0: the level only defines the null space.
            let row =
                TaskRow { jacobian: jacobian.row(axis).into_owned(), force: 0.0, potential: 0.0, activation: 1.0 };
            stack.push(0, row).map_err(|e| err(&e))?;
        }
        let unit = RowSVector::<f64, 4>::new(1.0, 0.0, 0.0, 0.0);
        let potential = 0.5 * k2 * e2 * e2;
        stack.push(1, TaskRow { jacobian: unit, force, potential, activation: 1.0 }).map_err(|e| err(&e))?;
        let (recursion, weighting) = match self.projection {
            Projection::Stiffness => (Recursion::Augmented, Weighting::Stiffness(&self.stiffness)),
            Projection::Static => (Recursion::Augmented, Weighting::Identity),
            Projection::Dynamic => (Recursion::Augmented, Weighting::Inertia(&mass)),
            Projection::Acceleration => (Recursion::Augmented, Weighting::AccelerationBased(&mass)),
            Projection::None => (Recursion::Unprojected, Weighting::Identity),
        };
        let config = HierarchyConfig { recursion, weighting, shaping: SHAPING, diagnose_last_level: true };
        let tau = *project(&config, &stack, &mut self.hierarchy).map_err(|e| err(&e))?;
        Ok((tau, [tcp_error.x, tcp_error.y, e2, reference]))
    }
}

/// One simulated variant.
pub struct VariantRun {
    /// Metric name of the variant.
    pub name: &'static str,
    /// Legend entry.
    pub label: &'static str,
    /// `t` and the signals.
    pub series: TimeSeries,
}

/// The Fig. 4.3 springs and dampers ([`fig_4_3_springs`]) with their rest angles set for
/// [`EQUILIBRIUM`] by the fixture's rule `rest = q₀ + K⁻¹ g(q₀)` (`k(q₀) = −g(q₀)`).
pub fn springs() -> ParallelSprings<f64> {
    let springs = fig_4_3_springs::<f64>();
    let q0 = SVector::<f64, 4>::from(EQUILIBRIUM);
    ParallelSprings { rest: q0 + four_dof_gravity(&q0).component_div(&springs.stiffness), ..springs }
}

/// Simulates one variant for `duration_s`.
pub fn run_variant(
    name: &'static str,
    label: &'static str,
    projection: Projection,
    duration_s: f64,
    options: &RunOptions,
) -> Result<VariantRun, String> {
    let model = four_dof::<f64>().map_err(|e| format!("planar model: {e}"))?;
    let springs = springs();
    let q0 = SVector::<f64, 4>::from(EQUILIBRIUM);
    let mut sim: Sim = options.simulator(model.clone(), SimConfig::default())?;
    sim.set_passive_joints(PassiveJoints {
        stiffness: springs.stiffness,
        rest: springs.rest,
        damping: springs.damping,
    })
    .map_err(|e| e.to_string())?;
    sim.set_state(q0, SVector::zeros()).map_err(|e| e.to_string())?;
    let tcp_goal = sim.frame_placement(PLANAR4_TCP).map_err(|e| e.to_string())?.translation.vector;
    let stiffness =
        Cholesky::new(Matrix4::from_diagonal(&springs.local_stiffness())).ok_or("K(q0) not positive definite")?;
    let mut controller = Controller {
        data: Data::new(&model),
        model,
        projection,
        stiffness,
        tcp_goal,
        integral: 0.0,
        hierarchy: HierarchyData::default(),
    };
    let mut series = series_with_time(signal_columns());
    run_loop(&mut sim, duration_s, CONTROL_PERIOD_S, |sim, info| -> Result<(), String> {
        series.push(control_cycle(sim, info.time_s, |q, v| controller.step(info.time_s, q, v))?)
    })?;
    Ok(VariantRun { name, label, series })
}

/// Runs the scenario with the full duration.
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    simulate_for(DURATION_S, options)
}

/// Runs all variants for `duration_s` and evaluates the claims.
pub fn simulate_for(duration_s: f64, options: &RunOptions) -> Result<Outcome, String> {
    let mut runs = Vec::new();
    for (k, (name, label, projection)) in VARIANTS.iter().enumerate() {
        #[allow(clippy::cast_precision_loss, reason = "five variants")]
        options.progress.report(NAME, duration_s * k as f64 / VARIANTS.len() as f64, duration_s);
        runs.push(run_variant(name, label, *projection, duration_s, options)?);
    }
    options.progress.finish();
    let summary = summarize(&runs, duration_s)?;
    let series = combine(&runs)?;
    let figures = figures(&runs)?;
    Ok(Outcome { summary, series, figures })
}

/// Per-variant numbers.
struct Metrics {
    max_tcp: f64,
    rms_tcp: f64,
    final_tcp: f64,
    final_l2: f64,
    /// `q₁ − q₁,ref` one second before the end.
    late_l2: f64,
    settle_l1: f64,
    settle_l2: f64,
    max_tau: f64,
    /// Largest `|q − q₀|` before the activation: the springs hold `q₀` without motor torque.
    drift_before: f64,
}

fn metrics(run: &VariantRun) -> Result<Metrics, String> {
    let t = column(&run.series, "t")?;
    let (ex, ey, e2) = (column(&run.series, "e1.x")?, column(&run.series, "e1.y")?, column(&run.series, "e2.q1")?);
    let tcp: Vec<f64> = ex.iter().zip(&ey).map(|(x, y)| x.hypot(*y)).collect();
    let after: Vec<f64> = t.iter().zip(&tcp).filter(|(ti, _)| **ti >= ACTIVATION_S).map(|(_, e)| *e).collect();
    #[allow(clippy::cast_precision_loss, reason = "a few thousand samples")]
    let rms = (after.iter().map(|e| e * e).sum::<f64>() / after.len().max(1) as f64).sqrt();
    let mut max_tau = 0.0_f64;
    for k in 1..=4 {
        max_tau = max_tau.max(max_abs(&column(&run.series, &format!("tau.{k}"))?));
    }
    let mut drift_before = 0.0_f64;
    for (k, q0) in EQUILIBRIUM.iter().enumerate() {
        let q = column(&run.series, &format!("q.{}", k + 1))?;
        let before = t.iter().zip(&q).filter(|(ti, _)| **ti < ACTIVATION_S).map(|(_, qk)| (qk - q0).abs());
        drift_before = before.fold(drift_before, f64::max);
    }
    Ok(Metrics {
        drift_before,
        max_tcp: max_abs(&tcp),
        rms_tcp: rms,
        final_tcp: tcp.last().copied().unwrap_or(f64::NAN),
        final_l2: e2.last().copied().unwrap_or(f64::NAN),
        late_l2: {
            let end = t.last().copied().unwrap_or(0.0);
            t.iter().zip(&e2).rev().find(|(ti, _)| **ti <= end - 1.0).map_or(f64::NAN, |(_, e)| *e)
        },
        settle_l1: settle_time(&t, &tcp, ACTIVATION_S, SETTLE_FRACTION),
        settle_l2: settle_time(&t, &e2, ACTIVATION_S, SETTLE_FRACTION),
        max_tau,
    })
}

fn summarize(runs: &[VariantRun], duration_s: f64) -> Result<Summary, String> {
    let mut summary = Summary::new(NAME);
    summary.metric("duration_s", duration_s).metric("q1_reference_rad", Q1_REFERENCE);
    let mut all = Vec::new();
    for run in runs {
        let m = metrics(run)?;
        let v = run.name;
        summary
            .metric(&format!("max_tcp_err_m_{v}"), m.max_tcp)
            .metric(&format!("rms_tcp_err_m_{v}"), m.rms_tcp)
            .metric(&format!("final_tcp_err_m_{v}"), m.final_tcp)
            .metric(&format!("final_err_{v}_l1"), m.final_tcp)
            .metric(&format!("final_err_{v}_l2"), m.final_l2)
            .metric(&format!("settle_time_s_{v}_l1"), m.settle_l1)
            .metric(&format!("settle_time_s_{v}_l2"), m.settle_l2)
            .metric(&format!("max_abs_tau_nm_{v}"), m.max_tau)
            .metric(&format!("max_drift_before_activation_rad_{v}"), m.drift_before);
        all.push((v, m));
    }
    let find = |name: &str| all.iter().find(|(n, _)| *n == name).map(|(_, m)| m);
    let (Some(k), Some(identity), Some(dynamic), Some(accel)) =
        (find("stiffness"), find("static"), find("dynamic"), find("accel"))
    else {
        return Err("missing variant".into());
    };
    let others = all.iter().filter(|(n, _)| *n != "stiffness");
    let next_max = others.clone().map(|(_, m)| m.max_tcp).fold(f64::INFINITY, f64::min);
    let next_rms = others.map(|(_, m)| m.rms_tcp).fold(f64::INFINITY, f64::min);
    summary.metric("max_tcp_err_ratio_next_best_over_stiffness", next_max / k.max_tcp);
    summary.claim(
        &format!(
            "W=K(q0) gives by far the smallest level-1 TCP error: max {:.2} mm vs {:.2} mm for the next best, RMS {:.2} mm vs {:.2} mm (at most half)",
            k.max_tcp * 1e3,
            next_max * 1e3,
            k.rms_tcp * 1e3,
            next_rms * 1e3
        ),
        2.0 * k.max_tcp <= next_max && 2.0 * k.rms_tcp <= next_rms,
    );
    summary.claim(
        &format!(
            "W=K(q0) keeps a small steady-state TCP error from the changed gravity torques: {:.3} mm (> 0, < 10 % of the W=I transient {:.2} mm)",
            k.final_tcp * 1e3,
            identity.max_tcp * 1e3
        ),
        k.final_tcp > 1e-6 && k.final_tcp < 0.1 * identity.max_tcp,
    );
    summary.claim(
        &format!(
            "the dynamically consistent projectors do worse than W=I during the transient (max TCP error W=M {:.2} mm, accel. {:.2} mm > W=I {:.2} mm)",
            dynamic.max_tcp * 1e3,
            accel.max_tcp * 1e3,
            identity.max_tcp * 1e3
        ),
        dynamic.max_tcp > identity.max_tcp && accel.max_tcp > identity.max_tcp,
    );
    // Level 2: with Kp = 200 Nm/rad and Ki = 10 Nm/(rad s) the integral removes the remaining
    // error with a time constant of at least Kp/Ki = 20 s, so the zero steady state the thesis
    // mentions lies far beyond the 4 s shown; what can be checked is that the task acts.
    let step = (EQUILIBRIUM[0] - Q1_REFERENCE).abs();
    let moving = all.iter().all(|(_, m)| m.final_l2.abs() <= 0.6 * step && m.late_l2.abs() > m.final_l2.abs());
    let worst_l2 = all.iter().map(|(_, m)| m.final_l2.abs()).fold(0.0_f64, f64::max);
    summary.claim(
        &format!("level 2 acts with every projection: |q1 - q1_ref| <= {worst_l2:.3} rad at the end (<= 60 % of the {step:.1} rad step) and still decreasing (integral)"),
        moving,
    );
    let fastest_static = k.settle_l2.min(identity.settle_l2);
    summary.claim(
        &format!(
            "the dynamically consistent projectors compensate the level-2 error faster (settling {:.2} s, {:.2} s vs {:.2} s for W=K, {:.2} s for W=I)",
            dynamic.settle_l2, accel.settle_l2, k.settle_l2, identity.settle_l2
        ),
        dynamic.settle_l2 < fastest_static && accel.settle_l2 < fastest_static,
    );
    Ok(summary)
}

fn combine(runs: &[VariantRun]) -> Result<TimeSeries, String> {
    let names = signal_columns();
    let head = runs.first().ok_or("no runs")?;
    let mut columns = vec!["t".to_owned()];
    columns.extend(names.iter().cloned());
    for run in runs {
        columns.extend(prefixed(&format!("{}.", run.name), &names));
    }
    let mut series = TimeSeries::new(columns);
    for (k, first) in head.series.rows().iter().enumerate() {
        let mut row = first.clone();
        for run in runs {
            row.extend(run.series.rows().get(k).ok_or("runs of different length")?.iter().skip(1));
        }
        series.push(row)?;
    }
    Ok(series)
}

fn figures(runs: &[VariantRun]) -> Result<Vec<(&'static str, Figure)>, String> {
    let activation = || vec![Span { label: "repulsion on (0.5 s)".into(), from: ACTIVATION_S, to: ACTIVATION_S }];
    let mut errors = vec![
        Panel {
            title: "level 1: TCP error in x".into(),
            y_label: "e_x (mm)".into(),
            lines: vec![],
            spans: activation(),
        },
        Panel {
            title: "level 1: TCP error in y".into(),
            y_label: "e_y (mm)".into(),
            lines: vec![],
            spans: activation(),
        },
        Panel {
            title: "level 2: first joint and its reference".into(),
            y_label: "q1 (rad)".into(),
            lines: vec![],
            spans: activation(),
        },
    ];
    let mut torques: Vec<Panel> = (1..=4)
        .map(|k| Panel {
            title: format!("joint {k} control torque"),
            y_label: "tau (Nm)".into(),
            lines: vec![],
            spans: activation(),
        })
        .collect();
    for run in runs {
        let t = column(&run.series, "t")?;
        let mm =
            |c: &str| -> Result<Vec<f64>, String> { Ok(column(&run.series, c)?.iter().map(|x| x * 1e3).collect()) };
        let targets = errors.iter_mut().zip([mm("e1.x")?, mm("e1.y")?, column(&run.series, "q.1")?]);
        for (panel, y) in targets {
            panel.lines.push(Line::new(run.label, points(&t, &y)));
        }
        for (k, panel) in torques.iter_mut().enumerate() {
            panel.lines.push(Line::new(run.label, points(&t, &column(&run.series, &format!("tau.{}", k + 1))?)));
        }
    }
    if let (Some(head), Some(panel)) = (runs.first(), errors.get_mut(2)) {
        let t = column(&head.series, "t")?;
        panel.lines.push(Line::dashed("reference q1_ref", points(&t, &column(&head.series, "q1_ref")?)));
    }
    Ok(vec![
        (
            "errors.svg",
            Figure {
                title: "stiffness_sim2: Fig. 4.4, TCP errors (level 1) and q1 (level 2)".into(),
                x_label: "time (s)".into(),
                panels: errors,
            },
        ),
        (
            "torques.svg",
            Figure {
                title: "stiffness_sim2: Fig. 4.5, control torques".into(),
                x_label: "time (s)".into(),
                panels: torques,
            },
        ),
    ])
}
