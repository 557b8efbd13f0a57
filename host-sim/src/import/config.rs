//! The default `config.toml` of an imported robot: every key of `robot-config`'s schema the
//! robot's parts need (`[platform]` only with `--base planar`, the torso's values only with a
//! torso), the parts from its [`Layout`], and the gains by one rule from the model.
//!
//! **The gain rule**, at the middle of every joint's range (the posture farthest from the end
//! stops; zero for a joint without limits), or at the import's `--home` posture if it gives one;
//! refused if a TCP is near a singularity there (the singular values of its translational or
//! rotational Jacobian further apart than [`SINGULAR_RATIO`]: the reflected inertia grows without
//! bound; the KUKA iiwa's mid-range is its stretched arm, the UR5's has the wrist's first and
//! last axes aligned): the Cartesian stiffness is `K = λ ω_c²` with `λ`
//! the largest eigenvalue of the translational reflected inertia `(J_p M⁻¹ J_pᵀ)⁻¹` over the
//! TCPs, the rotational one `λ_r ω_c²` likewise, so the heaviest TCP direction has the natural
//! frequency `ω_c` ([`CARTESIAN_FREQUENCY_RAD_S`]); the kernel damps it with the thesis'
//! `ξ = 0.7` ([`DAMPING_RATIO`], double diagonalisation). Per coordinate, from the diagonal
//! inertia `M_kk`: joint stiffness `ω_j² M_kk` and damping `2 ξ ω_j M_kk`
//! ([`JOINT_FREQUENCY_RAD_S`]; the safe output's damping too), torque rate `100 τ_max` per second
//! (the full torque in 10 ms, as Justin's). **End stops**, from [`END_STOP_MARGIN`] before a
//! stop, per coordinate on the joint's own inertia: the row `s = q_k` sees `w_k = (M⁻¹)_kk` (every
//! other joint free; the hierarchy's projections only add inertia), and its spring `2 k_mes`
//! ((3.58): `V = k_mes Δ²`) and damping get the natural frequency `ω_k = max(ω_j, v_k / margin)`
//! (`v_k` the joint's velocity limit: a joint entering the band at its limit speed stops within
//! `v_k / ω_k` ≤ the margin even undamped) and `ξ`: `k_mes = ω_k² / (2 w_k)`, `d = 2 ξ ω_k / w_k`.
//! `ω_k Δt` stays below 0.03 on every joint, so the rule holds on a 0.0067 kg m² wrist as on a
//! shoulder (one gain from the heaviest joint gave the wrist `d Δt w = 8.4`, unstable).
//! **Singularity avoidance** (`kernel::tasks::manipulability`, "Sampling"): below the
//! translational manipulability [`SINGULARITY_THRESHOLD`] the row `m` acts on the inertia `1 / w`,
//! `w = ∇m M⁻¹ ∇mᵀ`; `w_max` is the largest `w` over the postures of [`SINGULARITY_SAMPLES`]
//! random ones (uniform within the limits, seed [`SINGULARITY_SEED`]) whose `m` lies in the
//! band `[full_activation, threshold]` (∇m by central differences), over the arms. Then
//! `k_msa` is the smaller of the sampled loop's bound `(ω Δt)² / (2 w_max Δt²)` with `ω Δt =`
//! [`SINGULARITY_OMEGA_DT`] and the torque bound: the spring `2 k_msa (m₀ − m₁) |∂m/∂q_i|` at full
//! activation `m₁` is at most [`SINGULARITY_TORQUE_FRACTION`] of every joint's `τ_max,i` (the
//! largest `|∂m/∂q_i| / τ_max,i` of the survey). `d = 2 ξ ω / w_max` with `ω = √(2 k_msa w_max)`,
//! so `Δt d w ≤ 2 ξ ω Δt ≤ 0.35`, below the delayed damper's bound 0.88 with the margin Justin's
//! file keeps (ω Δt 0.29, `Δt d w` 0.30 at its soak's entry). The `arm` lists hold, per joint, the
//! largest value over the arms (all arms have `[robot] arm_joints` joints: arms of different
//! lengths are refused), the torso's value the largest over its joints. The force limiter is off
//! (no Cartesian force limits). Every other value is Justin's chosen or thesis value
//! (`fixtures/robots/justin/config.toml`, where each is argued); a planar base gets Justin's
//! admittance without ICR avoidance and leg motion (the import knows no legs). The arms are
//! named `arm_0`, `arm_1`, … in the order of the `--tcp` options. The Fig. 6.3 hierarchy for
//! arm 0: level 0 the strong collision avoidance and its Cartesian impedance, level 1 the weak
//! collision avoidance, its singularity avoidance, the end stops, the torso's and the other
//! arms' joint impedance and the damping of the upper body. No service tasks.

use nalgebra::DMatrix;

use super::layout::Layout;
use crate::dynamics_cli::{self, State};
use crate::urdf::Description;

/// Damping ratio of every gain rule (the thesis' `ξ = 0.7`, Ch. 6).
pub const DAMPING_RATIO: f64 = 0.7;
/// Natural frequency of the Cartesian impedance along the heaviest direction (rad/s): 1.5 Hz.
pub const CARTESIAN_FREQUENCY_RAD_S: f64 = 3.0 * core::f64::consts::PI;
/// Natural frequency of the joint impedance, the joint damping and the end stops (rad/s): 3 Hz.
pub const JOINT_FREQUENCY_RAD_S: f64 = 6.0 * core::f64::consts::PI;
/// Smallest ratio of the smallest to the largest singular value of a TCP's translational and of
/// its rotational Jacobian at the gain rule's posture: below it the reflected inertia, which
/// grows with the inverse square, is more than 10⁴ times heavier in one direction than in another.
pub const SINGULAR_RATIO: f64 = 0.01;

/// Distance from each stop at which the end-stop potential starts (rad, m).
pub const END_STOP_MARGIN: f64 = 0.1;
/// Translational manipulability below which the singularity avoidance acts (m³): a 7-DOF arm of
/// about 1 m reach has 0.03–0.1 away from its singularities.
pub const SINGULARITY_THRESHOLD: f64 = 0.01;
/// Manipulability of the singularity avoidance's full activation (m³).
pub const SINGULARITY_FULL_ACTIVATION: f64 = 0.002;
/// `ω Δt` of the singularity row at the largest sampled `w` (at most ⅓: module docs).
pub const SINGULARITY_OMEGA_DT: f64 = 0.25;
/// Largest fraction of a joint's peak torque the singularity avoidance's spring asks at full
/// activation.
pub const SINGULARITY_TORQUE_FRACTION: f64 = 0.5;
/// Random postures of the singularity rule's survey.
pub const SINGULARITY_SAMPLES: usize = 2000;
/// Seed of that survey.
pub const SINGULARITY_SEED: u64 = 0x5176_0001;
/// The control period the rule sizes the sampled rows for (s): the file's `period_s`.
const PERIOD_S: f64 = 0.001;
/// Step of the central differences of `∇m` (rad, m).
const GRADIENT_STEP: f64 = 1e-6;

/// The model's inertia at the rule's posture: the mass matrix and each TCP's Jacobian
/// (world-aligned, linear rows first).
struct Inertia {
    mass: DMatrix<f64>,
    jacobians: Vec<DMatrix<f64>>,
}

/// The middle of every joint's range (zero without limits).
pub(crate) fn mid_range(description: &Description) -> Vec<f64> {
    let middle = |c: &crate::urdf::CoordinateSpec| {
        let m = 0.5 * (c.lower + c.upper);
        if m.is_finite() {
            m
        } else {
            0.0
        }
    };
    description.coordinates.iter().map(middle).collect()
}

/// `M` and the TCP Jacobians at the posture `q`, through the `dynamics` command's evaluation;
/// refused if a TCP is near a singularity there ([`SINGULAR_RATIO`]).
fn inertia(description: &Description, tcps: &[String], q: &[f64], posture: &str) -> Result<Inertia, String> {
    let state = State { v: vec![0.0; q.len()], q: q.to_vec() };
    let mut mass = None;
    let mut jacobians = Vec::new();
    for tcp in tcps {
        let (m, jacobian) =
            evaluate(description, tcp, std::slice::from_ref(&state))?.pop().ok_or("no dynamics record")?;
        mass = Some(m);
        for (first_row, part) in [(0, "translational"), (3, "rotational")] {
            let sigma = jacobian.rows(first_row, 3).singular_values();
            let ratio = sigma.min() / sigma.max();
            if ratio.is_nan() || ratio < SINGULAR_RATIO {
                return Err(format!(
                    "TCP {tcp} is near a singularity at {posture} (q = {q:?}): its {part} Jacobian's singular values {:.3e} to {:.3e}, ratio below {SINGULAR_RATIO}; give the gain rule a posture away from it with --home",
                    sigma.min(),
                    sigma.max()
                ));
            }
        }
        jacobians.push(jacobian);
    }
    Ok(Inertia { mass: mass.ok_or("no TCP")?, jacobians })
}

/// The largest eigenvalue of the reflected inertia `(J M⁻¹ Jᵀ)⁻¹` of the Jacobian's `rows` (three
/// from the first), over the TCPs.
fn heaviest(inertia: &Inertia, inverse: &DMatrix<f64>, first_row: usize) -> Result<f64, String> {
    let mut heaviest: f64 = 0.0;
    for jacobian in &inertia.jacobians {
        let j = jacobian.rows(first_row, 3);
        let reflected = (j * inverse * j.transpose()).try_inverse().ok_or("a TCP is singular at the rule's posture")?;
        heaviest = heaviest.max(reflected.symmetric_eigenvalues().max());
    }
    Ok(heaviest)
}

/// The mass matrix and a TCP's Jacobian (world-aligned, linear rows first) at one state.
type MassAndJacobian = (DMatrix<f64>, DMatrix<f64>);

/// `M` and the TCP's Jacobian at each of `states` (the `dynamics` command's evaluation).
fn evaluate(description: &Description, tcp: &str, states: &[State]) -> Result<Vec<MassAndJacobian>, String> {
    let text = dynamics_cli::dispatch(description, tcp, states)?;
    let records: Vec<serde_json::Value> = serde_json::from_str(&text).map_err(|e| e.to_string())?;
    records.iter().map(|record| Ok((matrix(&record["M"])?, matrix(&record["J"])?))).collect()
}

/// A matrix of the `dynamics` command's output (a list of rows).
fn matrix(value: &serde_json::Value) -> Result<DMatrix<f64>, String> {
    let rows: Vec<Vec<f64>> = serde_json::from_value(value.clone()).map_err(|e| e.to_string())?;
    let columns = rows.first().map_or(0, Vec::len);
    Ok(DMatrix::from_row_iterator(rows.len(), columns, rows.into_iter().flatten()))
}

/// The translational manipulability `√det(J_p J_pᵀ)` (3.55) of the arm's columns `arm`.
fn manipulability(jacobian: &DMatrix<f64>, arm: &[bool]) -> f64 {
    let columns: Vec<usize> = arm.iter().enumerate().filter(|(_, on)| **on).map(|(k, _)| k).collect();
    let j = jacobian.rows(0, 3).select_columns(&columns);
    (&j * j.transpose()).determinant().max(0.0).sqrt()
}

/// Over the sampled postures in the singularity band and over the arms (module docs): the largest
/// `w = ∇m M⁻¹ ∇mᵀ` and the largest `|∂m/∂q_i| / τ_max,i`.
fn singularity_survey(description: &Description, layout: &Layout, tcps: &[String]) -> Result<(f64, f64), String> {
    use rand::rngs::Xoshiro256PlusPlus;
    use rand::SeedableRng;
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(SINGULARITY_SEED);
    let postures: Vec<State> = (0..SINGULARITY_SAMPLES)
        .map(|_| {
            let q = super::random_posture(description, &mut rng);
            State { v: vec![0.0; q.len()], q }
        })
        .collect();
    let (mut largest, mut slope, mut count): (f64, f64, usize) = (0.0, 0.0, 0);
    for (tcp, arm) in tcps.iter().zip(&layout.arms) {
        let band: Vec<(&State, DMatrix<f64>)> = postures
            .iter()
            .zip(evaluate(description, tcp, &postures)?)
            .filter(|(_, (_, j))| {
                (SINGULARITY_FULL_ACTIVATION..=SINGULARITY_THRESHOLD).contains(&manipulability(j, arm))
            })
            .map(|(state, (mass, _))| (state, mass))
            .collect();
        let coordinates: Vec<usize> = arm.iter().enumerate().filter(|(_, on)| **on).map(|(k, _)| k).collect();
        let mut shifted = Vec::new();
        for (state, _) in &band {
            for &k in &coordinates {
                for sign in [1.0, -1.0] {
                    let mut q = state.q.clone();
                    if let Some(x) = q.get_mut(k) {
                        *x += sign * GRADIENT_STEP;
                    }
                    shifted.push(State { v: state.v.clone(), q });
                }
            }
        }
        let values: Vec<f64> =
            evaluate(description, tcp, &shifted)?.iter().map(|(_, j)| manipulability(j, arm)).collect();
        for ((_, mass), differences) in band.iter().zip(values.chunks(2 * coordinates.len())) {
            let mut gradient = DMatrix::<f64>::zeros(1, mass.nrows());
            for (&k, pair) in coordinates.iter().zip(differences.chunks(2)) {
                if let ([plus, minus], Some(slot)) = (pair, gradient.get_mut(k)) {
                    *slot = (plus - minus) / (2.0 * GRADIENT_STEP);
                }
            }
            let inverse = mass.clone().try_inverse().ok_or("a sampled mass matrix is singular")?;
            largest = largest.max((&gradient * inverse * gradient.transpose()).trace());
            for (g, c) in gradient.iter().zip(&description.coordinates) {
                slope = slope.max(g.abs() / c.effort);
            }
        }
        count += band.len();
    }
    if count == 0 {
        return Err(format!(
            "no posture of {SINGULARITY_SAMPLES} samples has a manipulability in [{SINGULARITY_FULL_ACTIVATION}, {SINGULARITY_THRESHOLD}]"
        ));
    }
    Ok((largest, slope))
}

/// The default `config.toml` of the robot `name` (module docs), validated by `robot-config`; the
/// gain rule at `home` (one value per coordinate, rad or m) or, without it, at mid-range.
pub(crate) fn default_file(
    name: &str,
    description: &Description,
    layout: &Layout,
    tcps: &[String],
    home: Option<&[f64]>,
) -> Result<String, String> {
    let arm_joints = arm_joints(layout)?;
    let (q, posture) = match home {
        Some(q) => (q.to_vec(), "the --home posture"),
        None => (mid_range(description), "mid-range"),
    };
    let inertia = inertia(description, tcps, &q, posture)?;
    let inverse = inertia.mass.clone().try_inverse().ok_or("the mass matrix at the rule's posture is singular")?;
    let w2 = CARTESIAN_FREQUENCY_RAD_S * CARTESIAN_FREQUENCY_RAD_S;
    let diagonal: Vec<f64> = inertia.mass.diagonal().iter().copied().collect();
    let inverse_diagonal: Vec<f64> = inverse.diagonal().iter().copied().collect();
    let stop_frequency = |c: &crate::urdf::CoordinateSpec| JOINT_FREQUENCY_RAD_S.max(c.velocity / END_STOP_MARGIN);
    let stops = |rule: &dyn Fn(f64, f64) -> f64| {
        description
            .coordinates
            .iter()
            .zip(&inverse_diagonal)
            .map(|(c, w)| rule(stop_frequency(c), *w))
            .collect::<Vec<f64>>()
    };
    let (w_max, slope) = singularity_survey(description, layout, tcps)?;
    let sampled = (SINGULARITY_OMEGA_DT / PERIOD_S).powi(2) / (2.0 * w_max);
    let torque = SINGULARITY_TORQUE_FRACTION / (2.0 * (SINGULARITY_THRESHOLD - SINGULARITY_FULL_ACTIVATION) * slope);
    let singularity_stiffness = sampled.min(torque);
    let singularity_omega = (2.0 * singularity_stiffness * w_max).sqrt();
    let effort: Vec<f64> = description.coordinates.iter().map(|c| c.effort).collect();
    let joint_stiffness = |m: f64| JOINT_FREQUENCY_RAD_S * JOINT_FREQUENCY_RAD_S * m;
    let joint_damping = |m: f64| 2.0 * DAMPING_RATIO * JOINT_FREQUENCY_RAD_S * m;
    let per_coordinate = |values: &[f64], platform: &str| per_coordinate(layout, arm_joints, values, platform);
    let scaled = |rule: &dyn Fn(f64) -> f64| diagonal.iter().map(|m| rule(*m)).collect::<Vec<f64>>();
    let arms: Vec<String> = (0..layout.arms.len()).map(|a| format!("arm_{a}")).collect();
    let quoted = |names: &[String]| names.iter().map(|n| format!("\"{n}\"")).collect::<Vec<_>>().join(", ");
    let mut idle: Vec<String> = layout.torso.iter().map(|_| "joint_impedance_torso".to_owned()).collect();
    idle.extend(arms.iter().skip(1).map(|arm| format!("joint_impedance_{arm}_arm")));
    let level_1: Vec<String> = ["collision_weak".to_owned(), "singularity_arm_0".to_owned(), "end_stops".to_owned()]
        .into_iter()
        .chain(idle)
        .chain(["joint_damping_upper_body".to_owned()])
        .collect();
    let planar = layout.planar_base;
    let text = TEMPLATE
        .replace("{name}", name)
        .replace("{posture}", posture)
        .replace("{arms}", &quoted(&arms))
        .replace("{arm_joints}", &arm_joints.to_string())
        .replace("{torso}", &layout.torso.is_some().to_string())
        .replace("{platform}", &planar.to_string())
        .replace("{level_1}", &quoted(&level_1))
        .replace("{translational_stiffness}", &number(heaviest(&inertia, &inverse, 0)? * w2))
        .replace("{rotational_stiffness}", &number(heaviest(&inertia, &inverse, 3)? * w2))
        .replace("{singularity_threshold}", &number(SINGULARITY_THRESHOLD))
        .replace("{singularity_full_activation}", &number(SINGULARITY_FULL_ACTIVATION))
        .replace("{singularity_stiffness}", &number(singularity_stiffness))
        .replace("{singularity_damping}", &number(2.0 * DAMPING_RATIO * singularity_omega / w_max))
        .replace("{singularity_w}", &format!("{w_max:.3}"))
        .replace("{singularity_sampled}", &format!("{sampled:.0}"))
        .replace("{singularity_torque}", &format!("{torque:.0}"))
        .replace("{singularity_omega_dt}", &format!("{:.3}", singularity_omega * PERIOD_S))
        .replace("{end_stop_margin}", &number(END_STOP_MARGIN))
        .replace(
            "{end_stop_stiffness}",
            &per_coordinate(&stops(&|omega, w| omega * omega / (2.0 * w)), "[0.0, 0.0, 0.0]"),
        )
        .replace(
            "{end_stop_damping}",
            &per_coordinate(&stops(&|omega, w| 2.0 * DAMPING_RATIO * omega / w), "[0.0, 0.0, 0.0]"),
        )
        .replace("{stiffness}", &per_coordinate(&scaled(&joint_stiffness), "[200.0, 200.0, 100.0]"))
        .replace("{damping}", &per_coordinate(&scaled(&joint_damping), "[300.0, 300.0, 100.0]"))
        .replace("{safe_damping}", &per_coordinate(&scaled(&joint_damping), "[0.0, 0.0, 0.0]"))
        .replace(
            "{torque_rate}",
            &per_coordinate(&effort.iter().map(|e| 100.0 * e).collect::<Vec<_>>(), "[1.0, 1.0, 1.0]"),
        )
        .replace("{base_limits}", if planar { BASE_LIMITS } else { "" })
        .replace("{platform_tables}", if planar { PLATFORM_TABLES } else { "" });
    robot_config::parse(&text, &format!("fixtures/robots/{name}/config.toml")).map_err(|e| e.to_string())?;
    Ok(text)
}

/// The joints of every arm; refused if the arms differ (the file's `arm` lists serve them all).
fn arm_joints(layout: &Layout) -> Result<usize, String> {
    let counts: Vec<usize> = layout.arms.iter().map(|arm| arm.iter().filter(|on| **on).count()).collect();
    match counts.split_first() {
        Some((first, rest)) if rest.iter().all(|n| n == first) => Ok(*first),
        _ => Err(format!(
            "the arms have {counts:?} joints: the configuration file's per-coordinate tables hold one list for arms of equal length"
        )),
    }
}

/// A per-coordinate table of `values` (one per coordinate): the platform's `platform` with a
/// planar base, the torso's largest value with a torso, per arm joint the largest over the arms.
fn per_coordinate(layout: &Layout, arm_joints: usize, values: &[f64], platform: &str) -> String {
    let masked = |mask: &[bool]| -> Vec<f64> {
        mask.iter().zip(values).filter(|(on, _)| **on).map(|(_, value)| *value).collect()
    };
    let arm: Vec<String> = (0..arm_joints)
        .map(|j| layout.arms.iter().filter_map(|mask| masked(mask).get(j).copied()).fold(0.0, f64::max))
        .map(number)
        .collect();
    let mut entries = Vec::new();
    if layout.planar_base {
        entries.push(format!("platform = {platform}"));
    }
    if let Some(torso) = &layout.torso {
        entries.push(format!("torso = {}", number(masked(torso).into_iter().fold(0.0, f64::max))));
    }
    entries.push(format!("arm = [{}]", arm.join(", ")));
    format!("{{ {} }}", entries.join(", "))
}

/// The module `config` of the robot's `mod.rs` (the constants `fixtures/build.rs` compiles from
/// its `config.toml`), the compile-time check that every arm has `[robot] arm_joints`
/// coordinates, and `controller_config()`: the file in the kernel's types for `layout()`.
pub(crate) fn module_source(name: &str, layout: &Layout) -> String {
    let flag = |present: bool| if present { "yes" } else { "no" };
    format!(
        "\n/// The constants of `fixtures/robots/{name}/config.toml`, compiled by `fixtures/build.rs` (robot-config): one\n\
         /// module per TOML table, one constant per key in capitals.\n\
         #[allow(missing_docs, reason = \"one constant per key of the file, documented there\")]\n\
         pub mod config {{\n    include!(concat!(env!(\"OUT_DIR\"), \"/{name}_config.rs\"));\n}}\n\
         \n\
         const _: () = assert!(\n    crate::config_file::arms_have(&ARM_COORDINATES, config::robot::ARM_JOINTS),\n    \
         \"fixtures/robots/{name}/config.toml: robot.arm_joints differs from the model's arms\"\n);\n\
         \n\
         /// The controller configuration of `config.toml` for [`layout`] (`fixtures::config_file`).\n\
         pub fn controller_config<T: nalgebra::RealField + Copy>(\n) -> Result<kernel::controller::config::ControllerConfig<T, N, ARMS>, kernel::platform::PlatformError> {{\n    \
         Ok(crate::config_file::controller_config!(\n        config,\n        layout: layout()?,\n        \
         platform: {platform}(crate::fixed_base::unused_platform().avoidance),\n        torso: {torso},\n        \
         torso_workspace: no((), ()),\n    ))\n}}\n",
        platform = flag(layout.planar_base),
        torso = flag(layout.torso.is_some()),
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
arm_joints = {arm_joints}
torso = {torso}
platform = {platform}

[controller]
period_s = 0.001
transition_s = 1.0

[controller.shaping]
singular_full = 0.05
singular_start = 0.15

# The rule: the heaviest TCP direction at 1.5 Hz (reflected inertia at {posture}), ξ = 0.7.
[cartesian]
translational_stiffness = {translational_stiffness}
rotational_stiffness = {rotational_stiffness}
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

# A 7-DOF arm of about 1 m reach: translational manipulability 0.03–0.1 m³ away from its
# singularities; the avoidance acts below 0.01. The rule: the smaller of the sampled loop's
# bound (ω Δt = 0.25 on the largest row inverse inertia w = ∇m M⁻¹ ∇mᵀ = {singularity_w} of the
# sampled postures in the band: {singularity_sampled}) and the torque bound (the spring asks at
# most half of any joint's peak torque at full activation: {singularity_torque}); ω Δt = {singularity_omega_dt},
# damping ξ = 0.7 at that w.
[singularity]
rows = [true, true, true, false, false, false]
threshold = {singularity_threshold}
full_activation = {singularity_full_activation}
stiffness = {singularity_stiffness}
damping = {singularity_damping}

# The rule, per joint on its inverse inertia w_k = (M⁻¹)_kk at mid-range: the natural frequency
# ω_k = max(3 Hz, v_max / margin), k_mes = ω_k² / (2 w_k), d = 2 ξ ω_k / w_k (the platform has
# no stops).
[end_stops]
margin = {end_stop_margin}
stiffness = {end_stop_stiffness}
damping = {end_stop_damping}

# The rule: stiffness ω_j² M_kk, damping 2 ξ ω_j M_kk (3 Hz on the diagonal inertia at
# {posture}), torque rate 100 τ_max / s.
[joint]
stiffness = {stiffness}
damping = {damping}
safe_damping = {safe_damping}
# chosen: each joint task's damping lowered where its sampled loop would exceed 0.4 (two joint
# tasks reach 0.8, inside the delayed loop's 0.88; kernel::tasks::joint_impedance).
damping_loop_gain = 0.4
{platform_tables}
[output_limits]
torque_rate = {torque_rate}
{base_limits}
[input_limits]
position_tolerance = 0.05
velocity_factor = 1.5
max_cycle_gap = 5
brake_after_cycles = 200

[observer]
gain = 50.0
contact_threshold = 8.0

# No Cartesian force limits in this file: the limiter is off.
[force_limit]
enabled = false
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

/// The platform's tables of a planar base: Justin's admittance, no ICR avoidance and no leg
/// motion (the import knows no legs).
const PLATFORM_TABLES: &str = r#"
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
enabled = false
max_extension_m = 0.12
extension_ratio = 0.4
max_force = 0.8
min_yaw_rate = 0.001

[platform.legs]
motion = false
mass_kg = 0.2
damping_kg_s = 1.0
cubic_stiffness_n_m3 = 1.0e3
return_pole_rad_s = 2.0
return_blend_m = 0.05
"#;

/// The base's output limits of a planar base (Justin's).
const BASE_LIMITS: &str = "base_velocity = [1.1, 1.1, 2.1]\nbase_acceleration = [2.0, 2.0, 4.0]\nleg_rate = 0.2\n";
