//! The fast collision rows of one cycle (Sec. 3.1.2–3.1.4): the pair kinematics of
//! [`super::kinematics`], the closed-form pair damping (3.23), rows shared between the fields
//! of a cycle ([`PairRowCache`]), and the selection of the closest candidates per field. The plain
//! per-pair evaluation they are tested against is [`super::evaluate_pair`].

use heapless::Vec;
use nalgebra::{convert, RealField};

use super::kinematics::{factor_rows, pair_kinematics, PairFactor, PairKinematics, PairScratch, SupportTable};
use super::parameters::CollisionParameters;
use super::selection::{heapify, sift};
use crate::dynamics::InertiaFactor;
use crate::math::sqrt;
use crate::model::{Data, Model};
use crate::tasks::collision::model::{CollisionData, CollisionModel};
use crate::tasks::collision::volumes::Proximity;
use crate::tasks::{RowSink, TaskError, TaskRow, TaskRows};

/// The configuration- and velocity-dependent part of the pair rows of one cycle, shared by the
/// collision fields that evaluate the same geometry (the strong and the weak field of Fig. 6.3):
/// per pair, the row Jacobian `eᵀ(J_{x,q,j} − J_{x,q,i})` (3.17)–(3.18), the sum of the
/// inverse reflected masses `m_i⁻¹ + m_j⁻¹` (3.20) and the distance rate `ḋ = j q̇`. A pair
/// whose row one field computed costs the next field a copy of its Jacobian and its force
/// law. Valid for one state `(q, q̇)` and inertia factor: [`Self::clear`] it when they change
/// (every cycle). Holds up to `C` pairs, each written in place when its row is computed; a pair
/// that does not fit is computed again, never dropped. Also holds the selection of the first
/// field that had to drop candidates (its last selected distance and pair), which decides every
/// later field's selection with as many free rows without a heap.
#[derive(Clone, Debug)]
pub struct PairRowCache<T: RealField, const N: usize, const P: usize, const C: usize> {
    /// Entry of each pair in `entries` (`u16::MAX`: none).
    slot: [u16; P],
    entries: Vec<CachedPairRow<T, N>, C>,
    pub(super) selection: Option<Selection<T>>,
}

/// A field's selection when it had more candidates than free rows: the `count` smallest
/// `(distance, pair index)` of its candidates (the pairs closer than its emit distance `a`
/// with a direction), the last of them `(distance, pair)`. Another field with the same
/// geometry, `count` free rows and emit distance `b` selects the candidates up to that pair,
/// `(d, k) ≤ (distance, pair)`: if `distance < b`, the selected pairs are candidates of that
/// field too and every other candidate of it comes after the last one (its distance is at
/// least `a`, or it was a candidate of the first field and not selected); otherwise each of
/// its candidates (`d < b ≤ distance < a`) was selected, there are at most `count` of them
/// and the field takes them all. In both cases that is the field's own selection.
#[derive(Clone, Copy, Debug)]
pub(super) struct Selection<T> {
    distance: T,
    pair: usize,
    pub(super) count: usize,
}

#[derive(Clone, Copy, Debug)]
struct CachedPairRow<T: RealField, const N: usize> {
    jacobian: [T; N],
    kinematics: PairKinematics<T>,
}

impl<T: RealField + Copy, const N: usize, const P: usize, const C: usize> Default for PairRowCache<T, N, P, C> {
    fn default() -> Self {
        Self { slot: [u16::MAX; P], entries: Vec::new(), selection: None }
    }
}

impl<T: RealField + Copy, const N: usize, const P: usize, const C: usize> PairRowCache<T, N, P, C> {
    /// Forgets every pair and the selection (a new state or inertia factor).
    pub fn clear(&mut self) {
        self.slot = [u16::MAX; P];
        self.entries.clear();
        self.selection = None;
    }

    fn get(&self, pair: usize) -> Option<&CachedPairRow<T, N>> {
        let k = usize::from(*self.slot.get(pair)?);
        self.entries.get(k)
    }

    /// Appends a zero entry, to be written in place and then [`Self::commit`]ted or
    /// [`Self::discard`]ed; `None` when the cache is full.
    fn vacant(&mut self) -> Option<&mut CachedPairRow<T, N>> {
        let zero = CachedPairRow { jacobian: [T::zero(); N], kinematics: PairKinematics::zero() };
        self.entries.push(zero).ok()?;
        self.entries.last_mut()
    }

    /// Makes the last entry (from [`Self::vacant`]) `pair`'s, with its scalars.
    fn commit(&mut self, pair: usize, kinematics: PairKinematics<T>) {
        let k = self.entries.len().wrapping_sub(1);
        let (Some(slot), Some(entry), Ok(k)) = (self.slot.get_mut(pair), self.entries.get_mut(k), u16::try_from(k))
        else {
            return;
        };
        entry.kinematics = kinematics;
        *slot = k;
    }

    /// Number of cached pairs.
    #[cfg(test)]
    pub(super) fn len(&self) -> usize {
        self.entries.len()
    }

    /// Removes the last entry (from [`Self::vacant`]): its evaluation failed.
    fn discard(&mut self) {
        self.entries.pop();
    }
}

/// Copies `source` into `target` in blocks of eight entries (block moves the compiler keeps
/// inline, instead of a call of `memcpy`).
#[inline(always)]
fn copy_row<T: Copy, const N: usize>(target: &mut [T; N], source: &[T; N]) {
    let (mut to, mut from) = (target.chunks_exact_mut(8), source.chunks_exact(8));
    for (t, s) in (&mut to).zip(&mut from) {
        if let (Ok(t), Ok(s)) = (<&mut [T; 8]>::try_from(t), <&[T; 8]>::try_from(s)) {
            *t = *s;
        }
    }
    for (t, s) in to.into_remainder().iter_mut().zip(from.remainder()) {
        *t = *s;
    }
}

/// The row of pair `pair` (as [`evaluate_pair`](super::evaluate_pair)`(..).row`, equal to rounding) written into
/// `row` (every entry: its previous contents do not matter, as [`RowSink::push_with_metric`]
/// allows), without the pair's intermediate results: the row Jacobian, the inverse reflected masses and
/// the distance rate from `cache`, or from [`pair_kinematics`] (then cached, the Jacobian
/// written into the cache's entry in the same pass), the force law (3.10) of `parameters` and
/// the damping constant of (3.23) in the closed form `c = 2 ξ √(k / (m_i⁻¹ + m_j⁻¹))` (see
/// [`pair_damping`](super::pair_damping)). `work` holds the support table and the buffers of
/// [`pair_kinematics`], built on the first pair not in the cache. The proximity must have a
/// direction. Returns the row's `j M⁻¹ jᵀ` over the factor when the kinematics gave it
/// ([`pair_kinematics`]). On error `row` and `work` are unspecified. The row's finiteness is
/// checked by the row list.
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
    work: &mut Option<(SupportTable<T, B>, PairScratch<T, N>)>,
    parameters: &CollisionParameters<T>,
    pair: usize,
    cache: &mut PairRowCache<T, N, P, C>,
    row: &mut TaskRow<T, N>,
) -> Result<Option<T>, TaskError> {
    let invalid = TaskError::InvalidParameter { name: "pair" };
    let proximity: &Proximity<T> = collision.proximities.get(pair).ok_or(invalid)?;
    let d = proximity.distance;
    let jacobian = <&mut [T; N]>::try_from(row.jacobian.as_mut_slice()).map_err(|_| invalid)?;
    let kinematics = match cache.get(pair) {
        Some(entry) => {
            copy_row(jacobian, &entry.jacobian);
            entry.kinematics
        }
        None => {
            let (table, scratch) = work.get_or_insert_with(|| (SupportTable::new(model), PairScratch::new()));
            // `pair_kinematics` accumulates the row over the pair's support paths only.
            jacobian.fill(T::zero());
            let entry = cache.vacant();
            let cached = entry.is_some();
            let kinematics = pair_kinematics(
                collision_model,
                proximity,
                model,
                table,
                data,
                factor,
                pair,
                scratch,
                jacobian,
                entry.map(|e| &mut e.jacobian),
            );
            match kinematics {
                Ok(kinematics) => {
                    if cached {
                        cache.commit(pair, kinematics);
                    }
                    kinematics
                }
                Err(e) => {
                    if cached {
                        cache.discard();
                    }
                    return Err(e);
                }
            }
        }
    };
    let inverse_mass_sum = kinematics.inverse_mass_sum;
    let stiffness = parameters.stiffness(d);
    let c = if stiffness > T::zero() && inverse_mass_sum > T::zero() {
        convert::<f64, T>(2.0) * parameters.damping_ratio() * sqrt(stiffness / inverse_mass_sum)
    } else {
        T::zero()
    };
    row.force = parameters.force(d) - c * kinematics.rate;
    row.potential = parameters.potential(d);
    row.activation = parameters.activation(d);
    Ok(kinematics.metric)
}

/// [`pair_row_into`] returning the row.
#[cfg(test)]
#[allow(clippy::too_many_arguments, reason = "the inputs of pair_row_into")]
pub(super) fn pair_row<
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
    let mut row = TaskRow {
        jacobian: nalgebra::RowSVector::zeros(),
        force: T::zero(),
        potential: T::zero(),
        activation: T::zero(),
    };
    pair_row_into(collision_model, collision, model, data, factor, &mut None, parameters, pair, cache, &mut row)?;
    Ok(row)
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
/// and appends one row per selected pair in pair order ([`evaluate_pair`](super::evaluate_pair)). Summed alone the
/// rows give τ_sca of (3.2)/(3.24): `rows.torque()`.
///
/// Preconditions: `forward_kinematics` at `(q, q̇)`, then `crba` and the inertia factor `mass`
/// ([`InertiaFactor`]: `mass_matrix_cholesky`'s dense factor, O(R·N²) for the reflected masses,
/// or a [`TreeFactorization`](crate::dynamics::TreeFactorization), O(R·Σ depth) over the support paths).
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
/// a pair another field of this cycle already evaluated costs a copy of its Jacobian and its
/// force law. `cache` must be cleared ([`PairRowCache::clear`]) whenever the state (the
/// geometry, the velocity `data.v`) or the inertia factor change; with a cleared cache the rows
/// are those of [`collision_rows_from_geometry`], and with a filled one they are equal to them
/// (the same arithmetic).
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
    rows: &mut impl RowSink<T, N, R>,
) -> Result<CollisionReport<T>, TaskError> {
    let free = R.saturating_sub(rows.len());
    let limit = parameters.emit_distance();
    let mut report = CollisionReport { candidates: 0, rows: 0, dropped: 0, undefined_direction: 0, min_distance: None };
    // Rows in pair order: a pass over a membership mask of the pairs instead of a sort, whose
    // ordering-violation panic path would survive in the image.
    let mut chosen = [false; P];
    let mut count = 0;
    // A field of this cycle that had to drop candidates selected the `free` smallest
    // `(distance, pair index)`; this field's selection is then its candidates up to that
    // field's last one (see `Selection`), without a heap.
    if let Some(shared) = cache.selection.filter(|s| s.count == free) {
        for (index, (proximity, flag)) in
            collision.proximities.iter().take(collision_model.pairs().len()).zip(chosen.iter_mut()).enumerate()
        {
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
            if d < shared.distance || (d == shared.distance && index <= shared.pair) {
                *flag = true;
                count += 1;
            }
        }
        report.dropped = report.candidates - report.undefined_direction - count;
    } else {
        // The `free` closest candidates `(distance, pair index)`: filled in pair order, then
        // kept as a binary max-heap by distance whose root (the farthest) a closer candidate
        // replaces, O(log R) per replacement.
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
            // `(d, index)` comes after every selected pair in pair order: it enters when it is
            // closer than the root.
            if selected.first().is_some_and(|root| d < root.0) {
                sift(&mut selected, 0, (d, index));
            }
        }
        count = selected.len();
        for &(_, index) in &selected {
            if let Some(flag) = chosen.get_mut(index) {
                *flag = true;
            }
        }
        // The heap holds the `free` smallest `(distance, pair index)`, the last one at its root.
        if let (true, Some(&(distance, pair))) = (heap, selected.first()) {
            cache.selection = Some(Selection { distance, pair, count: free });
        }
    }
    // Each row is built in its slot of `rows`; on an error the rows appended here are removed.
    if count > 0 {
        let factor = match mass.into() {
            InertiaFactor::Dense(cholesky) => PairFactor::Rows(factor_rows(cholesky)),
            InertiaFactor::Tree(tree) => PairFactor::Tree(tree),
        };
        let start = rows.len();
        // Built when the first pair that is not in the cache is evaluated.
        let mut work = None;
        for (index, _) in chosen.iter().enumerate().filter(|(_, &flag)| flag) {
            let mut result = Ok(());
            let pushed = rows.push_with_metric(|row| {
                let row = pair_row_into(
                    collision_model,
                    collision,
                    model,
                    data,
                    &factor,
                    &mut work,
                    parameters,
                    index,
                    cache,
                    row,
                );
                row.unwrap_or_else(|e| {
                    result = Err(e);
                    None
                })
            });
            if let Err(e) = result.and(pushed) {
                rows.truncate(start);
                return Err(e);
            }
        }
    }
    report.rows = count;
    Ok(report)
}
