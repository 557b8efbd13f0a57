//! Repulsive potential, pair Jacobians, reflected masses, damping and task rows of the
//! collision pairs (Sec. 3.1.2–3.1.4, (3.2)–(3.24)).
//!
//! For a pair `(i, j)` with closest points `x_i`, `x_j`, distance `d` and unit direction
//! `e = (x_j − x_i)/‖x_j − x_i‖` (3.4)–(3.5):
//! - pair Jacobians `J_i = eᵀ J_{x_i,q}`, `J_j = eᵀ J_{x_j,q}` (1×N, (3.17)–(3.18)): the motions
//!   `ż_i`, `ż_j` of the closest points along `e`, both positive from `x_i` to `x_j`;
//! - reflected masses `m_i = (J_i M⁻¹ J_iᵀ)⁻¹` (3.20), `m_j` alike; a volume that cannot move
//!   along `e` (fixed in the world, or `J_i = 0`) has infinite mass, `m_i⁻¹ = 0`;
//! - potential `V(d) = −F_max/(3 d0²) (d − d0)³` for `d ≤ d0`, else 0 (3.8), repulsive force
//!   `F_sca(d) = −∂V/∂d = F_max/d0² (d − d0)²` (3.10), local stiffness
//!   `k = ∂²V/∂d² = 2 F_max/d0² (d0 − d)`; `V` is C² at `d0`, so the damping is continuous;
//! - damping `D_(i,j) = D(diag(m_i, m_j), k [[1, −1], [−1, 1]], ξ)` by double diagonalisation
//!   (3.21)–(3.23); the pair stiffness has rank one, so `D = c [[1, −1], [−1, 1]]` with
//!   `c = 2 ξ √(k m_eff)`, `m_eff⁻¹ = m_i⁻¹ + m_j⁻¹`, and the common mode is undamped;
//! - torque (3.24) `τ = [J_i; J_j]ᵀ ((−F_sca, F_sca)ᵀ − D [J_i; J_j] q̇)`.
//!
//! Because `D` acts only on the relative motion, (3.24) equals **one task row**: Jacobian
//! `j = J_j − J_i` (the rate `ḋ = j q̇` of the distance), force `f = F_sca(d) − c ḋ`, potential
//! `V(d)`: `τ = jᵀ f`. With `q̇ = 0`, `τ = −(∂V/∂q)ᵀ` wherever the closest points are unique
//! (envelope theorem: sliding the points along the surfaces does not change `d` to first
//! order, which is why only the principal block diagonal of (3.6) remains, (3.7)).

use nalgebra::{Cholesky, Const, Matrix1, Matrix2, RealField, RowSVector, SVector, Vector1, Vector2};

use super::model::{CollisionData, CollisionModel, CollisionPair};
use super::volumes::Proximity;
use crate::dynamics::DynamicsError;
use crate::math::damping::{double_diagonalization, DampingError, ReflectedInertia};
use crate::math::spatial::linear_at_point;
use crate::model::{BodyId, Data, Model};
use crate::tasks::{TaskError, TaskRow};

mod kinematics;
mod parameters;
mod rows;
mod selection;

pub use kinematics::{factor_rows, inverse_reflected_masses};
pub use parameters::CollisionParameters;
pub use rows::{
    collision_rows_from_geometry, collision_rows_shared, self_collision_rows, CollisionReport, PairRowCache,
};

/// Everything computed for one collision pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairEvaluation<T, const N: usize> {
    /// Index of the pair in [`CollisionModel::pairs`].
    pub pair: usize,
    /// Signed distance `d` (m).
    pub distance: T,
    /// `J_i` (1×N), (3.18): motion of `x_i` along `e`.
    pub jacobian_first: RowSVector<T, N>,
    /// `J_j` (1×N): motion of `x_j` along `e`.
    pub jacobian_second: RowSVector<T, N>,
    /// `(m_i⁻¹, m_j⁻¹) = (J_i M⁻¹ J_iᵀ, J_j M⁻¹ J_jᵀ)` (1/kg), (3.20); 0 means infinite mass.
    pub inverse_masses: Vector2<T>,
    /// Pair damping matrix `D_(i,j)` (Ns/m), (3.23).
    pub damping: Matrix2<T>,
    /// The pair as one task row: `j = J_j − J_i`, `f = F_sca(d) − c ḋ`, `V(d)`, activation.
    pub row: TaskRow<T, N>,
}

impl<T: RealField + Copy, const N: usize> PairEvaluation<T, N> {
    /// Reflected masses `(m_i, m_j)` (kg), (3.20); `None` for an infinite one.
    pub fn reflected_masses(&self) -> (Option<T>, Option<T>) {
        let mass = |w: T| (w > T::zero()).then(|| T::one() / w);
        (mass(self.inverse_masses.x), mass(self.inverse_masses.y))
    }

    /// The pair's torque by (3.24), `[J_i; J_j]ᵀ ((−F_sca, F_sca)ᵀ − D [J_i; J_j] q̇)`, with
    /// the 2×2 damping matrix (equal to `rowᵀ f` up to rounding).
    pub fn torque(&self, force: T, velocity: &SVector<T, N>) -> SVector<T, N> {
        let z = Vector2::new((self.jacobian_first * velocity).x, (self.jacobian_second * velocity).x);
        let f = Vector2::new(-force, force) - self.damping * z;
        self.jacobian_first.transpose() * f.x + self.jacobian_second.transpose() * f.y
    }
}

/// `eᵀ J_{x,q}` for the point `point` (world, m) on `body`; zero for a world-fixed volume.
fn projected_jacobian<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    body: Option<BodyId>,
    point: &nalgebra::Vector3<T>,
    direction: &nalgebra::Vector3<T>,
) -> Result<RowSVector<T, N>, TaskError> {
    let Some(body) = body else {
        return Ok(RowSVector::zeros());
    };
    // `eᵀ J_p` directly over the support path (as `point_jacobian`, with each column's linear
    // part projected on `e`): O(depth), without the 6×N Jacobian.
    model.body(body).ok_or(DynamicsError::UnknownBody)?;
    let mut row = RowSVector::<T, N>::zeros();
    for id in model.support(body) {
        let (Some(joint), Some(s)) = (model.body(id), data.motion_subspaces.get(id.0)) else {
            continue;
        };
        let value = direction.dot(&linear_at_point(s, point));
        for term in joint.drive.terms() {
            if let Some(x) = row.get_mut(term.coordinate) {
                *x += value * term.coefficient;
            }
        }
    }
    Ok(row)
}

/// `J M⁻¹ Jᵀ = ‖L⁻¹ Jᵀ‖²` with `M = L Lᵀ` (1/kg): the inverse reflected mass (3.20).
pub fn inverse_reflected_mass<T: RealField + Copy, const N: usize>(
    mass_cholesky: &Cholesky<T, Const<N>>,
    jacobian: &RowSVector<T, N>,
) -> Result<T, TaskError> {
    // Forward substitution `L y = Jᵀ`, column-oriented on the column-major storage: the
    // operations (and so the bits) of nalgebra's `solve_lower_triangular` (`y_i = b_i / l_ii`,
    // then `b_j += −y_i l_ji` below the diagonal), without its per-column views and strided
    // iterators; about a fifth of the instructions.
    let mut y = jacobian.transpose();
    let ys = y.as_mut_slice();
    for (i, column) in mass_cholesky.l_dirty().as_slice().chunks_exact(N).enumerate() {
        let (Some(&diag), Some((yi, below)), Some(l_below)) =
            (column.get(i), ys.get_mut(i..).and_then(|s| s.split_first_mut()), column.get(i + 1..))
        else {
            break;
        };
        if diag.is_zero() {
            return Err(TaskError::Singular);
        }
        let coeff = *yi / diag;
        *yi = coeff;
        for (yj, lji) in below.iter_mut().zip(l_below) {
            *yj += -coeff * *lji;
        }
    }
    Ok(y.norm_squared())
}

fn damping_error(e: DampingError) -> TaskError {
    match e {
        DampingError::NonFinite => TaskError::NonFinite,
        DampingError::InvalidDampingRatio => TaskError::InvalidParameter { name: "damping_ratio" },
        DampingError::StiffnessNotPositiveSemidefinite => TaskError::InvalidParameter { name: "stiffness" },
        DampingError::InertiaNotPositiveDefinite => TaskError::Singular,
    }
}

/// Pair damping (3.21)–(3.23) for inverse reflected masses `(m_i⁻¹, m_j⁻¹)`, local stiffness
/// `k` (N/m) and damping ratio `ξ`: returns `(c, D)` with `D = c [[1, −1], [−1, 1]]` (Ns/m),
/// `c = 2 ξ √(k m_eff)`, `m_eff⁻¹ = m_i⁻¹ + m_j⁻¹`.
///
/// Both masses finite: [`double_diagonalization`] of `(Λ⁻¹ = diag(m_i⁻¹, m_j⁻¹),
/// K = k [[1, −1], [−1, 1]], ξ)`; the common mode (both points moving together) has no
/// stiffness and gets no damping, so the result is `c [[1, −1], [−1, 1]]` and `c` is its first
/// entry.
/// One mass infinite (`m⁻¹ ≤ ε (m_i⁻¹ + m_j⁻¹)`: a world-fixed or locked volume): the 1-D
/// design `c = D(m, k, ξ)` of the moving side. Both infinite or `k = 0`: no damping.
///
/// ```
/// use kernel::tasks::collision::pair_damping;
/// use nalgebra::Vector2;
/// // m_i = 2 kg, m_j = 6 kg: m_eff = 1.5 kg; k = 300 N/m, ξ = 1: c = 2·√450 Ns/m.
/// let (c, d) = pair_damping(&Vector2::new(0.5, 1.0 / 6.0), 300.0_f64, 1.0).unwrap();
/// assert!((c - 2.0 * 450.0_f64.sqrt()).abs() < 1e-9 && (d[(0, 1)] + c).abs() < 1e-9);
/// // Against a world-fixed volume: m_eff = m_i.
/// let (c, _) = pair_damping(&Vector2::new(0.5, 0.0), 300.0_f64, 1.0).unwrap();
/// assert!((c - 2.0 * 600.0_f64.sqrt()).abs() < 1e-9);
/// ```
pub fn pair_damping<T: RealField + Copy>(
    inverse_masses: &Vector2<T>,
    stiffness: T,
    damping_ratio: T,
) -> Result<(T, Matrix2<T>), TaskError> {
    let pattern = Matrix2::new(T::one(), -T::one(), -T::one(), T::one());
    let (wi, wj) = (inverse_masses.x, inverse_masses.y);
    if !(wi.is_finite() && wj.is_finite() && stiffness.is_finite()) {
        return Err(TaskError::NonFinite);
    }
    if !damping_ratio.is_finite() || damping_ratio < T::zero() {
        return Err(TaskError::InvalidParameter { name: "damping_ratio" });
    }
    let threshold = T::default_epsilon() * (wi + wj);
    let c = match (wi > threshold, wj > threshold) {
        _ if stiffness <= T::zero() => T::zero(),
        (true, true) => {
            let inverse = Matrix2::new(wi, T::zero(), T::zero(), wj);
            let d = double_diagonalization(
                ReflectedInertia::Inverse(&inverse),
                &(pattern * stiffness),
                &Vector2::repeat(damping_ratio),
            )
            .map_err(damping_error)?;
            d.m11
        }
        (true, false) | (false, true) => {
            let d = double_diagonalization(
                ReflectedInertia::Inverse(&Matrix1::new(wi.max(wj))),
                &Matrix1::new(stiffness),
                &Vector1::new(damping_ratio),
            )
            .map_err(damping_error)?;
            d.x
        }
        (false, false) => T::zero(),
    };
    Ok((c, pattern * c))
}

/// Evaluates pair `pair` of `collision_model` from its proximity in `collision` (after
/// [`CollisionModel::update`]) and the dynamics of the last `forward_kinematics` (velocity
/// `data.v`) with `M = L Lᵀ` (`mass_cholesky`, from `crba` and `mass_matrix_cholesky`).
///
/// Cost: two point Jacobians O(depth·N), two triangular solves O(N²), one 2×2 damping design.
/// Errors: unknown pair or body, cores touching (no direction: [`TaskError::Singular`]),
/// non-finite values.
pub fn evaluate_pair<
    T: RealField + Copy,
    const N: usize,
    const B: usize,
    const F: usize,
    const V: usize,
    const P: usize,
>(
    collision_model: &CollisionModel<T, V, P>,
    collision: &CollisionData<T, V, P>,
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    mass_cholesky: &Cholesky<T, Const<N>>,
    parameters: &CollisionParameters<T>,
    pair: usize,
) -> Result<PairEvaluation<T, N>, TaskError> {
    let invalid = TaskError::InvalidParameter { name: "pair" };
    let &CollisionPair { first, second } = collision_model.pairs().get(pair).ok_or(invalid)?;
    let proximity: &Proximity<T> = collision.proximities.get(pair).ok_or(invalid)?;
    let (Some(a), Some(b)) = (collision_model.volume(first), collision_model.volume(second)) else {
        return Err(invalid);
    };
    let e = proximity.direction.ok_or(TaskError::Singular)?.into_inner();
    let jacobian_first = projected_jacobian(model, data, a.body, &proximity.core_first, &e)?;
    let jacobian_second = projected_jacobian(model, data, b.body, &proximity.core_second, &e)?;
    let inverse_masses = Vector2::new(
        inverse_reflected_mass(mass_cholesky, &jacobian_first)?,
        inverse_reflected_mass(mass_cholesky, &jacobian_second)?,
    );
    let d = proximity.distance;
    let (c, damping) = pair_damping(&inverse_masses, parameters.stiffness(d), parameters.damping_ratio())?;
    let jacobian = jacobian_second - jacobian_first;
    let rate = (jacobian * data.v).x;
    let row = TaskRow {
        jacobian,
        force: parameters.force(d) - c * rate,
        potential: parameters.potential(d),
        activation: parameters.activation(d),
    };
    Ok(PairEvaluation { pair, distance: d, jacobian_first, jacobian_second, inverse_masses, damping, row })
}

#[cfg(test)]
mod reflected_mass_tests;
#[cfg(test)]
mod row_cache_tests;
#[cfg(test)]
mod selection_tests;
#[cfg(test)]
mod tests;
