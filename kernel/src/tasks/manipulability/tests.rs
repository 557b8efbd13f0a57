#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
use super::*;
use crate::dynamics::{forward_kinematics, frame_jacobian, frame_jacobian_derivative};
use crate::test_models::{branched, state, Branched, N, TCP, WRIST};
use nalgebra::{SMatrix, SVector, Vector6};

/// The plain reference for [`manipulability`] (the implementation it replaced): the padded
/// `A = J̃ J̃ᵀ + (I − S)` from dense masking products, nalgebra's Cholesky, and one
/// [`frame_jacobian_derivative`] per coordinate, `∂m/∂q_k = m ⟨∂J/∂q_k, A⁻¹ J̃⟩_F`.
pub(crate) fn reference<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
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

/// Every non-empty row mask with several column selections on both branches (TCP: the
/// coupled joint, WRIST: the prismatic branch), including columns off the frame's path.
fn all_selections() -> impl Iterator<Item = (FrameId, AxisMask, [bool; N])> {
    let columns = [
        [true; N],
        [true, true, true, true, false, false],
        [false, true, false, false, true, true],
        [true, false, true, true, true, false],
        [false, true, true, false, true, true],
    ];
    [TCP, WRIST].into_iter().flat_map(move |frame| {
        (1..64_usize).flat_map(move |bits| {
            let rows = AxisMask::new(core::array::from_fn(|i| bits & (1 << i) != 0));
            columns.into_iter().map(move |c| (frame, rows, c))
        })
    })
}

/// `σ_min / max(σ_max, 1)` of the selected Jacobian (f64, SVD) at `q` (`σ_min / σ_max` if all
/// six rows are selected): the scale of the pivot floor of [`manipulability`] is the largest
/// diagonal entry of `J̃ J̃ᵀ + (I − S)`.
fn conditioning(q: &SVector<f64, N>, frame: FrameId, rows: AxisMask, columns: &[bool; N]) -> f64 {
    let model = branched::<f64>();
    let mut data = Data::new(&model);
    forward_kinematics(&model, &mut data, q, &SVector::zeros()).unwrap();
    let mut j = SMatrix::<f64, 6, N>::zeros();
    frame_jacobian(&model, &data, frame, &mut j).unwrap();
    let picked: std::vec::Vec<usize> = (0..6).filter(|i| rows.contains(*i)).collect();
    let selected = nalgebra::DMatrix::from_fn(picked.len(), N, |r, k| if columns[k] { j[(picked[r], k)] } else { 0.0 });
    let s = selected.singular_values();
    let largest = if picked.len() < 6 { s.max().max(1.0) } else { s.max() };
    if largest > 0.0 {
        s.min() / largest
    } else {
        0.0
    }
}

/// Fast vs reference at the same precision over [`all_selections`] and 20 random states.
/// Selections with `c² < 1e3 · 100 ε` (`c` of [`conditioning`]) are skipped: near the
/// pivot floor (e.g. a rank-deficient selection) the singular flag is decided by rounding.
/// On the others both must be regular with
/// `|Δm| ≤ tol (|m| + 1e-3) / c²` and `‖Δ∇m‖∞ ≤ tol (‖∇m‖∞ + 1e-3) / c²`
/// (the gradient goes through `(J Jᵀ)⁻¹`). Returns the worst scaled gradient difference and
/// the number of compared cases.
fn compare_with_reference<T: RealField + Copy>(tolerance: f64) -> (f64, usize) {
    let model = branched::<T>();
    let mut data = Data::new(&model);
    let (mut worst, mut compared) = (0.0_f64, 0);
    for seed in 0..20 {
        let q = state(seed, 2.0);
        forward_kinematics(&model, &mut data, &q.cast(), &SVector::zeros()).unwrap();
        for (frame, rows, columns) in all_selections() {
            let fast = manipulability(&model, &data, frame, rows, &columns).unwrap();
            let plain = reference(&model, &data, frame, rows, &columns).unwrap();
            if fast.singular {
                assert_eq!((fast.value, fast.gradient), (T::zero(), RowSVector::zeros()));
            }
            let f64_of = |x: T| -> f64 { nalgebra::try_convert(x).unwrap() };
            let c2 = conditioning(&q, frame, rows, &columns).powi(2);
            if c2 < 1e5 * f64_of(T::default_epsilon()) {
                continue;
            }
            assert!(!fast.singular && !plain.singular, "seed {seed} {frame:?} {rows:?} {columns:?}");
            compared += 1;
            let (m, dm) = (f64_of(plain.value), f64_of(fast.value - plain.value));
            assert!(dm.abs() * c2 <= tolerance * (m.abs() + 1e-3), "seed {seed}: m {m} vs {dm}");
            let scale = f64_of(plain.gradient.amax());
            let err = f64_of((fast.gradient - plain.gradient).amax()) * c2;
            worst = worst.max(err / (scale + 1e-3));
            assert!(err <= tolerance * (scale + 1e-3), "seed {seed} {frame:?} {rows:?} {columns:?}: {err} vs {scale}");
        }
    }
    (worst, compared)
}

#[test]
fn fast_gradient_matches_the_reference_f64() {
    let (worst, regular) = compare_with_reference::<f64>(1e-12);
    eprintln!("manipulability fast vs reference f64: worst scaled {worst:e} over {regular} cases");
    assert!(regular > 1000, "{regular}");
}

#[test]
fn fast_gradient_matches_the_reference_f32() {
    let (worst, regular) = compare_with_reference::<f32>(2e-4);
    eprintln!("manipulability fast vs reference f32: worst scaled {worst:e} over {regular} cases");
    assert!(regular > 1000, "{regular}");
}

/// The f32 fast gradient against the f64 reference on the selections of [`selections`]
/// (well-conditioned, as a controller uses them).
#[test]
fn fast_gradient_f32_matches_the_f64_reference() {
    let (m64, m32) = (branched::<f64>(), branched::<f32>());
    let (mut d64, mut d32) = (Data::new(&m64), Data::new(&m32));
    let mut worst = 0.0_f64;
    for seed in 0..40 {
        let q = state(seed, 2.0);
        forward_kinematics(&m64, &mut d64, &q, &SVector::zeros()).unwrap();
        forward_kinematics(&m32, &mut d32, &q.cast(), &SVector::zeros()).unwrap();
        for (frame, rows, columns) in selections() {
            let plain = reference(&m64, &d64, frame, rows, &columns).unwrap();
            let fast = manipulability(&m32, &d32, frame, rows, &columns).unwrap();
            assert!(!plain.singular && !fast.singular);
            let dm = (f64::from(fast.value) - plain.value).abs();
            assert!(dm <= 1e-4 * (plain.value + 1e-3), "seed {seed}: {dm} of {}", plain.value);
            let err = (fast.gradient.cast::<f64>() - plain.gradient).amax();
            worst = worst.max(err / (plain.gradient.amax() + 1e-3));
            assert!(err <= 3e-4 * (plain.gradient.amax() + 1e-3), "seed {seed}: {err}");
        }
    }
    eprintln!("manipulability f32 fast vs f64 reference: worst relative {worst:e}");
}

/// A world-fixed frame has J = 0: singular with any row, like the reference.
#[test]
fn world_fixed_frame_is_singular() {
    let mut b = crate::model::ModelBuilder::<f64, 1, 1, 1>::new(nalgebra::Vector3::zeros());
    let z = crate::model::JointKind::Revolute { axis: nalgebra::Unit::new_normalize(nalgebra::Vector3::z()) };
    let inertia = crate::model::Inertia::point_mass(1.0, nalgebra::Vector3::x());
    b.add_body(None, crate::math::spatial::Placement::identity(), z, crate::model::JointDrive::actuated(0), inertia)
        .unwrap();
    let fixed = b.add_frame(None, crate::math::spatial::Placement::identity()).unwrap();
    let model = b.try_build().unwrap();
    let mut data = Data::new(&model);
    forward_kinematics(&model, &mut data, &SVector::from([0.3]), &SVector::zeros()).unwrap();
    let x = AxisMask::new([true, false, false, false, false, false]);
    let fast = manipulability(&model, &data, fixed, x, &[true]).unwrap();
    assert!(fast.singular && fast == reference(&model, &data, fixed, x, &[true]).unwrap());
    assert_eq!(
        manipulability(&model, &data, FrameId(3), x, &[true]),
        Err(TaskError::Dynamics(DynamicsError::UnknownFrame))
    );
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

fn task<T: RealField + Copy>(s: &(FrameId, AxisMask, [bool; N]), threshold: f64, damping: f64) -> Manipulability<T, N> {
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
    let slope = |m: f64| (transition_activation(m + 1e-8, 0.5, 1.0) - transition_activation(m - 1e-8, 0.5, 1.0)) / 2e-8;
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
