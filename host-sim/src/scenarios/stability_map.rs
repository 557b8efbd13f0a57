//! `stability_map`: closed-loop poles of the linear three-DOF mobile robot of Fig. 5.2 /
//! Table 5.1 over the admittance parameters, with and without the coupling compensation
//! (Fig. 5.3).
//!
//! The model is the kernel fixture [`fixtures::mobile::three_dof`] (platform mass at `r`, upper
//! body masses at `r + q₁` and `r + q₁ + q₂`, 1 kg each, Table 5.1). The closed loop is
//! assembled from the kernel's components, not from a hand-derived polynomial:
//! - the virtual spring `K = 1 N/m` at the TCP is the kernel's Cartesian impedance task (x axis
//!   only, `ξ = 0`: Table 5.1 gives the damping separately), `τ_imp = −J_yᵀ K x̃` (5.10);
//! - the platform row is the kernel's admittance (5.1) with `m_adm`, `d_adm`, giving `r̈` (5.15);
//! - the upper body gets `τ_q = τ_imp,q − D_qq q̇` (5.11), `D_qq = diag(1, 1) kg/s`, plus — for
//!   the compensated loop — the kernel's coupling compensation (5.14);
//! - the plant is the upper-body row of the physical dynamics from the kernel's `crba`,
//!   `coriolis_matrix` and `gravity`: `M_qq q̈ = τ_q − M_qr r̈ − C_q ẏ − g_q`.
//!
//! The map `(y, ẏ) ↦ (ẏ, ÿ)` is linear (prismatic joints, `C = 0`, `g = 0`), so evaluating it at
//! the unit states gives the state matrix `A` (6×6) exactly; its eigenvalues are the closed-loop
//! poles. Two of them are always zero (the spring has rank one: the null space position is
//! neutral), so "stable" means `max Re λ ≤` [`STABLE_TOLERANCE`].
//!
//! Grid: `m_adm ∈ (0, 1.5]` kg × `d_adm ∈ (0, 1]` kg/s, the axes of Fig. 5.3, in steps of
//! [`GRID_STEP`]. Outputs: `stability_map_grid.csv` (the grid, no time column, written by the runner:
//! `m_adm,d_adm,max_real_eig_uncompensated,max_real_eig_compensated`), `stability_map.svg`
//! (the two region maps, drawn by [`write_files`]) and `max_real_eigenvalue.svg`.
//!
//! Claims (Sec. 5.1.1, Fig. 5.3): without compensation an unstable region exists inside the
//! window; with compensation every `m_adm, d_adm > 0` on the grid is stable.

use std::path::Path;

use fixtures::mobile::{table_5_1, three_dof, MOBILE_TCP};
use kernel::dynamics::{coriolis_matrix, crba, forward_kinematics, gravity};
use kernel::model::Placement;
use kernel::platform::admittance::{Admittance, AdmittanceConfig};
use kernel::platform::coupling_compensation::{coupling_compensation, CompensationSwitch};
use kernel::platform::{PlatformAxis, PlatformLayout};
use kernel::tasks::cartesian_impedance::{
    cartesian_impedance, AxisMask, CartesianImpedance, CartesianImpedanceConfig, CartesianTarget, StiffnessFrame,
};
use kernel::tasks::TaskRows;
use kernel::Data;
use nalgebra::{Cholesky, Matrix3, SMatrix, SVector, Vector2, Vector3, Vector6};
use plotters::prelude::*;

use super::{Outcome, RunOptions};
use crate::output::{Figure, Line, Panel, Summary, TimeSeries};

/// Registry name.
pub const NAME: &str = "stability_map";
/// One-line description.
pub const DESCRIPTION: &str =
    "linear 3-DOF mobile model (Fig. 5.2, Table 5.1): closed-loop poles over m_adm x d_adm with/without compensation (Fig. 5.3)";
/// Grid step of both axes (kg, kg/s).
pub const GRID_STEP: f64 = 0.01;
/// A pole counts as stable if its real part is at most this (1/s): the double zero pole of the
/// rank-one spring comes out at rounding level.
pub const STABLE_TOLERANCE: f64 = 1e-9;
/// File name of the grid CSV: one row per (m_adm, d_adm) cell.
pub const CSV_FILE: &str = "stability_map_grid.csv";
/// File name of the region map.
pub const MAP_FILE: &str = "stability_map.svg";

/// State matrix `A` of the closed loop `(y, ẏ)` → `(ẏ, ÿ)`, `y = (r, q₁, q₂)`.
pub type StateMatrix = SMatrix<f64, 6, 6>;

/// The closed loop of the linear model for one admittance, assembled from kernel components.
pub struct LinearMobile {
    model: fixtures::mobile::Mobile3<f64>,
    data: Data<f64, 3, 3, 3>,
    layout: PlatformLayout,
    task: CartesianImpedance<f64>,
    upper_body_damping: Vector2<f64>,
}

impl LinearMobile {
    /// The fixture with the gains of Table 5.1.
    pub fn new() -> Result<Self, String> {
        let model = three_dof::<f64>().map_err(|e| e.to_string())?;
        let p = table_5_1::<f64>();
        let layout =
            PlatformLayout::try_new::<3>([PlatformAxis::Admitted(0), PlatformAxis::Absent, PlatformAxis::Absent])
                .map_err(|e| e.to_string())?;
        let task = CartesianImpedance::try_new(CartesianImpedanceConfig {
            frame: MOBILE_TCP,
            axes: AxisMask::new([true, false, false, false, false, false]),
            stiffness_frame: StiffnessFrame::World,
            translational_stiffness: Matrix3::identity() * p.tcp_stiffness,
            rotational_stiffness: Matrix3::zeros(),
            damping_ratio: 0.0,
            force_lower: Vector6::repeat(f64::NEG_INFINITY),
            force_upper: Vector6::repeat(f64::INFINITY),
            fallback_damping: Vector6::zeros(),
        })
        .map_err(|e| e.to_string())?;
        let data = Data::new(&model);
        Ok(Self { model, data, layout, task, upper_body_damping: p.upper_body_damping })
    }

    /// `(ẏ, ÿ)` of the closed loop at the state `(y, ẏ)` with the desired TCP at 0.
    pub fn derivative(
        &mut self,
        admittance: &AdmittanceConfig<f64>,
        switch: CompensationSwitch,
        y: &SVector<f64, 3>,
        dy: &SVector<f64, 3>,
    ) -> Result<SVector<f64, 6>, String> {
        let (model, data) = (&self.model, &mut self.data);
        forward_kinematics(model, data, y, dy).map_err(|e| e.to_string())?;
        crba(model, data);
        coriolis_matrix(model, data);
        gravity(model, data);
        let mut rows = TaskRows::<f64, 3, 6>::new();
        cartesian_impedance(model, data, &self.task, &CartesianTarget::at_rest(Placement::identity()), &mut rows)
            .map_err(|e| e.to_string())?;
        let tau_imp = rows.torque();
        // Platform: the admittance (5.1) driven by the platform row of τ_imp (5.12), r̈ (5.15).
        let mut platform = Admittance::try_new(*admittance).map_err(|e| e.to_string())?;
        platform.reset(&Vector3::new(dy.x, 0.0, 0.0)).map_err(|e| e.to_string())?;
        let r_dd = platform
            .step(&Vector3::new(tau_imp.x, 0.0, 0.0), &Vector3::zeros(), 1e-3)
            .map_err(|e| e.to_string())?
            .acceleration;
        // Upper body: (5.11), (5.13)–(5.14).
        let compensation = coupling_compensation(data, &self.layout, &r_dd).map_err(|e| e.to_string())?.torque(switch);
        let damping = Vector2::new(dy.y, dy.z).component_mul(&self.upper_body_damping);
        let tau_q = Vector2::new(tau_imp.y, tau_imp.z) - damping + Vector2::new(compensation.y, compensation.z);
        // Plant: M_qq q̈ = τ_q − M_qr r̈ − (C ẏ + g)_q.
        let m_qq = data.mass_matrix.fixed_view::<2, 2>(1, 1).into_owned();
        let m_qr = data.mass_matrix.fixed_view::<2, 1>(1, 0).into_owned();
        let bias = data.coriolis * dy + data.gravity_torque;
        let rhs = tau_q - m_qr * r_dd.x - Vector2::new(bias.y, bias.z);
        let q_dd = Cholesky::new(m_qq).ok_or("M_qq not positive definite")?.solve(&rhs);
        Ok(SVector::<f64, 6>::from([dy.x, dy.y, dy.z, r_dd.x, q_dd.x, q_dd.y]))
    }

    /// The state matrix `A` for admittance `(m_adm, d_adm)` (kg, kg/s).
    pub fn state_matrix(&mut self, m_adm: f64, d_adm: f64, switch: CompensationSwitch) -> Result<StateMatrix, String> {
        let admittance = AdmittanceConfig {
            mass: Vector3::new(m_adm, 1.0, 1.0),
            damping: Vector3::new(d_adm, 1.0, 1.0),
            force_limit: Vector3::repeat(f64::INFINITY),
            free_axes: [true, false, false],
        };
        let mut a = StateMatrix::zeros();
        for k in 0..6 {
            let unit = SVector::<f64, 6>::from_fn(|i, _| if i == k { 1.0 } else { 0.0 });
            let (y, dy) = (unit.fixed_rows::<3>(0).into_owned(), unit.fixed_rows::<3>(3).into_owned());
            a.set_column(k, &self.derivative(&admittance, switch, &y, &dy)?);
        }
        Ok(a)
    }

    /// Largest real part of the closed-loop poles (1/s).
    pub fn max_real_eigenvalue(&mut self, m_adm: f64, d_adm: f64, switch: CompensationSwitch) -> Result<f64, String> {
        let a = self.state_matrix(m_adm, d_adm, switch)?;
        Ok(a.complex_eigenvalues().iter().map(|l| l.re).fold(f64::NEG_INFINITY, f64::max))
    }
}

/// One grid point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridPoint {
    /// `m_adm` (kg).
    pub m_adm: f64,
    /// `d_adm` (kg/s).
    pub d_adm: f64,
    /// Largest real part without compensation (1/s).
    pub uncompensated: f64,
    /// Largest real part with compensation (1/s).
    pub compensated: f64,
}

/// The grid `m_adm = k·step` (`k = 1 …`, up to 1.5 kg) × `d_adm = j·step` (up to 1 kg/s).
pub fn grid(step: f64) -> Result<Vec<GridPoint>, String> {
    let p = table_5_1::<f64>();
    let count = |max: f64| (max / step).round() as usize;
    let mut system = LinearMobile::new()?;
    let mut points = Vec::new();
    for i in 1..=count(p.admittance_damping_max) {
        for k in 1..=count(p.admittance_mass_max) {
            let (m_adm, d_adm) = (k as f64 * step, i as f64 * step);
            points.push(GridPoint {
                m_adm,
                d_adm,
                uncompensated: system.max_real_eigenvalue(m_adm, d_adm, CompensationSwitch::OFF)?,
                compensated: system.max_real_eigenvalue(m_adm, d_adm, CompensationSwitch::ON)?,
            });
        }
    }
    Ok(points)
}

/// Runs the scenario.
pub fn simulate(_options: &RunOptions) -> Result<Outcome, String> {
    let points = grid(GRID_STEP)?;
    evaluate(&points)
}

/// Summary, series and figures of a grid.
pub fn evaluate(points: &[GridPoint]) -> Result<Outcome, String> {
    let unstable: Vec<&GridPoint> = points.iter().filter(|p| p.uncompensated > STABLE_TOLERANCE).collect();
    let worst_compensated = points.iter().map(|p| p.compensated).fold(f64::NEG_INFINITY, f64::max);
    let extent = |f: fn(&GridPoint) -> f64| {
        unstable.iter().map(|p| f(p)).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| (lo.min(x), hi.max(x)))
    };
    let (m_range, d_range) = (extent(|p| p.m_adm), extent(|p| p.d_adm));
    let mut summary = Summary::new(NAME);
    summary
        .value("grid_points", points.len())
        .value("unstable_points_uncompensated", unstable.len())
        .value("unstable_points_compensated", points.iter().filter(|p| p.compensated > STABLE_TOLERANCE).count())
        .metric("unstable_fraction_uncompensated", unstable.len() as f64 / points.len().max(1) as f64)
        .metric("unstable_m_adm_max_kg", m_range.1)
        .metric("unstable_d_adm_max_kg_s", d_range.1)
        .metric(
            "max_real_eig_uncompensated_per_s",
            points.iter().map(|p| p.uncompensated).fold(f64::NEG_INFINITY, f64::max),
        )
        .metric("max_real_eig_compensated_per_s", worst_compensated)
        .metric("stable_tolerance_per_s", STABLE_TOLERANCE);
    summary.claim(
        &format!(
            "without compensation an unstable region exists ({} of {} grid points, m_adm up to {:.2} kg, d_adm up to {:.2} kg/s)",
            unstable.len(),
            points.len(),
            m_range.1,
            d_range.1
        ),
        !unstable.is_empty() && unstable.len() < points.len(),
    );
    summary.claim(
        &format!("with compensation every m_adm, d_adm > 0 is stable (max Re λ = {worst_compensated:.1e} ≤ {STABLE_TOLERANCE:.0e} 1/s)"),
        worst_compensated <= STABLE_TOLERANCE,
    );
    let mut series = TimeSeries::new(
        ["m_adm", "d_adm", "max_real_eig_uncompensated", "max_real_eig_compensated"].map(String::from).to_vec(),
    );
    for p in points {
        series.push(vec![p.m_adm, p.d_adm, p.uncompensated, p.compensated])?;
    }
    Ok(Outcome { summary, series, figures: vec![("max_real_eigenvalue.svg", eigenvalue_figure(points))] })
}

/// Largest real part over `m_adm` for a few dampings.
fn eigenvalue_figure(points: &[GridPoint]) -> Figure {
    let lines = |f: fn(&GridPoint) -> f64| {
        [0.1, 0.3, 0.5, 0.8]
            .iter()
            .map(|d| {
                let pts = points.iter().filter(|p| (p.d_adm - d).abs() < 1e-9).map(|p| (p.m_adm, f(p))).collect();
                Line::new(format!("d_adm = {d} kg/s"), pts)
            })
            .chain(std::iter::once(Line::dashed("stability limit", vec![(0.0, 0.0), (1.5, 0.0)])))
            .collect()
    };
    Figure {
        title: "stability_map: largest real part of the closed-loop poles (Fig. 5.2 model, Table 5.1)".into(),
        x_label: "admittance inertia m_adm (kg)".into(),
        panels: vec![
            Panel {
                title: "without compensation (M_qr ≠ 0, Fig. 5.3b)".into(),
                y_label: "max Re λ (1/s)".into(),
                lines: lines(|p| p.uncompensated),
                spans: vec![],
            },
            Panel {
                title: "with compensation (M_qr cancelled, Fig. 5.3a)".into(),
                y_label: "max Re λ (1/s)".into(),
                lines: lines(|p| p.compensated),
                spans: vec![],
            },
        ],
    }
}

/// Writes the region map [`MAP_FILE`] into `out` (the runner writes the grid as [`CSV_FILE`]);
/// the runner calls this after writing the [`Outcome`]. Returns the file names.
pub fn write_files(out: &Path, outcome: &Outcome) -> Result<Vec<&'static str>, String> {
    let m = outcome.series.column("m_adm").unwrap_or_default();
    let d = outcome.series.column("d_adm").unwrap_or_default();
    let off = outcome.series.column("max_real_eig_uncompensated").unwrap_or_default();
    let on = outcome.series.column("max_real_eig_compensated").unwrap_or_default();
    let path = out.join(MAP_FILE);
    let root = SVGBackend::new(&path, (1200, 560)).into_drawing_area();
    draw_maps(&root, &m, &d, [&on, &off]).map_err(|e| format!("plot {}: {e}", path.display()))?;
    root.present().map_err(|e| format!("plot {}: {e}", path.display()))?;
    Ok(vec![MAP_FILE])
}

type DrawResult = Result<(), Box<dyn std::error::Error>>;

fn draw_maps(
    root: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    m: &[f64],
    d: &[f64],
    cases: [&[f64]; 2],
) -> DrawResult {
    root.fill(&WHITE)?;
    let root = root.titled(
        "Stable and unstable closed-loop poles of the linear mobile robot (cf. Fig. 5.3)",
        ("sans-serif", 22),
    )?;
    let captions = ["(a) with compensation of M_qr (5.14)", "(b) without compensation, M_qr ≠ 0"];
    let half = GRID_STEP / 2.0;
    for ((area, values), caption) in root.split_evenly((1, 2)).iter().zip(cases).zip(captions) {
        let mut chart = ChartBuilder::on(area)
            .caption(caption, ("sans-serif", 17))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..1.5, 0.0..1.0)?;
        chart
            .configure_mesh()
            .x_desc("admittance inertia m_adm (kg)")
            .y_desc("admittance damping d_adm (kg/s)")
            .label_style(("sans-serif", 13))
            .axis_desc_style(("sans-serif", 14))
            .draw()?;
        let stable = RGBColor(170, 215, 170);
        let unstable = RGBColor(230, 120, 110);
        chart.draw_series(m.iter().zip(d).zip(values.iter()).map(|((m, d), v)| {
            let color = if *v > STABLE_TOLERANCE { unstable } else { stable };
            Rectangle::new([(m - half, d - half), (m + half, d + half)], color.filled())
        }))?;
        for (label, color) in [("stable", stable), ("unstable", unstable)] {
            chart
                .draw_series(std::iter::once(Rectangle::new([(0.0, 0.0), (0.0, 0.0)], color.filled())))?
                .label(label)
                .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 14, y + 6)], color.filled()));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(150, 150, 150))
            .draw()?;
    }
    Ok(())
}
