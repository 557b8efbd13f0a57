//! The simulated robot behind the `hal` traits.
//!
//! [`Simulator`] integrates the rigid-body dynamics of a kernel [`Model`] whose first
//! `base_dof ∈ {0, 3}` coordinates are a planar mobile base `r = (x, y, θ)` (world frame) and
//! whose remaining `U` coordinates are the torque-controlled upper body `q_u`:
//!
//! - **Upper body** (torque-driven): the partitioned equations of motion (2.1) with the base
//!   motion prescribed,
//!   `M_uu(q) q̈_u = τ_u + τ_ext,u − h_u(q, q̇) − M_ur(q) r̈`, `h = C(q, q̇) q̇ + g(q)`,
//!   integrated by classical fourth-order Runge–Kutta at a fixed physics step (default
//!   [`DEFAULT_PHYSICS_STEP_S`] = 1/6000 s, twice the 3 kHz torque loop of Rollin' Justin).
//!   Every derivative evaluation runs the kernel: [`forward_kinematics`], [`rnea`] with
//!   `q̈ = (r̈, 0)` (which yields `h + M_·r r̈` in one pass), [`crba`] for `M`, and a Cholesky
//!   solve of `M_uu` (nalgebra, fixed size).
//! - **Mobile base** (kinematic, velocity-controlled): the base velocity follows the commanded
//!   `ṙ_des` through a first-order lag `T` (`r̈ = (ṙ_des − ṙ)/T`), or exactly (`ṙ = ṙ_des`) for
//!   `T = 0`. Because `ṙ_des` is held constant between commands, the lag is integrated in
//!   closed form (`ṙ(s) = ṙ_des + (ṙ₀ − ṙ_des) e^{−s/T}`) at every Runge–Kutta stage, so the
//!   base follows its first-order response exactly for any `T ≥ 0`. The upper body's reaction
//!   on the base is not simulated: the base is an ideal velocity source (Sec. 5.1). With
//!   `T = 0` a velocity command takes effect as a step, so the base acceleration `r̈` never acts
//!   on the upper body through `M_ur r̈`; experiments on the dynamic coupling (Sec. 5.1.3, the
//!   coupling compensation) need `T > 0` (the mobile-impedance scenarios use 50 ms).
//! - **Legs**: the four leg lengths `λ_i` integrate their commanded rates and stop at the end
//!   stops of [`SimConfig`]. They do not enter the dynamics (the model has no leg coordinates).
//! - **Actuation**: the commanded torque is held constant between commands (zero-order hold)
//!   and clamped to the model's effort limits ([`kernel::model::JointLimits::effort`]);
//!   whether a clamp happened is reported per command and per step. The torque sensors measure
//!   the applied (clamped) torque exactly.
//! - **Disturbances**: [`Simulator::push`] adds a world-frame force at a frame's origin for a
//!   time window, applied as `τ_ext = J_pᵀ F` with the frame's positional Jacobian
//!   ([`frame_jacobian`]).
//! - **Contact surfaces** (optional, [`Simulator::add_surface`]): compliant half-spaces (a
//!   window, a floor, a table top) touched by a frame's origin. With the surface's outward unit
//!   normal `n` through `point`, the penetration is `δ = max(0, (point − p)·n)` and the normal
//!   force `F_n = max(0, k δ + d δ̇)` pushes along `n` only (Hunt–Crossley-like: no pulling, no
//!   force without penetration), optionally with a regularised Coulomb friction
//!   `F_t = −μ F_n v_t / √(|v_t|² + v_ε²)` against the tangential velocity `v_t`. Applied like a
//!   push (`τ_ext = J_pᵀ F`) at every Runge–Kutta stage; [`Simulator::surface_force`] reads the
//!   force at the current state.
//! - **Passive joint elements** (optional, [`Simulator::set_passive_joints`]): a linear spring
//!   and a viscous damper per upper-body coordinate, `τ_passive = −K (q_u − q_rest) − D q̇_u`,
//!   evaluated at every Runge–Kutta stage like the dynamics (the parallel springs of Fig. 4.3,
//!   (4.43), and the viscous joint friction of Fig. 4.11). None by default. The torque sensors
//!   measure the motor torque only.
//! - **Joint end stops** (optional, [`Simulator::set_joint_stops`]).
//! - **Plant**: ideal by default (the torque acts exactly and at once, the sensors read the
//!   state and the applied torque exactly, no friction). [`Simulator::set_plant_model`] makes it
//!   realistic ([`crate::plant`]): link friction in every Runge–Kutta stage, the torque loop's
//!   first-order lag per physics step, one control cycle between a command and its set point
//!   (the cycle starts when the controller reads the joint sensors), noisy, offset and
//!   quantised joint sensors.
//!
//! Reads never fail. A non-finite command is refused with a
//! [`SimError`] of kind [`ErrorKind::OutOfRange`] and triggers the documented safe reaction
//! (brakes for the upper body, a stop for the base), see the trait implementations.
//!
//! [`run_loop`] runs a controller at a fixed control period (1 kHz by default) with the physics
//! substeps in between.

use core::fmt;

use hal::{
    CycleClock, ErrorKind, ErrorType, JointSample, JointTorqueInterface, PlatformCommand, PlatformSample,
    PlatformVelocityInterface, LEGS,
};
use kernel::dynamics::{
    crba, forward_kinematics, frame_jacobian, kinetic_energy, potential_energy, rnea, DynamicsError,
};
use kernel::model::{Data, FrameId, Model, Placement};
use nalgebra::{Cholesky, SMatrix, SVector, Unit, Vector3};

use crate::plant::{PlantModel, RealisticJoints};

/// Default physics step (s): 1/6000 s, twice the rate of Rollin' Justin's 3 kHz torque loop.
pub const DEFAULT_PHYSICS_STEP_S: f64 = 1.0 / 6000.0;

/// Control period of the main loop (s): 1 kHz.
pub const CONTROL_PERIOD_S: f64 = 1e-3;

/// Number of planar base coordinates `(x, y, θ)` of a mobile robot.
pub const PLANAR_BASE_DOF: usize = 3;

/// Tick rate of the simulator's [`CycleClock`]: microseconds of simulated time.
pub const CLOCK_TICKS_PER_SECOND: u32 = 1_000_000;

/// Settings of the simulator, validated by [`Simulator::new`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimConfig {
    /// Fixed Runge–Kutta step (s), `> 0`.
    pub physics_step_s: f64,
    /// Time constant `T` (s) of the base velocity loop, `≥ 0`; `0` means `ṙ = ṙ_des` exactly.
    pub base_lag_s: f64,
    /// Shortest leg length (m), the inner end stop.
    pub leg_length_min_m: f64,
    /// Longest leg length (m), the outer end stop.
    pub leg_length_max_m: f64,
    /// Initial length of every leg (m), inside the end stops.
    pub initial_leg_length_m: f64,
}

impl Default for SimConfig {
    /// 1/6000 s physics step, ideal base (`T = 0`), legs of the Justin-like platform
    /// ([`fixtures::justin::LEG_LENGTH_MIN`] … [`fixtures::justin::LEG_LENGTH_MAX`], starting at
    /// [`fixtures::justin::LEG_LENGTH_NOMINAL`]).
    fn default() -> Self {
        Self {
            physics_step_s: DEFAULT_PHYSICS_STEP_S,
            base_lag_s: 0.0,
            leg_length_min_m: fixtures::justin::LEG_LENGTH_MIN,
            leg_length_max_m: fixtures::justin::LEG_LENGTH_MAX,
            initial_leg_length_m: fixtures::justin::LEG_LENGTH_NOMINAL,
        }
    }
}

/// Why the simulator refused a setting, a state or a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SimError {
    /// The model's `N` is not `base_dof + U` with `base_dof ∈ {0, 3}`.
    InvalidDimensions {
        /// Coordinates of the model (`N`).
        coordinates: usize,
        /// Upper-body coordinates (`U`).
        upper_body: usize,
    },
    /// A configuration value is out of its documented range (or NaN).
    InvalidConfig {
        /// The offending field of [`SimConfig`] (or argument).
        field: &'static str,
    },
    /// A command or a state contains NaN or ±∞.
    NonFinite {
        /// What was not finite.
        what: &'static str,
    },
    /// A non-zero base velocity was commanded to a robot without a mobile base.
    FixedBase,
    /// A frame id is not in the model.
    UnknownFrame,
    /// A kernel dynamics algorithm failed (the state diverged).
    Dynamics(DynamicsError),
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::InvalidDimensions { coordinates, upper_body } => write!(
                f,
                "model has {coordinates} coordinates, which is not 0 or 3 base coordinates plus {upper_body} upper-body ones"
            ),
            Self::InvalidConfig { field } => write!(f, "invalid simulator setting `{field}`"),
            Self::NonFinite { what } => write!(f, "{what} is not finite"),
            Self::FixedBase => f.write_str("non-zero base velocity commanded to a fixed-base robot"),
            Self::UnknownFrame => f.write_str("unknown frame"),
            Self::Dynamics(e) => write!(f, "dynamics: {e}"),
        }
    }
}

impl std::error::Error for SimError {}

impl hal::Error for SimError {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::Dynamics(_) => ErrorKind::Other,
            _ => ErrorKind::OutOfRange,
        }
    }
}

impl From<DynamicsError> for SimError {
    fn from(e: DynamicsError) -> Self {
        Self::Dynamics(e)
    }
}

/// Linear passive elements on the upper-body coordinates: `τ_passive = −K (q_u − q_rest) − D q̇_u`
/// with diagonal `K` (Nm/rad or N/m) and `D` (Nms/rad or Ns/m), e.g. the parallel springs and
/// joint dampers of Fig. 4.3 or viscous joint friction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassiveJoints<const U: usize> {
    /// Spring stiffness per coordinate, `≥ 0`.
    pub stiffness: SVector<f64, U>,
    /// Spring rest position per coordinate (rad or m).
    pub rest: SVector<f64, U>,
    /// Viscous damping per coordinate, `≥ 0`.
    pub damping: SVector<f64, U>,
}

impl<const U: usize> PassiveJoints<U> {
    /// No springs, no damping.
    pub fn none() -> Self {
        Self { stiffness: SVector::zeros(), rest: SVector::zeros(), damping: SVector::zeros() }
    }

    /// The torque the elements exert at `(q_u, q̇_u)`.
    pub fn torque(&self, q: &SVector<f64, U>, v: &SVector<f64, U>) -> SVector<f64, U> {
        -(self.stiffness.component_mul(&(q - self.rest)) + self.damping.component_mul(v))
    }
}

/// Mechanical end stops of the upper-body joints at the model's position limits: beyond a
/// limit a stiff unilateral spring–damper pushes the joint back, `τ = k δ − d q̇` towards the
/// range (never pulling), `δ` the penetration. Real joints have them; without them a simulated
/// joint driven past its limit (by pushes, by a low-priority end-stop task overpowered by the
/// levels above) would move on freely.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointStops {
    /// Stop stiffness `k` (Nm/rad or N/m), `≥ 0`.
    pub stiffness: f64,
    /// Stop damping `d` (Nms/rad or Ns/m), `≥ 0`.
    pub damping: f64,
}

impl JointStops {
    /// Stops of the Justin-like joints: 20 kNm/rad and 200 Nms/rad (chosen: a 200 Nm torque
    /// penetrates 10 mrad; the damping is close to critical for a link inertia of ≈ 0.5 kg m²).
    pub const JUSTIN: Self = Self { stiffness: 2.0e4, damping: 200.0 };

    /// The stop torque of one joint at `(q, q̇)` with limits `[lower, upper]`.
    pub fn torque(&self, q: f64, v: f64, lower: f64, upper: f64) -> f64 {
        if q < lower {
            (self.stiffness * (lower - q) - self.damping * v).max(0.0)
        } else if q > upper {
            (self.stiffness * (upper - q) - self.damping * v).min(0.0)
        } else {
            0.0
        }
    }
}

/// A world-frame force applied at the origin of a frame during `[start_s, start_s + duration_s)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Push {
    /// Frame at whose origin the force acts.
    pub frame: FrameId,
    /// Force (N), world frame.
    pub force_world: Vector3<f64>,
    /// Start time (s, simulated).
    pub start_s: f64,
    /// Duration (s).
    pub duration_s: f64,
}

impl Push {
    fn active(&self, t: f64) -> bool {
        t >= self.start_s && t < self.start_s + self.duration_s
    }
}

/// Tangential speed (m/s) below which the regularised friction of a [`Surface`] grows
/// linearly with the sliding velocity (viscous regularisation `v_ε` of the Coulomb law).
pub const FRICTION_REGULARISATION_M_S: f64 = 0.01;

/// A compliant contact surface: the half-space `{x : (x − point)·normal ≤ 0}` that the origin of
/// `frame` may penetrate (see the module docs for the force law).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    /// Frame whose origin touches the surface (a TCP).
    pub frame: FrameId,
    /// A point on the surface (m), world frame.
    pub point: Vector3<f64>,
    /// Outward unit normal (pointing out of the solid, into free space), world frame.
    pub normal: Unit<Vector3<f64>>,
    /// Normal stiffness `k` (N/m), `> 0`.
    pub stiffness_n_m: f64,
    /// Normal damping `d` (Ns/m), `≥ 0`, acting only while penetrating.
    pub damping_ns_m: f64,
    /// Coulomb friction coefficient `μ`, `≥ 0` (`0`: frictionless).
    pub friction: f64,
}

/// Contact state of one [`Surface`] at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceContact {
    /// Penetration depth `δ ≥ 0` (m).
    pub penetration_m: f64,
    /// Normal force `F_n ≥ 0` (N) along the outward normal.
    pub normal_force_n: f64,
    /// Total force on the frame (N, world frame): normal plus friction.
    pub force_world: Vector3<f64>,
}

impl Surface {
    /// The contact of a frame origin at `position` moving with `velocity` (world frame).
    pub fn contact(&self, position: &Vector3<f64>, velocity: &Vector3<f64>) -> SurfaceContact {
        let n = self.normal.into_inner();
        let depth = (self.point - position).dot(&n);
        if depth <= 0.0 {
            return SurfaceContact { penetration_m: 0.0, normal_force_n: 0.0, force_world: Vector3::zeros() };
        }
        let depth_rate = -velocity.dot(&n);
        let normal_force = (self.stiffness_n_m * depth + self.damping_ns_m * depth_rate).max(0.0);
        let tangential = velocity - n * velocity.dot(&n);
        let regularised =
            (tangential.norm_squared() + FRICTION_REGULARISATION_M_S * FRICTION_REGULARISATION_M_S).sqrt();
        let friction = tangential * (-self.friction * normal_force / regularised);
        SurfaceContact { penetration_m: depth, normal_force_n: normal_force, force_world: n * normal_force + friction }
    }
}

/// What happened during one physics step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepReport {
    /// Simulated time at the end of the step (s).
    pub time_s: f64,
    /// The torque applied during the step was clamped at an effort limit.
    pub torque_saturated: bool,
    /// At least one push acted during the step.
    pub pushed: bool,
}

/// Kinetic, potential and total energy (J) of the robot (kernel [`kinetic_energy`],
/// [`potential_energy`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Energies {
    /// Kinetic energy `½ q̇ᵀ M q̇` (J), base motion included.
    pub kinetic: f64,
    /// Gravitational potential energy (J), relative to the world origin.
    pub potential: f64,
    /// Sum of both (J).
    pub total: f64,
}

/// Motion of the kinematic base over one physics step with the command held constant.
#[derive(Clone, Copy, Debug)]
struct BaseMotion {
    pose: [f64; 3],
    velocity: [f64; 3],
    desired: [f64; 3],
    lag_s: f64,
}

impl BaseMotion {
    /// `(r, ṙ, r̈)` at `s` seconds into the step: exact first-order lag response.
    fn at(&self, s: f64) -> ([f64; 3], [f64; 3], [f64; 3]) {
        let mut out = ([0.0; 3], [0.0; 3], [0.0; 3]);
        let axes = self.pose.iter().zip(self.velocity.iter()).zip(self.desired.iter());
        let slots = out.0.iter_mut().zip(out.1.iter_mut()).zip(out.2.iter_mut());
        for (((r0, v0), vd), ((r, v), a)) in axes.zip(slots) {
            (*r, *v, *a) = if self.lag_s > 0.0 {
                let decay = (-s / self.lag_s).exp();
                let gap = v0 - vd;
                (r0 + vd * s + gap * self.lag_s * (1.0 - decay), vd + gap * decay, -gap * decay / self.lag_s)
            } else {
                (r0 + vd * s, *vd, 0.0)
            };
        }
        out
    }
}

/// The simulated robot: a kernel model with a kinematic planar base (`N − U ∈ {0, 3}`
/// coordinates) and `U` torque-controlled upper-body coordinates.
///
/// Time advances only through [`Simulator::step`] (one physics step) or
/// [`Simulator::advance`]; the `hal` implementations read the current state and set the
/// commands held from then on.
#[derive(Clone, Debug)]
pub struct Simulator<const N: usize, const B: usize, const F: usize, const U: usize> {
    model: Model<f64, N, B, F>,
    data: Data<f64, N, B, F>,
    config: SimConfig,
    base_dof: usize,
    q: SVector<f64, N>,
    v: SVector<f64, N>,
    steps: u64,
    torque: SVector<f64, U>,
    torque_saturated: bool,
    brakes: bool,
    base_command: PlatformCommand<f64>,
    legs: [f64; LEGS],
    pushes: Vec<Push>,
    surfaces: Vec<Surface>,
    passive: PassiveJoints<U>,
    stops: Option<JointStops>,
    realistic: Option<RealisticJoints<U>>,
}

impl<const N: usize, const B: usize, const F: usize, const U: usize> Simulator<N, B, F, U> {
    /// A simulator of `model` at rest at `q = 0`, `t = 0`, with zero commands.
    ///
    /// Errors: [`SimError::InvalidDimensions`] unless `N = U` (fixed base) or `N = U + 3`
    /// (planar base first); [`SimError::InvalidConfig`] for a non-positive step, a negative
    /// lag or an empty/ill-ordered leg range.
    pub fn new(model: Model<f64, N, B, F>, config: SimConfig) -> Result<Self, SimError> {
        let base_dof = match N.checked_sub(U) {
            Some(b @ (0 | PLANAR_BASE_DOF)) if U > 0 => b,
            _ => return Err(SimError::InvalidDimensions { coordinates: N, upper_body: U }),
        };
        validate(&config)?;
        let data = Data::new(&model);
        Ok(Self {
            model,
            data,
            config,
            base_dof,
            q: SVector::zeros(),
            v: SVector::zeros(),
            steps: 0,
            torque: SVector::zeros(),
            torque_saturated: false,
            brakes: false,
            base_command: PlatformCommand { velocity: [0.0; 3], leg_rates: [0.0; LEGS] },
            legs: [config.initial_leg_length_m; LEGS],
            pushes: Vec::new(),
            surfaces: Vec::new(),
            passive: PassiveJoints::none(),
            stops: None,
            realistic: None,
        })
    }

    /// Sets the full state `(q, q̇)` (base coordinates first). Errors: non-finite values.
    pub fn set_state(&mut self, q: SVector<f64, N>, v: SVector<f64, N>) -> Result<(), SimError> {
        if !q.iter().chain(v.iter()).all(|x| x.is_finite()) {
            return Err(SimError::NonFinite { what: "state" });
        }
        self.q = q;
        self.v = v;
        Ok(())
    }

    /// Coordinates `q` (base first), rad or m.
    pub fn q(&self) -> &SVector<f64, N> {
        &self.q
    }

    /// Velocities `q̇` (base first), rad/s or m/s.
    pub fn v(&self) -> &SVector<f64, N> {
        &self.v
    }

    /// Upper-body coordinates `q_u`.
    pub fn upper_q(&self) -> SVector<f64, U> {
        upper(&self.q, self.base_dof)
    }

    /// Upper-body velocities `q̇_u`.
    pub fn upper_v(&self) -> SVector<f64, U> {
        upper(&self.v, self.base_dof)
    }

    /// The applied (clamped) upper-body torque `τ_u` (Nm or N).
    pub fn applied_torque(&self) -> &SVector<f64, U> {
        &self.torque
    }

    /// The realistic plant's joint friction torque `τ_f` at the current upper-body velocities
    /// (Nm or N, [`crate::plant`]); zero on the ideal plant.
    pub fn friction_torque(&self) -> SVector<f64, U> {
        self.realistic.as_ref().map_or_else(SVector::zeros, |plant| plant.friction(&self.upper_v()))
    }

    /// The realistic plant's largest friction torque magnitudes at the current upper-body
    /// velocities, `τ_c + d |q̇|` per joint ([`crate::plant`]); zero on the ideal plant.
    pub fn friction_torque_bound(&self) -> SVector<f64, U> {
        self.realistic.as_ref().map_or_else(SVector::zeros, |plant| plant.friction_bound(&self.upper_v()))
    }

    /// `true` if the last torque command was clamped at an effort limit.
    pub fn torque_saturated(&self) -> bool {
        self.torque_saturated
    }

    /// `true` while the brakes hold the upper body (after a non-finite torque command).
    pub fn brakes_engaged(&self) -> bool {
        self.brakes
    }

    /// Leg lengths `λ_i` (m).
    pub fn leg_lengths(&self) -> [f64; LEGS] {
        self.legs
    }

    /// Number of base coordinates (0 or 3).
    pub fn base_dof(&self) -> usize {
        self.base_dof
    }

    /// Simulated time (s): the number of physics steps times the step.
    pub fn time_s(&self) -> f64 {
        #[allow(clippy::cast_precision_loss, reason = "step counts stay far below 2^52")]
        let steps = self.steps as f64;
        steps * self.config.physics_step_s
    }

    /// Number of physics steps taken.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// The settings.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// The simulated model.
    pub fn model(&self) -> &Model<f64, N, B, F> {
        &self.model
    }

    /// Schedules a world-frame force `force_world` (N) at the origin of `frame` during
    /// `[start_s, start_s + duration_s)`. Any number of pushes may overlap.
    ///
    /// Errors: unknown frame, non-finite force or times, negative duration.
    pub fn push(
        &mut self,
        frame: FrameId,
        force_world: Vector3<f64>,
        start_s: f64,
        duration_s: f64,
    ) -> Result<(), SimError> {
        self.model.frame(frame).ok_or(SimError::UnknownFrame)?;
        if !force_world.iter().chain([start_s, duration_s].iter()).all(|x| x.is_finite()) {
            return Err(SimError::NonFinite { what: "push" });
        }
        if duration_s < 0.0 {
            return Err(SimError::InvalidConfig { field: "duration_s" });
        }
        self.pushes.push(Push { frame, force_world, start_s, duration_s });
        Ok(())
    }

    /// Adds a contact surface (see the module docs); it acts from the next physics step on.
    /// Returns its index for [`Simulator::surface_force`].
    ///
    /// Errors: unknown frame, a non-finite value, a non-positive stiffness, a negative damping
    /// or friction coefficient.
    pub fn add_surface(&mut self, surface: Surface) -> Result<usize, SimError> {
        self.model.frame(surface.frame).ok_or(SimError::UnknownFrame)?;
        let values = [surface.stiffness_n_m, surface.damping_ns_m, surface.friction];
        if !surface.point.iter().chain(surface.normal.iter()).chain(values.iter()).all(|x| x.is_finite()) {
            return Err(SimError::NonFinite { what: "surface" });
        }
        if surface.stiffness_n_m <= 0.0 {
            return Err(SimError::InvalidConfig { field: "stiffness_n_m" });
        }
        if surface.damping_ns_m < 0.0 || surface.friction < 0.0 {
            return Err(SimError::InvalidConfig { field: "damping_ns_m/friction" });
        }
        self.surfaces.push(surface);
        Ok(self.surfaces.len() - 1)
    }

    /// The installed contact surfaces, in the order of [`Simulator::add_surface`].
    pub fn surfaces(&self) -> &[Surface] {
        &self.surfaces
    }

    /// The contact of surface `index` at the current state (`None` for an unknown index).
    ///
    /// Errors: the kinematics failed (non-finite state).
    pub fn surface_force(&mut self, index: usize) -> Result<Option<SurfaceContact>, SimError> {
        let Some(surface) = self.surfaces.get(index).copied() else {
            return Ok(None);
        };
        forward_kinematics(&self.model, &mut self.data, &self.q, &self.v)?;
        let v = self.v;
        let (position, velocity) = self.frame_motion(surface.frame, &v)?;
        Ok(Some(surface.contact(&position, &velocity)))
    }

    /// Position and linear velocity (world frame) of `frame`'s origin; needs the forward
    /// kinematics of the state whose velocity is `v`.
    fn frame_motion(&mut self, frame: FrameId, v: &SVector<f64, N>) -> Result<(Vector3<f64>, Vector3<f64>), SimError> {
        let position = self.data.frame_placements.get(frame.0).ok_or(SimError::UnknownFrame)?.translation.vector;
        let mut jacobian = SMatrix::<f64, 6, N>::zeros();
        frame_jacobian(&self.model, &self.data, frame, &mut jacobian)?;
        let velocity: Vector3<f64> = jacobian.fixed_rows::<3>(0) * v;
        Ok((position, velocity))
    }

    /// Installs passive joint springs and dampers on the upper body (see the module docs);
    /// they act from the next physics step on.
    ///
    /// Errors: a non-finite entry, or a negative stiffness or damping.
    pub fn set_passive_joints(&mut self, passive: PassiveJoints<U>) -> Result<(), SimError> {
        let all = || passive.stiffness.iter().chain(passive.rest.iter()).chain(passive.damping.iter());
        if !all().all(|x| x.is_finite()) {
            return Err(SimError::NonFinite { what: "passive joints" });
        }
        if passive.stiffness.iter().chain(passive.damping.iter()).any(|x| *x < 0.0) {
            return Err(SimError::InvalidConfig { field: "passive joints" });
        }
        self.passive = passive;
        Ok(())
    }

    /// Installs (or, with `None`, removes) mechanical end stops at the model's upper-body
    /// position limits; they act from the next physics step on.
    ///
    /// Errors: a non-finite or negative stiffness or damping.
    pub fn set_joint_stops(&mut self, stops: Option<JointStops>) -> Result<(), SimError> {
        if let Some(s) = stops {
            if !(s.stiffness.is_finite() && s.damping.is_finite() && s.stiffness >= 0.0 && s.damping >= 0.0) {
                return Err(SimError::InvalidConfig { field: "joint stops" });
            }
        }
        self.stops = stops;
        Ok(())
    }

    /// The realistic plant of `model` ([`crate::plant`]), or the ideal one for `None` (the
    /// default). Takes effect at once; the applied torque keeps its value and follows the next
    /// command. Errors: [`SimError::InvalidConfig`] naming a magnitude out of range.
    pub fn set_plant_model(&mut self, model: Option<PlantModel>) -> Result<(), SimError> {
        self.realistic = match model {
            Some(model) => {
                model.validate().map_err(|field| SimError::InvalidConfig { field })?;
                let effort: SVector<f64, U> = upper(&self.model.limits.effort, self.base_dof);
                Some(RealisticJoints::new(model, &effort))
            }
            None => None,
        };
        Ok(())
    }

    /// The installed passive joint elements.
    pub fn passive_joints(&self) -> &PassiveJoints<U> {
        &self.passive
    }

    /// Sum of the pushes active at time `t` on `frame` (N, world frame).
    pub fn push_force(&self, frame: FrameId, t: f64) -> Vector3<f64> {
        self.pushes.iter().filter(|p| p.frame == frame && p.active(t)).map(|p| p.force_world).sum()
    }

    /// World placement of `frame` at the current state.
    pub fn frame_placement(&mut self, frame: FrameId) -> Result<Placement<f64>, SimError> {
        forward_kinematics(&self.model, &mut self.data, &self.q, &self.v)?;
        self.data.frame_placements.get(frame.0).copied().ok_or(SimError::UnknownFrame)
    }

    /// Kinetic, potential and total energy at the current state.
    pub fn energies(&mut self) -> Result<Energies, SimError> {
        forward_kinematics(&self.model, &mut self.data, &self.q, &self.v)?;
        let kinetic = kinetic_energy(&self.model, &self.data);
        let potential = potential_energy(&self.model, &self.data);
        Ok(Energies { kinetic, potential, total: kinetic + potential })
    }

    /// Upper-body accelerations `q̈_u` at time `t` (absolute) and state `(q, v)` with the base
    /// accelerating at `base_acceleration`.
    fn upper_acceleration(
        &mut self,
        t: f64,
        q: &SVector<f64, N>,
        v: &SVector<f64, N>,
        base_acceleration: &[f64; 3],
    ) -> Result<SVector<f64, U>, SimError> {
        let b = self.base_dof;
        forward_kinematics(&self.model, &mut self.data, q, v)?;
        let mut qdd = SVector::<f64, N>::zeros();
        for (slot, a) in qdd.iter_mut().zip(base_acceleration.iter()).take(b) {
            *slot = *a;
        }
        // h + M_·r r̈ in one RNEA pass.
        let bias = *rnea(&self.model, &mut self.data, &qdd)?;
        let (qu, vu) = (upper(q, b), upper(v, b));
        let mut rhs: SVector<f64, U> = self.torque - upper(&bias, b) + self.passive.torque(&qu, &vu);
        if let Some(plant) = &self.realistic {
            rhs += plant.friction(&vu);
        }
        if let Some(stops) = self.stops {
            let (lower, high): (SVector<f64, U>, SVector<f64, U>) =
                (upper(&self.model.limits.position_lower, b), upper(&self.model.limits.position_upper, b));
            for ((((r, qi), vi), lo), hi) in
                rhs.iter_mut().zip(qu.iter()).zip(vu.iter()).zip(lower.iter()).zip(high.iter())
            {
                *r += stops.torque(*qi, *vi, *lo, *hi);
            }
        }
        let mut jacobian = SMatrix::<f64, 6, N>::zeros();
        for p in self.pushes.iter().filter(|p| p.active(t)) {
            frame_jacobian(&self.model, &self.data, p.frame, &mut jacobian)?;
            let generalized: SVector<f64, N> = jacobian.fixed_rows::<3>(0).transpose() * p.force_world;
            rhs += upper(&generalized, b);
        }
        for i in 0..self.surfaces.len() {
            let Some(surface) = self.surfaces.get(i).copied() else { continue };
            let (position, velocity) = self.frame_motion(surface.frame, v)?;
            let contact = surface.contact(&position, &velocity);
            if contact.normal_force_n > 0.0 {
                frame_jacobian(&self.model, &self.data, surface.frame, &mut jacobian)?;
                let generalized: SVector<f64, N> = jacobian.fixed_rows::<3>(0).transpose() * contact.force_world;
                rhs += upper(&generalized, b);
            }
        }
        crba(&self.model, &mut self.data);
        let m_uu = self.data.mass_matrix.fixed_view::<U, U>(b, b).into_owned();
        let factor = Cholesky::new(m_uu).ok_or(SimError::Dynamics(DynamicsError::MassMatrixNotPositiveDefinite))?;
        Ok(factor.solve(&rhs))
    }

    /// The full state from the upper-body state and the base state.
    fn assemble(
        &self,
        qu: &SVector<f64, U>,
        vu: &SVector<f64, U>,
        r: &[f64; 3],
        rd: &[f64; 3],
    ) -> (SVector<f64, N>, SVector<f64, N>) {
        let b = self.base_dof;
        let mut q = SVector::<f64, N>::zeros();
        let mut v = SVector::<f64, N>::zeros();
        for (i, (rv, rdv)) in r.iter().zip(rd.iter()).enumerate().take(b) {
            if let (Some(qi), Some(vi)) = (q.get_mut(i), v.get_mut(i)) {
                *qi = *rv;
                *vi = *rdv;
            }
        }
        q.fixed_rows_mut::<U>(b).copy_from(qu);
        v.fixed_rows_mut::<U>(b).copy_from(vu);
        (q, v)
    }

    /// Advances the simulation by one physics step (classical RK4 for the upper body,
    /// closed-form base motion, leg integration with end stops).
    ///
    /// Errors: [`SimError::Dynamics`] if the state diverged (the state is then unchanged).
    pub fn step(&mut self) -> Result<StepReport, SimError> {
        let h = self.config.physics_step_s;
        let t0 = self.time_s();
        let b = self.base_dof;
        let mut base =
            BaseMotion { pose: [0.0; 3], velocity: [0.0; 3], desired: [0.0; 3], lag_s: self.config.base_lag_s };
        for i in 0..b {
            if let (Some(p), Some(v), Some(d), Some(q), Some(qd), Some(cmd)) = (
                base.pose.get_mut(i),
                base.velocity.get_mut(i),
                base.desired.get_mut(i),
                self.q.get(i),
                self.v.get(i),
                self.base_command.velocity.get(i),
            ) {
                *p = *q;
                *v = *qd;
                *d = *cmd;
            }
        }
        if let (Some(plant), false) = (&self.realistic, self.brakes) {
            plant.follow(&mut self.torque, h);
        }
        let qu0 = self.upper_q();
        let vu0 = if self.brakes { SVector::zeros() } else { self.upper_v() };
        let pushed = self.pushes.iter().any(|p| p.active(t0));

        let (qu, vu) = if self.brakes {
            (qu0, vu0)
        } else {
            let mut stage = |s: f64, qu: &SVector<f64, U>, vu: &SVector<f64, U>| -> Result<SVector<f64, U>, SimError> {
                let (r, rd, rdd) = base.at(s);
                let (q, v) = self.assemble(qu, vu, &r, &rd);
                self.upper_acceleration(t0 + s, &q, &v, &rdd)
            };
            let half = 0.5 * h;
            let a1 = stage(0.0, &qu0, &vu0)?;
            let (q2, v2) = (qu0 + vu0 * half, vu0 + a1 * half);
            let a2 = stage(half, &q2, &v2)?;
            let (q3, v3) = (qu0 + v2 * half, vu0 + a2 * half);
            let a3 = stage(half, &q3, &v3)?;
            let (q4, v4) = (qu0 + v3 * h, vu0 + a3 * h);
            let a4 = stage(h, &q4, &v4)?;
            let sixth = h / 6.0;
            (qu0 + (vu0 + v2 * 2.0 + v3 * 2.0 + v4) * sixth, vu0 + (a1 + a2 * 2.0 + a3 * 2.0 + a4) * sixth)
        };
        if !qu.iter().chain(vu.iter()).all(|x| x.is_finite()) {
            return Err(SimError::Dynamics(DynamicsError::NonFinite { input: "state" }));
        }
        let (r, rd, _) = base.at(h);
        let (q, v) = self.assemble(&qu, &vu, &r, &rd);
        self.q = q;
        self.v = v;
        let (lo, hi) = (self.config.leg_length_min_m, self.config.leg_length_max_m);
        for (leg, rate) in self.legs.iter_mut().zip(self.base_command.leg_rates.iter()) {
            *leg = (*leg + rate * h).clamp(lo, hi);
        }
        self.steps += 1;
        Ok(StepReport { time_s: self.time_s(), torque_saturated: self.torque_saturated, pushed })
    }

    /// Advances by `duration_s` rounded to a whole number (at least one) of physics steps.
    /// Returns the number of steps and whether any of them ran with a clamped torque.
    pub fn advance(&mut self, duration_s: f64) -> Result<(u64, bool), SimError> {
        let n = whole_periods(duration_s, self.config.physics_step_s, 1, "period_s")?;
        let mut saturated = false;
        for _ in 0..n {
            saturated |= self.step()?.torque_saturated;
        }
        Ok((n, saturated))
    }
}

/// Number of whole `period_s` in `duration_s`, rounded to nearest, at least `minimum`.
/// `field` names the configuration value blamed when the ratio is not finite or below
/// `minimum − ½`.
fn whole_periods(duration_s: f64, period_s: f64, minimum: u64, field: &'static str) -> Result<u64, SimError> {
    let ratio = duration_s / period_s;
    #[allow(clippy::cast_precision_loss, reason = "minimum is 0 or 1")]
    let lowest = minimum as f64 - 0.5;
    if !ratio.is_finite() || ratio < lowest.max(0.0) {
        return Err(SimError::InvalidConfig { field });
    }
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss, reason = "finite, ≥ 0, rounded")]
    let n = ratio.round() as u64;
    Ok(n.max(minimum))
}

fn validate(c: &SimConfig) -> Result<(), SimError> {
    let bad = |field| Err(SimError::InvalidConfig { field });
    if !(c.physics_step_s > 0.0 && c.physics_step_s.is_finite()) {
        return bad("physics_step_s");
    }
    if !(c.base_lag_s >= 0.0 && c.base_lag_s.is_finite()) {
        return bad("base_lag_s");
    }
    if !(c.leg_length_min_m.is_finite() && c.leg_length_max_m.is_finite() && c.leg_length_min_m <= c.leg_length_max_m) {
        return bad("leg_length_min_m/leg_length_max_m");
    }
    if !(c.initial_leg_length_m >= c.leg_length_min_m && c.initial_leg_length_m <= c.leg_length_max_m) {
        return bad("initial_leg_length_m");
    }
    Ok(())
}

/// Rows `b..b+U` of a coordinate vector.
fn upper<const N: usize, const U: usize>(x: &SVector<f64, N>, b: usize) -> SVector<f64, U> {
    x.fixed_rows::<U>(b).into_owned()
}

impl<const N: usize, const B: usize, const F: usize, const U: usize> ErrorType for Simulator<N, B, F, U> {
    type Error = SimError;
}

/// The upper body: coordinates `base_dof..N` of the model, in model order.
///
/// - `read` never fails. `cycle` is the number of physics steps taken (a new sensor frame every
///   physics step); `torque` is the applied (clamped) torque.
/// - `write_torque` clamps each entry to `±effort` of the model's limits (reported by
///   [`Simulator::torque_saturated`]). A non-finite entry is refused with
///   [`SimError::NonFinite`] (kind `OutOfRange`) and engages the **brakes**: the upper body is
///   held at rest (`q̇_u = 0`) with zero torque until the next valid command releases them.
impl<const N: usize, const B: usize, const F: usize, const U: usize> JointTorqueInterface<f64, U>
    for Simulator<N, B, F, U>
{
    /// The joint sensors; with the realistic plant this starts a control cycle (the command
    /// of the last cycle becomes the torque set point) and the readings are noisy.
    fn read(&mut self) -> Result<JointSample<f64, U>, SimError> {
        let (q, v) = (self.upper_q(), if self.brakes { SVector::zeros() } else { self.upper_v() });
        let (position, velocity, torque) = match &mut self.realistic {
            Some(plant) => {
                plant.next_cycle();
                let velocity = if self.brakes { v } else { plant.sense_velocity(&v) };
                (plant.sense_position(&q), velocity, plant.sense_torque(&self.torque))
            }
            None => (q, v, self.torque),
        };
        Ok(JointSample {
            position: position.into(),
            velocity: velocity.into(),
            torque: torque.into(),
            cycle: self.steps,
        })
    }

    fn write_torque(&mut self, torque: &[f64; U]) -> Result<(), SimError> {
        if !torque.iter().all(|x| x.is_finite()) {
            self.brakes = true;
            self.torque = SVector::zeros();
            if let Some(plant) = &mut self.realistic {
                plant.stop();
            }
            self.torque_saturated = false;
            self.v.fixed_rows_mut::<U>(self.base_dof).fill(0.0);
            return Err(SimError::NonFinite { what: "torque command" });
        }
        let limits: SVector<f64, U> = upper(&self.model.limits.effort, self.base_dof);
        let mut clamped = SVector::<f64, U>::zeros();
        let mut saturated = false;
        for ((slot, commanded), limit) in clamped.iter_mut().zip(torque.iter()).zip(limits.iter()) {
            *slot = commanded.clamp(-limit, *limit);
            saturated |= *slot != *commanded;
        }
        match &mut self.realistic {
            Some(plant) => plant.command(&clamped),
            None => self.torque = clamped,
        }
        self.torque_saturated = saturated;
        self.brakes = false;
        Ok(())
    }
}

/// The mobile base: coordinates `0..3` (`x`, `y`, `θ`, world frame) and the four legs.
///
/// - `read` never fails; a fixed-base robot reads a zero pose and velocity. `cycle` counts
///   physics steps.
/// - `write_velocity` sets `ṙ_des`, tracked with the configured first-order lag, and the leg
///   rates (legs stop at their end stops). A non-finite entry is refused with
///   [`SimError::NonFinite`] and the base **stops**: `ṙ_des = 0`, leg rates 0 (with a lag the
///   base decelerates with the lag). A non-zero velocity for a fixed-base robot is refused
///   with [`SimError::FixedBase`] and the previous command stays in force.
impl<const N: usize, const B: usize, const F: usize, const U: usize> PlatformVelocityInterface<f64>
    for Simulator<N, B, F, U>
{
    fn read(&mut self) -> Result<PlatformSample<f64>, SimError> {
        let mut pose = [0.0; 3];
        let mut velocity = [0.0; 3];
        for (i, (p, v)) in pose.iter_mut().zip(velocity.iter_mut()).enumerate().take(self.base_dof) {
            *p = self.q.get(i).copied().unwrap_or(0.0);
            *v = self.v.get(i).copied().unwrap_or(0.0);
        }
        Ok(PlatformSample { pose, velocity, leg_lengths: self.legs, cycle: self.steps })
    }

    fn write_velocity(&mut self, command: &PlatformCommand<f64>) -> Result<(), SimError> {
        if !command.velocity.iter().chain(command.leg_rates.iter()).all(|x| x.is_finite()) {
            self.base_command = PlatformCommand { velocity: [0.0; 3], leg_rates: [0.0; LEGS] };
            return Err(SimError::NonFinite { what: "platform command" });
        }
        if self.base_dof == 0 && command.velocity.iter().any(|v| *v != 0.0) {
            return Err(SimError::FixedBase);
        }
        self.base_command = *command;
        Ok(())
    }
}

/// Simulated time in microseconds ([`CLOCK_TICKS_PER_SECOND`]), rounded to the nearest µs;
/// it advances only with the physics, never with wall-clock time.
impl<const N: usize, const B: usize, const F: usize, const U: usize> CycleClock for Simulator<N, B, F, U> {
    fn now(&mut self) -> Result<u64, SimError> {
        let micros = (self.time_s() * f64::from(CLOCK_TICKS_PER_SECOND)).round();
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss, reason = "time is ≥ 0 and far below 2^64 µs")]
        Ok(micros as u64)
    }

    fn ticks_per_second(&self) -> u32 {
        CLOCK_TICKS_PER_SECOND
    }
}

/// One control instant of [`run_loop`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CycleInfo {
    /// Control cycle index (0, 1, …).
    pub cycle: u64,
    /// Simulated time of the controller call (s).
    pub time_s: f64,
}

/// Totals of one [`run_loop`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoopReport {
    /// Controller calls.
    pub control_cycles: u64,
    /// Physics steps.
    pub physics_steps: u64,
    /// Physics steps run with a clamped torque.
    pub saturated_steps: u64,
}

/// What [`run_loop`] drives: a simulated robot whose physics advances in fixed steps between
/// control cycles (a [`Simulator`], or a rig that owns one, such as [`crate::wbc::Rig`]).
pub trait Physics {
    /// Simulated time (s).
    fn time_s(&self) -> f64;
    /// The physics step (s).
    fn physics_step_s(&self) -> f64;
    /// Advances the physics by one step.
    fn step_physics(&mut self) -> Result<StepReport, SimError>;
}

impl<const N: usize, const B: usize, const F: usize, const U: usize> Physics for Simulator<N, B, F, U> {
    fn time_s(&self) -> f64 {
        Simulator::time_s(self)
    }

    fn physics_step_s(&self) -> f64 {
        self.config.physics_step_s
    }

    fn step_physics(&mut self) -> Result<StepReport, SimError> {
        self.step()
    }
}

/// The scenarios' errors are one-line messages; a simulator error becomes its message.
impl From<SimError> for String {
    fn from(e: SimError) -> Self {
        e.to_string()
    }
}

/// The scenario loop: runs a controller in the loop for `duration_s` of simulated time.
///
/// Every `control_period_s` (rounded to a whole number of physics steps; 1 ms = 6 steps by
/// default) `cycle(robot, &info)` is called once: it runs the controller (read the sensors,
/// compute, write the commands through the `hal` traits), records whatever the scenario logs
/// (the state at the call and the command just written) and applies the scenario's events
/// (goals, pushes). Then the physics advances to the next call with the commands held
/// (zero-order hold).
///
/// Errors: the first error of `cycle` or of the physics; the loop stops there. The error type
/// is the scenario's: a message (`String`, what most scenarios use) or any type a [`SimError`]
/// converts into (e.g. one that tells an intended early stop from a failure).
pub fn run_loop<P, C, E>(robot: &mut P, duration_s: f64, control_period_s: f64, mut cycle: C) -> Result<LoopReport, E>
where
    P: Physics,
    C: FnMut(&mut P, &CycleInfo) -> Result<(), E>,
    E: From<SimError>,
{
    let step_s = robot.physics_step_s();
    let substeps = whole_periods(control_period_s, step_s, 1, "period_s")?;
    #[allow(clippy::cast_precision_loss, reason = "a handful of substeps")]
    let period = step_s * substeps as f64;
    let cycles = whole_periods(duration_s, period, 0, "duration_s")?;
    let mut report = LoopReport { control_cycles: 0, physics_steps: 0, saturated_steps: 0 };
    for index in 0..cycles {
        cycle(robot, &CycleInfo { cycle: index, time_s: robot.time_s() })?;
        for _ in 0..substeps {
            let step = robot.step_physics()?;
            report.physics_steps += 1;
            report.saturated_steps += u64::from(step.torque_saturated);
        }
        report.control_cycles += 1;
    }
    Ok(report)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "test code: failures should panic")]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn floor() -> Surface {
        Surface {
            frame: fixtures::justin::RIGHT_TCP,
            point: Vector3::new(0.0, 0.0, 0.5),
            normal: Unit::new_normalize(Vector3::z()),
            stiffness_n_m: 1.0e4,
            damping_ns_m: 100.0,
            friction: 0.5,
        }
    }

    #[test]
    fn surface_force_is_spring_plus_damper_and_only_pushes() {
        let s = floor();
        // Above the surface: no force.
        let free = s.contact(&Vector3::new(0.0, 0.0, 0.6), &Vector3::new(0.0, 0.0, -1.0));
        assert_eq!(free.normal_force_n, 0.0);
        assert_eq!(free.force_world, Vector3::zeros());
        // 1 mm deep, moving down at 0.02 m/s: 10 N + 2 N along the normal.
        let c = s.contact(&Vector3::new(0.0, 0.0, 0.499), &Vector3::new(0.0, 0.0, -0.02));
        assert!((c.penetration_m - 1e-3).abs() < 1e-12);
        assert!((c.normal_force_n - 12.0).abs() < 1e-9);
        assert!((c.force_world - Vector3::new(0.0, 0.0, 12.0)).norm() < 1e-9);
        // Leaving fast: the damper would pull, the force is clipped to zero.
        let leaving = s.contact(&Vector3::new(0.0, 0.0, 0.499), &Vector3::new(0.0, 0.0, 1.0));
        assert_eq!(leaving.normal_force_n, 0.0);
        // Sliding along x at 1 m/s (≫ v_ε): friction ≈ μ F_n against the motion.
        let sliding = s.contact(&Vector3::new(0.0, 0.0, 0.499), &Vector3::new(1.0, 0.0, 0.0));
        assert!((sliding.normal_force_n - 10.0).abs() < 1e-9);
        assert!((sliding.force_world.x + 5.0).abs() < 1e-3 && sliding.force_world.x < 0.0);
    }

    #[test]
    fn simulator_reads_and_applies_the_surface_force() {
        let model = fixtures::justin::model::<f64>().unwrap();
        let mut sim: Simulator<
            { fixtures::justin::N },
            { fixtures::justin::BODIES },
            { fixtures::justin::FRAMES },
            { fixtures::justin::UPPER_DOF },
        > = Simulator::new(model, SimConfig::default()).unwrap();
        sim.set_state(fixtures::justin::home_configuration(), SVector::zeros()).unwrap();
        let tcp = sim.frame_placement(fixtures::justin::RIGHT_TCP).unwrap().translation.vector;
        // A floor 2 mm above the TCP: 20 N upwards at rest.
        let mut surface = floor();
        surface.point = tcp + Vector3::new(0.0, 0.0, 0.002);
        surface.friction = 0.0;
        let index = sim.add_surface(surface).unwrap();
        assert_eq!(sim.surfaces().len(), 1);
        let contact = sim.surface_force(index).unwrap().unwrap();
        assert!((contact.normal_force_n - 20.0).abs() < 1e-9, "{contact:?}");
        assert!(sim.surface_force(7).unwrap().is_none());
        // Over one step it acts like a push of 20 N upwards (up to the motion within the step).
        let mut free = sim.clone();
        free.surfaces.clear();
        let mut pushed = free.clone();
        pushed.push(fixtures::justin::RIGHT_TCP, Vector3::new(0.0, 0.0, 20.0), 0.0, 1.0).unwrap();
        sim.step().unwrap();
        pushed.step().unwrap();
        free.step().unwrap();
        let by_push = pushed.upper_v() - free.upper_v();
        let by_surface = sim.upper_v() - free.upper_v();
        assert!(by_push.norm() > 1e-4);
        assert!((by_surface - by_push).norm() < 0.01 * by_push.norm(), "{by_surface} vs {by_push}");
        // Invalid surfaces are refused.
        let mut bad = floor();
        bad.stiffness_n_m = 0.0;
        assert!(sim.add_surface(bad).is_err());
        bad = floor();
        bad.damping_ns_m = f64::NAN;
        assert!(sim.add_surface(bad).is_err());
    }
}
