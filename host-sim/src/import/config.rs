//! The default `config.toml` of an imported robot: every key of `robot-config`'s schema, the
//! robot's parts from its [`Layout`], and gains by one rule from the model.
//!
//! **The default rule.** The arms are named `arm_0`, `arm_1`, … in the order of the `--tcp`
//! options. Per coordinate, from its effort limit `τ_max` (Nm, N): joint stiffness
//! `τ_max / (10 rad)` (a tenth of the peak torque one radian off the posture), joint and safe
//! damping `0.1 s` times the stiffness, torque rate `100 τ_max` per second (the full torque in
//! 10 ms, as Justin's). The arm values are per joint of arm 0 (every arm has the same joints,
//! [`PER_ARM_JOINTS`]), the torso's is the rule on its strongest joint. Every other value is
//! Justin's chosen or thesis value (`fixtures/robots/justin/config.toml`, where each is argued),
//! the platform's too: without a platform (`[robot] platform = false`) it drives nothing. The
//! Fig. 6.3 hierarchy for arm 0: level 0 the strong collision avoidance and its Cartesian
//! impedance, level 1 the weak collision avoidance, its singularity avoidance, the end stops,
//! the torso's and the other arms' joint impedance and the damping of the upper body. No
//! service tasks.

use super::layout::Layout;
use crate::urdf::Description;

/// Joints per arm the configuration file holds (`robot-config`'s `arm = [_; 7]`).
pub const PER_ARM_JOINTS: usize = 7;

/// The default `config.toml` of the robot `name` (module docs), validated by `robot-config`.
pub(crate) fn default_file(name: &str, description: &Description, layout: &Layout) -> Result<String, String> {
    let effort: Vec<f64> = description.coordinates.iter().map(|c| c.effort).collect();
    let arm_effort: Vec<f64> = layout
        .arms
        .first()
        .map(|arm| arm.iter().zip(&effort).filter(|(on, _)| **on).map(|(_, e)| *e).collect())
        .unwrap_or_default();
    if arm_effort.len() != PER_ARM_JOINTS {
        return Err(format!(
            "arm 0 has {} joints: the configuration file holds arms of {PER_ARM_JOINTS}",
            arm_effort.len()
        ));
    }
    let torso_effort = layout
        .torso
        .as_ref()
        .map_or(0.0, |torso| torso.iter().zip(&effort).filter(|(on, _)| **on).map(|(_, e)| *e).fold(0.0, f64::max));
    let stiffness = |effort: f64| effort / 10.0;
    let damping = |effort: f64| 0.1 * stiffness(effort);
    let per_coordinate = |platform: &str, rule: &dyn Fn(f64) -> f64| {
        let arm: Vec<String> = arm_effort.iter().map(|e| number(rule(*e))).collect();
        format!("{{ platform = {platform}, torso = {}, arm = [{}] }}", number(rule(torso_effort)), arm.join(", "))
    };
    let arms: Vec<String> = (0..layout.arms.len()).map(|a| format!("arm_{a}")).collect();
    let quoted = |names: &[String]| names.iter().map(|n| format!("\"{n}\"")).collect::<Vec<_>>().join(", ");
    let mut idle: Vec<String> = layout.torso.iter().map(|_| "joint_impedance_torso".to_owned()).collect();
    idle.extend(arms.iter().skip(1).map(|arm| format!("joint_impedance_{arm}_arm")));
    let level_1: Vec<String> = ["collision_weak".to_owned(), "singularity_arm_0".to_owned(), "end_stops".to_owned()]
        .into_iter()
        .chain(idle)
        .chain(["joint_damping_upper_body".to_owned()])
        .collect();
    let text = TEMPLATE
        .replace("{name}", name)
        .replace("{arms}", &quoted(&arms))
        .replace("{torso}", &layout.torso.is_some().to_string())
        .replace("{platform}", &layout.planar_base.to_string())
        .replace("{level_1}", &quoted(&level_1))
        .replace("{stiffness}", &per_coordinate("[200.0, 200.0, 100.0]", &stiffness))
        .replace("{damping}", &per_coordinate("[300.0, 300.0, 100.0]", &damping))
        .replace("{safe_damping}", &per_coordinate("[0.0, 0.0, 0.0]", &damping))
        .replace("{torque_rate}", &per_coordinate("[1.0, 1.0, 1.0]", &|e| 100.0 * e));
    robot_config::parse(&text, &format!("fixtures/robots/{name}/config.toml")).map_err(|e| e.to_string())?;
    Ok(text)
}

/// The module `config` of the robot's `mod.rs`: the constants `fixtures/build.rs` compiles
/// from its `config.toml`.
pub(crate) fn module_source(name: &str) -> String {
    format!(
        "\n/// The constants of `fixtures/robots/{name}/config.toml`, compiled by `fixtures/build.rs` (robot-config): one\n\
         /// module per TOML table, one constant per key in capitals.\n\
         #[allow(missing_docs, reason = \"one constant per key of the file, documented there\")]\n\
         pub mod config {{\n    include!(concat!(env!(\"OUT_DIR\"), \"/{name}_config.rs\"));\n}}\n"
    )
}

/// `x` as a TOML float that reads back to the same `f64`.
fn number(x: f64) -> String {
    format!("{x:?}")
}

/// The file with the robot's parts and the rule's values as `{placeholders}`.
const TEMPLATE: &str = r#"# The default whole-body configuration of the imported robot `{name}`, written by
# `host-sim import` (host-sim/src/import/config.rs documents the rule; re-running the import
# rewrites it). `fixtures/build.rs` compiles it into `fixtures::robots::{name}::config`. Justin's
# file (fixtures/robots/justin/config.toml) argues every value that is not from the rule.

[robot]
arms = [{arms}]
torso = {torso}
platform = {platform}

[controller]
period_s = 0.001
transition_s = 1.0

[controller.shaping]
singular_full = 0.05
singular_start = 0.15

[cartesian]
translational_stiffness = 500.0
rotational_stiffness = 100.0
damping_ratio = 0.7
fallback_damping = [70.0, 70.0, 70.0, 10.0, 10.0, 10.0]

# Fig. 6.3 for arm 0.
[hierarchy.fig_6_3]
levels = [
    ["collision_strong", "cartesian_arm_0"],
    [{level_1}],
]

[service_tasks]

[collision.strong]
max_force = 150.0
influence_distance = 0.05
damping_ratio = 0.7
activation_full = 0.01
activation_zero = 0.05

[collision.weak]
max_force = 25.0
influence_distance = 0.15
damping_ratio = 0.7
activation_full = 0.0
activation_zero = 0.15

[singularity]
rows = [true, true, true, false, false, false]
threshold = 0.025
full_activation = 0.01
stiffness = 2.0e5
damping = 50.0

[end_stops]
margin = 0.2
stiffness = 200.0
damping = 5.0

# Justin's torso geometry; unused by a robot without Justin's torso workspace task.
[torso_workspace]
torque_limit_nm = 230.0
load_force_n = 323.73
load_angle_deg = 90.0

[torso_workspace.repulsion]
max_stiffness = 1000.0
distance = 0.1
damping_ratio = 0.3

# The rule: stiffness τ_max / 10 rad, damping 0.1 s × stiffness, torque rate 100 τ_max / s.
[joint]
stiffness = {stiffness}
damping = {damping}
safe_damping = {safe_damping}

[platform]
force_deadband = [2.0, 2.0, 1.0]

[platform.compensation]
coupling = true
gravity = true

[platform.admittance]
mass = [60.0, 60.0, 20.0]
damping = [400.0, 400.0, 120.0]
force_limit = [200.0, 200.0, 80.0]
free_axes = [true, true, true]

[platform.icr_avoidance]
enabled = true
max_extension_m = 0.12
extension_ratio = 0.4
max_force = 0.8
min_yaw_rate = 0.001

[platform.legs]
motion = true
mass_kg = 0.2
damping_kg_s = 1.0
cubic_stiffness_n_m3 = 1.0e3
return_pole_rad_s = 2.0
return_blend_m = 0.05

[output_limits]
torque_rate = {torque_rate}
base_velocity = [1.1, 1.1, 2.1]
base_acceleration = [2.0, 2.0, 4.0]
leg_rate = 0.2

[input_limits]
position_tolerance = 0.05
velocity_factor = 1.5
max_cycle_gap = 5
brake_after_cycles = 200

[observer]
gain = 50.0
contact_threshold = 8.0

[force_limit]
enabled = true
margin = 0.05
gain = 3.0
max_correction = 10.0
regularisation = 1e-4

[speed_barrier]
onset = 0.5
full = 0.9
braking_time_s = 0.002
max_torque_fraction = 0.25

[recovery]
valid_cycles = 100
margin = 0.2
blend_s = 0.2
"#;
