//! Redundancy resolution of Chapter 4: a stack of task rows on priority levels turned into one
//! joint torque with a strict, continuous hierarchy, computed by a row-wise recursion whose
//! only inversion is of a scalar (the remark after Table 4.3).
//!
//! - [`Stack`]: the rows of all tasks, each tagged with its priority level (0 = highest); the
//!   stack owns the row storage, and a task writes its rows in place through a [`TaskWindow`].
//! - [`project`]: the projection recursion; [`Recursion`] selects successive (4.3)–(4.7) or
//!   augmented (4.8)–(4.13) projections (or none, for comparison), [`Weighting`] the
//!   consistency: static `W = I` (Def. 4.1), dynamic `W = M(q)` (Def. 4.2, (4.29)), stiffness
//!   `W = K(q₀)` (Def. 4.3, (4.51)) or the acceleration-based dynamically consistent projector
//!   (4.38)–(4.42). [`Shaping`] selects the continuous transition shaping of Sec. 4.4 or the
//!   classical discontinuous rank decision (4.62).
//! - [`push_transitioning`]: dynamic hierarchies, a task moving between levels continuously.
//!
//! Rows of one level share that level's input projector; the projector is then updated row by
//! row. Each update is `N ← N − a (N j̄ᵀ)(W⁻¹ j̄ᵀ)ᵀ / (j̄ W⁻¹ j̄ᵀ)` with the projected row
//! `j̄ᵀ = N jᵀ` and the row's activation `a ∈ [0, 1]`: for `a = 1` this is the rank-one form of
//! `N (I − J̄ᵀ (J̄^W#)ᵀ)` (4.13) with `J̄^W# = W⁻¹J̄ᵀ(J̄W⁻¹J̄ᵀ)⁻¹` (4.15); a fractional `a`
//! is the continuous projector `N = I − ĵᵀ a ĵ` of (4.70)–(4.72).

mod config;
mod error;
pub mod multilevel;
mod projection;
mod stack;
mod transition;

pub use crate::math::switching::transition_weight;
pub use config::{HierarchyConfig, Recursion, Shaping, Weighting};
pub use error::HierarchyError;
pub use projection::{project, HierarchyData, LevelDiagnostics, RowDiagnostics};
pub use stack::{Stack, StackRow, TaskWindow};
pub use transition::{push_scaled, push_transitioning};
