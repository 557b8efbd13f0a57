//! Manipulator singularity avoidance (Sec. 3.4.2, (3.55)–(3.57)) as one unilateral task row.
//!
//! The kinematic manipulability (3.55) `m = √det(J Jᵀ) = σ₁ ⋯ σ_m` is taken of a chosen
//! Jacobian: the world-aligned frame Jacobian (linear rows first) of a frame, restricted to
//! selected rows and selected coordinates (e.g. the 6×7 Jacobian of one arm). The potential
//! (3.56) `V = k_msa (m − m_kin,0)²` for `m ≤ m_kin,0` (else 0) repels from singularities.
//!
//! **Row.** The row's coordinate is `m` itself: `j = ∂m/∂q` (1×N, **not** unit-normalised),
//! `f = −∂V/∂m − a d ṁ = −2 k_msa (m − m_kin,0) − a d ṁ`, so `jᵀ f = −(∂V/∂q)ᵀ − a d jᵀ j q̇`
//! is exactly (3.57) with `D_msa = a d jᵀ j`. The gradient is analytic,
//! `∂m/∂q_k = m tr((J Jᵀ)⁻¹ (∂J/∂q_k) Jᵀ)`, with `∂J/∂q_k` taken from the structure of the
//! kinematic tree for all `k` in one walk over the frame's support path (see [`manipulability`];
//! no finite differences, no N directional derivatives). It covers every
//! coordinate, including those outside the selected columns (they move the frame and can change
//! `m`, e.g. through the world orientation when only some rows are selected). The unit-norm
//! direction `J_{1×n} = j/‖j‖` of (4.70) is left to the hierarchy: its scalar-inverse projectors
//! are invariant to the scale of a row, and normalising here would need a division by `‖j‖`,
//! which vanishes where `m` is extremal.
//!
//! **Activation.** The row is always emitted (see [`super::end_stops`] for the convention):
//! activation `a` follows (4.65)/(4.68) with `ϑ = m`, `ϑ₂ = m_kin,0` (the potential starts) and
//! `ϑ₁ = full_activation` (fully active), as in the simulation of Fig. 4.12 (`ϑ₂ = m₀ = 0.23`).
//! Above `m_kin,0` the force and potential are 0. `V` is C¹ at `m = m_kin,0` (value and
//! gradient vanish there); its second derivative jumps from 0 to `2 k_msa (∇m)ᵀ∇m`.
//!
//! **Exact singularity.** If `J Jᵀ` fails its Cholesky factorization, `m = 0` is reported with
//! `singular = true` and the row's Jacobian is zero (`m` is not differentiable there); the
//! force and potential keep their values at `m = 0`.
//!
//! **Sampling.** Along the row, the spring `2 k_msa` acts on the inertia `1 / w`,
//! `w = ∇m M̃⁻¹ ∇mᵀ`, and `w` is large where `∇m` points into light joints: near `q₂ = 0` of a
//! 7-joint arm (axes 1 and 3 aligned), `m` falls with `q₂` and the light joint 3 with it. The
//! spring switches on with its full stiffness at `m_kin,0` while the damping `a d` starts
//! from 0, so the row enters undamped; sampled at `Δt` and applied a cycle late, it then
//! gains energy at each entry (roughly by `π ω τ` of its kinetic energy, `ω = √(2 k_msa w)`,
//! `τ` the loop's delay), and its torque rises by `2 k_msa |ṁ| |∂m/∂q_i| Δt` per cycle on
//! joint `i`. Choose `k_msa` so that `ω Δt` stays small and that ramp inside the joints'
//! torque-rate limits, and `d` so that `Δt d w` stays below the delayed damper's bound
//! (`controller::speed_barrier`, ≈ 0.88). Justin's values and the soak event that set them are
//! in `fixtures/robots/justin/config.toml` (`[singularity]`).

use nalgebra::{RealField, RowSVector, Vector3};

use super::cartesian_impedance::AxisMask;
use super::{RowSink, TaskError};
#[cfg(test)]
use super::{TaskRow, TaskRows};
use crate::dynamics::DynamicsError;
use crate::math::cholesky::{cholesky_in_place, solve_lower_in_place, solve_lower_transpose_in_place};
use crate::math::spatial::{angular, linear_at_point};
use crate::math::switching::transition_activation;
use crate::model::{Data, FrameId, Model};

/// Parameters of a manipulator singularity avoidance. Validate with [`Manipulability::try_new`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ManipulabilityConfig<T, const N: usize> {
    /// Frame whose Jacobian is used.
    pub frame: FrameId,
    /// Selected rows `(v_x, v_y, v_z, ω_x, ω_y, ω_z)` of its world-aligned Jacobian (`m` rows).
    pub rows: AxisMask,
    /// Selected coordinates (columns), at least as many as rows (e.g. the 7 arm joints).
    pub coordinates: [bool; N],
    /// Threshold `m_kin,0 > 0` of (3.56) (units of `m`: m^{rows_lin} for the selected rows).
    pub threshold: T,
    /// Manipulability `ϑ₁ ∈ [0, m_kin,0)` at which the activation reaches 1.
    pub full_activation: T,
    /// Gain `k_msa ≥ 0` of (3.56) (J per unit² of `m`).
    pub stiffness: T,
    /// Damping `d ≥ 0` along the row (J s per unit² of `m`), applied as `a d ṁ`.
    pub damping: T,
}

/// A validated manipulability task.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Manipulability<T, const N: usize> {
    config: ManipulabilityConfig<T, N>,
}

impl<T: RealField + Copy, const N: usize> Manipulability<T, N> {
    /// Validates `config`: at least one row and no fewer coordinates than rows; finite
    /// `m_kin,0 > 0`, `0 ≤ ϑ₁ < m_kin,0`; finite `k_msa ≥ 0`, `d ≥ 0`.
    /// Errors: [`TaskError::InvalidParameter`] naming the field.
    pub fn try_new(config: ManipulabilityConfig<T, N>) -> Result<Self, TaskError> {
        let invalid = |name| Err(TaskError::InvalidParameter { name });
        if config.rows.count() == 0 {
            return invalid("rows");
        }
        if config.coordinates.iter().filter(|c| **c).count() < config.rows.count() {
            return invalid("coordinates");
        }
        if !(config.threshold.is_finite() && config.threshold > T::zero()) {
            return invalid("threshold");
        }
        if !(config.full_activation >= T::zero() && config.full_activation < config.threshold) {
            return invalid("full_activation");
        }
        if !(config.stiffness.is_finite() && config.stiffness >= T::zero()) {
            return invalid("stiffness");
        }
        if !(config.damping.is_finite() && config.damping >= T::zero()) {
            return invalid("damping");
        }
        Ok(Self { config })
    }

    /// The validated parameters.
    pub fn config(&self) -> &ManipulabilityConfig<T, N> {
        &self.config
    }
}

/// The manipulability of a selected Jacobian and its gradient.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ManipulabilityMeasure<T, const N: usize> {
    /// `m = √det(J Jᵀ)` (3.55).
    pub value: T,
    /// `∂m/∂q` (1×N); zero if `singular`.
    pub gradient: RowSVector<T, N>,
    /// `J Jᵀ` is numerically singular (see the module docs): `m = 0`, gradient set to zero.
    pub singular: bool,
}

/// Manipulability (3.55) of the rows `rows` and coordinates `coordinates` of the world-aligned
/// Jacobian of `frame`, and its analytic gradient over all N coordinates.
///
/// **Value.** With `J̃` the selected Jacobian (its `r` selected rows, zero columns outside the
/// selected coordinates) and the `r×r` Cholesky factor `J̃ J̃ᵀ = L Lᵀ`, `m = Π L_ii` (3.55).
///
/// **Gradient.** With `W = (J̃ J̃ᵀ)⁻¹ J̃`, `∂m/∂q_k = m ⟨∂J̃/∂q_k, W⟩_F` (the trace form of the
/// module docs; `W` vanishes outside the selection, so the full `∂J/∂q_k` can be used). It is
/// evaluated for all `k` in one walk over the frame's support path instead of N directional
/// Jacobian derivatives. With the world motion subspace `S_i = (a_i; b_i)` of a joint `i` on
/// the path and `v_i = b_i + a_i × p` the velocity it gives the frame origin `p`, the tree column
/// of (2.6) is `c_j = (v_j; a_j)` (linear rows first), and a tree joint `i` changes it by
/// - `∂c_j/∂θ_i = (a_i × v_j; a_i × a_j)` if `i` is `j` or one of its ancestors (axis and point
///   move rigidly with `S_i`: `∂S_j/∂θ_i = S_i × S_j`, `∂p/∂θ_i = v_i`, and the Jacobi identity),
/// - `∂c_j/∂θ_i = (a_j × v_i; 0)` if `i` is below `j` (only the point moves).
///
/// With the drive map `q_tree = G q + offset` ([`crate::model::JointDrive`]), `J = J_tree G`, so
/// `∂m/∂q_k = m Σ_i G_ik g_i` with `V_j = Σ_k G_jk W_k = (V_j,lin; V_j,ang)` and
/// `g_i = a_i · Σ_{j at or below i} (v_j × V_j,lin + a_j × V_j,ang)
///      + v_i · Σ_{j above i} (V_j,lin × a_j)`.
/// The first sum is a running sum from the frame's body towards the root; the second is the total
/// minus the running sum, and its total part sums to `J_lin,k · Σ_j (V_j,lin × a_j)` over `i`.
/// Coordinates that drive no joint of the path get gradient 0.
///
/// Precondition: [`crate::dynamics::forward_kinematics`] at `q`. Cost O(depth + N r²) small
/// 3-vector operations. Errors: [`TaskError::Dynamics`] for an unknown frame.
///
/// ```
/// # use kernel::model::{Data, Inertia, JointDrive, JointKind, ModelBuilder, Placement};
/// # use kernel::dynamics::forward_kinematics;
/// # use kernel::tasks::{cartesian_impedance::AxisMask, manipulability::manipulability};
/// # use nalgebra::{SVector, Unit, Vector3};
/// // Planar 2R arm (1 m links about z): m = |sin q₂| for the x-y rows, ∂m/∂q₂ = cos q₂.
/// let mut b = ModelBuilder::<f64, 2, 2, 1>::new(Vector3::zeros());
/// let z = JointKind::Revolute { axis: Unit::new_normalize(Vector3::z()) };
/// let l1 = b.add_body(None, Placement::identity(), z, JointDrive::actuated(0),
///     Inertia::point_mass(1.0, Vector3::x())).unwrap();
/// let l2 = b.add_body(Some(l1), Placement::translation(1.0, 0.0, 0.0), z, JointDrive::actuated(1),
///     Inertia::point_mass(1.0, Vector3::x())).unwrap();
/// let tip = b.add_frame(Some(l2), Placement::translation(1.0, 0.0, 0.0)).unwrap();
/// let model = b.try_build().unwrap();
/// let mut data = Data::new(&model);
/// forward_kinematics(&model, &mut data, &SVector::from([0.2, 0.5]), &SVector::zeros()).unwrap();
/// let xy = AxisMask::new([true, true, false, false, false, false]);
/// let m = manipulability(&model, &data, tip, xy, &[true, true]).unwrap();
/// assert!((m.value - 0.5_f64.sin()).abs() < 1e-14);
/// assert!((m.gradient[1] - 0.5_f64.cos()).abs() < 1e-14 && m.gradient[0].abs() < 1e-14);
/// ```
pub fn manipulability<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    frame: FrameId,
    rows: AxisMask,
    coordinates: &[bool; N],
) -> Result<ManipulabilityMeasure<T, N>, TaskError> {
    let parent = model.frame(frame).ok_or(DynamicsError::UnknownFrame)?.parent;
    let point = data.frame_placements.get(frame.0).ok_or(DynamicsError::UnknownFrame)?.translation.vector;
    if let Some(body) = parent {
        model.body(body).ok_or(DynamicsError::UnknownBody)?;
    }
    let singular = ManipulabilityMeasure { value: T::zero(), gradient: RowSVector::zeros(), singular: true };
    let axes = rows.axes();
    let r = rows.count();
    let path = || {
        parent.into_iter().flat_map(|body| model.support(body)).filter_map(|id| {
            let (joint, s) = (model.body(id)?, data.motion_subspaces.get(id.0)?);
            Some((joint.drive.terms(), angular(s), linear_at_point(s, &point)))
        })
    };

    // The full Jacobian (2.6), one `(v; a)` column per coordinate: `J_k = Σ_i G_ik c_i`.
    let mut columns = [[T::zero(); 6]; N];
    for (terms, a, v) in path() {
        let column = [v.x, v.y, v.z, a.x, a.y, a.z];
        for term in terms {
            if let Some(c) = columns.get_mut(term.coordinate) {
                for (x, y) in c.iter_mut().zip(column.iter()) {
                    *x += *y * term.coefficient;
                }
            }
        }
    }

    // A = J̃ J̃ᵀ of the selected rows: the lower triangle of an r × r column-major block.
    let mut storage = [T::zero(); 36];
    let Some(gram) = storage.get_mut(..r * r) else {
        return Ok(singular);
    };
    for (column, _) in columns.iter().zip(coordinates.iter()).filter(|(_, s)| **s) {
        let packed = pack(&axes, column);
        for (j, (a_column, y)) in gram.chunks_exact_mut(r.max(1)).zip(packed.iter()).enumerate() {
            for (entry, x) in a_column.iter_mut().zip(packed.iter()).skip(j) {
                *entry += *x * *y;
            }
        }
    }
    // A pivot at rounding level means a rank-deficient J (e.g. more rows than joints on the
    // frame's path): treat it as singular rather than differentiate rounding noise. The floor is
    // taken relative to the largest diagonal entry of `J̃ J̃ᵀ + (I − S)` (1 on unselected rows).
    let largest = diagonal(gram, r).fold(if r < 6 { T::one() } else { T::zero() }, |m, x| m.max(x));
    let floor = nalgebra::convert::<f64, T>(100.0) * T::default_epsilon() * largest;
    if !cholesky_in_place(gram, r) {
        return Ok(singular);
    }
    let factor = &*gram;
    if diagonal(factor, r).any(|l| l * l <= floor) || (r < 6 && T::one() <= floor) {
        return Ok(singular);
    }
    let value = diagonal(factor, r).fold(T::one(), |m, l| m * l);

    // W_k = A⁻¹ J̃_k of the selected coordinates, unpacked to the six rows (0 on unselected rows).
    let mut weights = [[T::zero(); 6]; N];
    for ((w, column), _) in weights.iter_mut().zip(columns.iter()).zip(coordinates.iter()).filter(|(_, s)| **s) {
        let mut x = pack(&axes, column);
        if let Some(selected) = x.get_mut(..r) {
            solve_lower_in_place(factor, selected);
            solve_lower_transpose_in_place(factor, selected);
        }
        *w = unpack(&axes, &x);
    }

    // One walk from the body to the root: `at_or_below` = Σ (v_j × V_j,lin + a_j × V_j,ang) and
    // `moment` = Σ V_j,lin × a_j over the joints at or below the current one.
    let mut gradient = RowSVector::<T, N>::zeros();
    let (mut at_or_below, mut moment) = (Vector3::<T>::zeros(), Vector3::<T>::zeros());
    for (terms, a, v) in path() {
        let mut weight = [T::zero(); 6];
        for term in terms {
            if let Some(w) = weights.get(term.coordinate) {
                for (x, y) in weight.iter_mut().zip(w.iter()) {
                    *x += *y * term.coefficient;
                }
            }
        }
        let [l0, l1, l2, a0, a1, a2] = weight;
        let (w_lin, w_ang) = (Vector3::new(l0, l1, l2), Vector3::new(a0, a1, a2));
        at_or_below += v.cross(&w_lin) + a.cross(&w_ang);
        moment += w_lin.cross(&a);
        let g = a.dot(&at_or_below) - v.dot(&moment);
        for term in terms {
            if let Some(x) = gradient.as_mut_slice().get_mut(term.coordinate) {
                *x += term.coefficient * g;
            }
        }
    }
    // The joints above `i` contribute v_i · (moment_total − moment_i); the total part summed
    // over the path with the drive coefficients is J_lin,k · moment_total.
    for (x, column) in gradient.as_mut_slice().iter_mut().zip(columns.iter()) {
        let [l0, l1, l2, ..] = *column;
        *x = value * (*x + l0 * moment.x + l1 * moment.y + l2 * moment.z);
    }
    if !(value.is_finite() && gradient.as_slice().iter().all(|x| x.is_finite())) {
        return Ok(singular);
    }
    Ok(ManipulabilityMeasure { value, gradient, singular: false })
}

/// The diagonal of the column-major `r × r` matrix `a`.
fn diagonal<T: Copy>(a: &[T], r: usize) -> impl Iterator<Item = T> + '_ {
    (0..r).filter_map(move |i| a.get(i * r + i).copied())
}

/// The selected entries of a 6-vector, in order, in the first `rows.count()` places.
fn pack<T: RealField + Copy>(axes: &[bool; 6], full: &[T; 6]) -> [T; 6] {
    let mut packed = [T::zero(); 6];
    for (p, x) in packed.iter_mut().zip(full.iter().zip(axes.iter()).filter(|(_, s)| **s).map(|(x, _)| x)) {
        *p = *x;
    }
    packed
}

/// Inverse of [`pack`]: the first `rows.count()` entries back in the selected places, 0 elsewhere.
fn unpack<T: RealField + Copy>(axes: &[bool; 6], packed: &[T; 6]) -> [T; 6] {
    let mut full = [T::zero(); 6];
    for (f, p) in full.iter_mut().zip(axes.iter()).filter(|(_, s)| **s).map(|(f, _)| f).zip(packed.iter()) {
        *f = *p;
    }
    full
}

/// What one call of [`manipulability_avoidance`] found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ManipulabilityReport<T> {
    /// The manipulability `m` (3.55).
    pub manipulability: T,
    /// `true` if `J Jᵀ` was numerically singular (row Jacobian set to zero).
    pub singular: bool,
}

/// Manipulator singularity avoidance (3.55)–(3.57): appends one row with `j = ∂m/∂q`,
/// `f = −2 k_msa min(m − m_kin,0, 0) − a d ṁ`, `V = k_msa min(m − m_kin,0, 0)²` and the
/// activation `a(m)` of (4.68); see the module docs. Used alone,
/// `τ = jᵀ f = −(∂V_msa/∂q)ᵀ − D_msa q̇`.
///
/// Precondition: [`crate::dynamics::forward_kinematics`] at `(q, q̇)` (reads `data.v`).
/// Cost O(depth + N r²) (`r` selected rows). Errors (the row list is unchanged): [`TaskError::Dynamics`] for an
/// unknown frame, [`TaskError::NonFinite`], [`TaskError::Capacity`].
pub fn manipulability_avoidance<T: RealField + Copy, const N: usize, const B: usize, const F: usize, const R: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    task: &Manipulability<T, N>,
    rows: &mut impl RowSink<T, N, R>,
) -> Result<ManipulabilityReport<T>, TaskError> {
    if rows.len() >= R {
        return Err(TaskError::Capacity { capacity: R });
    }
    let c = &task.config;
    let measure = manipulability(model, data, c.frame, c.rows, &c.coordinates)?;
    let deficit = (measure.value - c.threshold).min(T::zero());
    let activation = transition_activation(measure.value, c.full_activation, c.threshold);
    let rate = (measure.gradient * data.v).x;
    let two: T = nalgebra::convert(2.0);
    rows.push_with_metric(|row| {
        row.jacobian = measure.gradient;
        row.force = -two * c.stiffness * deficit - activation * c.damping * rate;
        row.potential = c.stiffness * deficit * deficit;
        row.activation = activation;
        None
    })?;
    Ok(ManipulabilityReport { manipulability: measure.value, singular: measure.singular })
}

#[cfg(test)]
mod tests;
