//! `replay.html`: a self-contained page that replays a run of the simulated Justin in 3-D.
//!
//! For every scenario whose time series has the Justin joint columns `q.<joint>`, [`write()`]
//! computes the world placement of every body at a reduced rate ([`REPLAY_RATE_HZ`]) by the
//! kernel's forward kinematics, and writes one HTML file holding
//! - the scene: the swept-sphere collision volumes in their body frames (the robot's geometry)
//!   and the world-fixed environment volumes (tables, walls), each with its body part;
//! - the frames: time and the body placements (position and unit quaternion);
//! - the signals the page shows: TCP positions and goals, platform pose, external forces on the
//!   TCPs, task errors per level, smallest collision distance, output mode
//!   ([`SIGNAL_PREFIXES`]), non-finite values as `null`;
//! - the claims of the summary;
//! - the page script `replay/dist/replay.js` (the page code and three.js, bundled by esbuild
//!   from the pinned npm packages in `replay/`, see `replay/README.md`), inlined, so the page
//!   opens from disk without a network.

use std::fs;
use std::path::Path;

use fixtures::justin::{self, collision};
use kernel::dynamics::forward_kinematics;
use kernel::model::Data;
use kernel::tasks::collision::SweptSphere;
use nalgebra::{SVector, UnitQuaternion};
use serde_json::{json, Value};

use crate::output::{Summary, TimeSeries};
use crate::wbc::{PAIRS, VOLUMES};

/// Frames per second of simulated time in the replay.
pub const REPLAY_RATE_HZ: f64 = 50.0;

/// Columns copied into the replay (every column whose name starts with one of these).
pub const SIGNAL_PREFIXES: [&str; 10] =
    ["right_tcp.", "left_tcp.", "e0.", "e1.", "S", "force.", "min_distance", "mode", "contact", "q.base_"];

/// The page template; `/*REPLAY_DATA*/` and `/*REPLAY_SCRIPT*/` are replaced.
const TEMPLATE: &str = include_str!("../../replay/page.html");
/// The bundled page script (page code and three.js).
const SCRIPT: &str = include_str!("../../replay/dist/replay.js");

/// Whether `series` can be replayed: it has every Justin joint position column.
pub fn is_replayable(series: &TimeSeries) -> bool {
    justin::JOINT_NAMES.iter().all(|j| series.columns().iter().any(|c| *c == format!("q.{j}")))
}

/// Writes `replay.html` of `series` into `dir` with the `environment` volumes (world frame) and
/// the claims of `summary`.
pub fn write(
    dir: &Path,
    series: &TimeSeries,
    summary: &Summary,
    environment: &[SweptSphere<f64>],
) -> Result<(), String> {
    let data = replay_data(series, summary, environment)?;
    let data = serde_json::to_string(&data).map_err(|e| e.to_string())?;
    // `</` inside a script element would end it early.
    let data = data.replace("</", "<\\/");
    let page = TEMPLATE.replacen("/*REPLAY_DATA*/", &data, 1).replacen("/*REPLAY_SCRIPT*/", SCRIPT, 1);
    let path = dir.join("replay.html");
    fs::write(&path, page).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// The JSON object the page reads (see the module docs).
pub fn replay_data(series: &TimeSeries, summary: &Summary, environment: &[SweptSphere<f64>]) -> Result<Value, String> {
    let rows = replay_rows(series)?;
    Ok(json!({
        "scenario": summary.to_json().get("scenario").cloned().unwrap_or(Value::Null),
        "passed_claims": summary.passed_claims(),
        "failed_claims": summary.failed_claims(),
        "volumes": volumes(environment)?,
        "parents": justin::model::<f64>()
            .map_err(|e| format!("model: {e}"))?
            .bodies()
            .iter()
            .map(|b| b.parent.map_or(-1, |p| i64::try_from(p.0).unwrap_or(-1)))
            .collect::<Vec<_>>(),
        "t": rows.iter().map(|&r| cell(series, r, 0)).collect::<Vec<_>>(),
        "bodies": body_placements(series, &rows)?,
        "signals": signals(series, &rows),
    }))
}

/// The indices of the rows kept: the first row, then one per `1 / REPLAY_RATE_HZ` of time.
fn replay_rows(series: &TimeSeries) -> Result<Vec<usize>, String> {
    let mut kept = Vec::new();
    let mut next = f64::NEG_INFINITY;
    for (index, row) in series.rows().iter().enumerate() {
        let t = row.first().copied().ok_or("empty row")?;
        if t >= next - 1e-9 {
            kept.push(index);
            next = t + 1.0 / REPLAY_RATE_HZ;
        }
    }
    Ok(kept)
}

/// Value of column `column` in row `row`, rounded to 0.1 mm / 0.1 mrad, `null` if not finite.
fn cell(series: &TimeSeries, row: usize, column: usize) -> Value {
    let x = series.rows().get(row).and_then(|r| r.get(column)).copied().unwrap_or(f64::NAN);
    rounded(x)
}

fn rounded(x: f64) -> Value {
    serde_json::Number::from_f64((x * 1e4).round() / 1e4).map_or(Value::Null, Value::Number)
}

/// Per kept row, every body's `[x, y, z, qx, qy, qz, qw]` flattened.
fn body_placements(series: &TimeSeries, rows: &[usize]) -> Result<Vec<Vec<Value>>, String> {
    let model = justin::model::<f64>().map_err(|e| format!("model: {e}"))?;
    let mut data = Data::new(&model);
    let columns = justin::JOINT_NAMES
        .iter()
        .map(|j| crate::scenarios::column_index(series, &format!("q.{j}")))
        .collect::<Result<Vec<_>, _>>()?;
    let mut frames = Vec::with_capacity(rows.len());
    for &row in rows {
        let values = series.rows().get(row).ok_or("row out of range")?;
        let q = SVector::<f64, { justin::N }>::from_iterator(
            columns.iter().map(|&c| values.get(c).copied().unwrap_or(f64::NAN)),
        );
        forward_kinematics(&model, &mut data, &q, &SVector::zeros()).map_err(|e| format!("kinematics: {e}"))?;
        let mut frame = Vec::with_capacity(7 * justin::BODIES);
        for placement in &data.body_placements {
            let r = UnitQuaternion::from_rotation_matrix(&placement.rotation);
            let p = placement.translation.vector;
            frame.extend([p.x, p.y, p.z, r.i, r.j, r.k, r.w].map(rounded));
        }
        frames.push(frame);
    }
    Ok(frames)
}

/// The robot's volumes in their body frames and the environment's in the world frame:
/// `{ body (−1: world), part, radius, points }`.
fn volumes(environment: &[SweptSphere<f64>]) -> Result<Vec<Value>, String> {
    let model = justin::model::<f64>().map_err(|e| format!("model: {e}"))?;
    let collision = collision::collision_model_with_environment::<f64, VOLUMES, PAIRS>(&model, environment)
        .map_err(|e| format!("collision model: {e}"))?;
    Ok(collision
        .volumes()
        .iter()
        .enumerate()
        .map(|(index, volume)| {
            let part = collision::VOLUME_SPECS.get(index).map_or("environment", |s| s.group.name());
            let points: Vec<Vec<Value>> =
                volume.shape.core.points().iter().map(|p| p.iter().map(|x| rounded(*x)).collect()).collect();
            json!({
                "body": volume.body.map_or(-1, |b| i64::try_from(b.0).unwrap_or(-1)),
                "part": part,
                "radius": rounded(volume.shape.radius),
                "points": points,
            })
        })
        .collect())
}

/// The kept rows of every column named by [`SIGNAL_PREFIXES`]: `{ name: [values] }`.
fn signals(series: &TimeSeries, rows: &[usize]) -> Value {
    let mut object = serde_json::Map::new();
    for (column, name) in series.columns().iter().enumerate() {
        if SIGNAL_PREFIXES.iter().any(|p| name.starts_with(p)) {
            let values: Vec<Value> = rows.iter().map(|&r| cell(series, r, column)).collect();
            object.insert(name.clone(), Value::from(values));
        }
    }
    Value::Object(object)
}

#[cfg(test)]
mod tests {
    #![allow(
        clippy::unwrap_used,
        clippy::indexing_slicing,
        clippy::cast_precision_loss,
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "tests"
    )]
    use super::*;

    fn still_justin(seconds: f64) -> TimeSeries {
        let mut columns = vec!["t".to_string()];
        columns.extend(justin::JOINT_NAMES.iter().map(|j| format!("q.{j}")));
        columns.push("min_distance".into());
        let mut series = TimeSeries::new(columns);
        let q = justin::home_configuration();
        for k in 0..=(seconds * 1000.0).round() as usize {
            let mut row = vec![k as f64 * 1e-3];
            row.extend(q.iter());
            row.push(if k == 0 { f64::NAN } else { 0.1 });
            series.push(row).unwrap();
        }
        series
    }

    #[test]
    fn the_replay_keeps_fifty_frames_per_second_and_every_body() {
        let series = still_justin(2.0);
        let data = replay_data(&series, &Summary::new("still"), &[]).unwrap();
        let t = data["t"].as_array().unwrap();
        assert_eq!(t.len(), 101);
        assert_eq!(t[1].as_f64().unwrap(), 0.02);
        assert_eq!(data["bodies"][0].as_array().unwrap().len(), 7 * justin::BODIES);
        assert_eq!(data["volumes"].as_array().unwrap().len(), collision::VOLUMES);
        assert_eq!(data["parents"].as_array().unwrap().len(), justin::BODIES);
    }

    #[test]
    fn a_non_finite_signal_is_null_in_the_replay() {
        let series = still_justin(0.1);
        let data = replay_data(&series, &Summary::new("still"), &[]).unwrap();
        assert!(data["signals"]["min_distance"][0].is_null());
        assert_eq!(data["signals"]["min_distance"][1].as_f64().unwrap(), 0.1);
    }

    #[test]
    fn a_series_without_justin_joints_is_not_replayable() {
        assert!(is_replayable(&still_justin(0.01)));
        assert!(!is_replayable(&TimeSeries::new(vec!["t".into(), "x".into()])));
    }
}
