//! Workspace of the tendon-coupled torso (Sec. 3.3, App. A): its kinematic and load-dependent
//! dynamic boundaries, the distance of the torso centre point to each of them, and the
//! repulsive potential with damping (3.53) as unilateral task rows.
//!
//! # Model
//! Justin's torso pitches with two driven joints `q_t2`, `q_t3`; tendons keep the chest upright
//! through the passive joint `q_t4 = −(q_t2 + q_t3)` (3.41). The torso centre point `p_t`
//! (the `q_t4` axis) moves in the torso's X-Z plane ([`TorsoGeometry`] and [`direction`]
//! define `x`, `z` and the angle convention): `p_t = l_t2 e(q_t2) + l_t3 e(q_t2 + q_t3)` (3.42).
//!
//! # Boundaries ([`Boundary`], twelve in a fixed order)
//! - **Kinematic** (Table 3.2 → Table A.1): six arcs, one per range limit of `q_t2`, `q_t3`,
//!   `q_t2 + q_t3`.
//! - **Dynamic, joint 2** (3.48): two straight lines where the torque that holds the load
//!   `F_t` (3.44) at `p_t` reaches `τ_t2,min` or `τ_t2,max`.
//! - **Dynamic, joint 3** (3.49)–(3.52), Table A.2: up to four half circles where that torque
//!   reaches `τ_t3,min` or `τ_t3,max`. Each limit excludes the band of angle sums between its
//!   two circles and exists only if `F_t,load l_t3 > |τ|` ("at the point of overlapping, the
//!   constraints vanish", Fig. 3.16d).
//!
//! # Distance to a boundary
//! The Euclidean distance (m) in the torso plane from `p_t` to the boundary curve, signed
//! positive on the feasible side: to the arc segment itself for arcs (not to the full circle,
//! which can pass through the inside of the workspace), to the full line for the joint-2
//! limits. The sign comes from the joint-space side of the limit, so a folded configuration
//! (`q_t3 < 0`, mapped onto the same points as `q_t3 > 0`) is reported as violated. A joint-3
//! band is left through its nearer side: each of its two circles governs the angle sums on its
//! own half of the band (and beyond it); a circle outside the kinematic workspace is absent
//! and the present one governs the whole band.
//!
//! # Repulsion (3.53)
//! Each boundary is one unilateral row with the potential of (3.8) in its distance `d`,
//! `V(d) = F_max/(3 d₀²) (d₀ − d)³` for `d < d₀`, else 0: C² at the activation distance
//! `d₀` (value, force and stiffness vanish there, Sec. 3.1.2), force `f = −∂V/∂d =
//! F_max/d₀² (d₀ − d)²` pushing `p_t` away from the boundary, local stiffness
//! `k = ∂²V/∂d² = 2 F_max (d₀ − d)/d₀²` (largest, `2 F_max/d₀`, at the boundary). The rows of
//! all boundaries are summed (`V_tws = Σ V(d_i)`) rather than taking only the nearest one: the
//! nearest boundary switches on the medial axis of the workspace, where a single row would
//! make the force direction jump; near one boundary the sum is the thesis' "repulsion from
//! the nearest boundary", near a corner both walls push. Damping as in Sec. 3.1.3 with the
//! stiffness `k` and the reflected mass `m = (j M⁻¹ jᵀ)⁻¹` of the row: the 1-D double
//! diagonalisation gives `D = 2 ξ √(k m)`. Gravity `g(q)` of (3.53) is compensated elsewhere.
//!
//! The Jacobian row is `j = (∂d/∂p_t)ᵀ J_t` (3.43) in the columns of `q_t2`, `q_t3`. At the
//! outstretched torso (`q_t3 = 0`, arc 5) `J_t` is singular with the radial direction in its
//! left null space, so the row of arc 5 vanishes there (the distance is quadratic in `q_t3`):
//! the thesis adds a separate singularity avoidance against it (Sec. 3.3.5).
//!
//! **Unilateral-row convention** (as [`super::end_stops`]): [`torso_workspace`] always emits
//! exactly [`BOUNDARIES`] rows in [`Boundary::ALL`] order. A row whose boundary is absent (no
//! load, no joint-3 band, arc outside the workspace) or not governing has `j = 0`, `f = 0`,
//! `V = 0`, `a = 0`. The activation is the cubic (4.68)
//! ([`crate::math::switching::transition_activation`]) of the distance, 1 at
//! [`RepulsionGains::activation_full`], 0 from [`RepulsionGains::activation_start`] on.

mod boundary;
mod distance;
mod dynamic_limits;
mod kinematics;

pub use boundary::{Boundary, RepulsionGains, BOUNDARIES};
pub use dynamic_limits::{joint2_lines, load_torque, TorqueBand, TorqueLimits, TorqueLine, TorsoLoad};
pub use kinematics::{direction, Arc, JointLine, Range, TorsoGeometry};

use nalgebra::{Cholesky, Const, RealField, SMatrix, SVector, Vector2};

use crate::dynamics::{InertiaFactor, TreeFactorization};

use self::distance::ArcBoundary;
use self::kinematics::{wrap_from, wrap_to_pi};
use super::{RowSink, TaskError};
use crate::math::cholesky::solve_lower_in_place;
use crate::math::sqrt;
use crate::math::switching::transition_activation;
#[cfg(test)]
use {
    super::{TaskRow, TaskRows},
    nalgebra::RowSVector,
};

/// Everything the torso-workspace task needs. Validate with [`TorsoWorkspace::try_new`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TorsoWorkspaceConfig<T> {
    /// Link lengths and joint ranges.
    pub geometry: TorsoGeometry<T>,
    /// Actuator torque limits of `q_t2`, `q_t3`.
    pub torque_limits: TorqueLimits<T>,
    /// The load at the torso centre point.
    pub load: TorsoLoad<T>,
    /// Potential, damping and activation.
    pub gains: RepulsionGains<T>,
    /// Indices of `q_t2` and `q_t3` in the coordinate vector (`[4, 5]` for the Justin-like
    /// model).
    pub coordinates: [usize; 2],
}

/// A boundary's curve in the torso plane, for plotting and planning.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BoundaryCurve<T> {
    /// The boundary does not exist for this load, or misses the kinematic workspace.
    Absent,
    /// A circular arc (kinematic limits, joint-3 torque limits).
    Arc(Arc<T>),
    /// A straight line (joint-2 torque limits).
    Line(TorqueLine<T>),
}

/// The joint-space side of an arc boundary and, for joint-3 torque bands, which angle sums
/// the arc governs.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Side<T> {
    /// A range limit: feasible where `±(line offset) ≥ 0`.
    Limit { line: JointLine<T>, above: bool },
    /// One circle of a joint-3 torque band: the upper (`above`) or lower edge.
    Band { band: TorqueBand<T>, above: bool, governs_all: bool },
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Shape<T> {
    Absent,
    Arc(ArcBoundary<T>, Side<T>),
    Line(TorqueLine<T>),
}

/// The state of the torso relative to its workspace (one call of [`torso_workspace`] or
/// [`TorsoWorkspace::report`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TorsoWorkspaceReport<T> {
    /// Torso centre point `p_t = (x, z)` (m), (3.42).
    pub center: Vector2<T>,
    /// Signed distance (m) to each boundary in [`Boundary::ALL`] order; positive on the
    /// feasible side. `None`: the boundary is absent, or (joint-3 bands) the other circle of
    /// the band governs this angle sum.
    pub distances: [Option<T>; BOUNDARIES],
    /// Torques `(τ_t2, τ_t3)` (Nm) that hold the configured load here, (3.45).
    pub load_torque: Vector2<T>,
    /// `(q_t2, q_t3)` within the ranges of Table 3.2.
    pub kinematically_feasible: bool,
    /// [`TorsoWorkspaceReport::load_torque`] within the torque limits (3.46)–(3.47).
    pub dynamically_feasible: bool,
}

impl<T: RealField + Copy> TorsoWorkspaceReport<T> {
    /// Signed distance to `boundary` (m), if it is present and governing.
    pub fn distance(&self, boundary: Boundary) -> Option<T> {
        self.distances.get(boundary.index()).copied().flatten()
    }

    /// The nearest boundary and its signed distance (m) (smallest signed distance, so a
    /// violated boundary comes first).
    pub fn nearest(&self) -> Option<(Boundary, T)> {
        Boundary::ALL.iter().zip(self.distances.iter()).filter_map(|(b, d)| d.map(|d| (*b, d))).fold(
            None,
            |best, (b, d)| match best {
                Some((_, e)) if e <= d => best,
                _ => Some((b, d)),
            },
        )
    }
}

/// The validated torso-workspace task with its boundaries for the current load.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TorsoWorkspace<T, const N: usize> {
    config: TorsoWorkspaceConfig<T>,
    shapes: [Shape<T>; BOUNDARIES],
}

impl<T: RealField + Copy, const N: usize> TorsoWorkspace<T, N> {
    /// Validates `config` (geometry, torque limits, load, gains, two distinct coordinates
    /// `< N`) and computes the boundaries. Errors: [`TaskError::InvalidParameter`].
    ///
    /// ```
    /// use kernel::tasks::torso_workspace::*;
    /// let config = TorsoWorkspaceConfig {
    ///     geometry: TorsoGeometry::<f64>::from_degrees([0.3, 0.3], [-90.0, 90.0], [0.0, 135.0], [0.0, 135.0]),
    ///     torque_limits: TorqueLimits::symmetric(230.0),
    ///     load: TorsoLoad::from_degrees(800.0, 90.0),
    ///     gains: RepulsionGains::thesis_experiment(),
    ///     coordinates: [0, 1],
    /// };
    /// let task = TorsoWorkspace::<f64, 2>::try_new(config).unwrap();
    /// // Upright torso, 800 N downwards: x = 0, so 230 Nm / 800 N = 0.2875 m to each τ_t2 line.
    /// let report = task.report(0.0, 0.0);
    /// assert!((report.distance(Boundary::Torque2Max).unwrap() - 0.2875).abs() < 1e-12);
    /// ```
    pub fn try_new(config: TorsoWorkspaceConfig<T>) -> Result<Self, TaskError> {
        config.geometry.validate()?;
        config.torque_limits.validate()?;
        config.load.validate()?;
        config.gains.validate()?;
        let [i2, i3] = config.coordinates;
        if i2 == i3 || i2 >= N || i3 >= N {
            return Err(TaskError::InvalidParameter { name: "coordinates" });
        }
        let mut task = Self { config, shapes: [Shape::Absent; BOUNDARIES] };
        task.update_shapes();
        Ok(task)
    }

    /// The validated configuration.
    pub fn config(&self) -> &TorsoWorkspaceConfig<T> {
        &self.config
    }

    /// Changes the load (e.g. a new payload from the planner, Table 7.1) and recomputes the
    /// dynamic boundaries. Errors (the task is unchanged): [`TaskError::InvalidParameter`].
    pub fn set_load(&mut self, load: TorsoLoad<T>) -> Result<(), TaskError> {
        load.validate()?;
        self.config.load = load;
        self.update_shapes();
        Ok(())
    }

    /// The curve of `boundary` in the torso plane.
    pub fn curve(&self, boundary: Boundary) -> BoundaryCurve<T> {
        match self.shapes.get(boundary.index()) {
            Some(Shape::Arc(arc, _)) => BoundaryCurve::Arc(arc.arc),
            Some(Shape::Line(line)) => BoundaryCurve::Line(*line),
            Some(Shape::Absent) | None => BoundaryCurve::Absent,
        }
    }

    /// The state of `(q_t2, q_t3)` (rad) relative to the workspace: `p_t`, the signed distance
    /// to every boundary, the load torques and the feasibility flags. Cost O(1) (12 distances).
    pub fn report(&self, q2: T, q3: T) -> TorsoWorkspaceReport<T> {
        self.evaluate(q2, q3).0
    }

    /// Report plus, per boundary, the gradient `∂d/∂p_t` (zero where absent).
    fn evaluate(&self, q2: T, q3: T) -> (TorsoWorkspaceReport<T>, [Vector2<T>; BOUNDARIES]) {
        let c = &self.config;
        let p = c.geometry.center(q2, q3);
        let tiny = (c.geometry.link2 + c.geometry.link3) * T::default_epsilon() * nalgebra::convert::<f64, T>(64.0);
        let mut distances = [None; BOUNDARIES];
        let mut gradients = [Vector2::zeros(); BOUNDARIES];
        for ((shape, distance), gradient) in self.shapes.iter().zip(distances.iter_mut()).zip(gradients.iter_mut()) {
            let value = match shape {
                Shape::Absent => None,
                Shape::Line(line) => Some((line.normal.dot(&p) + line.offset, line.normal)),
                Shape::Arc(arc, side) => {
                    governing_side(side, q2, q3).map(|feasible| arc.signed_distance(&p, feasible, tiny))
                }
            };
            if let Some((d, g)) = value {
                *distance = Some(d);
                *gradient = g;
            }
        }
        let load_torque = load_torque(&c.geometry, &c.load, q2, q3);
        let report = TorsoWorkspaceReport {
            center: p,
            distances,
            load_torque,
            kinematically_feasible: c.geometry.contains(q2, q3),
            dynamically_feasible: c.torque_limits.contains(&load_torque),
        };
        (report, gradients)
    }

    fn update_shapes(&mut self) {
        let c = self.config;
        let g = &c.geometry;
        let limit = |line: JointLine<T>, above: bool| {
            // Near the arc the feasible side is inside the circle for a lower limit of q_t3 or
            // of the sum and for an upper limit of q_t2 (see `kinematics`: increasing q_t3 or
            // the sum at fixed q_t2 moves p_t inwards, increasing q_t2 at fixed sum outwards).
            let inside = match line {
                JointLine::Joint2(_) => !above,
                JointLine::Joint3(_) | JointLine::Sum(_) => above,
            };
            g.arc(line)
                .map_or(Shape::Absent, |arc| Shape::Arc(ArcBoundary::new(arc, inside), Side::Limit { line, above }))
        };
        let lines = joint2_lines(&c.load, &c.torque_limits.joint2);
        let band_min = TorqueBand::new(g.link3, &c.load, c.torque_limits.joint3.min);
        let band_max = TorqueBand::new(g.link3, &c.load, c.torque_limits.joint3.max);
        // The circles of a band: the edge at a sum φ exists if φ (mod 2π) meets the workspace.
        let edges = |band: Option<TorqueBand<T>>| -> [Shape<T>; 2] {
            let Some(band) = band else { return [Shape::Absent; 2] };
            let mut shapes = [Shape::Absent; 2];
            for (shape, (phi, above)) in shapes.iter_mut().zip(band.boundaries().into_iter().zip([false, true])) {
                let sum = wrap_from(phi, g.sum.min);
                if let Some(arc) = g.arc(JointLine::Sum(sum)) {
                    let side = Side::Band { band, above, governs_all: false };
                    *shape = Shape::Arc(ArcBoundary::new(arc, above), side);
                }
            }
            // A lone edge governs the whole band.
            if let [Shape::Arc(_, Side::Band { governs_all: a, .. }), Shape::Absent]
            | [Shape::Absent, Shape::Arc(_, Side::Band { governs_all: a, .. })] = &mut shapes
            {
                *a = true;
            }
            shapes
        };
        let [min_lower, min_upper] = edges(band_min);
        let [max_lower, max_upper] = edges(band_max);
        let [arc1, arc2, arc3, arc4, arc5, arc6] = g.arc_lines();
        self.shapes = [
            limit(arc1, true),
            limit(arc2, false),
            limit(arc3, false),
            limit(arc4, false),
            limit(arc5, true),
            limit(arc6, true),
            lines.map_or(Shape::Absent, |[low, _]| Shape::Line(low)),
            lines.map_or(Shape::Absent, |[_, high]| Shape::Line(high)),
            // Table A.2 signs: τ_min "+" is the upper edge of the band around α, "−" the lower;
            // τ_max "+" (α + π − w) is the lower edge of the band around α + π, "−" the upper.
            min_upper,
            min_lower,
            max_lower,
            max_upper,
        ];
    }
}

/// For an arc boundary at `(q_t2, q_t3)`: `Some(feasible)` with the joint-space verdict (the
/// range limit holds; the angle sum is outside the torque band), or `None` if the other edge
/// of its torque band governs this angle sum (the other half of the circle of sums).
fn governing_side<T: RealField + Copy>(side: &Side<T>, q2: T, q3: T) -> Option<bool> {
    match *side {
        Side::Limit { line, above } => {
            let offset = line.offset(q2, q3);
            Some(if above { offset >= T::zero() } else { offset <= T::zero() })
        }
        Side::Band { band, above, governs_all } => {
            let delta = wrap_to_pi(q2 + q3 - band.center);
            if !governs_all && above != (delta >= T::zero()) {
                return None;
            }
            // Feasible for this band: outside it, on either side.
            Some(delta.abs() >= band.half_width)
        }
    }
}

/// Torso-workspace repulsion (3.53): appends exactly [`BOUNDARIES`] rows, one per
/// [`Boundary`] in [`Boundary::ALL`] order (see the module docs), and returns the
/// [`TorsoWorkspaceReport`].
///
/// Row of a present boundary at distance `d`: `j = (∂d/∂p_t)ᵀ J_t` in the columns of `q_t2`,
/// `q_t3`; `f = F_max/d₀² (d₀ − d)² − 2 ξ √(k m) ḋ` for `d < d₀` with `k = 2 F_max (d₀ − d)/d₀²`,
/// `m = 1/(j M⁻¹ jᵀ)`, `ḋ = j q̇`; `V = F_max/(3 d₀²)(d₀ − d)³`; `a` the cubic (4.68) of `d`.
/// Used alone, `τ = Σ jᵀ f = −(∂V_tws/∂q)ᵀ − D_tws q̇`.
///
/// Inputs: `q`, `q̇` (rad, rad/s), a factor of `M(q)` ([`InertiaFactor`]: the dense Cholesky
/// factor of [`crate::dynamics::mass_matrix_cholesky`], O(N²) once for two forward
/// substitutions, or a [`TreeFactorization`], O(depth) along the two coordinates' chains) for
/// the 2×2 block of `M⁻¹` the rows live in; O(1) per row.
/// Errors (the row list is unchanged): [`TaskError::NonFinite`], [`TaskError::Capacity`] if
/// fewer than [`BOUNDARIES`] rows are free.
///
/// ```
/// use kernel::tasks::{torso_workspace::*, TaskRows};
/// use nalgebra::{Cholesky, Matrix2, Vector2};
/// let config = TorsoWorkspaceConfig {
///     geometry: TorsoGeometry::<f64>::from_degrees([0.3, 0.3], [-90.0, 90.0], [0.0, 135.0], [0.0, 135.0]),
///     torque_limits: TorqueLimits::symmetric(230.0),
///     load: TorsoLoad::from_degrees(550.0, 90.0),
///     gains: RepulsionGains::thesis_experiment(), // F_max = 50 N, d₀ = 0.1 m
///     coordinates: [0, 1],
/// };
/// let task = TorsoWorkspace::<f64, 2>::try_new(config).unwrap();
/// let inertia = Cholesky::new(Matrix2::new(3.0, 0.5, 0.5, 1.0)).unwrap();
/// let mut rows = TaskRows::<f64, 2, 12>::new();
/// // 10° inside the limit q_t2 = −90° (arc 1), a few cm from it: F = F_max/d₀² (d₀ − d)².
/// let q = Vector2::new((-80.0_f64).to_radians(), 2.0);
/// let report = torso_workspace(&task, &q, &Vector2::zeros(), &inertia, &mut rows).unwrap();
/// let d = report.distance(Boundary::Joint2Min).unwrap();
/// let row = rows.rows()[Boundary::Joint2Min.index()];
/// assert!(d > 0.0 && d < 0.1);
/// assert!((row.force - 5000.0 * (0.1 - d).powi(2)).abs() < 1e-9);
/// ```
pub fn torso_workspace<'m, T: RealField + Copy, const N: usize, const R: usize>(
    task: &TorsoWorkspace<T, N>,
    q: &SVector<T, N>,
    v: &SVector<T, N>,
    inertia: impl Into<InertiaFactor<'m, T, N>>,
    rows: &mut impl RowSink<T, N, R>,
) -> Result<TorsoWorkspaceReport<T>, TaskError> {
    if !(crate::math::all_finite(q) && crate::math::all_finite(v)) {
        return Err(TaskError::NonFinite);
    }
    if rows.len().saturating_add(BOUNDARIES) > R {
        return Err(TaskError::Capacity { capacity: R });
    }
    let c = &task.config;
    let [i2, i3] = c.coordinates;
    let (Some(&q2), Some(&q3)) = (q.get(i2), q.get(i3)) else {
        return Err(TaskError::InvalidParameter { name: "coordinates" });
    };
    let (report, gradients) = task.evaluate(q2, q3);
    let jt = c.geometry.jacobian(q2, q3);
    let gains = &c.gains;
    let two: T = nalgebra::convert(2.0);
    // Every row lives in the columns (i2, i3): j M⁻¹ jᵀ = lᵀ W l with l = (∂d/∂p_t)ᵀ J_t and W
    // the 2×2 block of M⁻¹ on (i2, i3), W_ab = (L⁻¹ e_a)·(L⁻¹ e_b) for M = L Lᵀ: two forward
    // substitutions (from the coordinate on) for all rows instead of one full solve per row.
    let block = if report.distances.iter().any(Option::is_some) {
        match inertia.into() {
            InertiaFactor::Dense(factor) => inverse_block(factor, i2, i3),
            InertiaFactor::Tree(factor) => inverse_block_tree(factor, i2, i3),
        }
    } else {
        [T::zero(); 3]
    };
    let [w22, w23, w33] = block;
    let (v2, v3) = (v.get(i2).copied().unwrap_or_else(T::zero), v.get(i3).copied().unwrap_or_else(T::zero));
    // Each row is built in place in its slot of `rows`, in the columns `first..end` spanning
    // (i2, i3) (a boundary without a distance is the zero row); a failure removes the rows
    // pushed so far, so that `rows` is left unchanged.
    let (first, end) = (i2.min(i3), i2.max(i3) + 1);
    let start = rows.len();
    for (distance, gradient) in report.distances.iter().zip(gradients.iter()) {
        let pushed = rows.push_with(first..end, |row| {
            let Some(d) = *distance else { return };
            let local = gradient.transpose() * jt;
            let (l2, l3) = (local.x, local.y);
            if let Some(a) = row.jacobian.get_mut(i2 - first) {
                *a = l2;
            }
            if let Some(a) = row.jacobian.get_mut(i3 - first) {
                *a = l3;
            }
            let rate = l2 * v2 + l3 * v3;
            // Damping 2ξ√(k m) ḋ with m = 1/(j M⁻¹ jᵀ): 2ξ√k ḋ/√(j M⁻¹ jᵀ). At a singular row
            // (j → 0) both ḋ and √(j M⁻¹ jᵀ) vanish linearly; below the guard no damping.
            let stiffness = gains.stiffness(d);
            let mobility = sqrt((l2 * (l2 * w22 + l3 * w23) + l3 * (l2 * w23 + l3 * w33)).max(T::zero()));
            let damping = crate::math::guarded_divide(
                two * gains.damping_ratio * sqrt(stiffness) * rate,
                mobility,
                T::default_epsilon(),
            )
            .unwrap_or_else(T::zero);
            row.force = gains.force(d) - damping;
            row.potential = gains.potential(d);
            row.activation = transition_activation(d, gains.activation_full, gains.activation_start);
        });
        if let Err(e) = pushed {
            rows.truncate(start);
            return Err(e);
        }
    }
    Ok(report)
}

/// `(W₂₂, W₂₃, W₃₃)` of `W = M⁻¹` on the coordinates `(i2, i3)` from the Cholesky factor
/// `M = L Lᵀ`: `W_ab = (L⁻¹ e_a)·(L⁻¹ e_b)`, two forward substitutions on the column-major
/// factor ([`crate::math::cholesky::solve_lower_in_place`]; the leading zeros cost nothing).
fn inverse_block<T: RealField + Copy, const N: usize>(inertia: &Cholesky<T, Const<N>>, i2: usize, i3: usize) -> [T; 3] {
    let l = inertia.l_dirty().as_slice();
    let unit = |i: usize| {
        let mut e = SVector::<T, N>::zeros();
        if let Some(x) = e.get_mut(i) {
            *x = T::one();
        }
        solve_lower_in_place(l, e.as_mut_slice());
        e
    };
    let (y2, y3) = (unit(i2), unit(i3));
    let dot = |a: &SVector<T, N>, b: &SVector<T, N>| {
        a.as_slice().iter().zip(b.as_slice().iter()).fold(T::zero(), |s, (x, y)| s + *x * *y)
    };
    [dot(&y2, &y2), dot(&y2, &y3), dot(&y3, &y3)]
}

/// [`inverse_block`] on the tree-sparse factor `M = Lᵀ L`: `X = E L⁻¹` for the two unit rows
/// `E = (e_i2, e_i3)ᵀ` ([`TreeFactorization::right_solve_mut`], only the ancestor chains of
/// the two coordinates are touched) and `W = X Xᵀ`.
fn inverse_block_tree<T: RealField + Copy, const N: usize>(
    inertia: &TreeFactorization<T, N>,
    i2: usize,
    i3: usize,
) -> [T; 3] {
    let mut x = SMatrix::<T, 2, N>::zeros();
    if let Some(e) = x.get_mut((0, i2)) {
        *e = T::one();
    }
    if let Some(e) = x.get_mut((1, i3)) {
        *e = T::one();
    }
    inertia.right_solve_mut(&mut x);
    let (mut w22, mut w23, mut w33) = (T::zero(), T::zero(), T::zero());
    for column in x.data.0.iter() {
        let [a, b] = *column;
        w22 += a * a;
        w23 += a * b;
        w33 += b * b;
    }
    [w22, w23, w33]
}

#[cfg(test)]
mod tests;
