//! What the controller keeps between cycles ([`ControllerState`]: targets, the running
//! hierarchy, the platform loop, the observer and limiter estimates, the last output and
//! telemetry) and what it only uses within a cycle ([`Workspace`]: the dynamics, the collision
//! geometry, the stack and the projection).

use nalgebra::{RealField, SMatrix, SVector, Vector3, Vector6};

use super::active_hierarchy::ActiveHierarchy;
use super::capacity::{MAX_LEVELS, MAX_ROWS};
use super::config::ControllerConfig;
use super::force_limit::ForceLimiter;
use super::frames::ActuatorFrame;
use super::layout::PerArm;
use super::observer::MomentumObserver;
use super::recovery::Recovery;
use super::speed_barrier::BarrierHold;
use super::telemetry::Telemetry;
use super::trajectory::{JointTrajectory, PoseTrajectory};
use crate::dynamics::{TreeFactorization, TreeStructure};
use crate::hierarchy::{HierarchyData, Stack};
use crate::math::Placement;
use crate::model::{Data, Model};
use crate::platform::admittance::Admittance;
use crate::platform::avoidance::PlatformAvoidance;
use crate::tasks::collision::{CollisionData, CollisionModel};

/// The controller's state: everything one cycle leaves for the next (see the module docs).
#[derive(Clone, Debug)]
pub(super) struct ControllerState<T: RealField, const N: usize, const U: usize, const A: usize> {
    pub(super) hierarchy: ActiveHierarchy<T>,
    /// The TCP targets, per arm ([`ArmId`](super::layout::ArmId)).
    pub(super) hands: PerArm<PoseTrajectory<T>, A>,
    pub(super) joint_goal: JointTrajectory<T, N>,
    pub(super) admittance: Admittance<T>,
    pub(super) avoidance: PlatformAvoidance<T>,
    /// The admittance's integrated pose, the reference of the ICR avoidance.
    pub(super) reference_pose: Vector3<T>,
    pub(super) observer: MomentumObserver<T, N>,
    pub(super) force_limiter: ForceLimiter<T, N, A>,
    /// `true` once a valid frame set the targets.
    pub(super) started: bool,
    pub(super) recovery: Recovery<T>,
    /// The cycle counter of the last frame, `None` before the first.
    pub(super) last_cycle: Option<u64>,
    /// Gravity at the last valid positions, for the safe output.
    pub(super) hold_gravity: SVector<T, N>,
    /// The last torque and platform command, for the rate limits.
    pub(super) previous_torque: SVector<T, N>,
    pub(super) previous_base_velocity: Vector3<T>,
    /// What the speed barrier holds ([`super::speed_barrier::BarrierHold`]).
    pub(super) barrier_hold: BarrierHold<T, N>,
    pub(super) telemetry: Telemetry<T, N, A>,
    pub(super) output: ActuatorFrame<T, U>,
}

impl<T: RealField + Copy, const N: usize, const U: usize, const A: usize> ControllerState<T, N, U, A> {
    /// The state before the first frame: targets at the origin until the first valid frame sets
    /// them, the hold output.
    #[inline(always)]
    pub(super) fn new(
        config: &ControllerConfig<T, N, A>,
        hierarchy: ActiveHierarchy<T>,
        admittance: Admittance<T>,
        avoidance: PlatformAvoidance<T>,
    ) -> Self {
        Self {
            hierarchy,
            hands: [PoseTrajectory::hold(Placement::identity()); A],
            joint_goal: JointTrajectory::hold(SVector::zeros()),
            admittance,
            avoidance,
            reference_pose: Vector3::zeros(),
            observer: MomentumObserver::new(config.observer.gain),
            force_limiter: ForceLimiter::new(),
            started: false,
            recovery: Recovery::Normal,
            last_cycle: None,
            hold_gravity: SVector::zeros(),
            previous_torque: SVector::zeros(),
            previous_base_velocity: Vector3::zeros(),
            barrier_hold: BarrierHold::new(),
            telemetry: Telemetry::empty(),
            output: ActuatorFrame::initial(),
        }
    }
}

/// The controller's workspace: preallocated, recomputed every cycle (see the module docs).
#[derive(Clone, Debug)]
pub(super) struct Workspace<
    T: RealField,
    const N: usize,
    const B: usize,
    const F: usize,
    const V: usize,
    const P: usize,
    const A: usize,
> {
    /// The dynamics of the last valid cycle.
    pub(super) data: Data<T, N, B, F>,
    /// The collision geometry; `exact_within` follows the collision fields' emit distances.
    pub(super) collision_data: CollisionData<T, V, P>,
    /// Every task's rows, written in place by the tasks (`Stack::task`).
    pub(super) stack: Stack<T, N, MAX_ROWS>,
    pub(super) projection: HierarchyData<T, N, MAX_ROWS, MAX_LEVELS>,
    /// The Cartesian damping force of each arm this cycle (task axes), outside the force limits,
    /// per arm.
    pub(super) cartesian_damping: PerArm<Vector6<T>, A>,
    /// The world-aligned TCP Jacobians of this cycle (contact-force limiter and Cartesian tasks).
    pub(super) tcp_jacobians: PerArm<SMatrix<T, 6, N>, A>,
    /// The closed-loop inertia `M̃` (5.17) of this cycle.
    pub(super) closed_loop: SMatrix<T, N, N>,
    /// The dense `M̃⁻¹` of this cycle (dynamically consistent projection and speed barrier).
    pub(super) inverse_inertia: SMatrix<T, N, N>,
}

/// The step's two tree factors, kept between cycles so that no cycle builds or clones one: the
/// plain `M = Lᵀ L` and the closed-loop `M̃ = Lᵀ L` (5.17) decoupled from it.
#[derive(Clone, Debug)]
pub(super) struct InertiaFactors<T: RealField, const N: usize> {
    pub(super) mass: TreeFactorization<T, N>,
    pub(super) inertia: TreeFactorization<T, N>,
}

impl<T: RealField + Copy, const N: usize> InertiaFactors<T, N> {
    /// Zero factors over `structure`.
    pub(super) fn new(structure: TreeStructure<N>) -> Self {
        Self {
            mass: TreeFactorization::from_structure(structure),
            inertia: TreeFactorization::from_structure(structure),
        }
    }
}

impl<
        T: RealField + Copy,
        const N: usize,
        const B: usize,
        const F: usize,
        const V: usize,
        const P: usize,
        const A: usize,
    > Workspace<T, N, B, F, V, P, A>
{
    /// A workspace for `model` and `collision_model`; the broad phase evaluates the pairs within
    /// `exact_within` exactly.
    #[inline(always)]
    pub(super) fn new(model: &Model<T, N, B, F>, collision_model: &CollisionModel<T, V, P>, exact_within: T) -> Self {
        let mut collision_data = CollisionData::new(collision_model);
        collision_data.exact_within = Some(exact_within);
        Self {
            data: Data::new(model),
            collision_data,
            stack: Stack::new(),
            projection: HierarchyData::default(),
            cartesian_damping: [Vector6::zeros(); A],
            tcp_jacobians: [SMatrix::zeros(); A],
            closed_loop: SMatrix::zeros(),
            inverse_inertia: SMatrix::zeros(),
        }
    }
}
