//! The whole-body impedance with an admittance-controlled platform of Sec. 5.1 (Fig. 5.4), run
//! in the loop by the `mobile_impedance` scenarios.
//!
//! Per control cycle, with `y = (r, q)` (5.7) assembled from the joint and platform samples:
//! 1. **Impedance** (5.9)–(5.10): the kernel's Cartesian impedance task
//!    ([`kernel::tasks::cartesian_impedance`]) at the TCP gives the spring force `−K x̃` per
//!    axis and, through its double-diagonalisation damping for the robot's inertia `M(q)`,
//!    `D_qq` (Table 5.2: `D_qq = D(M(q), K_tra, K_rot, ξ = 0.7)`). The task is evaluated on a
//!    copy of the dynamics data whose platform velocities are zero, so the damping acts on `q̇`
//!    only ((5.11): "Damping is not applied to the platform subsystem"): `D_qq = J_qᵀ D_x J_q`.
//! 2. **Platform** (5.12): the platform rows of `τ_imp = −J_yᵀ K x̃` are the virtual forces
//!    `τ_r,vir` of the admittance (5.1) ([`kernel::platform::admittance`]), which yields the
//!    command `ṙ_des` and `r̈` (5.15). The platform has no force sensors: `τ_r,ext = 0`.
//! 3. **Upper body** (5.13): `τ_q = τ_imp,q + τ_damp,q + τ_posture + τ_comp`, with the coupling
//!    compensation (5.14) ([`kernel::platform::coupling_compensation`]) switched by
//!    [`CompensationSwitch`], and a weak joint impedance towards a posture (plus its damping),
//!    which makes `D_qq` positive definite on the whole upper body ("Redundant Robot with Null
//!    Space Damping", Sec. 5.1.3) and holds the arm that is not in the chain.
//! 4. **Telemetry**: the storage function (5.21) with the closed-loop inertia, its rate (5.22)
//!    predicted from the damping, and the passivity monitor
//!    ([`kernel::platform::storage::PassivityMonitor`]) fed with the power the moving desired pose
//!    supplies, `−(K x̃)ᵀ ẋ_des`.
//!
//! The torque is clamped to the effort limits before it is written. If the state cannot be
//! processed, the step writes the safe output (the last valid gravity torque, zero platform
//! velocity) and reports the fault.

use core::fmt;

use hal::{JointSample, JointTorqueInterface, PlatformCommand, PlatformSample, PlatformVelocityInterface, LEGS};
use kernel::dynamics::{coriolis_matrix, crba, forward_kinematics, gravity, DynamicsError};
use kernel::math::guarded_divide;
use kernel::model::{Data, FrameId, Model, Placement};
use kernel::platform::admittance::{Admittance, AdmittanceConfig};
use kernel::platform::coupling_compensation::{coupling_compensation, CompensationSwitch};
use kernel::platform::storage::{
    closed_loop_inertia, storage_function, storage_rate, PassivityMonitor, PassivityMonitorConfig, PassivityReport,
    Storage,
};
use kernel::platform::{PlatformError, PlatformLayout};
use kernel::tasks::cartesian_impedance::{
    cartesian_impedance, AxisMask, CartesianImpedance, CartesianImpedanceConfig, CartesianTarget, StiffnessFrame,
};
use kernel::tasks::{TaskError, TaskRows};
use nalgebra::{Matrix3, SVector, Vector3, Vector6};

/// Number of base coordinates of the simulated models (`x`, `y`, `θ` first).
const BASE: usize = 3;

/// Settings of [`MobileImpedance`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MobileImpedanceSettings<const U: usize> {
    /// The controlled frame (TCP).
    pub tcp: FrameId,
    /// Platform coordinates `0, 1, 2` and which of them the admittance drives.
    pub layout: PlatformLayout,
    /// The admittance (5.1)–(5.5); its `free_axes` must agree with `layout`.
    pub admittance: AdmittanceConfig<f64>,
    /// `K_tra` (N/m), world axes.
    pub translational_stiffness: Matrix3<f64>,
    /// `K_rot` (Nm/rad), world axes.
    pub rotational_stiffness: Matrix3<f64>,
    /// `ξ` of the double-diagonalisation damping (Table 5.2: 0.7).
    pub damping_ratio: f64,
    /// Posture `q_0` of the joint impedance (upper-body coordinates).
    pub posture: SVector<f64, U>,
    /// Joint stiffness towards the posture (Nm/rad), per upper-body joint.
    pub posture_stiffness: SVector<f64, U>,
    /// Joint damping (Nms/rad), per upper-body joint.
    pub posture_damping: SVector<f64, U>,
    /// Which parts of (5.14) to apply.
    pub compensation: CompensationSwitch,
    /// Tolerance of the passivity monitor (J).
    pub passivity_tolerance_j: f64,
}

/// Why [`MobileImpedance::new`] refused its settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MobileSetupError {
    /// The model is not `3 + U` coordinates.
    Dimensions,
    /// A kernel component refused its parameters.
    Platform(PlatformError),
    /// The Cartesian task refused its parameters.
    Task(TaskError),
    /// The posture gains are negative or not finite, or the admittance axes disagree with the
    /// layout.
    Settings,
}

impl fmt::Display for MobileSetupError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Dimensions => f.write_str("model coordinates are not 3 base coordinates plus the upper body"),
            Self::Platform(e) => write!(f, "platform: {e}"),
            Self::Task(e) => write!(f, "Cartesian task: {e}"),
            Self::Settings => f.write_str("invalid posture gains or admittance axes"),
        }
    }
}

impl std::error::Error for MobileSetupError {}

/// Why a step fell back to the safe output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MobileFault {
    /// The dynamics refused the state.
    Dynamics(DynamicsError),
    /// The Cartesian task failed.
    Task(TaskError),
    /// A platform component refused its input.
    Platform(PlatformError),
}

/// What the controller computed in its last step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MobileTelemetry<const U: usize> {
    /// TCP error `x̃ = (p − p_des, 2ε)` (m, rad-like), world axes.
    pub error: Vector6<f64>,
    /// Storage function (5.21), including the posture spring in its potential.
    pub storage: Storage<f64>,
    /// `V_imp` (5.9) of the TCP spring alone (J).
    pub impedance_potential: f64,
    /// `V̇` predicted by (5.22) plus the supplied power (W).
    pub predicted_rate_w: f64,
    /// Power supplied by the moving desired pose, `−(K x̃)ᵀ ẋ_des` (W).
    pub supplied_power_w: f64,
    /// The passivity monitor.
    pub passivity: PassivityReport<f64>,
    /// `τ_r,vir` (N, N, Nm).
    pub virtual_force: Vector3<f64>,
    /// Commanded `ṙ_des` (m/s, m/s, rad/s).
    pub base_velocity: Vector3<f64>,
    /// `r̈` of the admittance (5.15).
    pub base_acceleration: Vector3<f64>,
    /// Applied compensation torque (upper body).
    pub compensation: SVector<f64, U>,
    /// Coupling part `M_qr r̈ + C_qr ṙ` of (5.14), applied or not (upper body).
    pub coupling: SVector<f64, U>,
    /// Torque written (clamped), upper body.
    pub torque: SVector<f64, U>,
    /// Largest `|τ_i| / τ_max,i` before clamping.
    pub torque_ratio: f64,
    /// `true` if the Cartesian damping fell back to its diagonal.
    pub damping_fallback: bool,
    /// `Some` if the step wrote the safe output.
    pub fault: Option<MobileFault>,
}

/// The mobile whole-body impedance of Sec. 5.1 (see the module docs).
#[derive(Clone, Debug)]
pub struct MobileImpedance<const N: usize, const B: usize, const F: usize, const U: usize> {
    model: Model<f64, N, B, F>,
    data: Data<f64, N, B, F>,
    task_data: Data<f64, N, B, F>,
    task: CartesianImpedance<f64>,
    settings: MobileImpedanceSettings<U>,
    admittance: Admittance<f64>,
    monitor: PassivityMonitor<f64>,
    target: CartesianTarget<f64>,
    effort: SVector<f64, U>,
    safe_torque: SVector<f64, U>,
    period_s: f64,
    telemetry: MobileTelemetry<U>,
}

impl<const N: usize, const B: usize, const F: usize, const U: usize> MobileImpedance<N, B, F, U> {
    /// A controller for `model` holding the TCP at `target`, stepping every `period_s`.
    pub fn new(
        model: Model<f64, N, B, F>,
        settings: MobileImpedanceSettings<U>,
        target: Placement<f64>,
        period_s: f64,
    ) -> Result<Self, MobileSetupError> {
        if N != U + BASE {
            return Err(MobileSetupError::Dimensions);
        }
        let gains_ok = settings
            .posture_stiffness
            .iter()
            .chain(settings.posture_damping.iter())
            .chain(settings.posture.iter())
            .all(|x| x.is_finite())
            && settings.posture_stiffness.iter().chain(settings.posture_damping.iter()).all(|x| *x >= 0.0)
            && settings.layout.admitted_axes() == settings.admittance.free_axes
            && period_s > 0.0;
        if !gains_ok {
            return Err(MobileSetupError::Settings);
        }
        let task = CartesianImpedance::try_new(CartesianImpedanceConfig {
            frame: settings.tcp,
            axes: AxisMask::ALL,
            stiffness_frame: StiffnessFrame::World,
            translational_stiffness: settings.translational_stiffness,
            rotational_stiffness: settings.rotational_stiffness,
            damping_ratio: settings.damping_ratio,
            force_lower: Vector6::repeat(f64::NEG_INFINITY),
            force_upper: Vector6::repeat(f64::INFINITY),
            // Used only if the design fails (singular arm): 2ξ√(k · 5 kg) per axis.
            fallback_damping: Vector6::new(100.0, 100.0, 100.0, 10.0, 10.0, 10.0),
        })
        .map_err(MobileSetupError::Task)?;
        let admittance = Admittance::try_new(settings.admittance).map_err(MobileSetupError::Platform)?;
        let monitor = PassivityMonitor::try_new(PassivityMonitorConfig { tolerance: settings.passivity_tolerance_j })
            .map_err(MobileSetupError::Platform)?;
        let effort = model.limits.effort.fixed_rows::<U>(BASE).into_owned();
        let data = Data::new(&model);
        Ok(Self {
            task_data: data.clone(),
            data,
            model,
            task,
            settings,
            admittance,
            monitor,
            target: CartesianTarget::at_rest(target),
            effort,
            safe_torque: SVector::zeros(),
            period_s,
            telemetry: MobileTelemetry {
                error: Vector6::zeros(),
                storage: Storage { kinetic: 0.0, potential: 0.0, total: 0.0 },
                impedance_potential: 0.0,
                predicted_rate_w: 0.0,
                supplied_power_w: 0.0,
                passivity: PassivityReport { rate: 0.0, excess: 0.0, growth: 0.0, violated: false, latched: false },
                virtual_force: Vector3::zeros(),
                base_velocity: Vector3::zeros(),
                base_acceleration: Vector3::zeros(),
                compensation: SVector::zeros(),
                coupling: SVector::zeros(),
                torque: SVector::zeros(),
                torque_ratio: 0.0,
                damping_fallback: false,
                fault: None,
            },
        })
    }

    /// Sets the desired TCP pose and its linear velocity `ẋ_des` (world, m/s). The damping acts
    /// on `q̇` only (5.11); the velocity enters the supplied power of the passivity monitor.
    pub fn set_target(&mut self, pose: Placement<f64>, linear_velocity: Vector3<f64>) {
        self.target = CartesianTarget { pose, linear_velocity, angular_velocity: Vector3::zeros() };
    }

    /// The settings.
    pub fn settings(&self) -> &MobileImpedanceSettings<U> {
        &self.settings
    }

    /// What the last step computed.
    pub fn telemetry(&self) -> &MobileTelemetry<U> {
        &self.telemetry
    }

    /// One control cycle through the `hal` traits. Errors are those of the interfaces.
    pub fn step<R>(&mut self, robot: &mut R) -> Result<&MobileTelemetry<U>, R::Error>
    where
        R: JointTorqueInterface<f64, U> + PlatformVelocityInterface<f64>,
    {
        let joints = JointTorqueInterface::read(robot)?;
        let base = PlatformVelocityInterface::read(robot)?;
        let (torque, velocity) = match self.compute(&joints, &base) {
            Ok(command) => {
                self.telemetry.fault = None;
                command
            }
            Err(fault) => {
                self.telemetry.fault = Some(fault);
                (self.safe_torque, Vector3::zeros())
            }
        };
        self.telemetry.torque = torque;
        robot.write_torque(&torque.into())?;
        robot.write_velocity(&PlatformCommand { velocity: velocity.into(), leg_rates: [0.0; LEGS] })?;
        Ok(&self.telemetry)
    }

    fn compute(
        &mut self,
        joints: &JointSample<f64, U>,
        base: &PlatformSample<f64>,
    ) -> Result<(SVector<f64, U>, Vector3<f64>), MobileFault> {
        let mut q = SVector::<f64, N>::zeros();
        let mut v = SVector::<f64, N>::zeros();
        for (i, (p, r)) in base.pose.iter().zip(base.velocity.iter()).enumerate() {
            if let (Some(qi), Some(vi)) = (q.get_mut(i), v.get_mut(i)) {
                *qi = *p;
                *vi = *r;
            }
        }
        let qu = SVector::<f64, U>::from(joints.position);
        let vu = SVector::<f64, U>::from(joints.velocity);
        q.fixed_rows_mut::<U>(BASE).copy_from(&qu);
        v.fixed_rows_mut::<U>(BASE).copy_from(&vu);
        let layout = self.settings.layout;
        // ẏ: locked axes are not part of y.
        for (axis, free) in layout.axes().iter().zip(layout.admitted_axes()) {
            if let (Some(c), false) = (axis.coordinate(), free) {
                if let Some(x) = v.get_mut(c) {
                    *x = 0.0;
                }
            }
        }

        let (model, data) = (&self.model, &mut self.data);
        forward_kinematics(model, data, &q, &v).map_err(MobileFault::Dynamics)?;
        crba(model, data);
        coriolis_matrix(model, data);
        gravity(model, data);
        let m_closed = closed_loop_inertia(&data.mass_matrix, &layout, &self.settings.admittance.mass);

        // (1) The impedance with the platform at rest: damping on q̇ only (5.11).
        let task_data = &mut self.task_data;
        task_data.clone_from(data);
        task_data.v.fixed_rows_mut::<BASE>(0).fill(0.0);
        let mut rows = TaskRows::<f64, N, 6>::new();
        let at_rest = CartesianTarget::at_rest(self.target.pose);
        let report =
            cartesian_impedance(model, task_data, &self.task, &at_rest, &mut rows).map_err(MobileFault::Task)?;
        let spring = self.task.stiffness() * report.error;
        let mut tau_task = SVector::<f64, N>::zeros();
        let mut tau_spring = SVector::<f64, N>::zeros();
        for (row, k) in rows.rows().iter().zip(spring.iter()) {
            tau_task += row.jacobian.transpose() * row.force;
            tau_spring -= row.jacobian.transpose() * *k;
        }

        // (2) The platform rows drive the admittance (5.1), (5.12); no force sensors.
        let mut virtual_force = Vector3::zeros();
        for (axis, f) in layout.axes().iter().zip(virtual_force.iter_mut()) {
            if let Some(c) = axis.coordinate().filter(|_| axis.is_admitted()) {
                *f = tau_spring.get(c).copied().unwrap_or(0.0);
            }
        }
        let admittance =
            self.admittance.step(&virtual_force, &Vector3::zeros(), self.period_s).map_err(MobileFault::Platform)?;

        // (3) Upper body: impedance, damping, posture and compensation (5.13)–(5.14).
        let terms = coupling_compensation(data, &layout, &admittance.acceleration).map_err(MobileFault::Platform)?;
        let compensation = terms.torque(self.settings.compensation).fixed_rows::<U>(BASE).into_owned();
        let coupling = (terms.inertia + terms.coriolis).fixed_rows::<U>(BASE).into_owned();
        let s = &self.settings;
        let posture_error = qu - s.posture;
        let posture_torque = -posture_error.component_mul(&s.posture_stiffness) - vu.component_mul(&s.posture_damping);
        let desired = tau_task.fixed_rows::<U>(BASE) + posture_torque + compensation;
        if !desired.iter().all(|x| x.is_finite()) {
            return Err(MobileFault::Dynamics(DynamicsError::NonFinite { input: "torque" }));
        }

        // (4) Storage (5.21), its predicted rate (5.22) and the monitor.
        let posture_potential = 0.5 * posture_error.component_mul(&posture_error).dot(&s.posture_stiffness);
        let impedance_potential = rows.potential();
        let storage =
            storage_function(&m_closed, &v, impedance_potential + posture_potential).map_err(MobileFault::Platform)?;
        let mut damping_torque = SVector::<f64, N>::zeros();
        damping_torque
            .fixed_rows_mut::<U>(BASE)
            .copy_from(&(-(tau_task - tau_spring).fixed_rows::<U>(BASE) + vu.component_mul(&s.posture_damping)));
        for ((axis, d), rate) in layout.axes().iter().zip(s.admittance.damping.iter()).zip(base.velocity.iter()) {
            if let (Some(c), true) = (axis.coordinate(), axis.is_admitted()) {
                if let Some(x) = damping_torque.get_mut(c) {
                    *x = d * rate;
                }
            }
        }
        let supplied = -spring.fixed_rows::<3>(0).dot(&self.target.linear_velocity);
        let predicted = storage_rate(&v, &damping_torque, &SVector::zeros()) + supplied;
        let passivity = self.monitor.update(storage.total, supplied, self.period_s).map_err(MobileFault::Platform)?;

        let mut ratio: f64 = 0.0;
        let mut torque = desired;
        for (t, limit) in torque.iter_mut().zip(self.effort.iter()) {
            if let Some(r) = guarded_divide(t.abs(), *limit, 0.0) {
                ratio = ratio.max(r);
            }
            *t = t.clamp(-limit, *limit);
        }
        self.safe_torque = terms.gravity.fixed_rows::<U>(BASE).zip_map(&self.effort, |g, l| g.clamp(-l, l));
        let t = &mut self.telemetry;
        t.error = report.error;
        t.storage = storage;
        t.impedance_potential = impedance_potential;
        t.predicted_rate_w = predicted;
        t.supplied_power_w = supplied;
        t.passivity = passivity;
        t.virtual_force = virtual_force;
        t.base_velocity = admittance.velocity;
        t.base_acceleration = admittance.acceleration;
        t.compensation = compensation;
        t.coupling = coupling;
        t.torque_ratio = ratio;
        t.damping_fallback = report.damping_fallback.is_some();
        Ok((torque, admittance.velocity))
    }
}
