//! Rigid-body dynamics of URDF robots against independent references.
//!
//! - [`pinocchio`]: `M`, `C`, `g` and frame Jacobians of the URDFs in `fixtures/urdf/`, loaded
//!   with `host_sim::urdf`, against the values Pinocchio computed for the same files
//!   (`fixtures/pinocchio/<robot>.json`, written by `fixtures/pinocchio/generate.py`), and the
//!   `host-sim dynamics` command against the library.
//!
//! This module holds what those tests share: the fixture reader and one evaluation of the
//! kernel's dynamics at a state.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "test code: failures should panic")]

mod pinocchio;

use std::path::{Path, PathBuf};

use host_sim::urdf::UrdfRobot;
use kernel::dynamics::{coriolis_matrix, crba, forward_kinematics, frame_jacobian, gravity};
use kernel::{Data, FrameId};
use nalgebra::{SMatrix, SVector};
use serde_json::Value;

/// Row-major dense matrix (the fixtures' layout).
pub(crate) type Rows = Vec<Vec<f64>>;

/// The repository root (the workspace directory).
pub(crate) fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// One reference file `fixtures/pinocchio/<robot>.json`.
pub(crate) struct Fixture {
    pub robot: String,
    /// Absolute path of the URDF the reference was computed from.
    pub urdf: PathBuf,
    /// Links whose origin Jacobians and placements are given: the file's `frame`, then its
    /// `other_frames` (a robot with two TCPs).
    pub frames: Vec<String>,
    /// Joint names in the reference's coordinate order.
    pub joints: Vec<String>,
    pub states: Vec<Reference>,
}

/// Reference values at one state, in the reference's coordinate order.
pub(crate) struct Reference {
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    pub m: Rows,
    pub c: Rows,
    pub g: Vec<f64>,
    /// The values of each of the fixture's `frames`.
    pub frames: Vec<FrameValues>,
}

/// A frame's Jacobian and world placement at one state.
#[derive(Debug, PartialEq)]
pub(crate) struct FrameValues {
    /// 6×N, linear rows first, world-aligned at the frame origin.
    pub j: Rows,
    pub translation: Vec<f64>,
    pub rotation: Rows,
}

impl Fixture {
    /// Reads `fixtures/pinocchio/<robot>.json`.
    pub fn load(robot: &str) -> Self {
        let path = repo_root().join("fixtures/pinocchio").join(format!("{robot}.json"));
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let doc: Value = serde_json::from_str(&text).unwrap();
        let string = |v: &Value| v.as_str().unwrap().to_owned();
        let vector = |v: &Value| -> Vec<f64> { v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect() };
        let rows = |v: &Value| -> Rows { v.as_array().unwrap().iter().map(vector).collect() };
        let frame_values = |f: &Value| FrameValues {
            j: rows(&f["J"]),
            translation: vector(&f["frame_translation"]),
            rotation: rows(&f["frame_rotation"]),
        };
        let others = |v: &Value| v.as_array().cloned().unwrap_or_default();
        let states = doc["states"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| Reference {
                q: vector(&s["q"]),
                v: vector(&s["v"]),
                m: rows(&s["M"]),
                c: rows(&s["C"]),
                g: vector(&s["g"]),
                frames: std::iter::once(frame_values(s))
                    .chain(others(&s["other_frames"]).iter().map(frame_values))
                    .collect(),
            })
            .collect();
        Self {
            robot: string(&doc["robot"]),
            urdf: repo_root().join(string(&doc["urdf"])),
            frames: std::iter::once(string(&doc["frame"]))
                .chain(others(&doc["other_frames"]).iter().map(string))
                .collect(),
            joints: doc["joints"].as_array().unwrap().iter().map(string).collect(),
            states,
        }
    }

    /// `perm[k]` = index in the reference's order of our coordinate `k` (matched by joint name).
    pub fn permutation(&self, joint_names: &[String]) -> Vec<usize> {
        assert_eq!(joint_names.len(), self.joints.len(), "{}: coordinate count", self.robot);
        joint_names
            .iter()
            .map(|name| {
                self.joints
                    .iter()
                    .position(|j| j == name)
                    .unwrap_or_else(|| panic!("{}: joint {name} is not in the reference", self.robot))
            })
            .collect()
    }
}

/// The kernel's dynamics at one state, in our coordinate order.
pub(crate) struct Evaluated {
    pub m: Rows,
    pub c: Rows,
    pub g: Vec<f64>,
    pub frame: FrameValues,
}

/// Evaluates `M`, `C`, `g`, the Jacobian and the placement of `frame` at `(q, v)`.
pub(crate) fn evaluate<const N: usize, const B: usize, const F: usize>(
    robot: &UrdfRobot<N, B, F>,
    frame: FrameId,
    q: &[f64],
    v: &[f64],
) -> Evaluated {
    let model = &robot.model;
    let mut data = Data::new(model);
    let q = SVector::<f64, N>::from_column_slice(q);
    let v = SVector::<f64, N>::from_column_slice(v);
    forward_kinematics(model, &mut data, &q, &v).unwrap();
    let m = *crba(model, &mut data);
    let c = *coriolis_matrix(model, &mut data);
    let g = *gravity(model, &mut data);
    let mut j = SMatrix::<f64, 6, N>::zeros();
    frame_jacobian(model, &data, frame, &mut j).unwrap();
    let placement = data.frame_placements[frame.0];
    Evaluated {
        m: rows(&m),
        c: rows(&c),
        g: g.iter().copied().collect(),
        frame: FrameValues {
            j: rows(&j),
            translation: placement.translation.vector.iter().copied().collect(),
            rotation: rows(placement.rotation.matrix()),
        },
    }
}

/// The rows of a fixed-size matrix.
pub(crate) fn rows<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> Rows {
    m.row_iter().map(|r| r.iter().copied().collect()).collect()
}
