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
//! and stacked for both hands (12 × N), the contact wrenches (on the robot) are the regularised
//! least-squares estimate
//!
//! `F̂_ext = (J_u J_uᵀ + μ I)⁻¹ J_u τ̂_ext`,
//!
//! one 12 × 12 Cholesky solve (`μ > 0` keeps it positive definite, also with one hand's rows
//! zero). Both hands are always estimated together, so that a contact of one hand seen through
//! the torso is not attributed to the other. It is an *estimate*: contacts away from the TCPs
//! and model errors end up in it, and it lags the true force by the observer's time constant
//! `1/K_O`. The force the hand applies on the environment is `a = −F̂_ext`.
//!
//! ## Command-side limit: the contact force the commanded torque produces
//! What a commanded torque `τ = Σ_i N_i τ_i` (4.7) presses with is the force of a rigid contact
//! along the limited axes `L` (the axes with a finite bound; rows `J_L` of `J_u`, both hands):
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

use nalgebra::{Cholesky, Const, Matrix3, RealField, SMatrix, SVector, Vector6};

use super::config::RobotLayout;
use crate::dynamics::{frame_jacobian, DynamicsError, InertiaFactor, TreeFactorization};
use crate::math::cholesky::{cholesky_in_place, solve_lower_in_place, solve_lower_transpose_in_place};
use crate::model::{Data, Model};

/// Parameters of the contact-force limiter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceLimitParameters<T> {
    /// `true` enables the command-side limit, the governor and the platform relief (the
    /// estimate is always reported).
    pub enabled: bool,
    /// Share `0 ≤ m < 1` of every finite bound kept free: the limiter holds the force within
    /// `(1 − m)` times the configured bounds, for what neither the command-side prediction nor
    /// the lagging estimate sees (surface compliance, friction changes, model error).
    pub margin: T,
    /// Governor gain `k_F > 0` (1/s): N of correction per N·s of excess.
    pub gain: T,
    /// Largest correction `c_max ≥ 0` per axis (N, Nm).
    pub max_correction: T,
    /// Regularisation `μ > 0` of the wrench estimate (m², in the units of `J Jᵀ`) and of the
    /// reflected inertia of the command-side limit (1/kg, in the units of `J M⁻¹ Jᵀ`).
    pub regularisation: T,
}

/// What one hand's limiter needs this cycle: its TCP frame, the orientation of the desired
/// frame and the task's configured bounds (desired-frame axes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HandLimits<T> {
    /// Orientation `A = R_des` of the desired TCP frame (world).
    pub axes: Matrix3<T>,
    /// Configured lower bounds (N, Nm), `≤ 0`, may be `−∞`.
    pub lower: Vector6<T>,
    /// Configured upper bounds (N, Nm), `≥ 0`, may be `+∞`.
    pub upper: Vector6<T>,
}

/// State of the limiter: per hand the estimated applied wrench and the governor corrections;
/// the cycle's Jacobians and effective bounds for the command-side limit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceLimiter<T, const N: usize> {
    applied: [Vector6<T>; 2],
    correction: [Vector6<T>; 2],
    relief: SVector<T, N>,
    /// `J_u` of both hands, stacked (12 × N, desired-frame axes, platform columns zero).
    stacked: SMatrix<T, 12, N>,
    /// Effective bounds `(lower, upper)` per hand with an enabled limit, this cycle.
    effective: [Option<(Vector6<T>, Vector6<T>)>; 2],
}

/// What the command-side limit did: the torque to add and the axes it acted on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandLimit<T, const N: usize> {
    /// `−J_Lᵀ e` (upper-body rows; zero without excess).
    pub torque: SVector<T, N>,
    /// Per hand and axis: the commanded contact force left its bounds.
    pub limited: [[bool; 6]; 2],
}

impl<T: RealField + Copy, const N: usize> Default for ForceLimiter<T, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: RealField + Copy, const N: usize> ForceLimiter<T, N> {
    /// A limiter at rest (no correction).
    pub fn new() -> Self {
        Self {
            applied: [Vector6::zeros(); 2],
            correction: [Vector6::zeros(); 2],
            relief: SVector::zeros(),
            stacked: SMatrix::zeros(),
            effective: [None; 2],
        }
    }

    /// Forgets every correction and estimate (after a fault).
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// Estimated wrench the TCP of hand `index` applies on its environment, `a = −F̂_ext`
    /// (N, Nm, desired-frame axes).
    pub fn applied(&self) -> [Vector6<T>; 2] {
        self.applied
    }

    /// Governor corrections `c` per hand and axis (N, Nm): positive lowers the upper bound,
    /// negative raises the lower bound.
    pub fn correction(&self) -> [Vector6<T>; 2] {
        self.correction
    }

    /// Torque to add to the platform rows of `τ` (the estimated reaction along the limited
    /// axes; zero on the upper body).
    pub fn platform_relief(&self) -> &SVector<T, N> {
        &self.relief
    }

    /// The effective bounds `(lower, upper)` of hand `index` for the configured ones.
    pub fn bounds(&self, index: usize, lower: &Vector6<T>, upper: &Vector6<T>) -> (Vector6<T>, Vector6<T>) {
        let c = self.correction.get(index).copied().unwrap_or_else(Vector6::zeros);
        (lower - c.map(|x| x.min(T::zero())), upper - c.map(|x| x.max(T::zero())))
    }

    /// One period `dt`: estimates the wrenches from `residual` (`τ̂_ext`, [`super::observer`]) at
    /// the kinematics of `data` (after `forward_kinematics`), then advances the governor of each
    /// hand with `Some` limits (a hand with `None` is reset). If the 12 × 12 solve fails (a
    /// non-finite input), the estimate is zero and the corrections are held. Cost two frame
    /// Jacobians, the 12 × 12 Gram matrix as N rank-one updates and one 12 × 12 Cholesky, all
    /// as loops over the column-major storage.
    /// Errors: [`DynamicsError::UnknownFrame`] for a TCP frame outside the model.
    #[allow(clippy::too_many_arguments, reason = "the controller's pieces, each used once")]
    pub fn update<const B: usize, const F: usize>(
        &mut self,
        parameters: &ForceLimitParameters<T>,
        model: &Model<T, N, B, F>,
        data: &Data<T, N, B, F>,
        layout: &RobotLayout<N>,
        residual: &SVector<T, N>,
        hands: &[Option<HandLimits<T>>; 2],
        dt: T,
    ) -> Result<(), DynamicsError> {
        // J_h = blockdiag(A_hᵀ, A_hᵀ) J_h,world column by column; J_u (platform columns zero)
        // stacked for both hands into the 12 × N matrix, one 12-entry column per coordinate.
        let mut full = [SMatrix::<T, 6, N>::zeros(); 2];
        let mut stacked = SMatrix::<T, 12, N>::zeros();
        for (h, ((tcp, limits), jacobian)) in layout.tcp.iter().zip(hands.iter()).zip(full.iter_mut()).enumerate() {
            let axes = limits.map_or_else(Matrix3::identity, |l| l.axes);
            frame_jacobian(model, data, *tcp, jacobian)?;
            for (k, (column, target)) in
                jacobian.as_mut_slice().chunks_exact_mut(6).zip(stacked.as_mut_slice().chunks_exact_mut(12)).enumerate()
            {
                for half in column.chunks_exact_mut(3) {
                    let world = [
                        half.first().copied().unwrap_or_else(T::zero),
                        half.get(1).copied().unwrap_or_else(T::zero),
                        half.get(2).copied().unwrap_or_else(T::zero),
                    ];
                    // (Aᵀ x)_i = column i of A · x.
                    for (x, a) in half.iter_mut().zip(axes.as_slice().chunks_exact(3)) {
                        *x = a.iter().zip(world.iter()).fold(T::zero(), |s, (a, w)| s + *a * *w);
                    }
                }
                if layout.platform.is_platform(k) {
                    continue;
                }
                if let Some(rows) = target.get_mut(6 * h..6 * h + 6) {
                    rows.copy_from_slice(column);
                }
            }
        }
        // Gram matrix J_u J_uᵀ + μ I as a sum of rank-one terms over the columns, and J_u τ̂_ext.
        let mut gram = SMatrix::<T, 12, 12>::identity() * parameters.regularisation;
        let mut projected = SVector::<T, 12>::zeros();
        for (column, r) in stacked.as_slice().chunks_exact(12).zip(residual.iter()) {
            for (g_column, c_j) in gram.as_mut_slice().chunks_exact_mut(12).zip(column.iter()) {
                if *c_j != T::zero() {
                    for (g, c_i) in g_column.iter_mut().zip(column.iter()) {
                        *g += *c_i * *c_j;
                    }
                }
            }
            for (p, c) in projected.iter_mut().zip(column.iter()) {
                *p += *c * *r;
            }
        }
        self.stacked = stacked;
        self.effective = [None; 2];
        let mut external = projected;
        let solved = cholesky_in_place(gram.as_mut_slice(), 12)
            && solve_lower_in_place(gram.as_slice(), external.as_mut_slice())
            && solve_lower_transpose_in_place(gram.as_slice(), external.as_mut_slice());
        if !solved {
            self.applied = [Vector6::zeros(); 2];
            self.relief = SVector::zeros();
            return Ok(());
        }
        if !crate::math::all_finite(&external) {
            self.applied = [Vector6::zeros(); 2];
            self.relief = SVector::zeros();
            return Ok(());
        }
        self.relief = SVector::zeros();
        let step = parameters.gain * dt;
        let wrenches: [Vector6<T>; 2] =
            [external.fixed_rows::<6>(0).into_owned(), external.fixed_rows::<6>(6).into_owned()];
        for (h, ((limits, jacobian), wrench)) in hands.iter().zip(full.iter()).zip(wrenches).enumerate() {
            let applied = -wrench;
            if let Some(a) = self.applied.get_mut(h) {
                *a = applied;
            }
            let Some(correction) = self.correction.get_mut(h) else { continue };
            let Some(limits) = limits.filter(|_| parameters.enabled) else {
                *correction = Vector6::zeros();
                continue;
            };
            let share = T::one() - parameters.margin;
            let limits = HandLimits { lower: limits.lower * share, upper: limits.upper * share, ..limits };
            let mut reaction = Vector6::zeros();
            for axis in 0..6 {
                let get = |v: &Vector6<T>| v.get(axis).copied().unwrap_or_else(T::zero);
                let (a, lower, upper) = (get(&applied), get(&limits.lower), get(&limits.upper));
                let lower = Some(lower).filter(|x| x.is_finite());
                let upper = Some(upper).filter(|x| x.is_finite());
                if let Some(c) = correction.get_mut(axis) {
                    *c = governor_step(*c, a, lower, upper, step, parameters.max_correction);
                }
                let pressing = (upper.is_some() && a > T::zero()) || (lower.is_some() && a < T::zero());
                if let (true, Some(r)) = (pressing, reaction.get_mut(axis)) {
                    *r = get(&wrench);
                }
            }
            let bounds = self.bounds(h, &limits.lower, &limits.upper);
            if let Some(e) = self.effective.get_mut(h) {
                *e = Some(bounds);
            }
            // J_r,hᵀ P_h F̂: the platform columns of J_h only.
            for (k, (r, column)) in self.relief.iter_mut().zip(jacobian.as_slice().chunks_exact(6)).enumerate() {
                if layout.platform.is_platform(k) {
                    *r += column.iter().zip(reaction.iter()).fold(T::zero(), |s, (j, f)| s + *j * *f);
                }
            }
        }
        Ok(())
    }
}

impl<T: RealField + Copy, const N: usize> ForceLimiter<T, N> {
    /// The command-side limit (module docs) for the projected task torque `τ = Σ_i N_i τ_i` of
    /// this cycle, after [`Self::update`]: `regularisation` is `μ` of the parameters, `factor`
    /// a factor of the closed-loop inertia ([`InertiaFactor`]: dense or tree-sparse), `damping`
    /// the Cartesian damping force of each hand (task axes). Returns the torque `−J_Lᵀ e` that
    /// moves every limited axis' rigid-contact force onto its bound (with the damping rule of
    /// the module docs). Zero without an enabled limit or if a solve fails.
    /// Cost: one substitution with `factor` per limited row plus one for `τ`
    /// (`reflected_dense`, `reflected_tree`), one 12 × 12 Cholesky.
    pub fn limit_command<'m>(
        &self,
        regularisation: T,
        task_torque: &SVector<T, N>,
        factor: impl Into<InertiaFactor<'m, T, N>>,
        damping: &[Vector6<T>; 2],
    ) -> CommandLimit<T, N> {
        let none = CommandLimit { torque: SVector::zeros(), limited: [[false; 6]; 2] };
        // The limited rows L: an axis of a hand with an enabled limit and a finite bound.
        let mut selected = [false; 12];
        for (h, bounds) in self.effective.iter().enumerate() {
            let Some((lower, upper)) = bounds else { continue };
            for (axis, (low, high)) in lower.iter().zip(upper.iter()).enumerate() {
                if let Some(s) = selected.get_mut(6 * h + axis) {
                    *s = low.is_finite() || high.is_finite();
                }
            }
        }
        if !selected.iter().any(|s| *s) {
            return none;
        }
        let (solved, mut reflected, mut force) = match factor.into() {
            InertiaFactor::Dense(factor) => self.reflected_dense(regularisation, task_torque, factor, &selected),
            InertiaFactor::Tree(factor) => self.reflected_tree(regularisation, task_torque, factor, &selected),
        };
        let solved = solved
            && cholesky_in_place(reflected.as_mut_slice(), 12)
            && solve_lower_in_place(reflected.as_slice(), force.as_mut_slice())
            && solve_lower_transpose_in_place(reflected.as_slice(), force.as_mut_slice());
        if !(solved && force.iter().all(|x| x.is_finite())) {
            return none;
        }
        let mut excess = SVector::<T, 12>::zeros();
        let mut limited = [[false; 6]; 2];
        for (h, ((bounds, flags), damping)) in
            self.effective.iter().zip(limited.iter_mut()).zip(damping.iter()).enumerate()
        {
            let Some((lower, upper)) = bounds else { continue };
            for (axis, flag) in flags.iter_mut().enumerate() {
                let row = 6 * h + axis;
                let get = |v: &Vector6<T>| v.get(axis).copied().unwrap_or_else(T::zero);
                let (Some(f), Some(e)) = (force.get(row), excess.get_mut(row)) else { continue };
                let d = get(damping);
                let (low, high) = (get(lower) + d.max(T::zero()), get(upper) + d.min(T::zero()));
                let over = *f - f.max(low).min(high);
                *e = over;
                *flag = over != T::zero();
            }
        }
        // −J_Lᵀ e: one dot product per column of the stacked Jacobian.
        let dot = |a: &[T], b: &[T]| a.iter().zip(b.iter()).fold(T::zero(), |s, (x, y)| s + *x * *y);
        let mut torque = SVector::<T, N>::zeros();
        for (t, column) in torque.iter_mut().zip(self.stacked.as_slice().chunks_exact(12)) {
            *t = -dot(column, excess.as_slice());
        }
        CommandLimit { torque, limited }
    }

    /// The reflected inertia `J_L M⁻¹ J_Lᵀ + μ I` of the limited rows (identity on the others;
    /// the lower triangle is written) and `J_L M⁻¹ τ` with the dense `M = L Lᵀ`:
    /// `Y = L⁻¹ J_Lᵀ` (forward substitution of the selected rows only, loops on the column-major
    /// factor) and `z = L⁻¹ τ`, then `Yᵀ Y` and `Yᵀ z`. `false` if a substitution failed.
    fn reflected_dense(
        &self,
        regularisation: T,
        task_torque: &SVector<T, N>,
        factor: &Cholesky<T, Const<N>>,
        selected: &[bool; 12],
    ) -> (bool, SMatrix<T, 12, 12>, SVector<T, 12>) {
        // With M = L Lᵀ: Y = L⁻¹ J_Lᵀ (forward substitution of the selected rows only) and
        // z = L⁻¹ τ; the reflected inertia J_L M⁻¹ J_Lᵀ = Yᵀ Y (identity on the other rows) and
        // J_L M⁻¹ τ = Yᵀ z.
        let l = factor.l_dirty().as_slice();
        let mut z = *task_torque;
        let mut reduced = SMatrix::<T, N, 12>::zeros();
        let mut solved = solve_lower_in_place(l, z.as_mut_slice());
        for (i, (column, s)) in reduced.as_mut_slice().chunks_exact_mut(N).zip(selected.iter()).enumerate() {
            if !s {
                continue;
            }
            for (y, j) in column.iter_mut().zip(self.stacked.as_slice().chunks_exact(12)) {
                *y = j.get(i).copied().unwrap_or_else(T::zero);
            }
            solved &= solve_lower_in_place(l, column);
        }
        let mut reflected = SMatrix::<T, 12, 12>::identity();
        let mut force = SVector::<T, 12>::zeros();
        let dot = |a: &[T], b: &[T]| a.iter().zip(b.iter()).fold(T::zero(), |s, (x, y)| s + *x * *y);
        for (i, ((yi, si), (r_column, f))) in reduced
            .as_slice()
            .chunks_exact(N)
            .zip(selected.iter())
            .zip(reflected.as_mut_slice().chunks_exact_mut(12).zip(force.iter_mut()))
            .enumerate()
        {
            if !si {
                continue;
            }
            *f = dot(yi, z.as_slice());
            // Column i, rows j ≥ i (the lower triangle the factorisation reads).
            for (j, ((yj, sj), x)) in
                reduced.as_slice().chunks_exact(N).zip(selected.iter()).zip(r_column.iter_mut()).enumerate().skip(i)
            {
                if *sj {
                    *x = dot(yi, yj) + if i == j { regularisation } else { T::zero() };
                }
            }
        }
        (solved, reflected, force)
    }

    /// [`Self::reflected_dense`] on the tree-sparse `M = Lᵀ L`: `X = S L⁻¹` for the stack `S`
    /// of the selected rows of `J_u` and `τᵀ` ([`TreeFactorization::right_solve_mut`]), then
    /// `J_L M⁻¹ J_Lᵀ = X_L X_Lᵀ` and `J_L M⁻¹ τ = X_L x_τᵀ` over the columns of `X`.
    fn reflected_tree(
        &self,
        regularisation: T,
        task_torque: &SVector<T, N>,
        factor: &TreeFactorization<T, N>,
        selected: &[bool; 12],
    ) -> (bool, SMatrix<T, 12, 12>, SVector<T, 12>) {
        let mut x = SMatrix::<T, 13, N>::zeros();
        for ((column, j), t) in x.data.0.iter_mut().zip(self.stacked.data.0.iter()).zip(task_torque.iter()) {
            for ((c, v), s) in column.iter_mut().zip(j.iter()).zip(selected.iter()) {
                if *s {
                    *c = *v;
                }
            }
            if let Some(c) = column.get_mut(12) {
                *c = *t;
            }
        }
        factor.right_solve_mut(&mut x);
        // The rows of X as contiguous columns: the Gram entries are dot products.
        let rows = x.transpose();
        let Some((torque_row, _)) = rows.data.0.split_last() else {
            return (false, SMatrix::identity(), SVector::zeros());
        };
        let dot = |a: &[T; N], b: &[T; N]| a.iter().zip(b.iter()).fold(T::zero(), |s, (x, y)| s + *x * *y);
        let mut reflected = SMatrix::<T, 12, 12>::identity();
        let mut force = SVector::<T, 12>::zeros();
        for (i, ((r_column, f), (x_i, si))) in
            reflected.data.0.iter_mut().zip(force.iter_mut()).zip(rows.data.0.iter().zip(selected.iter())).enumerate()
        {
            if !si {
                continue;
            }
            *f = dot(x_i, torque_row);
            // Column i, rows j ≥ i (the lower triangle the factorisation reads).
            for (j, ((r, x_j), sj)) in
                r_column.iter_mut().zip(rows.data.0.iter()).zip(selected.iter()).enumerate().skip(i)
            {
                if *sj {
                    *r = dot(x_i, x_j) + if i == j { regularisation } else { T::zero() };
                }
            }
        }
        (true, reflected, force)
    }
}

/// One step of the governor of one axis: correction `c`, applied force `a`, the finite bounds,
/// `step = k_F dt`, `|c| ≤ max` (module docs).
pub fn governor_step<T: RealField + Copy>(c: T, a: T, lower: Option<T>, upper: Option<T>, step: T, max: T) -> T {
    let zero = T::zero();
    match (upper, lower) {
        (Some(u), _) if c > zero || (c == zero && a > u) => (c + step * (a - u)).max(zero).min(max),
        (_, Some(l)) if c < zero || (c == zero && a < l) => (c + step * (a - l)).min(zero).max(-max),
        _ => zero,
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "test code: failures should panic")]
mod tests {
    use super::*;

    macro_rules! for_scalars {
        ($name:ident, $body:ident) => {
            mod $name {
                #[test]
                fn f64() {
                    super::$body::<f64>();
                }
                #[test]
                fn f32() {
                    super::$body::<f32>();
                }
            }
        };
    }

    fn c<T: RealField + Copy>(x: f64) -> T {
        nalgebra::convert(x)
    }

    /// The plain limiter (nalgebra products, `Cholesky::new`/`solve`, 12 full solves with the
    /// N × N factor): the reference for the loops of [`ForceLimiter::update`] and
    /// [`ForceLimiter::limit_command`].
    struct Reference<T: RealField, const N: usize>(ForceLimiter<T, N>);

    impl<T: RealField + Copy, const N: usize> Reference<T, N> {
        fn bounds(&self, index: usize, lower: &Vector6<T>, upper: &Vector6<T>) -> (Vector6<T>, Vector6<T>) {
            self.0.bounds(index, lower, upper)
        }
        #[allow(clippy::too_many_arguments)]
        fn update<const B: usize, const F: usize>(
            &mut self,
            parameters: &ForceLimitParameters<T>,
            model: &Model<T, N, B, F>,
            data: &Data<T, N, B, F>,
            layout: &RobotLayout<N>,
            residual: &SVector<T, N>,
            hands: &[Option<HandLimits<T>>; 2],
            dt: T,
        ) -> Result<(), DynamicsError> {
            let mut full = [SMatrix::<T, 6, N>::zeros(); 2];
            let mut upper = [SMatrix::<T, 6, N>::zeros(); 2];
            for ((tcp, limits), (jacobian, upper_body)) in
                layout.tcp.iter().zip(hands.iter()).zip(full.iter_mut().zip(upper.iter_mut()))
            {
                let axes = limits.map_or_else(Matrix3::identity, |l| l.axes);
                let mut world = SMatrix::<T, 6, N>::zeros();
                frame_jacobian(model, data, *tcp, &mut world)?;
                let at = axes.transpose();
                jacobian.fixed_rows_mut::<3>(0).copy_from(&(at * world.fixed_rows::<3>(0)));
                jacobian.fixed_rows_mut::<3>(3).copy_from(&(at * world.fixed_rows::<3>(3)));
                *upper_body = *jacobian;
                for (k, mut column) in upper_body.column_iter_mut().enumerate() {
                    if layout.platform.is_platform(k) {
                        column.fill(T::zero());
                    }
                }
            }
            // Constant offsets only: a run-time offset into `fixed_rows` keeps nalgebra's bounds
            // assertion (a panic path) in the image.
            let [right, left] = &upper;
            let mut stacked = SMatrix::<T, 12, N>::zeros();
            stacked.fixed_rows_mut::<6>(0).copy_from(right);
            stacked.fixed_rows_mut::<6>(6).copy_from(left);
            let gram = stacked * stacked.transpose() + SMatrix::<T, 12, 12>::identity() * parameters.regularisation;
            self.0.stacked = stacked;
            self.0.effective = [None; 2];
            let Some(factor) = Cholesky::new(gram) else {
                self.0.applied = [Vector6::zeros(); 2];
                self.0.relief = SVector::zeros();
                return Ok(());
            };
            let external = factor.solve(&(stacked * residual));
            if !crate::math::all_finite(&external) {
                self.0.applied = [Vector6::zeros(); 2];
                self.0.relief = SVector::zeros();
                return Ok(());
            }
            self.0.relief = SVector::zeros();
            let step = parameters.gain * dt;
            let wrenches: [Vector6<T>; 2] =
                [external.fixed_rows::<6>(0).into_owned(), external.fixed_rows::<6>(6).into_owned()];
            for (h, ((limits, jacobian), wrench)) in hands.iter().zip(full.iter()).zip(wrenches).enumerate() {
                let applied = -wrench;
                if let Some(a) = self.0.applied.get_mut(h) {
                    *a = applied;
                }
                let Some(correction) = self.0.correction.get_mut(h) else { continue };
                let Some(limits) = limits.filter(|_| parameters.enabled) else {
                    *correction = Vector6::zeros();
                    continue;
                };
                let share = T::one() - parameters.margin;
                let limits = HandLimits { lower: limits.lower * share, upper: limits.upper * share, ..limits };
                let mut reaction = Vector6::zeros();
                for axis in 0..6 {
                    let get = |v: &Vector6<T>| v.get(axis).copied().unwrap_or_else(T::zero);
                    let (a, lower, upper) = (get(&applied), get(&limits.lower), get(&limits.upper));
                    let lower = Some(lower).filter(|x| x.is_finite());
                    let upper = Some(upper).filter(|x| x.is_finite());
                    if let Some(c) = correction.get_mut(axis) {
                        *c = governor_step(*c, a, lower, upper, step, parameters.max_correction);
                    }
                    let pressing = (upper.is_some() && a > T::zero()) || (lower.is_some() && a < T::zero());
                    if let (true, Some(r)) = (pressing, reaction.get_mut(axis)) {
                        *r = get(&wrench);
                    }
                }
                let bounds = self.bounds(h, &limits.lower, &limits.upper);
                if let Some(e) = self.0.effective.get_mut(h) {
                    *e = Some(bounds);
                }
                let torque = jacobian.transpose() * reaction;
                for (k, (r, t)) in self.0.relief.iter_mut().zip(torque.iter()).enumerate() {
                    if layout.platform.is_platform(k) {
                        *r += *t;
                    }
                }
            }
            Ok(())
        }

        fn limit_command(
            &self,
            regularisation: T,
            task_torque: &SVector<T, N>,
            factor: &Cholesky<T, Const<N>>,
            damping: &[Vector6<T>; 2],
        ) -> CommandLimit<T, N> {
            let none = CommandLimit { torque: SVector::zeros(), limited: [[false; 6]; 2] };
            // The limited rows L: an axis of a hand with an enabled limit and a finite bound.
            let mut selected = [false; 12];
            for (h, bounds) in self.0.effective.iter().enumerate() {
                let Some((lower, upper)) = bounds else { continue };
                for (axis, (low, high)) in lower.iter().zip(upper.iter()).enumerate() {
                    if let Some(s) = selected.get_mut(6 * h + axis) {
                        *s = low.is_finite() || high.is_finite();
                    }
                }
            }
            if !selected.iter().any(|s| *s) {
                return none;
            }
            // M⁻¹ J_uᵀ, then the reflected inertia of L (identity on the other rows) and J_L M⁻¹ τ.
            let mobility = factor.solve(&self.0.stacked.transpose());
            let mut reflected = self.0.stacked * mobility;
            let mut rhs = mobility.transpose() * task_torque;
            for (i, mut row) in reflected.row_iter_mut().enumerate() {
                let row_selected = selected.get(i).copied().unwrap_or(false);
                for (j, x) in row.iter_mut().enumerate() {
                    let both = row_selected && selected.get(j).copied().unwrap_or(false);
                    *x = match (i == j, both) {
                        (true, true) => *x + regularisation,
                        (true, false) => T::one(),
                        (false, true) => *x,
                        (false, false) => T::zero(),
                    };
                }
            }
            for (r, s) in rhs.iter_mut().zip(selected.iter()) {
                if !s {
                    *r = T::zero();
                }
            }
            let Some(force) = Cholesky::new(reflected).map(|f| f.solve(&rhs)).filter(crate::math::all_finite) else {
                return none;
            };
            let mut excess = SVector::<T, 12>::zeros();
            let mut limited = [[false; 6]; 2];
            for (h, ((bounds, flags), damping)) in
                self.0.effective.iter().zip(limited.iter_mut()).zip(damping.iter()).enumerate()
            {
                let Some((lower, upper)) = bounds else { continue };
                for (axis, flag) in flags.iter_mut().enumerate() {
                    let row = 6 * h + axis;
                    let get = |v: &Vector6<T>| v.get(axis).copied().unwrap_or_else(T::zero);
                    let (Some(f), Some(e)) = (force.get(row), excess.get_mut(row)) else { continue };
                    let d = get(damping);
                    let (low, high) = (get(lower) + d.max(T::zero()), get(upper) + d.min(T::zero()));
                    let over = *f - f.max(low).min(high);
                    *e = over;
                    *flag = over != T::zero();
                }
            }
            CommandLimit { torque: -(self.0.stacked.transpose() * excess), limited }
        }
    }

    /// A quasi-static contact: the applied force is the (effective) bound plus a disturbance
    /// `d` the task cannot see, seen through the observer's first-order lag `K_O`.
    fn governor_settles_at_the_limit<T: RealField + Copy>() {
        let (k_o, dt, limit, d) = (c::<T>(50.0), c::<T>(1e-3), c::<T>(10.0), c::<T>(3.0));
        let (mut correction, mut estimate) = (T::zero(), T::zero());
        let mut peak = T::zero();
        for _ in 0..2000 {
            let applied = limit - correction.max(T::zero()) + d;
            estimate += k_o * dt * (applied - estimate);
            correction = governor_step(correction, estimate, None, Some(limit), k_o / c(4.0) * dt, c(20.0));
            peak = peak.max(applied);
        }
        let applied = limit - correction + d;
        assert!((applied - limit).abs() < c(1e-2), "settles at the limit");
        assert!((correction - d).abs() < c(1e-2));
        assert!(peak <= limit + d + c(1e-3), "no overshoot beyond the first excess");
        // Disturbance gone: relaxes back to zero.
        for _ in 0..2000 {
            let applied = limit - correction.max(T::zero());
            estimate += k_o * dt * (applied - estimate);
            correction = governor_step(correction, estimate, None, Some(limit), k_o / c(4.0) * dt, c(20.0));
        }
        assert!(correction.abs() < c(1e-2));
    }
    for_scalars!(settles, governor_settles_at_the_limit);

    fn governor_sides_and_bounds<T: RealField + Copy>() {
        let step = c::<T>(0.1);
        // Inside both bounds at zero: stays zero; unlimited axes are never governed.
        assert_eq!(governor_step(T::zero(), c(5.0), Some(c(-20.0)), Some(c(20.0)), step, c(10.0)), T::zero());
        assert_eq!(governor_step(c(3.0), c(50.0), None, None, step, c(10.0)), T::zero());
        // Above the upper bound: positive, clamped to the maximum.
        assert_eq!(governor_step(T::zero(), c(30.0), None, Some(c(20.0)), step, c(10.0)), c(1.0));
        assert_eq!(governor_step(c(9.5), c(30.0), None, Some(c(20.0)), step, c(10.0)), c(10.0));
        // Below the lower bound: negative.
        assert_eq!(governor_step(T::zero(), c(-30.0), Some(c(-20.0)), None, step, c(10.0)), c(-1.0));
        // Relaxation stops at zero, never crosses to the other side.
        assert_eq!(governor_step(c(0.5), c(0.0), Some(c(-20.0)), Some(c(20.0)), step, c(10.0)), T::zero());
        let limiter = ForceLimiter::<T, 3> {
            correction: [Vector6::new(c(2.0), c(-1.0), T::zero(), T::zero(), T::zero(), T::zero()), Vector6::zeros()],
            ..ForceLimiter::new()
        };
        let (lower, upper) = limiter.bounds(0, &Vector6::repeat(c(-20.0)), &Vector6::repeat(c(20.0)));
        assert_eq!((lower[0], upper[0]), (c(-20.0), c(18.0)));
        assert_eq!((lower[1], upper[1]), (c(-19.0), c(20.0)));
        assert_eq!(limiter.bounds(7, &lower, &upper), (lower, upper));
    }
    for_scalars!(sides, governor_sides_and_bounds);

    /// The estimate on a 3-DOF model: platform slider x, an upper-body slider x and one along z,
    /// TCP on the last body. A wrench on the TCP gives `τ_ext = Jᵀ F`; the platform column is
    /// not observed; the estimate recovers the observable forces and the relief is their
    /// reaction on the platform along the limited axis.
    /// A 3-DOF model: platform slider x, an upper-body slider x and one along z, 1 kg on each
    /// body, TCP on the last one (both hands' frame); kinematics and `M` at rest.
    fn sliders<T: RealField + Copy>() -> (Model<T, 3, 3, 1>, Data<T, 3, 3, 1>, RobotLayout<3>) {
        use crate::dynamics::{crba, forward_kinematics};
        use crate::math::Placement;
        use crate::model::{Inertia, JointDrive, JointKind, ModelBuilder};
        use crate::platform::{PlatformAxis, PlatformLayout};
        use nalgebra::{Unit, Vector3};
        let mut b = ModelBuilder::<T, 3, 3, 1>::new(Vector3::zeros());
        let mut parent = None;
        for (i, axis) in [Vector3::x(), Vector3::x(), Vector3::z()].into_iter().enumerate() {
            parent = Some(
                b.add_body(
                    parent,
                    Placement::identity(),
                    JointKind::Prismatic { axis: Unit::new_normalize(axis) },
                    JointDrive::actuated(i),
                    Inertia::point_mass(c(1.0), Vector3::zeros()),
                )
                .unwrap(),
            );
        }
        let tcp = b.add_frame(parent, Placement::identity()).unwrap();
        let model = b.try_build().unwrap();
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &SVector::zeros(), &SVector::zeros()).unwrap();
        crba(&model, &mut data);
        let platform =
            PlatformLayout::try_new::<3>([PlatformAxis::Admitted(0), PlatformAxis::Absent, PlatformAxis::Absent])
                .unwrap();
        (
            model,
            data,
            RobotLayout { tcp: [tcp, tcp], platform, torso: [false; 3], arms: [[false, true, true], [false; 3]] },
        )
    }

    /// The loops of [`ForceLimiter::update`] and [`ForceLimiter::limit_command`] against the
    /// plain [`Reference`] on the branched test model (platform slider 0, both TCP frames,
    /// turned desired frames), over 40 governed cycles with random residuals, torques, limits
    /// and damping: same estimate, corrections, relief, flags and command torque (the command
    /// also on the tree-sparse factor).
    fn loops_match_the_reference<T: RealField + Copy>(regularisation: f64, tolerance: f64) {
        use crate::dynamics::{crba, forward_kinematics};
        use crate::platform::{PlatformAxis, PlatformLayout};
        use crate::test_models::{branched, state, N, TCP, WRIST};
        use nalgebra::Rotation3;
        let model = branched::<T>();
        let platform =
            PlatformLayout::try_new::<N>([PlatformAxis::Admitted(0), PlatformAxis::Absent, PlatformAxis::Absent])
                .unwrap();
        let layout = RobotLayout {
            tcp: [TCP, WRIST],
            platform,
            torso: [false, true, true, false, false, false],
            arms: [[false, false, false, true, false, false], [false, false, false, false, true, true]],
        };
        let (mut fast, mut plain) = (ForceLimiter::<T, N>::new(), Reference(ForceLimiter::<T, N>::new()));
        let parameters = ForceLimitParameters {
            enabled: true,
            margin: c(0.1),
            gain: c(20.0),
            max_correction: c(15.0),
            regularisation: c(regularisation),
        };
        let to_f64 = |x: T| -> f64 { nalgebra::try_convert(x).unwrap() };
        let mut worst = 0.0_f64;
        let mut limited_rows = 0;
        for cycle in 0..40_u64 {
            let q: SVector<T, N> = state(cycle, 1.5).cast();
            let mut data = Data::new(&model);
            forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
            crba(&model, &mut data);
            let factor = Cholesky::new(data.mass_matrix).unwrap();
            let residual: SVector<T, N> = (state(cycle ^ 3, 40.0) - state(cycle ^ 5, 40.0)).cast();
            let hand = |seed: u64| {
                let s = state(seed, 1.0);
                let mut upper = Vector6::repeat(f64::INFINITY);
                let mut lower = Vector6::repeat(f64::NEG_INFINITY);
                upper[(seed % 6) as usize] = 5.0;
                lower[((seed + 2) % 6) as usize] = -3.0;
                if seed % 4 == 0 {
                    upper[((seed + 4) % 6) as usize] = 2.0;
                }
                HandLimits {
                    axes: Rotation3::from_scaled_axis(nalgebra::Vector3::new(s[0], s[1], s[2])).into_inner(),
                    lower,
                    upper,
                }
                .cast_limits::<T>()
            };
            let hands = [Some(hand(cycle * 7 + 1)), if cycle % 3 == 0 { None } else { Some(hand(cycle * 5 + 2)) }];
            let dt = c(1e-3);
            fast.update(&parameters, &model, &data, &layout, &residual, &hands, dt).unwrap();
            plain.update(&parameters, &model, &data, &layout, &residual, &hands, dt).unwrap();
            let scale = to_f64(residual.amax()) + 1.0;
            for h in 0..2 {
                worst = worst.max(to_f64((fast.applied[h] - plain.0.applied[h]).amax()) / scale);
                worst = worst.max(to_f64((fast.correction[h] - plain.0.correction[h]).amax()) / scale);
            }
            worst = worst.max(to_f64((fast.relief - plain.0.relief).amax()) / scale);
            worst = worst.max(to_f64((fast.stacked - plain.0.stacked).amax()));
            let torque: SVector<T, N> = (state(cycle ^ 11, 60.0) - state(cycle ^ 13, 60.0)).cast();
            let damping = [Vector6::from_fn(|i, _| c((i as f64 - 2.5) * 0.7)), Vector6::zeros()];
            let a = fast.limit_command(parameters.regularisation, &torque, &factor, &damping);
            let b = plain.limit_command(parameters.regularisation, &torque, &factor, &damping);
            assert_eq!(a.limited, b.limited, "cycle {cycle}");
            limited_rows += a.limited.iter().flatten().filter(|f| **f).count();
            let command = to_f64((a.torque - b.torque).amax()) / (to_f64(b.torque.amax()) + 1.0);
            worst = worst.max(command);
            // The same limit on the tree-sparse factor M = LᵀL.
            let mut tree = TreeFactorization::new(&model);
            tree.factorize(&data.mass_matrix).unwrap();
            let t = fast.limit_command(parameters.regularisation, &torque, &tree, &damping);
            assert_eq!(t.limited, b.limited, "tree, cycle {cycle}");
            worst = worst.max(to_f64((t.torque - b.torque).amax()) / (to_f64(b.torque.amax()) + 1.0));
            assert!(worst <= tolerance, "cycle {cycle}: relative difference {worst:e}");
        }
        assert!(limited_rows > 10, "the command-side limit acted ({limited_rows} rows)");
        eprintln!("force limiter fast vs reference: {worst:e}");
    }

    impl HandLimits<f64> {
        fn cast_limits<T: RealField + Copy>(&self) -> HandLimits<T> {
            HandLimits { axes: self.axes.cast(), lower: self.lower.cast(), upper: self.upper.cast() }
        }
    }

    #[test]
    fn loops_match_the_reference_f64() {
        loops_match_the_reference::<f64>(1e-4, 1e-10);
    }

    #[test]
    fn loops_match_the_reference_f32() {
        // μ = 1e-2: the Gram matrix of the 5 upper-body columns has rank 5 of 12, its condition
        // is about 1/μ (and that of J_L M⁻¹ J_Lᵀ + μ I similar): f32 rounding of both versions
        // scales with it; a wrong entry would differ by O(1).
        loops_match_the_reference::<f32>(1e-2, 1e-3);
    }

    /// `+10 N` on the right TCP's x, nothing else.
    fn wiper_limits<T: RealField + Copy>() -> HandLimits<T> {
        let mut upper = Vector6::repeat(c(f64::INFINITY));
        upper[0] = c(10.0);
        HandLimits { axes: Matrix3::identity(), lower: Vector6::repeat(c(f64::NEG_INFINITY)), upper }
    }

    fn estimate_recovers_the_contact<T: RealField + Copy>() {
        let (model, data, layout) = sliders::<T>();
        // The window pushes back with 30 N along −x on a TCP pressing along +x.
        let residual = SVector::<T, 3>::new(T::zero(), c(-30.0), c(0.0));
        let limits = wiper_limits::<T>();
        let parameters = ForceLimitParameters {
            enabled: true,
            margin: c(0.0),
            gain: c(12.5),
            max_correction: c(10.0),
            regularisation: c(1e-6),
        };
        let mut limiter = ForceLimiter::<T, 3>::new();
        limiter.update(&parameters, &model, &data, &layout, &residual, &[Some(limits), None], c(1e-3)).unwrap();
        // Both hands share the frame here: the estimate splits the 30 N between them (15 N each, over the 10 N limit).
        let total = limiter.applied()[0][0] + limiter.applied()[1][0];
        assert!((total - c(30.0)).abs() < c(1e-3), "{total}");
        assert!(limiter.correction()[0][0] > T::zero());
        assert_eq!(limiter.correction()[1], Vector6::zeros());
        // Relief: the reaction of the right hand's share on the platform x, zero elsewhere.
        assert!((limiter.platform_relief()[0] + limiter.applied()[0][0]).abs() < c(1e-3));
        assert_eq!(limiter.platform_relief()[1], T::zero());
        // Disabled: estimate only, no correction, no relief.
        let disabled = ForceLimitParameters { enabled: false, ..parameters };
        limiter.update(&disabled, &model, &data, &layout, &residual, &[Some(limits), None], c(1e-3)).unwrap();
        assert_eq!(limiter.correction()[0], Vector6::zeros());
        assert_eq!(limiter.platform_relief()[0], T::zero());
        limiter.reset();
        assert_eq!(limiter, ForceLimiter::new());
    }
    for_scalars!(estimate, estimate_recovers_the_contact);

    /// The command-side limit on the sliders: `M = [[3, 2, 0], [2, 2, 0], [0, 0, 1]]`, the TCP x
    /// row of `J_u` is `(0, 1, 0)` (platform column zero), so a task torque `τ` presses a rigid
    /// contact along x with `λ = (J M⁻¹ Jᵀ)⁻¹ J M⁻¹ τ = τ₁` (z decoupled). The returned torque puts
    /// the rigid-contact force of the limited torque exactly on the bound (checked with `M⁻¹`
    /// computed independently), leaves the unlimited axis alone, keeps the damping that pulls
    /// away from the bound, applies the margin, and is zero below the bound and when disabled.
    fn command_side_limit_puts_the_contact_force_on_the_bound<T: RealField + Copy>() {
        let (model, data, layout) = sliders::<T>();
        let factor = Cholesky::new(data.mass_matrix).unwrap();
        let inverse = data.mass_matrix.try_inverse().unwrap();
        let row = nalgebra::RowVector3::new(T::zero(), T::one(), T::zero());
        let contact = |tau: &SVector<T, 3>| (row * inverse * tau)[0] / (row * inverse * row.transpose())[0];
        let run = |margin: f64, enabled: bool, tau: SVector<T, 3>, damping_x: f64| {
            let parameters = ForceLimitParameters {
                enabled,
                margin: c(margin),
                gain: c(3.0),
                max_correction: c(10.0),
                regularisation: c(1e-6),
            };
            let mut limiter = ForceLimiter::<T, 3>::new();
            limiter
                .update(&parameters, &model, &data, &layout, &SVector::zeros(), &[Some(wiper_limits()), None], c(1e-3))
                .unwrap();
            let mut damping = [Vector6::zeros(); 2];
            damping[0][0] = c(damping_x);
            limiter.limit_command(parameters.regularisation, &tau, &factor, &damping)
        };
        let close = |a: T, b: f64| (a - c(b)).abs() < c(1e-3);
        let tau = SVector::<T, 3>::new(T::zero(), c(30.0), c(5.0));
        assert!(close(contact(&tau), 30.0));
        let limit = run(0.0, true, tau, 0.0);
        assert!(close(contact(&(tau + limit.torque)), 10.0), "{}", contact(&(tau + limit.torque)));
        assert!(close(limit.torque[1], -20.0) && limit.torque[0] == T::zero() && close(limit.torque[2], 0.0));
        assert_eq!(limit.limited[0], [true, false, false, false, false, false]);
        assert_eq!(limit.limited[1], [false; 6]);
        // Damping pushing towards the bound is dropped: the total is held at the bound.
        assert!(close(contact(&(tau + run(0.0, true, tau, 3.0).torque)), 10.0));
        // Damping pulling away from it acts on top of the bound: 10 − 3 N in total.
        assert!(close(contact(&(tau + run(0.0, true, tau, -3.0).torque)), 7.0));
        // The margin shrinks the bound to (1 − m) · 10 N.
        assert!(close(contact(&(tau + run(0.1, true, tau, 0.0).torque)), 9.0));
        // Below the bound, or disabled: nothing.
        let below = SVector::<T, 3>::new(T::zero(), c(6.0), c(5.0));
        assert_eq!(run(0.0, true, below, 0.0).torque, SVector::<T, 3>::zeros());
        assert_eq!(run(0.0, false, tau, 0.0), CommandLimit { torque: SVector::zeros(), limited: [[false; 6]; 2] });
    }
    for_scalars!(command_side, command_side_limit_puts_the_contact_force_on_the_bound);
}
