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

use heapless::Vec;
use nalgebra::{
    convert, Cholesky, Const, Matrix1, Matrix2, RealField, RowSVector, SMatrix, SVector, Vector1, Vector2, Vector3,
};

use super::model::{CollisionData, CollisionModel, CollisionPair};
use super::volumes::Proximity;
use crate::dynamics::{DynamicsError, InertiaFactor, TreeFactorization};
use crate::math::damping::{double_diagonalization, DampingError, ReflectedInertia};
use crate::math::spatial::linear_at_point;
use crate::math::sqrt;
use crate::model::{BodyId, Data, Model};
use crate::tasks::{TaskError, TaskRow, TaskRows};

/// Parameters of the repulsive potentials, shared by all pairs (Table 3.1, Table 4.5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CollisionParameters<T> {
    max_force: T,
    influence_distance: T,
    damping_ratio: T,
    activation_full: T,
    activation_zero: T,
}

impl<T: RealField + Copy> CollisionParameters<T> {
    /// Validated parameters:
    /// - `max_force` `F_max > 0` (N): the repulsive force at contact, `d = 0` (3.8);
    /// - `influence_distance` `d0 > 0` (m): the potential vanishes for `d ≥ d0`;
    /// - `damping_ratio` `ξ ≥ 0` of every pair (3.23);
    /// - the activation band `0 ≤ ϑ1 < ϑ2` (m) of (4.68) for the hierarchy: a row's
    ///   activation is 1 for `d ≤ ϑ1`, 0 for `d ≥ ϑ2`, and `1 − (3s² − 2s³)`, `s = (d − ϑ1)/(ϑ2 − ϑ1)`
    ///   in between (Table 4.5: `N'max = 1.5/(ϑ2 − ϑ1)`).
    ///
    /// ```
    /// use kernel::tasks::collision::CollisionParameters;
    /// // Table 3.1: F_max = 25 N, d0 = 0.15 m, ξ = 0.7 (activation band [0, d0]).
    /// let p = CollisionParameters::try_new(25.0_f64, 0.15, 0.7, 0.0, 0.15).unwrap();
    /// assert_eq!(p.force(0.0), 25.0);
    /// assert!((p.stiffness(0.0) - 2.0 * 25.0 / 0.15).abs() < 1e-12); // 333 N/m
    /// assert_eq!(p.potential(0.2), 0.0);
    /// ```
    pub fn try_new(
        max_force: T,
        influence_distance: T,
        damping_ratio: T,
        activation_full: T,
        activation_zero: T,
    ) -> Result<Self, TaskError> {
        let finite = [max_force, influence_distance, damping_ratio, activation_full, activation_zero]
            .iter()
            .all(|x| x.is_finite());
        if !finite {
            return Err(TaskError::NonFinite);
        }
        let zero = T::zero();
        if max_force <= zero {
            return Err(TaskError::InvalidParameter { name: "max_force" });
        }
        if influence_distance <= zero {
            return Err(TaskError::InvalidParameter { name: "influence_distance" });
        }
        if damping_ratio < zero {
            return Err(TaskError::InvalidParameter { name: "damping_ratio" });
        }
        if activation_full < zero || activation_zero <= activation_full {
            return Err(TaskError::InvalidParameter { name: "activation band" });
        }
        Ok(Self { max_force, influence_distance, damping_ratio, activation_full, activation_zero })
    }

    /// `F_max` (N).
    pub fn max_force(&self) -> T {
        self.max_force
    }

    /// `d0` (m).
    pub fn influence_distance(&self) -> T {
        self.influence_distance
    }

    /// `ξ`.
    pub fn damping_ratio(&self) -> T {
        self.damping_ratio
    }

    /// The same parameters with damping ratio `ξ` (validated).
    pub fn with_damping_ratio(&self, damping_ratio: T) -> Result<Self, TaskError> {
        Self::try_new(
            self.max_force,
            self.influence_distance,
            damping_ratio,
            self.activation_full,
            self.activation_zero,
        )
    }

    /// Distance below which a pair emits a row: `max(d0, ϑ2)` (m).
    pub fn emit_distance(&self) -> T {
        self.influence_distance.max(self.activation_zero)
    }

    /// Potential `V(d)` (J), (3.8): `−F_max/(3 d0²) (d − d0)³` for `d ≤ d0`, else 0. For
    /// `d < 0` (overlapping volumes) the same cubic continues.
    pub fn potential(&self, d: T) -> T {
        let s = (d - self.influence_distance) / self.influence_distance;
        if s >= T::zero() {
            return T::zero();
        }
        -self.max_force * self.influence_distance / convert::<f64, T>(3.0) * s * s * s
    }

    /// Repulsive force `F_sca(d) = −∂V/∂d = F_max/d0² (d − d0)²` for `d ≤ d0`, else 0 (N),
    /// (3.10); `F_sca(0) = F_max`.
    pub fn force(&self, d: T) -> T {
        let s = (d - self.influence_distance) / self.influence_distance;
        if s >= T::zero() {
            return T::zero();
        }
        self.max_force * s * s
    }

    /// Local stiffness `k = ∂²V/∂d² = 2 F_max/d0² (d0 − d)` for `d ≤ d0`, else 0 (N/m), (3.22).
    pub fn stiffness(&self, d: T) -> T {
        let s = (self.influence_distance - d) / self.influence_distance;
        if s <= T::zero() {
            return T::zero();
        }
        convert::<f64, T>(2.0) * self.max_force / self.influence_distance * s
    }

    /// Activation `a(d) = 1 − N_des(d)` with the cubic `N_des` of (4.68) on `[ϑ1, ϑ2]`.
    pub fn activation(&self, d: T) -> T {
        crate::math::switching::transition_activation(d, self.activation_full, self.activation_zero)
    }
}

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
    let (c, damping) = pair_damping(&inverse_masses, parameters.stiffness(d), parameters.damping_ratio)?;
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

/// The inertia factor of the pair rows: the rows of a dense factor ([`factor_rows`]) or the
/// tree-sparse factor (reflected masses by [`TreeFactorization::inverse_reflected_masses`] over
/// the support paths of the two Jacobians).
enum PairFactor<'a, T: RealField, const N: usize> {
    Rows(SMatrix<T, N, N>),
    Tree(&'a TreeFactorization<T, N>),
}

/// The rows of the Cholesky factor `L` of `M = L Lᵀ` as contiguous slices: `Lᵀ` in
/// column-major storage (column `i` holds row `i` of `L`; only its first `i + 1` entries, the
/// lower triangle, are written). Built once per [`collision_rows_from_geometry`] call for the
/// dot-product forward substitutions of [`inverse_reflected_masses`].
pub fn factor_rows<T: RealField + Copy, const N: usize>(mass_cholesky: &Cholesky<T, Const<N>>) -> SMatrix<T, N, N> {
    let mut rows = SMatrix::<T, N, N>::zeros();
    let out = rows.as_mut_slice();
    for (c, column) in mass_cholesky.l_dirty().as_slice().chunks_exact(N).enumerate() {
        for (r, &x) in column.iter().enumerate().skip(c) {
            if let Some(slot) = out.get_mut(r * N + c) {
                *slot = x;
            }
        }
    }
    rows
}

/// `(‖L⁻¹ b₁‖², …, ‖L⁻¹ b_K‖²)` with `M = L Lᵀ` given by [`factor_rows`] (1/kg): the inverse
/// reflected masses `J M⁻¹ Jᵀ` (3.20) of the Jacobian rows `J = bₖᵀ`.
///
/// Forward substitution in dot-product form over the rows of `L`,
/// `yᵢ = (bᵢ − Σ_{k<i} l_ik y_k) / l_ii`, with the same operations in the same order as the
/// column-oriented [`inverse_reflected_mass`] (the reference), starting at the first nonzero
/// entry of the right-hand sides (the entries of `y` before it are zero).
pub fn inverse_reflected_masses<T: RealField + Copy, const N: usize, const K: usize>(
    factor_rows: &SMatrix<T, N, N>,
    rhs: [&[T; N]; K],
) -> Result<[T; K], TaskError> {
    // `y[k]` holds the K solutions' entries `k` side by side: one pass over each row of `L`
    // serves every right-hand side.
    let mut y = [[T::zero(); K]; N];
    let start = rhs.iter().map(|b| b.iter().position(|x| !x.is_zero()).unwrap_or(N)).fold(N, usize::min);
    let rows = factor_rows.as_slice().chunks_exact(N).skip(start);
    for (i, row) in (start..N).zip(rows) {
        let (Some(before), Some(&diag), Some(done)) = (row.get(start..i), row.get(i), y.get(start..i)) else {
            break;
        };
        if diag.is_zero() {
            return Err(TaskError::Singular);
        }
        let mut sum = [T::zero(); K];
        for (s, b) in sum.iter_mut().zip(rhs) {
            *s = b.get(i).copied().unwrap_or_else(T::zero);
        }
        for (&l, yk) in before.iter().zip(done) {
            for (s, &x) in sum.iter_mut().zip(yk) {
                *s += -(x * l);
            }
        }
        if let Some(yi) = y.get_mut(i) {
            for (x, s) in yi.iter_mut().zip(sum) {
                *x = s / diag;
            }
        }
    }
    let mut norms = [T::zero(); K];
    for yk in y.get(start..).unwrap_or_default() {
        for (n, &x) in norms.iter_mut().zip(yk) {
            *n += x * x;
        }
    }
    Ok(norms)
}

/// Writes `eᵀ J_{x,q}` for the point `point` (world, m) on `body` into `row` (zeroed first):
/// per joint on the support path, `eᵀ (v_S + ω_S × x) = eᵀ v_S + ω_Sᵀ (x × e)` spread over
/// the joint's drive terms, (3.17)–(3.18). The fast form of [`projected_jacobian`].
fn projected_jacobian_into<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    body: BodyId,
    point: &Vector3<T>,
    direction: &Vector3<T>,
    row: &mut [T; N],
) -> Result<(), TaskError> {
    *row = [T::zero(); N];
    let bodies = model.bodies();
    bodies.get(body.0).ok_or(DynamicsError::UnknownBody)?;
    let moment = point.cross(direction);
    let (e, m) = (direction, &moment);
    let mut next = Some(body);
    for _ in 0..B {
        let Some(id) = next else {
            break;
        };
        let Some(joint) = bodies.get(id.0) else {
            break;
        };
        next = joint.parent;
        let Some(s) = data.motion_subspaces.get(id.0) else {
            continue;
        };
        let value = e.x * s.w + e.y * s.a + e.z * s.b + (m.x * s.x + m.y * s.y + m.z * s.z);
        // Most joints have one drive term: no loop set-up for them.
        match joint.drive.terms() {
            [term] => {
                if let Some(x) = row.get_mut(term.coordinate) {
                    *x += value * term.coefficient;
                }
            }
            terms => {
                for term in terms {
                    if let Some(x) = row.get_mut(term.coordinate) {
                        *x += value * term.coefficient;
                    }
                }
            }
        }
    }
    Ok(())
}

/// The configuration-dependent part of the pair rows of one cycle, shared by the collision
/// fields that evaluate the same geometry (the strong and the weak field of Fig. 6.3): per pair,
/// the row Jacobian `eᵀ(J_{x,q,j} − J_{x,q,i})` (3.17)–(3.18) and the sum of the inverse
/// reflected masses `m_i⁻¹ + m_j⁻¹` (3.20). A pair whose row one field computed costs the next
/// field only its force law. Valid for one geometry: [`Self::clear`] it when the kinematics or
/// the inertia factor change (every cycle). Holds up to `C` pairs; a pair that does not fit is
/// computed again, never dropped.
#[derive(Clone, Debug)]
pub struct PairRowCache<T: RealField, const N: usize, const P: usize, const C: usize> {
    /// Entry of each pair in `entries` (`u16::MAX`: none).
    slot: [u16; P],
    entries: Vec<CachedPairRow<T, N>, C>,
}

#[derive(Clone, Copy, Debug)]
struct CachedPairRow<T: RealField, const N: usize> {
    jacobian: RowSVector<T, N>,
    inverse_mass_sum: T,
}

impl<T: RealField + Copy, const N: usize, const P: usize, const C: usize> Default for PairRowCache<T, N, P, C> {
    fn default() -> Self {
        Self { slot: [u16::MAX; P], entries: Vec::new() }
    }
}

impl<T: RealField + Copy, const N: usize, const P: usize, const C: usize> PairRowCache<T, N, P, C> {
    /// Forgets every pair (a new geometry or inertia factor).
    pub fn clear(&mut self) {
        self.slot = [u16::MAX; P];
        self.entries.clear();
    }

    fn get(&self, pair: usize) -> Option<&CachedPairRow<T, N>> {
        let k = usize::from(*self.slot.get(pair)?);
        self.entries.get(k)
    }

    fn insert(&mut self, pair: usize, row: CachedPairRow<T, N>) {
        let (Some(slot), Ok(k)) = (self.slot.get_mut(pair), u16::try_from(self.entries.len())) else {
            return;
        };
        if self.entries.push(row).is_ok() {
            *slot = k;
        }
    }
}

/// The row of pair `pair` (as [`evaluate_pair`]`(..).row`, equal to rounding) written into
/// `row` without the pair's intermediate results: the row Jacobian and the inverse reflected
/// masses from `cache`, or from [`pair_kinematics`] (then cached), the force law (3.10) of
/// `parameters` and the damping constant of (3.23) in the closed form
/// `c = 2 ξ √(k / (m_i⁻¹ + m_j⁻¹))` (see [`pair_damping`]). The proximity must have a
/// direction. On error `row` is unspecified.
#[allow(clippy::too_many_arguments, reason = "the inputs of pair_kinematics, the force law and the cache")]
fn pair_row_into<
    T: RealField + Copy,
    const N: usize,
    const B: usize,
    const F: usize,
    const V: usize,
    const P: usize,
    const C: usize,
>(
    collision_model: &CollisionModel<T, V, P>,
    collision: &CollisionData<T, V, P>,
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    factor: &PairFactor<'_, T, N>,
    parameters: &CollisionParameters<T>,
    pair: usize,
    cache: &mut PairRowCache<T, N, P, C>,
    row: &mut TaskRow<T, N>,
) -> Result<(), TaskError> {
    let invalid = TaskError::InvalidParameter { name: "pair" };
    let proximity: &Proximity<T> = collision.proximities.get(pair).ok_or(invalid)?;
    let d = proximity.distance;
    let inverse_mass_sum = match cache.get(pair) {
        Some(entry) => {
            row.jacobian = entry.jacobian;
            entry.inverse_mass_sum
        }
        None => {
            let sum = pair_kinematics(collision_model, proximity, model, data, factor, pair, &mut row.jacobian)?;
            cache.insert(pair, CachedPairRow { jacobian: row.jacobian, inverse_mass_sum: sum });
            sum
        }
    };
    let stiffness = parameters.stiffness(d);
    let c = if stiffness > T::zero() && inverse_mass_sum > T::zero() {
        convert::<f64, T>(2.0) * parameters.damping_ratio * sqrt(stiffness / inverse_mass_sum)
    } else {
        T::zero()
    };
    let rate = row.jacobian.as_slice().iter().zip(data.v.as_slice()).fold(T::zero(), |r, (&j, &v)| r + j * v);
    row.force = parameters.force(d) - c * rate;
    row.potential = parameters.potential(d);
    row.activation = parameters.activation(d);
    if !(row.force.is_finite() && row.potential.is_finite() && row.activation.is_finite()) {
        return Err(TaskError::NonFinite);
    }
    Ok(())
}

/// [`pair_row_into`] returning the row.
#[cfg(test)]
#[allow(clippy::too_many_arguments, reason = "the inputs of pair_row_into")]
fn pair_row<
    T: RealField + Copy,
    const N: usize,
    const B: usize,
    const F: usize,
    const V: usize,
    const P: usize,
    const C: usize,
>(
    collision_model: &CollisionModel<T, V, P>,
    collision: &CollisionData<T, V, P>,
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    factor: &PairFactor<'_, T, N>,
    parameters: &CollisionParameters<T>,
    pair: usize,
    cache: &mut PairRowCache<T, N, P, C>,
) -> Result<TaskRow<T, N>, TaskError> {
    let mut row =
        TaskRow { jacobian: RowSVector::zeros(), force: T::zero(), potential: T::zero(), activation: T::zero() };
    pair_row_into(collision_model, collision, model, data, factor, parameters, pair, cache, &mut row)?;
    Ok(row)
}

/// The configuration-dependent part of pair `pair`'s row: the two projected Jacobians written in
/// place ([`projected_jacobian_into`]), their difference written into `jacobian`, and the sum of
/// both inverse reflected masses (3.20), returned: one forward substitution over the factor for
/// both ([`inverse_reflected_masses`] on dense rows, [`TreeFactorization::inverse_reflected_masses`]
/// on the tree factor); none for a world-fixed volume, whose mass is infinite. The proximity must have a direction.
fn pair_kinematics<
    T: RealField + Copy,
    const N: usize,
    const B: usize,
    const F: usize,
    const V: usize,
    const P: usize,
>(
    collision_model: &CollisionModel<T, V, P>,
    proximity: &Proximity<T>,
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    factor: &PairFactor<'_, T, N>,
    pair: usize,
    jacobian: &mut RowSVector<T, N>,
) -> Result<T, TaskError> {
    let invalid = TaskError::InvalidParameter { name: "pair" };
    let &CollisionPair { first, second } = collision_model.pairs().get(pair).ok_or(invalid)?;
    let (Some(a), Some(b)) = (collision_model.volume(first), collision_model.volume(second)) else {
        return Err(invalid);
    };
    let e = proximity.direction.ok_or(TaskError::Singular)?.into_inner();
    let mut jacobian_first = [T::zero(); N];
    let mut jacobian_second = [T::zero(); N];
    if let Some(body) = a.body {
        projected_jacobian_into(model, data, body, &proximity.core_first, &e, &mut jacobian_first)?;
    }
    if let Some(body) = b.body {
        projected_jacobian_into(model, data, body, &proximity.core_second, &e, &mut jacobian_second)?;
    }
    let inverse_mass_sum = match (a.body.is_some(), b.body.is_some(), factor) {
        (true, true, PairFactor::Rows(rows)) => {
            let [wi, wj] = inverse_reflected_masses(rows, [&jacobian_first, &jacobian_second])?;
            wi + wj
        }
        (true, false, PairFactor::Rows(rows)) => inverse_reflected_masses(rows, [&jacobian_first])?[0],
        (false, true, PairFactor::Rows(rows)) => inverse_reflected_masses(rows, [&jacobian_second])?[0],
        (true, true, PairFactor::Tree(tree)) => {
            let [wi, wj] = tree.inverse_reflected_masses([&jacobian_first, &jacobian_second]);
            wi + wj
        }
        (true, false, PairFactor::Tree(tree)) => tree.inverse_reflected_masses([&jacobian_first])[0],
        (false, true, PairFactor::Tree(tree)) => tree.inverse_reflected_masses([&jacobian_second])[0],
        (false, false, _) => T::zero(),
    };
    // The difference and its finiteness in one pass (no early exit: a branch-free flag).
    let mut finite = inverse_mass_sum.is_finite();
    for ((x, &ji), &jj) in jacobian.as_mut_slice().iter_mut().zip(&jacobian_first).zip(&jacobian_second) {
        let value = jj - ji;
        finite &= value.is_finite();
        *x = value;
    }
    if !finite {
        return Err(TaskError::NonFinite);
    }
    Ok(inverse_mass_sum)
}

/// Puts `item` at node `root` of the binary max-heap `heap` (by distance, the farthest at the
/// root), whose subtrees below `root` are heaps, and restores the order of that subtree: the
/// larger child moves up into the hole until `item` is no closer than both children.
/// O(log len).
fn sift<T: RealField + Copy>(heap: &mut [(T, usize)], root: usize, item: (T, usize)) {
    let mut hole = root;
    for _ in 0..heap.len() {
        let left = 2 * hole + 1;
        let Some(&l) = heap.get(left) else { break };
        let (child, c) = match heap.get(left + 1) {
            Some(&r) if r.0 > l.0 => (left + 1, r),
            _ => (left, l),
        };
        if c.0 <= item.0 {
            break;
        }
        if let Some(h) = heap.get_mut(hole) {
            *h = c;
        }
        hole = child;
    }
    if let Some(h) = heap.get_mut(hole) {
        *h = item;
    }
}

/// Orders `heap` as a binary max-heap by distance (the farthest at the root), O(len).
fn heapify<T: RealField + Copy>(heap: &mut [(T, usize)]) {
    for root in (0..heap.len() / 2).rev() {
        if let Some(&item) = heap.get(root) {
            sift(heap, root, item);
        }
    }
}

/// What [`self_collision_rows`] did in one cycle (telemetry).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CollisionReport<T> {
    /// Pairs closer than [`CollisionParameters::emit_distance`].
    pub candidates: usize,
    /// Rows appended.
    pub rows: usize,
    /// Candidates left out because the row list was full (the farthest ones).
    pub dropped: usize,
    /// Candidates whose cores touch (no collision direction): deep penetration, left out.
    pub undefined_direction: usize,
    /// The smallest distance over all enabled pairs (m), `None` without pairs.
    pub min_distance: Option<T>,
}

/// The self- and environment-collision avoidance rows of one control cycle (Sec. 3.1,
/// n_sca contact-point pairs of (3.3)).
///
/// Updates the geometry ([`CollisionModel::update`]), selects the pairs closer than
/// `max(d0, ϑ2)` — the closest ones if more than the free row capacity `R − rows.len()` —
/// and appends one row per selected pair in pair order ([`evaluate_pair`]). Summed alone the
/// rows give τ_sca of (3.2)/(3.24): `rows.torque()`.
///
/// Preconditions: `forward_kinematics` at `(q, q̇)`, then `crba` and the inertia factor `mass`
/// ([`InertiaFactor`]: `mass_matrix_cholesky`'s dense factor, O(R·N²) for the reflected masses,
/// or a [`TreeFactorization`], O(R·Σ depth) over the support paths).
/// Writes `collision`; appends to `rows`. Cost O(V + P·R) plus the reflected masses. On error `rows` is
/// unchanged (the geometry in `collision` is updated).
pub fn self_collision_rows<
    'm,
    T: RealField + Copy,
    const N: usize,
    const B: usize,
    const F: usize,
    const V: usize,
    const P: usize,
    const R: usize,
>(
    collision_model: &CollisionModel<T, V, P>,
    collision: &mut CollisionData<T, V, P>,
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    mass: impl Into<InertiaFactor<'m, T, N>>,
    parameters: &CollisionParameters<T>,
    rows: &mut TaskRows<T, N, R>,
) -> Result<CollisionReport<T>, TaskError> {
    collision_model.update(data, collision);
    collision_rows_from_geometry(collision_model, collision, model, data, mass, parameters, rows)
}

/// [`self_collision_rows`] without the geometry update: selects and evaluates the pairs from
/// the proximities already in `collision`, which must come from [`CollisionModel::update`]
/// after the `forward_kinematics` of `data` (this cycle's). Gives exactly the rows and report
/// of [`self_collision_rows`] then; lets several collision fields (the strong and the weak one
/// of Fig. 6.3) share one geometry update per cycle, which is most of the cost of a field with
/// few active pairs (214 pair distances for Justin).
///
/// ```
/// # use kernel::dynamics::{crba, forward_kinematics, mass_matrix_cholesky};
/// # use kernel::model::{Data, Inertia, JointDrive, JointKind, ModelBuilder, Placement};
/// # use kernel::tasks::collision::{collision_rows_from_geometry, self_collision_rows,
/// #     CollisionData, CollisionModelBuilder, CollisionParameters, SweptSphere};
/// # use kernel::tasks::TaskRows;
/// # use nalgebra::{SVector, Unit, Vector3};
/// # let mut b = ModelBuilder::<f64, 1, 1, 1>::new(Vector3::zeros());
/// # let slider = b.add_body(None, Placement::identity(),
/// #     JointKind::Prismatic { axis: Unit::new_normalize(Vector3::x()) }, JointDrive::actuated(0),
/// #     Inertia::point_mass(2.0, Vector3::zeros())).unwrap();
/// # let robot = b.try_build().unwrap();
/// # let mut c = CollisionModelBuilder::<f64, 2, 1>::new();
/// # c.add_volume(Some(slider), SweptSphere::sphere(Vector3::zeros(), 0.1)).unwrap();
/// # c.add_volume(None, SweptSphere::sphere(Vector3::new(0.3, 0.0, 0.0), 0.1)).unwrap();
/// # let collision_model = c.try_build(&robot, &[]).unwrap();
/// # let mut collision = CollisionData::new(&collision_model);
/// # let mut data = Data::new(&robot);
/// # forward_kinematics(&robot, &mut data, &SVector::zeros(), &SVector::zeros()).unwrap();
/// # crba(&robot, &mut data);
/// # let factor = mass_matrix_cholesky(&data).unwrap();
/// let strong = CollisionParameters::try_new(150.0, 0.05, 0.7, 0.01, 0.05).unwrap();
/// let weak = CollisionParameters::try_new(25.0, 0.15, 0.7, 0.0, 0.15).unwrap();
/// let (mut a, mut b) = (TaskRows::<f64, 1, 4>::new(), TaskRows::<f64, 1, 4>::new());
/// // First field: updates the geometry; second field: reuses it.
/// self_collision_rows(&collision_model, &mut collision, &robot, &data, &factor, &strong, &mut a).unwrap();
/// collision_rows_from_geometry(&collision_model, &collision, &robot, &data, &factor, &weak, &mut b).unwrap();
/// let mut c = TaskRows::<f64, 1, 4>::new();
/// self_collision_rows(&collision_model, &mut collision, &robot, &data, &factor, &weak, &mut c).unwrap();
/// assert_eq!(b, c);
/// ```
pub fn collision_rows_from_geometry<
    'm,
    T: RealField + Copy,
    const N: usize,
    const B: usize,
    const F: usize,
    const V: usize,
    const P: usize,
    const R: usize,
>(
    collision_model: &CollisionModel<T, V, P>,
    collision: &CollisionData<T, V, P>,
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    mass: impl Into<InertiaFactor<'m, T, N>>,
    parameters: &CollisionParameters<T>,
    rows: &mut TaskRows<T, N, R>,
) -> Result<CollisionReport<T>, TaskError> {
    let mut cache = PairRowCache::<T, N, P, R>::default();
    collision_rows_shared(collision_model, collision, model, data, mass, parameters, &mut cache, rows)
}

/// [`collision_rows_from_geometry`] with the pair rows shared between fields through `cache`:
/// a pair another field of this cycle already evaluated costs only its force law. `cache`
/// must be cleared ([`PairRowCache::clear`]) whenever the geometry or the inertia factor
/// change; with a cleared cache the rows are those of [`collision_rows_from_geometry`], and
/// with a filled one they are equal to them (the same arithmetic).
#[allow(clippy::too_many_arguments, reason = "the inputs of collision_rows_from_geometry and the cache")]
pub fn collision_rows_shared<
    'm,
    T: RealField + Copy,
    const N: usize,
    const B: usize,
    const F: usize,
    const V: usize,
    const P: usize,
    const C: usize,
    const R: usize,
>(
    collision_model: &CollisionModel<T, V, P>,
    collision: &CollisionData<T, V, P>,
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    mass: impl Into<InertiaFactor<'m, T, N>>,
    parameters: &CollisionParameters<T>,
    cache: &mut PairRowCache<T, N, P, C>,
    rows: &mut TaskRows<T, N, R>,
) -> Result<CollisionReport<T>, TaskError> {
    let free = R.saturating_sub(rows.len());
    let limit = parameters.emit_distance();
    let mut report = CollisionReport { candidates: 0, rows: 0, dropped: 0, undefined_direction: 0, min_distance: None };
    // The `free` closest candidates `(distance, pair index)`: filled in pair order, then kept as
    // a binary max-heap by distance whose root (the farthest) a closer candidate replaces,
    // O(log R) per replacement.
    let mut selected: Vec<(T, usize), R> = Vec::new();
    let mut heap = false;
    for (index, proximity) in collision.proximities.iter().take(collision_model.pairs().len()).enumerate() {
        let d = proximity.distance;
        if !d.is_finite() {
            return Err(TaskError::NonFinite);
        }
        report.min_distance = Some(report.min_distance.map_or(d, |m: T| m.min(d)));
        if d >= limit {
            continue;
        }
        report.candidates += 1;
        if proximity.direction.is_none() {
            report.undefined_direction += 1;
            continue;
        }
        if selected.len() < free {
            let _ = selected.push((d, index));
            continue;
        }
        report.dropped += 1;
        if !heap {
            heapify(&mut selected);
            heap = true;
        }
        // A candidate at the root's distance stays out (the earlier pair is kept).
        if selected.first().is_some_and(|root| d < root.0) {
            sift(&mut selected, 0, (d, index));
        }
    }
    // Rows in pair order: a pass over a membership mask of the pairs instead of a sort, whose
    // ordering-violation panic path would survive in the image.
    let mut chosen = [false; P];
    for &(_, index) in &selected {
        if let Some(flag) = chosen.get_mut(index) {
            *flag = true;
        }
    }
    // Each row is built in its slot of `rows`; on an error the rows appended here are removed.
    if !selected.is_empty() {
        let factor = match mass.into() {
            InertiaFactor::Dense(cholesky) => PairFactor::Rows(factor_rows(cholesky)),
            InertiaFactor::Tree(tree) => PairFactor::Tree(tree),
        };
        let start = rows.len();
        for (index, _) in chosen.iter().enumerate().filter(|(_, &flag)| flag) {
            let mut result = Ok(());
            let pushed = rows.push_with(|row| {
                result = pair_row_into(collision_model, collision, model, data, &factor, parameters, index, cache, row);
            });
            if let Err(e) = result.and(pushed) {
                rows.truncate(start);
                return Err(e);
            }
        }
    }
    report.rows = selected.len();
    Ok(report)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::dynamics::{crba, forward_kinematics, mass_matrix_cholesky};
    use crate::tasks::collision::{CollisionModelBuilder, SweptSphere};
    use crate::test_models::{branched, state, Branched, B, F, N};
    use nalgebra::Vector3;

    const V: usize = 6;
    const P: usize = 15;

    fn v3<T: RealField + Copy>(x: f64, y: f64, z: f64) -> Vector3<T> {
        Vector3::new(convert(x), convert(y), convert(z))
    }

    /// Volumes on both branches of the test tree and in the world: a capsule on the coupled
    /// branch, a swept triangle and a sphere on the prismatic branch, a capsule on the pitch
    /// body, a world-fixed floor triangle and a world-fixed sphere.
    fn collision_model<T: RealField + Copy>(robot: &Branched<T>) -> CollisionModel<T, V, P> {
        let mut c = CollisionModelBuilder::<T, V, P>::new();
        let r = |x: f64| convert::<f64, T>(x);
        c.add_volume(Some(BodyId(4)), SweptSphere::capsule(v3(0.0, 0.0, 0.0), v3(0.15, 0.02, 0.0), r(0.05))).unwrap();
        c.add_volume(
            Some(BodyId(6)),
            SweptSphere::swept_triangle(v3(0.0, 0.0, 0.0), v3(0.1, 0.0, 0.05), v3(0.0, 0.12, 0.1), r(0.03)),
        )
        .unwrap();
        c.add_volume(Some(BodyId(5)), SweptSphere::sphere(v3(0.05, -0.02, 0.1), r(0.06))).unwrap();
        c.add_volume(Some(BodyId(2)), SweptSphere::capsule(v3(0.05, 0.0, 0.0), v3(0.25, 0.0, 0.0), r(0.04))).unwrap();
        c.add_volume(
            None,
            SweptSphere::swept_triangle(v3(-5.0, -5.0, -0.2), v3(10.0, -5.0, -0.2), v3(-5.0, 10.0, -0.2), r(0.0)),
        )
        .unwrap();
        c.add_volume(None, SweptSphere::sphere(v3(0.4, 0.3, 0.5), r(0.1))).unwrap();
        c.try_build(robot, &[]).unwrap()
    }

    fn parameters<T: RealField + Copy>(xi: f64) -> CollisionParameters<T> {
        // d0 large enough that most pairs are inside their potential at random states.
        CollisionParameters::try_new(convert(25.0), convert(1.0), convert(xi), convert(0.1), convert(0.6)).unwrap()
    }

    #[test]
    fn potential_force_and_stiffness() {
        let p = CollisionParameters::try_new(25.0_f64, 0.15, 0.7, 0.0, 0.15).unwrap();
        // (3.10): F(0) = F_max; local stiffness 2 F_max/d0 = 333 N/m at contact.
        assert_eq!(p.force(0.0), 25.0);
        assert!((p.stiffness(0.0) - 1000.0 / 3.0).abs() < 1e-12);
        assert!((p.potential(0.0) - 25.0 * 0.15 / 3.0).abs() < 1e-15);
        // F = −dV/dd and k = dF/dd... = −dF/dd, by central differences (relative 1e-6).
        let h = 1e-6;
        for k in 0..300 {
            let d = -0.05 + 0.2 * f64::from(k) / 300.0;
            if (d - 0.15).abs() < 2.0 * h {
                continue;
            }
            let force = -(p.potential(d + h) - p.potential(d - h)) / (2.0 * h);
            let stiffness = -(p.force(d + h) - p.force(d - h)) / (2.0 * h);
            assert!((force - p.force(d)).abs() <= 1e-6 * p.force(d).max(1e-3), "F at {d}");
            assert!((stiffness - p.stiffness(d)).abs() <= 1e-6 * p.stiffness(d).max(1e-3), "k at {d}");
        }
        // C² at d0: one-sided second differences of V on both sides tend to V''(d0) = 0.
        let d0 = 0.15;
        for h in [1e-3, 1e-4] {
            let left = (p.potential(d0) - 2.0 * p.potential(d0 - h) + p.potential(d0 - 2.0 * h)) / (h * h);
            let right = (p.potential(d0 + 2.0 * h) - 2.0 * p.potential(d0 + h) + p.potential(d0)) / (h * h);
            assert!(
                right == 0.0 && left.abs() <= 2.0 * 25.0 / (0.15 * 0.15) * 3.0 * h,
                "V'' left {left} right {right}"
            );
        }
        assert_eq!((p.potential(d0), p.force(d0), p.stiffness(d0)), (0.0, 0.0, 0.0));
        // Activation band [0, d0]: 1 at contact, ½ in the middle, 0 beyond.
        assert_eq!((p.activation(0.0), p.activation(0.2)), (1.0, 0.0));
        assert!((p.activation(0.075) - 0.5).abs() < 1e-15);
        // Table 4.5 band: maximal slope 1.5/(ϑ2 − ϑ1) = 18.75 1/m.
        let t = CollisionParameters::try_new(30.0_f64, 0.10, 0.5, 0.05, 0.13).unwrap();
        let slope = (t.activation(0.09 - 1e-7) - t.activation(0.09 + 1e-7)) / 2e-7;
        assert!((slope - 18.75).abs() < 1e-5);
        // f32.
        let p32 = CollisionParameters::try_new(25.0_f32, 0.15, 0.7, 0.0, 0.15).unwrap();
        assert_eq!(p32.force(0.0), 25.0);
        assert!((p32.potential(0.05) - 25.0 / (3.0 * 0.0225) * 0.001).abs() < 1e-6);
        // Validation.
        assert_eq!(
            CollisionParameters::try_new(0.0_f64, 0.1, 0.5, 0.0, 0.1),
            Err(TaskError::InvalidParameter { name: "max_force" })
        );
        assert_eq!(
            CollisionParameters::try_new(1.0_f64, 0.1, -0.5, 0.0, 0.1),
            Err(TaskError::InvalidParameter { name: "damping_ratio" })
        );
        assert_eq!(
            CollisionParameters::try_new(1.0_f64, 0.1, 0.5, 0.2, 0.1),
            Err(TaskError::InvalidParameter { name: "activation band" })
        );
        assert_eq!(CollisionParameters::try_new(1.0_f64, f64::NAN, 0.5, 0.0, 0.1), Err(TaskError::NonFinite));
    }

    #[test]
    fn pair_damping_matches_the_closed_form() {
        for seed in 7..207 {
            let s = state(seed, 1.0);
            let (mi, mj, k, xi) =
                (0.5 + 10.0 * s[0].abs(), 0.5 + 10.0 * s[1].abs(), 400.0 * s[2].abs(), 1.5 * s[3].abs());
            let (c, d) = pair_damping(&Vector2::new(1.0 / mi, 1.0 / mj), k, xi).unwrap();
            let expected = 2.0 * xi * (k * mi * mj / (mi + mj)).sqrt();
            assert!((c - expected).abs() <= 1e-12 * (1.0 + expected), "{c} vs {expected}");
            // D = c [[1, −1], [−1, 1]]: the common mode is undamped.
            assert_eq!(d * Vector2::new(1.0, 1.0), Vector2::zeros());
            // World-fixed partner: m_eff = m_i.
            let (c, _) = pair_damping(&Vector2::new(0.0, 1.0 / mj), k, xi).unwrap();
            assert!((c - 2.0 * xi * (k * mj).sqrt()).abs() <= 1e-9 * (1.0 + c));
        }
        // Extreme mass ratios (a point near a joint axis): still the closed form, f64 and f32.
        for ratio in [1e2, 1e4, 1e6, 1e9] {
            let (c, _) = pair_damping(&Vector2::new(1.0 / ratio, 0.5), 300.0_f64, 0.7).unwrap();
            let expected = 2.0 * 0.7 * (300.0 / (0.5 + 1.0 / ratio)).sqrt();
            assert!((c - expected).abs() <= 1e-10 * expected, "ratio {ratio}: {c} vs {expected}");
            let (c, _) = pair_damping(&Vector2::new(1.0 / ratio as f32, 0.5), 300.0_f32, 0.7).unwrap();
            assert!((f64::from(c) - expected).abs() <= 1e-4 * expected, "f32 ratio {ratio}: {c} vs {expected}");
        }
        assert_eq!(pair_damping(&Vector2::new(0.0, 0.0), 100.0, 0.7).unwrap().0, 0.0);
        assert_eq!(pair_damping(&Vector2::new(1.0, 1.0), 0.0, 0.7).unwrap().0, 0.0);
        assert_eq!(pair_damping(&Vector2::new(1.0, f64::NAN), 1.0, 0.7), Err(TaskError::NonFinite));
        // f32.
        let (c, _) = pair_damping(&Vector2::new(0.5_f32, 0.5), 200.0, 1.0).unwrap();
        assert!((c - 2.0 * 200.0_f32.sqrt()).abs() < 1e-3);
    }

    /// Total collision potential `Σ V(d_k(q))` of all enabled pairs.
    fn total_potential(
        robot: &Branched<f64>,
        data: &mut Data<f64, N, B, F>,
        cm: &CollisionModel<f64, V, P>,
        cd: &mut CollisionData<f64, V, P>,
        p: &CollisionParameters<f64>,
        q: &SVector<f64, N>,
    ) -> f64 {
        forward_kinematics(robot, data, q, &SVector::zeros()).unwrap();
        cm.update(data, cd);
        cd.proximities.iter().take(cm.pairs().len()).map(|x| p.potential(x.distance)).sum()
    }

    /// τ = Σ jᵀ f equals −∂V/∂q (central differences, relative 1e-6) at random states, and
    /// j q̇ equals the rate of each distance; with q̇ ≠ 0 the rows equal (3.24) with the 2×2
    /// damping matrices.
    #[test]
    fn torques_are_the_negative_potential_gradient() {
        let robot = branched::<f64>();
        let cm = collision_model(&robot);
        assert_eq!(cm.pairs().len(), 13, "15 pairs minus world–world and wrist–prism (adjacent)");
        let mut cd = CollisionData::new(&cm);
        let mut data = Data::new(&robot);
        let p = parameters::<f64>(0.7);
        let mut checked = 0;
        for seed in 0..200 {
            let q = state(seed, 1.5);
            let v = state(seed + 1000, 1.0);
            forward_kinematics(&robot, &mut data, &q, &SVector::zeros()).unwrap();
            crba(&robot, &mut data);
            let factor = mass_matrix_cholesky(&data).unwrap();
            let mut rows = TaskRows::<f64, N, P>::new();
            let report = self_collision_rows(&cm, &mut cd, &robot, &data, &factor, &p, &mut rows).unwrap();
            assert_eq!(report.dropped, 0);
            if report.undefined_direction > 0 || rows.is_empty() {
                continue;
            }
            let tau = rows.torque();
            let h = 1e-6;
            let gradient = SVector::<f64, N>::from_fn(|k, _| {
                let e = SVector::<f64, N>::from_fn(|i, _| if i == k { h } else { 0.0 });
                (total_potential(&robot, &mut data, &cm, &mut cd, &p, &(q + e))
                    - total_potential(&robot, &mut data, &cm, &mut cd, &p, &(q - e)))
                    / (2.0 * h)
            });
            assert!((tau + gradient).amax() <= 1e-6 * tau.amax().max(1e-3), "seed {seed}: {tau} vs {gradient}");
            assert!((rows.potential() - total_potential(&robot, &mut data, &cm, &mut cd, &p, &q)).abs() < 1e-12);
            checked += 1;

            // Rates: j q̇ = ḋ by central differences along q̇.
            let distances = |data: &mut Data<f64, N, B, F>, cd: &mut CollisionData<f64, V, P>, q: &SVector<f64, N>| {
                forward_kinematics(&robot, data, q, &SVector::zeros()).unwrap();
                cm.update(data, cd);
                cd.proximities.map(|x| x.distance)
            };
            let (plus, minus) =
                (distances(&mut data, &mut cd, &(q + v * h)), distances(&mut data, &mut cd, &(q - v * h)));
            forward_kinematics(&robot, &mut data, &q, &v).unwrap();
            crba(&robot, &mut data);
            cm.update(&data, &mut cd);
            for pair in 0..cm.pairs().len() {
                if cd.proximities[pair].distance >= p.emit_distance() {
                    continue;
                }
                let e = evaluate_pair(&cm, &cd, &robot, &data, &factor, &p, pair).unwrap();
                let rate = (plus[pair] - minus[pair]) / (2.0 * h);
                assert!(((e.row.jacobian * v).x - rate).abs() <= 1e-6 * (1.0 + rate.abs()));
                // (3.24) with the 2×2 matrix equals the row form.
                let row_torque = e.row.jacobian.transpose() * e.row.force;
                let thesis = e.torque(p.force(e.distance), &v);
                assert!((row_torque - thesis).amax() <= 1e-12 * (1.0 + row_torque.amax()), "{row_torque} vs {thesis}");
                // Reflected masses against an explicit inverse of M.
                let inverse = data.mass_matrix.try_inverse().unwrap();
                let wi = (e.jacobian_first * inverse * e.jacobian_first.transpose()).x;
                let wj = (e.jacobian_second * inverse * e.jacobian_second.transpose()).x;
                assert!((e.inverse_masses - Vector2::new(wi, wj)).amax() <= 1e-10 * (1.0 + wi.max(wj)));
                let world_fixed = cm.volume(cm.pairs()[pair].second).unwrap().body.is_none();
                assert_eq!(e.reflected_masses().1.is_none(), world_fixed);
            }
        }
        assert!(checked > 150, "only {checked} states had active pairs");
    }

    #[test]
    fn rows_keep_the_closest_pairs_and_errors_leave_rows_unchanged() {
        let robot = branched::<f64>();
        let cm = collision_model(&robot);
        let mut cd = CollisionData::new(&cm);
        let mut data = Data::new(&robot);
        let q = state(3, 1.0);
        forward_kinematics(&robot, &mut data, &q, &state(4, 1.0)).unwrap();
        crba(&robot, &mut data);
        let factor = mass_matrix_cholesky(&data).unwrap();
        let p = parameters::<f64>(1.0);
        let mut all = TaskRows::<f64, N, P>::new();
        let full = self_collision_rows(&cm, &mut cd, &robot, &data, &factor, &p, &mut all).unwrap();
        assert!(full.candidates >= 4, "{full:?}");
        // Capacity 3 with one row already present: the two closest candidates.
        let mut few = TaskRows::<f64, N, 3>::new();
        let marker = TaskRow { jacobian: RowSVector::zeros(), force: 1.0, potential: 0.0, activation: 1.0 };
        few.push(marker).unwrap();
        let report = self_collision_rows(&cm, &mut cd, &robot, &data, &factor, &p, &mut few).unwrap();
        assert_eq!((report.rows, report.dropped), (2, full.candidates - 2));
        let mut candidates: std::vec::Vec<(f64, usize)> = cd
            .proximities
            .iter()
            .take(cm.pairs().len())
            .enumerate()
            .filter(|(_, x)| x.distance < p.emit_distance())
            .map(|(i, x)| (x.distance, i))
            .collect();
        candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut closest: std::vec::Vec<usize> = candidates.iter().take(2).map(|c| c.1).collect();
        closest.sort_unstable();
        // The rows are exactly those of the selected pairs (the fast form; it equals the
        // reference `evaluate_pair` to rounding, `fast_rows_match_the_reference_*`).
        let rows_of_l = factor_rows(&factor);
        for (row, pair) in few.rows()[1..].iter().zip(&closest) {
            let mut cache = PairRowCache::<f64, N, P, 4>::default();
            assert_eq!(
                *row,
                pair_row(&cm, &cd, &robot, &data, &PairFactor::Rows(rows_of_l), &p, *pair, &mut cache).unwrap()
            );
            let e = evaluate_pair(&cm, &cd, &robot, &data, &factor, &p, *pair).unwrap();
            assert!(row_difference(row, &e.row) <= 1e-12, "{row:?} vs {:?}", e.row);
        }
        // A full list stays as it was.
        let before = few.clone();
        let report = self_collision_rows(&cm, &mut cd, &robot, &data, &factor, &p, &mut few).unwrap();
        assert_eq!((report.rows, few), (0, before));
        // Unknown pair.
        assert!(evaluate_pair(&cm, &cd, &robot, &data, &factor, &p, 99).is_err());
    }

    /// [`CollisionModel::compute_distances`] (triangle frames computed once per volume) gives
    /// every pair the proximity of [`crate::tasks::collision::proximity`] of its world volumes,
    /// bit for bit, at random states (f64 and f32), with and without the broad phase's far pairs.
    fn shared_triangle_frames_match_proximity<T: RealField + Copy>() {
        let robot = branched::<T>();
        let cm = collision_model(&robot);
        let mut cd = CollisionData::new(&cm);
        let mut data = Data::new(&robot);
        let mut exact = 0;
        for seed in 0..100 {
            forward_kinematics(&robot, &mut data, &state(seed, 1.5).cast::<T>(), &SVector::zeros()).unwrap();
            cd.exact_within = if seed % 2 == 0 { None } else { Some(convert(0.05)) };
            cm.update(&data, &mut cd);
            for (pair, proximity) in cm.pairs().iter().zip(&cd.proximities) {
                let (a, b) = (&cd.world_volumes[pair.first.0], &cd.world_volumes[pair.second.0]);
                if proximity.direction.is_none() && cd.exact_within.is_some() {
                    continue; // a far pair of the broad phase
                }
                assert_eq!(*proximity, crate::tasks::collision::proximity(a, b), "seed {seed} {pair:?}");
                exact += 1;
            }
        }
        assert!(exact > 800, "{exact}");
    }

    #[test]
    fn shared_triangle_frames_match_proximity_f64() {
        shared_triangle_frames_match_proximity::<f64>();
    }

    #[test]
    fn shared_triangle_frames_match_proximity_f32() {
        shared_triangle_frames_match_proximity::<f32>();
    }

    /// The heap selection of the `k` closest candidates against a sort: at random states and
    /// every capacity `k` from 1 to 6, the rows of a field with `k` free rows are exactly the
    /// rows (bit for bit, in pair order) of the `k` candidates with the smallest distances in a
    /// field with room for all, f64 and f32.
    fn selection_matches_a_sort<T: RealField + Copy>() {
        let robot = branched::<T>();
        let cm = collision_model(&robot);
        let mut cd = CollisionData::new(&cm);
        let mut data = Data::new(&robot);
        let p = parameters::<T>(0.7);
        let mut checked = 0;
        for seed in 0..100 {
            forward_kinematics(&robot, &mut data, &state(seed, 1.5).cast::<T>(), &state(seed + 300, 1.0).cast::<T>())
                .unwrap();
            crba(&robot, &mut data);
            let factor = mass_matrix_cholesky(&data).unwrap();
            let mut all = TaskRows::<T, N, P>::new();
            let full = self_collision_rows(&cm, &mut cd, &robot, &data, &factor, &p, &mut all).unwrap();
            assert_eq!(full.dropped, 0);
            let mut candidates: std::vec::Vec<(T, usize)> = cd
                .proximities
                .iter()
                .take(cm.pairs().len())
                .enumerate()
                .filter(|(_, x)| x.distance < p.emit_distance() && x.direction.is_some())
                .map(|(i, x)| (x.distance, i))
                .collect();
            let order: std::vec::Vec<usize> = candidates.iter().map(|c| c.1).collect();
            candidates.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap().then(a.1.cmp(&b.1)));
            for k in 1..=6_usize {
                let mut few = TaskRows::<T, N, 6>::new();
                for _ in k..6 {
                    few.push(TaskRow {
                        jacobian: RowSVector::zeros(),
                        force: T::one(),
                        potential: T::zero(),
                        activation: T::one(),
                    })
                    .unwrap();
                }
                let report = collision_rows_from_geometry(&cm, &cd, &robot, &data, &factor, &p, &mut few).unwrap();
                let mut closest: std::vec::Vec<usize> = candidates.iter().take(k).map(|c| c.1).collect();
                closest.sort_unstable();
                assert_eq!(report.rows, closest.len());
                assert_eq!(report.dropped, candidates.len() - closest.len());
                for (row, pair) in few.rows()[6 - k..].iter().zip(&closest) {
                    let position = order.iter().position(|x| x == pair).unwrap();
                    assert_eq!(*row, all.rows()[position], "seed {seed} k {k} pair {pair}");
                }
                checked += usize::from(candidates.len() > k);
            }
        }
        assert!(checked > 300, "{checked} selections dropped candidates");
    }

    #[test]
    fn selection_matches_a_sort_f64() {
        selection_matches_a_sort::<f64>();
    }

    #[test]
    fn selection_matches_a_sort_f32() {
        selection_matches_a_sort::<f32>();
    }

    /// Largest relative difference of two rows' Jacobians, forces, potentials and activations.
    fn row_difference<T: RealField + Copy>(fast: &TaskRow<T, N>, reference: &TaskRow<T, N>) -> f64 {
        let scale = |x: T| 1.0 + nalgebra::try_convert::<T, f64>(x.abs()).unwrap();
        let rel = |a: T, b: T| nalgebra::try_convert::<T, f64>((a - b).abs()).unwrap() / scale(b);
        let jacobian = fast
            .jacobian
            .iter()
            .zip(reference.jacobian.iter())
            .map(|(&a, &b)| nalgebra::try_convert::<T, f64>((a - b).abs()).unwrap() / scale(reference.jacobian.amax()))
            .fold(0.0, f64::max);
        jacobian
            .max(rel(fast.force, reference.force))
            .max(rel(fast.potential, reference.potential))
            .max(rel(fast.activation, reference.activation))
    }

    /// The fast pair rows ([`pair_row`], used by [`collision_rows_from_geometry`]) and the
    /// fast reflected masses ([`inverse_reflected_masses`]) against the reference
    /// [`evaluate_pair`] / [`inverse_reflected_mass`] at random states with random velocities,
    /// every pair with a direction below the emit distance, f64 (tight) and f32.
    fn fast_rows_match_reference<T: RealField + Copy>(tolerance: f64) {
        let robot = branched::<T>();
        let cm = collision_model(&robot);
        let mut cd = CollisionData::new(&cm);
        let mut data = Data::new(&robot);
        let p = parameters::<T>(0.7);
        let other_field =
            CollisionParameters::try_new(convert(150.0), convert(0.3), convert(1.0), convert(0.0), convert(1.2))
                .unwrap();
        let fresh_cache = PairRowCache::<T, N, P, P>::default;
        let (mut compared, mut damped) = (0, 0);
        for seed in 0..200 {
            let (q, v) = (state(seed, 1.5).cast::<T>(), state(seed + 500, 1.0).cast::<T>());
            forward_kinematics(&robot, &mut data, &q, &v).unwrap();
            crba(&robot, &mut data);
            let factor = mass_matrix_cholesky(&data).unwrap();
            let rows_of_l = factor_rows(&factor);
            let mut tree = TreeFactorization::new(&robot);
            tree.factorize(&data.mass_matrix).unwrap();
            let tree_factor = PairFactor::Tree(&tree);
            cm.update(&data, &mut cd);
            for pair in 0..cm.pairs().len() {
                let proximity = cd.proximities[pair];
                if proximity.distance >= p.emit_distance() || proximity.direction.is_none() {
                    continue;
                }
                let reference = evaluate_pair(&cm, &cd, &robot, &data, &factor, &p, pair).unwrap();
                let fast =
                    pair_row(&cm, &cd, &robot, &data, &PairFactor::Rows(rows_of_l), &p, pair, &mut fresh_cache())
                        .unwrap();
                // Shared with another field (other force law and damping): the row from the
                // cache that field filled is the same row, to the bit.
                let mut shared = fresh_cache();
                pair_row(&cm, &cd, &robot, &data, &PairFactor::Rows(rows_of_l), &other_field, pair, &mut shared)
                    .unwrap();
                assert_eq!(
                    pair_row(&cm, &cd, &robot, &data, &PairFactor::Rows(rows_of_l), &p, pair, &mut shared).unwrap(),
                    fast
                );
                let difference = row_difference(&fast, &reference.row);
                assert!(
                    difference <= tolerance,
                    "seed {seed} pair {pair}: {difference:e}\n{fast:?}\n{:?}",
                    reference.row
                );
                // The tree-sparse factor (M = LᵀL, reflected masses over the support paths).
                let tree_row = pair_row(&cm, &cd, &robot, &data, &tree_factor, &p, pair, &mut fresh_cache()).unwrap();
                let difference = row_difference(&tree_row, &reference.row);
                assert!(difference <= tolerance, "tree, seed {seed} pair {pair}: {difference:e}");
                let [wi, wj] = inverse_reflected_masses(
                    &rows_of_l,
                    [&reference.jacobian_first.transpose().into(), &reference.jacobian_second.transpose().into()],
                )
                .unwrap();
                for (fast, reference) in [(wi, reference.inverse_masses.x), (wj, reference.inverse_masses.y)] {
                    let (f, r) = (
                        nalgebra::try_convert::<T, f64>(fast).unwrap(),
                        nalgebra::try_convert::<T, f64>(reference).unwrap(),
                    );
                    assert!((f - r).abs() <= tolerance * r.abs(), "seed {seed} pair {pair}: {f} vs {r}");
                }
                compared += 1;
                if reference.row.force != p.force(reference.distance) {
                    damped += 1;
                }
            }
        }
        assert!(compared > 500 && damped > 300, "{compared} rows, {damped} damped");
    }

    #[test]
    fn fast_rows_match_the_reference_f64() {
        fast_rows_match_reference::<f64>(1e-12);
    }

    #[test]
    fn fast_rows_match_the_reference_f32() {
        fast_rows_match_reference::<f32>(2e-4);
    }

    /// The rows of [`collision_rows_from_geometry`] are the reference rows of the selected
    /// pairs, in pair order.
    #[test]
    fn field_rows_are_the_reference_rows() {
        let robot = branched::<f64>();
        let cm = collision_model(&robot);
        let mut cd = CollisionData::new(&cm);
        let mut data = Data::new(&robot);
        let p = parameters::<f64>(0.9);
        let mut total = 0;
        for seed in 0..50 {
            forward_kinematics(&robot, &mut data, &state(seed, 1.5), &state(seed + 77, 1.0)).unwrap();
            crba(&robot, &mut data);
            let factor = mass_matrix_cholesky(&data).unwrap();
            let mut rows = TaskRows::<f64, N, P>::new();
            let report = self_collision_rows(&cm, &mut cd, &robot, &data, &factor, &p, &mut rows).unwrap();
            let expected: std::vec::Vec<TaskRow<f64, N>> = (0..cm.pairs().len())
                .filter(|&k| cd.proximities[k].distance < p.emit_distance() && cd.proximities[k].direction.is_some())
                .map(|k| evaluate_pair(&cm, &cd, &robot, &data, &factor, &p, k).unwrap().row)
                .collect();
            assert_eq!((report.rows, rows.len()), (expected.len(), expected.len()));
            for (fast, reference) in rows.rows().iter().zip(&expected) {
                assert!(row_difference(fast, reference) <= 1e-12, "seed {seed}: {fast:?} vs {reference:?}");
            }
            total += expected.len();
        }
        assert!(total > 100, "{total}");
    }

    /// Leading zeros of the right-hand sides are skipped; a zero pivot is an error.
    #[test]
    fn reflected_masses_of_sparse_rows_and_singular_factors() {
        let robot = branched::<f64>();
        let mut data = Data::new(&robot);
        forward_kinematics(&robot, &mut data, &state(9, 1.0), &SVector::zeros()).unwrap();
        crba(&robot, &mut data);
        let factor = mass_matrix_cholesky(&data).unwrap();
        let rows_of_l = factor_rows(&factor);
        let inverse = data.mass_matrix.try_inverse().unwrap();
        for start in 0..=N {
            let b = SVector::<f64, N>::from_fn(|i, _| if i < start { 0.0 } else { 0.3 + i as f64 });
            let [w] = inverse_reflected_masses(&rows_of_l, [&b.into()]).unwrap();
            let expected = (b.transpose() * inverse * b).x;
            assert!((w - expected).abs() <= 1e-12 * (1.0 + expected), "start {start}: {w} vs {expected}");
            let reference = inverse_reflected_mass(&factor, &b.transpose()).unwrap();
            assert!((w - reference).abs() <= 1e-14 * (1.0 + reference));
        }
        let mut singular = rows_of_l;
        singular[(2, 2)] = 0.0;
        let b = SVector::<f64, N>::repeat(1.0);
        assert_eq!(inverse_reflected_masses(&singular, [&b.into(), &b.into()]), Err(TaskError::Singular));
    }

    #[test]
    fn f32_rows_agree_with_f64() {
        let (r64, r32) = (branched::<f64>(), branched::<f32>());
        let (c64, c32) = (collision_model(&r64), collision_model(&r32));
        let (mut d64, mut d32) = (Data::new(&r64), Data::new(&r32));
        let (mut k64, mut k32) = (CollisionData::new(&c64), CollisionData::new(&c32));
        let (p64, p32) = (parameters::<f64>(0.7), parameters::<f32>(0.7));
        for seed in 0..20 {
            let (q, v) = (state(seed, 1.5), state(seed + 50, 1.0));
            forward_kinematics(&r64, &mut d64, &q, &v).unwrap();
            forward_kinematics(&r32, &mut d32, &q.cast(), &v.cast()).unwrap();
            crba(&r64, &mut d64);
            crba(&r32, &mut d32);
            let (f64_, f32_) = (mass_matrix_cholesky(&d64).unwrap(), mass_matrix_cholesky(&d32).unwrap());
            let (mut rows64, mut rows32) = (TaskRows::<f64, N, P>::new(), TaskRows::<f32, N, P>::new());
            self_collision_rows(&c64, &mut k64, &r64, &d64, &f64_, &p64, &mut rows64).unwrap();
            self_collision_rows(&c32, &mut k32, &r32, &d32, &f32_, &p32, &mut rows32).unwrap();
            if rows64.len() != rows32.len() {
                continue; // a pair at the emit distance
            }
            let (t64, t32) = (rows64.torque(), rows32.torque().cast::<f64>());
            assert!((t64 - t32).amax() <= 1e-3 * (1.0 + t64.amax()), "seed {seed}: {:?}", (t64 - t32).transpose());
        }
    }
}
