//! What the controller is configured with: the robot and collision models, the configuration
//! and what is derived from them once (the validated task objects; the inertia's elimination
//! tree, which the controller's tree factors are built on). The cycle only reads it; accepted
//! planner commands change it.

use nalgebra::RealField;

use super::active_hierarchy::ActiveHierarchy;
use super::config::{ControllerConfig, TaskSpec};
use super::error::{CommandError, ConfigError};
use super::task_set::TaskSet;
use crate::dynamics::TreeStructure;
use crate::model::Model;
use crate::platform::admittance::Admittance;
use crate::platform::avoidance::PlatformAvoidance;
use crate::tasks::collision::CollisionModel;

/// The controller's configuration part (see the module docs).
#[derive(Clone, Debug)]
pub(super) struct ControllerSettings<
    T: RealField,
    const N: usize,
    const B: usize,
    const F: usize,
    const V: usize,
    const P: usize,
    const A: usize,
> {
    pub(super) model: Model<T, N, B, F>,
    pub(super) collision_model: CollisionModel<T, V, P>,
    pub(super) config: ControllerConfig<T, N, A>,
    /// The task objects of `config`, validated.
    pub(super) tasks: TaskSet<T, N, A>,
}

/// What the constructor validates and derives from the models and the configuration before it
/// builds the controller: the task objects, the elimination tree and the initial platform loop
/// and hierarchy (a few KB; see [`Derived::try_new`]).
pub(super) struct Derived<T: RealField, const N: usize, const A: usize> {
    pub(super) tasks: TaskSet<T, N, A>,
    pub(super) tree: TreeStructure<N>,
    pub(super) admittance: Admittance<T>,
    pub(super) avoidance: PlatformAvoidance<T>,
    pub(super) hierarchy: ActiveHierarchy<T>,
}

impl<T: RealField + Copy, const N: usize, const A: usize> Derived<T, N, A> {
    /// Validates `config` and the initial `hierarchy` on `model` and builds the task objects,
    /// the elimination tree, the admittance and the ICR avoidance.
    ///
    /// Never inlined: every fallible step of [`super::Controller::try_new`] runs here, in a
    /// frame of its own that is released before the controller (68 KB in f32, 136 KB in f64)
    /// is assembled, and only this small result crosses into the caller. Inlined, its
    /// temporaries and branches joined the caller's frame and LLVM kept by-value copies of the
    /// whole controller next to them (round 5: a smaller `RobotLayout::coordinates` was inlined
    /// into `TaskSet::try_new`, which LLVM then inlined into the firmware's `init`, whose frame
    /// grew from 116 KB to 233 KB in f32; out of line, `init` takes 87 KB and this 17 KB).
    #[inline(never)]
    pub(super) fn try_new<const B: usize, const F: usize>(
        model: &Model<T, N, B, F>,
        config: &ControllerConfig<T, N, A>,
        hierarchy: &[TaskSpec],
        platform_coordinates: usize,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        // A fixed base (no platform coordinates in the model) has no platform axis.
        if config.layout.platform.axes().iter().filter_map(|a| a.coordinate()).any(|c| c >= platform_coordinates) {
            return Err(ConfigError::InvalidParameter { name: "layout.platform" });
        }
        let tasks = TaskSet::try_new(model, config)?;
        let admittance = Admittance::try_new(config.platform.admittance).map_err(ConfigError::Platform)?;
        let avoidance = PlatformAvoidance::try_new(config.platform.avoidance).map_err(ConfigError::Platform)?;
        if hierarchy.iter().any(|spec| !tasks.supports(spec.kind)) {
            return Err(ConfigError::Hierarchy(CommandError::UnknownTask));
        }
        let hierarchy = ActiveHierarchy::initial(hierarchy).map_err(ConfigError::Hierarchy)?;
        Ok(Self { tasks, tree: TreeStructure::new(model), admittance, avoidance, hierarchy })
    }
}
