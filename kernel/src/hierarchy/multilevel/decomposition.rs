//! The hierarchical dynamics representation (5.40)–(5.56): null space bases `Z_i`, their rates,
//! the dynamically consistent `J̄_i`, the block-diagonal `Λ` and the level velocities `v_i`.

use nalgebra::{RealField, RowSVector, SMatrix, SVector};

use super::compliance_stack::ComplianceStack;
use super::config::{DynamicsTerms, MultilevelConfig};
use super::error::MultilevelError;

/// One row of the extended Jacobian and of its inverse, with its rates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BasisRow<T, const N: usize> {
    /// Priority level the row belongs to (0 = highest).
    pub level: usize,
    /// Null space basis row `z` (1×N), a row of `Z_i` (5.51); `J̄⁻¹ = Zᵀ` (5.52).
    pub basis: RowSVector<T, N>,
    /// Its time derivative `ż` along the current `q̇` (1×N).
    pub basis_rate: RowSVector<T, N>,
    /// Row of the dynamically consistent Jacobian `J̄ = (z M zᵀ)⁻¹ z M` (5.44) (1×N).
    pub jacobian: RowSVector<T, N>,
    /// Its inertia `λ = z M zᵀ`, a diagonal entry of `Λ` (5.55)–(5.56).
    pub inertia: T,
    /// `λ̇ = d/dt (z M zᵀ)`, a diagonal entry of `Λ̇ = μ + μᵀ`.
    pub inertia_rate: T,
    /// Its velocity `v = J̄_row q̇` (5.40).
    pub velocity: T,
}

impl<T: RealField + Copy, const N: usize> BasisRow<T, N> {
    fn zero() -> Self {
        Self {
            level: 0,
            basis: RowSVector::zeros(),
            basis_rate: RowSVector::zeros(),
            jacobian: RowSVector::zeros(),
            inertia: T::zero(),
            inertia_rate: T::zero(),
            velocity: T::zero(),
        }
    }
}

/// The basis rows of one level: `rows()[start .. start + len]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LevelSpan {
    /// Index of the level's first basis row.
    pub start: usize,
    /// Number of basis rows: the level's rows `m_i` for `i < r`, the remaining null space
    /// dimension `N − Σ_{i<r} m_i` for the last level.
    pub len: usize,
}

/// Output of [`decompose`] for `N` coordinates and at most `L` levels.
#[derive(Clone, Debug, PartialEq)]
pub struct Decomposition<T, const N: usize, const L: usize> {
    rows: [BasisRow<T, N>; N],
    levels: [LevelSpan; L],
    level_count: usize,
}

impl<T: RealField + Copy, const N: usize, const L: usize> Default for Decomposition<T, N, L> {
    fn default() -> Self {
        Self { rows: [BasisRow::zero(); N], levels: [LevelSpan::default(); L], level_count: 0 }
    }
}

impl<T: RealField + Copy, const N: usize, const L: usize> Decomposition<T, N, L> {
    /// Number of levels `r` (0 for an empty stack, then there are no rows).
    pub fn level_count(&self) -> usize {
        self.level_count
    }

    /// The `N` basis rows, level by level (empty for an empty stack).
    pub fn rows(&self) -> &[BasisRow<T, N>] {
        if self.level_count == 0 {
            &[]
        } else {
            &self.rows
        }
    }

    /// The span of every level.
    pub fn levels(&self) -> &[LevelSpan] {
        self.levels.get(..self.level_count).unwrap_or(&[])
    }

    /// The basis rows of `level` (empty if there is no such level).
    pub fn level_rows(&self, level: usize) -> &[BasisRow<T, N>] {
        self.levels()
            .get(level)
            .and_then(|span| self.rows().get(span.start..span.start.saturating_add(span.len)))
            .unwrap_or(&[])
    }

    /// The stacked null space bases `Z = (Z₁; …; Z_r)` (N×N), so `J̄⁻¹ = Zᵀ` (5.52).
    pub fn basis(&self) -> SMatrix<T, N, N> {
        self.stack(|r| &r.basis)
    }

    /// `Ż` (N×N) along the current `q̇`.
    pub fn basis_rate(&self) -> SMatrix<T, N, N> {
        self.stack(|r| &r.basis_rate)
    }

    /// The extended Jacobian `J̄ = (J̄₁; …; J̄_r)` (N×N) of (5.41).
    pub fn extended_jacobian(&self) -> SMatrix<T, N, N> {
        self.stack(|r| &r.jacobian)
    }

    /// The diagonal of `Λ` (5.55), row by row.
    pub fn inertia(&self) -> SVector<T, N> {
        self.column(|r| r.inertia)
    }

    /// The diagonal of `Λ̇`, row by row.
    pub fn inertia_rate(&self) -> SVector<T, N> {
        self.column(|r| r.inertia_rate)
    }

    /// The velocities `v = J̄ q̇` (5.41).
    pub fn velocity(&self) -> SVector<T, N> {
        self.column(|r| r.velocity)
    }

    fn stack(&self, part: impl Fn(&BasisRow<T, N>) -> &RowSVector<T, N>) -> SMatrix<T, N, N> {
        let mut m = SMatrix::<T, N, N>::zeros();
        for (mut target, row) in m.row_iter_mut().zip(self.rows()) {
            target.copy_from(part(row));
        }
        m
    }

    fn column(&self, part: impl Fn(&BasisRow<T, N>) -> T) -> SVector<T, N> {
        let mut v = SVector::<T, N>::zeros();
        for (target, row) in v.iter_mut().zip(self.rows()) {
            *target = part(row);
        }
        v
    }
}

/// The tangent-propagating row recursion: the accumulated torque projector `N` and `Ṅ`.
struct RowRecursion<'a, T: RealField, const N: usize> {
    dynamics: &'a DynamicsTerms<'a, T, N>,
    mass_matrix_rate: SMatrix<T, N, N>,
    projector: SMatrix<T, N, N>,
    projector_rate: SMatrix<T, N, N>,
}

/// What one accepted row produced (see [`RowRecursion::append`]).
struct Appended<T, const N: usize> {
    row: BasisRow<T, N>,
    /// `w = M⁻¹ N jᵀ = zᵀ`, for the pivot update of the last level.
    w: SVector<T, N>,
}

impl<'a, T: RealField + Copy, const N: usize> RowRecursion<'a, T, N> {
    fn new(dynamics: &'a DynamicsTerms<'a, T, N>) -> Self {
        Self {
            dynamics,
            mass_matrix_rate: dynamics.mass_matrix_rate(),
            projector: SMatrix::identity(),
            projector_rate: SMatrix::zeros(),
        }
    }

    /// Processes the row `j` (as the column `jᵀ`) with rate `j̇ᵀ`; accepts it if `s = j M⁻¹ N jᵀ`
    /// exceeds `min_s`, then updates `N` and `Ṅ`. Cost O(N²): two Cholesky solves, four
    /// matrix-vector products, two rank-one updates.
    fn append(&mut self, j: &SVector<T, N>, j_rate: &SVector<T, N>, min_s: T, level: usize) -> Option<Appended<T, N>> {
        let factor = self.dynamics.mass_factor;
        let p = self.projector * j;
        let p_rate = self.projector_rate * j + self.projector * j_rate;
        let w = factor.solve(&p);
        let w_rate = factor.solve(&(p_rate - self.mass_matrix_rate * w));
        let s = p.dot(&w);
        if !(s.is_finite() && s > min_s && s > T::zero()) {
            return None;
        }
        let s_rate = p_rate.dot(&w) + p.dot(&w_rate);
        let inverse = T::one() / s;
        let jacobian = p.transpose() * inverse;
        let velocity = jacobian.dot(&self.dynamics.velocity.transpose());
        self.projector -= p * (w.transpose() * inverse);
        self.projector_rate -= (p_rate * w.transpose() + p * w_rate.transpose()) * inverse
            - p * (w.transpose() * (s_rate * inverse * inverse));
        let row = BasisRow {
            level,
            basis: w.transpose(),
            basis_rate: w_rate.transpose(),
            jacobian,
            inertia: s,
            inertia_rate: s_rate,
            velocity,
        };
        Some(Appended { row, w })
    }
}

/// Hierarchical dynamics representation of a compliance stack (Sec. 5.2.2): writes the basis
/// rows `z` (rows of `Z_i` (5.51), `J̄⁻¹ = Zᵀ` (5.52)), their rates `ż`, the rows of
/// `J̄_i = (Z_i M Z_iᵀ)⁻¹ Z_i M` (5.44), `Λ = diag(λ)` (5.55)–(5.56), `Λ̇` and `v = J̄ q̇`
/// (5.40) into `out`, level by level.
///
/// Rows of the levels `0 … r−2` are processed in stack order by the scalar-inverse recursion
/// (module docs); each gives one basis row. The last level `r−1` gets the remaining null
/// space, `N − Σ_{i<r−1} m_i` rows, spanned by pivoted coordinate axes. Within a level the basis
/// is M-orthogonal (an admissible choice of `Z_i`; all level quantities are invariant to it).
///
/// Inputs: the stack (only `jacobian` and `jacobian_rate` are used here), the controller's
/// model terms at `(q, q̇)`. Cost: O(m N²) for the `m` rows above the last level, O(N³) for the
/// last level (one Cholesky solve with `N` right-hand sides for the pivot choice). The only
/// inversions are of the scalars `s`.
///
/// Errors: [`MultilevelError::InvalidConfig`], [`MultilevelError::TooManyLevels`],
/// [`MultilevelError::NonFinite`], [`MultilevelError::TooManyConstraints`] (these before
/// anything is written), [`MultilevelError::Singular`] for a row with share
/// `ρ < singular_threshold`, [`MultilevelError::NullSpaceDeficient`]; after the last two, `out`
/// is reset to the empty decomposition.
///
/// ```
/// use kernel::hierarchy::multilevel::*;
/// use nalgebra::{Matrix2, RowVector2, Vector2};
/// // Two unit masses on orthogonal slides, M = diag(1, 4); one level-0 row on the sum x₁ + x₂,
/// // the last level (index 1) gets the remaining one-dimensional null space.
/// let m = Matrix2::new(1.0, 0.0, 0.0, 4.0);
/// let factor = m.cholesky().unwrap();
/// let (c, g, qd) = (Matrix2::zeros(), Vector2::zeros(), Vector2::new(0.3, -0.1));
/// let dynamics = DynamicsTerms { mass_matrix: &m, mass_factor: &factor, coriolis: &c, gravity: &g, velocity: &qd };
/// let mut stack = ComplianceStack::<f64, 2, 4>::new();
/// let row = |j: RowVector2<f64>| ComplianceRow { jacobian: j, jacobian_rate: RowVector2::zeros(),
///     stiffness_force: 0.0, damping_force: 0.0, potential: 0.0 };
/// stack.push(0, row(RowVector2::new(1.0, 1.0))).unwrap();
/// stack.push(1, row(RowVector2::new(1.0, 0.0))).unwrap();
/// let mut out = Decomposition::<f64, 2, 2>::default();
/// decompose(&MultilevelConfig::default(), &stack, &dynamics, &mut out).unwrap();
/// // Level 0: z = j M⁻¹ = (1, 0.25) (5.51), λ = z M zᵀ = 1.25 (5.56).
/// assert!((out.rows()[0].inertia - 1.25).abs() < 1e-12);
/// // J̄ Zᵀ = I: the extended Jacobian's inverse is Zᵀ (5.52).
/// assert!((out.extended_jacobian() * out.basis().transpose() - Matrix2::identity()).amax() < 1e-12);
/// ```
pub fn decompose<'d, T: RealField + Copy, const N: usize, const R: usize, const L: usize>(
    config: &MultilevelConfig<T>,
    stack: &ComplianceStack<T, N, R>,
    dynamics: &DynamicsTerms<'_, T, N>,
    out: &'d mut Decomposition<T, N, L>,
) -> Result<&'d Decomposition<T, N, L>, MultilevelError> {
    config.validate()?;
    let level_count = stack.level_count();
    if level_count > L {
        return Err(MultilevelError::TooManyLevels { capacity: L });
    }
    if !(dynamics.is_finite() && stack.rows().iter().all(|(_, row)| row.is_finite())) {
        return Err(MultilevelError::NonFinite);
    }
    let last = level_count.saturating_sub(1);
    let constrained = stack.rows().iter().filter(|(level, _)| *level < last).count();
    if constrained > N {
        return Err(MultilevelError::TooManyConstraints { rows: constrained });
    }
    let result = fill(config, stack, dynamics, out, level_count);
    if result.is_err() {
        *out = Decomposition::default();
    }
    result.map(|()| &*out)
}

fn fill<T: RealField + Copy, const N: usize, const R: usize, const L: usize>(
    config: &MultilevelConfig<T>,
    stack: &ComplianceStack<T, N, R>,
    dynamics: &DynamicsTerms<'_, T, N>,
    out: &mut Decomposition<T, N, L>,
    level_count: usize,
) -> Result<(), MultilevelError> {
    out.level_count = 0;
    if level_count == 0 {
        return Ok(());
    }
    let threshold_squared = config.singular_threshold * config.singular_threshold;
    let last = level_count - 1;
    let mut recursion = RowRecursion::new(dynamics);
    let mut count = 0;
    for (level, span) in out.levels.iter_mut().enumerate().take(last) {
        span.start = count;
        for row in stack.level(level) {
            let j = row.jacobian.transpose();
            let reference = j.dot(&dynamics.mass_factor.solve(&j));
            if !(reference.is_finite() && reference > T::zero()) {
                return Err(MultilevelError::Singular { level });
            }
            let appended = recursion
                .append(&j, &row.jacobian_rate.transpose(), threshold_squared * reference, level)
                .ok_or(MultilevelError::Singular { level })?;
            let slot = out.rows.get_mut(count).ok_or(MultilevelError::TooManyConstraints { rows: count + 1 })?;
            *slot = appended.row;
            count += 1;
        }
        span.len = count - span.start;
    }
    let span = out.levels.get_mut(last).ok_or(MultilevelError::TooManyLevels { capacity: L })?;
    *span = LevelSpan { start: count, len: N - count };
    null_space_rows(&mut recursion, &mut out.rows, count, last, threshold_squared)?;
    out.level_count = level_count;
    Ok(())
}

/// Fills `rows[count..]` with the remaining null space `Z_r = Y_{r−1}` (5.51): pivoted axes
/// `e_k` through the recursion, largest free share `ρ_k² = (M⁻¹N)_kk / (M⁻¹)_kk` first.
fn null_space_rows<T: RealField + Copy, const N: usize>(
    recursion: &mut RowRecursion<'_, T, N>,
    rows: &mut [BasisRow<T, N>; N],
    count: usize,
    level: usize,
    threshold_squared: T,
) -> Result<(), MultilevelError> {
    if count >= N {
        return Ok(());
    }
    // P = M⁻¹ N (symmetric); (M⁻¹)_kk = P_kk + Σ_rows z_k² / λ because M⁻¹ = P + Σ zᵀz/λ.
    let mut free = recursion.dynamics.mass_factor.solve(&recursion.projector);
    let mut reference: SVector<T, N> = free.diagonal();
    for row in rows.iter().take(count) {
        reference += row.basis.transpose().map(|z| z * z / row.inertia);
    }
    for slot in rows.iter_mut().skip(count) {
        let (axis, share) = free
            .diagonal()
            .iter()
            .zip(reference.iter())
            .map(|(p, r)| if *r > T::zero() { *p / *r } else { T::zero() })
            .enumerate()
            .fold((0, T::zero()), |best, (k, share)| if share > best.1 { (k, share) } else { best });
        if share < threshold_squared || !share.is_finite() {
            return Err(MultilevelError::NullSpaceDeficient);
        }
        let e = SVector::<T, N>::from_fn(|r, _| if r == axis { T::one() } else { T::zero() });
        let min_s = threshold_squared * reference.get(axis).copied().unwrap_or_else(T::zero);
        let appended =
            recursion.append(&e, &SVector::zeros(), min_s, level).ok_or(MultilevelError::NullSpaceDeficient)?;
        free -= appended.w * (appended.w.transpose() / appended.row.inertia);
        *slot = appended.row;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::super::test_support::*;
    use super::*;
    use crate::hierarchy::{
        project, HierarchyConfig, HierarchyData, Recursion as ProjectionKind, Shaping, Stack, Weighting,
    };
    use crate::tasks::TaskRow;
    use crate::test_models::N;
    use nalgebra::DMatrix;

    #[test]
    fn extended_jacobian_is_inverted_by_the_stacked_bases_and_lambda_is_block_diagonal() {
        for seed in 0..40 {
            let fixture = Fixture::new(seed, &[3, 2]);
            let out = fixture.decompose().unwrap();
            let (jbar, z) = (out.extended_jacobian(), out.basis());
            assert!((jbar * z.transpose() - SMatrix::<f64, N, N>::identity()).amax() < 1e-9, "seed {seed}");
            assert!((z.transpose() * jbar - SMatrix::<f64, N, N>::identity()).amax() < 1e-9, "seed {seed}");
            let lambda = z * fixture.mass * z.transpose();
            let scale = lambda.amax();
            assert!((lambda - SMatrix::from_diagonal(&out.inertia())).amax() < 1e-9 * scale, "seed {seed}");
            assert_eq!(
                out.levels(),
                &[LevelSpan { start: 0, len: 3 }, LevelSpan { start: 3, len: 2 }, LevelSpan { start: 5, len: 1 }]
            );
        }
    }

    /// (5.49) `J^aug_{i−1} Z_iᵀ = 0` and (5.50) `J̄_iᵀ Z_i J_iᵀ = N_i J_iᵀ` with `N_i` from the
    /// projector recursion of Chapter 4 (augmented, `W = M`).
    #[test]
    fn projected_torque_map_equals_the_dynamically_consistent_projector() {
        for seed in 0..40 {
            let fixture = Fixture::new(seed, &[3, 2]);
            let out = fixture.decompose().unwrap();
            for level in 0..3 {
                let mut above = Stack::<f64, N, 16>::new();
                for (l, row) in fixture.stack.rows().iter().filter(|(l, _)| *l < level) {
                    above
                        .push(*l, TaskRow { jacobian: row.jacobian, force: 0.0, potential: 0.0, activation: 1.0 })
                        .unwrap();
                }
                let config = HierarchyConfig {
                    recursion: ProjectionKind::Augmented,
                    weighting: Weighting::Inertia(&fixture.factor),
                    shaping: Shaping::Continuous { singular_full: 1e-6, singular_start: 2e-6 },
                    diagnose_last_level: true,
                };
                let mut data = HierarchyData::<f64, N, 16, 4>::default();
                project(&config, &above, &mut data).unwrap();
                let n_i = data.projector;
                let rows = out.level_rows(level);
                let map: SMatrix<f64, N, N> = rows.iter().map(|r| r.jacobian.transpose() * r.basis).sum();
                for (_, row) in fixture.stack.rows().iter().filter(|(l, _)| *l == level) {
                    let jt = row.jacobian.transpose();
                    assert!((map * jt - n_i * jt).amax() < 1e-9 * (1.0 + jt.amax()), "seed {seed} level {level}");
                }
                for (_, row) in fixture.stack.rows().iter().filter(|(l, _)| *l < level) {
                    for r in rows {
                        assert!(row.jacobian.dot(&r.basis).abs() < 1e-10, "(5.49) seed {seed} level {level}");
                    }
                }
            }
        }
    }

    /// The M-orthogonal basis spans the thesis' `Z_i = J_i M⁻¹ N_i` (5.51): its level map
    /// `J̄_iᵀ Z_i` equals the one built from the thesis basis with the dense inverse (5.44).
    #[test]
    fn level_quantities_equal_those_of_the_thesis_basis() {
        for seed in 0..20 {
            let fixture = Fixture::new(seed, &[3, 2]);
            let out = fixture.decompose().unwrap();
            let m = DMatrix::from_fn(N, N, |r, c| fixture.mass[(r, c)]);
            let m_inv = m.clone().try_inverse().unwrap();
            let mut n = DMatrix::<f64>::identity(N, N);
            for level in 0..2 {
                let j = DMatrix::from_fn(fixture.rows_on(level).len(), N, |r, c| fixture.rows_on(level)[r].jacobian[c]);
                let z = if level == 0 {
                    (&j * &m_inv * j.transpose()).try_inverse().unwrap() * &j * &m_inv
                } else {
                    &j * &m_inv * &n
                };
                let jbar = (&z * &m * z.transpose()).try_inverse().unwrap() * &z * &m;
                let thesis_map = jbar.transpose() * &z;
                let ours: SMatrix<f64, N, N> =
                    out.level_rows(level).iter().map(|r| r.jacobian.transpose() * r.basis).sum();
                let diff = (DMatrix::from_fn(N, N, |r, c| ours[(r, c)]) - &thesis_map).amax();
                assert!(diff < 1e-9, "seed {seed} level {level}: {diff}");
                // Kinetic energy of the level: ½ v_iᵀ Λ_i v_i with v_i = J̄_i q̇.
                let qd = DMatrix::from_fn(N, 1, |r, _| fixture.velocity[r]);
                let v = &jbar * &qd;
                let thesis_kinetic = 0.5 * (v.transpose() * (&z * &m * z.transpose()) * &v)[(0, 0)];
                let kinetic: f64 =
                    out.level_rows(level).iter().map(|r| 0.5 * r.inertia * r.velocity * r.velocity).sum();
                assert!((kinetic - thesis_kinetic).abs() < 1e-9 * (1.0 + thesis_kinetic), "seed {seed} level {level}");
                n = &n - j.transpose() * (&j * &m_inv * &n * j.transpose()).try_inverse().unwrap() * &j * &m_inv * &n;
            }
        }
    }

    /// `Ż` of the forward-mode recursion against a central difference along the motion,
    /// `(Z(q + h q̇) − Z(q − h q̇)) / 2h` (rows of the task levels; the last level's basis is
    /// compared through its invariant map `J̄_rᵀ Z_r`).
    #[test]
    fn basis_rate_matches_a_central_difference_along_the_motion() {
        let mut worst = 0.0_f64;
        for seed in 0..30 {
            let fixture = Fixture::new(seed, &[3, 2]);
            let out = fixture.decompose().unwrap();
            let h = 1e-6;
            let plus = Fixture::at(&(fixture.q + fixture.velocity * h), &fixture.velocity, &[3, 2]);
            let minus = Fixture::at(&(fixture.q - fixture.velocity * h), &fixture.velocity, &[3, 2]);
            let (zp, zm) = (plus.decompose().unwrap().basis(), minus.decompose().unwrap().basis());
            let rate = out.basis_rate();
            for k in 0..5 {
                let fd = (zp.row(k) - zm.row(k)) / (2.0 * h);
                let error = (fd - rate.row(k)).amax() / (1.0 + rate.row(k).amax());
                worst = worst.max(error);
            }
            let fd_lambda = (plus.decompose().unwrap().inertia() - minus.decompose().unwrap().inertia()) / (2.0 * h);
            let scale = 1.0 + out.inertia_rate().amax();
            assert!((fd_lambda.rows(0, 5) - out.inertia_rate().rows(0, 5)).amax() < 1e-5 * scale, "seed {seed}");
        }
        assert!(worst < 1e-5, "relative Ż error {worst}");
    }

    #[test]
    fn dependent_rows_and_bad_input_are_errors() {
        let fixture = Fixture::new(3, &[3, 2]);
        let mut stack = fixture.stack.clone();
        let duplicate = stack.rows()[0].1;
        stack.push(1, duplicate).unwrap();
        let mut out = Decomposition::<f64, N, 4>::default();
        assert_eq!(
            decompose(&MultilevelConfig::default(), &stack, &fixture.terms(), &mut out),
            Err(MultilevelError::Singular { level: 1 })
        );
        assert_eq!(out.level_count(), 0);
        let mut crowded = fixture.stack.clone();
        crowded.push(1, duplicate).unwrap();
        crowded.push(1, duplicate).unwrap();
        assert_eq!(
            decompose(&MultilevelConfig::default(), &crowded, &fixture.terms(), &mut out),
            Err(MultilevelError::TooManyConstraints { rows: 7 })
        );
        let bad = MultilevelConfig { singular_threshold: 1.5, ..MultilevelConfig::default() };
        assert_eq!(decompose(&bad, &fixture.stack, &fixture.terms(), &mut out), Err(MultilevelError::InvalidConfig));
        let mut small = Decomposition::<f64, N, 2>::default();
        assert_eq!(
            decompose(&MultilevelConfig::default(), &fixture.stack, &fixture.terms(), &mut small),
            Err(MultilevelError::TooManyLevels { capacity: 2 })
        );
        let nan = SVector::<f64, N>::repeat(f64::NAN);
        let terms = DynamicsTerms { velocity: &nan, ..fixture.terms() };
        assert_eq!(
            decompose(&MultilevelConfig::default(), &fixture.stack, &terms, &mut out),
            Err(MultilevelError::NonFinite)
        );
    }

    #[test]
    fn single_level_spans_everything_and_empty_stack_is_empty() {
        let fixture = Fixture::new(5, &[]);
        let out = fixture.decompose().unwrap();
        assert_eq!(out.levels(), &[LevelSpan { start: 0, len: N }]);
        let z = out.basis();
        let lambda = z * fixture.mass * z.transpose();
        assert!((lambda - SMatrix::from_diagonal(&out.inertia())).amax() < 1e-9);
        let mut empty = Decomposition::<f64, N, 4>::default();
        decompose(&MultilevelConfig::default(), &ComplianceStack::<f64, N, 4>::new(), &fixture.terms(), &mut empty)
            .unwrap();
        assert_eq!((empty.level_count(), empty.rows().len()), (0, 0));
    }

    #[test]
    fn f32_agrees_with_f64() {
        let fixture = Fixture::new(11, &[3, 2]);
        let out = fixture.decompose().unwrap();
        let f32_fixture = fixture.cast_f32();
        let terms = f32_fixture.terms();
        let mut out32 = Decomposition::<f32, N, 4>::default();
        decompose(&MultilevelConfig::default(), &f32_fixture.stack, &terms, &mut out32).unwrap();
        let map = |rows: &[BasisRow<f64, N>]| -> SMatrix<f64, N, N> {
            rows.iter().map(|r| r.jacobian.transpose() * r.basis).sum()
        };
        for level in 0..3 {
            let rows32: std::vec::Vec<BasisRow<f64, N>> = out32
                .level_rows(level)
                .iter()
                .map(|r| BasisRow {
                    level,
                    basis: r.basis.cast(),
                    basis_rate: r.basis_rate.cast(),
                    jacobian: r.jacobian.cast(),
                    inertia: r.inertia.into(),
                    inertia_rate: r.inertia_rate.into(),
                    velocity: r.velocity.into(),
                })
                .collect();
            let error = (map(&rows32) - map(out.level_rows(level))).amax();
            assert!(error < 2e-3, "level {level}: {error}");
        }
    }
}
