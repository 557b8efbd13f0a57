//! `icr_avoidance`: singularity avoidance for the steerable wheels of the platform, with and
//! without leg motion (Sec. 3.2.6, Fig. 3.11–3.13).
//!
//! The nominal platform trajectory (in `x`, `y`, `θ`) is a chain of **quintic Bézier
//! segments** (C² at the knots, [`BezierSpline`]) through knots every [`KNOT_STEP_S`] of a
//! designed motion: a pure rotation at 2.1 rad/s ("the platform achieves a rotational speed of
//! 2.1 rad/s, which requires the maximum spinning rates of the wheels (13.9 rad/s)"), then turns
//! at 0.7 rad/s whose ICR, in the platform frame, passes near three wheels ([`design`]):
//! radially past wheel 3 around `t = 9 s`, tangentially past wheel 2 around `t = 15 s` and past
//! wheel 1 around `t = 18 s` (the thesis' "critical moments" at 9, 15 and 18 s). Each pass
//! misses the steering axis by about 3 cm, the near miss that makes the steering rate peak.
//!
//! Three runs through the simulator's `hal::PlatformVelocityInterface` (kinematic base,
//! [`crate::sim::Simulator`]), each with the loop of Fig. 3.10
//! ([`kernel::platform::avoidance::PlatformAvoidance`]), commanding `ṙ_des` and leg rates:
//! 1. ICR control OFF: a plain trajectory tracker;
//! 2. ICR control ON, legs fixed ("Initially, the leg lengths are kept constant");
//! 3. ICR control ON with leg motion (Fig. 3.13).
//!
//! The wheels ([`crate::wheels`]) turn the platform motion into steering angles, steering rates
//! and spinning rates; the steering drives are rate limited
//! ([`crate::wheels::STEERING_RATE_LIMIT_RAD_S`]), so a steering-rate peak shows up as
//! misalignment. The legs of Rollin' Justin are passive prismatic joints moved by steering and
//! driving the wheels, so a leg motion near the ICR needs steering too; the leg run reports it.
//!
//! # Why leg motion first made things worse, and the steering limit
//! With the leg admittance (3.37)–(3.40) and the return loop alone, the leg-motion run was
//! worse than the legs-fixed run over the whole trajectory: peak steering rate 17.1 vs
//! 5.8 rad/s, misalignment 1.00 vs 0 rad, position error 7.6 vs 4.9 cm (bound 7 cm), 6.8° vs
//! 2.9°. The peaks came from the legs, not from the ICR (which stayed 5.2 cm from the axes, as
//! with the legs fixed):
//! - wheel 3, `t = 8.95–9.05 s`: leg 3 starts extending (to 4 cm/s within 0.15 s,
//!   `λ̈ ≈ 0.3 m/s²`) while the ICR is 6 cm from the wheel, where the platform motion moves the
//!   contact point at only `θ̇ d_sap ≈ 0.7 · 0.06 = 0.04 m/s`: the leg's `λ̇ l`, as large as
//!   that, turns the wheel's direction by tens of degrees within 0.15 s (the leg acceleration's
//!   share of the steering rate is up to `|λ̈| / ‖v‖ ≈ 8 rad/s`): 11–12.5 rad/s, 0.6 rad
//!   misalignment;
//! - wheel 3, `t = 10.0–10.05 s`: the ICR has left the field, the return loop pulls leg 3 back
//!   at 9 cm/s; a leg rate `λ̇` moves the point where the wheel's velocity vanishes by `λ̇/θ̇`
//!   (here 13 cm, more than the 12 cm field) across the leg, where the repulsion does not look:
//!   15.7 rad/s, 1.0 rad misalignment;
//! - wheel 2, `t = 14.6–14.7 s` (the Fig. 3.13 pass): leg 2 starts retracting, 9.8 rad/s;
//! - the radial pass of wheel 3 (the ICR travels outwards along leg 3): the leg force (3.39)
//!   pushes the wheel away from the ICR, i.e. outwards, ahead of the ICR on its path, so the
//!   ICR stays in the field longer (at `t = 9.7 s` 8 cm from the wheel instead of 15 cm) and the
//!   repulsion, with the return loop off inside the field, deviates the platform further:
//!   7.6 cm at `t = 10.2 s`. Here the leg repulsion and the ICR repulsion fight.
//!
//! The leg parameters (mass, damping, cubic stiffness, return gains) only scale these: every
//! admittance that moves a leg by centimetres within the half second the ICR spends in a field
//! has the leg rate of the ICR's approach, which is the contact speed `θ̇ d_sap` the platform
//! gives the wheel there. The fix is therefore a limit of the leg motion by the steering it
//! needs ([`kernel::platform::legs::SteeringLimit`], [`LEG_STEERING_LIMIT`]):
//! `|λ̈| ≤ 1.5 rad/s · ‖v‖` and `|λ̇| ≤ 0.5 · θ̇ d_sap`. With it the leg-motion run holds the
//! thesis' statements itself: peak steering rate 5.97 rad/s (25 % of the uncontrolled
//! 24.1 rad/s), misalignment 0 rad, position error 6.3 cm and 2.4°, and at the wheel-2 pass
//! 8 % less translational and 11 % less rotational error than with the legs fixed. What does
//! not hold on this model is the size of the benefit: the legs move 1.8 cm (thesis A→B:
//! 5.5 cm) and the error reduction at the wheel-2 pass is a third of the thesis' 32 %/24 %;
//! a leg moving 5.5 cm while the ICR crosses a 12 cm field at ~0.25 m/s needs a leg rate of the
//! order of the contact speed, which turns the wheel faster than the avoidance saves. Over the
//! whole trajectory the leg-motion run's position error (6.3 cm) stays above the legs-fixed
//! run's (4.9 cm) because of the radial pass of wheel 3 (last item above).
//! The platform carries a one-joint dummy upper body held by a PD controller: the upper body
//! plays no role here.
//!
//! Parameters the thesis does not give (all **invented**): the field extension
//! [`MAX_EXTENSION_M`] and its leg-length ratio [`EXTENSION_RATIO`] (Fig. 3.9), `F_max`
//! ([`MAX_FORCE_N`]), the leg admittance ([`LEG_MASS_KG`], [`LEG_DAMPING_KG_S`],
//! [`LEG_CUBIC_STIFFNESS_N_M3`], chosen so that the repelled wheel would move about 6 cm
//! without the steering limit, as A→B (5.5 cm) in Fig. 3.13), the return gains
//! ([`RETURN_POLE_RAD_S`], [`RETURN_BLEND_M`]), the leg motion's steering limit
//! ([`LEG_STEERING_LIMIT`]), the steering-rate limit of the drives. The nominal leg length is `13.9 · 0.08 / 2.1 = 0.5295 m`, so the
//! 2.1 rad/s rotation needs exactly the 13.9 rad/s wheel rate.
//!
//! Claims: the nominal trajectory reaches 2.1 rad/s with wheel rates ≤ 13.9 rad/s; without
//! avoidance the ICR passes within 2.5 cm of a steering axis and the steering rate peaks above
//! 15 rad/s; with it the peak steering rate is less than a third of that, the rate-limited
//! steering keeps up (misalignment < 0.05 rad, without avoidance > 0.1 rad) and the position
//! error stays within ±7 cm and ±15° (Sec. 3.2.6), each for the legs-fixed and for the
//! leg-motion run; at the pass of wheel 2 — the manoeuvre of
//! Fig. 3.13 — leg motion reduces the translational and rotational deviation ("32% less
//! translational error, 24% less rotational error"); no NaN.
//!
//! Outputs: `timeseries.csv` (reference, and per run pose, errors, ICR, avoidance
//! accelerations, steering rates, misalignments, spinning rates, leg lengths),
//! `summary.json`, `icr_path.svg` (square ICR plot of Fig. 3.11 top, drawn by [`write_files`]),
//! `steering_rates.svg`, `accelerations.svg`, `errors.svg`.

use std::f64::consts::PI;

use fixtures::justin::whole_body;

use hal::{JointTorqueInterface, PlatformCommand, PlatformVelocityInterface, LEGS};
use kernel::model::{Inertia, JointDrive, JointKind, Model, ModelBuilder, Placement};
use kernel::platform::avoidance::{AvoidanceConfig, AvoidanceOutput, PlatformAvoidance, PlatformReference};
use kernel::platform::icr::{instantaneous_center, BaseTwist, IcrRepulsionConfig};
use kernel::platform::legs::{LegAdmittanceConfig, ReturnGains, SteeringLimit};
use nalgebra::{Matrix3, Vector2, Vector3};
use plotters::prelude::*;

use super::{Outcome, RunOptions};
use crate::output::{Figure, Line, Panel, Span, Summary, TimeSeries};
use crate::replay::Robot;
use crate::sim::{run_loop, SimConfig, Simulator, CONTROL_PERIOD_S};
use crate::wheels::{WheelConfig, Wheels};

/// Registry name.
pub const NAME: &str = "icr_avoidance";
/// One-line description.
pub const DESCRIPTION: &str =
    "platform ICR singularity avoidance (Fig. 3.11-3.13): quintic Bezier trajectory to 2.1 rad/s past three wheels, avoidance OFF / ON / ON with legs";

/// The replay's robot: Justin's platform in the run with avoidance and leg motion (`legs.*`),
/// the upper body at the home configuration, the reference path as the platform's goal.
pub const REPLAY: Robot = Robot::Justin {
    tcp_errors: ["", ""],
    aliases: &[
        ("q.base_x", "legs.x"),
        ("q.base_y", "legs.y"),
        ("q.base_theta", "legs.theta"),
        ("leg_length.0", "legs.leg.1"),
        ("leg_length.1", "legs.leg.2"),
        ("leg_length.2", "legs.leg.3"),
        ("leg_length.3", "legs.leg.4"),
    ],
};
/// Simulated time (s).
pub const DURATION_S: f64 = 22.5;
/// Knot spacing of the Bézier spline (s).
pub const KNOT_STEP_S: f64 = 0.25;
/// Nominal leg length (m): `13.9 rad/s · 0.08 m / 2.1 rad/s` (Sec. 3.2.6, derived).
pub const NOMINAL_LEG_M: f64 = fixtures::justin::WHEEL_SPIN_RATE_MAX * fixtures::justin::WHEEL_RADIUS / 2.1;
/// Largest field extension `d₀,max` (m). Invented: "They [the position errors] can be reduced
/// by using weaker potential fields. A trade-off between low steering rate and high tracking
/// performance has to be found."
pub const MAX_EXTENSION_M: f64 = whole_body::ICR_MAX_EXTENSION_M;
/// `d₀ ≤ κ λ` (Fig. 3.9). Invented.
pub const EXTENSION_RATIO: f64 = whole_body::ICR_EXTENSION_RATIO;
/// `F_max` (N): with `1 m/(N s)` the ICR speed at contact (m/s). Invented.
pub const MAX_FORCE_N: f64 = whole_body::ICR_MAX_FORCE;
/// Virtual leg mass `m_w` (kg). Invented.
pub const LEG_MASS_KG: f64 = whole_body::LEG_MASS_KG;
/// Virtual leg damping `d_w` (kg/s). Invented.
pub const LEG_DAMPING_KG_S: f64 = whole_body::LEG_DAMPING_KG_S;
/// Cubic leg stiffness `c₁` (N/m³). Invented: a third of `F_max` balances it at 6.4 cm.
pub const LEG_CUBIC_STIFFNESS_N_M3: f64 = whole_body::LEG_CUBIC_STIFFNESS_N_M3;
/// Double pole of the return loop (rad/s): `k₁ = ω²`, `k₂ = 2ω`. Invented.
pub const RETURN_POLE_RAD_S: f64 = whole_body::RETURN_POLE_RAD_S;
/// Width over which the return gains fade in outside a field (m). Invented.
pub const RETURN_BLEND_M: f64 = whole_body::RETURN_BLEND_M;
/// The leg motion's limit by the steering it needs ([`SteeringLimit`]). Chosen: a leg
/// acceleration may turn its wheel at up to 1.5 rad/s, a quarter of the steering drives' limit
/// ([`crate::wheels::STEERING_RATE_LIMIT_RAD_S`]), leaving the rest for the platform motion
/// (5.8 rad/s at most with the legs fixed); a leg moves at most half as fast as the platform
/// motion moves its wheel, so the wheel's velocity pole stays within half the ICR distance.
/// Measured (steering-rate peak, misalignment, position error, leg excursion, wheel-2-pass
/// reduction of the translational/rotational error): 1.5 rad/s, 0.5: 5.97 rad/s, 0 rad, 6.3 cm,
/// 1.8 cm, 8 %/11 %; 2 rad/s, 0.5: 6.38 rad/s, 0.022 rad, 6.5 cm, 1.8 cm, 9 %/12 %; 3 rad/s,
/// 0.7: 8.2 rad/s, 0.18 rad, 7.4 cm; 2 rad/s, 0.3: 5.35 rad/s, 0 rad, 5.9 cm, 1.2 cm, 8 %/9 %;
/// 4 rad/s, 0.8: the pole reaches the ICR (1155 rad/s).
pub const LEG_STEERING_LIMIT: SteeringLimit<f64> = SteeringLimit { steering_rate: 1.5, speed_ratio: 0.5 };
/// Time window of the tangential pass of wheel 2, the manoeuvre of Fig. 3.13 (s).
pub const LEG_WINDOW_S: (f64, f64) = (13.5, 17.0);
/// Thesis bound on the translational position error (m), Sec. 3.2.6.
pub const TRANSLATION_BOUND_M: f64 = 0.07;
/// Thesis bound on the rotational position error (rad): 15°.
pub const ROTATION_BOUND_RAD: f64 = 15.0 * PI / 180.0;

// ---------------------------------------------------------------------------------------------
// The trajectory.

/// Integral of the quintic smoothstep, `∫₀ˣ (10u³ − 15u⁴ + 6u⁵) du`, continued linearly.
fn smoothstep_integral(x: f64) -> f64 {
    if x <= 0.0 {
        0.0
    } else if x >= 1.0 {
        x - 0.5
    } else {
        x.powi(4) * (2.5 - 3.0 * x + x * x)
    }
}

/// A signal that changes at rate `rate` from `a` to `b`, the rate ramping in and out with a
/// quintic smoothstep of width `ramp` (s): total change `rate (b − a)`.
#[derive(Clone, Copy, Debug)]
struct RateSegment {
    rate: f64,
    a: f64,
    b: f64,
    ramp: f64,
}

fn signal(initial: f64, segments: &[RateSegment], t: f64) -> f64 {
    segments.iter().fold(initial, |v, s| {
        v + s.rate * s.ramp * (smoothstep_integral((t - s.a) / s.ramp) - smoothstep_integral((t - s.b) / s.ramp))
    })
}

/// The free parameters of the designed motion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Design {
    /// ICR direction (deg) when the first pass starts.
    pub phi0_deg: f64,
    /// Rate (deg/s) at which the ICR direction turns during the first pass.
    pub sweep1_deg_s: f64,
}

/// The motion of the scenario: the first pass crosses the field of wheel 3 obliquely (45°)
/// and misses its steering axis by about 2.5 cm.
pub const DESIGN: Design = Design { phi0_deg: -175.0, sweep1_deg_s: 27.0 };

/// The designed motion at `t`: body-frame ICR `p = ρ (cos φ, sin φ)` (m) and yaw rate `ω`
/// (rad/s); the body twist is `(ẋ_b, ẏ_b) = ω (p_y, −p_x)`.
pub fn design(d: &Design, t: f64) -> (Vector2<f64>, f64) {
    let seg = |rate, a, b, ramp| RateSegment { rate, a, b, ramp };
    let omega =
        signal(0.0, &[seg(1.4, 0.5, 2.0, 0.5), seg(-1.4 / 1.5, 4.5, 6.0, 0.5), seg(-0.7 / 1.2, 20.0, 21.2, 0.5)], t);
    let rho = signal(
        0.0,
        &[
            seg(0.12, 5.2, 6.7, 0.5),
            seg(0.25, 7.4, 10.2, 0.5),
            seg(-0.32 / 1.5, 12.0, 13.5, 0.5),
            seg(-0.06, 15.8, 16.8, 0.4),
            seg(-0.5 / 1.5, 20.0, 21.5, 0.5),
        ],
        t,
    );
    let deg = PI / 180.0;
    let after_first = d.phi0_deg + d.sweep1_deg_s * 2.8;
    let phi = signal(
        d.phi0_deg * deg,
        &[
            seg(d.sweep1_deg_s * deg, 7.4, 10.2, 0.5),
            seg((-190.0 - after_first) / 2.0 * deg, 11.0, 13.0, 0.5),
            seg(-30.0 * deg, 13.3, 13.3 + 170.0 / 30.0, 0.6),
        ],
        t,
    );
    (Vector2::new(phi.cos(), phi.sin()) * rho, omega)
}

/// Body twist `(ẋ_b, ẏ_b, θ̇)` of the design at `t`.
fn design_twist(d: &Design, t: f64) -> Vector3<f64> {
    let (p, omega) = design(d, t);
    Vector3::new(omega * p.y, -omega * p.x, omega)
}

/// A knot `(t, r, ṙ, r̈)` of a [`BezierSpline`] (s; world `(x, y, θ)` and its derivatives).
pub type Knot = (f64, Vector3<f64>, Vector3<f64>, Vector3<f64>);

/// A chain of quintic Bézier segments per axis through knots `(t_k, r_k, ṙ_k, r̈_k)`.
#[derive(Clone, Debug)]
pub struct BezierSpline {
    times: Vec<f64>,
    /// Control points `P₀ … P₅` of each segment, per axis.
    controls: Vec<[Vector3<f64>; 6]>,
}

impl BezierSpline {
    /// The spline through the knots: per segment `P₀ = r₀`, `P₁ = r₀ + ṙ₀ T/5`,
    /// `P₂ = r₀ + 2ṙ₀ T/5 + r̈₀ T²/20`, and symmetrically at the end (position, velocity and
    /// acceleration continuous).
    pub fn through(knots: &[Knot]) -> Self {
        let mut times = Vec::new();
        let mut controls = Vec::new();
        for pair in knots.windows(2) {
            if let [(t0, p0, v0, a0), (t1, p1, v1, a1)] = pair {
                let h = t1 - t0;
                times.push(*t0);
                controls.push([
                    *p0,
                    p0 + v0 * (h / 5.0),
                    p0 + v0 * (2.0 * h / 5.0) + a0 * (h * h / 20.0),
                    p1 - v1 * (2.0 * h / 5.0) + a1 * (h * h / 20.0),
                    p1 - v1 * (h / 5.0),
                    *p1,
                ]);
            }
        }
        if let Some((t, ..)) = knots.last() {
            times.push(*t);
        }
        Self { times, controls }
    }

    /// `(r, ṙ, r̈)` at `t` (clamped to the spline's time range).
    pub fn evaluate(&self, t: f64) -> PlatformReference<f64> {
        let last = self.controls.len().saturating_sub(1);
        let k = self.times.partition_point(|tk| *tk <= t).saturating_sub(1).min(last);
        let (Some(t0), Some(t1), Some(p)) = (self.times.get(k), self.times.get(k + 1), self.controls.get(k)) else {
            return PlatformReference {
                pose: Vector3::zeros(),
                velocity: Vector3::zeros(),
                acceleration: Vector3::zeros(),
            };
        };
        let h = t1 - t0;
        let s = ((t - t0) / h).clamp(0.0, 1.0);
        let u = 1.0 - s;
        let b5 = [
            u.powi(5),
            5.0 * s * u.powi(4),
            10.0 * s * s * u.powi(3),
            10.0 * s.powi(3) * u * u,
            5.0 * s.powi(4) * u,
            s.powi(5),
        ];
        let b4 = [u.powi(4), 4.0 * s * u.powi(3), 6.0 * s * s * u * u, 4.0 * s.powi(3) * u, s.powi(4)];
        let b3 = [u.powi(3), 3.0 * s * u * u, 3.0 * s * s * u, s.powi(3)];
        let pose = p.iter().zip(b5).fold(Vector3::zeros(), |acc, (c, b)| acc + c * b);
        let velocity = p.windows(2).zip(b4).fold(Vector3::zeros(), |acc, (w, b)| match w {
            [c0, c1] => acc + (c1 - c0) * (5.0 * b / h),
            _ => acc,
        });
        let acceleration = p.windows(3).zip(b3).fold(Vector3::zeros(), |acc, (w, b)| match w {
            [c0, c1, c2] => acc + (c2 - c1 * 2.0 + c0) * (20.0 * b / (h * h)),
            _ => acc,
        });
        PlatformReference { pose, velocity, acceleration }
    }
}

/// The nominal trajectory: the design integrated to world poses, sampled at knots every
/// [`KNOT_STEP_S`] with its exact velocity and acceleration, joined by quintic Bézier segments.
pub fn nominal_trajectory(d: &Design) -> BezierSpline {
    let step = 1e-3;
    let world_velocity = |t: f64, heading: f64| {
        let b = design_twist(d, t);
        let (s, c) = heading.sin_cos();
        Vector3::new(c * b.x - s * b.y, s * b.x + c * b.y, b.z)
    };
    let knots_every = (KNOT_STEP_S / step).round() as usize;
    let total = (DURATION_S / step).round() as usize;
    let mut pose = Vector3::<f64>::zeros();
    let mut knots = Vec::new();
    for k in 0..=total {
        let t = k as f64 * step;
        if k % knots_every == 0 {
            let velocity = world_velocity(t, pose.z);
            // r̈ = R (u̇, ẇ) + θ̇ R (−ẏ_b, ẋ_b): the body velocity's change plus its rotation.
            let h = 1e-5;
            let body_rate = (design_twist(d, t + h) - design_twist(d, t - h)) / (2.0 * h);
            let body = design_twist(d, t);
            let (s, c) = pose.z.sin_cos();
            let (ax, ay) = (body_rate.x - body.z * body.y, body_rate.y + body.z * body.x);
            knots.push((t, pose, velocity, Vector3::new(c * ax - s * ay, s * ax + c * ay, body_rate.z)));
        }
        // RK4 of the pose.
        let k1 = world_velocity(t, pose.z);
        let k2 = world_velocity(t + step / 2.0, pose.z + k1.z * step / 2.0);
        let k3 = world_velocity(t + step / 2.0, pose.z + k2.z * step / 2.0);
        let k4 = world_velocity(t + step, pose.z + k3.z * step);
        pose += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (step / 6.0);
    }
    BezierSpline::through(&knots)
}

// ---------------------------------------------------------------------------------------------
// The runs.

/// Which loop runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// ICR control OFF.
    Off,
    /// ICR control ON, legs fixed.
    On,
    /// ICR control ON with leg motion.
    Legs,
}

/// The avoidance parameters of a mode.
pub fn avoidance_config(mode: Mode) -> AvoidanceConfig<f64> {
    AvoidanceConfig {
        repulsion: IcrRepulsionConfig {
            leg_directions: fixtures::justin::LEG_DIRECTIONS,
            max_extension: MAX_EXTENSION_M,
            extension_ratio: EXTENSION_RATIO,
            max_force: MAX_FORCE_N,
            min_yaw_rate: 1e-3,
        },
        legs: LegAdmittanceConfig {
            mass: LEG_MASS_KG,
            damping: LEG_DAMPING_KG_S,
            cubic_stiffness: LEG_CUBIC_STIFFNESS_N_M3,
            nominal_length: NOMINAL_LEG_M,
            min_length: fixtures::justin::LEG_LENGTH_MIN,
            max_length: fixtures::justin::LEG_LENGTH_MAX,
        },
        return_gains: ReturnGains::critically_damped(RETURN_POLE_RAD_S, RETURN_BLEND_M),
        icr_avoidance: mode != Mode::Off,
        leg_motion: mode == Mode::Legs,
    }
}

/// One control cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Time (s).
    pub t: f64,
    /// Reference and measured pose `(x, y, θ)`.
    pub reference: Vector3<f64>,
    /// Measured pose.
    pub pose: Vector3<f64>,
    /// The loop's output.
    pub output: AvoidanceOutput<f64>,
    /// ICR of the measured twist in the platform frame (m), if finite.
    pub icr: Option<Vector2<f64>>,
    /// Distance of the ICR to the nearest wheel (m), `∞` without an ICR.
    pub wheel_distance_m: f64,
    /// Required steering rates (rad/s).
    pub steering_rate: [f64; LEGS],
    /// Misalignment of the rate-limited steering (rad).
    pub misalignment: [f64; LEGS],
    /// Wheel spinning rates (rad/s).
    pub spin: [f64; LEGS],
    /// Leg lengths (m).
    pub legs: [f64; LEGS],
}

/// The model of the runs: a planar base (150 kg) with a one-joint dummy upper body.
fn platform_model() -> Result<Model<f64, 4, 4, 1>, String> {
    let mut b = ModelBuilder::<f64, 4, 4, 1>::new(Vector3::new(0.0, 0.0, -9.81));
    let prismatic = |axis| JointKind::Prismatic { axis };
    let x = b
        .add_body(None, Placement::identity(), prismatic(Vector3::x_axis()), JointDrive::actuated(0), Inertia::zero())
        .map_err(|e| e.to_string())?;
    let y = b
        .add_body(
            Some(x),
            Placement::identity(),
            prismatic(Vector3::y_axis()),
            JointDrive::actuated(1),
            Inertia::zero(),
        )
        .map_err(|e| e.to_string())?;
    let platform = Inertia {
        mass: 150.0,
        com: Vector3::new(0.0, 0.0, 0.3),
        rotational: Matrix3::from_diagonal(&Vector3::new(7.6, 9.2, 10.6)),
    };
    let base = b
        .add_body(
            Some(y),
            Placement::identity(),
            JointKind::Revolute { axis: Vector3::z_axis() },
            JointDrive::actuated(2),
            platform,
        )
        .map_err(|e| e.to_string())?;
    let dummy =
        Inertia { mass: 5.0, com: Vector3::zeros(), rotational: Matrix3::from_diagonal(&Vector3::new(0.1, 0.1, 0.1)) };
    let top = b
        .add_body(
            Some(base),
            Placement::translation(0.0, 0.0, 0.6),
            JointKind::Revolute { axis: Vector3::z_axis() },
            JointDrive::actuated(3),
            dummy,
        )
        .map_err(|e| e.to_string())?;
    b.add_frame(Some(top), Placement::identity()).map_err(|e| e.to_string())?;
    b.try_build().map_err(|e| e.to_string())
}

/// Runs one mode for `duration_s`.
pub fn run(
    mode: Mode,
    trajectory: &BezierSpline,
    duration_s: f64,
    options: &RunOptions,
) -> Result<Vec<Sample>, String> {
    run_with(avoidance_config(mode), trajectory, duration_s, options)
}

/// Runs the loop with the parameters `avoidance` for `duration_s`.
pub fn run_with(
    avoidance: AvoidanceConfig<f64>,
    trajectory: &BezierSpline,
    duration_s: f64,
    options: &RunOptions,
) -> Result<Vec<Sample>, String> {
    let mode = match (avoidance.icr_avoidance, avoidance.leg_motion) {
        (false, _) => Mode::Off,
        (true, false) => Mode::On,
        (true, true) => Mode::Legs,
    };
    let config =
        SimConfig { physics_step_s: CONTROL_PERIOD_S, initial_leg_length_m: NOMINAL_LEG_M, ..SimConfig::default() };
    let mut sim: Simulator<4, 4, 1, 1> = options.simulator(platform_model()?, config)?;
    let mut avoidance = PlatformAvoidance::try_new(avoidance).map_err(|e| e.to_string())?;
    if mode == Mode::Legs {
        avoidance = avoidance.with_steering_limit(LEG_STEERING_LIMIT).map_err(|e| e.to_string())?;
    }
    avoidance.reset(&Vector3::zeros(), &[NOMINAL_LEG_M; LEGS]).map_err(|e| e.to_string())?;
    let mut wheels = Wheels::new(WheelConfig::default());
    let mut samples = Vec::new();
    let label = format!("{NAME} ({mode:?})");
    run_loop(&mut sim, duration_s, CONTROL_PERIOD_S, |sim, info| -> Result<(), String> {
        if info.cycle % 500 == 0 {
            options.progress.report(&label, info.time_s, duration_s);
        }
        let joint = JointTorqueInterface::read(sim)?;
        let base = PlatformVelocityInterface::read(sim)?;
        let [q] = joint.position;
        let [dq] = joint.velocity;
        sim.write_torque(&[-20.0 * q - 5.0 * dq])?;
        let reference = trajectory.evaluate(info.time_s);
        let pose = Vector3::from(base.pose);
        let output = avoidance
            .step(&reference, &pose, &Vector3::from(base.velocity), CONTROL_PERIOD_S)
            .map_err(|e| format!("{label}: {e} at t = {:.3} s", info.time_s))?;
        sim.write_velocity(&PlatformCommand { velocity: output.velocity.into(), leg_rates: output.leg_rates })?;
        let states = wheels.update(&base, &output.leg_rates, CONTROL_PERIOD_S);
        let twist = BaseTwist::from_world(&Vector3::from(base.velocity), base.pose[2]);
        let icr = instantaneous_center(&twist, 1e-3).position;
        let wheel_positions = avoidance.repulsion().wheel_positions(&base.leg_lengths);
        let wheel_distance_m =
            icr.map_or(f64::INFINITY, |p| wheel_positions.iter().map(|w| (p - w).norm()).fold(f64::INFINITY, f64::min));
        samples.push(Sample {
            t: info.time_s,
            reference: reference.pose,
            pose,
            output,
            icr,
            wheel_distance_m,
            steering_rate: states.map(|s| s.required_rate_rad_s),
            misalignment: states.map(|s| s.misalignment_rad),
            spin: states.map(|s| s.propulsion_rad_s),
            legs: base.leg_lengths,
        });
        Ok(())
    })?;
    options.progress.finish();
    Ok(samples)
}

// ---------------------------------------------------------------------------------------------
// Evaluation.

/// Metrics of one run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metrics {
    /// Largest required steering rate of any wheel (rad/s).
    pub peak_steering_rate: f64,
    /// Largest required steering rate per wheel (rad/s).
    pub peak_steering_rate_per_wheel: [f64; LEGS],
    /// Largest misalignment of the rate-limited steering (rad).
    pub peak_misalignment: f64,
    /// Closest approach of the ICR to a steering axis (m).
    pub closest_icr_m: f64,
    /// Largest translational position error (m).
    pub max_translation_error_m: f64,
    /// Largest rotational position error (rad).
    pub max_rotation_error_rad: f64,
    /// Largest wheel spinning rate (rad/s).
    pub max_spin: f64,
    /// Largest yaw rate (rad/s).
    pub max_yaw_rate: f64,
    /// Largest leg deviation from the nominal length (m).
    pub max_leg_deviation_m: f64,
    /// Largest commanded avoidance acceleration, translational (m/s²) and yaw (rad/s²).
    pub peak_avoidance_acceleration: [f64; 2],
    /// Share of the time the repulsion was active.
    pub repelling_share: f64,
    /// Every value finite.
    pub finite: bool,
}

/// Metrics of a run.
pub fn metrics(samples: &[Sample]) -> Metrics {
    let max = |f: &dyn Fn(&Sample) -> f64| samples.iter().map(f).fold(0.0, f64::max);
    let mut per_wheel = [0.0; LEGS];
    for s in samples {
        for (p, r) in per_wheel.iter_mut().zip(s.steering_rate) {
            *p = f64::max(*p, r.abs());
        }
    }
    let finite = samples.iter().all(|s| {
        let o = &s.output;
        o.velocity
            .iter()
            .chain(o.leg_rates.iter())
            .chain(o.acceleration.iter())
            .chain(s.pose.iter())
            .all(|x| x.is_finite())
            && s.steering_rate.iter().chain(s.spin.iter()).chain(s.misalignment.iter()).all(|x| x.is_finite())
    });
    Metrics {
        peak_steering_rate: per_wheel.iter().copied().fold(0.0, f64::max),
        peak_steering_rate_per_wheel: per_wheel,
        peak_misalignment: max(&|s| s.misalignment.iter().fold(0.0, |m, x| f64::max(m, x.abs()))),
        closest_icr_m: samples.iter().map(|s| s.wheel_distance_m).fold(f64::INFINITY, f64::min),
        max_translation_error_m: max(&|s| (s.reference - s.pose).fixed_rows::<2>(0).norm()),
        max_rotation_error_rad: max(&|s| (s.reference.z - s.pose.z).abs()),
        max_spin: max(&|s| s.spin.iter().fold(0.0, |m, x| f64::max(m, x.abs()))),
        max_yaw_rate: max(&|s| s.output.velocity.z.abs()),
        max_leg_deviation_m: max(&|s| s.legs.iter().fold(0.0, |m, l| f64::max(m, (l - NOMINAL_LEG_M).abs()))),
        peak_avoidance_acceleration: [
            max(&|s| s.output.avoidance_acceleration.fixed_rows::<2>(0).norm()),
            max(&|s| s.output.avoidance_acceleration.z.abs()),
        ],
        repelling_share: samples.iter().filter(|s| s.output.repelling).count() as f64 / samples.len().max(1) as f64,
        finite,
    }
}

/// Runs the scenario.
pub fn simulate(options: &RunOptions) -> Result<Outcome, String> {
    let trajectory = nominal_trajectory(&DESIGN);
    let runs = [Mode::Off, Mode::On, Mode::Legs].map(|m| run(m, &trajectory, DURATION_S, options));
    let [off, on, legs] = runs;
    evaluate(&off?, &on?, &legs?)
}

/// Claims, metrics and figures of the three runs.
pub fn evaluate(off: &[Sample], on: &[Sample], legs: &[Sample]) -> Result<Outcome, String> {
    let (m_off, m_on, m_legs) = (metrics(off), metrics(on), metrics(legs));
    let mut summary = Summary::new(NAME);
    for (tag, m) in [("off", &m_off), ("on", &m_on), ("legs", &m_legs)] {
        summary
            .metric(&format!("{tag}_peak_steering_rate_rad_s"), m.peak_steering_rate)
            .metric(&format!("{tag}_peak_steering_rate_wheel1_rad_s"), m.peak_steering_rate_per_wheel[0])
            .metric(&format!("{tag}_peak_steering_rate_wheel2_rad_s"), m.peak_steering_rate_per_wheel[1])
            .metric(&format!("{tag}_peak_steering_rate_wheel3_rad_s"), m.peak_steering_rate_per_wheel[2])
            .metric(&format!("{tag}_peak_steering_rate_wheel4_rad_s"), m.peak_steering_rate_per_wheel[3])
            .metric(&format!("{tag}_peak_misalignment_rad"), m.peak_misalignment)
            .metric(&format!("{tag}_closest_icr_to_wheel_m"), m.closest_icr_m)
            .metric(&format!("{tag}_max_translation_error_m"), m.max_translation_error_m)
            .metric(&format!("{tag}_max_rotation_error_deg"), m.max_rotation_error_rad.to_degrees())
            .metric(&format!("{tag}_max_wheel_spin_rad_s"), m.max_spin)
            .metric(&format!("{tag}_max_yaw_rate_rad_s"), m.max_yaw_rate)
            .metric(&format!("{tag}_max_leg_deviation_m"), m.max_leg_deviation_m)
            .metric(&format!("{tag}_peak_avoidance_acceleration_m_s2"), m.peak_avoidance_acceleration[0])
            .metric(&format!("{tag}_peak_avoidance_acceleration_rad_s2"), m.peak_avoidance_acceleration[1])
            .metric(&format!("{tag}_repelling_share"), m.repelling_share);
    }
    let ratio = m_on.peak_steering_rate / m_off.peak_steering_rate;
    let legs_ratio = m_legs.peak_steering_rate / m_off.peak_steering_rate;
    let window = |samples: &[Sample]| {
        metrics(&samples.iter().filter(|x| x.t >= LEG_WINDOW_S.0 && x.t < LEG_WINDOW_S.1).copied().collect::<Vec<_>>())
    };
    let (w_on, w_legs) = (window(on), window(legs));
    let translation_reduction = 1.0 - w_legs.max_translation_error_m / w_on.max_translation_error_m;
    let rotation_reduction = 1.0 - w_legs.max_rotation_error_rad / w_on.max_rotation_error_rad;
    summary
        .metric("steering_rate_ratio_on_off", ratio)
        .metric("steering_rate_ratio_legs_off", legs_ratio)
        .metric("wheel2_pass_on_max_translation_error_m", w_on.max_translation_error_m)
        .metric("wheel2_pass_legs_max_translation_error_m", w_legs.max_translation_error_m)
        .metric("wheel2_pass_on_max_rotation_error_deg", w_on.max_rotation_error_rad.to_degrees())
        .metric("wheel2_pass_legs_max_rotation_error_deg", w_legs.max_rotation_error_rad.to_degrees())
        .metric("wheel2_pass_on_peak_avoidance_acceleration_m_s2", w_on.peak_avoidance_acceleration[0])
        .metric("wheel2_pass_legs_peak_avoidance_acceleration_m_s2", w_legs.peak_avoidance_acceleration[0])
        .metric("wheel2_pass_on_peak_avoidance_acceleration_rad_s2", w_on.peak_avoidance_acceleration[1])
        .metric("wheel2_pass_legs_peak_avoidance_acceleration_rad_s2", w_legs.peak_avoidance_acceleration[1])
        .metric("wheel2_pass_leg_deviation_m", w_legs.max_leg_deviation_m)
        .metric("legs_translation_error_reduction", translation_reduction)
        .metric("legs_rotation_error_reduction", rotation_reduction);
    summary.claim(
        &format!(
            "the nominal trajectory reaches {:.2} rad/s with wheel rates ≤ 13.9 rad/s (max {:.3} rad/s)",
            m_off.max_yaw_rate, m_off.max_spin
        ),
        m_off.max_yaw_rate >= 2.1 - 1e-3 && m_off.max_spin <= fixtures::justin::WHEEL_SPIN_RATE_MAX + 1e-3,
    );
    summary.claim(
        &format!(
            "without avoidance the ICR passes {:.1} cm from a steering axis and the steering rate peaks at {:.1} rad/s",
            m_off.closest_icr_m * 100.0,
            m_off.peak_steering_rate
        ),
        m_off.closest_icr_m < 0.025 && m_off.peak_steering_rate > 15.0,
    );
    for (run, m, r) in [("legs fixed", &m_on, ratio), ("with leg motion", &m_legs, legs_ratio)] {
        summary.claim(
            &format!(
                "with avoidance ({run}) the peak steering rate is a fraction of it: {:.2} rad/s = {:.0} %; the ICR stays {:.1} cm from the axes",
                m.peak_steering_rate,
                r * 100.0,
                m.closest_icr_m * 100.0
            ),
            r < 1.0 / 3.0,
        );
        summary.claim(
            &format!(
                "with avoidance ({run}) the rate-limited steering keeps up (misalignment {:.3} rad), without it not ({:.2} rad)",
                m.peak_misalignment, m_off.peak_misalignment
            ),
            m.peak_misalignment < 0.05 && m_off.peak_misalignment > 0.1,
        );
        summary.claim(
            &format!(
                "position error ({run}) within ±7 cm and ±15° (thesis): {:.1} cm, {:.1}°",
                m.max_translation_error_m * 100.0,
                m.max_rotation_error_rad.to_degrees()
            ),
            m.max_translation_error_m <= TRANSLATION_BOUND_M && m.max_rotation_error_rad <= ROTATION_BOUND_RAD,
        );
    }
    summary.claim(
        &format!(
            "at the pass of wheel 2 (Fig. 3.13) leg motion ({:.1} cm, thesis 5.5 cm) reduces the deviation: {:.0} % less translational, {:.0} % less rotational error (thesis: 32 %, 24 %)",
            w_legs.max_leg_deviation_m * 100.0,
            translation_reduction * 100.0,
            rotation_reduction * 100.0
        ),
        translation_reduction > 0.0 && rotation_reduction > 0.0,
    );
    summary.claim("no NaN or infinite value", m_off.finite && m_on.finite && m_legs.finite);
    Ok(Outcome { summary, series: series(off, on, legs)?, figures: figures(off, on, legs) })
}

fn series(off: &[Sample], on: &[Sample], legs: &[Sample]) -> Result<TimeSeries, String> {
    let mut columns: Vec<String> = ["t", "ref.x", "ref.y", "ref.theta"].map(String::from).to_vec();
    let per_run = |tag: &str| {
        let mut c: Vec<String> = [
            "x",
            "y",
            "theta",
            "e.x",
            "e.y",
            "e.theta",
            "icr.x",
            "icr.y",
            "icr_wheel_distance",
            "repelling",
            "sap.ax",
            "sap.ay",
            "sap.alpha",
        ]
        .iter()
        .map(|s| format!("{tag}.{s}"))
        .collect();
        for i in 1..=LEGS {
            c.extend([
                format!("{tag}.steer_rate.{i}"),
                format!("{tag}.misalign.{i}"),
                format!("{tag}.spin.{i}"),
                format!("{tag}.leg.{i}"),
            ]);
        }
        c
    };
    for tag in ["off", "on", "legs"] {
        columns.extend(per_run(tag));
    }
    let mut table = TimeSeries::new(columns);
    for ((a, b), c) in off.iter().zip(on).zip(legs) {
        let mut row = vec![a.t, a.reference.x, a.reference.y, a.reference.z];
        for s in [a, b, c] {
            let e = s.reference - s.pose;
            let icr = s.icr.unwrap_or(Vector2::repeat(f64::NAN));
            let sap = s.output.avoidance_acceleration;
            row.extend([
                s.pose.x,
                s.pose.y,
                s.pose.z,
                e.x,
                e.y,
                e.z,
                icr.x,
                icr.y,
                s.wheel_distance_m,
                f64::from(u8::from(s.output.repelling)),
                sap.x,
                sap.y,
                sap.z,
            ]);
            for i in 0..LEGS {
                row.extend(
                    [s.steering_rate.get(i), s.misalignment.get(i), s.spin.get(i), s.legs.get(i)]
                        .map(|x| x.copied().unwrap_or(f64::NAN)),
                );
            }
        }
        table.push(row)?;
    }
    Ok(table)
}

fn figures(off: &[Sample], on: &[Sample], legs: &[Sample]) -> Vec<(&'static str, Figure)> {
    let runs = [("ICR control OFF", off), ("ICR control ON", on), ("ICR control ON, leg motion", legs)];
    let events = || {
        [9.0, 15.0, 18.0]
            .iter()
            .enumerate()
            .map(|(i, t)| Span {
                label: if i == 0 { "thesis' critical moments".into() } else { String::new() },
                from: *t,
                to: *t,
            })
            .collect::<Vec<_>>()
    };
    let steering = Figure {
        title: "icr_avoidance: required steering rates (cf. Fig. 3.11 bottom)".into(),
        x_label: "time (s)".into(),
        panels: (0..LEGS)
            .map(|w| Panel {
                title: format!("wheel {}", w + 1),
                y_label: "steering rate (rad/s)".into(),
                lines: runs
                    .iter()
                    .map(|(label, s)| {
                        Line::new(
                            *label,
                            s.iter().map(|x| (x.t, x.steering_rate.get(w).copied().unwrap_or(0.0))).collect(),
                        )
                    })
                    .collect(),
                spans: events(),
            })
            .collect(),
    };
    let acceleration = |f: fn(&Sample) -> f64| {
        runs.iter().skip(1).map(|(label, s)| Line::new(*label, s.iter().map(|x| (x.t, f(x))).collect())).collect()
    };
    let accelerations = Figure {
        title: "icr_avoidance: commanded avoidance accelerations, world frame (cf. Fig. 3.12, 3.13)".into(),
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: "x-direction".into(),
                y_label: "acceleration (m/s²)".into(),
                lines: acceleration(|s| s.output.avoidance_acceleration.x),
                spans: events(),
            },
            Panel {
                title: "y-direction".into(),
                y_label: "acceleration (m/s²)".into(),
                lines: acceleration(|s| s.output.avoidance_acceleration.y),
                spans: events(),
            },
            Panel {
                title: "θ-direction".into(),
                y_label: "acceleration (rad/s²)".into(),
                lines: acceleration(|s| s.output.avoidance_acceleration.z),
                spans: events(),
            },
            Panel {
                title: "leg length deviation from nominal (leg motion run)".into(),
                y_label: "deviation (m)".into(),
                lines: (0..LEGS)
                    .map(|w| {
                        Line::new(
                            format!("leg {}", w + 1),
                            legs.iter().map(|x| (x.t, x.legs.get(w).copied().unwrap_or(0.0) - NOMINAL_LEG_M)).collect(),
                        )
                    })
                    .collect(),
                spans: events(),
            },
        ],
    };
    let errors = Figure {
        title: "icr_avoidance: deviation from the nominal trajectory".into(),
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: "translational error".into(),
                y_label: "error (m)".into(),
                lines: runs
                    .iter()
                    .map(|(label, s)| {
                        Line::new(
                            *label,
                            s.iter().map(|x| (x.t, (x.reference - x.pose).fixed_rows::<2>(0).norm())).collect(),
                        )
                    })
                    .collect(),
                spans: events(),
            },
            Panel {
                title: "rotational error".into(),
                y_label: "error (°)".into(),
                lines: runs
                    .iter()
                    .map(|(label, s)| {
                        Line::new(*label, s.iter().map(|x| (x.t, (x.reference.z - x.pose.z).to_degrees())).collect())
                    })
                    .collect(),
                spans: events(),
            },
        ],
    };
    vec![("steering_rates.svg", steering), ("accelerations.svg", accelerations), ("errors.svg", errors)]
}

/// File name of the ICR plot.
pub const ICR_FILE: &str = "icr_path.svg";

/// Draws the ICR paths of the three runs in the platform frame (y ±0.8 m as Fig. 3.11, x to scale)
/// with the wheels and their fields into [`ICR_FILE`] in `out`; the runner calls this after
/// writing the [`Outcome`]. Returns the file name.
pub fn write_files(out: &std::path::Path, outcome: &Outcome) -> Result<Vec<&'static str>, String> {
    let path = out.join(ICR_FILE);
    let root = SVGBackend::new(&path, (900, 900)).into_drawing_area();
    draw_icr(&root, &outcome.series).map_err(|e| format!("plot {}: {e}", path.display()))?;
    root.present().map_err(|e| format!("plot {}: {e}", path.display()))?;
    Ok(vec![ICR_FILE])
}

/// Margin around the ICR plot and the sizes of its label areas (px).
const ICR_MARGIN_PX: u32 = 15;
const ICR_X_LABELS_PX: u32 = 45;
const ICR_Y_LABELS_PX: u32 = 55;

fn draw_icr(
    root: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    series: &TimeSeries,
) -> Result<(), Box<dyn std::error::Error>> {
    root.fill(&WHITE)?;
    let area = root.titled("ICR in the platform frame for t > 6.5 s (cf. Fig. 3.11 top)", ("sans-serif", 20))?;
    // The plot area is what the margins and label areas leave; x spans ±0.8 m scaled by its
    // aspect ratio, so that both axes have the same metres per pixel.
    let (width, height) = area.dim_in_pixel();
    let plot_width = f64::from(width) - f64::from(2 * ICR_MARGIN_PX + ICR_Y_LABELS_PX);
    let plot_height = f64::from(height) - f64::from(2 * ICR_MARGIN_PX + ICR_X_LABELS_PX);
    let half_x = 0.8 * plot_width / plot_height;
    let mut chart = ChartBuilder::on(&area)
        .margin(ICR_MARGIN_PX)
        .x_label_area_size(ICR_X_LABELS_PX)
        .y_label_area_size(ICR_Y_LABELS_PX)
        .build_cartesian_2d(-half_x..half_x, -0.8..0.8)?;
    chart.configure_mesh().x_desc("x (m)").y_desc("y (m)").label_style(("sans-serif", 13)).draw()?;
    let field = RGBColor(200, 200, 200);
    for (i, psi) in fixtures::justin::LEG_DIRECTIONS.iter().enumerate() {
        let (x, y) = (NOMINAL_LEG_M * psi.cos(), NOMINAL_LEG_M * psi.sin());
        chart.draw_series(std::iter::once(Circle::new((x, y), 0, field.filled())))?;
        let ring: Vec<(f64, f64)> = (0..=64)
            .map(|k| {
                let a = f64::from(k) * 2.0 * PI / 64.0;
                (x + MAX_EXTENSION_M * a.cos(), y + MAX_EXTENSION_M * a.sin())
            })
            .collect();
        chart.draw_series(std::iter::once(Polygon::new(ring, field.mix(0.5).filled())))?;
        chart.draw_series(std::iter::once(Cross::new((x, y), 6, BLACK.stroke_width(2))))?;
        chart.draw_series(std::iter::once(Text::new(
            format!("wheel {}", i + 1),
            (x + 0.03 * psi.cos().signum(), y + 0.16 * psi.sin().signum()),
            ("sans-serif", 15),
        )))?;
    }
    let colors = [RGBColor(31, 119, 180), RGBColor(214, 39, 40), RGBColor(44, 160, 44)];
    let t = series.column("t").unwrap_or_default();
    for ((tag, label), color) in
        [("off", "ICR control OFF"), ("on", "ICR control ON"), ("legs", "ICR control ON, leg motion")]
            .iter()
            .zip(colors)
    {
        let xs = series.column(&format!("{tag}.icr.x")).unwrap_or_default();
        let ys = series.column(&format!("{tag}.icr.y")).unwrap_or_default();
        // Break the path where it leaves the window (or the ICR is at infinity).
        let mut segments: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
        for ((ti, x), y) in t.iter().zip(&xs).zip(&ys) {
            let inside = *ti > 6.5 && x.abs() < 0.8 && y.abs() < 0.8;
            match segments.last_mut() {
                Some(current) if inside => current.push((*x, *y)),
                Some(current) if !current.is_empty() => segments.push(Vec::new()),
                _ => {}
            }
        }
        let mut first = true;
        for segment in segments.into_iter().filter(|s| s.len() > 1) {
            let drawn = chart.draw_series(LineSeries::new(segment, color.stroke_width(2)))?;
            if first {
                drawn
                    .label(*label)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2)));
                first = false;
            }
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperMiddle)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}
