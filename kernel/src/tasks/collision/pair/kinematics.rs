//! The configuration-dependent part of a collision pair's row (Sec. 3.1.2–3.1.3): the
//! support-path pair Jacobians (3.17)–(3.18) and both inverse reflected masses (3.20) over the
//! inertia factor (dense rows or the tree-sparse factor).

use nalgebra::{Cholesky, Const, RealField, RowSVector, SMatrix, Vector3};

use crate::dynamics::{DynamicsError, TreeFactorization};
use crate::model::{BodyId, Data, Model};
use crate::tasks::collision::model::{CollisionModel, CollisionPair};
use crate::tasks::collision::volumes::Proximity;
use crate::tasks::TaskError;

/// The inertia factor of the pair rows: the rows of a dense factor ([`factor_rows`]) or the
/// tree-sparse factor (reflected masses by [`TreeFactorization::inverse_reflected_mass`] over
/// the support path of each Jacobian).
pub(super) enum PairFactor<'a, T: RealField, const N: usize> {
    Rows(SMatrix<T, N, N>),
    Tree(&'a TreeFactorization<T, N>),
}

/// The rows of the Cholesky factor `L` of `M = L Lᵀ` as contiguous slices: `Lᵀ` in
/// column-major storage (column `i` holds row `i` of `L`; only its first `i + 1` entries, the
/// lower triangle, are written). Built once per [`collision_rows_from_geometry`](super::collision_rows_from_geometry) call for the
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
/// column-oriented [`inverse_reflected_mass`](super::inverse_reflected_mass) (the reference), starting at the first nonzero
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

/// The kinematic tree as the support-path walks of [`projected_jacobian_into`] read it: per
/// body its parent (`usize::MAX`: the world) and its joint's drive term when it has exactly
/// one (`coordinate = usize::MAX` otherwise: no term, or several, read from the model), and
/// the length of the head of a point Jacobian on the body (one past the largest coordinate of
/// any drive term on its support path: the entries a walk may write). Built once per
/// [`collision_rows_shared`](super::collision_rows_shared) call that evaluates a pair (a row
/// not in the cache), instead of reading the body descriptions in every walk.
pub(super) struct SupportTable<T, const B: usize> {
    parent: [usize; B],
    coordinate: [usize; B],
    coefficient: [T; B],
    head: [usize; B],
}

impl<T: RealField + Copy, const B: usize> SupportTable<T, B> {
    pub(super) fn new<const N: usize, const F: usize>(model: &Model<T, N, B, F>) -> Self {
        let mut table =
            Self { parent: [usize::MAX; B], coordinate: [usize::MAX; B], coefficient: [T::zero(); B], head: [0; B] };
        let bodies = model.bodies();
        let slots = table.parent.iter_mut().zip(table.coordinate.iter_mut()).zip(table.coefficient.iter_mut());
        for (body, ((parent, coordinate), coefficient)) in bodies.iter().zip(slots) {
            *parent = body.parent.map_or(usize::MAX, |p| p.0);
            if let [term] = body.drive.terms() {
                *coordinate = term.coordinate;
                *coefficient = term.coefficient;
            }
        }
        // One pass when parents precede their children (a parent's head is final), a walk to
        // the root otherwise.
        for i in 0..B {
            let (Some(body), Some(&parent)) = (bodies.get(i), table.parent.get(i)) else { break };
            let own = body.drive.terms().iter().fold(0, |h, t| h.max(t.coordinate + 1));
            let above = if parent < i {
                table.head.get(parent).copied().unwrap_or(0)
            } else {
                let mut next = body.parent.map(|p| p.0);
                let mut above = 0;
                for _ in 0..B {
                    let Some(ancestor) = next.and_then(|j| bodies.get(j)) else { break };
                    above = ancestor.drive.terms().iter().fold(above, |h, t| h.max(t.coordinate + 1));
                    next = ancestor.parent.map(|p| p.0);
                }
                above
            };
            if let Some(head) = table.head.get_mut(i) {
                *head = own.max(above);
            }
        }
        table
    }
}

/// Adds `eᵀ J_{x,q}` for the point `point` (world, m) on `body` to `row` (zero on entry): per
/// joint on the support path, `eᵀ (v_S + ω_S × x) = eᵀ v_S + ω_Sᵀ (x × e)` spread over the
/// joint's drive terms, (3.17)–(3.18), the path and single drive terms read from `table`. The
/// fast form of [`projected_jacobian`](super::projected_jacobian).
#[allow(clippy::too_many_arguments, reason = "the model, its table, the state and the point")]
fn projected_jacobian_into<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    table: &SupportTable<T, B>,
    data: &Data<T, N, B, F>,
    body: BodyId,
    point: &Vector3<T>,
    direction: &Vector3<T>,
    row: &mut [T; N],
) -> Result<(), TaskError> {
    let bodies = model.bodies();
    bodies.get(body.0).ok_or(DynamicsError::UnknownBody)?;
    let moment = point.cross(direction);
    let (e, m) = (direction, &moment);
    let mut next = body.0;
    for _ in 0..B {
        let (Some(&parent), Some(&coordinate), Some(&coefficient), Some(s)) = (
            table.parent.get(next),
            table.coordinate.get(next),
            table.coefficient.get(next),
            data.motion_subspaces.get(next),
        ) else {
            break;
        };
        let value = e.x * s.w + e.y * s.a + e.z * s.b + (m.x * s.x + m.y * s.y + m.z * s.z);
        if let Some(x) = row.get_mut(coordinate) {
            *x += value * coefficient;
        } else if let Some(joint) = bodies.get(next) {
            for term in joint.drive.terms() {
                if let Some(x) = row.get_mut(term.coordinate) {
                    *x += value * term.coefficient;
                }
            }
        }
        next = parent;
    }
    Ok(())
}

/// The scalars of a pair row's kinematics ([`pair_kinematics`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct PairKinematics<T> {
    /// `m_i⁻¹ + m_j⁻¹` (3.20), 1/kg.
    pub(super) inverse_mass_sum: T,
    /// `j M⁻¹ jᵀ` of the row `j = J_j − J_i` over the same factor (the metric of its norm ratio
    /// in the projection with the inverse-inertia weighting: the squared norm `σ₁²` of (4.70) in
    /// the `M⁻¹` metric); `None` on dense factor
    /// rows or when a support is not a chain of the tree factor.
    pub(super) metric: Option<T>,
}

/// The configuration-dependent part of pair `pair`'s row: the two projected Jacobians written in
/// place ([`projected_jacobian_into`]), their difference written into `jacobian`, and the sum of
/// both inverse reflected masses (3.20), returned: one forward substitution over the factor for
/// both ([`inverse_reflected_masses`] on dense rows) or one substitution along each support
/// path ([`TreeFactorization::substitute_head`] on the tree factor, the
/// head's length from `table`); none for a world-fixed volume, whose mass is infinite. On the
/// tree factor it also returns the row's `j M⁻¹ jᵀ = ‖x_j − x_i‖²` from the two substitutions'
/// solutions `x = J L⁻¹` (the two supports share only their common ancestors). The proximity
/// must have a direction.
#[allow(clippy::too_many_arguments, reason = "the pair, the model with its table, the state and the factor")]
pub(super) fn pair_kinematics<
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
    table: &SupportTable<T, B>,
    data: &Data<T, N, B, F>,
    factor: &PairFactor<'_, T, N>,
    pair: usize,
    jacobian: &mut RowSVector<T, N>,
) -> Result<PairKinematics<T>, TaskError> {
    let invalid = TaskError::InvalidParameter { name: "pair" };
    let &CollisionPair { first, second } = collision_model.pairs().get(pair).ok_or(invalid)?;
    let (Some(a), Some(b)) = (collision_model.volume(first), collision_model.volume(second)) else {
        return Err(invalid);
    };
    let e = proximity.direction.ok_or(TaskError::Singular)?.into_inner();
    let mut jacobian_first = [T::zero(); N];
    let mut jacobian_second = [T::zero(); N];
    if let Some(body) = a.body {
        projected_jacobian_into(model, table, data, body, &proximity.core_first, &e, &mut jacobian_first)?;
    }
    if let Some(body) = b.body {
        projected_jacobian_into(model, table, data, body, &proximity.core_second, &e, &mut jacobian_second)?;
    }
    let end = |body: Option<BodyId>| body.and_then(|b| table.head.get(b.0)).copied().unwrap_or(N);
    let head_first = jacobian_first.get(..end(a.body)).unwrap_or(&jacobian_first);
    let head_second = jacobian_second.get(..end(b.body)).unwrap_or(&jacobian_second);
    let (inverse_mass_sum, metric) = match (a.body.is_some(), b.body.is_some(), factor) {
        (true, true, PairFactor::Rows(rows)) => {
            let [wi, wj] = inverse_reflected_masses(rows, [&jacobian_first, &jacobian_second])?;
            (wi + wj, None)
        }
        (true, false, PairFactor::Rows(rows)) => (inverse_reflected_masses(rows, [&jacobian_first])?[0], None),
        (false, true, PairFactor::Rows(rows)) => (inverse_reflected_masses(rows, [&jacobian_second])?[0], None),
        (true, true, PairFactor::Tree(tree)) => {
            // `j = J_j − J_i` is linear in the substitution: `j M⁻¹ jᵀ = ‖x_i − x_j‖²`.
            let (mut difference, mut work) = ([T::zero(); N], [T::zero(); N]);
            let wi = tree.substitute_head(head_first, &mut work, |k, x| {
                if let Some(d) = difference.get_mut(k) {
                    *d = x;
                }
            });
            let wj = tree.substitute_head(head_second, &mut work, |k, x| {
                if let Some(d) = difference.get_mut(k) {
                    *d -= x;
                }
            });
            match (wi, wj) {
                (Some(wi), Some(wj)) => (wi + wj, Some(difference.iter().fold(T::zero(), |sum, &d| sum + d * d))),
                _ => (
                    tree.inverse_reflected_mass_of_head(head_first) + tree.inverse_reflected_mass_of_head(head_second),
                    None,
                ),
            }
        }
        // One body: `j = ∓J` and `j M⁻¹ jᵀ` is that body's inverse reflected mass.
        (true, false, PairFactor::Tree(tree)) => {
            let w = tree.inverse_reflected_mass_of_head(head_first);
            (w, Some(w))
        }
        (false, true, PairFactor::Tree(tree)) => {
            let w = tree.inverse_reflected_mass_of_head(head_second);
            (w, Some(w))
        }
        (false, false, PairFactor::Tree(_)) => (T::zero(), Some(T::zero())),
        (false, false, PairFactor::Rows(_)) => (T::zero(), None),
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
    Ok(PairKinematics { inverse_mass_sum, metric: metric.filter(|m| m.is_finite()) })
}
