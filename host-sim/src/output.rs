//! The scenario output convention; every column and its unit is listed in `docs/OUTPUT.md`.
//!
//! Every scenario writes into its output directory:
//! - `timeseries.csv`: a header row, `t` (s) first, then `q.<joint>`, `dq.<joint>`,
//!   `tau.<joint>` per joint, task errors `e<level>.<axis>` (signed `x − x_des` in the task's
//!   units), storage functions `S<level>` and activations `a.<row>` where defined, then the
//!   scenario's own signals ([`TimeSeries`]); an undefined value is an empty cell;
//! - `summary.json`: a flat JSON object of named metrics (snake_case with a unit suffix),
//!   `"scenario"`, `"passed_claims"` and `"failed_claims"` ([`Summary`]);
//! - `*.svg`: plots ([`plot`]), drawn with `plotters`' SVG backend (text as SVG `<text>`, no
//!   font files needed).

use std::fmt::Write as _;
use std::fs;
use std::path::Path;

use plotters::prelude::*;
use serde_json::{Map, Value};

/// A table of samples with named columns, `t` first.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TimeSeries {
    columns: Vec<String>,
    rows: Vec<Vec<f64>>,
}

impl TimeSeries {
    /// An empty table with the given column names (the first should be `t`).
    pub fn new(columns: Vec<String>) -> Self {
        Self { columns, rows: Vec::new() }
    }

    /// The column names.
    pub fn columns(&self) -> &[String] {
        &self.columns
    }

    /// The rows.
    pub fn rows(&self) -> &[Vec<f64>] {
        &self.rows
    }

    /// Appends a row. Errors if its length differs from the number of columns.
    pub fn push(&mut self, row: Vec<f64>) -> Result<(), String> {
        if row.len() != self.columns.len() {
            return Err(format!("row has {} values for {} columns", row.len(), self.columns.len()));
        }
        self.rows.push(row);
        Ok(())
    }

    /// All values of column `name`, or `None` if there is no such column.
    pub fn column(&self, name: &str) -> Option<Vec<f64>> {
        let index = self.columns.iter().position(|c| c == name)?;
        Some(self.rows.iter().filter_map(|r| r.get(index).copied()).collect())
    }

    /// Writes the table as CSV: the header row, then every `every`-th sample (the first
    /// included; `every` = 0 counts as 1), each value in its shortest round-trip decimal
    /// representation and an undefined (non-finite) value as an empty cell.
    pub fn write_csv(&self, path: &Path, every: u64) -> Result<(), String> {
        fs::write(path, self.csv(every)).map_err(|e| format!("cannot write {}: {e}", path.display()))
    }

    /// The CSV text of [`TimeSeries::write_csv`].
    pub fn csv(&self, every: u64) -> String {
        let every = usize::try_from(every).unwrap_or(usize::MAX).max(1);
        let mut text = self.columns.join(",");
        text.push('\n');
        for row in self.rows.iter().step_by(every) {
            for (i, x) in row.iter().enumerate() {
                if i > 0 {
                    text.push(',');
                }
                if x.is_finite() {
                    let _ = write!(text, "{x}");
                }
            }
            text.push('\n');
        }
        text
    }
}

/// The summary of one scenario run: named metrics and the claims it checked.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    scenario: String,
    metrics: Map<String, Value>,
    passed: Vec<String>,
    failed: Vec<String>,
}

impl Summary {
    /// An empty summary of scenario `scenario`.
    pub fn new(scenario: &str) -> Self {
        Self { scenario: scenario.to_owned(), metrics: Map::new(), passed: Vec::new(), failed: Vec::new() }
    }

    /// Records a numeric metric (`snake_case_unit`, e.g. `settle_time_s`). Non-finite values are
    /// written as JSON `null`.
    pub fn metric(&mut self, name: &str, value: f64) -> &mut Self {
        self.metrics.insert(name.to_owned(), serde_json::Number::from_f64(value).map_or(Value::Null, Value::Number));
        self
    }

    /// Records a non-numeric metric (count, flag, text).
    pub fn value(&mut self, name: &str, value: impl Into<Value>) -> &mut Self {
        self.metrics.insert(name.to_owned(), value.into());
        self
    }

    /// Records a claim and whether it held; returns `holds`.
    pub fn claim(&mut self, claim: &str, holds: bool) -> bool {
        if holds { &mut self.passed } else { &mut self.failed }.push(claim.to_owned());
        holds
    }

    /// The numeric metric `name`, if recorded and finite.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.metrics.get(name).and_then(Value::as_f64)
    }

    /// Claims that held.
    pub fn passed_claims(&self) -> &[String] {
        &self.passed
    }

    /// Claims that failed.
    pub fn failed_claims(&self) -> &[String] {
        &self.failed
    }

    /// The flat JSON object: metrics, `"scenario"`, `"passed_claims"`, `"failed_claims"`.
    pub fn to_json(&self) -> Value {
        let mut object = self.metrics.clone();
        object.insert("scenario".into(), Value::from(self.scenario.clone()));
        object.insert("passed_claims".into(), Value::from(self.passed.clone()));
        object.insert("failed_claims".into(), Value::from(self.failed.clone()));
        Value::Object(object)
    }

    /// Writes [`Summary::to_json`] pretty-printed.
    pub fn write_json(&self, path: &Path) -> Result<(), String> {
        let text = serde_json::to_string_pretty(&self.to_json()).map_err(|e| e.to_string())?;
        fs::write(path, text + "\n").map_err(|e| format!("cannot write {}: {e}", path.display()))
    }
}

/// One line of a plot.
#[derive(Clone, Debug, PartialEq)]
pub struct Line {
    /// Legend entry.
    pub label: String,
    /// `(x, y)` points.
    pub points: Vec<(f64, f64)>,
    /// Dashed grey line (for references such as targets and bounds).
    pub dashed: bool,
}

impl Line {
    /// A solid line.
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self { label: label.into(), points, dashed: false }
    }

    /// A dashed line.
    pub fn dashed(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self { label: label.into(), points, dashed: true }
    }
}

/// A shaded time window with a label (an event such as a push).
#[derive(Clone, Debug, PartialEq)]
pub struct Span {
    /// Legend entry.
    pub label: String,
    /// Start (x units).
    pub from: f64,
    /// End (x units); equal to `from` draws a vertical marker line.
    pub to: f64,
}

/// One panel (sub-plot) of a figure; panels are stacked vertically and share the x axis.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Panel {
    /// Panel caption.
    pub title: String,
    /// y-axis label with unit, e.g. `"error (mm)"`.
    pub y_label: String,
    /// The lines.
    pub lines: Vec<Line>,
    /// Shaded event windows.
    pub spans: Vec<Span>,
}

/// A figure: a title, a shared x-axis label and stacked panels.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure {
    /// Title on top of the figure.
    pub title: String,
    /// x-axis label with unit, e.g. `"time (s)"`.
    pub x_label: String,
    /// Panels, top to bottom.
    pub panels: Vec<Panel>,
}

/// Distinguishable line colours (Tableau 10), cycled.
const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Width of a figure (px) and height of each panel (px).
const WIDTH_PX: u32 = 1000;
const PANEL_HEIGHT_PX: u32 = 380;
const TITLE_HEIGHT_PX: u32 = 40;

/// Draws `figure` into an SVG file.
pub fn plot(path: &Path, figure: &Figure) -> Result<(), String> {
    let panels = u32::try_from(figure.panels.len().max(1)).map_err(|e| e.to_string())?;
    let height = TITLE_HEIGHT_PX + PANEL_HEIGHT_PX * panels;
    let root = SVGBackend::new(path, (WIDTH_PX, height)).into_drawing_area();
    draw(&root, figure).map_err(|e| format!("plot {}: {e}", path.display()))?;
    root.present().map_err(|e| format!("plot {}: {e}", path.display()))
}

type DrawResult = Result<(), Box<dyn std::error::Error>>;

fn draw(root: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>, figure: &Figure) -> DrawResult {
    root.fill(&WHITE)?;
    let root = root.titled(&figure.title, ("sans-serif", 24))?;
    let count = figure.panels.len().max(1);
    let areas = root.split_evenly((count, 1));
    for (panel, area) in figure.panels.iter().zip(areas.iter()) {
        draw_panel(area, panel, &figure.x_label)?;
    }
    Ok(())
}

/// A tick label: at most four significant decimals, trailing zeros dropped, never `-0`.
fn tick_label(value: f64) -> String {
    let text = format!("{value:.4}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".to_string()
    } else {
        text.to_string()
    }
}

fn draw_panel<'a>(
    area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    panel: &'a Panel,
    x_label: &str,
) -> DrawResult {
    let (x_range, y_range) = ranges(panel);
    let (x_range, y_range) = if drawn_to_scale(panel, x_label) {
        let (width, height) = area.dim_in_pixel();
        to_scale(x_range, y_range, f64::from(width) - PLOT_INSET_X_PX, f64::from(height) - PLOT_INSET_Y_PX)
    } else {
        (x_range, y_range)
    };
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x_range.clone(), y_range.clone())?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(&panel.y_label)
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(RGBColor(235, 235, 235))
        .x_label_formatter(&|x| tick_label(*x))
        .y_label_formatter(&|y| tick_label(*y))
        .draw()?;
    // One legend entry per label: a repeated label (a second band bound, repeated windows)
    // is drawn but not listed again.
    let mut listed: Vec<&str> = Vec::new();
    let mut first_listing = |label: &'a str| {
        let new = !label.is_empty() && !listed.contains(&label);
        if new {
            listed.push(label);
        }
        new
    };

    for span in &panel.spans {
        let shade = RGBColor(255, 200, 120);
        if span.to > span.from {
            let drawn = chart.draw_series(std::iter::once(Rectangle::new(
                [(span.from, y_range.start), (span.to, y_range.end)],
                shade.mix(0.35).filled(),
            )))?;
            if first_listing(&span.label) {
                drawn
                    .label(&span.label)
                    .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 18, y + 5)], shade.mix(0.6).filled()));
            }
        } else {
            let marker = RGBColor(90, 90, 90);
            let drawn = chart.draw_series(std::iter::once(PathElement::new(
                vec![(span.from, y_range.start), (span.from, y_range.end)],
                marker.stroke_width(1),
            )))?;
            if first_listing(&span.label) {
                drawn
                    .label(&span.label)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], marker.stroke_width(1)));
            }
        }
    }

    for (i, line) in panel.lines.iter().enumerate() {
        // Solid lines cycle through the palette; dashed reference lines are grey.
        let color = if line.dashed {
            RGBColor(100, 100, 100)
        } else {
            PALETTE.get(i % PALETTE.len()).copied().unwrap_or(BLACK)
        };
        let style = color.stroke_width(if line.dashed { 1 } else { 2 });
        let points = line.points.iter().copied();
        let drawn = if line.dashed {
            chart.draw_series(DashedLineSeries::new(points, 8, 5, style))?
        } else {
            chart.draw_series(LineSeries::new(points, style))?
        };
        // An empty label keeps the line out of the legend (e.g. the second bound of a band).
        if first_listing(&line.label) {
            // The legend sample is two segments: touching for a solid line, two 7 px dashes
            // with a gap for a dashed one.
            let [(a0, a1), (b0, b1)] = if line.dashed { [(0, 7), (11, 18)] } else { [(0, 9), (9, 18)] };
            drawn.label(&line.label).legend(move |(x, y)| {
                EmptyElement::at((x, y))
                    + PathElement::new(vec![(a0, 0), (a1, 0)], style)
                    + PathElement::new(vec![(b0, 0), (b1, 0)], style)
            });
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(180, 180, 180))
        .label_font(("sans-serif", 13))
        .draw()?;
    Ok(())
}

/// Pixels of a panel's width outside its plotting area: margins (2 × 12) and y labels (70).
const PLOT_INSET_X_PX: f64 = 94.0;
/// Pixels of a panel's height outside its plotting area: margins (2 × 12), x labels (40) and the
/// caption (about 30).
const PLOT_INSET_Y_PX: f64 = 94.0;

/// Whether a panel is a view of the world (a top or side view): both axes are world coordinates
/// (labels `world …`), drawn to the same scale.
fn drawn_to_scale(panel: &Panel, x_label: &str) -> bool {
    x_label.starts_with("world ") && panel.y_label.starts_with("world ")
}

/// `x` and `y` widened about their centres so that one unit is as long on both axes of a
/// plotting area of `width` × `height` px.
fn to_scale(
    x: std::ops::Range<f64>,
    y: std::ops::Range<f64>,
    width: f64,
    height: f64,
) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let per_px = ((x.end - x.start) / width).max((y.end - y.start) / height);
    let widen = |r: std::ops::Range<f64>, px: f64| {
        let (centre, half) = (0.5 * (r.start + r.end), 0.5 * per_px * px);
        (centre - half)..(centre + half)
    };
    (widen(x, width), widen(y, height))
}

/// Height of one legend entry and of the legend box's frame (px).
const LEGEND_ENTRY_PX: f64 = 19.0;
const LEGEND_FRAME_PX: f64 = 16.0;

/// The number of entries of a panel's legend: its distinct non-empty labels.
fn legend_entries(panel: &Panel) -> usize {
    let mut labels: Vec<&str> = panel.spans.iter().map(|s| s.label.as_str()).collect();
    labels.extend(panel.lines.iter().map(|l| l.label.as_str()));
    labels.retain(|l| !l.is_empty());
    labels.sort_unstable();
    labels.dedup();
    labels.len()
}

/// Data ranges of a panel with a 5 % margin below the data and, above it, a band as high as the
/// legend (which is drawn there, upper right, so it covers no data; at most 60 % of the panel);
/// degenerate ranges are widened.
fn ranges(panel: &Panel) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let points = || panel.lines.iter().flat_map(|l| l.points.iter()).filter(|(x, y)| x.is_finite() && y.is_finite());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for (x, y) in points() {
        x0 = x0.min(*x);
        x1 = x1.max(*x);
        y0 = y0.min(*y);
        y1 = y1.max(*y);
    }
    if !(x0.is_finite() && x1.is_finite()) {
        (x0, x1) = (0.0, 1.0);
    }
    if !(y0.is_finite() && y1.is_finite()) {
        (y0, y1) = (-1.0, 1.0);
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    let pad = if y1 > y0 { 0.05 * (y1 - y0) } else { 0.5 * y0.abs().max(1.0) };
    #[allow(clippy::cast_precision_loss, reason = "a few legend entries")]
    let legend_px = LEGEND_ENTRY_PX * legend_entries(panel) as f64 + LEGEND_FRAME_PX;
    let legend_share = (legend_px / (f64::from(PANEL_HEIGHT_PX) - PLOT_INSET_Y_PX)).min(0.6);
    let span = (y1 - y0 + 2.0 * pad) / (1.0 - legend_share);
    (x0..x1, (y0 - pad)..(y0 - pad + span))
}

/// Creates `dir` (and parents) if needed.
pub fn create_dir(dir: &Path) -> Result<(), String> {
    fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;

    #[test]
    fn an_undefined_value_is_an_empty_cell_and_every_nth_row_is_written() {
        let mut series = TimeSeries::new(vec!["t".into(), "a".into(), "b".into()]);
        for k in 0..5_u32 {
            let t = f64::from(k) * 1e-3;
            series.push(vec![t, f64::NAN, if k == 2 { f64::NEG_INFINITY } else { 1.5 }]).unwrap();
        }
        assert_eq!(series.csv(1), "t,a,b\n0,,1.5\n0.001,,1.5\n0.002,,\n0.003,,1.5\n0.004,,1.5\n");
        assert_eq!(series.csv(2), "t,a,b\n0,,1.5\n0.002,,\n0.004,,1.5\n");
        assert_eq!(series.csv(0), series.csv(1));
    }

    #[test]
    fn a_view_of_the_world_gets_one_scale_on_both_axes() {
        let panel = Panel { y_label: "world y (m)".into(), ..Panel::default() };
        assert!(drawn_to_scale(&panel, "world x (m)"));
        assert!(!drawn_to_scale(&panel, "time (s)"));
        // 4 m over 800 px and 1 m over 400 px: y widens to 2 m, x keeps its 4 m.
        let (x, y) = to_scale(0.0..4.0, 1.0..2.0, 800.0, 400.0);
        assert_eq!((x, y), (0.0..4.0, 0.5..2.5));
        let (x, y) = to_scale(0.0..1.0, 0.0..4.0, 800.0, 400.0);
        assert_eq!((x, y), (-3.5..4.5, 0.0..4.0));
    }

    #[test]
    fn the_legend_gets_a_band_above_the_data() {
        let line = |label: &str| Line::new(label, vec![(0.0, 0.0), (1.0, 1.0)]);
        let panel = Panel { lines: vec![line("a"), line("b"), line(""), line("a")], ..Panel::default() };
        assert_eq!(legend_entries(&panel), 2);
        let (_, y) = ranges(&panel);
        // Two entries: 54 px of the 286 px plotting height above the data (1.0 plus its 5 %).
        let band = (y.end - 1.05) / (y.end - y.start);
        assert!((band - 54.0 / 286.0).abs() < 1e-9, "{band}");
    }

    #[test]
    fn tick_labels_have_no_negative_zero_and_no_trailing_zeros() {
        assert_eq!(tick_label(-0.0), "0");
        assert_eq!(tick_label(-0.00001), "0");
        assert_eq!(tick_label(0.25), "0.25");
        assert_eq!(tick_label(-1.5), "-1.5");
        assert_eq!(tick_label(200.0), "200");
    }
}
