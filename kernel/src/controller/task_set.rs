//! The task set: every task kind of the hierarchy ([`TaskKind`]) as a validated task object
//! built from the configuration ([`TaskSet`]), and the dispatch that evaluates one hierarchy
//! entry into its rows ([`evaluate`]). A new task kind adds its variant to [`TaskKind`], its
//! parameters to the configuration, and here its object and its arm of [`evaluate`].

use heapless::Vec;
use nalgebra::{Matrix3, RealField, SMatrix, SVector, Vector3, Vector6};

use super::capacity::MAX_TASK_ROWS;
use super::config::{CartesianParameters, CollisionFieldParameters, ControllerConfig, TaskKind};
use super::error::ConfigError;
use super::faults::Fault;
use super::layout::{ArmId, JointGroup, PerArm, MAX_GROUPS};
use super::telemetry::Telemetry;
use super::trajectory::{JointTrajectory, PoseTrajectory};
use crate::dynamics::TreeFactorization;
use crate::hierarchy::StackRow;
use crate::math::sqrt;
use crate::model::{Data, FrameId, Model};
use crate::tasks::cartesian_impedance::{
    cartesian_impedance_with_jacobian, AxisMask, CartesianImpedance, CartesianImpedanceConfig, StiffnessFrame,
};
use crate::tasks::collision::{
    collision_rows_shared, CollisionData, CollisionModel, CollisionParameters, PairRowCache,
};
use crate::tasks::end_stops::{end_stops, EndStop, EndStopConfig};
use crate::tasks::joint_impedance::{joint_impedance, JointImpedance, JointImpedanceConfig, JointTarget, SampledLoop};
use crate::tasks::manipulability::{manipulability_avoidance, Manipulability, ManipulabilityConfig};
use crate::tasks::torso_workspace::{torso_workspace, TorsoWorkspace};
use crate::tasks::{RowSink, TaskError};

/// Validated task objects built from the configuration.
#[derive(Clone, Debug)]
pub(super) struct TaskSet<T: RealField, const N: usize, const A: usize> {
    /// Per arm ([`ArmId`]).
    pub(super) cartesian: PerArm<CartesianImpedance<T>, A>,
    /// Per [`Field`](super::config::Field).
    pub(super) collision: [CollisionParameters<T>; 2],
    /// Per arm ([`ArmId`]).
    pub(super) singularity: PerArm<Manipulability<T, N>, A>,
    end_stops: Vec<EndStop<T, N>, MAX_TASK_ROWS>,
    torso: Option<TorsoWorkspace<T, N>>,
    /// Impedance, then pure damping; each per [`JointGroup`] of the layout, at
    /// [`JointGroup::index`].
    joint: [Vec<JointImpedance<T, N>, MAX_GROUPS>; 2],
    /// Which groups have coordinates, at [`JointGroup::index`] (a joint task on an empty group
    /// is refused).
    populated: [bool; MAX_GROUPS],
}

pub(super) fn cartesian_task<T: RealField + Copy, const N: usize, const A: usize>(
    config: &ControllerConfig<T, N, A>,
    frame: FrameId,
    parameters: &CartesianParameters<T>,
) -> Result<CartesianImpedance<T>, TaskError> {
    CartesianImpedance::try_new(CartesianImpedanceConfig {
        frame,
        axes: AxisMask::ALL,
        stiffness_frame: StiffnessFrame::Desired,
        translational_stiffness: Matrix3::from_diagonal(&Vector3::from(parameters.translational_stiffness)),
        rotational_stiffness: Matrix3::from_diagonal(&Vector3::from(parameters.rotational_stiffness)),
        damping_ratio: parameters.damping_ratio,
        force_lower: Vector6::from(parameters.force_lower),
        force_upper: Vector6::from(parameters.force_upper),
        fallback_damping: config.cartesian_fallback_damping,
    })
}

/// `[build(ArmId(0)), …, build(ArmId(A − 1))]`, or the first error.
fn try_per_arm<X, const A: usize>(
    mut build: impl FnMut(ArmId) -> Result<X, ConfigError>,
) -> Result<PerArm<X, A>, ConfigError> {
    let mut built: Vec<X, A> = Vec::new();
    for arm in ArmId::all::<A>() {
        if built.push(build(arm)?).is_err() {
            break;
        }
    }
    built.into_array().map_err(|_| ConfigError::InvalidParameter { name: "arms" })
}

pub(super) fn collision_parameters<T: RealField + Copy>(
    p: &CollisionFieldParameters<T>,
) -> Result<CollisionParameters<T>, TaskError> {
    CollisionParameters::try_new(
        p.max_force,
        p.influence_distance,
        p.damping_ratio,
        p.activation_full,
        p.activation_zero,
    )
}

impl<T: RealField + Copy, const N: usize, const A: usize> TaskSet<T, N, A> {
    /// The distance below which both collision fields need exact pair distances (their larger
    /// emit distance): the broad phase of the geometry update skips the pairs beyond it.
    pub(super) fn broad_phase_distance(&self) -> T {
        self.collision.iter().map(CollisionParameters::emit_distance).fold(T::zero(), |m, d| m.max(d))
    }

    /// `false` for a task this robot cannot run: the torso workspace without a coupled torso, a
    /// task of an arm the robot does not have, a joint task on a group without coordinates.
    pub(super) fn supports(&self, kind: TaskKind) -> bool {
        match kind {
            TaskKind::TorsoWorkspace => self.torso.is_some(),
            TaskKind::CartesianImpedance(arm) | TaskKind::SingularityAvoidance(arm) => arm.index() < A,
            TaskKind::JointImpedance(group) | TaskKind::JointDamping(group) => {
                self.populated.get(group.index()).copied().unwrap_or(false)
            }
            TaskKind::CollisionAvoidance(_) | TaskKind::EndStops => true,
        }
    }

    /// Validates and builds every task object of `config` on `model`.
    pub(super) fn try_new<const B: usize, const F: usize>(
        model: &Model<T, N, B, F>,
        config: &ControllerConfig<T, N, A>,
    ) -> Result<Self, ConfigError> {
        let layout = &config.layout;
        let cartesian = try_per_arm(|arm| {
            let (Some(frame), Some(parameters)) = (arm.of(&layout.tcp), arm.of(&config.cartesian)) else {
                return Err(ConfigError::InvalidParameter { name: "arms" });
            };
            cartesian_task(config, *frame, parameters).map_err(ConfigError::Task)
        })?;
        let [strong, weak] = config.collision;
        let collision = [
            collision_parameters(&strong).map_err(ConfigError::Task)?,
            collision_parameters(&weak).map_err(ConfigError::Task)?,
        ];
        let s = &config.singularity;
        let singularity = try_per_arm(|arm| {
            let frame = *arm.of(&layout.tcp).ok_or(ConfigError::InvalidParameter { name: "arms" })?;
            Manipulability::try_new(ManipulabilityConfig {
                frame,
                rows: s.rows,
                coordinates: layout.coordinates(JointGroup::Arm(arm)),
                threshold: s.threshold,
                full_activation: s.full_activation,
                stiffness: s.stiffness,
                damping: s.damping,
            })
            .map_err(ConfigError::Task)
        })?;
        let mut stops = Vec::new();
        let limits = &model.limits;
        let e = &config.end_stops;
        for i in (0..N).filter(|i| !config.layout.platform.is_platform(*i)) {
            let (Some(&lower), Some(&upper)) = (limits.position_lower.get(i), limits.position_upper.get(i)) else {
                continue;
            };
            let span = upper - lower;
            if !(span.is_finite() && span > e.margin + e.margin) {
                continue;
            }
            let (Some(&stiffness), Some(&damping)) = (e.stiffness.get(i), e.damping.get(i)) else {
                continue;
            };
            let stop = EndStop::try_new(EndStopConfig::coordinate(i, lower, upper, e.margin, stiffness, damping))
                .map_err(ConfigError::Task)?;
            stops
                .push(stop)
                .map_err(|_| ConfigError::InvalidParameter { name: "end stops: more than MAX_TASK_ROWS" })?;
        }
        let torso = config.torso_workspace.map(TorsoWorkspace::try_new).transpose().map_err(ConfigError::Task)?;
        let joint_task = |group: JointGroup, stiffness: SVector<T, N>, damping: SVector<T, N>| {
            JointImpedance::try_new(JointImpedanceConfig {
                selected: config.layout.coordinates(group),
                stiffness,
                damping,
            })
            .map_err(ConfigError::Task)
        };
        // Every group of `A` arms in storage order ([`JointGroup::index`]); an empty group gets an
        // empty task that [`Self::supports`] keeps out of the hierarchy.
        let mut groups = JointGroup::all::<A>();
        groups.sort_unstable_by_key(|group| group.index());
        let mut joint = [Vec::new(), Vec::new()];
        let mut populated = [false; MAX_GROUPS];
        // By reference: the drop of heapless' `IntoIter` indexes a slice (a panic path).
        for &group in groups.iter() {
            let [impedance, damping] = &mut joint;
            let full = ConfigError::InvalidParameter { name: "arms: more than MAX_ARMS" };
            impedance.push(joint_task(group, config.joint_stiffness, config.joint_damping)?).map_err(|_| full)?;
            damping.push(joint_task(group, SVector::zeros(), config.safe_damping)?).map_err(|_| full)?;
            if let Some(flag) = populated.get_mut(group.index()) {
                *flag = layout.coordinates(group).contains(&true);
            }
        }
        Ok(Self { cartesian, collision, singularity, end_stops: stops, torso, joint, populated })
    }
}

/// What the task evaluations of one cycle share: the collision geometry and whether it is
/// current (updated this cycle), the pair rows the collision fields evaluated (the strong
/// field's pairs are mostly among the weak field's), and the Cartesian damping force of each
/// arm (task axes) for the command-side force limit ([`super::force_limit`]).
pub(super) struct Scratch<'a, T: RealField, const N: usize, const V: usize, const P: usize, const A: usize> {
    pub(super) collision: &'a mut CollisionData<T, V, P>,
    pub(super) geometry_current: bool,
    pub(super) pair_rows: PairRowCache<T, N, P, MAX_TASK_ROWS>,
    pub(super) cartesian_damping: PerArm<Vector6<T>, A>,
}

/// Read-only inputs of a task evaluation.
pub(super) struct EvaluationContext<
    'a,
    T: RealField,
    const N: usize,
    const B: usize,
    const F: usize,
    const V: usize,
    const P: usize,
    const A: usize,
> {
    pub(super) model: &'a Model<T, N, B, F>,
    pub(super) collision_model: &'a CollisionModel<T, V, P>,
    pub(super) config: &'a ControllerConfig<T, N, A>,
    pub(super) tasks: &'a TaskSet<T, N, A>,
    pub(super) hands: &'a PerArm<PoseTrajectory<T>, A>,
    pub(super) joint_goal: &'a JointTrajectory<T, N>,
    /// The tree-sparse factor of the plain `M` (Cartesian damping design), `None` if `M` is not
    /// positive definite.
    pub(super) mass: Option<&'a TreeFactorization<T, N>>,
    /// The tree-sparse factor of the closed-loop inertia (5.17) (collision and torso rows).
    pub(super) inertia: &'a TreeFactorization<T, N>,
    /// Its inverse `M̃⁻¹`, formed whenever the hierarchy has a joint task (their damping's
    /// sampled-loop bound) or the projection is dynamically consistent.
    pub(super) inverse_inertia: Option<&'a SMatrix<T, N, N>>,
    /// The world-aligned TCP Jacobians at `data` (from the contact-force limiter).
    pub(super) tcp_jacobians: &'a PerArm<SMatrix<T, 6, N>, A>,
}

/// Appends the rows of one task to `rows` (the task's window of the stack) and records its
/// telemetry.
pub(super) fn evaluate<
    T: RealField + Copy,
    const N: usize,
    const B: usize,
    const F: usize,
    const V: usize,
    const P: usize,
    const A: usize,
>(
    kind: TaskKind,
    cx: &EvaluationContext<'_, T, N, B, F, V, P, A>,
    data: &mut Data<T, N, B, F>,
    scratch: &mut Scratch<'_, T, N, V, P, A>,
    rows: &mut impl RowSink<T, N, MAX_TASK_ROWS>,
    telemetry: &mut Telemetry<T, N, A>,
) -> Result<(), Fault> {
    match kind {
        TaskKind::CartesianImpedance(arm) => {
            let (Some(task), Some(trajectory), Some(jacobian)) =
                (arm.of(&cx.tasks.cartesian), arm.of(cx.hands), arm.of(cx.tcp_jacobians))
            else {
                return Ok(());
            };
            // (5.11): no Cartesian damping on the platform coordinates.
            let velocity = data.v;
            for (i, x) in data.v.iter_mut().enumerate() {
                if cx.config.layout.platform.is_platform(i) {
                    *x = T::zero();
                }
            }
            let report =
                cartesian_impedance_with_jacobian(cx.model, data, cx.mass, task, &trajectory.sample(), jacobian, rows);
            data.v = velocity;
            let report = report.map_err(Fault::Task)?;
            if let (Some(error), Some(limited), Some(damping)) = (
                arm.of_mut(&mut telemetry.tcp_error),
                arm.of_mut(&mut telemetry.tcp_force_limited),
                scratch.cartesian_damping.get_mut(arm.index()),
            ) {
                (*error, *limited, *damping) = (report.error, report.saturated, report.damping_force);
            }
        }
        TaskKind::CollisionAvoidance(field) => {
            let Some(parameters) = cx.tasks.collision.get(field.index()) else { return Ok(()) };
            // The geometry (volumes in the world, all pair distances) and the pair rows' Jacobians
            // and reflected masses depend only on this cycle's kinematics and inertia: the first
            // collision entry of the cycle updates the geometry, the later ones (the other field)
            // reuse it and the rows already evaluated. Same rows as evaluating each field alone.
            let (model, data_ref, factor, collision_model) = (cx.model, &*data, cx.inertia, cx.collision_model);
            if !scratch.geometry_current {
                collision_model.update(data_ref, scratch.collision);
                scratch.pair_rows.clear();
                scratch.geometry_current = true;
            }
            let report = collision_rows_shared(
                collision_model,
                scratch.collision,
                model,
                data_ref,
                factor,
                parameters,
                &mut scratch.pair_rows,
                rows,
            );
            let report = report.map_err(Fault::Task)?;
            telemetry.min_collision_distance = report.min_distance;
            telemetry.collision_rows += report.rows;
        }
        TaskKind::SingularityAvoidance(arm) => {
            let Some(task) = arm.of(&cx.tasks.singularity) else { return Ok(()) };
            let report = manipulability_avoidance(cx.model, data, task, rows).map_err(Fault::Task)?;
            if let Some(manipulability) = arm.of_mut(&mut telemetry.manipulability) {
                *manipulability = report.manipulability;
            }
        }
        TaskKind::EndStops => end_stops(&cx.tasks.end_stops, &data.q, &data.v, rows).map_err(Fault::Task)?,
        TaskKind::TorsoWorkspace => {
            if let Some(task) = &cx.tasks.torso {
                torso_workspace(task, &data.q, &data.v, cx.inertia, rows).map_err(Fault::Task)?;
            }
        }
        TaskKind::JointImpedance(group) | TaskKind::JointDamping(group) => {
            let damping_only = matches!(kind, TaskKind::JointDamping(_));
            let Some(task) = cx.tasks.joint.get(usize::from(damping_only)).and_then(|t| t.get(group.index())) else {
                return Ok(());
            };
            let (position, velocity) = cx.joint_goal.sample();
            let target = if damping_only { JointTarget::at_rest(data.q) } else { JointTarget { position, velocity } };
            let sampled = cx.inverse_inertia.map(|inverse_inertia| SampledLoop {
                inverse_inertia,
                period_s: cx.config.period_s,
                loop_gain: cx.config.joint_damping_loop_gain,
            });
            joint_impedance(task, &data.q, &data.v, &target, sampled.as_ref(), rows).map_err(Fault::Task)?;
        }
    }
    Ok(())
}

/// The telemetry of one task's rows as the task emitted them (before the level weight): the
/// largest activation and the norm of the torque `τ = Σ jᵀ f` of the rows used alone.
pub(super) fn row_summary<T: RealField + Copy, const N: usize>(rows: &[StackRow<T, N>]) -> (T, T) {
    let activation = rows.iter().fold(T::zero(), |a, r| a.max(r.row.activation));
    let torque = rows.iter().fold(SVector::<T, N>::zeros(), |tau, r| tau + r.row.jacobian.transpose() * r.row.force);
    (activation, sqrt(torque.norm_squared()))
}
