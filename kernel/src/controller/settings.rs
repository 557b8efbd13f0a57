//! What the controller is configured with: the robot and collision models, the configuration
//! and what is derived from them once (the validated task objects, the inertia's elimination
//! tree). The cycle only reads it; accepted planner commands change it.

use nalgebra::RealField;

use super::config::ControllerConfig;
use super::error::ConfigError;
use super::task_set::TaskSet;
use crate::dynamics::TreeStructure;
use crate::model::Model;
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
> {
    pub(super) model: Model<T, N, B, F>,
    pub(super) collision_model: CollisionModel<T, V, P>,
    pub(super) config: ControllerConfig<T, N>,
    /// The task objects of `config`, validated.
    pub(super) tasks: TaskSet<T, N>,
    /// The elimination tree of the model's inertia ([`crate::dynamics::TreeFactorization`]).
    pub(super) tree: TreeStructure<N>,
}

impl<T: RealField + Copy, const N: usize, const B: usize, const F: usize, const V: usize, const P: usize>
    ControllerSettings<T, N, B, F, V, P>
{
    /// Validates `config` and builds the task objects and the elimination tree.
    #[inline(always)]
    pub(super) fn try_new(
        model: Model<T, N, B, F>,
        collision_model: CollisionModel<T, V, P>,
        config: ControllerConfig<T, N>,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        let tasks = TaskSet::try_new(&model, &config)?;
        let tree = TreeStructure::new(&model);
        Ok(Self { model, collision_model, config, tasks, tree })
    }
}
