//! Justin's configuration file, and the one-line error of each kind of bad file (made from
//! Justin's by one edit).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    reason = "tests: a failure is a test failure"
)]

use kernel::controller::config::{ArmId, TaskKind};
use robot_config::parse;

const ORIGIN: &str = "justin/config.toml";

fn justin() -> String {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/robots/justin/config.toml");
    std::fs::read_to_string(path).unwrap()
}

/// The error of Justin's file with `from` replaced by `to` (which must occur exactly once).
fn error_after(from: &str, to: &str) -> String {
    let text = justin();
    assert_eq!(text.matches(from).count(), 1, "`{from}` must occur once");
    let error = parse(&text.replacen(from, to, 1), ORIGIN).expect_err("the edited file must be refused");
    error.to_string()
}

/// The line (1-based) of Justin's file where `needle` first occurs.
fn line_of(needle: &str) -> usize {
    let text = justin();
    text[..text.find(needle).unwrap()].matches('\n').count() + 1
}

/// Justin's file with the Fig. 6.3 hierarchy replaced by `levels` (TOML).
fn error_with_fig_6_3_levels(levels: &str) -> String {
    let text = justin();
    let start = text.find("[hierarchy.fig_6_3]\nlevels = [").unwrap();
    let end = start + text[start..].find("\n]\n").unwrap() + 3;
    let edited = format!("{}[hierarchy.fig_6_3]\nlevels = {levels}\n{}", &text[..start], &text[end..]);
    parse(&edited, ORIGIN).expect_err("the edited file must be refused").to_string()
}

#[test]
fn justins_file_holds_the_thesis_values() {
    let config = parse(&justin(), ORIGIN).unwrap();
    assert_eq!(config.cartesian.translational_stiffness.0, 500.0);
    assert_eq!(config.cartesian.rotational_stiffness.0, 100.0);
    assert_eq!(config.cartesian.damping_ratio.0, 0.7);
    let fig_6_3: Vec<(usize, TaskKind)> = config.hierarchy.fig_6_3.levels.tasks().collect();
    assert_eq!(fig_6_3.len(), 9);
    assert_eq!(fig_6_3[1], (0, TaskKind::CartesianImpedance(ArmId::RIGHT)));
    assert_eq!(fig_6_3.iter().filter(|(level, _)| *level == 1).count(), 7);
    let names: Vec<&str> = config.service_tasks.keys().map(String::as_str).collect();
    assert_eq!(names, ["clean_mug", "sweep_floor", "wipe_window"]);
    let wipe = &config.service_tasks["wipe_window"];
    assert_eq!(wipe.force_upper.map(|f| f.0), [10.0, f64::INFINITY, f64::INFINITY]);
    assert_eq!(wipe.levels.tasks().count(), 5);
}

#[test]
fn a_missing_key_is_named() {
    assert_eq!(
        error_after("threshold = 0.025\n", ""),
        format!("justin/config.toml:{}: singularity.threshold: missing key", line_of("[singularity]"))
    );
}

#[test]
fn an_unknown_key_is_named_with_the_known_ones() {
    assert_eq!(
        error_after("threshold = 0.025\n", "threshold = 0.025\nthreshhold = 1.0\n"),
        format!(
            "justin/config.toml:{}: singularity.threshhold: unknown key (expected one of `rows`, `threshold`, \
             `full_activation`, `stiffness`, `damping`)",
            line_of("threshold = 0.025") + 1
        )
    );
}

#[test]
fn negative_or_non_finite_stiffness_damping_and_limits_are_refused() {
    assert_eq!(
        error_after("stiffness = 2.0e4", "stiffness = -2.0e4"),
        format!(
            "justin/config.toml:{}: singularity.stiffness: -20000 is not finite and non-negative",
            line_of("stiffness = 2.0e4")
        )
    );
    assert_eq!(
        error_after("gain = 50.0", "gain = nan"),
        format!("justin/config.toml:{}: observer.gain: NaN is not finite and non-negative", line_of("gain = 50.0"))
    );
    assert_eq!(
        error_after("torso = 40.0", "torso = inf"),
        format!(
            "justin/config.toml:{}: joint.damping.torso: inf is not finite and non-negative",
            line_of("torso = 40.0")
        )
    );
    assert_eq!(
        error_after("base_velocity = [1.1, 1.1, 2.1]", "base_velocity = [1.1, -1.1, 2.1]"),
        format!(
            "justin/config.toml:{}: output_limits.base_velocity[1]: -1.1 is not finite and non-negative",
            line_of("base_velocity =")
        )
    );
    assert_eq!(
        error_after("force_upper = [20.0, 20.0, 20.0]", "force_upper = [20.0, nan, 20.0]"),
        format!("justin/config.toml:{}: service_tasks.clean_mug.force_upper[1]: NaN is not a force limit (inf or -inf for none)", line_of("force_upper = [20.0, 20.0, 20.0]"))
    );
}

#[test]
fn an_unknown_task_or_hand_is_named() {
    let error = error_after("\"end_stops\",\n        \"torso", "\"end_stop\",\n        \"torso");
    assert!(
        error.starts_with(&format!(
            "justin/config.toml:{}: hierarchy.fig_6_3.levels[1][2]: unknown task `end_stop` (known: cartesian_right, ",
            line_of("[hierarchy.fig_6_3]") + 3 // the line of level 1
        )),
        "{error}"
    );
    assert!(!error.contains('\n'));
    assert_eq!(
        error_after("hands = [\"right\"]", "hands = [\"middle\"]"),
        format!(
            "justin/config.toml:{}: service_tasks.wipe_window.hands[0]: unknown hand `middle` (known: right, left)",
            line_of("hands = [\"right\"]")
        )
    );
}

#[test]
fn a_duplicate_task_is_refused() {
    assert_eq!(
        error_after(
            "[\"cartesian_right\"],\n    [\"collision_strong\"]",
            "[\"cartesian_right\"],\n    [\"cartesian_right\"]"
        ),
        format!("justin/config.toml:{}: service_tasks.wipe_window.levels: duplicate task `cartesian_right` on levels 0 and 1", line_of("[service_tasks.wipe_window]") + 1)
    );
}

#[test]
fn more_levels_or_tasks_than_the_kernel_holds_overflow() {
    let nine_levels: Vec<String> =
        TaskKind::all::<2>().iter().take(9).map(|kind| format!("[\"{}\"]", kind.name())).collect();
    assert_eq!(
        error_with_fig_6_3_levels(&format!("[{}]", nine_levels.join(", "))),
        format!("justin/config.toml:{}: hierarchy.fig_6_3.levels: level overflow: 9 levels, the kernel holds 8 (MAX_LEVELS)", line_of("[hierarchy.fig_6_3]") + 1)
    );
    let seventeen_tasks: Vec<String> =
        TaskKind::all::<2>().iter().take(17).map(|kind| format!("\"{}\"", kind.name())).collect();
    assert_eq!(
        error_with_fig_6_3_levels(&format!("[[{}]]", seventeen_tasks.join(", "))),
        format!("justin/config.toml:{}: hierarchy.fig_6_3.levels: level overflow: 17 tasks, the kernel holds 16 (MAX_TASKS)", line_of("[hierarchy.fig_6_3]") + 1)
    );
    assert_eq!(
        error_with_fig_6_3_levels("[[\"cartesian_right\"], [], [\"end_stops\"]]"),
        format!(
            "justin/config.toml:{}: hierarchy.fig_6_3.levels: level 1 is empty",
            line_of("[hierarchy.fig_6_3]") + 1
        )
    );
}

#[test]
fn a_wrong_type_or_syntax_is_one_line() {
    assert_eq!(
        error_after("max_cycle_gap = 5", "max_cycle_gap = -5"),
        format!(
            "justin/config.toml:{}: input_limits.max_cycle_gap: invalid value: integer `-5`, expected u32",
            line_of("max_cycle_gap")
        )
    );
    assert_eq!(
        error_after("leg_rate = 0.2", "leg_rate = 0.2 0.3"),
        format!("justin/config.toml:{}: string values must be quoted, expected literal string", line_of("leg_rate"))
    );
}

#[test]
fn a_stiffness_edited_in_the_file_is_the_compiled_constant() {
    let constants = |text: &str| robot_config::rust_constants(&parse(text, ORIGIN).unwrap(), ORIGIN).unwrap();
    let singularity = |code: &str| {
        let start = code.find("pub mod singularity {").unwrap();
        code[start..start + code[start..].find('}').unwrap()].to_string()
    };
    let justin = justin();
    assert!(singularity(&constants(&justin)).contains("pub const STIFFNESS: f64 = 20000.0;\n"));
    let stiffer = justin.replacen("stiffness = 2.0e4", "stiffness = 2.5e5", 1);
    assert!(singularity(&constants(&stiffer)).contains("pub const STIFFNESS: f64 = 250000.0;\n"));
    let code = constants(&justin);
    assert!(code.contains("pub const FORCE_UPPER: [f64; 3] = [10.0, f64::INFINITY, f64::INFINITY];"));
    assert!(code.contains("pub const REGULARISATION: f64 = 0.0001;"));
    assert!(code.contains(
        "pub const HANDS: [::kernel::controller::config::ArmId; 1] = [::kernel::controller::config::ArmId(0)];"
    ));
}

/// The task names follow `[robot]`: with the arms renamed, Justin's hierarchy names tasks of arms
/// the robot does not have; a robot without a torso refuses its torso tasks; the renamed tasks
/// read as the same kernel tasks.
#[test]
fn tasks_are_checked_against_the_robots_parts() {
    let one_arm = justin().replacen("arms = [\"right\", \"left\"]", "arms = [\"right\"]", 1);
    let error = parse(&one_arm, ORIGIN).expect_err("Justin's hierarchy names the left arm").to_string();
    assert_eq!(
        error,
        format!(
            "justin/config.toml:{}: hierarchy.fig_6_3.levels[1][5]: unknown task `joint_impedance_left_arm` (known: \
             cartesian_right, collision_strong, collision_weak, singularity_right, end_stops, torso_workspace, \
             joint_impedance_platform, joint_impedance_torso, joint_impedance_right_arm, joint_impedance_upper_body, \
             joint_damping_platform, joint_damping_torso, joint_damping_right_arm, joint_damping_upper_body)",
            line_of("[hierarchy.fig_6_3]") + 3 // the line of level 1
        )
    );
    // Without the end stops' torso values (`[end_stops]` is read before `[hierarchy]`).
    let no_torso = justin()
        .replacen("torso = true", "torso = false", 1)
        .replace("torso = 200.0, ", "")
        .replace("torso = 5.0, ", "");
    let error = parse(&no_torso, ORIGIN).expect_err("Justin's hierarchy names the torso").to_string();
    assert!(error.contains("levels[1][3]: unknown task `torso_workspace` (known: "), "{error}");
    let renamed = justin()
        .replacen("arms = [\"right\", \"left\"]", "arms = [\"tool\", \"camera\"]", 1)
        .replace("_right", "_tool")
        .replace("_left", "_camera")
        .replace("hands = [\"right\"]", "hands = [\"tool\"]")
        .replace("hands = [\"right\", \"left\"]", "hands = [\"tool\", \"camera\"]");
    let renamed = parse(&renamed, ORIGIN).unwrap();
    let original = parse(&justin(), ORIGIN).unwrap();
    assert_eq!(renamed.hierarchy, original.hierarchy);
    assert_eq!(renamed.service_tasks, original.service_tasks);
    assert_eq!(renamed.hierarchy.fig_6_3.levels.0[0][1].0, TaskKind::CartesianImpedance(ArmId::RIGHT));
}

/// The tables of the robot's parts agree with `[robot]`: an `arm` list has `arm_joints` values, a
/// robot without a platform refuses the platform's values, one with a platform or a torso needs
/// theirs, the `torso_workspace` task needs its table. Each refusal names the key.
#[test]
fn the_parts_tables_agree_with_the_robot() {
    assert_eq!(
        error_after("arm_joints = 7", "arm_joints = 6"),
        format!(
            "justin/config.toml:{}: end_stops.damping.arm: 7 values for arms of 6 joints ([robot] arm_joints)",
            line_of("damping = { platform")
        )
    );
    assert_eq!(
        error_after("platform = true", "platform = false"),
        format!(
            "justin/config.toml:{}: end_stops.damping.platform: the robot has no platform ([robot] platform = false)",
            line_of("damping = { platform")
        )
    );
    assert_eq!(
        error_after("leg_rate = 0.2\n", ""),
        "justin/config.toml: output_limits.leg_rate: missing key ([robot] platform = true)"
    );
    assert_eq!(
        error_after("torso = 40.0, ", ""),
        "justin/config.toml: joint.damping.torso: missing key ([robot] torso = true)"
    );
    let text = justin();
    let (start, end) = (text.find("[torso_workspace]").unwrap(), text.find("# Joint impedance and damping").unwrap());
    let error = parse(&format!("{}{}", &text[..start], &text[end..]), ORIGIN).unwrap_err().to_string();
    assert_eq!(error, "justin/config.toml: torso_workspace: missing key (a hierarchy has the torso_workspace task)");
}
