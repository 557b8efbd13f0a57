//! Contact-force limiter: keeps the force a TCP applies on its environment within the Cartesian
//! force limits of Table 7.1 (Sec. 7.3: "window wiper: +10 N"), using only what the robot
//! measures.
//!
//! ## Why the task's own clamp is not enough
//! The Cartesian impedance clamps its own *spring* force to `[f_lower, f_upper]`
//! ([`crate::tasks::cartesian_impedance`]). The contact force is the sum of everything that
//! reaches the TCP: the task's other rows (a stroke decelerating along the surface presses into
//! it through the coupling of the inertia), the lower levels through the projection (4.7)
//! (zero in the TCP's acceleration only for a dynamically consistent projection, and in a static
//! equilibrium only for a statically consistent one, Def. 4.1), the other arm's task through the
//! shared torso, and the velocity-controlled base, whose admittance (5.1) is driven by the
//! platform rows of `τ` and so keeps pushing the arm into the surface. Three mechanisms act on
//! that sum, on the bounds shrunk by the margin `m` (`(1 − m) f_bound`, for what none of them
//! sees): the command-side limit on the commanded torque, the governor on the measured force, the
//! platform relief on the base.
//!
//! ## Estimate of the contact wrench
//! The momentum observer ([`super::observer`]) gives `τ̂_ext`, the external torque low-passed
//! with the gain `K_O`, on the upper-body coordinates. With the TCP Jacobians in the axes of
//! the desired frames (those of the limits), `J_h = blockdiag(A_hᵀ, A_hᵀ) J_h,world`
//! (`A_h = R_des,h`), restricted to the upper-body columns (`J_u`, the platform columns zero)
//! and stacked for the `A` hands of the layout (`6 A × N`, [`ForceLimiter`] is generic over `A`,
//! the controller takes up to [`MAX_ARMS`](super::layout::MAX_ARMS)), the contact wrenches (on
//! the robot) are the regularised least-squares estimate
//!
//! `F̂_ext = (J_u J_uᵀ + μ I)⁻¹ J_u τ̂_ext`,
//!
//! one `6 A × 6 A` Cholesky solve (`μ > 0` keeps it positive definite, also with a hand's rows
//! zero). All hands are always estimated together, so that a contact of one hand seen through
//! the torso is not attributed to another. It is an *estimate*: contacts away from the TCPs,
//! model errors and joint friction the torque sensors do not see (link-side friction, taken
//! for an external torque) end up in it, and it lags the true force by the observer's time
//! constant `1/K_O`. The force the hand applies on the environment is `a = −F̂_ext`.
//!
//! ## Command-side limit: the contact force the commanded torque produces
//! What a commanded torque `τ = Σ_i N_i τ_i` (4.7) presses with is the force of a rigid contact
//! along the limited axes `L` (the axes with a finite bound; rows `J_L` of `J_u`, every hand):
//!
//! `λ_L = (J_L M⁻¹ J_Lᵀ + μ I)⁻¹ J_L M⁻¹ τ`,
//!
//! with `M` the closed-loop inertia of the cycle (the platform block the admittance mass, the
//! inertia the projections use). With the effective bounds `[l, u]` and the Cartesian damping
//! force `f_D` along the axis, it is kept inside `[l + max(f_D, 0), u + min(f_D, 0)]`: where the
//! damping pulls away from a bound, the bound holds for the rest of the force and the damping
//! acts on top (a contact pressed at the bound stays damped while the TCP moves into the
//! surface); where it pushes towards the bound, the bound holds for the total (that part of the
//! damping is dropped; what remains is still dissipative). Clamping the damping away entirely
//! left the pressed contact undamped. `f_D` is the task's damping before projection and
//! blending: exact for a Cartesian task on the first level (Fig. 6.3, Table 7.1), an
//! approximation during its transition or on a lower level. With
//! the excess `e` of `λ_L` over these bounds, `τ ← τ − J_Lᵀ e` lowers `λ_L` by exactly `e` (up to
//! `μ`) and changes nothing else of the contact; the torque joins the compensation `τ₀`, which
//! the output guard scales last. It acts before the contact exists as well: the bound is on what
//! the controller commands, as Table 7.1's is. Velocity terms (`C q̇`, `J̇ q̇`), friction and the
//! surface's compliance are left to the governor and the margin.
//!
//! ## Governor
//! Per hand with a running Cartesian task and per axis with a finite bound, a correction
//! `c_i ∈ [−c_max, c_max]` shifts the effective bounds of the command-side limit:
//! `f_upper,eff = f_upper − max(c_i, 0)`, `f_lower,eff = f_lower − min(c_i, 0)`. It integrates
//! the excess of the applied force over the limit,
//!
//! `ċ_i = k_F (a_i − f_upper,i)` on the upper side (`c_i ≥ 0`),
//! `ċ_i = k_F (a_i − f_lower,i)` on the lower side (`c_i ≤ 0`),
//!
//! starting on a side only when `a_i` crosses that limit, and relaxing back towards zero at the
//! same gain once `a_i` is inside again (`f_upper`, `f_lower` the bounds after the margin). At
//! rest `c_i` settles where `a_i` equals the limit (integral action: what the command-side
//! limit does not predict, the bound gives back). With the observer as a first-order lag and a quasi-static contact, the loop is `s² + K_O s + k_F K_O`:
//! `k_F = K_O/4` would be critically damped. That is an upper bound only: the contact force does
//! not follow the bound quasi-statically (arm and surface dynamics), and on the simulated Justin
//! `K_O/4` oscillated in the two-handed tasks; the fixture's gain is lower (see there).
//! Unlimited axes (`±∞`) are never governed.
//!
//! ## Platform relief
//! The admittance of the velocity-controlled base only sees the controller's torque, not the
//! environment's reaction. Along the limited axes the estimated reaction is added to the
//! platform's virtual force, `F_v += J_r,hᵀ P_h F̂_ext,h` (`J_r,h` the platform columns of `J_h`,
//! `P_h` keeps the components of limited axes in the direction of their finite bound): in a
//! steady contact it cancels the task force that would otherwise drive the base into the
//! surface; out of contact it is zero and the base follows the task as before.
//!
//! Everything is reset on a fault (with the observer) and per hand when its task is not in the
//! hierarchy.

mod command_limit;
mod estimate;
mod governor;
mod limiter;
#[cfg(test)]
mod tests;

pub use command_limit::CommandLimit;
pub use governor::governor_step;
pub use limiter::{ForceLimitParameters, ForceLimiter, HandLimits, Stacked};
