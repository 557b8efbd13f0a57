//! Shared machinery of the Sec. 5.2.5 simulations `multilevel_sim1` … `multilevel_sim3`: the
//! planar 4-DOF arm of Fig. 4.1 under the multi-level compliance controller (5.58) with the
//! hierarchy of Table 5.4 and the gains of Table 5.5.
//!
//! # Setup
//! - Plant: [`fixtures::planar::four_dof`] (four 0.5 m links, 1 kg point masses at the link
//!   centres, g = 9.81 m/s² along −y), simulated by [`Simulator`] (RK4, 1/6000 s). It starts at
//!   rest in the Table 5.4 initial configuration (elbow branch A of THESIS-NUMBERS §5.2:
//!   TCP (0.84, 0.96) m, `Σq = −1.37` rad, `q₁ = 0.40` rad); all goals step at `t = 0`.
//! - Hierarchy (Table 5.4): level 1 the TCP position `(x, y)` (world, m), level 2 the TCP
//!   orientation `Σq` (rad), level 3 the first joint `q₁` (rad). Levels 1–3 have 2 + 1 + 1 = 4
//!   rows, so the last level's null space (5.51) is one-dimensional and the goal is feasible.
//! - Potentials `V_i = ½ K_i x̃_i²` with the constant diagonal `K_i`, `D_i` of Table 5.5; forces
//!   `f = −K x̃ − D ẋ` per row.
//! - Controller: [`multilevel_control`] with the controller's model (exact, or perturbed in
//!   sim #3) for `M`, `C` and the bases, and the **exact** gravity `g(q)` of the plant (the
//!   thesis says only that "the assumed inertia in the controller differs"; THESIS-NUMBERS §5.4
//!   recommends exact gravity). The controller runs every [`THESIS_CONTROL_PERIOD_S`] (the
//!   physics step) with zero-order hold, approximating the thesis' continuous-time loop.
//!
//! # Cross-level accelerations
//! The acceleration of level `i` caused by the torque of level `j` is evaluated with the
//! plant's inertia, `q̈_j = M⁻¹ τ_j^p`:
//! - every pair `i ≠ j` in the decoupled coordinates of (5.62), `J̄_i q̈_j` (columns
//!   `acc<i>…_by<j>`): level 1 in the thesis' coordinates `v₁ = ẋ₁` (`J̄₁ = J₁`, m/s²),
//!   levels 2 and 3 (one row each, so our `J̄_i` is the thesis' one for level 2; level 3 is
//!   scaled by the pivot normalisation) in rad/s²; zero iff `Λ` is block-diagonal for the
//!   plant — what Fig. 5.17 (right) and Fig. 5.19 plot ("After solving the dynamics (5.62) for
//!   the accelerations"; the magnitudes of Fig. 5.19, ±6 m/s² and ±1.5 rad/s², match these
//!   coordinates);
//! - in addition, level 2 disturbed by level 3 in its operational space, `Σq̈₃`
//!   (`acc2_op_by3`): zero iff the projection is dynamically consistent (Def. 4.2).

use fixtures::planar::{four_dof, four_dof_configuration, Planar4, LINK_LENGTH, PLANAR4_TCP};
use hal::JointTorqueInterface;
use kernel::dynamics::{
    coriolis_matrix, crba, forward_kinematics, frame_jacobian, frame_jacobian_derivative, gravity, mass_matrix_cholesky,
};
use kernel::hierarchy::multilevel::{
    multilevel_control, ComplianceRow, ComplianceStack, DynamicsTerms, MultilevelConfig, MultilevelData,
};
use kernel::model::{Data, Inertia, JointDrive, JointKind, ModelBuilder, ModelError, Placement};
use nalgebra::{RowSVector, SMatrix, SVector, Vector3};

use super::{joint_columns, RunOptions};
use crate::output::{Figure, Line, Panel, TimeSeries};
use crate::sim::{run_loop, SimConfig, Simulator};

/// Coordinates of the planar arm.
pub const N: usize = 4;
/// Control period (s) of the 1 kHz main loop.
pub const CONTROL_PERIOD_S: f64 = 1e-3;
/// Control period (s) of the thesis simulations: the physics step (6 kHz). The thesis' plant
/// and controller are continuous-time; the zero-order hold of a 1 kHz loop delays the torque by
/// half a period on average, which acts like a negative damping of about `K T / 2`
/// (0.3 Nms/rad for `K = 600` Nm/rad against `D₂ = D₃ = 1.5` Nms/rad in sims #2/#3) and holds
/// each level's projected torque while the projectors move. Measured in sim #2 at 1 kHz: `S₁`
/// rises by 3.6e-5 J right after the start (2.8e-8 J at 6 kHz) and `S₂`, `S₃` become almost
/// zero at 0.51 s and 0.92 s instead of 0.42 s and 0.71 s (sim #2 reports both rates).
pub const THESIS_CONTROL_PERIOD_S: f64 = crate::sim::DEFAULT_PHYSICS_STEP_S;

/// Table 5.4, initial TCP position `(x, y)` (m).
pub const TCP_INITIAL_M: [f64; 2] = [0.84, 0.96];
/// Table 5.4, goal TCP position `(x, y)` (m).
pub const TCP_GOAL_M: [f64; 2] = [0.90, 0.80];
/// Table 5.4, initial TCP orientation `Σq` (rad).
pub const ORIENTATION_INITIAL_RAD: f64 = -1.37;
/// Table 5.4, goal TCP orientation `Σq` (rad), used literally (not −π/2).
pub const ORIENTATION_GOAL_RAD: f64 = -1.57;
/// Table 5.4, initial first joint `q₁` (rad).
pub const Q1_INITIAL_RAD: f64 = 0.40;
/// Table 5.4, goal first joint `q₁` (rad).
pub const Q1_GOAL_RAD: f64 = 0.35;

/// Stiffness and damping per level (Table 5.5); level 1 is `K₁ I₂`, `D₁ I₂`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gains {
    /// `K₁` (N/m).
    pub k1: f64,
    /// `D₁` (Ns/m).
    pub d1: f64,
    /// `K₂` (Nm/rad).
    pub k2: f64,
    /// `D₂` (Nms/rad).
    pub d2: f64,
    /// `K₃` (Nm/rad).
    pub k3: f64,
    /// `D₃` (Nms/rad).
    pub d3: f64,
}

/// Table 5.5, simulation #1 (high damping).
pub const SIM1_GAINS: Gains = Gains { k1: 1000.0, d1: 40.0, k2: 800.0, d2: 5.0, k3: 2400.0, d3: 15.0 };
/// Table 5.5, simulations #2 and #3 (low damping).
pub const SIM2_GAINS: Gains = Gains { k1: 500.0, d1: 30.0, k2: 600.0, d2: 1.5, k3: 600.0, d3: 1.5 };

/// Sim. #3: the controller's link masses (kg), "the first two link masses have been reduced by
/// 10 %, and the last two link masses have been increased by 10 %".
pub const SIM3_MASSES_KG: [f64; 4] = [0.9, 0.9, 1.1, 1.1];
/// Sim. #3: distance of each point mass from its proximal joint (m), "each point mass has been
/// shifted by 5 cm (closer to the TCP)": 0.25 + 0.05.
pub const SIM3_COM_M: [f64; 4] = [0.30, 0.30, 0.30, 0.30];

/// A planar 4-DOF arm with the geometry of [`four_dof`] but link masses `masses` (kg) placed
/// `com` (m) from the proximal joint along each link. With `[1; 4]` and `[0.25; 4]` it is
/// [`four_dof`] (checked by the tests). Frames as in [`four_dof`] (link centres, TCP = frame 4).
pub fn planar_arm(masses: [f64; 4], com: [f64; 4]) -> Result<Planar4<f64>, ModelError> {
    let mut builder = ModelBuilder::<f64, 4, 4, 5>::new(Vector3::new(0.0, -fixtures::planar::GRAVITY, 0.0));
    let mut parent = None;
    for (k, (mass, offset)) in masses.iter().zip(com.iter()).enumerate() {
        let placement = match parent {
            None => Placement::identity(),
            Some(_) => Placement::translation(0.0, LINK_LENGTH, 0.0),
        };
        let body = builder.add_body(
            parent,
            placement,
            JointKind::Revolute { axis: Vector3::z_axis() },
            JointDrive::actuated(k),
            Inertia::point_mass(*mass, Vector3::new(0.0, *offset, 0.0)),
        )?;
        builder.add_frame(Some(body), Placement::translation(0.0, 0.5 * LINK_LENGTH, 0.0))?;
        parent = Some(body);
    }
    builder.add_frame(parent, Placement::translation(0.0, LINK_LENGTH, 0.0))?;
    builder.try_build()
}

/// One simulation of the planar arm under the multi-level controller.
#[derive(Clone, Debug)]
pub struct Setup {
    /// Scenario name (progress output).
    pub name: &'static str,
    /// Gains of Table 5.5.
    pub gains: Gains,
    /// The controller's model (the plant is always [`four_dof`]).
    pub controller_model: Planar4<f64>,
    /// Whether `τ_μ` (5.60) is applied.
    pub coriolis_decoupling: bool,
    /// Simulated time (s).
    pub duration_s: f64,
    /// Control period (s), a whole multiple of the physics step: [`THESIS_CONTROL_PERIOD_S`]
    /// or the 1 kHz main loop [`CONTROL_PERIOD_S`].
    pub control_period_s: f64,
}

/// Task values and errors of the Table 5.4 hierarchy at `q`: `(x, y, Σq, q₁)` minus the goals.
fn task_errors(tcp: &Vector3<f64>, q: &SVector<f64, N>) -> [f64; 4] {
    [tcp.x - TCP_GOAL_M[0], tcp.y - TCP_GOAL_M[1], q.sum() - ORIENTATION_GOAL_RAD, q.x - Q1_GOAL_RAD]
}

/// The compliance rows of Table 5.4 at the controller's kinematics (`data` after
/// `forward_kinematics`).
fn stack_rows(
    model: &Planar4<f64>,
    data: &Data<f64, 4, 4, 5>,
    gains: &Gains,
    stack: &mut ComplianceStack<f64, N, 8>,
) -> Result<[f64; 4], String> {
    let mut jacobian = SMatrix::<f64, 6, N>::zeros();
    let mut rate = SMatrix::<f64, 6, N>::zeros();
    frame_jacobian(model, data, PLANAR4_TCP, &mut jacobian).map_err(|e| e.to_string())?;
    frame_jacobian_derivative(model, data, PLANAR4_TCP, &data.v, &mut rate).map_err(|e| e.to_string())?;
    let tcp = data.frame_placements.get(PLANAR4_TCP.0).ok_or("no TCP frame")?.translation.vector;
    let errors = task_errors(&tcp, &data.q);
    stack.clear();
    let spring = |level: usize,
                  j: RowSVector<f64, N>,
                  j_rate: RowSVector<f64, N>,
                  error: f64,
                  (k, d): (f64, f64),
                  stack: &mut ComplianceStack<f64, N, 8>| {
        let rate = j.dot(&data.v.transpose());
        stack
            .push(
                level,
                ComplianceRow {
                    jacobian: j,
                    jacobian_rate: j_rate,
                    stiffness_force: -k * error,
                    damping_force: -d * rate,
                    potential: 0.5 * k * error * error,
                },
            )
            .map_err(|e| e.to_string())
    };
    for axis in 0..2 {
        let error = errors.get(axis).copied().unwrap_or_default();
        spring(0, jacobian.row(axis).into_owned(), rate.row(axis).into_owned(), error, (gains.k1, gains.d1), stack)?;
    }
    let ones = RowSVector::<f64, N>::repeat(1.0);
    spring(1, ones, RowSVector::zeros(), errors[2], (gains.k2, gains.d2), stack)?;
    let first = RowSVector::<f64, N>::from_fn(|_, c| if c == 0 { 1.0 } else { 0.0 });
    spring(2, first, RowSVector::zeros(), errors[3], (gains.k3, gains.d3), stack)?;
    Ok(errors)
}

/// The time series of one run (columns in [`columns`]).
pub fn run(setup: &Setup, options: &RunOptions) -> Result<TimeSeries, String> {
    let plant = four_dof::<f64>().map_err(|e| format!("planar model: {e}"))?;
    let model = &setup.controller_model;
    let mut sim: Simulator<4, 4, 5, 4> = options.simulator(plant.clone(), SimConfig::default())?;
    let q0 = four_dof_configuration(TCP_INITIAL_M[0], TCP_INITIAL_M[1], ORIENTATION_INITIAL_RAD, Q1_INITIAL_RAD, false)
        .ok_or("Table 5.4 initial configuration unreachable")?;
    sim.set_state(q0, SVector::zeros()).map_err(|e| e.to_string())?;

    let config = MultilevelConfig { coriolis_decoupling: setup.coriolis_decoupling, ..MultilevelConfig::default() };
    let mut controller_data = Data::new(model);
    let mut plant_data = Data::new(&plant);
    let mut stack = ComplianceStack::<f64, N, 8>::new();
    let mut out = MultilevelData::<f64, N, 3>::default();
    let mut series = TimeSeries::new(columns());
    let gains = setup.gains;

    let mut cycle = |sim: &mut Simulator<4, 4, 5, 4>, t: f64| -> Result<Vec<f64>, String> {
        let (q, v) = (*sim.q(), *sim.v());
        let err = |e: kernel::dynamics::DynamicsError| e.to_string();
        forward_kinematics(model, &mut controller_data, &q, &v).map_err(err)?;
        let mass = *crba(model, &mut controller_data);
        let coriolis = *coriolis_matrix(model, &mut controller_data);
        let factor = mass_matrix_cholesky(&controller_data).map_err(err)?;
        forward_kinematics(&plant, &mut plant_data, &q, &v).map_err(err)?;
        let g = *gravity(&plant, &mut plant_data);
        crba(&plant, &mut plant_data);
        let plant_factor = mass_matrix_cholesky(&plant_data).map_err(err)?;
        let errors = stack_rows(model, &controller_data, &gains, &mut stack)?;
        let terms =
            DynamicsTerms { mass_matrix: &mass, mass_factor: &factor, coriolis: &coriolis, gravity: &g, velocity: &v };
        let torque = *multilevel_control(&config, &stack, &terms, &mut out).map_err(|e| e.to_string())?;
        JointTorqueInterface::<f64, 4>::write_torque(sim, &torque.into()).map_err(|e| e.to_string())?;

        let mut row = vec![t];
        row.extend(q.iter().chain(v.iter()).chain(sim.applied_torque().iter()));
        row.extend(errors);
        let storage = out.storage;
        row.extend(storage.iter().map(|s| s.storage));
        row.extend(storage.iter().map(|s| s.storage_rate));
        row.extend(storage.iter().map(|s| s.kinetic));
        row.extend(storage.iter().map(|s| s.potential));
        row.extend(storage.iter().map(|s| s.static_residual));
        row.extend(storage.iter().map(|s| f64::from(u8::from(s.in_set))));
        row.extend(out.coriolis_torque.iter());
        for level_torque in &out.level_torques {
            row.extend(level_torque.iter());
        }
        row.extend(cross_accelerations(&controller_data, model, &out, &plant_factor)?);
        Ok(row)
    };
    run_loop(&mut sim, setup.duration_s, setup.control_period_s, |sim, info| {
        if info.cycle % 500 == 0 {
            options.progress.report(setup.name, info.time_s, setup.duration_s);
        }
        series.push(cycle(sim, info.time_s)?)
    })?;
    options.progress.finish();
    Ok(series)
}

/// The cross-level acceleration columns: `acc<i>…_by<j>` is the acceleration of level `i`'s
/// task coordinates caused by level `j`'s torque (zero under dynamic consistency).
pub const CROSS_COLUMNS: [&str; 9] = [
    "acc1.x_by2",
    "acc1.y_by2",
    "acc1.x_by3",
    "acc1.y_by3",
    "acc2_op_by3",
    "acc2_by1",
    "acc2_by3",
    "acc3_by1",
    "acc3_by2",
];

/// The columns of [`run`]'s time series.
pub fn columns() -> Vec<String> {
    let mut columns = vec!["t".to_owned()];
    columns.extend(joint_columns(&["1", "2", "3", "4"]));
    columns.extend(["e1.x", "e1.y", "e2.rot", "e3.q1", "S1", "S2", "S3"].map(String::from));
    for prefix in ["Sdot", "T", "V", "residual", "in_A"] {
        columns.extend((1..=3).map(|level| format!("{prefix}{level}")));
    }
    columns.extend((1..=4).map(|k| format!("tau_mu.{k}")));
    for level in 1..=3 {
        columns.extend((1..=4).map(|k| format!("tau{level}p.{k}")));
    }
    columns.extend(CROSS_COLUMNS.map(String::from));
    columns
}

/// Accelerations of each level caused by the torques of the others, with the plant's inertia
/// (module docs), in the order of the `acc*` columns.
fn cross_accelerations(
    data: &Data<f64, 4, 4, 5>,
    model: &Planar4<f64>,
    out: &MultilevelData<f64, N, 3>,
    plant_factor: &kernel::math::CholeskyFactor<f64, N>,
) -> Result<[f64; 9], String> {
    let mut jacobian = SMatrix::<f64, 6, N>::zeros();
    frame_jacobian(model, data, PLANAR4_TCP, &mut jacobian).map_err(|e| e.to_string())?;
    let qdd: Vec<SVector<f64, N>> = out.level_torques.iter().map(|t| plant_factor.solve(t)).collect();
    let by = |level: usize| qdd.get(level).copied().unwrap_or_default();
    let rows = &out.decomposition;
    let jbar = |level: usize| rows.level_rows(level).first().map(|r| r.jacobian).unwrap_or_default();
    let op = |axis: usize, level: usize| jacobian.row(axis).dot(&by(level).transpose());
    Ok([
        op(0, 1),
        op(1, 1),
        op(0, 2),
        op(1, 2),
        by(2).sum(),
        jbar(1).dot(&by(0).transpose()),
        jbar(1).dot(&by(2).transpose()),
        jbar(2).dot(&by(0).transpose()),
        jbar(2).dot(&by(1).transpose()),
    ])
}

/// Values of column `name`.
pub fn column(series: &TimeSeries, name: &str) -> Result<Vec<f64>, String> {
    series.column(name).ok_or_else(|| format!("no column {name}"))
}

/// Time after which `|signal|` stays at or below `band` (the time of the first sample of the
/// final stretch inside the band; 0 if it never leaves it, NaN if it ends outside).
pub fn settle_time(t: &[f64], signal: &[f64], band: f64) -> f64 {
    match signal.iter().rposition(|x| x.abs() > band) {
        None => 0.0,
        Some(last) => t.get(last + 1).copied().unwrap_or(f64::NAN),
    }
}

/// Largest rise of `s` over a stretch of consecutive non-decreasing samples, counting only
/// samples with `t ≥ from`: `max (s[e] − s[b])` over such stretches `b ≤ e` (0 if `s` only
/// decreases there). Independent of the sampling rate, unlike a per-sample step.
pub fn largest_rise(t: &[f64], s: &[f64], from: f64) -> f64 {
    let mut best: f64 = 0.0;
    let mut start: Option<f64> = None;
    let mut previous: Option<f64> = None;
    for (time, value) in t.iter().zip(s.iter()) {
        if *time < from {
            continue;
        }
        match previous {
            Some(p) if *value >= p => best = best.max(value - start.unwrap_or(p)),
            _ => start = Some(*value),
        }
        previous = Some(*value);
    }
    best
}

/// Largest `|x|` of a column.
pub fn peak(values: &[f64]) -> f64 {
    values.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// Points `(t, y)` for a plot.
pub fn points(t: &[f64], y: &[f64]) -> Vec<(f64, f64)> {
    t.iter().copied().zip(y.iter().copied()).collect()
}

/// The two standard figures: errors per level, and storage functions per level.
pub fn figures(series: &TimeSeries, title: &str) -> Result<Vec<(&'static str, Figure)>, String> {
    let t = column(series, "t")?;
    let line =
        |name: &str, label: &str| -> Result<Line, String> { Ok(Line::new(label, points(&t, &column(series, name)?))) };
    let errors = Figure {
        title: format!("{title}: task errors (Table 5.4 hierarchy)"),
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: "level 1: TCP position".into(),
                y_label: "error (m)".into(),
                lines: vec![line("e1.x", "x")?, line("e1.y", "y")?],
                spans: vec![],
            },
            Panel {
                title: "level 2: TCP orientation Σq".into(),
                y_label: "error (rad)".into(),
                lines: vec![line("e2.rot", "Σq")?],
                spans: vec![],
            },
            Panel {
                title: "level 3: first joint".into(),
                y_label: "error (rad)".into(),
                lines: vec![line("e3.q1", "q1")?],
                spans: vec![],
            },
        ],
    };
    let mut panels = Vec::new();
    for level in 1..=3 {
        panels.push(Panel {
            title: format!("level {level}: storage function (5.64)"),
            y_label: "energy (J)".into(),
            lines: vec![
                line(&format!("S{level}"), "total S")?,
                line(&format!("V{level}"), "potential V")?,
                line(&format!("T{level}"), "kinetic ½vᵀΛv")?,
            ],
            spans: vec![],
        });
    }
    let energies = Figure { title: format!("{title}: energies per level"), x_label: "time (s)".into(), panels };
    Ok(vec![("errors.svg", errors), ("energies.svg", energies)])
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;

    #[test]
    fn nominal_parameters_give_the_fixture_arm() {
        let (ours, fixture) = (planar_arm([1.0; 4], [0.25; 4]).unwrap(), four_dof::<f64>().unwrap());
        let (mut a, mut b) = (Data::new(&ours), Data::new(&fixture));
        for k in 0..5 {
            let q = SVector::<f64, 4>::from_fn(|i, _| 0.3 * (1.3 * (i + k) as f64).sin());
            forward_kinematics(&ours, &mut a, &q, &SVector::zeros()).unwrap();
            forward_kinematics(&fixture, &mut b, &q, &SVector::zeros()).unwrap();
            assert!((crba(&ours, &mut a) - crba(&fixture, &mut b)).amax() < 1e-14);
            assert!((gravity(&ours, &mut a) - gravity(&fixture, &mut b)).amax() < 1e-12);
            assert!(
                (a.frame_placements[4].translation.vector - b.frame_placements[4].translation.vector).amax() < 1e-15
            );
        }
    }

    #[test]
    fn metric_helpers() {
        let t = [0.0, 1.0, 2.0, 3.0];
        assert_eq!(settle_time(&t, &[1.0, 0.5, 0.05, 0.01], 0.1), 2.0);
        assert_eq!(settle_time(&t, &[0.0; 4], 0.1), 0.0);
        let t = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(largest_rise(&t, &[3.0, 2.0, 2.5, 2.75, 1.0, 1.5], 0.0), 0.75);
        assert_eq!(largest_rise(&t, &[3.0, 2.0, 2.5, 2.75, 1.0, 1.5], 2.0), 0.5);
        assert_eq!(largest_rise(&t, &[3.0, 2.0, 1.5, 1.0, 0.5, 0.0], 0.0), 0.0);
    }
}
