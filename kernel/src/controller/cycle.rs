//! The control cycle (module docs of [`super`], "The cycle"): validate the frame, dynamics,
//! contact-force limiter, the stack of every hierarchy entry, projection, platform, upper body,
//! guards, telemetry; or the safe output on a fault.

use nalgebra::{convert, RealField, SVector, Vector3, Vector6};

use hal::{PlatformCommand, LEGS};

use super::capacity::{MAX_ACTIVE, MAX_LEVELS, MAX_TASK_ROWS};
use super::config::{Consistency, TaskKind};
use super::faults::{validate_frame, Fault, SafeOutput};
use super::force_limit::HandLimits;
use super::frames::SensorFrame;
use super::guard::{limit_base_velocity, limit_leg_rates, limit_rate, saturate_with_priority, Saturation};
use super::layout::{ArmId, JointGroup};
use super::settings::ControllerSettings;
use super::speed_barrier::{speed_barrier, BarrierHold, InverseInertia, JointLimits};
use super::state::{ControllerState, InertiaFactors, Workspace};
use super::task_set::{evaluate, row_summary, EvaluationContext, Scratch};
use super::trajectory::{JointTrajectory, PoseTrajectory};
use crate::dynamics::{
    coriolis_transpose_velocity, coriolis_velocity_products, crba, forward_kinematics, gravity, kinematics,
    DynamicsError, KinematicsLevel, TreeFactorization,
};
use crate::hierarchy::{project, HierarchyConfig, Weighting};
use crate::math::sqrt;
use crate::platform::avoidance::PlatformReference;
use crate::platform::coupling_compensation::coupling_compensation_recursive;
use crate::platform::storage::closed_loop_inertia_into;
use crate::tasks::collision::PairRowCache;

/// The platform commands of one cycle, after the guards.
#[derive(Clone, Copy, Debug, PartialEq)]
struct PlatformStep<T> {
    /// `ṙ_des` (m/s, m/s, rad/s).
    velocity: Vector3<T>,
    /// Commanded `r̈` (the change of `ṙ_des` over the period), for (5.14).
    acceleration: Vector3<T>,
    /// `λ̇` (m/s).
    leg_rates: [T; LEGS],
}

/// One cycle's view of the controller: the settings it reads, the state it advances and the
/// workspace it computes in.
pub(super) struct Cycle<
    'a,
    T: RealField,
    const N: usize,
    const B: usize,
    const F: usize,
    const U: usize,
    const V: usize,
    const P: usize,
    const A: usize,
> {
    pub(super) settings: &'a ControllerSettings<T, N, B, F, V, P, A>,
    pub(super) state: &'a mut ControllerState<T, N, U, A>,
    pub(super) work: &'a mut Workspace<T, N, B, F, V, P, A>,
}

impl<
        T: RealField + Copy,
        const N: usize,
        const B: usize,
        const F: usize,
        const U: usize,
        const V: usize,
        const P: usize,
        const A: usize,
    > Cycle<'_, T, N, B, F, U, V, P, A>
{
    /// The model's platform coordinates ahead of the `U` joints: 3, or 0 for a fixed base.
    const PLATFORM_COORDINATES: usize = N - U;
    /// No platform coordinates: the cycle skips the platform-only work (the decoupling of `M̃`'s
    /// factor and the coupling compensation's tree pass), known at compile time.
    const FIXED_BASE: bool = Self::PLATFORM_COORDINATES == 0;

    /// One control cycle: never panics, always writes a checked output (the whole-body torque,
    /// or the safe output of [`super::faults`] with the fault in the telemetry).
    /// `factors` holds the cycle's tree factors (overwritten).
    pub(super) fn step(&mut self, frame: &SensorFrame<T, U>, factors: &mut InertiaFactors<T, N>) {
        self.state.telemetry.cycle = frame.joints.cycle;
        match self.control(frame, factors) {
            Ok(()) => {
                self.state.telemetry.fault = self.state.recovery.output().1;
                self.state.telemetry.fault_cycles = 0;
                self.state.recovery.valid_cycle(&self.settings.config.recovery, self.settings.config.period_s);
            }
            Err(fault) => {
                self.state.recovery.fault(fault);
                self.safe_output(frame, fault);
            }
        }
        if self.state.last_cycle.is_none_or(|last| frame.joints.cycle > last) {
            self.state.last_cycle = Some(frame.joints.cycle);
        }
    }

    fn control(&mut self, frame: &SensorFrame<T, U>, factors: &mut InertiaFactors<T, N>) -> Result<(), Fault> {
        let input_limits =
            self.state.recovery.input_limits(&self.settings.config.input_limits, &self.settings.config.recovery);
        validate_frame(&self.settings.model, &input_limits, frame, Self::PLATFORM_COORDINATES, self.state.last_cycle)?;
        let dt = self.settings.config.period_s;
        let (q, v) = frame.coordinates(Self::PLATFORM_COORDINATES);
        let (model, data) = (&self.settings.model, &mut self.work.data);
        // Everything the step reads; the 6×6 body inertias are not among it.
        kinematics(model, data, &q, KinematicsLevel::Velocities(&v)).map_err(Fault::Dynamics)?;
        crba(model, data);
        gravity(model, data);
        let layout = self.settings.config.layout.platform;
        let closed_loop = &mut self.work.closed_loop;
        closed_loop_inertia_into(
            &data.mass_matrix,
            &layout,
            &self.settings.config.platform.admittance.mass,
            closed_loop,
        );
        let closed_loop = &*closed_loop;
        // The plain `M = Lᵀ L` for the Cartesian damping design, shared by both hands (`None`:
        // not positive definite, the tasks fall back to their configured damping).
        let InertiaFactors { mass, inertia } = factors;
        let mass_factored = mass.factorize(&self.work.data.mass_matrix).is_ok();
        // The closed-loop inertia's tree factor, the one factor of every consumer of `M̃⁻¹`
        // (collision, torso, projection, force limit): the platform rows and columns decoupled
        // from the factor of `M` (or factored anew when `M` is not positive definite). Fails
        // with `MassMatrixNotPositiveDefinite` when `M̃` is not positive definite. A fixed base
        // (no platform coordinates in the model) decouples nothing: `M̃ = M`, the factor of `M`.
        inertia.assign(mass);
        let mut decoupled = [false; N];
        for c in layout.axes().iter().filter_map(|a| a.coordinate()) {
            if let Some(flag) = decoupled.get_mut(c) {
                *flag = true;
            }
        }
        match (mass_factored, Self::FIXED_BASE) {
            (true, true) => Ok(()),
            (true, false) => inertia.decouple(&decoupled, closed_loop),
            (false, _) => inertia.factorize(closed_loop),
        }
        .map_err(Fault::Dynamics)?;
        let (mass, inertia) = (mass_factored.then_some(&*mass), &*inertia);
        if !self.state.started {
            self.start(&q, frame)?;
        }
        self.advance_targets(dt);
        self.limit_contact_forces(dt)?;
        let dynamic = self.settings.config.consistency == Consistency::Dynamic;
        // `M̃⁻¹` of the same tree factor the collision rows used: the `j M̃⁻¹ jᵀ` they carry
        // (`StackRow::metric_norm_squared`) is this weighting's quadratic form. The joint tasks
        // bound their damping with it (`joint_impedance::sampled_damping`).
        let joint_tasks = self.state.hierarchy.entries().iter().any(|e| e.kind.is_joint_task());
        let inverse_formed = dynamic || joint_tasks;
        if inverse_formed {
            inertia.inverse_into(&mut self.work.inverse_inertia);
        }
        self.build_stack(mass, inertia, inverse_formed)?;
        let weighting =
            if dynamic { Weighting::InverseInertia(&self.work.inverse_inertia) } else { Weighting::Identity };
        let config = HierarchyConfig {
            recursion: self.settings.config.recursion,
            weighting,
            shaping: self.settings.config.shaping,
            diagnose_last_level: false,
        };
        project(&config, &self.work.stack, &mut self.work.projection).map_err(Fault::Hierarchy)?;

        let platform = self.platform_command(frame, dt)?;
        let (model, data) = (&self.settings.model, &self.work.data);
        let terms = coupling_compensation_recursive(model, data, &layout, &platform.acceleration, Self::FIXED_BASE)
            .map_err(Fault::Platform)?;
        // `Cᵀ q̇` for the observer: from the barrier's fused pass when it ran.
        let mut coriolis_transpose = None;
        let mut held = self.state.barrier_hold;
        let compensation = terms.torque(self.settings.config.platform.compensation)
            + self.speed_barrier(
                &v,
                if inverse_formed {
                    InverseInertia::Dense(&self.work.inverse_inertia)
                } else {
                    InverseInertia::Factor(inertia)
                },
                &mut coriolis_transpose,
                &mut held,
            );
        self.state.barrier_hold = held;
        let compensation = self.blend_from_hold(&compensation, &v);
        let torque = self.guard_torque(&compensation, inertia, dt);
        let coriolis_transpose =
            coriolis_transpose.unwrap_or_else(|| coriolis_transpose_velocity(&self.settings.model, &self.work.data));
        self.commit(frame, &torque, &platform, &coriolis_transpose, dt)
    }

    /// Sets every target to the measured state (first valid frame).
    fn start(&mut self, q: &SVector<T, N>, frame: &SensorFrame<T, U>) -> Result<(), Fault> {
        for (trajectory, frame_id) in self.state.hands.iter_mut().zip(self.settings.config.layout.tcp.iter()) {
            let pose = self
                .work
                .data
                .frame_placements
                .get(frame_id.0)
                .copied()
                .ok_or(Fault::Dynamics(DynamicsError::UnknownFrame))?;
            *trajectory = PoseTrajectory::hold(pose);
        }
        self.state.joint_goal = JointTrajectory::hold(*q);
        self.state.reference_pose = Vector3::from(frame.platform.pose);
        self.state.admittance.reset(&Vector3::zeros()).map_err(Fault::Platform)?;
        self.state.avoidance.reset(&Vector3::zeros(), &frame.platform.leg_lengths).map_err(Fault::Platform)?;
        self.state.previous_torque = self.work.data.gravity_torque;
        self.state.started = true;
        self.state.telemetry.time_s = T::zero();
        Ok(())
    }

    fn advance_targets(&mut self, dt: T) {
        for hand in self.state.hands.iter_mut() {
            hand.advance(dt);
        }
        self.state.joint_goal.advance(dt);
        self.state.hierarchy.advance(dt / self.settings.config.transition_s);
        self.state.telemetry.time_s += dt;
    }

    /// The contact-force limiter ([`super::force_limit`]) on the last cycle's observer estimate, for the
    /// hands whose Cartesian task is in the hierarchy with at least one finite force bound.
    fn limit_contact_forces(&mut self, dt: T) -> Result<(), Fault> {
        let (cartesian, targets) = (&self.settings.config.cartesian, &self.state.hands);
        let mut hands = [None; A];
        for (((hand, arm), parameters), target) in hands.iter_mut().zip(ArmId::all::<A>()).zip(cartesian).zip(targets) {
            let running = self.state.hierarchy.contains(TaskKind::CartesianImpedance(arm));
            let (lower, upper) = (Vector6::from(parameters.force_lower), Vector6::from(parameters.force_upper));
            let limited = lower.iter().chain(upper.iter()).any(|x| x.is_finite());
            let axes = *target.sample().pose.rotation.matrix();
            *hand = (running && limited).then_some(HandLimits { axes, lower, upper });
        }
        let residual = *self.state.observer.residual();
        self.state
            .force_limiter
            .update_with_jacobians(
                &self.settings.config.force_limit,
                &self.settings.model,
                &self.work.data,
                &self.settings.config.layout,
                &residual,
                &hands,
                dt,
                &mut self.work.tcp_jacobians,
            )
            .map_err(Fault::Dynamics)?;
        let t = &mut self.state.telemetry;
        let (applied, correction) = (self.state.force_limiter.applied(), self.state.force_limiter.correction());
        for (((wrench, c), a), k) in
            t.contact_wrench.iter_mut().zip(t.force_limit_correction.iter_mut()).zip(applied).zip(correction)
        {
            (*wrench, *c) = (a, k);
        }
        Ok(())
    }

    /// Evaluates every hierarchy entry onto the stack; fills the per-task telemetry.
    /// `inverse_formed`: `work.inverse_inertia` holds this cycle's `M̃⁻¹`.
    fn build_stack(
        &mut self,
        mass: Option<&TreeFactorization<T, N>>,
        inertia: &TreeFactorization<T, N>,
        inverse_formed: bool,
    ) -> Result<(), Fault> {
        self.work.stack.clear();
        let t = &mut self.state.telemetry;
        t.tcp_error = [Vector6::zeros(); A];
        t.tcp_force_limited = [[false; 6]; A];
        t.min_collision_distance = None;
        t.collision_rows = 0;
        t.manipulability = [T::zero(); A];
        t.tasks = [None; MAX_ACTIVE];
        t.task_count = self.state.hierarchy.entries().len();
        let mut scratch = Scratch {
            collision: &mut self.work.collision_data,
            geometry_current: false,
            pair_rows: PairRowCache::default(),
            cartesian_damping: [Vector6::zeros(); A],
        };
        for (index, entry) in self.state.hierarchy.entries().iter().enumerate() {
            // The task writes its rows into the stack's slots; `place` tags and weights them.
            let mut rows = self.work.stack.task::<MAX_TASK_ROWS>();
            let evaluated = evaluate(
                entry.kind,
                &EvaluationContext {
                    model: &self.settings.model,
                    collision_model: &self.settings.collision_model,
                    config: &self.settings.config,
                    tasks: &self.settings.tasks,
                    hands: &self.state.hands,
                    joint_goal: &self.state.joint_goal,
                    mass,
                    inertia,
                    inverse_inertia: inverse_formed.then_some(&self.work.inverse_inertia),
                    tcp_jacobians: &self.work.tcp_jacobians,
                },
                &mut self.work.data,
                &mut scratch,
                &mut rows,
                &mut self.state.telemetry,
            );
            evaluated.map_err(|fault| rows.overflow().map_or(fault, Fault::Hierarchy))?;
            let t = &mut self.state.telemetry;
            if let (Some(kind), Some(activation), Some(norm)) =
                (t.tasks.get_mut(index), t.task_activation.get_mut(index), t.task_torque_norm.get_mut(index))
            {
                *kind = Some(entry.kind);
                (*activation, *norm) = row_summary(rows.rows());
            }
            entry.place(rows).map_err(Fault::Hierarchy)?;
        }
        self.work.cartesian_damping = scratch.cartesian_damping;
        Ok(())
    }

    /// Admittance (5.1) driven by the platform rows of `τ`, then the ICR avoidance loop.
    /// Returns `ṙ_des`, the commanded `r̈` and the leg rates, all limited.
    /// A fixed base (no platform axis in the layout) runs neither: the platform command is zero.
    fn platform_command(&mut self, frame: &SensorFrame<T, U>, dt: T) -> Result<PlatformStep<T>, Fault> {
        if self.settings.config.layout.platform.axes().iter().all(|axis| axis.coordinate().is_none()) {
            let t = &mut self.state.telemetry;
            t.saturation = Saturation::none();
            (t.virtual_force, t.base_acceleration, t.icr_repelling) = (Vector3::zeros(), Vector3::zeros(), false);
            return Ok(PlatformStep {
                velocity: Vector3::zeros(),
                acceleration: Vector3::zeros(),
                leg_rates: [T::zero(); LEGS],
            });
        }
        let platform = &self.settings.config.platform;
        let mut force = Vector3::zeros();
        for ((axis, f), deadband) in
            self.settings.config.layout.platform.axes().iter().zip(force.iter_mut()).zip(platform.force_deadband.iter())
        {
            if let Some(c) = axis.coordinate().filter(|_| axis.is_admitted()) {
                // The contact-force limiter's platform relief: the estimated reaction along the
                // limited axes ([`super::force_limit`]).
                let relief = self.state.force_limiter.platform_relief().get(c).copied().unwrap_or_else(T::zero);
                let raw = self.work.projection.torque.get(c).copied().unwrap_or_else(T::zero) + relief;
                // Deadband with a continuous output: F − sign(F) F₀ outside, 0 inside.
                *f = if raw > *deadband {
                    raw - *deadband
                } else if raw < -*deadband {
                    raw + *deadband
                } else {
                    T::zero()
                };
            }
        }
        let admitted = self.state.admittance.step(&force, &Vector3::zeros(), dt).map_err(Fault::Platform)?;
        self.state.reference_pose += admitted.velocity * dt;
        let reference = PlatformReference {
            pose: self.state.reference_pose,
            velocity: admitted.velocity,
            acceleration: admitted.acceleration,
        };
        let pose = Vector3::from(frame.platform.pose);
        let measured = Vector3::from(frame.platform.velocity);
        let avoidance = self.state.avoidance.step(&reference, &pose, &measured, dt).map_err(Fault::Platform)?;
        let limits = &self.settings.config.output_limits;
        let mut limited = [false; 3];
        let velocity = limit_base_velocity(
            &avoidance.velocity,
            &self.state.previous_base_velocity,
            &limits.base_velocity,
            &limits.base_acceleration,
            dt,
            &mut limited,
        );
        let mut legs = avoidance.leg_rates;
        let t = &mut self.state.telemetry;
        t.saturation = Saturation::none();
        t.saturation.base_limited = limited;
        t.saturation.leg_rate_limited = limit_leg_rates(&mut legs, limits.leg_rate);
        t.virtual_force = force;
        t.icr_repelling = avoidance.repelling;
        let acceleration = (velocity - self.state.previous_base_velocity) / dt;
        t.base_acceleration = acceleration;
        Ok(PlatformStep { velocity, acceleration, leg_rates: legs })
    }

    /// The joint speed barrier ([`mod@super::speed_barrier`]) on the upper body, from the measured `v`
    /// and the inverse closed-loop inertia `M̃⁻¹` (dense when the step formed it, else the
    /// factor). The driving torque is the levels' sum plus the observer's external-torque
    /// estimate minus the velocity terms `C q̇`. When the barrier drives, `C q̇` comes from the
    /// fused pass of [`coriolis_velocity_products`], whose `Cᵀ q̇` is left in
    /// `coriolis_transpose` for the observer.
    fn speed_barrier(
        &self,
        v: &SVector<T, N>,
        inverse: InverseInertia<'_, T, N>,
        coriolis_transpose: &mut Option<SVector<T, N>>,
        held: &mut BarrierHold<T, N>,
    ) -> SVector<T, N> {
        let active = self.settings.config.layout.coordinates(JointGroup::UpperBody);
        let limits =
            JointLimits { speed: &self.settings.model.limits.velocity, effort: &self.settings.model.limits.effort };
        let drive = |damping: &SVector<T, N>| {
            let count = self.work.projection.level_count.min(MAX_LEVELS);
            let levels = self.work.projection.level_torques.get(..count).unwrap_or(&[]);
            let mut torque = self.state.observer.residual() + damping;
            let sum = &mut torque.data.0[0];
            for level in levels {
                for (s, l) in sum.iter_mut().zip(&level.data.0[0]) {
                    *s += *l;
                }
            }
            // `− C q̇` by one O(B) tree pass: the step does not form `C` (`data.coriolis` is stale).
            let (velocity_terms, transpose) = coriolis_velocity_products(&self.settings.model, &self.work.data);
            *coriolis_transpose = Some(transpose);
            for (s, c) in sum.iter_mut().zip(&velocity_terms.data.0[0]) {
                *s -= *c;
            }
            for (a, upper) in sum.iter_mut().zip(active.iter()) {
                if !upper {
                    *a = T::zero();
                }
            }
            inverse.apply(&torque)
        };
        speed_barrier(&self.settings.config.speed_barrier, v, limits, |i| inverse.mobility(i), drive, &active, held)
    }

    /// While returning from the safe output ([`super::recovery`]): the levels' torques scaled by the
    /// weight `β` and the compensation moved towards the hold torque `g − D_safe q̇`, so that
    /// the guard receives `(1 − β) τ_hold + β (τ₀ + Σ τ_i^p)`. `compensation` itself in normal
    /// operation.
    fn blend_from_hold(&mut self, compensation: &SVector<T, N>, v: &SVector<T, N>) -> SVector<T, N> {
        let weight = self.state.recovery.weight();
        if weight >= T::one() {
            return *compensation;
        }
        let count = self.work.projection.level_count.min(MAX_LEVELS);
        for level in self.work.projection.level_torques.iter_mut().take(count) {
            *level *= weight;
        }
        let hold = self.work.data.gravity_torque - self.settings.config.safe_damping.component_mul(v);
        compensation + (hold - compensation) * (T::one() - weight)
    }

    /// The upper-body torque `τ₀ + Σ N_i τ_i` with the command-side contact-force limit
    /// ([`super::force_limit`]) through the priority-preserving guard. The limit's torque joins `τ₀`:
    /// the guard scales the task levels, never the bound on the contact force.
    fn guard_torque(&mut self, compensation: &SVector<T, N>, factor: &TreeFactorization<T, N>, dt: T) -> SVector<T, N> {
        let count = self.work.projection.level_count.min(MAX_LEVELS);
        let levels = self.work.projection.level_torques.get(..count).unwrap_or(&[]);
        let tasks = levels.iter().fold(SVector::<T, N>::zeros(), |t, l| t + l);
        let limit = self.state.force_limiter.limit_command(
            self.settings.config.force_limit.regularisation,
            &tasks,
            factor,
            &self.work.cartesian_damping,
        );
        for (flags, limited) in self.state.telemetry.tcp_force_limited.iter_mut().zip(limit.limited.iter()) {
            for (flag, l) in flags.iter_mut().zip(limited.iter()) {
                *flag |= *l;
            }
        }
        let compensation = &(compensation + limit.torque);
        let mut saturation = self.state.telemetry.saturation;
        let torque = self.guarded(compensation, levels, dt, &mut saturation);
        self.state.telemetry.saturation = saturation;
        torque
    }

    /// `compensation + Σ levels` through the upper body's effort box with priority-preserving
    /// scaling, then its torque-rate limit ([`super::guard`]); zero on the platform coordinates.
    fn guarded(
        &self,
        compensation: &SVector<T, N>,
        levels: &[SVector<T, N>],
        dt: T,
        saturation: &mut Saturation<T>,
    ) -> SVector<T, N> {
        let active = self.settings.config.layout.coordinates(JointGroup::UpperBody);
        let rate = &self.settings.config.output_limits.torque_rate;
        let effort = &self.settings.model.limits.effort;
        let within_effort = saturate_with_priority(compensation, levels, effort, &active, saturation);
        let (mut torque, rate_limited) =
            limit_rate(&within_effort, &self.state.previous_torque, rate, effort, dt, &active);
        saturation.torque_rate_limited = rate_limited;
        for (t, a) in torque.as_mut_slice().iter_mut().zip(active.iter()) {
            if !a {
                *t = T::zero();
            }
        }
        torque
    }

    /// Writes the actuator frame and remembers the torque and platform command for the rate
    /// limits of the next cycle.
    fn write_output(&mut self, torque: &SVector<T, N>, platform: PlatformCommand<T>, mode: SafeOutput) {
        if self.state.last_cycle.is_some() && mode != self.state.output.mode {
            self.state.telemetry.mode_changes = self.state.telemetry.mode_changes.saturating_add(1);
        }
        self.state.previous_torque = *torque;
        self.state.previous_base_velocity = Vector3::from(platform.velocity);
        let out = &mut self.state.output;
        for (o, t) in out.torque.iter_mut().zip(torque.as_slice().iter().skip(Self::PLATFORM_COORDINATES)) {
            *o = *t;
        }
        out.platform = platform;
        out.brake = mode == SafeOutput::Brake;
        out.mode = mode;
    }

    /// Checks the commands, updates the observer (with `Cᵀ q̇` = `coriolis`) and the telemetry,
    /// writes the output.
    fn commit(
        &mut self,
        frame: &SensorFrame<T, U>,
        torque: &SVector<T, N>,
        platform: &PlatformStep<T>,
        coriolis: &SVector<T, N>,
        dt: T,
    ) -> Result<(), Fault> {
        let (velocity, leg_rates) = (&platform.velocity, &platform.leg_rates);
        let finite = crate::math::all_finite(torque)
            && crate::math::all_finite(velocity)
            && leg_rates.iter().all(|x| x.is_finite());
        if !finite {
            return Err(Fault::NonFiniteOutput);
        }
        let mut measured = SVector::<T, N>::zeros();
        for (m, t) in
            measured.as_mut_slice().iter_mut().skip(Self::PLATFORM_COORDINATES).zip(frame.joints.torque.iter())
        {
            *m = *t;
        }
        let observed = self.settings.config.layout.coordinates(JointGroup::UpperBody);
        let residual = *self.state.observer.update_with(&self.work.data, coriolis, &measured, &observed, dt);
        let t = &mut self.state.telemetry;
        t.external_torque = residual;
        t.contact = sqrt(residual.norm_squared()) > self.settings.config.observer.contact_threshold;
        t.level_count = self.work.projection.level_count;
        // The stored energy of every level in one pass over the stack (each level's sum in stack
        // order).
        let mut storages = [T::zero(); MAX_LEVELS];
        for r in self.work.stack.rows() {
            if let Some(s) = storages.get_mut(r.level) {
                *s += r.row.potential;
            }
        }
        let mut potential = T::zero();
        for (level, &storage) in storages.iter().enumerate() {
            potential += storage;
            let diagnostics =
                self.work.projection.levels.get(level).filter(|_| level < self.work.projection.level_count);
            if let (Some(s), Some(rate), Some(norm), Some(conflict)) = (
                t.level_storage.get_mut(level),
                t.level_storage_rate.get_mut(level),
                t.level_torque_norm.get_mut(level),
                t.level_conflict.get_mut(level),
            ) {
                *rate = (storage - *s) / dt;
                *s = storage;
                *norm = diagnostics.map_or(T::zero(), |d| d.projected_torque_norm);
                *conflict = diagnostics.map_or(T::zero(), |d| d.conflict);
            }
        }
        t.potential_energy = potential;
        let half: T = convert(0.5);
        // M̃ q̇ as a sum of the columns of M̃, in column order.
        let mut momentum = SVector::<T, N>::zeros();
        for (column, v) in self.work.closed_loop.data.0.iter().zip(self.work.data.v.as_slice().iter()) {
            for (p, m) in momentum.as_mut_slice().iter_mut().zip(column.iter()) {
                *p += *v * *m;
            }
        }
        t.kinetic_energy = half * self.work.data.v.dot(&momentum);
        t.base_velocity = *velocity;

        self.state.hold_gravity = self.work.data.gravity_torque;
        self.write_output(
            torque,
            PlatformCommand { velocity: (*velocity).into(), leg_rates: *leg_rates },
            self.state.recovery.output().0,
        );
        Ok(())
    }

    /// The safe output of [`super::faults`]: gravity compensation with joint damping through the
    /// guards, the platform ramped to rest, the legs stopped; the brakes after
    /// `brake_after_cycles` faulty cycles. The platform loop restarts from rest afterwards.
    fn safe_output(&mut self, frame: &SensorFrame<T, U>, fault: Fault) {
        let t = &mut self.state.telemetry;
        t.fault = Some(fault);
        t.fault_cycles = t.fault_cycles.saturating_add(1);
        let brake = t.fault_cycles >= self.settings.config.input_limits.brake_after_cycles;
        let dt = self.settings.config.period_s;
        let (q, v) = frame.coordinates(Self::PLATFORM_COORDINATES);
        let positions_valid = crate::math::all_finite(&q)
            && forward_kinematics(&self.settings.model, &mut self.work.data, &q, &SVector::zeros()).is_ok();
        let gravity_torque =
            if positions_valid { *gravity(&self.settings.model, &mut self.work.data) } else { self.state.hold_gravity };
        let velocity = if crate::math::all_finite(&v) { v } else { SVector::zeros() };
        let hold = gravity_torque - self.settings.config.safe_damping.component_mul(&velocity);
        let mut saturation = Saturation::none();
        let mut torque = self.guarded(&hold, &[], dt, &mut saturation);
        if !crate::math::all_finite(&torque) {
            torque = self.state.previous_torque;
        }
        let limits = &self.settings.config.output_limits;
        let mut limited = [false; 3];
        let base = limit_base_velocity(
            &Vector3::zeros(),
            &self.state.previous_base_velocity,
            &limits.base_velocity,
            &limits.base_acceleration,
            dt,
            &mut limited,
        );
        saturation.base_limited = limited;
        self.state.telemetry.saturation = saturation;
        self.state.telemetry.base_velocity = base;
        // The platform loop restarts from the commanded (decaying) velocity.
        let _ = self.state.admittance.reset(&Vector3::zeros());
        let _ = self
            .state
            .avoidance
            .reset(&base, &frame.platform.leg_lengths.map(|l| if l.is_finite() { l } else { T::zero() }));
        let pose = Vector3::from(frame.platform.pose);
        if crate::math::all_finite(&pose) {
            self.state.reference_pose = pose;
        }
        self.state.observer.reset();
        self.state.force_limiter.reset();
        let mode = if brake { SafeOutput::Brake } else { SafeOutput::Hold };
        self.write_output(&torque, PlatformCommand { velocity: base.into(), leg_rates: [T::zero(); LEGS] }, mode);
    }
}
