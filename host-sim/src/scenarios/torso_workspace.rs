//! `torso_workspace`: the workspace of the tendon-coupled torso under load (Fig. 3.16).
//!
//! The torso centre point `p_t = (x, z)` moves in the torso's sagittal plane: `x` horizontal
//! and forward, `z` up along the vertical joint `q_t1`, both relative to the axis of the first
//! pitch joint `q_t2` ([`TorsoGeometry`](kernel::tasks::torso_workspace::TorsoGeometry), (3.42)). With the Justin-like geometry
//! (`l_t2 = l_t3 = 0.3 m`, the ranges of Table 3.2) and the torque limits ±230 Nm of Fig. 3.16,
//! the scenario samples the plane on a [`GRID_STEP_M`] grid for the four loads of Fig. 3.16
//! ([`CASES`]) and classifies every point: out of kinematic reach (Table 3.2 / Table A.1), or
//! reachable and then feasible or excluded by the joint-2 torque (3.48), the joint-3 torque
//! (3.49) or both. The load torques come from (3.45) at the point's unique inverse kinematics
//! (`q_t3 ≥ 0`).
//!
//! Outputs: `summary.json` (areas and excluded fractions per case, the claims),
//! `torso_workspace_grid.csv` (a static map, so no time column: one row per reachable point of a 1 cm
//! sub-grid and case, `case` first), `excluded_fraction.svg` (excluded share of the
//! kinematic workspace over the load). The region map of the four cases, the figure to look at
//! first, is drawn by [`write_files`] (2×2 panels with equal axes, `torso_workspace_region_map.svg`):
//! the runner's line plots cannot fill regions.
//!
//! Claims (Sec. 3.3.3):
//! - the kinematic workspace area from the grid agrees with the joint-space integral
//!   `∫∫ l_t2 l_t3 sin q_t3 dq_t2 dq_t3` within 1 %; the excluded fractions within 1 point;
//! - 550 N, 90°: the joint-3 constraints vanish ("At the point of overlapping, the constraints
//!   vanish", Fig. 3.16d): no reachable point is excluded by the joint-3 torque;
//! - 800 N, 90°: they exist and exclude more than 10 % of the kinematic workspace (Fig. 3.16a);
//! - the feasible workspace shrinks with the load, 550 N > 800 N > 1200 N ("If `F_t,load`
//!   gets smaller, … the workspace grows");
//! - every joint-3 circle centre lies on a joint-2 line (symmetric limits, Sec. 3.3.3);
//! - the signed boundary distances of the task agree with the torque check at every point.
//!
//! Note: with `l_t2 + l_t3 = 0.6 m` the joint-2 limit still cuts the far front of the workspace
//! (`x > 230/550 = 0.42 m`) at 550 N; the thesis' "the constraints vanish" refers to the
//! joint-3 half circles.

use std::path::Path;

use kernel::tasks::torso_workspace::{
    direction, joint2_lines, Boundary, BoundaryCurve, RepulsionGains, TorqueBand, TorqueLimits, TorsoLoad,
    TorsoWorkspace, TorsoWorkspaceConfig,
};
use nalgebra::Vector2;
use plotters::prelude::*;

use super::{Outcome, RunOptions};
use crate::output::{Figure, Line, Panel, Span, Summary, TimeSeries};

/// Registry name.
pub const NAME: &str = "torso_workspace";
/// One-line description.
pub const DESCRIPTION: &str =
    "torso workspace of Fig. 3.16: kinematic arcs (Table A.1) and torque limits for 4 loads, ±230 Nm";
/// Torque limit of both driven torso joints (Nm), Fig. 3.16.
pub const TORQUE_LIMIT_NM: f64 = 230.0;
/// Grid step of the torso-plane sampling (m).
pub const GRID_STEP_M: f64 = 0.005;
/// Every how many grid points (in x and z) a reachable point is written to the CSV (1 cm).
pub const CSV_STRIDE: usize = 2;
/// Sampled region of the torso plane: `x` range (m).
pub const X_RANGE_M: (f64, f64) = (-0.36, 0.66);
/// Sampled region of the torso plane: `z` range (m).
pub const Z_RANGE_M: (f64, f64) = (-0.30, 0.66);
/// Joint-space integration grid (points per joint).
pub const JOINT_GRID: usize = 600;
/// Joint-space grid of the load sweep figure (points per joint).
pub const SWEEP_GRID: usize = 150;

/// One load case of Fig. 3.16.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadCase {
    /// Panel letter of Fig. 3.16.
    pub label: &'static str,
    /// `F_t,load` (N).
    pub force_n: f64,
    /// `α` (degrees).
    pub angle_deg: f64,
}

/// The four panels of Fig. 3.16.
pub const CASES: [LoadCase; 4] = [
    LoadCase { label: "a", force_n: 800.0, angle_deg: 90.0 },
    LoadCase { label: "b", force_n: 800.0, angle_deg: 70.0 },
    LoadCase { label: "c", force_n: 1200.0, angle_deg: 90.0 },
    LoadCase { label: "d", force_n: 550.0, angle_deg: 90.0 },
];

/// Class of a grid point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cell {
    /// Outside the kinematic workspace.
    Unreachable,
    /// Reachable and both load torques within the limits.
    Feasible,
    /// Reachable, only the joint-2 torque out of its limits.
    Joint2,
    /// Reachable, only the joint-3 torque out of its limits.
    Joint3,
    /// Reachable, both torques out of their limits.
    Both,
}

/// Areas and fractions of one case.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CaseStats {
    /// Area of the kinematic workspace on the grid (m²).
    pub kinematic_area_m2: f64,
    /// Area of the feasible (kinematic and dynamic) workspace on the grid (m²).
    pub feasible_area_m2: f64,
    /// Share of the kinematic workspace excluded by the torque limits (grid).
    pub excluded_fraction: f64,
    /// Share excluded by the joint-2 torque (alone or with joint 3).
    pub excluded_by_joint2_fraction: f64,
    /// Share excluded by the joint-3 torque (alone or with joint 2).
    pub excluded_by_joint3_fraction: f64,
    /// Kinematic workspace area from the joint-space integral (m²).
    pub joint_space_area_m2: f64,
    /// Excluded share from the joint-space integral.
    pub joint_space_excluded_fraction: f64,
    /// Share excluded by joint 3 from the joint-space integral.
    pub joint_space_excluded_by_joint3_fraction: f64,
    /// Reachable grid points where the sign of the smallest dynamic boundary distance
    /// disagrees with the torque check (points within 1e-9 m of a boundary excepted).
    pub distance_mismatches: usize,
}

/// The sampled map of one case.
#[derive(Clone, Debug)]
pub struct CaseMap {
    /// The load case.
    pub case: LoadCase,
    /// The task (its boundaries for this load).
    pub task: TorsoWorkspace<f64, 2>,
    /// Grid point `x` values (m), cell centres.
    pub xs: Vec<f64>,
    /// Grid point `z` values (m), cell centres.
    pub zs: Vec<f64>,
    /// Classes, row-major: index `iz * xs.len() + ix`.
    pub cells: Vec<Cell>,
    /// Areas and fractions.
    pub stats: CaseStats,
}

/// The torso-workspace task of `case` (Justin-like geometry, ±230 Nm, gains of Sec. 3.3.5,
/// coordinates `[q_t2, q_t3] = [0, 1]`).
pub fn task(case: &LoadCase) -> Result<TorsoWorkspace<f64, 2>, String> {
    let config = TorsoWorkspaceConfig {
        geometry: fixtures::justin::torso_geometry(),
        torque_limits: TorqueLimits::symmetric(TORQUE_LIMIT_NM),
        load: TorsoLoad::from_degrees(case.force_n, case.angle_deg),
        gains: RepulsionGains::thesis_experiment(),
        coordinates: [0, 1],
    };
    TorsoWorkspace::try_new(config).map_err(|e| format!("torso workspace: {e}"))
}

/// Cell centres from `lo` to `hi` with `step`.
fn axis(range: (f64, f64), step: f64) -> Vec<f64> {
    let count = ((range.1 - range.0) / step).round() as usize;
    (0..count).map(|i| range.0 + (i as f64 + 0.5) * step).collect()
}

/// Classifies `(q_t2, q_t3)` for `task`; also whether the signed distances agree.
fn classify(task: &TorsoWorkspace<f64, 2>, q2: f64, q3: f64) -> (Cell, bool) {
    let report = task.report(q2, q3);
    if !report.kinematically_feasible {
        return (Cell::Unreachable, true);
    }
    let limits = &task.config().torque_limits;
    let (ok2, ok3) = (limits.joint2.contains(report.load_torque.x), limits.joint3.contains(report.load_torque.y));
    let cell = match (ok2, ok3) {
        (true, true) => Cell::Feasible,
        (false, true) => Cell::Joint2,
        (true, false) => Cell::Joint3,
        (false, false) => Cell::Both,
    };
    // On a boundary (|d| ≤ 1e-9 m, e.g. grid points exactly on a τ_t2 line) either verdict is
    // right; elsewhere the sign of the smallest dynamic distance must match the torque check.
    let nearest = Boundary::ALL
        .iter()
        .filter(|b| !b.is_kinematic())
        .filter_map(|b| report.distance(*b))
        .fold(f64::INFINITY, f64::min);
    let tolerance = 1e-9;
    let agree = nearest.abs() <= tolerance || (nearest > 0.0) == report.dynamically_feasible;
    (cell, agree)
}

/// Kinematic area (m²) and the excluded shares (total, by joint 2, by joint 3) by the midpoint
/// rule in joint space with the area element `|det J_t| = l_t2 l_t3 sin q_t3`, `points` per
/// joint.
pub fn joint_space_fractions(task: &TorsoWorkspace<f64, 2>, points: usize) -> (f64, [f64; 3]) {
    let g = task.config().geometry;
    let (h2, h3) = ((g.joint2.max - g.joint2.min) / points as f64, (g.joint3.max - g.joint3.min) / points as f64);
    let (mut area, mut excluded) = (0.0, [0.0; 3]);
    for i in 0..points {
        let q2 = g.joint2.min + (i as f64 + 0.5) * h2;
        for k in 0..points {
            let q3 = g.joint3.min + (k as f64 + 0.5) * h3;
            let (cell, _) = classify(task, q2, q3);
            if cell == Cell::Unreachable {
                continue;
            }
            let w = g.link2 * g.link3 * q3.sin() * h2 * h3;
            area += w;
            let flags = [
                cell != Cell::Feasible,
                matches!(cell, Cell::Joint2 | Cell::Both),
                matches!(cell, Cell::Joint3 | Cell::Both),
            ];
            for (sum, flag) in excluded.iter_mut().zip(flags) {
                if flag {
                    *sum += w;
                }
            }
        }
    }
    (area, excluded.map(|e| e / area))
}

/// Samples the torso plane for `case`.
pub fn map_case(case: &LoadCase) -> Result<CaseMap, String> {
    let task = task(case)?;
    let g = task.config().geometry;
    let (xs, zs) = (axis(X_RANGE_M, GRID_STEP_M), axis(Z_RANGE_M, GRID_STEP_M));
    let mut cells = Vec::with_capacity(xs.len() * zs.len());
    let mut mismatches = 0;
    for z in &zs {
        for x in &xs {
            let cell = match g.inverse_kinematics(&Vector2::new(*x, *z)) {
                Some([q2, q3]) => {
                    let (cell, agree) = classify(&task, q2, q3);
                    mismatches += usize::from(!agree);
                    cell
                }
                None => Cell::Unreachable,
            };
            cells.push(cell);
        }
    }
    let count = |f: &dyn Fn(Cell) -> bool| cells.iter().filter(|c| f(**c)).count() as f64;
    let reachable = count(&|c| c != Cell::Unreachable);
    let cell_area = GRID_STEP_M * GRID_STEP_M;
    let (joint_area, [joint_excluded, _, joint_excluded3]) = joint_space_fractions(&task, JOINT_GRID);
    let stats = CaseStats {
        kinematic_area_m2: reachable * cell_area,
        feasible_area_m2: count(&|c| c == Cell::Feasible) * cell_area,
        excluded_fraction: count(&|c| matches!(c, Cell::Joint2 | Cell::Joint3 | Cell::Both)) / reachable,
        excluded_by_joint2_fraction: count(&|c| matches!(c, Cell::Joint2 | Cell::Both)) / reachable,
        excluded_by_joint3_fraction: count(&|c| matches!(c, Cell::Joint3 | Cell::Both)) / reachable,
        joint_space_area_m2: joint_area,
        joint_space_excluded_fraction: joint_excluded,
        joint_space_excluded_by_joint3_fraction: joint_excluded3,
        distance_mismatches: mismatches,
    };
    Ok(CaseMap { case: *case, task, xs, zs, cells, stats })
}

/// Largest distance (m) of a joint-3 circle centre from the nearer joint-2 line.
fn centre_line_offset(task: &TorsoWorkspace<f64, 2>) -> f64 {
    let c = task.config();
    let Some(lines) = joint2_lines(&c.load, &c.torque_limits.joint2) else { return 0.0 };
    let mut worst: f64 = 0.0;
    for limit in [c.torque_limits.joint3.min, c.torque_limits.joint3.max] {
        if let Some(band) = TorqueBand::new(c.geometry.link3, &c.load, limit) {
            for phi in band.boundaries() {
                let centre = direction(phi) * c.geometry.link3;
                let offset =
                    lines.iter().map(|l| (l.normal.dot(&centre) + l.offset).abs()).fold(f64::INFINITY, f64::min);
                worst = worst.max(offset);
            }
        }
    }
    worst
}

/// Runs the scenario (see the module docs).
pub fn simulate(_options: &RunOptions) -> Result<Outcome, String> {
    // A static map: no simulated time to report, no plant.
    let maps = CASES.iter().map(map_case).collect::<Result<Vec<_>, _>>()?;
    let summary = summarize(&maps);
    Ok(Outcome { summary, series: samples(&maps)?, figures: vec![("excluded_fraction.svg", sweep_figure()?)] })
}

/// Metrics and claims.
fn summarize(maps: &[CaseMap]) -> Summary {
    let mut s = Summary::new(NAME);
    s.metric("grid_step_m", GRID_STEP_M)
        .metric("torque_limit_nm", TORQUE_LIMIT_NM)
        .metric("link_length_t2_m", 0.3)
        .metric("link_length_t3_m", 0.3);
    let find = |label: &str| maps.iter().find(|m| m.case.label == label).map(|m| m.stats);
    let mut area_ok = true;
    let mut fractions_ok = true;
    for m in maps {
        let (p, st) = (format!("case_{}", m.case.label), &m.stats);
        s.metric(&format!("{p}_force_n"), m.case.force_n)
            .metric(&format!("{p}_angle_deg"), m.case.angle_deg)
            .metric(&format!("{p}_kinematic_area_m2"), st.kinematic_area_m2)
            .metric(&format!("{p}_feasible_area_m2"), st.feasible_area_m2)
            .metric(&format!("{p}_excluded_fraction"), st.excluded_fraction)
            .metric(&format!("{p}_excluded_by_joint2_fraction"), st.excluded_by_joint2_fraction)
            .metric(&format!("{p}_excluded_by_joint3_fraction"), st.excluded_by_joint3_fraction)
            .metric(&format!("{p}_joint_space_excluded_fraction"), st.joint_space_excluded_fraction)
            .metric(&format!("{p}_joint_space_excluded_by_joint3_fraction"), st.joint_space_excluded_by_joint3_fraction)
            .value(&format!("{p}_distance_mismatches"), st.distance_mismatches)
            .metric(&format!("{p}_circle_centre_line_offset_m"), centre_line_offset(&m.task));
        area_ok &= (st.kinematic_area_m2 / st.joint_space_area_m2 - 1.0).abs() < 0.01;
        fractions_ok &= (st.excluded_fraction - st.joint_space_excluded_fraction).abs() < 0.01
            && (st.excluded_by_joint3_fraction - st.joint_space_excluded_by_joint3_fraction).abs() < 0.01;
    }
    if let Some(first) = maps.first() {
        s.metric("kinematic_area_m2", first.stats.kinematic_area_m2)
            .metric("kinematic_area_joint_space_m2", first.stats.joint_space_area_m2);
    }
    s.claim("kinematic workspace area: grid and joint-space integral agree within 1 %", area_ok);
    s.claim("excluded fractions: grid and joint-space integral agree within 1 point", fractions_ok);
    let (a, c, d) = (find("a"), find("c"), find("d"));
    s.claim(
        "550 N, 90°: the joint-3 constraints vanish (Fig. 3.16d): nothing excluded by joint 3",
        d.is_some_and(|d| d.excluded_by_joint3_fraction == 0.0 && d.joint_space_excluded_by_joint3_fraction == 0.0),
    );
    s.claim(
        "800 N, 90°: the joint-3 constraints exclude more than 10 % of the kinematic workspace (Fig. 3.16a)",
        a.is_some_and(|a| a.excluded_by_joint3_fraction > 0.1),
    );
    s.claim(
        "the feasible workspace shrinks with the load: 550 N > 800 N > 1200 N (alpha = 90°)",
        matches!((a, c, d), (Some(a), Some(c), Some(d)) if d.feasible_area_m2 > a.feasible_area_m2 && a.feasible_area_m2 > c.feasible_area_m2),
    );
    s.claim(
        "symmetric limits: every joint-3 circle centre lies on a joint-2 line (Sec. 3.3.3)",
        maps.iter().all(|m| centre_line_offset(&m.task) < 1e-12),
    );
    s.claim(
        "the signed boundary distances agree with the torque check at every reachable grid point",
        maps.iter().all(|m| m.stats.distance_mismatches == 0),
    );
    s
}

/// The CSV table: reachable points of the 1 cm sub-grid, all cases.
fn samples(maps: &[CaseMap]) -> Result<TimeSeries, String> {
    let columns = [
        "case",
        "force_n",
        "angle_deg",
        "x_m",
        "z_m",
        "q_t2_rad",
        "q_t3_rad",
        "tau_t2_nm",
        "tau_t3_nm",
        "feasible",
        "excluded_by_joint2",
        "excluded_by_joint3",
        "nearest_boundary",
        "nearest_distance_m",
    ];
    let mut series = TimeSeries::new(columns.iter().map(|c| (*c).to_owned()).collect());
    for (index, m) in maps.iter().enumerate() {
        let g = m.task.config().geometry;
        for (iz, z) in m.zs.iter().enumerate().step_by(CSV_STRIDE) {
            for (ix, x) in m.xs.iter().enumerate().step_by(CSV_STRIDE) {
                let cell = m.cells.get(iz * m.xs.len() + ix).copied().unwrap_or(Cell::Unreachable);
                let Some([q2, q3]) = g.inverse_kinematics(&Vector2::new(*x, *z)) else { continue };
                if cell == Cell::Unreachable {
                    continue;
                }
                let report = m.task.report(q2, q3);
                let (nearest, distance) = report.nearest().map_or((f64::NAN, f64::NAN), |(b, d)| (b.index() as f64, d));
                let flag = |b: bool| if b { 1.0 } else { 0.0 };
                series.push(vec![
                    index as f64,
                    m.case.force_n,
                    m.case.angle_deg,
                    *x,
                    *z,
                    q2,
                    q3,
                    report.load_torque.x,
                    report.load_torque.y,
                    flag(cell == Cell::Feasible),
                    flag(matches!(cell, Cell::Joint2 | Cell::Both)),
                    flag(matches!(cell, Cell::Joint3 | Cell::Both)),
                    nearest,
                    distance,
                ])?;
            }
        }
    }
    Ok(series)
}

/// Excluded share of the kinematic workspace over the load, α = 90° and 70° (joint-space
/// integral on a coarser grid).
fn sweep_figure() -> Result<Figure, String> {
    let mut panels = Vec::new();
    for angle in [90.0, 70.0] {
        let (mut total, mut joint2, mut joint3) = (Vec::new(), Vec::new(), Vec::new());
        for step in 0..=60 {
            let force = 25.0 * f64::from(step);
            let case = LoadCase { label: "", force_n: force, angle_deg: angle };
            let (_, [excluded, by2, by3]) = joint_space_fractions(&task(&case)?, SWEEP_GRID);
            total.push((force, 100.0 * excluded));
            joint2.push((force, 100.0 * by2));
            joint3.push((force, 100.0 * by3));
        }
        let marks = CASES.iter().filter(|c| c.angle_deg == angle);
        panels.push(Panel {
            title: format!("load direction α = {angle}°, torque limits ±{TORQUE_LIMIT_NM} Nm"),
            y_label: "excluded share of kinematic workspace (%)".into(),
            lines: vec![
                Line::new("both limits", total),
                Line::new("joint-2 limit (lines 3.48)", joint2),
                Line::new("joint-3 limit (half circles 3.49)", joint3),
            ],
            spans: marks
                .map(|c| Span { label: format!("Fig. 3.16{}", c.label), from: c.force_n, to: c.force_n })
                .collect(),
        });
    }
    Ok(Figure {
        title: "Torso workspace excluded by the load torques (l_t2 = l_t3 = 0.3 m)".into(),
        x_label: "load F_t,load at the torso centre point (N)".into(),
        panels,
    })
}

/// Colours of the classes.
fn fill(cell: Cell) -> Option<RGBColor> {
    match cell {
        Cell::Unreachable => None,
        Cell::Feasible => Some(RGBColor(140, 205, 140)),
        Cell::Joint2 => Some(RGBColor(250, 205, 140)),
        Cell::Joint3 => Some(RGBColor(160, 190, 240)),
        Cell::Both => Some(RGBColor(235, 140, 140)),
    }
}

const KINEMATIC: RGBColor = RGBColor(0, 0, 0);
const JOINT2_LINE: RGBColor = RGBColor(200, 110, 0);
const JOINT3_LINE: RGBColor = RGBColor(30, 70, 180);

/// Points of an arc for drawing.
fn arc_points(arc: &kernel::tasks::torso_workspace::Arc<f64>) -> Vec<(f64, f64)> {
    (0..=120)
        .map(|k| {
            let p = arc.point(arc.start + (arc.end - arc.start) * f64::from(k) / 120.0);
            (p.x, p.y)
        })
        .collect()
}

/// Clips the line `n·p + o = 0` to the sampled rectangle.
fn clip_line(normal: Vector2<f64>, offset: f64) -> Vec<(f64, f64)> {
    let (x0, x1, z0, z1) = (X_RANGE_M.0, X_RANGE_M.1, Z_RANGE_M.0, Z_RANGE_M.1);
    let mut points = Vec::new();
    // Intersections with the four sides.
    for x in [x0, x1] {
        if normal.y.abs() > 1e-12 {
            let z = -(offset + normal.x * x) / normal.y;
            if (z0..=z1).contains(&z) {
                points.push((x, z));
            }
        }
    }
    for z in [z0, z1] {
        if normal.x.abs() > 1e-12 {
            let x = -(offset + normal.y * z) / normal.x;
            if (x0..=x1).contains(&x) {
                points.push((x, z));
            }
        }
    }
    points.truncate(2);
    points
}

/// Axis tick text with one decimal and no "-0.0".
fn tick(value: f64) -> String {
    let value = if value.abs() < 1e-9 { 0.0 } else { value };
    format!("{value:.1}")
}

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;
type DrawResult = Result<(), Box<dyn std::error::Error>>;

/// File name of the region map written by [`write_files`].
pub const REGION_MAP_FILE: &str = "torso_workspace_region_map.svg";
/// The sampled grid (every cell's joint angles and class), written by the runner.
pub const GRID_FILE: &str = "torso_workspace_grid.csv";

/// Samples the four cases and writes the region map [`REGION_MAP_FILE`] into `out`; returns
/// the file names written. `output::plot` draws only line figures, so the runner has to call
/// this in addition to writing the [`Outcome`].
pub fn write_files(out: &Path, _outcome: &Outcome) -> Result<Vec<&'static str>, String> {
    let maps = CASES.iter().map(map_case).collect::<Result<Vec<_>, _>>()?;
    write_region_map(&out.join(REGION_MAP_FILE), &maps)?;
    Ok(vec![REGION_MAP_FILE])
}

/// Draws the 2×2 region map of the four cases into `path` (SVG): filled classes, the six
/// kinematic arcs (Table A.1, black), the joint-2 lines (orange, dashed) and the joint-3
/// half circles (blue), the `q_t2` axis and the load direction.
pub fn write_region_map(path: &Path, maps: &[CaseMap]) -> Result<(), String> {
    let root = SVGBackend::new(path, (1240, 1330)).into_drawing_area();
    draw_map(&root, maps).map_err(|e| format!("plot {}: {e}", path.display()))?;
    root.present().map_err(|e| format!("plot {}: {e}", path.display()))
}

fn draw_map(root: &Area<'_>, maps: &[CaseMap]) -> DrawResult {
    root.fill(&WHITE)?;
    let root = root.titled(
        "Torso workspace of the torso centre point under load (Fig. 3.16), torque limits ±230 Nm",
        ("sans-serif", 24),
    )?;
    let (panels, legend) = root.split_vertically(1230);
    for (map, area) in maps.iter().zip(panels.split_evenly((2, 2)).iter()) {
        draw_case(area, map)?;
    }
    draw_legend(&legend)
}

fn draw_case(area: &Area<'_>, map: &CaseMap) -> DrawResult {
    let st = &map.stats;
    let caption = format!(
        "({}) F = {} N, α = {}°: {:.0} % of the kinematic workspace excluded",
        map.case.label,
        map.case.force_n,
        map.case.angle_deg,
        100.0 * st.excluded_fraction
    );
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 17))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(X_RANGE_M.0..X_RANGE_M.1, Z_RANGE_M.0..Z_RANGE_M.1)?;
    chart
        .configure_mesh()
        .x_desc("x: forward from the q_t2 axis (m)")
        .y_desc("z: up from the q_t2 axis (m)")
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| tick(*v))
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 14))
        .light_line_style(RGBColor(240, 240, 240))
        .draw()?;
    // Runs of equal class per grid row.
    let half = GRID_STEP_M / 2.0;
    let mut rects = Vec::new();
    for (iz, z) in map.zs.iter().enumerate() {
        let row = map.cells.get(iz * map.xs.len()..(iz + 1) * map.xs.len()).unwrap_or(&[]);
        let mut start = 0;
        while start < row.len() {
            let class = row.get(start).copied().unwrap_or(Cell::Unreachable);
            let mut end = start;
            while row.get(end + 1) == Some(&class) {
                end += 1;
            }
            if let (Some(color), Some(x0), Some(x1)) = (fill(class), map.xs.get(start), map.xs.get(end)) {
                rects.push(Rectangle::new([(x0 - half, z - half), (x1 + half, z + half)], color.filled()));
            }
            start = end + 1;
        }
    }
    chart.draw_series(rects)?;
    for boundary in Boundary::ALL {
        match map.task.curve(boundary) {
            BoundaryCurve::Absent => {}
            BoundaryCurve::Arc(arc) => {
                let color = if boundary.is_kinematic() { KINEMATIC } else { JOINT3_LINE };
                chart.draw_series(LineSeries::new(arc_points(&arc), color.stroke_width(2)))?;
            }
            BoundaryCurve::Line(line) => {
                let points = clip_line(line.normal, line.offset);
                chart.draw_series(DashedLineSeries::new(points, 9, 6, JOINT2_LINE.stroke_width(2)))?;
            }
        }
    }
    // q_t2 axis and load direction (3.44) drawn from the upper left corner.
    chart.draw_series(std::iter::once(Cross::new((0.0, 0.0), 6, KINEMATIC.stroke_width(2))))?;
    chart.draw_series(std::iter::once(Text::new("q_t2 axis", (0.015, -0.03), ("sans-serif", 13))))?;
    let load = map.task.config().load;
    let tail = (-0.28, 0.58);
    let dir = load.vector() / load.force.max(1e-9) * 0.12;
    let head = (tail.0 + dir.x, tail.1 + dir.y);
    chart.draw_series(std::iter::once(PathElement::new(vec![tail, head], KINEMATIC.stroke_width(2))))?;
    let back = -dir / dir.norm().max(1e-9) * 0.025;
    for turn in [0.45_f64, -0.45] {
        let (s, c) = turn.sin_cos();
        let wing = Vector2::new(c * back.x - s * back.y, s * back.x + c * back.y);
        chart.draw_series(std::iter::once(PathElement::new(
            vec![head, (head.0 + wing.x, head.1 + wing.y)],
            KINEMATIC.stroke_width(2),
        )))?;
    }
    chart.draw_series(std::iter::once(Text::new("F_t", (tail.0 + 0.02, tail.1 + 0.02), ("sans-serif", 14))))?;
    Ok(())
}

fn draw_legend(area: &Area<'_>) -> DrawResult {
    let entries: [(&str, RGBColor, bool); 7] = [
        ("feasible", RGBColor(140, 205, 140), true),
        ("excluded by τ_t2 limit", RGBColor(250, 205, 140), true),
        ("excluded by τ_t3 limit", RGBColor(160, 190, 240), true),
        ("excluded by both", RGBColor(235, 140, 140), true),
        ("kinematic arcs (Table A.1)", KINEMATIC, false),
        ("τ_t2 limits (3.48)", JOINT2_LINE, false),
        ("τ_t3 limits (3.49)", JOINT3_LINE, false),
    ];
    let mut x = 20;
    for (label, color, filled) in entries {
        if filled {
            area.draw(&Rectangle::new([(x, 20), (x + 22, 36)], color.filled()))?;
        } else {
            area.draw(&PathElement::new(vec![(x, 28), (x + 22, 28)], color.stroke_width(3)))?;
        }
        area.draw(&Text::new(label, (x + 28, 21), ("sans-serif", 14)))?;
        x += 30 + 8 * i32::try_from(label.chars().count()).unwrap_or(20);
    }
    Ok(())
}
