//! `soak`: the Justin-like robot under the whole-body controller of Ch. 6 (Fig. 6.3 hierarchy,
//! right hand, [`crate::wbc::chapter_6_rig`]) for a long simulated time with seeded random
//! disturbances (issue 9, "fuzzing and soak"):
//!
//! - **goals**: every [`GOAL_INTERVAL_S`] a new right-TCP goal, uniform in a box of half-widths
//!   [`GOAL_BOX_M`] around the home TCP position (reachable: the platform and the torso help),
//!   turned by up to [`GOAL_YAW_RAD`] about the vertical, reached along the cubic in
//!   [`GOAL_DURATION_S`];
//! - **pushes**: every [`PUSH_INTERVAL_S`] a world-frame force of [`PUSH_FORCE_N`] in a random
//!   direction on a random one of the right TCP, the left TCP and the torso, for
//!   [`PUSH_DURATION_S`].
//!
//! All intervals are uniform in their ranges, drawn from a xorshift generator seeded with
//! `SOAK_SEED` (environment, default [`SEED`]); with `--plant realistic` the same seed drives the
//! plant's sensor noise. The simulated duration is `SOAK_SECONDS`
//! (environment, default [`DEFAULT_SECONDS`]); `SOAK_SECONDS=3600` is the one-hour soak.
//! `SOAK_RECORD_FROM` (s, environment) records a window for a closer look: no row before it,
//! every cycle from it on (`--record-every` decimates as usual).
//!
//! Reported: the largest torque rate (absolute and relative to its limit), the largest
//! `|τ_i|/τ_max,i`, the largest controller energy (kinetic energy with the closed-loop inertia
//! plus the task potentials), the smallest collision distance (a collision is a pair at
//! distance ≤ 0), the number of cycles with a non-finite state or command, the number of
//! faulty cycles (and per hour), and the largest joint speed relative to its limit. Claims: no
//! NaN, no collision, torques within their effort and rate limits, energy below
//! [`ENERGY_BOUND_J`], no fault, every joint speed within its limit.
//!
//! The time series is downsampled: one row every [`RECORD_EVERY`] cycles with the columns of
//! [`crate::wbc::columns`] plus the window maxima `tau_ratio_max`, `rate_ratio_max` and
//! `energy_j`.

use fixtures::justin;
use kernel::controller::config::ArmId;
use kernel::controller::messages::{Command, Pose};
use kernel::controller::PLATFORM_DOF;
use kernel::model::{FrameId, Placement};
use nalgebra::{SVector, UnitQuaternion, Vector3};

use super::{Outcome, RunOptions};
use crate::output::{Figure, Line, Panel, Summary, TimeSeries};
use crate::sim::{run_loop, CycleInfo, CONTROL_PERIOD_S};
use crate::wbc;

/// Registry name.
pub const NAME: &str = "soak";
/// One-line description.
pub const DESCRIPTION: &str =
    "Justin-like robot, whole-body controller: random TCP goals and pushes (SOAK_SEED) for SOAK_SECONDS (default 60 s); no NaN, no collision, no fault, torques within limits, energy bounded";
/// Simulated time without `SOAK_SECONDS` (s).
pub const DEFAULT_SECONDS: f64 = 60.0;
/// Seed of the disturbance generator.
pub const SEED: u64 = 0x5eed_0f50_a6a6;
/// Half-widths of the goal box around the home TCP position (m). Chosen: inside the arm's
/// reach with some platform and torso motion.
pub const GOAL_BOX_M: [f64; 3] = [0.2, 0.2, 0.15];
/// Largest goal rotation about the vertical (rad). Chosen.
pub const GOAL_YAW_RAD: f64 = 0.3;
/// Time between goals (s), uniform. Chosen.
pub const GOAL_INTERVAL_S: (f64, f64) = (1.5, 4.0);
/// Duration of a goal motion (s), uniform. Chosen.
pub const GOAL_DURATION_S: (f64, f64) = (0.3, 2.0);
/// Time between pushes (s), uniform. Chosen.
pub const PUSH_INTERVAL_S: (f64, f64) = (0.5, 3.0);
/// Push force magnitude (N), uniform. Chosen: a firm hand.
pub const PUSH_FORCE_N: (f64, f64) = (10.0, 50.0);
/// Push duration (s), uniform. Chosen.
pub const PUSH_DURATION_S: (f64, f64) = (0.05, 0.4);
/// Bound of the controller energy (J). Chosen: the springs of a goal at the far corner of the
/// box (½ · 500 N/m · 0.33² m² + ½ · 100 Nm/rad · 0.3² ≈ 32 J) plus the work of the largest push
/// and the other tasks' potentials, with margin.
pub const ENERGY_BOUND_J: f64 = 150.0;
/// Record one time-series row every this many control cycles.
pub const RECORD_EVERY: u64 = 50;

/// The disturbance seed: `SOAK_SEED` (decimal or `0x` hexadecimal) or [`SEED`].
pub fn seed() -> Result<u64, String> {
    match std::env::var("SOAK_SEED") {
        Ok(s) => {
            let text = s.trim();
            let parsed = match text.strip_prefix("0x") {
                Some(hex) => u64::from_str_radix(hex, 16),
                None => text.parse(),
            };
            parsed.map_err(|e| format!("SOAK_SEED={s}: {e}"))
        }
        Err(_) => Ok(SEED),
    }
}

/// The simulated duration: `SOAK_SECONDS` or [`DEFAULT_SECONDS`].
pub fn duration_s() -> Result<f64, String> {
    seconds_from_env("SOAK_SECONDS").map(|s| s.unwrap_or(DEFAULT_SECONDS))
}

/// The start of the recorded window: `SOAK_RECORD_FROM`, or `None` (the whole run, one row
/// every [`RECORD_EVERY`] cycles).
pub fn record_from_s() -> Result<Option<f64>, String> {
    seconds_from_env("SOAK_RECORD_FROM")
}

/// A positive number of seconds from the environment variable `name`, if set.
fn seconds_from_env(name: &str) -> Result<Option<f64>, String> {
    let Ok(s) = std::env::var(name) else { return Ok(None) };
    let value: f64 = s.trim().parse().map_err(|e| format!("{name}={s}: {e}"))?;
    if value.is_finite() && value > 0.0 {
        Ok(Some(value))
    } else {
        Err(format!("{name}={s}: must be a positive number of seconds"))
    }
}

/// xorshift64*, uniform in [0, 1).
#[derive(Clone, Debug)]
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        #[allow(clippy::cast_precision_loss, reason = "53 random bits")]
        let unit = (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1_u64 << 53) as f64;
        unit
    }

    fn uniform(&mut self, (lower, upper): (f64, f64)) -> f64 {
        lower + (upper - lower) * self.next()
    }
}

/// What a soak run found.
#[derive(Clone, Debug, PartialEq)]
pub struct SoakMetrics {
    /// Simulated time (s).
    pub duration_s: f64,
    /// Largest `|τ_i(k) − τ_i(k−1)| / Δt` (Nm/s).
    pub max_torque_rate: f64,
    /// Largest torque step relative to its rate limit `τ̇_max,i Δt`.
    pub max_torque_rate_ratio: f64,
    /// Largest `|τ_i| / τ_max,i`.
    pub max_torque_ratio: f64,
    /// Largest controller energy (J).
    pub max_energy_j: f64,
    /// Smallest collision distance (m).
    pub min_distance_m: f64,
    /// Cycles with a non-finite state or command.
    pub nan_count: u64,
    /// Cycles with a fault (safe output).
    pub fault_count: u64,
    /// The first fault and its time (s).
    pub first_fault: Option<(f64, String)>,
    /// Goals and pushes issued.
    pub goals: u64,
    /// Pushes issued.
    pub pushes: u64,
    /// Cycles in which some output guard acted.
    pub saturated_cycles: u64,
    /// Largest `|q̇_i| / q̇_max,i` over the upper-body joints (measured velocities).
    pub max_velocity_ratio: f64,
    /// The joint (upper-body coordinate) and time (s) of [`SoakMetrics::max_velocity_ratio`].
    pub max_velocity_at: (usize, f64),
}

/// Runs the soak for [`duration_s`] (see the module docs).
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    let duration = duration_s()?;
    let (metrics, series) = run(duration, seed()?, record_from_s()?, options)?;
    evaluate(&metrics, series)
}

/// The soak of `duration` simulated seconds with disturbances (and, on the realistic plant,
/// sensor noise) from `seed`, recording every cycle from `record_from` (s) if given.
pub fn run(
    duration: f64,
    seed: u64,
    record_from: Option<f64>,
    options: &RunOptions,
) -> Result<(SoakMetrics, TimeSeries), String> {
    let mut rig = wbc::chapter_6_rig(ArmId::RIGHT, &[], options)?;
    rig.sim.set_plant_model(options.plant_model(seed))?;
    let mut rng = Rng(seed.max(1));
    let mut disturbances = Disturbances::new(&mut rng, &mut rig)?;
    let mut observer = Observer::new(&rig, duration);
    let mut columns = wbc::columns();
    columns.extend(["tau_ratio_max", "rate_ratio_max", "energy_j"].iter().map(|s| (*s).to_string()));
    let mut series = TimeSeries::new(columns);
    run_loop(&mut rig, duration, CONTROL_PERIOD_S, |rig, info| -> Result<(), String> {
        let cycle = info.cycle;
        rig.cycle(info).map_err(|e| format!("cycle {cycle}: {e}"))?;
        observer.observe(rig, info);
        let recorded = record_from.map_or(cycle % RECORD_EVERY == 0, |from| info.time_s >= from);
        if recorded {
            let mut row = rig.record(info).map_err(|e| format!("cycle {cycle}: {e}"))?;
            row.extend(observer.take_window());
            series.push(row)?;
        }
        disturbances.apply(&mut rng, rig, info.time_s, &mut observer.metrics)?;
        if cycle % 1000 == 0 {
            options.progress.report(NAME, info.time_s, duration);
        }
        Ok(())
    })?;
    options.progress.finish();
    let mut metrics = observer.metrics;
    metrics.min_distance_m = rig.min_distance_m;
    Ok((metrics, series))
}

/// The seeded goals and pushes: when the next of each is due, and the home pose they are drawn
/// around.
struct Disturbances {
    next_goal: f64,
    next_push: f64,
    home_tcp: Placement<f64>,
    home_rotation: UnitQuaternion<f64>,
}

/// The frames a push acts on.
const PUSH_FRAMES: [FrameId; 3] = [justin::RIGHT_TCP, justin::LEFT_TCP, justin::TORSO_CENTER];

impl Disturbances {
    fn new(rng: &mut Rng, rig: &mut wbc::Rig) -> Result<Self, String> {
        let home_tcp = rig.sim.frame_placement(justin::RIGHT_TCP)?;
        let home_rotation = UnitQuaternion::from_rotation_matrix(&home_tcp.rotation);
        let next_goal = rng.uniform(GOAL_INTERVAL_S);
        let next_push = rng.uniform(PUSH_INTERVAL_S);
        Ok(Self { next_goal, next_push, home_tcp, home_rotation })
    }

    /// Issues the goal and the push due at `t` (s), counting them in `m`.
    fn apply(&mut self, rng: &mut Rng, rig: &mut wbc::Rig, t: f64, m: &mut SoakMetrics) -> Result<(), String> {
        if t >= self.next_goal {
            let offset = Vector3::from(GOAL_BOX_M.map(|h| rng.uniform((-h, h))));
            let position = self.home_tcp.translation.vector + offset;
            let yaw = rng.uniform((-GOAL_YAW_RAD, GOAL_YAW_RAD));
            let q = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw) * self.home_rotation;
            let pose = Pose { position: [position.x, position.y, position.z], orientation: [q.w, q.i, q.j, q.k] };
            let duration_s = rng.uniform(GOAL_DURATION_S);
            rig.apply(&Command::TcpGoal { hand: ArmId::RIGHT, pose, duration_s })
                .map_err(|e| format!("goal at {t:.3} s: {e}"))?;
            m.goals += 1;
            self.next_goal = t + rng.uniform(GOAL_INTERVAL_S);
        }
        if t >= self.next_push {
            let frame = PUSH_FRAMES.get((rng.next() * 3.0) as usize % 3).copied().unwrap_or(justin::RIGHT_TCP);
            let direction = Vector3::new(rng.uniform((-1.0, 1.0)), rng.uniform((-1.0, 1.0)), rng.uniform((-1.0, 1.0)));
            let direction = direction.try_normalize(1e-6).unwrap_or_else(Vector3::x);
            let force = direction * rng.uniform(PUSH_FORCE_N);
            rig.sim
                .push(frame, force, t, rng.uniform(PUSH_DURATION_S))
                .map_err(|e| format!("push at {t:.3} s: {e}"))?;
            m.pushes += 1;
            self.next_push = t + rng.uniform(PUSH_INTERVAL_S);
        }
        Ok(())
    }
}

/// Accumulates the [`SoakMetrics`] cycle by cycle, and the maxima of the current recording
/// window (`tau_ratio_max`, `rate_ratio_max`, `energy_j`).
struct Observer {
    metrics: SoakMetrics,
    effort: SVector<f64, { justin::N }>,
    rate: SVector<f64, { justin::N }>,
    speed_limit: SVector<f64, { justin::N }>,
    dt: f64,
    previous: [f64; justin::UPPER_DOF],
    window: [f64; 3],
}

impl Observer {
    fn new(rig: &wbc::Rig, duration: f64) -> Self {
        let metrics = SoakMetrics {
            duration_s: duration,
            max_torque_rate: 0.0,
            max_torque_rate_ratio: 0.0,
            max_torque_ratio: 0.0,
            max_energy_j: 0.0,
            min_distance_m: f64::INFINITY,
            nan_count: 0,
            fault_count: 0,
            first_fault: None,
            goals: 0,
            pushes: 0,
            saturated_cycles: 0,
            max_velocity_ratio: 0.0,
            max_velocity_at: (0, 0.0),
        };
        Self {
            metrics,
            effort: rig.controller.model().limits.effort,
            rate: rig.controller.config().output_limits.torque_rate,
            speed_limit: rig.controller.model().limits.velocity,
            dt: rig.controller.config().period_s,
            previous: [0.0; justin::UPPER_DOF],
            window: [0.0; 3],
        }
    }

    /// The window maxima since the last call; starts a new window.
    fn take_window(&mut self) -> [f64; 3] {
        core::mem::take(&mut self.window)
    }

    /// Folds the cycle just run into the metrics and the window.
    fn observe(&mut self, rig: &wbc::Rig, info: &CycleInfo) {
        let (m, t) = (&mut self.metrics, info.time_s);
        let output = *rig.controller.output();
        let telemetry = rig.controller.telemetry();
        let finite = output
            .torque
            .iter()
            .chain(output.platform.velocity.iter())
            .chain(output.platform.leg_rates.iter())
            .all(|x| x.is_finite())
            && rig.sim.q().iter().chain(rig.sim.v().iter()).all(|x| x.is_finite());
        if !finite {
            m.nan_count += 1;
        }
        if let Some(fault) = telemetry.fault {
            m.fault_count += 1;
            if m.first_fault.is_none() {
                m.first_fault = Some((t, format!("{fault:?}")));
            }
        }
        m.saturated_cycles += u64::from(telemetry.saturation.any());
        for (i, v) in rig.sim.upper_v().iter().enumerate() {
            let limit = self.speed_limit.get(i + PLATFORM_DOF).copied().unwrap_or(f64::INFINITY);
            if v.abs() / limit > m.max_velocity_ratio {
                m.max_velocity_ratio = v.abs() / limit;
                m.max_velocity_at = (i, t);
            }
        }
        let energy = telemetry.kinetic_energy + telemetry.potential_energy;
        m.max_energy_j = m.max_energy_j.max(energy);
        self.window[2] = self.window[2].max(energy);
        let dt = self.dt;
        for (i, (tau, prev)) in output.torque.iter().zip(self.previous.iter()).enumerate() {
            let (Some(e), Some(r)) = (self.effort.get(i + PLATFORM_DOF), self.rate.get(i + PLATFORM_DOF)) else {
                continue;
            };
            let ratio = tau.abs() / e;
            m.max_torque_ratio = m.max_torque_ratio.max(ratio);
            self.window[0] = self.window[0].max(ratio);
            if info.cycle > 0 {
                let step = (tau - prev).abs();
                m.max_torque_rate = m.max_torque_rate.max(step / dt);
                m.max_torque_rate_ratio = m.max_torque_rate_ratio.max(step / (r * dt));
                self.window[1] = self.window[1].max(step / (r * dt));
            }
        }
        self.previous = output.torque;
    }
}

/// Summary, claims and figure of a soak run.
pub fn evaluate(m: &SoakMetrics, series: TimeSeries) -> Result<Outcome, String> {
    let mut summary = Summary::new(NAME);
    #[allow(clippy::cast_precision_loss, reason = "counts")]
    {
        summary
            .metric("duration_s", m.duration_s)
            .metric("max_torque_rate_nm_s", m.max_torque_rate)
            .metric("max_torque_rate_ratio", m.max_torque_rate_ratio)
            .metric("max_torque_ratio", m.max_torque_ratio)
            .metric("max_energy_j", m.max_energy_j)
            .metric("min_collision_distance_m", m.min_distance_m)
            .metric("nan_count", m.nan_count as f64)
            .metric("fault_count", m.fault_count as f64)
            .metric("fault_cycles_per_hour", m.fault_count as f64 * 3600.0 / m.duration_s)
            .metric("max_joint_speed_ratio", m.max_velocity_ratio)
            .value(
                "max_joint_speed_at",
                format!("upper-body joint {} at t = {:.3} s", m.max_velocity_at.0, m.max_velocity_at.1),
            )
            .value(
                "first_fault",
                m.first_fault.as_ref().map_or_else(|| "none".to_string(), |(t, f)| format!("{f} at t = {t:.3} s")),
            )
            .metric("goal_count", m.goals as f64)
            .metric("push_count", m.pushes as f64)
            .metric("saturated_cycles", m.saturated_cycles as f64)
            .metric("energy_bound_j", ENERGY_BOUND_J);
    }
    summary.claim("no NaN or infinite value in the state or the commands", m.nan_count == 0);
    summary.claim("no collision (every pair's distance > 0)", m.min_distance_m > 0.0);
    summary.claim(
        "torques within their effort and rate limits",
        m.max_torque_ratio <= 1.0 + 1e-9 && m.max_torque_rate_ratio <= 1.0 + 1e-6,
    );
    summary.claim(&format!("controller energy bounded (≤ {ENERGY_BOUND_J} J)"), m.max_energy_j <= ENERGY_BOUND_J);
    summary.claim("no fault (no cycle with the safe output)", m.fault_count == 0);
    summary.claim("every joint speed within its limit", m.max_velocity_ratio <= 1.0);
    let column = |name: &str| -> Result<Vec<(f64, f64)>, String> {
        let t = series.column("t").ok_or("no column t")?;
        let y = series.column(name).ok_or_else(|| format!("no column {name}"))?;
        Ok(t.into_iter().zip(y).collect())
    };
    let figure = Figure {
        title: format!("{NAME}: random goals and pushes"),
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: "guards (window maxima)".into(),
                y_label: "ratio to limit".into(),
                lines: vec![
                    Line::new("|τ|/τ_max", column("tau_ratio_max")?),
                    Line::new("|Δτ|/(τ̇_max Δt)", column("rate_ratio_max")?),
                ],
                spans: vec![],
            },
            Panel {
                title: "controller energy".into(),
                y_label: "energy (J)".into(),
                lines: vec![Line::new("kinetic + potential", column("energy_j")?)],
                spans: vec![],
            },
            Panel {
                title: "smallest collision distance".into(),
                y_label: "distance (m)".into(),
                lines: vec![Line::new("min distance", column("min_distance")?)],
                spans: vec![],
            },
        ],
    };
    Ok(Outcome { summary, series, figures: vec![("soak.svg", figure)] })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use kernel::controller::layout::JointGroup;
    use kernel::dynamics::{crba, forward_kinematics};
    use kernel::model::Data;
    use kernel::platform::storage::closed_loop_inertia_into;
    use kernel::tasks::manipulability::manipulability;
    use nalgebra::SMatrix;

    /// The right arm's singularity row where the realistic one-hour soak with seed 3 entered it
    /// (t = 634.988 s; the state as recorded: base, torso, right arm, left arm), with Justin's
    /// configuration: `m` = 0.0249 at the threshold 0.025, `ṁ = ∇m q̇` ≈ −0.17 m³/s, and the
    /// row's inverse inertia `w = ∇m M̃⁻¹ ∇mᵀ` ≈ 2.0 (mostly arm joint 3, 69 1/(kg m²)).
    /// The loop of the row's spring `2 k_msa` and damping `d` sampled at `Δt` (the module docs
    /// of `kernel::tasks::manipulability`, "Sampling"): with the former `k_msa` = 2·10⁵ its
    /// frequency was `ω Δt` = 0.90 and its torque rose on joint 3 by 1.07 × the joint's rate
    /// limit per cycle — the guard scaled level 1, then level 0, in alternate cycles, and the
    /// right arm's joints 1 and 3 swung to 2 × their limit. Now `ω Δt` ≤ ⅓, the entry ramp
    /// is below a fifth of every rate limit, and the damping gain `Δt d w` stays within half
    /// the delayed damper's bound 0.88.
    #[test]
    fn the_singularity_row_where_seed_3_entered_it_fits_the_sampled_loop() {
        let model = justin::model::<f64>().unwrap();
        let config = justin::whole_body::controller_config::<f64>().unwrap();
        let q = SVector::<f64, { justin::N }>::from_column_slice(&[
            -0.0988, 0.2432, 0.2475, 0.0507, -0.1749, 0.6338, 0.2732, 0.0886, -1.5154, 1.4494, 0.7270, -0.0069, 0.0440,
            0.4860, 0.4929, 0.4997, 1.5093, -0.4999, -0.4984, -0.2016,
        ]);
        let v = SVector::<f64, { justin::N }>::from_column_slice(&[
            -0.026, 0.123, 0.105, 0.264, 0.140, 0.192, -1.190, -1.084, -0.027, 1.144, 0.119, -0.049, -2.450, 0.025,
            -0.012, 0.019, 0.060, -0.004, 0.006, -0.012,
        ]);
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &q, &v).unwrap();
        let mass = *crba(&model, &mut data);
        let mut closed_loop = SMatrix::zeros();
        closed_loop_inertia_into(&mass, &config.layout.platform, &config.platform.admittance.mass, &mut closed_loop);
        let s = &config.singularity;
        let arm = config.layout.coordinates(JointGroup::Arm(ArmId::RIGHT));
        let measure = manipulability(&model, &data, justin::RIGHT_TCP, s.rows, &arm).unwrap();
        assert!((measure.value - s.threshold).abs() < 2e-4, "entering the band: m = {}", measure.value);
        let gradient = measure.gradient.transpose();
        let rate = gradient.dot(&v);
        assert!((rate + 0.17).abs() < 0.03, "ṁ = {rate}");
        let w = (measure.gradient * closed_loop.try_inverse().unwrap() * gradient).x;
        assert!((w - 2.0).abs() < 0.2, "w = {w}");
        let dt = config.period_s;
        let frequency = dt * (2.0 * s.stiffness * w).sqrt();
        assert!(frequency <= 1.0 / 3.0, "ω Δt = {frequency}");
        let limits = &config.output_limits.torque_rate;
        let ramp = gradient.iter().zip(limits.iter()).map(|(g, r)| 2.0 * s.stiffness * rate.abs() * g.abs() / r);
        let ramp = ramp.skip(PLATFORM_DOF).fold(0.0, f64::max);
        assert!(ramp <= 0.2, "entry ramp {ramp} × the rate limit");
        let damping = dt * s.damping * w;
        assert!(damping <= 0.44, "Δt d w = {damping}");
    }

    #[test]
    fn a_short_soak_holds_its_claims() {
        let (metrics, series) = run(4.0, SEED, None, &RunOptions::default()).unwrap();
        let outcome = evaluate(&metrics, series).unwrap();
        assert!(outcome.summary.failed_claims().is_empty(), "{:?} {metrics:?}", outcome.summary.failed_claims());
        assert!(metrics.goals >= 1 && metrics.pushes >= 1, "{metrics:?}");
        assert_eq!(metrics.fault_count, 0, "{metrics:?}");
    }
}
