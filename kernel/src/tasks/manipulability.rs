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
//! `∂m/∂q_k = m tr((J Jᵀ)⁻¹ (∂J/∂q_k) Jᵀ)`, with `∂J/∂q_k` from
//! [`crate::dynamics::frame_jacobian_derivative`] (no finite differences). It covers every
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

use nalgebra::{RealField, RowSVector, SMatrix, SVector, Vector6};

use super::cartesian_impedance::AxisMask;
use super::{TaskError, TaskRow, TaskRows};
use crate::dynamics::{frame_jacobian, frame_jacobian_derivative};
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
/// With `J̃` the selected Jacobian padded with zeros (6×N) and `A = J̃ J̃ᵀ + (I − S)` (identity
/// on unselected rows, so `det A = det(J Jᵀ)`), `A = L Lᵀ` gives `m = Π L_ii` and, with
/// `W = A⁻¹ J̃`, `∂m/∂q_k = m ⟨∂J̃/∂q_k, W⟩_F` (the trace form of the module docs; `W`
/// vanishes outside the selection, so the full `∂J/∂q_k` can be used).
///
/// Precondition: [`crate::dynamics::forward_kinematics`] at `q`. Cost O(N·(depth + N)).
/// Errors: [`TaskError::Dynamics`] for an unknown frame.
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
    let mut jacobian = SMatrix::<T, 6, N>::zeros();
    frame_jacobian(model, data, frame, &mut jacobian)?;
    let row_mask = Vector6::from_fn(|i, _| if rows.contains(i) { T::one() } else { T::zero() });
    let column_mask =
        SVector::<T, N>::from_fn(
            |k, _| {
                if coordinates.get(k).copied().unwrap_or(false) {
                    T::one()
                } else {
                    T::zero()
                }
            },
        );
    let selected = SMatrix::from_diagonal(&row_mask) * jacobian * SMatrix::from_diagonal(&column_mask);
    let padded = selected * selected.transpose() + SMatrix::from_diagonal(&row_mask.map(|r| T::one() - r));
    let singular = ManipulabilityMeasure { value: T::zero(), gradient: RowSVector::zeros(), singular: true };
    let Some(factor) = nalgebra::Cholesky::new(padded) else {
        return Ok(singular);
    };
    // A pivot at rounding level means a rank-deficient J (e.g. more rows than joints on the
    // frame's path): treat it as singular rather than differentiate rounding noise.
    let pivots = factor.l_dirty().diagonal();
    let floor = nalgebra::convert::<f64, T>(100.0) * T::default_epsilon() * padded.diagonal().amax();
    if pivots.iter().any(|l| *l * *l <= floor) {
        return Ok(singular);
    }
    let value = pivots.iter().fold(T::one(), |m, l| m * *l);
    let weights = factor.solve(&selected);
    let mut derivative = SMatrix::<T, 6, N>::zeros();
    let mut gradient = RowSVector::<T, N>::zeros();
    for (k, entry) in gradient.iter_mut().enumerate() {
        let direction = SVector::<T, N>::from_fn(|r, _| if r == k { T::one() } else { T::zero() });
        frame_jacobian_derivative(model, data, frame, &direction, &mut derivative)?;
        *entry = value * derivative.dot(&weights);
    }
    if !(value.is_finite() && crate::math::all_finite(&gradient)) {
        return Ok(singular);
    }
    Ok(ManipulabilityMeasure { value, gradient, singular: false })
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
/// Cost O(N·(depth + N)). Errors (the row list is unchanged): [`TaskError::Dynamics`] for an
/// unknown frame, [`TaskError::NonFinite`], [`TaskError::Capacity`].
pub fn manipulability_avoidance<T: RealField + Copy, const N: usize, const B: usize, const F: usize, const R: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    task: &Manipulability<T, N>,
    rows: &mut TaskRows<T, N, R>,
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
    rows.push(TaskRow {
        jacobian: measure.gradient,
        force: -two * c.stiffness * deficit - activation * c.damping * rate,
        potential: c.stiffness * deficit * deficit,
        activation,
    })?;
    Ok(ManipulabilityReport { manipulability: measure.value, singular: measure.singular })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::dynamics::forward_kinematics;
    use crate::test_models::{branched, state, Branched, N, TCP, WRIST};

    fn c<T: RealField + Copy>(x: f64) -> T {
        nalgebra::convert(x)
    }

    /// Selections of the branched model: (frame, rows, coordinates). TCP and WRIST have 4
    /// driving coordinates each; the last case leaves a path coordinate out of the columns.
    fn selections() -> [(FrameId, AxisMask, [bool; N]); 4] {
        [
            (TCP, AxisMask::TRANSLATION, [true, true, true, true, false, false]),
            (TCP, AxisMask::new([true, false, true, false, true, true]), [true; N]),
            (WRIST, AxisMask::new([true, true, false, true, false, false]), [true, true, false, false, true, true]),
            (WRIST, AxisMask::new([false, true, true, false, false, false]), [false, true, false, false, true, false]),
        ]
    }

    fn measure<T: RealField + Copy>(
        model: &Branched<T>,
        q: &SVector<T, N>,
        s: &(FrameId, AxisMask, [bool; N]),
    ) -> ManipulabilityMeasure<T, N> {
        let mut data = Data::new(model);
        forward_kinematics(model, &mut data, q, &SVector::zeros()).unwrap();
        manipulability(model, &data, s.0, s.1, &s.2).unwrap()
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let model = branched::<f64>();
        let mut worst = 0.0_f64;
        for seed in 0..40 {
            let q = state(seed, 2.0);
            for s in selections() {
                let m = measure(&model, &q, &s);
                assert!(!m.singular);
                let h = 1e-6;
                let fd = RowSVector::<f64, N>::from_fn(|_, k| {
                    let e = SVector::<f64, N>::from_fn(|r, _| if r == k { h } else { 0.0 });
                    (measure(&model, &(q + e), &s).value - measure(&model, &(q - e), &s).value) / (2.0 * h)
                });
                let err = (fd - m.gradient).amax();
                worst = worst.max(err / (m.gradient.amax() + 1e-3));
                assert!(err < 1e-6 * (m.gradient.amax() + 1e-3), "seed {seed}: {err}");
            }
        }
        eprintln!("manipulability gradient worst relative error {worst:e}");
    }

    #[test]
    fn manipulability_is_the_product_of_singular_values() {
        let model = branched::<f64>();
        let q = state(3, 2.0);
        let s = selections()[1];
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
        let mut j = SMatrix::<f64, 6, N>::zeros();
        frame_jacobian(&model, &data, s.0, &mut j).unwrap();
        // Rows (x, z, ωy, ωz), all columns.
        let selected = SMatrix::<f64, 4, N>::from_fn(|r, k| j[([0, 2, 4, 5][r], k)]);
        assert!(s.1 == AxisMask::new([true, false, true, false, true, true]) && s.2 == [true; N]);
        let product: f64 = selected.singular_values().iter().product();
        assert!((measure(&model, &q, &s).value - product).abs() < 1e-12);
    }

    fn task<T: RealField + Copy>(
        s: &(FrameId, AxisMask, [bool; N]),
        threshold: f64,
        damping: f64,
    ) -> Manipulability<T, N> {
        Manipulability::try_new(ManipulabilityConfig {
            frame: s.0,
            rows: s.1,
            coordinates: s.2,
            threshold: c(threshold),
            full_activation: c(0.5 * threshold),
            stiffness: c(200.0),
            damping: c(damping),
        })
        .unwrap()
    }

    fn row<T: RealField + Copy>(
        model: &Branched<T>,
        task: &Manipulability<T, N>,
        q: &SVector<T, N>,
        v: &SVector<T, N>,
    ) -> TaskRow<T, N> {
        let mut data = Data::new(model);
        forward_kinematics(model, &mut data, q, v).unwrap();
        let mut rows = TaskRows::<T, N, 1>::new();
        manipulability_avoidance(model, &data, task, &mut rows).unwrap();
        rows.rows()[0]
    }

    /// jᵀ f (v = 0) against central differences of V, with the potential active (large
    /// threshold) and with thresholds around the current value (both sides).
    fn gradient_check<T: RealField + Copy>(h: f64, tolerance: f64, thresholds: &[fn(f64) -> f64]) -> f64 {
        let model = branched::<T>();
        let mut worst = 0.0_f64;
        for seed in 0..30 {
            let q: SVector<T, N> = state(seed, 2.0).cast();
            for s in selections() {
                let m: f64 = nalgebra::try_convert(measure(&model, &q, &s).value).unwrap();
                for threshold in thresholds {
                    let task = task::<T>(&s, threshold(m), 5.0);
                    let r = row(&model, &task, &q, &SVector::zeros());
                    let tau = r.jacobian.transpose() * r.force;
                    let hh: T = c(h);
                    let fd = SVector::<T, N>::from_fn(|k, _| {
                        let e = SVector::<T, N>::from_fn(|i, _| if i == k { hh } else { T::zero() });
                        let plus = row(&model, &task, &(q + e), &SVector::zeros()).potential;
                        (plus - row(&model, &task, &(q - e), &SVector::zeros()).potential) / (hh + hh)
                    });
                    let err: f64 = nalgebra::try_convert((tau + fd).amax()).unwrap();
                    let scale: f64 = nalgebra::try_convert(tau.amax()).unwrap();
                    worst = worst.max(err / (scale + 1e-3));
                    assert!(err <= tolerance * (scale + 1e-3), "seed {seed}: {err} vs {scale}");
                }
            }
        }
        worst
    }

    #[test]
    fn force_is_the_negative_gradient_f64() {
        let worst = gradient_check::<f64>(1e-6, 1e-6, &[|m| 4.0 * m + 0.1, |m| 1.05 * m + 1e-3, |m| 0.9 * m + 1e-3]);
        eprintln!("manipulability f64 worst relative gradient error {worst:e}");
    }

    #[test]
    fn force_is_the_negative_gradient_f32() {
        // f32: h = 3e-3, rounding ≈ ε·V/h; stated tolerance 5e-3 of the torque scale. Only
        // thresholds the differences cannot cross (V is C¹, not C², at m_kin,0).
        let worst = gradient_check::<f32>(3e-3, 5e-3, &[|m| 4.0 * m + 0.1, |m| 0.5 * m]);
        eprintln!("manipulability f32 worst relative gradient error {worst:e}");
    }

    /// (3.56) is C¹ at m = m_kin,0: crossing the threshold along −∇m, V and ∇V vanish on the
    /// outside and grow like δ² and δ inside. The activation is C¹ at both transition ends.
    #[test]
    fn potential_is_c1_at_the_threshold() {
        let model = branched::<f64>();
        let s = selections()[0];
        let q = state(12, 2.0);
        let base = measure(&model, &q, &s);
        let task = task::<f64>(&s, base.value, 5.0);
        let direction = base.gradient.transpose() / base.gradient.norm();
        let mut previous: Option<(f64, f64)> = None;
        for delta in [1e-4, 1e-5, 1e-6] {
            let outside = row(&model, &task, &(q + direction * delta), &SVector::zeros());
            let inside = row(&model, &task, &(q - direction * delta), &SVector::zeros());
            assert_eq!((outside.potential, outside.force, outside.activation), (0.0, 0.0, 0.0));
            let (v, g) = (inside.potential, (inside.jacobian * inside.force).norm());
            if let Some((v0, g0)) = previous {
                // δ → δ/10: V shrinks ×100 (C¹: no jump in value or slope), ∇V shrinks ×10.
                assert!((v0 / v - 100.0).abs() < 2.0 && (g0 / g - 10.0).abs() < 0.2, "{v0} {v} {g0} {g}");
            }
            previous = Some((v, g));
        }
        let slope =
            |m: f64| (transition_activation(m + 1e-8, 0.5, 1.0) - transition_activation(m - 1e-8, 0.5, 1.0)) / 2e-8;
        assert!(slope(0.5).abs() < 1e-6 && slope(1.0).abs() < 1e-6);
    }

    #[test]
    fn damping_acts_with_the_activation() {
        let model = branched::<f64>();
        let s = selections()[2];
        let q = state(8, 2.0);
        let v = state(9, 1.0);
        let m = measure(&model, &q, &s);
        // Fully active (m below ϑ₁ = threshold/2): f = −2k(m − m₀) − d ṁ.
        let active = task::<f64>(&s, 3.0 * m.value, 7.0);
        let r = row(&model, &active, &q, &v);
        let rate = (m.gradient * v).x;
        assert_eq!(r.activation, 1.0);
        assert!((r.force - (-2.0 * 200.0 * (m.value - 3.0 * m.value) - 7.0 * rate)).abs() < 1e-9);
        // Inactive: no force at all.
        let inactive = task::<f64>(&s, 0.5 * m.value, 7.0);
        let r = row(&model, &inactive, &q, &v);
        assert_eq!((r.activation, r.force, r.potential), (0.0, 0.0, 0.0));
    }

    #[test]
    fn singular_jacobian_gives_a_zero_row() {
        let model = branched::<f64>();
        // Six rows of a 4-joint branch: J Jᵀ is singular.
        let s = (TCP, AxisMask::ALL, [true; N]);
        let task = task::<f64>(&s, 0.1, 1.0);
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &state(2, 1.0), &SVector::zeros()).unwrap();
        let mut rows = TaskRows::<f64, N, 1>::new();
        let report = manipulability_avoidance(&model, &data, &task, &mut rows).unwrap();
        assert!(report.singular && report.manipulability == 0.0);
        assert_eq!(rows.rows()[0].jacobian, RowSVector::<f64, N>::zeros());
        assert_eq!(manipulability_avoidance(&model, &data, &task, &mut rows), Err(TaskError::Capacity { capacity: 1 }));
    }

    #[test]
    fn invalid_parameters_are_rejected() {
        let good = *task::<f64>(&selections()[0], 0.2, 1.0).config();
        let check = |cfg, name| assert_eq!(Manipulability::try_new(cfg), Err(TaskError::InvalidParameter { name }));
        check(ManipulabilityConfig { rows: AxisMask::new([false; 6]), ..good }, "rows");
        check(ManipulabilityConfig { coordinates: [true, true, false, false, false, false], ..good }, "coordinates");
        check(ManipulabilityConfig { threshold: 0.0, ..good }, "threshold");
        check(ManipulabilityConfig { full_activation: 0.2, ..good }, "full_activation");
        check(ManipulabilityConfig { stiffness: f64::NAN, ..good }, "stiffness");
        check(ManipulabilityConfig { damping: -1.0, ..good }, "damping");
    }
}
