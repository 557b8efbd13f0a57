//! The kernel's rigid-body dynamics of real robots against Pinocchio.
//!
//! For every fixture `fixtures/pinocchio/<robot>.json` (Pinocchio's `crba`,
//! `computeCoriolisMatrix`, `computeGeneralizedGravity` and `LOCAL_WORLD_ALIGNED` frame
//! Jacobians at 24 random states of the URDF in `fixtures/urdf/`), the URDF is loaded with
//! `host_sim::urdf::load` (independent joints, fixed joints merged, as Pinocchio does), or the
//! imported robot is built by its generated constructor, and `M`, `C`, `g`, `C v`, and each
//! frame's `J` and placement must agree per state within
//! `max|A − B| ≤ 1e-9 · max(1, max|B|)`. Coordinates are matched by joint name, so the two
//! libraries may order the tree differently. The `dynamics` command of `host-sim` must print
//! exactly the library's numbers, and reject bad input with a one-line message.

use std::path::{Path, PathBuf};

use host_sim::dynamics_cli;
use host_sim::urdf::{load, load_str, Coupling, UrdfRobot};
use serde_json::{json, Value};

use kernel::FrameId;

use super::{evaluate, Evaluated, Fixture, Rows};

/// Relative tolerance per quantity and state: `max|A − B| ≤ TOLERANCE · max(1, max|B|)`.
const TOLERANCE: f64 = 1e-9;

/// Frame capacity of the test models (the largest fixture has 40 links).
const FRAMES: usize = 64;

/// `max_ij |ours[i][j] − reference[rows[i]][cols[j]]| / max(1, max|reference|)`.
fn relative_error(ours: &Rows, reference: &Rows, rows: &[usize], cols: &[usize]) -> f64 {
    let scale = reference.iter().flatten().fold(1.0_f64, |m, x| m.max(x.abs()));
    let mut worst = 0.0_f64;
    for (i, row) in ours.iter().enumerate() {
        for (j, x) in row.iter().enumerate() {
            worst = worst.max((x - reference[rows[i]][cols[j]]).abs());
        }
    }
    worst / scale
}

fn column(v: &[f64]) -> Rows {
    v.iter().map(|x| vec![*x]).collect()
}

fn product(m: &Rows, v: &[f64]) -> Vec<f64> {
    m.iter().map(|row| row.iter().zip(v).map(|(a, b)| a * b).sum()).collect()
}

/// Compares every state of fixture `name` (a robot with `N` coordinates) with the URDF the
/// fixture names; prints the worst relative error per quantity and asserts the tolerance.
fn check_against_pinocchio<const N: usize>(name: &str) {
    let fixture = Fixture::load(name);
    let robot = load::<N, N, FRAMES>(&fixture.urdf, Coupling::Independent).unwrap();
    check_robot(&fixture, &robot, TOLERANCE);
}

/// Compares `robot` (loaded from the fixture's URDF, or an equivalent text or generated model)
/// with `fixture`, within the relative `tolerance`.
fn check_robot<const N: usize, const B: usize, const F: usize>(
    fixture: &Fixture,
    robot: &UrdfRobot<N, B, F>,
    tolerance: f64,
) {
    let name = &fixture.robot;
    let frames: Vec<FrameId> = fixture.frames.iter().map(|f| robot.frame(f).unwrap()).collect();
    let perm = fixture.permutation(&robot.joint_names);
    let identity: Vec<usize> = (0..N.max(6)).collect();
    let mut quantities: Vec<String> = ["M", "C", "g", "C v"].map(str::to_owned).into();
    for frame in &fixture.frames {
        quantities.extend(["J", "translation", "rotation"].map(|q| format!("{frame} {q}")));
    }
    let mut worst = vec![(0.0_f64, 0_usize); quantities.len()];
    for (s, reference) in fixture.states.iter().enumerate() {
        let q: Vec<f64> = perm.iter().map(|&p| reference.q[p]).collect();
        let v: Vec<f64> = perm.iter().map(|&p| reference.v[p]).collect();
        let ours: Vec<Evaluated> = frames.iter().map(|&frame| evaluate(robot, frame, &q, &v)).collect();
        let mut errors = vec![
            relative_error(&ours[0].m, &reference.m, &perm, &perm),
            relative_error(&ours[0].c, &reference.c, &perm, &perm),
            relative_error(&column(&ours[0].g), &column(&reference.g), &perm, &[0]),
            relative_error(
                &column(&product(&ours[0].c, &v)),
                &column(&product(&reference.c, &reference.v)),
                &perm,
                &[0],
            ),
        ];
        assert_eq!(reference.frames.len(), frames.len(), "{name}: state {s} lacks a frame");
        for (ours, theirs) in ours.iter().map(|o| &o.frame).zip(&reference.frames) {
            errors.push(relative_error(&ours.j, &theirs.j, &identity, &perm));
            errors.push(relative_error(&column(&ours.translation), &column(&theirs.translation), &identity, &[0]));
            errors.push(relative_error(&ours.rotation, &theirs.rotation, &identity, &identity));
        }
        for (w, e) in worst.iter_mut().zip(errors) {
            if e > w.0 || e.is_nan() {
                *w = (e, s);
            }
        }
    }
    let report: Vec<String> =
        quantities.iter().zip(&worst).map(|(q, (e, s))| format!("{q} {e:.2e} (state {s})")).collect();
    println!("{name} vs Pinocchio, {} states, worst relative error: {}", fixture.states.len(), report.join(", "));
    assert!(
        worst.iter().all(|(e, _)| *e <= tolerance),
        "{name}: disagreement with Pinocchio beyond {tolerance:e}: {}",
        report.join(", ")
    );
}

#[test]
fn panda_matches_pinocchio() {
    check_against_pinocchio::<9>("panda");
}

#[test]
fn g1_29dof_matches_pinocchio() {
    check_against_pinocchio::<29>("g1_29dof");
}

/// Coordinates are matched by joint name: with the two finger joints swapped in the file our
/// order differs from Pinocchio's, and everything still agrees.
#[test]
fn joint_order_is_matched_by_name() {
    let fixture = Fixture::load("panda");
    let text = std::fs::read_to_string(&fixture.urdf).unwrap();
    let start = text.find("<joint name=\"panda_finger_joint1\"").unwrap();
    let middle = start + text[start..].find("</joint>").unwrap() + "</joint>".len();
    let end = middle + text[middle..].find("</joint>").unwrap() + "</joint>".len();
    let swapped = format!("{}{}{}{}", &text[..start], &text[middle..end], &text[start..middle], &text[end..]);
    let robot = load_str::<9, 9, FRAMES>(&swapped, Coupling::Independent).unwrap();
    assert_eq!(robot.joint_names[7..], ["panda_finger_joint2", "panda_finger_joint1"]);
    assert_eq!(fixture.permutation(&robot.joint_names), [0, 1, 2, 3, 4, 5, 6, 8, 7]);
    check_robot(&fixture, &robot, TOLERANCE);
}

/// An imported robot's generated model with the names the generated module lists.
fn imported<const N: usize, const B: usize, const F: usize>(
    model: kernel::Model<f64, N, B, F>,
    joints: &[&str],
    frames: &[&str],
    bodies: &[&str],
) -> UrdfRobot<N, B, F> {
    let names = |list: &[&str]| list.iter().map(|s| (*s).to_owned()).collect::<Vec<_>>();
    UrdfRobot { model, joint_names: names(joints), frame_names: names(frames), body_names: names(bodies) }
}

/// The imported Panda (`fixtures::robots::panda`, generated by `host-sim import`: the seven arm
/// joints, the fingers frozen at zero) against Pinocchio's model with the fingers locked at
/// zero (`panda_arm.json`): `M`, `C`, `g` and the Jacobian of the TCP `panda_hand_tcp` at 24
/// random states, to 1e-12 relative.
#[test]
fn imported_panda_matches_pinocchio() {
    use fixtures::robots::panda;
    let fixture = Fixture::load("panda_arm");
    assert_eq!(fixture.states.len(), 24);
    let robot = imported(panda::model::<f64>().unwrap(), &panda::JOINT_NAMES, &panda::FRAME_NAMES, &panda::BODY_NAMES);
    assert_eq!(fixture.frames, ["panda_hand_tcp"]);
    assert_eq!(robot.frame(&fixture.frames[0]), Some(panda::PANDA_HAND_TCP));
    check_robot(&fixture, &robot, 1e-12);
}

/// The imported TIAGo++ (`fixtures::robots::tiago_dual`: the torso lift and both arms, the head,
/// wheels, casters and hands frozen at zero) against Pinocchio's model with the same joints
/// locked at zero (`tiago_dual.json`): `M`, `C`, `g` and the Jacobians of both TCPs at 24 random
/// states, to 1e-9 relative (the bound).
#[test]
fn imported_tiago_dual_matches_pinocchio() {
    use fixtures::robots::tiago_dual as tiago;
    let fixture = Fixture::load("tiago_dual");
    assert_eq!(fixture.states.len(), 24);
    let robot = imported(tiago::model::<f64>().unwrap(), &tiago::JOINT_NAMES, &tiago::FRAME_NAMES, &tiago::BODY_NAMES);
    assert_eq!(fixture.frames, ["hand_left_grasping_frame", "hand_right_grasping_frame"]);
    let tcps: Vec<_> = fixture.frames.iter().map(|f| robot.frame(f).unwrap()).collect();
    assert_eq!(tcps, tiago::TCPS);
    check_robot(&fixture, &robot, TOLERANCE);
}

/// A file in the system temp directory, removed when dropped.
struct TempFile(PathBuf);

impl TempFile {
    fn new(name: &str, contents: &str) -> Self {
        let path = std::env::temp_dir().join(format!("thesis-tests-{}-{name}", std::process::id()));
        std::fs::write(&path, contents).unwrap();
        Self(path)
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// The `dynamics` command on the fixture's states (in our joint order) prints exactly what
/// the library computes.
fn cli_matches_library<const N: usize>(name: &str) {
    let fixture = Fixture::load(name);
    let robot = load::<N, N, FRAMES>(&fixture.urdf, Coupling::Independent).unwrap();
    let frame = robot.frame(&fixture.frames[0]).unwrap();
    let perm = fixture.permutation(&robot.joint_names);
    let states: Vec<(Vec<f64>, Vec<f64>)> = fixture
        .states
        .iter()
        .map(|r| (perm.iter().map(|&p| r.q[p]).collect(), perm.iter().map(|&p| r.v[p]).collect()))
        .collect();
    let input: Vec<Value> = states.iter().map(|(q, v)| json!({"q": q, "v": v})).collect();
    let file = TempFile::new(&format!("{name}-states.json"), &Value::Array(input).to_string());
    let output = dynamics_cli::run(&fixture.urdf, &fixture.frames[0], &file.0).unwrap();
    let records: Vec<Value> = serde_json::from_str::<Value>(&output).unwrap().as_array().unwrap().clone();
    assert_eq!(records.len(), states.len());
    let vector = |v: &Value| -> Vec<f64> { v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect() };
    let rows = |v: &Value| -> Rows { v.as_array().unwrap().iter().map(vector).collect() };
    for (record, (q, v)) in records.iter().zip(&states) {
        let expected = evaluate(&robot, frame, q, v);
        let joints: Vec<&str> = record["joints"].as_array().unwrap().iter().map(|j| j.as_str().unwrap()).collect();
        assert_eq!(joints, robot.joint_names);
        assert_eq!(rows(&record["M"]), expected.m);
        assert_eq!(rows(&record["C"]), expected.c);
        assert_eq!(vector(&record["g"]), expected.g);
        assert_eq!(rows(&record["J"]), expected.frame.j);
    }
}

#[test]
fn dynamics_command_prints_the_library_result() {
    cli_matches_library::<9>("panda");
    cli_matches_library::<29>("g1_29dof");
}

/// The error message of the `dynamics` command on the panda URDF.
fn cli_error(urdf: &Path, frame: &str, states: &str) -> String {
    let file = TempFile::new("bad-states.json", states);
    let message = dynamics_cli::run(urdf, frame, &file.0).unwrap_err();
    assert!(!message.contains('\n'), "not one line: {message}");
    message
}

#[test]
fn dynamics_command_rejects_bad_input_with_a_one_line_message() {
    let panda = Fixture::load("panda").urdf;
    let zeros = vec![0.0; 9];
    let good = json!([{"q": zeros, "v": zeros}]).to_string();
    let check = |message: String, expected: &str| {
        assert!(message.contains(expected), "expected \"{expected}\" in: {message}");
    };

    check(cli_error(Path::new("/nonexistent/robot.urdf"), "x", &good), "cannot read URDF /nonexistent/robot.urdf");
    let missing = dynamics_cli::run(&panda, "panda_hand", Path::new("/nonexistent/states.json")).unwrap_err();
    check(missing, "cannot read states file /nonexistent/states.json");
    check(cli_error(&panda, "nope", &good), "unknown frame \"nope\"");
    check(cli_error(&panda, "panda_hand", "[{\"q\": [0, 0"), "malformed JSON");
    check(cli_error(&panda, "panda_hand", "{\"q\": []}"), "expected a JSON array");
    let nan = good.replacen("0.0", "NaN", 1);
    check(cli_error(&panda, "panda_hand", &nan), "non-finite number NaN");
    let null = good.replacen("0.0", "null", 1);
    check(cli_error(&panda, "panda_hand", &null), "state 0: q[0] is null, expected a finite number");
    let short = json!([{"q": zeros, "v": zeros}, {"q": zeros, "v": vec![0.0; 8]}]).to_string();
    check(cli_error(&panda, "panda_hand", &short), "state 1: \"v\" has 8 entries, expected 9 (one per joint)");

    let garbage = TempFile::new("garbage.urdf", "<robot name='x'><link name='a'>");
    check(cli_error(&garbage.0, "a", &good), "malformed XML");
    // 41 revolute joints in a chain: beyond the command's compile-time sizes.
    let mut chain = String::from("<robot name='chain'><link name='l0'/>");
    for i in 1..=41 {
        chain += &format!(
            "<link name='l{i}'><inertial><mass value='1'/><inertia ixx='1' ixy='0' ixz='0' iyy='1' iyz='0' izz='1'/>\
             </inertial></link><joint name='j{i}' type='continuous'><parent link='l{}'/><child link='l{i}'/></joint>",
            i - 1
        );
    }
    let chain = TempFile::new("chain.urdf", &(chain + "</robot>"));
    check(cli_error(&chain.0, "l0", &good), "the URDF has 41 movable joints; the dynamics command supports at most 40");
}
