//! The `dynamics` subcommand: `M`, `C`, `g` and a frame Jacobian of a URDF robot at given
//! states, as JSON, for comparison with other rigid-body libraries.
//!
//! ```text
//! host-sim dynamics --urdf robot.urdf --frame tool_link --states states.json
//! ```
//!
//! The URDF is loaded with [`Coupling::Independent`] (every movable joint is a coordinate, as
//! Pinocchio does by default). `states.json` is an array of `{"q": [..], "v": [..]}` in the
//! robot's joint order (movable joints in tree order, depth first, children in file order).
//! The output is an array with one object per state:
//! `{"joints": [names..], "M": [[..]], "C": [[..]], "g": [..], "J": [[..]]}` — the mass matrix
//! (N×N), the Christoffel-consistent Coriolis matrix (N×N, `Ṁ = C + Cᵀ`), the generalized
//! gravity (N, for 9.81 m/s² along −z) and the 6×N Jacobian of the origin of link `frame`,
//! world-aligned, linear rows first (Pinocchio's `LOCAL_WORLD_ALIGNED`), all as rows.

use std::path::Path;

use kernel::dynamics::{coriolis_matrix, crba, forward_kinematics, frame_jacobian, gravity};
use kernel::model::Data;
use nalgebra::{SMatrix, SVector};
use serde::Serialize;
use serde_json::Value;

use crate::urdf::{self, Coupling, Description};

/// Largest number of degrees of freedom the command handles (sizes are compile-time constants).
pub const MAX_DOF: usize = 40;

/// Frame capacity of the models the command builds (one frame per URDF link).
pub const MAX_FRAMES: usize = 160;

/// Runs the command: returns the JSON text for stdout, or a one-line error message.
///
/// ```
/// let dir = std::env::temp_dir().join(format!("host-sim-doc-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// // A 1 kg point mass 0.5 m from a horizontal joint axis: g = m · 9.81 · 0.5 at q = 0.
/// let urdf = dir.join("pendulum.urdf");
/// std::fs::write(&urdf, r#"<robot name="p"><link name="base"/>
///   <link name="bob"><inertial><origin xyz="0.5 0 0"/><mass value="1"/>
///     <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
///   <joint name="j" type="continuous"><parent link="base"/><child link="bob"/>
///     <axis xyz="0 1 0"/></joint></robot>"#).unwrap();
/// let states = dir.join("states.json");
/// std::fs::write(&states, r#"[{"q": [0], "v": [0]}]"#).unwrap();
/// let out = host_sim::dynamics_cli::run(&urdf, "bob", &states).unwrap();
/// let value: serde_json::Value = serde_json::from_str(&out).unwrap();
/// assert!((value[0]["g"][0].as_f64().unwrap() + 4.905).abs() < 1e-12);
/// assert!((value[0]["M"][0][0].as_f64().unwrap() - 0.25).abs() < 1e-12);
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub fn run(urdf: &Path, frame: &str, states: &Path) -> Result<String, String> {
    let description = urdf::describe_file(urdf, Coupling::Independent)?;
    let n = description.coordinate_count();
    if n == 0 {
        return Err(format!("{} has no movable joints", urdf.display()));
    }
    if n > MAX_DOF {
        return Err(format!("the URDF has {n} movable joints; the dynamics command supports at most {MAX_DOF}"));
    }
    if !description.frame_names().any(|name| name == frame) {
        let links: Vec<&str> = description.frame_names().collect();
        return Err(format!(
            "unknown frame \"{frame}\": {} has no link of that name (links: {})",
            urdf.display(),
            links.join(", ")
        ));
    }
    let text =
        std::fs::read_to_string(states).map_err(|e| format!("cannot read states file {}: {e}", states.display()))?;
    let states = parse_states(&text, n).map_err(|e| format!("states file {}: {e}", states.display()))?;
    dispatch(&description, frame, &states)
}

/// One input state: joint positions and velocities in the robot's joint order.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Joint positions (rad, m).
    pub q: Vec<f64>,
    /// Joint velocities (rad/s, m/s).
    pub v: Vec<f64>,
}

/// Parses and checks the states array for a robot with `n` coordinates (errors name the
/// offending entry; the fuzz target `host_parsers` runs it on arbitrary text).
pub fn parse_states(text: &str, n: usize) -> Result<Vec<State>, String> {
    let value: Value = serde_json::from_str(text).map_err(|e| json_error(text, &e))?;
    let Value::Array(items) = value else {
        return Err("expected a JSON array of {\"q\": [..], \"v\": [..]} objects".to_owned());
    };
    items
        .iter()
        .enumerate()
        .map(|(i, item)| {
            let vector = |key: &str| -> Result<Vec<f64>, String> {
                let entries = match item.get(key) {
                    Some(Value::Array(entries)) => entries,
                    Some(_) => return Err(format!("state {i}: \"{key}\" is not an array")),
                    None if item.is_object() => return Err(format!("state {i}: missing \"{key}\"")),
                    None => return Err(format!("state {i} is not an object {{\"q\": [..], \"v\": [..]}}")),
                };
                if entries.len() != n {
                    return Err(format!(
                        "state {i}: \"{key}\" has {} entries, expected {n} (one per joint)",
                        entries.len()
                    ));
                }
                entries
                    .iter()
                    .enumerate()
                    .map(|(k, x)| match x {
                        Value::Number(number) => number
                            .as_f64()
                            .filter(|x| x.is_finite())
                            .ok_or_else(|| format!("state {i}: {key}[{k}] = {number} is not a finite number")),
                        Value::Null => Err(format!("state {i}: {key}[{k}] is null, expected a finite number")),
                        other => Err(format!("state {i}: {key}[{k}] = {other} is not a finite number")),
                    })
                    .collect()
            };
            Ok(State { q: vector("q")?, v: vector("v")? })
        })
        .collect()
}

/// A one-line message for a JSON syntax error; names non-finite literals (`NaN`,
/// `Infinity`, as Python's `json` writes them) explicitly.
fn json_error(text: &str, error: &serde_json::Error) -> String {
    let line = text.lines().nth(error.line().saturating_sub(1)).unwrap_or_default();
    let around: String = line.chars().skip(error.column().saturating_sub(2)).take(12).collect();
    let non_finite =
        ["-Infinity", "Infinity", "NaN", "nan", "-inf", "inf"].into_iter().find(|token| around.contains(token));
    match non_finite {
        Some(token) => format!(
            "non-finite number {token} at line {} column {}: states must be finite",
            error.line(),
            error.column()
        ),
        None => format!("malformed JSON: {error}"),
    }
}

/// Runs [`evaluate`] with `N` = the robot's coordinate count (a compile-time constant).
pub(crate) fn dispatch(description: &Description, frame: &str, states: &[State]) -> Result<String, String> {
    macro_rules! with_dof {
        ($($n:literal)*) => {
            match description.coordinate_count() {
                $($n => evaluate::<$n, $n, MAX_FRAMES>(description, frame, states),)*
                0 => Err("the URDF has no movable joints".to_owned()),
                n => Err(format!("the URDF has {n} movable joints; the dynamics command supports at most {MAX_DOF}")),
            }
        };
    }
    with_dof!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29 30 31 32 33 34 35 36 37 38 39 40)
}

/// One output record.
#[derive(Serialize)]
struct Record<'a> {
    joints: &'a [String],
    #[serde(rename = "M")]
    mass_matrix: Vec<Vec<f64>>,
    #[serde(rename = "C")]
    coriolis: Vec<Vec<f64>>,
    g: Vec<f64>,
    #[serde(rename = "J")]
    jacobian: Vec<Vec<f64>>,
}

/// Evaluates every state; one JSON record per line.
fn evaluate<const N: usize, const B: usize, const F: usize>(
    description: &Description,
    frame: &str,
    states: &[State],
) -> Result<String, String> {
    let robot = urdf::build::<N, B, F>(description)?;
    let frame_id = robot.frame(frame).ok_or_else(|| format!("unknown frame \"{frame}\""))?;
    let model = &robot.model;
    let mut data = Data::new(model);
    let mut jacobian = SMatrix::<f64, 6, N>::zeros();
    let mut lines = Vec::with_capacity(states.len());
    for (i, state) in states.iter().enumerate() {
        let vector = |x: &[f64]| SVector::<f64, N>::from_fn(|k, _| x.get(k).copied().unwrap_or(f64::NAN));
        forward_kinematics(model, &mut data, &vector(&state.q), &vector(&state.v))
            .map_err(|e| format!("state {i}: {e}"))?;
        crba(model, &mut data);
        coriolis_matrix(model, &mut data);
        gravity(model, &mut data);
        frame_jacobian(model, &data, frame_id, &mut jacobian).map_err(|e| format!("state {i}: {e}"))?;
        let record = Record {
            joints: &robot.joint_names,
            mass_matrix: rows(&data.mass_matrix),
            coriolis: rows(&data.coriolis),
            g: data.gravity_torque.iter().copied().collect(),
            jacobian: rows(&jacobian),
        };
        let finite = [&record.mass_matrix, &record.coriolis, &record.jacobian]
            .into_iter()
            .flatten()
            .flatten()
            .chain(record.g.iter())
            .all(|x| x.is_finite());
        if !finite {
            return Err(format!("state {i}: the dynamics are not finite"));
        }
        lines.push(serde_json::to_string(&record).map_err(|e| format!("state {i}: {e}"))?);
    }
    if lines.is_empty() {
        return Ok("[]".to_owned());
    }
    Ok(format!("[\n{}\n]", lines.join(",\n")))
}

/// The rows of a matrix as nested vectors.
fn rows<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> Vec<Vec<f64>> {
    m.row_iter().map(|row| row.iter().copied().collect()).collect()
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "test code: failures should panic")]
mod tests {
    use super::*;

    #[test]
    fn states_are_checked_entry_by_entry() {
        let ok = parse_states(r#"[{"q": [1, 2.5], "v": [0, -1e-3]}]"#, 2).unwrap();
        assert_eq!(ok, [State { q: vec![1.0, 2.5], v: vec![0.0, -1e-3] }]);
        assert_eq!(parse_states("[]", 3).unwrap(), []);
        let err = |text: &str| parse_states(text, 2).unwrap_err();
        assert_eq!(err(r#"{"q": []}"#), "expected a JSON array of {\"q\": [..], \"v\": [..]} objects");
        assert_eq!(
            err(r#"[{"q": [1, 2], "v": [0, 0]}, {"q": [1], "v": [0, 0]}]"#),
            "state 1: \"q\" has 1 entries, expected 2 (one per joint)"
        );
        assert_eq!(err(r#"[{"q": [1, 2]}]"#), "state 0: missing \"v\"");
        assert_eq!(err(r#"[3]"#), "state 0 is not an object {\"q\": [..], \"v\": [..]}");
        assert_eq!(err(r#"[{"q": [1, null], "v": [0, 0]}]"#), "state 0: q[1] is null, expected a finite number");
        assert_eq!(err(r#"[{"q": [1, "NaN"], "v": [0, 0]}]"#), "state 0: q[1] = \"NaN\" is not a finite number");
        let nan = err("[{\"q\": [1, 2],\n \"v\": [NaN, 0]}]");
        assert!(nan.starts_with("non-finite number NaN at line 2"), "{nan}");
        let inf = err(r#"[{"q": [1, -Infinity], "v": [0, 0]}]"#);
        assert!(inf.starts_with("non-finite number -Infinity"), "{inf}");
        // Out of f64's range: kept as written by the parser (serde_json's arbitrary precision,
        // which the defmt decoder enables), refused as it converts to infinity.
        assert_eq!(err(r#"[{"q": [1, 1e999], "v": [0, 0]}]"#), "state 0: q[1] = 1e+999 is not a finite number");
        assert!(err(r#"[{"q": [1, 2], "v": [0, 0]"#).contains("malformed JSON"));
    }
}
