//! `mobile_impedance`: whole-body impedance of the Justin-like robot with an admittance-driven
//! platform, with and without the coupling compensation (Sec. 5.1.4, Fig. 5.5 and 5.6).
//!
//! Setup (Sec. 5.1.4, Table 5.2): the chain "platform – torso – right arm", the platform
//! allowed to move forward/backward only (footnote 2: `y` and `θ` locked), the Cartesian
//! impedance of the right TCP with `K_tra = diag(1000, 1000, 1000)` N/m,
//! `K_rot = diag(100, 100, 100)` Nm/rad and double-diagonalisation damping for `ξ = 0.7`, the
//! admittance `M_adm = diag(7.5 kg, 7.5 kg, 2.5 kg m²)`, `D_adm = diag(24, 24, 8)`
//! ([`crate::mobile_controller::MobileImpedance`]). The desired TCP moves 0.3 m forward, rests,
//! and moves back ("a continuous forward-rest-backward trajectory of length 0.3 m"): quintic
//! ramps over [`FORWARD_S`] and [`BACKWARD_S`], [`DURATION_S`] in total like Fig. 5.5.
//!
//! Choices the thesis leaves open (all **invented**, documented here):
//! - the platform's velocity loop is a first-order lag of [`BASE_LAG_S`] = 50 ms: "the
//!   kinematic velocity controller of the mobile base is not ideal. The introduced phase delay
//!   …", and Sec. 5.1.5: "the velocity control \[GFASH09\] of the platform does not perform as
//!   desired due to phase delays and amplitude errors". (With an ideal velocity source the
//!   simulator changes the base velocity in steps that the upper body does not feel, so the
//!   inertial coupling `M_qr r̈` would vanish from the plant: a lag is needed in any case.)
//!   The lag matters for the critical experiment: the linearised closed loop of this
//!   Justin-like model without compensation is stable for the critical admittance up to a
//!   lag of about 38 ms and unstable beyond (see the `thesis-tests` module `platform`);
//! - the torso and the right arm get only a friction-level joint damping
//!   [`NULL_SPACE_DAMPING_NMS_RAD`] in the null space of the TCP task (the thesis: "Redundant
//!   Robot with Null Space Damping", so that `D_qq` is positive definite); the left arm, not in
//!   the chain, is held by a joint impedance ([`HOLD_STIFFNESS_NM_RAD`], damping ratio
//!   [`HOLD_DAMPING_RATIO`] on the diagonal of `M` at the home pose). (A stronger null space
//!   damping — e.g. a posture impedance on the torso — damps the coupling mode too, and then
//!   the critical set is stable without compensation as well);
//! - gravity is compensated in both cases (the thesis' `g_q` is part of `τ_comp`; "compensation
//!   OFF" here drops the couplings `M_qr r̈ + C_qr ṙ` only);
//! - the admittance's force limit is the model's effort limit of the base axes (1000 N,
//!   500 Nm), i.e. `K_i F_max` = 41.7 m/s: no velocity limit acts in these experiments.
//!
//! Claims (Fig. 5.5/5.6): both runs track the trajectory (stable); with compensation the total
//! energy (5.21) decays after each motion segment, without it the energy and the TCP oscillate
//! longer (energy settling time ON < OFF, more energy oscillations OFF); the storage rate
//! predicted by (5.22) matches the measured one with compensation; no NaN. On the realistic
//! plant the storage change is compared over [`RATE_WINDOW_S`] instead of one cycle, with the
//! joint friction's work as the known extra term ([`rate_mismatch`], README `--plant`).

use fixtures::justin::{self, JustinModel, BODIES, FRAMES, JOINT_NAMES, N, RIGHT_TCP, UPPER_DOF};
use kernel::model::Placement;
use kernel::platform::admittance::AdmittanceConfig;
use kernel::platform::coupling_compensation::CompensationSwitch;
use kernel::platform::{PlatformAxis, PlatformLayout};
use nalgebra::{Matrix3, SVector, Translation3, Vector3};

use super::{joint_columns, pose_error_columns, Outcome, RunOptions};
use crate::mobile_controller::{MobileImpedance, MobileImpedanceSettings};
use crate::output::{Figure, Line, Panel, Span, Summary, TimeSeries};
use crate::plant::PlantKind;
use crate::replay::Robot;
use crate::sim::{run_loop, SimConfig, SimError, Simulator, CONTROL_PERIOD_S, DEFAULT_PHYSICS_STEP_S};

/// Registry name.
pub const NAME: &str = "mobile_impedance";
/// One-line description.
pub const DESCRIPTION: &str =
    "Justin-like robot, mobile impedance (Table 5.2): 0.3 m forward-rest-backward TCP trajectory, compensation ON vs OFF (Fig. 5.5/5.6)";

/// The replay's robot (also of `mobile_impedance_critical`): Justin with the run's platform
/// position along x and the right TCP's error in `e1.*` (the compensated run).
pub const REPLAY: Robot = Robot::right_hand_at_level_1(&[("q.base_x", "base.x")]);
/// Simulated time (s), as in Fig. 5.5.
pub const DURATION_S: f64 = 12.0;
/// Forward ramp of the desired TCP (s).
pub const FORWARD_S: (f64, f64) = (0.5, 2.5);
/// Backward ramp (s).
pub const BACKWARD_S: (f64, f64) = (6.5, 8.5);
/// Length of the trajectory (m), Sec. 5.1.4.
pub const TRAJECTORY_M: f64 = 0.3;
/// Time constant of the platform's velocity loop (s). Invented (see the module docs).
pub const BASE_LAG_S: f64 = 0.05;
/// Null space damping of the torso and the right arm (Nms/rad), per joint. Invented: joint
/// friction level; it makes `D_qq` positive definite (Sec. 5.1.3, "Redundant Robot with Null
/// Space Damping").
pub const NULL_SPACE_DAMPING_NMS_RAD: f64 = 0.2;
/// Joint stiffness holding the left arm (Nm/rad). Invented.
pub const HOLD_STIFFNESS_NM_RAD: f64 = 50.0;
/// Damping ratio of the left arm's joint springs on the diagonal inertia at home. Invented.
pub const HOLD_DAMPING_RATIO: f64 = 0.7;
/// Window of the storage-rate comparison on the realistic plant (s); see [`rate_window_cycles`]
/// and README `--plant`.
pub const RATE_WINDOW_S: f64 = 0.05;
/// Tolerance of the passivity monitor (J). Invented: above the energy a short push injects.
pub const PASSIVITY_TOLERANCE_J: f64 = 2.0;
/// Total energy below which a transient counts as settled (J). Invented: about 2 % of the
/// peak energy of a ramp with compensation.
pub const SETTLED_ENERGY_J: f64 = 0.005;
/// Kinetic-energy maxima count as oscillations above this share of the run's peak kinetic
/// energy.
pub const OSCILLATION_SHARE: f64 = 0.01;

/// Table 5.2: `M_adm = diag(7.5 kg, 7.5 kg, 2.5 kg m²)`, `D_adm = diag(24, 24, 8)`.
pub fn table_5_2_admittance() -> AdmittanceConfig<f64> {
    admittance(Vector3::new(7.5, 7.5, 2.5), Vector3::new(24.0, 24.0, 8.0))
}

/// The critical set of Sec. 5.1.4: `M_adm = diag(3, 3, 1)`, `D_adm = diag(21, 21, 7)`.
pub fn critical_admittance() -> AdmittanceConfig<f64> {
    admittance(Vector3::new(3.0, 3.0, 1.0), Vector3::new(21.0, 21.0, 7.0))
}

fn admittance(mass: Vector3<f64>, damping: Vector3<f64>) -> AdmittanceConfig<f64> {
    let limits = justin::model::<f64>().map(|m| m.limits.effort.fixed_rows::<3>(0).into_owned());
    AdmittanceConfig {
        mass,
        damping,
        force_limit: limits.unwrap_or(Vector3::new(1000.0, 1000.0, 500.0)),
        free_axes: [true, false, false],
    }
}

/// What the desired TCP does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Disturbance {
    /// The forward-rest-backward trajectory (Fig. 5.5).
    Trajectory,
    /// The TCP is held; a world-frame force `force_n` pushes it during `[start_s, start_s + duration_s)`.
    Push {
        /// Force (N), world frame.
        force_n: Vector3<f64>,
        /// Start (s).
        start_s: f64,
        /// Duration (s).
        duration_s: f64,
    },
}

/// One simulated experiment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Experiment {
    /// The admittance.
    pub admittance: AdmittanceConfig<f64>,
    /// Compensation ON or OFF.
    pub compensation: CompensationSwitch,
    /// Trajectory or push.
    pub disturbance: Disturbance,
    /// Simulated time (s).
    pub duration_s: f64,
    /// Physics step (s).
    pub physics_step_s: f64,
    /// Stop the run ("emergency stop") once the storage exceeds this (J).
    pub stop_energy_j: f64,
}

/// One control cycle of a run.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    /// Time (s).
    pub t: f64,
    /// Upper-body `q`, `q̇`, `τ`.
    pub q: SVector<f64, UPPER_DOF>,
    /// Upper-body velocities.
    pub dq: SVector<f64, UPPER_DOF>,
    /// Applied torque.
    pub tau: SVector<f64, UPPER_DOF>,
    /// TCP error (m, rad-like).
    pub error: [f64; 6],
    /// Storage (5.21): kinetic, potential, total (J).
    pub storage: [f64; 3],
    /// `V_imp` of the TCP spring (J).
    pub impedance_potential: f64,
    /// Predicted (5.22) and measured storage rate (W).
    pub rates: [f64; 2],
    /// Passivity growth (J) and latch.
    pub growth: f64,
    /// Monitor latched.
    pub latched: bool,
    /// Platform `x` (m), measured velocity and commanded velocity (m/s).
    pub base: [f64; 3],
    /// `τ_r,vir,x` (N) and `r̈_x` (m/s²) of the admittance.
    pub admittance: [f64; 2],
    /// TCP `x` and desired `x` (m, world).
    pub tcp_x: [f64; 2],
    /// Largest `|τ_i|/τ_max,i` before clamping.
    pub torque_ratio: f64,
    /// Coupling torque `M_qr r̈ + C_qr ṙ` at torso joint 2 (Nm).
    pub coupling_torso2: f64,
    /// Power of the realistic plant's joint friction `q̇ᵀ τ_f` (W, ≤ 0; zero on the ideal plant).
    pub friction_power_w: f64,
}

/// The record of one experiment.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    /// Every control cycle until the end or the emergency stop.
    pub samples: Vec<Sample>,
    /// Time of the emergency stop (s), if the storage exceeded the stop energy.
    pub stopped_at_s: Option<f64>,
    /// Physics steps run with a clamped torque.
    pub saturated_steps: u64,
    /// The plant it ran on.
    pub plant: PlantKind,
}

/// Quintic smoothstep `s(τ) = 10τ³ − 15τ⁴ + 6τ⁵` on `[a, b]` and its time derivative.
pub fn smoothstep(t: f64, (a, b): (f64, f64)) -> (f64, f64) {
    let width = b - a;
    let tau = ((t - a) / width).clamp(0.0, 1.0);
    let s = tau * tau * tau * (10.0 - 15.0 * tau + 6.0 * tau * tau);
    let ds = 30.0 * tau * tau * (1.0 - tau) * (1.0 - tau) / width;
    (s, ds)
}

/// Offset of the desired TCP along world x (m) and its rate (m/s) at `t`.
pub fn trajectory(t: f64) -> (f64, f64) {
    let (f, df) = smoothstep(t, FORWARD_S);
    let (b, db) = smoothstep(t, BACKWARD_S);
    (TRAJECTORY_M * (f - b), TRAJECTORY_M * (df - db))
}

type Sim = Simulator<N, BODIES, FRAMES, UPPER_DOF>;
type Controller = MobileImpedance<N, BODIES, FRAMES, UPPER_DOF>;

/// The settings of the experiments (Table 5.2 gains and the invented posture terms).
pub fn settings(
    admittance: AdmittanceConfig<f64>,
    compensation: CompensationSwitch,
) -> Result<MobileImpedanceSettings<UPPER_DOF>, String> {
    let layout =
        PlatformLayout::try_new::<N>([PlatformAxis::Admitted(0), PlatformAxis::Locked(1), PlatformAxis::Locked(2)])
            .map_err(|e| e.to_string())?;
    let home = justin::home_configuration::<f64>();
    let base = N - UPPER_DOF;
    let left = |k: usize| justin::LEFT_ARM_COORDINATES.contains(&(k + base));
    let model = justin::model::<f64>().map_err(|e| e.to_string())?;
    let mut data = kernel::Data::new(&model);
    kernel::dynamics::forward_kinematics(&model, &mut data, &home, &SVector::zeros()).map_err(|e| e.to_string())?;
    let inertia = kernel::dynamics::crba(&model, &mut data).diagonal().fixed_rows::<UPPER_DOF>(base).into_owned();
    let stiffness = SVector::<f64, UPPER_DOF>::from_fn(|k, _| if left(k) { HOLD_STIFFNESS_NM_RAD } else { 0.0 });
    let damping = SVector::<f64, UPPER_DOF>::from_fn(|k, _| {
        let hold = 2.0 * HOLD_DAMPING_RATIO * (HOLD_STIFFNESS_NM_RAD * inertia.get(k).copied().unwrap_or(0.0)).sqrt();
        if left(k) {
            hold
        } else {
            NULL_SPACE_DAMPING_NMS_RAD
        }
    });
    Ok(MobileImpedanceSettings {
        tcp: RIGHT_TCP,
        layout,
        admittance,
        translational_stiffness: Matrix3::identity() * 1000.0,
        rotational_stiffness: Matrix3::identity() * 100.0,
        damping_ratio: 0.7,
        posture: home.fixed_rows::<UPPER_DOF>(base).into_owned(),
        posture_stiffness: stiffness,
        posture_damping: damping,
        compensation,
        passivity_tolerance_j: PASSIVITY_TOLERANCE_J,
    })
}

/// Runs one experiment from rest at the home pose.
pub fn run(experiment: &Experiment, options: &RunOptions, label: &str) -> Result<Run, String> {
    let model: JustinModel<f64> = justin::model::<f64>().map_err(|e| format!("Justin model: {e}"))?;
    let home = justin::home_configuration::<f64>();
    let config =
        SimConfig { physics_step_s: experiment.physics_step_s, base_lag_s: BASE_LAG_S, ..SimConfig::default() };
    let mut sim: Sim = options.simulator(model.clone(), config)?;
    sim.set_state(home, SVector::zeros()).map_err(|e| e.to_string())?;
    if let Disturbance::Push { force_n, start_s, duration_s } = experiment.disturbance {
        sim.push(RIGHT_TCP, force_n, start_s, duration_s).map_err(|e| e.to_string())?;
    }
    let start = sim.frame_placement(RIGHT_TCP).map_err(|e| e.to_string())?;
    let mut controller =
        Controller::new(model, settings(experiment.admittance, experiment.compensation)?, start, CONTROL_PERIOD_S)
            .map_err(|e| e.to_string())?;
    let mut samples = Vec::new();
    let plant = options.plant;
    let report = run_loop(&mut sim, experiment.duration_s, CONTROL_PERIOD_S, |sim, info| -> Result<(), Stop> {
        if info.cycle % 200 == 0 {
            options.progress.report(label, info.time_s, experiment.duration_s);
        }
        let (offset, rate) = match experiment.disturbance {
            Disturbance::Trajectory => trajectory(info.time_s),
            Disturbance::Push { .. } => (0.0, 0.0),
        };
        let desired = Placement::from_parts(
            Translation3::from(start.translation.vector + Vector3::new(offset, 0.0, 0.0)),
            start.rotation,
        );
        controller.set_target(desired, Vector3::new(rate, 0.0, 0.0));
        let t = *controller.step(sim)?;
        if t.fault.is_some() {
            return Err(Stop::Failed(format!("{label}: controller fault {:?} at t = {:.3} s", t.fault, info.time_s)));
        }
        let tcp = sim.frame_placement(RIGHT_TCP)?.translation.vector;
        let torso2 = justin::TORSO_COORDINATES.start + 1 - (N - UPPER_DOF);
        samples.push(Sample {
            t: info.time_s,
            q: sim.upper_q(),
            dq: sim.upper_v(),
            tau: *sim.applied_torque(),
            error: t.error.into(),
            storage: [t.storage.kinetic, t.storage.potential, t.storage.total],
            impedance_potential: t.impedance_potential,
            rates: [t.predicted_rate_w, t.passivity.rate],
            growth: t.passivity.growth,
            latched: t.passivity.latched,
            base: [
                sim.q().get(0).copied().unwrap_or(f64::NAN),
                sim.v().get(0).copied().unwrap_or(f64::NAN),
                t.base_velocity.x,
            ],
            admittance: [t.virtual_force.x, t.base_acceleration.x],
            tcp_x: [tcp.x, desired.translation.vector.x],
            torque_ratio: t.torque_ratio,
            coupling_torso2: t.coupling.get(torso2).copied().unwrap_or(f64::NAN),
            friction_power_w: sim.upper_v().dot(&sim.friction_torque()),
        });
        if t.storage.total.is_nan() || t.storage.total > experiment.stop_energy_j {
            return Err(Stop::Emergency { t_s: info.time_s });
        }
        Ok(())
    });
    match report {
        Ok(report) => Ok(Run { samples, stopped_at_s: None, saturated_steps: report.saturated_steps, plant }),
        Err(Stop::Emergency { t_s }) => Ok(Run { samples, stopped_at_s: Some(t_s), saturated_steps: 0, plant }),
        // A diverging state (the physics refuses it) also counts as a stop.
        Err(Stop::Diverged(_)) if !samples.is_empty() => {
            let stopped_at_s = samples.last().map(|s| s.t);
            Ok(Run { samples, stopped_at_s, saturated_steps: 0, plant })
        }
        Err(Stop::Diverged(e)) => Err(e.to_string()),
        Err(Stop::Failed(message)) => Err(message),
    }
}

/// Why an experiment's loop ended before its duration.
enum Stop {
    /// The emergency stop: the storage exceeded the experiment's bound (or is NaN) at `t_s`.
    Emergency {
        /// Simulated time of the stop (s).
        t_s: f64,
    },
    /// The physics refused the state: it diverged.
    Diverged(SimError),
    /// Any other error.
    Failed(String),
}

impl From<SimError> for Stop {
    fn from(e: SimError) -> Self {
        match e {
            SimError::Dynamics(_) => Self::Diverged(e),
            other => Self::Failed(other.to_string()),
        }
    }
}

/// Energy the realistic plant's joint friction dissipated over `run` (J, `−∫ q̇ᵀ τ_f dt` at the
/// control samples; zero on the ideal plant).
pub fn friction_dissipated_j(run: &Run) -> f64 {
    0.0 - run.samples.iter().map(|s| s.friction_power_w).sum::<f64>() * CONTROL_PERIOD_S
}

/// Metrics of one run of the trajectory experiment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrajectoryMetrics {
    /// Time after the end of each ramp until the total energy stays below
    /// [`SETTLED_ENERGY_J`] (s); `∞` if never.
    pub energy_settle_s: [f64; 2],
    /// Number of local maxima of the kinetic energy above [`OSCILLATION_SHARE`] of its peak
    /// after the ramps.
    pub energy_oscillations: usize,
    /// Peak total energy (J).
    pub peak_energy_j: f64,
    /// Largest TCP error in x (m).
    pub max_error_x_m: f64,
    /// TCP error in x at the end (m).
    pub final_error_m: f64,
    /// Largest platform excursion (m).
    pub max_base_x_m: f64,
    /// Largest |predicted − measured| storage rate relative to the largest |predicted| (–).
    pub rate_mismatch: f64,
    /// Largest torque ratio.
    pub torque_ratio: f64,
    /// Every value finite.
    pub finite: bool,
}

/// Control cycles over which the measured storage change is compared with (5.22): one on the
/// ideal plant (the storage's one-cycle difference, exact there), [`RATE_WINDOW_S`] on the
/// realistic plant.
pub fn rate_window_cycles(plant: PlantKind) -> usize {
    match plant {
        PlantKind::Ideal => 1,
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss, reason = "a few hundred cycles")]
        PlantKind::Realistic => (RATE_WINDOW_S / CONTROL_PERIOD_S).round() as usize,
    }
}

/// Largest mismatch between the measured storage change over `window` control cycles and the
/// change (5.22) predicts plus the joint friction's work, `|ΔS − ∫ (Ṡ_(5.22) + q̇ᵀ τ_f) dt|`
/// over every window, as a mean rate relative to the largest predicted rate (–). With
/// `window = 1` and no friction it is the largest one-cycle rate difference.
pub fn rate_mismatch(samples: &[Sample], window: usize) -> f64 {
    let scale = samples.iter().map(|x| x.rates[0].abs()).fold(0.0, f64::max);
    let residual: Vec<f64> = samples.iter().skip(1).map(|x| x.rates[1] - x.rates[0] - x.friction_power_w).collect();
    let width = window.max(1);
    #[allow(clippy::cast_precision_loss, reason = "a few hundred cycles")]
    let mean = |w: &[f64]| w.iter().sum::<f64>().abs() / width as f64;
    residual.windows(width).map(mean).fold(0.0, f64::max) / scale.max(1e-9)
}

/// Metrics of a trajectory run.
pub fn trajectory_metrics(run: &Run) -> TrajectoryMetrics {
    let s = &run.samples;
    let ends = [FORWARD_S.1, BACKWARD_S.1];
    let windows = [(FORWARD_S.1, BACKWARD_S.0), (BACKWARD_S.1, f64::INFINITY)];
    let mut energy_settle_s = [f64::INFINITY; 2];
    let mut energy_oscillations = 0;
    let peak_kinetic = s.iter().map(|x| x.storage[0]).fold(0.0, f64::max);
    for ((settle, end), (from, to)) in energy_settle_s.iter_mut().zip(ends).zip(windows) {
        let window: Vec<&Sample> = s.iter().filter(|x| x.t >= from && x.t < to).collect();
        let last_above = window.iter().rev().find(|x| x.storage[2] >= SETTLED_ENERGY_J).map(|x| x.t);
        *settle = match (last_above, window.last()) {
            (None, Some(_)) => 0.0,
            (Some(t), Some(last)) if t < last.t => t - end,
            _ => f64::INFINITY,
        };
        energy_oscillations += window
            .windows(3)
            .filter(|w| match w {
                [a, b, c] => {
                    b.storage[0] > a.storage[0]
                        && b.storage[0] >= c.storage[0]
                        && b.storage[0] > OSCILLATION_SHARE * peak_kinetic
                }
                _ => false,
            })
            .count();
    }
    let rate_mismatch = rate_mismatch(s, rate_window_cycles(run.plant));
    let finite = s.iter().all(|x| {
        x.q.iter()
            .chain(x.dq.iter())
            .chain(x.tau.iter())
            .chain(x.error.iter())
            .chain(x.storage.iter())
            .all(|v| v.is_finite())
    });
    TrajectoryMetrics {
        energy_settle_s,
        energy_oscillations,
        peak_energy_j: s.iter().map(|x| x.storage[2]).fold(0.0, f64::max),
        max_error_x_m: s.iter().map(|x| x.error[0].abs()).fold(0.0, f64::max),
        final_error_m: s.last().map_or(f64::NAN, |x| x.error[..3].iter().map(|e| e * e).sum::<f64>().sqrt()),
        max_base_x_m: s.iter().map(|x| x.base[0].abs()).fold(0.0, f64::max),
        rate_mismatch,
        torque_ratio: s.iter().map(|x| x.torque_ratio).fold(0.0, f64::max),
        finite,
    }
}

/// The two trajectory runs with compensation ON and OFF.
pub fn trajectory_experiments(duration_s: f64, physics_step_s: f64) -> [Experiment; 2] {
    [CompensationSwitch::ON, CompensationSwitch::OFF].map(|compensation| Experiment {
        admittance: table_5_2_admittance(),
        compensation,
        disturbance: Disturbance::Trajectory,
        duration_s,
        physics_step_s,
        stop_energy_j: 1e3,
    })
}

/// Runs the scenario.
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    let [on, off] = trajectory_experiments(DURATION_S, DEFAULT_PHYSICS_STEP_S);
    let on = run(&on, options, "mobile_impedance (compensation ON)")?;
    options.progress.finish();
    let off = run(&off, options, "mobile_impedance (compensation OFF)")?;
    options.progress.finish();
    evaluate(&on, &off)
}

/// Claims, metrics and figures of the two trajectory runs.
pub fn evaluate(on: &Run, off: &Run) -> Result<Outcome, String> {
    let (m_on, m_off) = (trajectory_metrics(on), trajectory_metrics(off));
    let mut summary = Summary::new(NAME);
    for (tag, m, r) in [("on", &m_on, on), ("off", &m_off, off)] {
        summary
            .metric(&format!("{tag}_energy_settle_forward_s"), m.energy_settle_s[0])
            .metric(&format!("{tag}_energy_settle_backward_s"), m.energy_settle_s[1])
            .value(&format!("{tag}_energy_oscillations"), m.energy_oscillations)
            .metric(&format!("{tag}_peak_energy_j"), m.peak_energy_j)
            .metric(&format!("{tag}_max_error_x_m"), m.max_error_x_m)
            .metric(&format!("{tag}_final_error_m"), m.final_error_m)
            .metric(&format!("{tag}_max_base_x_m"), m.max_base_x_m)
            .metric(&format!("{tag}_rate_mismatch"), m.rate_mismatch)
            .metric(&format!("{tag}_friction_dissipated_j"), friction_dissipated_j(r))
            .metric(&format!("{tag}_max_tau_ratio"), m.torque_ratio)
            .value(&format!("{tag}_saturated_physics_steps"), r.saturated_steps)
            .value(&format!("{tag}_passivity_latched"), r.samples.iter().any(|s| s.latched));
    }
    let settle_sum = |m: &TrajectoryMetrics| m.energy_settle_s[0] + m.energy_settle_s[1];
    summary.claim(
        &format!(
            "both runs stay stable and track: final TCP error ON {:.1} mm, OFF {:.1} mm < 10 mm, no emergency stop",
            m_on.final_error_m * 1e3,
            m_off.final_error_m * 1e3
        ),
        m_on.final_error_m < 0.01
            && m_off.final_error_m < 0.01
            && on.stopped_at_s.is_none()
            && off.stopped_at_s.is_none(),
    );
    summary.claim(
        &format!(
            "with compensation the total energy (5.21) decays faster: settles {:.2} + {:.2} s (ON) vs {:.2} + {:.2} s (OFF) after the ramps",
            m_on.energy_settle_s[0], m_on.energy_settle_s[1], m_off.energy_settle_s[0], m_off.energy_settle_s[1]
        ),
        settle_sum(&m_on) < settle_sum(&m_off),
    );
    summary.claim(
        &format!(
            "without compensation the energy oscillates longer: {} kinetic-energy maxima (OFF) vs {} (ON)",
            m_off.energy_oscillations, m_on.energy_oscillations
        ),
        m_off.energy_oscillations > m_on.energy_oscillations,
    );
    summary.claim(
        &format!(
            "the storage rate follows (5.22) far better with compensation: largest mismatch {:.0} % (ON) vs {:.0} % (OFF) of the largest predicted rate",
            m_on.rate_mismatch * 100.0,
            m_off.rate_mismatch * 100.0
        ),
        m_on.rate_mismatch < 0.25 * m_off.rate_mismatch,
    );
    summary.claim("no NaN or infinite value", m_on.finite && m_off.finite);
    Ok(Outcome { summary, series: series(on, off)?, figures: figures(on, off) })
}

/// The time series: the standard columns of the compensated run, then scenario signals of both.
pub fn series(on: &Run, off: &Run) -> Result<TimeSeries, String> {
    let names: Vec<&str> = JOINT_NAMES.iter().copied().skip(N - UPPER_DOF).collect();
    let mut columns = vec!["t".to_owned()];
    columns.extend(joint_columns(&names));
    columns.extend(pose_error_columns(1));
    columns.push("S1".into());
    let signals = [
        "kinetic",
        "potential",
        "v_imp",
        "rate_predicted",
        "rate_measured",
        "passivity_growth",
        "base.x",
        "base.vx",
        "base.vx_cmd",
        "tau_vir.x",
        "base.ax_adm",
        "tcp.x",
        "x_des.x",
        "tau_ratio_max",
        "coupling.torso_joint2",
    ];
    columns.extend(signals.iter().map(|s| (*s).to_owned()));
    columns.extend(["e1.x", "S1", "kinetic", "base.x", "tau.torso_joint2"].iter().map(|s| format!("off.{s}")));
    let mut series = TimeSeries::new(columns);
    let torso2 = justin::TORSO_COORDINATES.start + 1 - (N - UPPER_DOF);
    for (k, s) in on.samples.iter().enumerate() {
        let mut row = vec![s.t];
        row.extend(s.q.iter().chain(s.dq.iter()).chain(s.tau.iter()));
        row.extend(s.error);
        row.push(s.storage[2]);
        row.extend([s.storage[0], s.storage[1], s.impedance_potential, s.rates[0], s.rates[1], s.growth]);
        row.extend(s.base);
        row.extend(s.admittance);
        row.extend(s.tcp_x);
        row.extend([s.torque_ratio, s.coupling_torso2]);
        match off.samples.get(k) {
            Some(o) => row.extend([
                o.error[0],
                o.storage[2],
                o.storage[0],
                o.base[0],
                o.tau.get(torso2).copied().unwrap_or(f64::NAN),
            ]),
            None => row.extend([f64::NAN; 5]),
        }
        series.push(row)?;
    }
    Ok(series)
}

fn figures(on: &Run, off: &Run) -> Vec<(&'static str, Figure)> {
    let line = |label: &str, run: &Run, f: &dyn Fn(&Sample) -> f64| {
        Line::new(label, run.samples.iter().map(|s| (s.t, f(s))).collect())
    };
    let ramps = || {
        vec![
            Span { label: "forward ramp".into(), from: FORWARD_S.0, to: FORWARD_S.1 },
            Span { label: "backward ramp".into(), from: BACKWARD_S.0, to: BACKWARD_S.1 },
        ]
    };
    let x0 = on.samples.first().map_or(0.0, |s| s.tcp_x[1]);
    let tcp = Figure {
        title: "mobile_impedance: TCP x (forward), Table 5.2 (cf. Fig. 5.5)".into(),
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: "TCP x-coordinate relative to the start".into(),
                y_label: "x (m)".into(),
                lines: vec![
                    line("compensation ON", on, &|s| s.tcp_x[0] - x0),
                    line("compensation OFF", off, &|s| s.tcp_x[0] - x0),
                    Line::dashed("reference", on.samples.iter().map(|s| (s.t, s.tcp_x[1] - x0)).collect()),
                ],
                spans: ramps(),
            },
            Panel {
                title: "platform x".into(),
                y_label: "x (m)".into(),
                lines: vec![line("compensation ON", on, &|s| s.base[0]), line("compensation OFF", off, &|s| s.base[0])],
                spans: ramps(),
            },
        ],
    };
    let energy = Figure {
        title: "mobile_impedance: storage function (5.21) (cf. Fig. 5.6)".into(),
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: "kinetic energy ½ ẏᵀMẏ (admittance inertia)".into(),
                y_label: "energy (J)".into(),
                lines: vec![
                    line("compensation ON", on, &|s| s.storage[0]),
                    line("compensation OFF", off, &|s| s.storage[0]),
                ],
                spans: ramps(),
            },
            Panel {
                title: "potential energy V_imp + posture".into(),
                y_label: "energy (J)".into(),
                lines: vec![
                    line("compensation ON", on, &|s| s.storage[1]),
                    line("compensation OFF", off, &|s| s.storage[1]),
                ],
                spans: ramps(),
            },
            Panel {
                title: "total energy".into(),
                y_label: "energy (J)".into(),
                lines: vec![
                    line("compensation ON", on, &|s| s.storage[2]),
                    line("compensation OFF", off, &|s| s.storage[2]),
                ],
                spans: ramps(),
            },
        ],
    };
    let torso2 = justin::TORSO_COORDINATES.start + 1 - (N - UPPER_DOF);
    let joint = Figure {
        title: "mobile_impedance: second torso joint (cf. Fig. 5.7)".into(),
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: "torque".into(),
                y_label: "torque (Nm)".into(),
                lines: vec![
                    line("compensation ON", on, &|s| s.tau.get(torso2).copied().unwrap_or(f64::NAN)),
                    line("compensation OFF", off, &|s| s.tau.get(torso2).copied().unwrap_or(f64::NAN)),
                ],
                spans: ramps(),
            },
            Panel {
                title: "coupling torque M_qr r̈ + C_qr ṙ (applied only with compensation ON)".into(),
                y_label: "torque (Nm)".into(),
                lines: vec![line("compensation ON", on, &|s| s.coupling_torso2)],
                spans: ramps(),
            },
        ],
    };
    vec![("tcp_x.svg", tcp), ("energy.svg", energy), ("torso_joint2.svg", joint)]
}
