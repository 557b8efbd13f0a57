//! Controllers run in the loop by the scenarios.
//!
//! [`CartesianJointImpedance`] is the foundation's **loop-proving controller**: a classical
//! Cartesian impedance at one frame (the TCP) plus a weak joint impedance, with gravity
//! compensation, the scheme of Sec. 2.2.1 of the thesis. It exists to show that the
//! read → compute (kernel) → write loop through the `hal` traits works end to end; the
//! thesis' prioritised task stack (null space projections, Ch. 4–5) replaces it later.
//!
//! It talks to the robot only through [`hal::JointTorqueInterface`] and
//! [`hal::PlatformVelocityInterface`], computes with the kernel on its own [`Model`]/[`Data`]
//! copy and allocates nothing in [`CartesianJointImpedance::step`], so the same code could
//! drive real hardware.

use core::fmt;

use hal::{JointSample, JointTorqueInterface, PlatformCommand, PlatformSample, PlatformVelocityInterface, LEGS};
use kernel::dynamics::{crba, forward_kinematics, frame_jacobian, gravity, DynamicsError};
use kernel::math::guarded_divide;
use kernel::model::{Data, FrameId, Model, Placement};
use nalgebra::{Cholesky, SMatrix, SVector, Vector3, Vector6};

/// Gains of [`CartesianJointImpedance`]. Defaults are in [`CartesianJointGains::default`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CartesianJointGains {
    /// Translational stiffness `K_x` along world x, y, z (N/m).
    pub translational_stiffness: Vector3<f64>,
    /// Rotational stiffness about world x, y, z (Nm/rad).
    pub rotational_stiffness: Vector3<f64>,
    /// Damping ratio `ζ` of every Cartesian axis (dimensionless, > 0).
    pub damping_ratio: f64,
    /// Joint stiffness `K_q` towards the rest configuration (Nm/rad), same for every joint.
    pub joint_stiffness: f64,
    /// Joint damping `D_q` (Nm s/rad), same for every joint.
    pub joint_damping: f64,
}

impl Default for CartesianJointGains {
    /// The translational stiffness and the damping ratio of the thesis' arm experiment
    /// (Table 5.6, level 1: `K₁ = diag(1200, 1200, 1200)` N/m, `ξ₁ = 0.9`); a rotational
    /// stiffness of 100 Nm/rad (Table 5.6 uses 30 Nm/rad on a lower priority level; here the
    /// orientation shares the level with the position and is held tighter); a weak joint
    /// stiffness `K_q = 2` Nm/rad (Table 5.6 level 3 uses 10 Nm/rad inside a null space; here it
    /// is not projected, so it must be weak to leave the TCP error small) and
    /// `D_q = 3` Nm s/rad (Table 5.6, `D₃`).
    fn default() -> Self {
        Self {
            translational_stiffness: Vector3::repeat(1200.0),
            rotational_stiffness: Vector3::repeat(100.0),
            damping_ratio: 0.9,
            joint_stiffness: 2.0,
            joint_damping: 3.0,
        }
    }
}

/// Why [`CartesianJointImpedance::new`] refused its settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControllerError {
    /// The model's `N` is not `U` or `U + 3`.
    InvalidDimensions,
    /// The TCP frame is not in the model.
    UnknownFrame,
    /// A gain is negative, NaN, or the damping ratio is not positive.
    InvalidGains,
    /// The rest configuration or the target is not finite.
    NonFinite,
}

impl fmt::Display for ControllerError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::InvalidDimensions => "model coordinates are not 0 or 3 base coordinates plus the upper body",
            Self::UnknownFrame => "unknown TCP frame",
            Self::InvalidGains => "gains must be finite and non-negative, the damping ratio positive",
            Self::NonFinite => "rest configuration or target not finite",
        })
    }
}

impl std::error::Error for ControllerError {}

/// Why one step fell back to the safe output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControllerFault {
    /// A kernel algorithm refused the sensor data (non-finite state).
    Dynamics(DynamicsError),
    /// The upper-body mass matrix failed its Cholesky factorization.
    MassMatrix,
}

/// What the controller computed in its last step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CartesianTelemetry<const U: usize> {
    /// Sensor cycle of the joint sample the step used.
    pub cycle: u64,
    /// TCP pose error `e_x = (x − x_des; rotation vector of R R_desᵀ)` (m; rad), world frame.
    pub error: Vector6<f64>,
    /// TCP velocity `ẋ = J q̇` (m/s; rad/s), world frame, linear first.
    pub tcp_velocity: Vector6<f64>,
    /// Cartesian damping `D_x` actually used (N s/m; Nm s/rad).
    pub damping: Vector6<f64>,
    /// Torque written (after clamping to the effort limits), Nm.
    pub torque: SVector<f64, U>,
    /// Largest `|τ_i| / τ_max,i` of the torque **before** clamping (> 1 means clamped).
    pub torque_ratio: f64,
    /// `Some` if this step fell back to the safe output.
    pub fault: Option<ControllerFault>,
}

/// Cartesian impedance at one frame plus joint impedance, with gravity compensation:
///
/// `τ_u = g_u(q) − J_uᵀ (K_x e_x + D_x ẋ) − K_q (q_u − q_rest) − D_q q̇_u`
///
/// on the upper-body coordinates `u`, where
/// - `e_x = (p − p_des; φ)` is the 6-D TCP pose error with `φ` the rotation vector
///   (axis · angle) of `R R_desᵀ` (world frame), so `K_x e_x` is the restoring wrench of a
///   spring of stiffness `K_x` (exact for an isotropic rotational stiffness);
/// - `ẋ = J q̇` is the TCP twist (world-aligned, linear first) with the full Jacobian, so
///   motion of the base counts too; `J_u` are its upper-body columns (the torque acts on the
///   upper body only);
/// - `K_x`, `D_x` are diagonal. `D_x,ii = 2 ζ √(K_x,ii Λ_ii)` with the **diagonal
///   approximation** of the reflected mass `Λ_ii = 1 / (J_u M_uu⁻¹ J_uᵀ)_ii` (the mass felt
///   along axis `i` when the other axes are free). The proper damping design by double
///   diagonalisation (\[ASOFH03\], Sec. 3.1.3) arrives with the task stack.
///
/// The base is always commanded to stand still (`ṙ_des = 0`, leg rates 0). The torque is
/// clamped to the model's effort limits before it is written. If the sensor data cannot be
/// processed, the step writes the **safe output**: the last valid gravity torque `g_u`
/// (zero before the first valid step) and reports the fault in the telemetry.
///
/// Cost per step: one forward kinematics, gravity, frame Jacobian, CRBA and a `U×U`
/// Cholesky factorization; no allocation.
#[derive(Clone, Debug)]
pub struct CartesianJointImpedance<const N: usize, const B: usize, const F: usize, const U: usize> {
    model: Model<f64, N, B, F>,
    data: Data<f64, N, B, F>,
    base_dof: usize,
    tcp: FrameId,
    gains: CartesianJointGains,
    stiffness: Vector6<f64>,
    rest: SVector<f64, U>,
    target: Placement<f64>,
    effort: SVector<f64, U>,
    safe_torque: SVector<f64, U>,
    telemetry: CartesianTelemetry<U>,
}

impl<const N: usize, const B: usize, const F: usize, const U: usize> CartesianJointImpedance<N, B, F, U> {
    /// A controller for `model` holding frame `tcp` at `target` (world placement) with the
    /// posture springs pulling towards `rest` (upper-body coordinates).
    ///
    /// Errors: bad dimensions, unknown frame, invalid gains, non-finite rest or target.
    pub fn new(
        model: Model<f64, N, B, F>,
        tcp: FrameId,
        gains: CartesianJointGains,
        rest: SVector<f64, U>,
        target: Placement<f64>,
    ) -> Result<Self, ControllerError> {
        let base_dof = match N.checked_sub(U) {
            Some(b @ (0 | 3)) if U > 0 => b,
            _ => return Err(ControllerError::InvalidDimensions),
        };
        model.frame(tcp).ok_or(ControllerError::UnknownFrame)?;
        let non_negative = |x: f64| x.is_finite() && x >= 0.0;
        let gains_ok =
            gains.translational_stiffness.iter().chain(gains.rotational_stiffness.iter()).all(|k| non_negative(*k))
                && non_negative(gains.joint_stiffness)
                && non_negative(gains.joint_damping)
                && gains.damping_ratio.is_finite()
                && gains.damping_ratio > 0.0;
        if !gains_ok {
            return Err(ControllerError::InvalidGains);
        }
        if !rest.iter().all(|x| x.is_finite()) || !placement_is_finite(&target) {
            return Err(ControllerError::NonFinite);
        }
        let t = gains.translational_stiffness;
        let r = gains.rotational_stiffness;
        let effort = model.limits.effort.fixed_rows::<U>(base_dof).into_owned();
        let data = Data::new(&model);
        Ok(Self {
            model,
            data,
            base_dof,
            tcp,
            gains,
            stiffness: Vector6::new(t.x, t.y, t.z, r.x, r.y, r.z),
            rest,
            target,
            effort,
            safe_torque: SVector::zeros(),
            telemetry: CartesianTelemetry {
                cycle: 0,
                error: Vector6::zeros(),
                tcp_velocity: Vector6::zeros(),
                damping: Vector6::zeros(),
                torque: SVector::zeros(),
                torque_ratio: 0.0,
                fault: None,
            },
        })
    }

    /// Sets the desired TCP placement `x_des` (world frame). Non-finite targets are ignored
    /// and reported as `false`.
    pub fn set_target(&mut self, target: Placement<f64>) -> bool {
        let ok = placement_is_finite(&target);
        if ok {
            self.target = target;
        }
        ok
    }

    /// The desired TCP placement.
    pub fn target(&self) -> &Placement<f64> {
        &self.target
    }

    /// The gains.
    pub fn gains(&self) -> &CartesianJointGains {
        &self.gains
    }

    /// The TCP frame.
    pub fn tcp(&self) -> FrameId {
        self.tcp
    }

    /// What the last step computed.
    pub fn telemetry(&self) -> &CartesianTelemetry<U> {
        &self.telemetry
    }

    /// One control cycle: read the joint and base sensors, compute the torque, write it and a
    /// zero base velocity. Errors are those of the interfaces (the computation itself never
    /// fails: it falls back to the safe output).
    pub fn step<R>(&mut self, robot: &mut R) -> Result<&CartesianTelemetry<U>, R::Error>
    where
        R: JointTorqueInterface<f64, U> + PlatformVelocityInterface<f64>,
    {
        let joints = JointTorqueInterface::read(robot)?;
        let base = PlatformVelocityInterface::read(robot)?;
        self.telemetry.cycle = joints.cycle;
        let torque = match self.compute(&joints, &base) {
            Ok(torque) => {
                self.telemetry.fault = None;
                torque
            }
            Err(fault) => {
                self.telemetry.fault = Some(fault);
                self.telemetry.torque_ratio = 0.0;
                self.safe_torque
            }
        };
        self.telemetry.torque = torque;
        robot.write_torque(&torque.into())?;
        robot.write_velocity(&PlatformCommand { velocity: [0.0; 3], leg_rates: [0.0; LEGS] })?;
        Ok(&self.telemetry)
    }

    /// The control law; returns the clamped torque.
    fn compute(
        &mut self,
        joints: &JointSample<f64, U>,
        base: &PlatformSample<f64>,
    ) -> Result<SVector<f64, U>, ControllerFault> {
        let b = self.base_dof;
        let mut q = SVector::<f64, N>::zeros();
        let mut v = SVector::<f64, N>::zeros();
        for (i, (p, r)) in base.pose.iter().zip(base.velocity.iter()).enumerate().take(b) {
            if let (Some(qi), Some(vi)) = (q.get_mut(i), v.get_mut(i)) {
                *qi = *p;
                *vi = *r;
            }
        }
        let qu = SVector::<f64, U>::from(joints.position);
        let vu = SVector::<f64, U>::from(joints.velocity);
        q.fixed_rows_mut::<U>(b).copy_from(&qu);
        v.fixed_rows_mut::<U>(b).copy_from(&vu);

        let (model, data) = (&self.model, &mut self.data);
        forward_kinematics(model, data, &q, &v).map_err(ControllerFault::Dynamics)?;
        let g_u = gravity(model, data).fixed_rows::<U>(b).into_owned();
        let mut jacobian = SMatrix::<f64, 6, N>::zeros();
        frame_jacobian(model, data, self.tcp, &mut jacobian).map_err(ControllerFault::Dynamics)?;
        let x = data
            .frame_placements
            .get(self.tcp.0)
            .copied()
            .ok_or(ControllerFault::Dynamics(DynamicsError::UnknownFrame))?;
        crba(model, data);
        let m_uu = data.mass_matrix.fixed_view::<U, U>(b, b).into_owned();
        let factor = Cholesky::new(m_uu).ok_or(ControllerFault::MassMatrix)?;

        let j_u: SMatrix<f64, 6, U> = jacobian.fixed_columns::<U>(b).into_owned();
        // Diagonal of the inverse reflected mass J_u M_uu⁻¹ J_uᵀ, one scalar per axis.
        let m_inv_jt = factor.solve(&j_u.transpose());
        let mut damping = Vector6::zeros();
        for (i, (d, k)) in damping.iter_mut().zip(self.stiffness.iter()).enumerate() {
            let inverse_mass = j_u.row(i).dot(&m_inv_jt.column(i).transpose());
            let mass = guarded_divide(1.0, inverse_mass, 1e-12).unwrap_or(0.0);
            *d = 2.0 * self.gains.damping_ratio * (k * mass).max(0.0).sqrt();
        }

        let translation = x.translation.vector - self.target.translation.vector;
        let rotation = (x.rotation * self.target.rotation.inverse()).scaled_axis();
        let error = Vector6::new(translation.x, translation.y, translation.z, rotation.x, rotation.y, rotation.z);
        let tcp_velocity = jacobian * v;
        let wrench = self.stiffness.component_mul(&error) + damping.component_mul(&tcp_velocity);
        let desired = g_u
            - j_u.transpose() * wrench
            - (qu - self.rest) * self.gains.joint_stiffness
            - vu * self.gains.joint_damping;
        if !desired.iter().all(|x| x.is_finite()) {
            return Err(ControllerFault::Dynamics(DynamicsError::NonFinite { input: "torque" }));
        }

        let mut ratio: f64 = 0.0;
        let mut torque = desired;
        for (t, limit) in torque.iter_mut().zip(self.effort.iter()) {
            if let Some(r) = guarded_divide(t.abs(), *limit, 0.0) {
                ratio = ratio.max(r);
            }
            *t = t.clamp(-limit, *limit);
        }
        self.safe_torque = g_u.zip_map(&self.effort, |g, l| g.clamp(-l, l));
        self.telemetry.error = error;
        self.telemetry.tcp_velocity = tcp_velocity;
        self.telemetry.damping = damping;
        self.telemetry.torque_ratio = ratio;
        Ok(torque)
    }
}

fn placement_is_finite(p: &Placement<f64>) -> bool {
    p.rotation.matrix().iter().chain(p.translation.vector.iter()).all(|x| x.is_finite())
}
