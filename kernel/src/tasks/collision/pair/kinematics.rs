//! The configuration-dependent part of a collision pair's row (Sec. 3.1.2–3.1.3): the
//! support-path pair Jacobians (3.17)–(3.18) and both inverse reflected masses (3.20) over the
//! inertia factor (dense rows or the tree-sparse factor).

use nalgebra::{Cholesky, Const, RealField, SMatrix, Vector3};

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
/// body one [`Link`] (its parent and its joint's drive term when it has exactly one), and the
/// length of the head of a point Jacobian on the body (one past the largest coordinate of any
/// drive term on its support path: the entries a walk may write). Built once per
/// [`collision_rows_shared`](super::collision_rows_shared) call that evaluates a pair (a row
/// not in the cache), instead of reading the body descriptions in every walk.
pub(super) struct SupportTable<T, const B: usize> {
    links: [Link<T>; B],
    head: [usize; B],
}

/// One body of a [`SupportTable`]: its parent (`usize::MAX`: the world) and its joint's drive
/// term when it has exactly one (`coordinate = usize::MAX` otherwise: no term, or several,
/// read from the model). One record, so that a walk step reads it with one bounds check.
#[derive(Clone, Copy)]
struct Link<T> {
    parent: usize,
    coordinate: usize,
    coefficient: T,
}

impl<T: RealField + Copy, const B: usize> SupportTable<T, B> {
    pub(super) fn new<const N: usize, const F: usize>(model: &Model<T, N, B, F>) -> Self {
        let none = Link { parent: usize::MAX, coordinate: usize::MAX, coefficient: T::zero() };
        let mut table = Self { links: [none; B], head: [0; B] };
        let bodies = model.bodies();
        for (body, link) in bodies.iter().zip(table.links.iter_mut()) {
            link.parent = body.parent.map_or(usize::MAX, |p| p.0);
            if let [term] = body.drive.terms() {
                link.coordinate = term.coordinate;
                link.coefficient = term.coefficient;
            }
        }
        // One pass when parents precede their children (a parent's head is final), a walk to
        // the root otherwise.
        for i in 0..B {
            let (Some(body), Some(parent)) = (bodies.get(i), table.links.get(i).map(|l| l.parent)) else { break };
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
#[inline(always)]
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
        let (Some(link), Some(s)) = (table.links.get(next), data.motion_subspaces.get(next)) else {
            break;
        };
        let value = e.x * s.w + e.y * s.a + e.z * s.b + (m.x * s.x + m.y * s.y + m.z * s.z);
        if let Some(x) = row.get_mut(link.coordinate) {
            *x += value * link.coefficient;
        } else if let Some(joint) = bodies.get(next) {
            for term in joint.drive.terms() {
                if let Some(x) = row.get_mut(term.coordinate) {
                    *x += value * term.coefficient;
                }
            }
        }
        next = link.parent;
    }
    Ok(())
}

/// The configuration- and velocity-dependent scalars of a pair row ([`pair_kinematics`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct PairKinematics<T> {
    /// `m_i⁻¹ + m_j⁻¹` (3.20), 1/kg.
    pub(super) inverse_mass_sum: T,
    /// `j M⁻¹ jᵀ` of the row `j = J_j − J_i` over the same factor (the metric of its norm ratio
    /// in the projection with the inverse-inertia weighting: the squared norm `σ₁²` of (4.70) in
    /// the `M⁻¹` metric); `None` on dense factor
    /// rows or when a support is not a chain of the tree factor.
    pub(super) metric: Option<T>,
    /// The distance rate `ḋ = j q̇` at the velocity `data.v`.
    pub(super) rate: T,
}

impl<T: RealField + Copy> PairKinematics<T> {
    /// Zero masses, rate and metric (a placeholder of an unused cache entry).
    pub(super) fn zero() -> Self {
        Self { inverse_mass_sum: T::zero(), metric: None, rate: T::zero() }
    }
}

/// The buffers of [`pair_kinematics`], allocated once for all pairs of a call: `first` and
/// `difference` are zero between pairs (each pair resets what it wrote), `work` (the tree
/// substitution's buffer) and `spare` (the row's copy when the cache is full) are scratch.
/// After an error their content is unspecified: the buffers are dropped with the call.
pub(super) struct PairScratch<T, const N: usize> {
    /// `J_i` of the pair being evaluated.
    first: [T; N],
    /// `x_i − x_j` of the two tree substitutions.
    difference: [T; N],
    work: [T; N],
    spare: [T; N],
}

impl<T: RealField + Copy, const N: usize> PairScratch<T, N> {
    pub(super) fn new() -> Self {
        Self { first: [T::zero(); N], difference: [T::zero(); N], work: [T::zero(); N], spare: [T::zero(); N] }
    }
}

/// The configuration-dependent part of pair `pair`'s row: the two projected Jacobians
/// ([`projected_jacobian_into`]: `J_j` walked into `jacobian`, which must be zero on entry,
/// `J_i` into `scratch`), the row `j = J_j − J_i` written into `jacobian` and `copy` (the
/// cache's entry; `None`: a scratch buffer) in one pass that also forms the distance rate
/// `ḋ = j q̇` at `data.v`, and the sum of both inverse reflected masses (3.20): one forward
/// substitution over the factor for both ([`inverse_reflected_masses`] on dense rows) or one
/// substitution along each support path ([`TreeFactorization::substitute_head`] on the tree
/// factor, the head's length from `table`); none for a world-fixed volume, whose mass is
/// infinite. On the tree factor it also returns the row's `j M⁻¹ jᵀ = ‖x_j − x_i‖²` from the
/// two substitutions' solutions `x = J L⁻¹` (the two supports share only their common
/// ancestors). The proximity must have a direction.
///
/// The row's finiteness is left to the row list ([`crate::tasks::TaskRows::push_with_metric`]
/// rejects a non-finite row and ignores a non-finite metric); a non-finite mass sum, which
/// would only zero the damping, is an error here.
#[allow(clippy::too_many_arguments, reason = "the pair, the model with its table, the state, the factor, the outputs")]
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
    scratch: &mut PairScratch<T, N>,
    jacobian: &mut [T; N],
    copy: Option<&mut [T; N]>,
) -> Result<PairKinematics<T>, TaskError> {
    let invalid = TaskError::InvalidParameter { name: "pair" };
    let &CollisionPair { first, second } = collision_model.pairs().get(pair).ok_or(invalid)?;
    let (Some(a), Some(b)) = (collision_model.volume(first), collision_model.volume(second)) else {
        return Err(invalid);
    };
    let Some(direction) = proximity.direction.as_ref() else {
        return Err(TaskError::Singular);
    };
    let e: &Vector3<T> = direction;
    let PairScratch { first: jacobian_first, difference, work, spare } = scratch;
    if let Some(body) = a.body {
        projected_jacobian_into(model, table, data, body, &proximity.core_first, e, jacobian_first)?;
    }
    if let Some(body) = b.body {
        projected_jacobian_into(model, table, data, body, &proximity.core_second, e, jacobian)?;
    }
    let jacobian_second = &*jacobian;
    let end = |body: Option<BodyId>| body.and_then(|b| table.head.get(b.0)).copied().unwrap_or(N);
    let head_first = jacobian_first.get(..end(a.body)).unwrap_or(jacobian_first.as_slice());
    let head_second = jacobian_second.get(..end(b.body)).unwrap_or(jacobian_second.as_slice());
    let (inverse_mass_sum, metric) = match (a.body.is_some(), b.body.is_some(), factor) {
        (true, true, PairFactor::Rows(rows)) => {
            let [wi, wj] = inverse_reflected_masses(rows, [&*jacobian_first, jacobian_second])?;
            (wi + wj, None)
        }
        (true, false, PairFactor::Rows(rows)) => (inverse_reflected_masses(rows, [&*jacobian_first])?[0], None),
        (false, true, PairFactor::Rows(rows)) => (inverse_reflected_masses(rows, [jacobian_second])?[0], None),
        (true, true, PairFactor::Tree(tree)) => {
            // `j = J_j − J_i` is linear in the substitution: `j M⁻¹ jᵀ = ‖x_i − x_j‖²`.
            let wi = tree.substitute_head(head_first, work, |k, x| {
                if let Some(d) = difference.get_mut(k) {
                    *d = x;
                }
            });
            let wj = tree.substitute_head(head_second, work, |k, x| {
                if let Some(d) = difference.get_mut(k) {
                    *d -= x;
                }
            });
            // The squared norm, zeroing `difference` for the next pair.
            let norm = difference.iter_mut().fold(T::zero(), |sum, d| {
                let x = *d;
                *d = T::zero();
                sum + x * x
            });
            match (wi, wj) {
                (Some(wi), Some(wj)) => (wi + wj, Some(norm)),
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
    // The difference, its copy and the rate in one pass, zeroing `J_i` for the next pair.
    let copy = copy.unwrap_or(spare);
    let mut rate = T::zero();
    let outputs = jacobian.iter_mut().zip(copy.iter_mut());
    for (((x, c), ji), &v) in outputs.zip(jacobian_first.iter_mut()).zip(data.v.as_slice()) {
        let value = *x - *ji;
        *ji = T::zero();
        *x = value;
        *c = value;
        rate += value * v;
    }
    if !inverse_mass_sum.is_finite() {
        return Err(TaskError::NonFinite);
    }
    Ok(PairKinematics { inverse_mass_sum, metric, rate })
}
