#![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "tests")]

use nalgebra::{Matrix4, SMatrix, Vector4};

use super::*;
use crate::math::damping::{double_diagonalization, ReflectedInertia};

/// The torso geometry of the tests: links of 0.3 m and the ranges of Table 3.2.
pub(super) fn test_geometry<T: RealField + Copy>() -> TorsoGeometry<T> {
    TorsoGeometry::from_degrees([0.3, 0.3], [-90.0, 90.0], [0.0, 135.0], [0.0, 135.0])
}

/// Four coordinates with the torso pitch joints at 1 and 3 (not adjacent, not first).
const N4: usize = 4;

fn config<T: RealField + Copy>(force: f64, angle_deg: f64, limit: f64) -> TorsoWorkspaceConfig<T> {
    TorsoWorkspaceConfig {
        geometry: test_geometry(),
        torque_limits: TorqueLimits::symmetric(limit),
        load: TorsoLoad::from_degrees(force, angle_deg),
        gains: RepulsionGains::thesis_experiment(),
        coordinates: [1, 3],
    }
}

fn inertia<T: RealField + Copy>() -> Cholesky<T, Const<N4>> {
    let a = Matrix4::<f64>::new(2.0, 0.3, 0.1, 0.2, 0.0, 1.5, 0.2, 0.4, 0.1, 0.0, 1.2, 0.1, 0.0, 0.3, 0.0, 0.9);
    Cholesky::new((a * a.transpose() + Matrix4::identity()).cast::<T>()).unwrap()
}

/// Deterministic uniform numbers in [0, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1_u64 << 53) as f64
    }
}

/// Uniform joint samples inside Table 3.2's ranges (the physically reachable set).
fn torso_sample(rng: &mut Lcg) -> (f64, f64) {
    let g = test_geometry::<f64>();
    loop {
        let q2 = g.joint2.min + (g.joint2.max - g.joint2.min) * rng.next();
        let q3 = g.joint3.min + (g.joint3.max - g.joint3.min) * rng.next();
        if g.contains(q2, q3) {
            return (q2, q3);
        }
    }
}

fn state<T: RealField + Copy>(q2: f64, q3: f64) -> SVector<T, N4> {
    Vector4::new(0.4, q2, -0.7, q3).cast()
}

fn potential<T: RealField + Copy>(task: &TorsoWorkspace<T, N4>, q: &SVector<T, N4>) -> T {
    let mut rows = TaskRows::<T, N4, BOUNDARIES>::new();
    torso_workspace(task, q, &SVector::zeros(), &inertia(), &mut rows).unwrap();
    rows.potential()
}

/// τ = Σ jᵀ f at q̇ = 0 against central differences of V_tws; returns the largest relative
/// error and the number of active rows seen.
fn gradient_error<T: RealField + Copy>(h: f64, force: f64, angle: f64) -> (f64, usize) {
    let task = TorsoWorkspace::<T, N4>::try_new(config(force, angle, 230.0)).unwrap();
    let mut rng = Lcg(11);
    let (mut worst, mut active) = (0.0_f64, 0);
    for _ in 0..400 {
        let (q2, q3) = torso_sample(&mut rng);
        let q = state::<T>(q2, q3);
        let mut rows = TaskRows::<T, N4, BOUNDARIES>::new();
        torso_workspace(&task, &q, &SVector::zeros(), &inertia(), &mut rows).unwrap();
        active += rows.rows().iter().filter(|r| r.potential > T::zero()).count();
        let tau = rows.torque();
        let hh: T = nalgebra::convert(h);
        let fd = SVector::<T, N4>::from_fn(|k, _| {
            let mut e = SVector::<T, N4>::zeros();
            e[k] = hh;
            (potential(&task, &(q + e)) - potential(&task, &(q - e))) / (hh + hh)
        });
        let err: f64 = nalgebra::try_convert((tau + fd).amax()).unwrap();
        let scale: f64 = nalgebra::try_convert(tau.amax()).unwrap();
        worst = worst.max(err / scale.max(1.0));
    }
    (worst, active)
}

#[test]
fn force_is_the_negative_gradient_of_the_potential_f64() {
    for (force, angle) in [(800.0, 90.0), (800.0, 70.0), (1200.0, 90.0), (550.0, 90.0)] {
        let (err, active) = gradient_error::<f64>(1e-6, force, angle);
        eprintln!("{force} N {angle}°: largest relative FD error {err:.2e}, {active} active rows");
        assert!(err < 1e-6, "{force} N {angle}°: {err}");
        assert!(active > 300, "the samples must exercise the rows ({active})");
    }
}

#[test]
fn force_is_the_negative_gradient_of_the_potential_f32() {
    // f32 central differences are limited by rounding: V is computed from positions with
    // errors ≈ ε|p| ≈ 4e-8 m times forces up to F_max = 50 N, so V errs by ≈ 1e-6 J and
    // V/h by ≈ 1e-3 at h = 1e-3 rad; truncation near corners (d ≈ 5 mm) is of the same size.
    // Stated tolerance: 5e-3 relative at h = 1e-3 rad.
    let (err, _) = gradient_error::<f32>(1e-3, 800.0, 90.0);
    eprintln!("f32: largest relative FD error {err:.2e}");
    assert!(err < 5e-3, "{err}");
}

/// The f32 rows agree with the f64 rows to f32 rounding (a sharper check than f32 finite
/// differences): torque within 1e-4 relative.
#[test]
fn f32_rows_agree_with_f64_rows() {
    let task64 = TorsoWorkspace::<f64, N4>::try_new(config(800.0, 70.0, 230.0)).unwrap();
    let task32 = TorsoWorkspace::<f32, N4>::try_new(config(800.0, 70.0, 230.0)).unwrap();
    let v = Vector4::new(0.1, 0.5, -0.2, -0.4);
    let mut rng = Lcg(21);
    let mut worst = 0.0_f64;
    for _ in 0..400 {
        let (q2, q3) = torso_sample(&mut rng);
        let mut rows64 = TaskRows::<f64, N4, BOUNDARIES>::new();
        let mut rows32 = TaskRows::<f32, N4, BOUNDARIES>::new();
        torso_workspace(&task64, &state(q2, q3), &v, &inertia(), &mut rows64).unwrap();
        torso_workspace(&task32, &state(q2, q3), &v.cast(), &inertia(), &mut rows32).unwrap();
        let (t64, t32) = (rows64.torque(), rows32.torque().cast::<f64>());
        worst = worst.max((t64 - t32).amax() / t64.amax().max(1.0));
    }
    eprintln!("f32 vs f64 torque: {worst:.2e}");
    assert!(worst < 1e-4, "{worst}");
}

/// (3.8) is C² at d₀: value, first and second derivative are continuous (all zero there),
/// the third jumps.
#[test]
fn potential_is_c2_at_the_activation_distance() {
    let g = RepulsionGains::<f64>::thesis_experiment();
    let d0 = g.distance;
    let e = 1e-7;
    for f in [RepulsionGains::potential, RepulsionGains::force, RepulsionGains::stiffness] {
        assert!(f(&g, d0 - e).abs() <= 1.0001 * 2.0 * g.max_force / (d0 * d0) * e);
        assert_eq!(f(&g, d0 + e), 0.0);
    }
    // Numerical derivatives: −V' = force, −force' = −stiffness (chain), across d₀ too.
    for d in [-0.05, 0.0, 0.03, 0.0999999, 0.1, 0.10001, 0.2] {
        let h = 1e-8;
        let dv = (g.potential(d + h) - g.potential(d - h)) / (2.0 * h);
        let df = (g.force(d + h) - g.force(d - h)) / (2.0 * h);
        assert!((dv + g.force(d)).abs() < 1e-6, "{d}");
        // The stiffness has a kink at d₀ (V''' jumps): the central difference errs by
        // F_max/d₀² h/2 = 2.5e-5 N/m there.
        assert!((df + g.stiffness(d)).abs() < 1e-4, "{d}");
    }
    // 1000 N/m at the boundary, F_max = 50 N (Sec. 3.3.5).
    assert!((g.stiffness(0.0) - 1000.0).abs() < 1e-9 && (g.force(0.0) - 50.0).abs() < 1e-12);
}

/// Rows stay continuous when p_t crosses the activation distance of a boundary.
#[test]
fn rows_are_continuous_across_activation() {
    let task = TorsoWorkspace::<f64, N4>::try_new(config(550.0, 90.0, 230.0)).unwrap();
    // Walk q_t2 from −90° upwards at q_t3 = 2.0 rad: the distance to arc 1 passes d₀.
    let mut previous: Option<(f64, TaskRow<f64, N4>)> = None;
    let mut crossed = false;
    for k in 0..4000 {
        let q2 = -core::f64::consts::FRAC_PI_2 + 0.6 * f64::from(k) / 4000.0;
        let q = state::<f64>(q2, 2.0);
        let v = Vector4::new(0.0, 0.3, 0.0, -0.2);
        let mut rows = TaskRows::<f64, N4, BOUNDARIES>::new();
        let report = torso_workspace(&task, &q, &v, &inertia(), &mut rows).unwrap();
        let d = report.distance(Boundary::Joint2Min).unwrap();
        let row = rows.rows()[Boundary::Joint2Min.index()];
        if let Some((d_prev, prev)) = previous {
            assert!((row.force - prev.force).abs() < 0.3, "{q2}");
            assert!((row.activation - prev.activation).abs() < 0.01, "{q2}");
            if d_prev < 0.1 && d >= 0.1 {
                crossed = true;
                assert!(row.force.abs() < 1e-3 && row.potential < 1e-6 && row.activation < 1e-3);
            }
        }
        previous = Some((d, row));
    }
    assert!(crossed);
}

/// Brute-force Euclidean distance from p to the boundary of the kinematic workspace (dense
/// samples of the six arcs).
fn brute_kinematic_distance(g: &TorsoGeometry<f64>, p: &Vector2<f64>) -> f64 {
    g.arc_lines()
        .iter()
        .map(|line| {
            let arc = g.arc(*line).unwrap();
            (0..=4000)
                .map(|k| (arc.point(arc.start + (arc.end - arc.start) * f64::from(k) / 4000.0) - p).norm())
                .fold(f64::INFINITY, f64::min)
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn kinematic_distances_are_positive_inside_and_the_nearest_matches_brute_force() {
    let task = TorsoWorkspace::<f64, N4>::try_new(config(800.0, 90.0, 230.0)).unwrap();
    let g = test_geometry();
    let mut rng = Lcg(3);
    for _ in 0..300 {
        let (q2, q3) = torso_sample(&mut rng);
        let report = task.report(q2, q3);
        assert!(report.kinematically_feasible);
        let kinematic: Vec<f64> =
            Boundary::ALL.iter().filter(|b| b.is_kinematic()).map(|b| report.distance(*b).unwrap()).collect();
        assert!(kinematic.iter().all(|d| *d >= -1e-12), "{q2} {q3}: {kinematic:?}");
        let nearest = kinematic.iter().copied().fold(f64::INFINITY, f64::min);
        let brute = brute_kinematic_distance(&g, &report.center);
        assert!((nearest - brute).abs() < 2e-4, "{q2} {q3}: {nearest} vs {brute}");
    }
}

/// Outside the ranges of Table 3.2 the violated limit has a negative distance.
#[test]
fn violated_kinematic_limits_have_negative_distances() {
    let task = TorsoWorkspace::<f64, N4>::try_new(config(550.0, 90.0, 230.0)).unwrap();
    let r = task.report(-1.7, 2.2); // q_t2 < −90°
    assert!(!r.kinematically_feasible && r.distance(Boundary::Joint2Min).unwrap() < 0.0);
    let r = task.report(0.5, -0.1); // q_t3 < 0
    assert!(r.distance(Boundary::Joint3Min).unwrap() < 0.0);
    let r = task.report(1.0, 1.5); // q_t2 + q_t3 > 135°
    assert!(r.distance(Boundary::SumMax).unwrap() < 0.0);
}

/// The dynamic distances agree with the torque check (3.45)–(3.47): every present distance is
/// non-negative exactly where the load torques are within the limits.
#[test]
fn dynamic_distances_agree_with_the_torque_limits() {
    for (force, angle, limit) in
        [(800.0, 90.0, 230.0), (800.0, 70.0, 230.0), (1200.0, 90.0, 230.0), (470.0, 90.0, 140.0), (900.0, 0.0, 100.0)]
    {
        let task = TorsoWorkspace::<f64, N4>::try_new(config(force, angle, limit)).unwrap();
        let mut rng = Lcg(5);
        let mut infeasible = 0;
        for _ in 0..2000 {
            let (q2, q3) = torso_sample(&mut rng);
            let r = task.report(q2, q3);
            let by_distance =
                Boundary::ALL.iter().filter(|b| !b.is_kinematic()).all(|b| r.distance(*b).is_none_or(|d| d >= 0.0));
            assert_eq!(by_distance, r.dynamically_feasible, "{force} N {angle}° at {q2} {q3}: {r:?}");
            infeasible += usize::from(!r.dynamically_feasible);
        }
        assert!(infeasible > 0, "{force} N {angle}°");
    }
}

#[test]
fn joint3_constraints_vanish_below_the_overlap_load() {
    // 550 N · 0.3 m = 165 Nm < 230 Nm (Fig. 3.16d); 800 N · 0.3 m = 240 Nm > 230 Nm (Fig. 3.16a).
    let mut task = TorsoWorkspace::<f64, N4>::try_new(config(550.0, 90.0, 230.0)).unwrap();
    let joint3 =
        [Boundary::Torque3MinPlus, Boundary::Torque3MinMinus, Boundary::Torque3MaxPlus, Boundary::Torque3MaxMinus];
    assert!(joint3.iter().all(|b| task.curve(*b) == BoundaryCurve::Absent));
    task.set_load(TorsoLoad::from_degrees(800.0, 90.0)).unwrap();
    // τ_min band around q_t2 + q_t3 = 90°, both half circles inside the workspace; the τ_max
    // band lies around 270°, outside.
    assert!(matches!(task.curve(Boundary::Torque3MinPlus), BoundaryCurve::Arc(_)));
    assert!(matches!(task.curve(Boundary::Torque3MinMinus), BoundaryCurve::Arc(_)));
    assert_eq!(task.curve(Boundary::Torque3MaxPlus), BoundaryCurve::Absent);
    assert_eq!(task.curve(Boundary::Torque3MaxMinus), BoundaryCurve::Absent);
    // Table A.2 centres: l_t3 e(α ± arccos(230/240)).
    let w = (230.0_f64 / 240.0).acos();
    let BoundaryCurve::Arc(plus) = task.curve(Boundary::Torque3MinPlus) else { panic!() };
    assert!((plus.center - direction(core::f64::consts::FRAC_PI_2 + w) * 0.3).amax() < 1e-12 && plus.radius == 0.3);
    assert_eq!(task.set_load(TorsoLoad { force: -1.0, angle: 0.0 }), Err(TaskError::InvalidParameter { name: "load" }));
}

/// The four joint-3 circles carry the names of Table A.2: centre `l_t3 e(α ± arccos(−τ/(F l_t3)))`.
#[test]
fn joint3_circles_follow_table_a2() {
    // 900 N forwards (α = 0), ±100 Nm: F l_t3 = 270 Nm. The "+" circles lie at sums 68.3° (τ_min)
    // and 111.7° (τ_max) inside the workspace, the "−" circles at negative sums outside it.
    let task = TorsoWorkspace::<f64, N4>::try_new(config(900.0, 0.0, 100.0)).unwrap();
    for (boundary, tau) in [(Boundary::Torque3MinPlus, -100.0), (Boundary::Torque3MaxPlus, 100.0)] {
        let BoundaryCurve::Arc(arc) = task.curve(boundary) else { panic!("{boundary:?}") };
        let phi = (-tau / 270.0_f64).acos();
        assert!((arc.center - direction(phi) * 0.3).amax() < 1e-12, "{boundary:?}");
    }
    assert_eq!(task.curve(Boundary::Torque3MinMinus), BoundaryCurve::Absent);
    assert_eq!(task.curve(Boundary::Torque3MaxMinus), BoundaryCurve::Absent);
    // Feasible sides (Table A.2): τ_min "+" inside, τ_max "+" outside its circle.
    let deg = f64::to_radians;
    let inside_min = task.report(deg(40.0), deg(40.0)); // sum 80°: between the two circles
    assert!(inside_min.load_torque.y.abs() < 100.0); // (joint 2 is beyond its limit here)
    assert!(inside_min.distance(Boundary::Torque3MinPlus).unwrap() > 0.0);
    assert!(inside_min.distance(Boundary::Torque3MaxPlus).unwrap() > 0.0);
}

/// Inside a joint-3 band each half is pushed out through its own edge.
#[test]
fn a_torque_band_is_left_through_its_nearer_edge() {
    let task = TorsoWorkspace::<f64, N4>::try_new(config(800.0, 90.0, 230.0)).unwrap();
    let deg = f64::to_radians;
    // Sum 80° (lower half of the band 73.4°…106.6°): governed by the "−" edge.
    let r = task.report(deg(20.0), deg(60.0));
    assert!(r.distance(Boundary::Torque3MinMinus).unwrap() < 0.0 && r.distance(Boundary::Torque3MinPlus).is_none());
    let r = task.report(deg(20.0), deg(80.0));
    assert!(r.distance(Boundary::Torque3MinPlus).unwrap() < 0.0 && r.distance(Boundary::Torque3MinMinus).is_none());
    assert!(!r.dynamically_feasible);
    // Sum 60°: feasible, below the band, governed (and repelled) by the "−" edge only.
    let r = task.report(deg(0.0), deg(60.0));
    assert!(r.dynamically_feasible && r.distance(Boundary::Torque3MinMinus).unwrap() > 0.0);
    assert!(r.distance(Boundary::Torque3MinPlus).is_none());
}

/// The damping of a row is that of the 1-D double diagonalisation with the row's reflected
/// mass and local stiffness (Sec. 3.1.3).
#[test]
fn damping_is_the_double_diagonalisation_of_each_row() {
    let task = TorsoWorkspace::<f64, N4>::try_new(config(800.0, 70.0, 230.0)).unwrap();
    let chol = inertia::<f64>();
    let m_inv = chol.inverse();
    let v = Vector4::new(0.2, -0.4, 0.1, 0.3);
    let mut rng = Lcg(9);
    let mut checked = 0;
    for _ in 0..100 {
        let (q2, q3) = torso_sample(&mut rng);
        let q = state::<f64>(q2, q3);
        let mut still = TaskRows::<f64, N4, BOUNDARIES>::new();
        let mut moving = TaskRows::<f64, N4, BOUNDARIES>::new();
        torso_workspace(&task, &q, &SVector::zeros(), &chol, &mut still).unwrap();
        let report = torso_workspace(&task, &q, &v, &chol, &mut moving).unwrap();
        for ((a, b), d) in still.rows().iter().zip(moving.rows()).zip(report.distances) {
            let Some(d) = d else { continue };
            let k = task.config().gains.stiffness(d);
            if k <= 0.0 || (a.jacobian * m_inv * a.jacobian.transpose()).x < 1e-6 {
                continue;
            }
            let lambda_inv = SMatrix::<f64, 1, 1>::new((a.jacobian * m_inv * a.jacobian.transpose()).x);
            let damping = double_diagonalization(
                ReflectedInertia::Inverse(&lambda_inv),
                &SMatrix::<f64, 1, 1>::new(k),
                &nalgebra::Vector1::new(0.3),
            )
            .unwrap()[0];
            let expected = a.force - damping * (a.jacobian * v).x;
            assert!((b.force - expected).abs() < 1e-9 * (1.0 + expected.abs()), "{} vs {expected}", b.force);
            checked += 1;
        }
    }
    assert!(checked > 50, "{checked}");
}

#[test]
fn row_list_errors_leave_it_unchanged() {
    let task = TorsoWorkspace::<f64, N4>::try_new(config(800.0, 90.0, 230.0)).unwrap();
    let q = state::<f64>(0.2, 0.5);
    let mut rows = TaskRows::<f64, N4, 13>::new();
    rows.push(TaskRow { jacobian: RowSVector::zeros(), force: 1.0, potential: 0.0, activation: 1.0 }).unwrap();
    let before = rows.clone();
    let mut nan = q;
    nan[1] = f64::NAN;
    assert_eq!(torso_workspace(&task, &nan, &SVector::zeros(), &inertia(), &mut rows), Err(TaskError::NonFinite));
    assert_eq!(rows, before);
    let mut small = TaskRows::<f64, N4, 12>::new();
    small.push(before.rows()[0]).unwrap();
    assert_eq!(
        torso_workspace(&task, &q, &SVector::zeros(), &inertia(), &mut small),
        Err(TaskError::Capacity { capacity: 12 })
    );
    assert_eq!(small.len(), 1);
    torso_workspace(&task, &q, &SVector::zeros(), &inertia(), &mut rows).unwrap();
    assert_eq!(rows.len(), 13);
    // Absent boundaries (no τ_max band under a downward load) give zero rows.
    let absent = rows.rows()[1 + Boundary::Torque3MaxPlus.index()];
    assert_eq!(
        (absent.jacobian, absent.force, absent.potential, absent.activation),
        (RowSVector::zeros(), 0.0, 0.0, 0.0)
    );
}

#[test]
fn invalid_configurations_are_rejected() {
    let good = config::<f64>(800.0, 90.0, 230.0);
    assert!(TorsoWorkspace::<f64, N4>::try_new(good).is_ok());
    let bad = [
        TorsoWorkspaceConfig { coordinates: [1, 1], ..good },
        TorsoWorkspaceConfig { coordinates: [1, 4], ..good },
        TorsoWorkspaceConfig { gains: RepulsionGains { distance: 0.0, ..good.gains }, ..good },
        TorsoWorkspaceConfig { gains: RepulsionGains { activation_start: -1.0, ..good.gains }, ..good },
        TorsoWorkspaceConfig { torque_limits: TorqueLimits::symmetric(0.0), ..good },
        TorsoWorkspaceConfig { load: TorsoLoad { force: f64::INFINITY, angle: 0.0 }, ..good },
    ];
    for b in bad {
        assert!(matches!(TorsoWorkspace::<f64, N4>::try_new(b), Err(TaskError::InvalidParameter { .. })), "{b:?}");
    }
}

/// The plain row loop (one full `Cholesky::solve` per row for `j M⁻¹ jᵀ`, nalgebra row products,
/// finiteness of every row checked on its whole Jacobian): the reference for
/// [`torso_workspace`].
fn reference_torso_workspace<T: RealField + Copy, const N: usize, const R: usize>(
    task: &TorsoWorkspace<T, N>,
    q: &SVector<T, N>,
    v: &SVector<T, N>,
    inertia: &Cholesky<T, Const<N>>,
    rows: &mut TaskRows<T, N, R>,
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
    let mut new_rows =
        [TaskRow { jacobian: RowSVector::zeros(), force: T::zero(), potential: T::zero(), activation: T::zero() };
            BOUNDARIES];
    for ((row, distance), gradient) in new_rows.iter_mut().zip(report.distances.iter()).zip(gradients.iter()) {
        let Some(d) = *distance else { continue };
        let local = gradient.transpose() * jt;
        let mut jacobian = RowSVector::<T, N>::zeros();
        if let (Some(a), Some(b)) = (jacobian.get_mut(i2), local.get(0)) {
            *a = *b;
        }
        if let (Some(a), Some(b)) = (jacobian.get_mut(i3), local.get(1)) {
            *a = *b;
        }
        let rate = (jacobian * v).x;
        // Damping 2ξ√(k m) ḋ with m = 1/(j M⁻¹ jᵀ): 2ξ√k ḋ/√(j M⁻¹ jᵀ). At a singular row
        // (j → 0) both ḋ and √(j M⁻¹ jᵀ) vanish linearly; below the guard no damping.
        let stiffness = gains.stiffness(d);
        let mobility = (jacobian * inertia.solve(&jacobian.transpose())).x.max(T::zero()).sqrt();
        let damping = crate::math::guarded_divide(
            two * gains.damping_ratio * stiffness.sqrt() * rate,
            mobility,
            T::default_epsilon(),
        )
        .unwrap_or_else(T::zero);
        *row = TaskRow {
            jacobian,
            force: gains.force(d) - damping,
            potential: gains.potential(d),
            activation: transition_activation(d, gains.activation_full, gains.activation_start),
        };
    }
    let finite = new_rows.iter().all(|r| {
        r.force.is_finite()
            && r.potential.is_finite()
            && r.activation.is_finite()
            && crate::math::all_finite(&r.jacobian)
    });
    if !finite {
        return Err(TaskError::NonFinite);
    }
    for row in new_rows {
        rows.push(row)?;
    }
    Ok(report)
}

/// [`torso_workspace`] against [`reference_torso_workspace`] on random torso states (near and
/// inside every boundary), loads and velocities, f64 and f32: same rows to rounding.
fn fast_matches_reference<T: RealField + Copy>(tolerance: f64) -> f64 {
    let mut rng = Lcg(0xDEC0DE);
    let mut worst = 0.0_f64;
    let mut active = 0;
    for case in 0..400 {
        let (force, angle) = (300.0 + 700.0 * rng.next(), 360.0 * rng.next());
        let task = TorsoWorkspace::<T, N4>::try_new(config(force, angle, 150.0 + 150.0 * rng.next())).unwrap();
        let (q2, q3) = torso_sample(&mut rng);
        let q = state::<T>(q2, q3);
        let v = Vector4::new(rng.next() - 0.5, 2.0 * rng.next() - 1.0, rng.next(), 2.0 * rng.next() - 1.0).cast::<T>();
        let (mut fast_rows, mut plain_rows) =
            (TaskRows::<T, N4, BOUNDARIES>::new(), TaskRows::<T, N4, BOUNDARIES>::new());
        let fast = torso_workspace(&task, &q, &v, &inertia(), &mut fast_rows).unwrap();
        let plain = reference_torso_workspace(&task, &q, &v, &inertia(), &mut plain_rows).unwrap();
        assert_eq!(fast, plain, "case {case}");
        for (a, b) in fast_rows.rows().iter().zip(plain_rows.rows()) {
            let to_f64 = |x: T| -> f64 { nalgebra::try_convert(x).unwrap() };
            assert_eq!(a.jacobian, b.jacobian);
            assert_eq!((a.potential, a.activation), (b.potential, b.activation));
            let error = to_f64((a.force - b.force).abs()) / (to_f64(b.force.abs()) + 1.0);
            worst = worst.max(error);
            assert!(error <= tolerance, "case {case}: {} vs {}", a.force, b.force);
            active += usize::from(b.activation > T::zero() && b.force != T::zero());
        }
    }
    assert!(active > 50, "rows with force seen: {active}");
    worst
}

#[test]
fn row_loop_matches_the_reference_f64() {
    let worst = fast_matches_reference::<f64>(1e-12);
    eprintln!("torso fast vs reference, f64: {worst:e}");
}

#[test]
fn row_loop_matches_the_reference_f32() {
    let worst = fast_matches_reference::<f32>(1e-5);
    eprintln!("torso fast vs reference, f32: {worst:e}");
}

/// [`torso_workspace`] on the tree-sparse factor of the branched test model's `M` (torso
/// coordinates 2 and 3 on one branch, 1 their common ancestor) against
/// [`reference_torso_workspace`] on the dense Cholesky factor, f64 and f32.
fn tree_factor_matches_reference<T: RealField + Copy>(tolerance: f64) -> f64 {
    use crate::dynamics::{crba, forward_kinematics};
    use crate::model::Data;
    use crate::test_models::{branched, state as model_state, N};
    let model = branched::<T>();
    let mut data = Data::new(&model);
    let mut tree = TreeFactorization::new(&model);
    let mut rng = Lcg(0xFACADE);
    let (mut worst, mut active) = (0.0_f64, 0);
    for case in 0..300_u64 {
        let (force, angle) = (300.0 + 700.0 * rng.next(), 360.0 * rng.next());
        let mut cfg = config::<T>(force, angle, 150.0 + 150.0 * rng.next());
        cfg.coordinates = [2, 3];
        let task = TorsoWorkspace::<T, N>::try_new(cfg).unwrap();
        let (q2, q3) = torso_sample(&mut rng);
        let mut q = model_state(case, 1.5);
        (q[2], q[3]) = (q2, q3);
        let (q, v) = (q.cast::<T>(), model_state(case ^ 7, 1.0).cast::<T>());
        forward_kinematics(&model, &mut data, &q, &v).unwrap();
        crba(&model, &mut data);
        tree.factorize(&data.mass_matrix).unwrap();
        let dense = Cholesky::new(data.mass_matrix).unwrap();
        let (mut fast_rows, mut plain_rows) =
            (TaskRows::<T, N, BOUNDARIES>::new(), TaskRows::<T, N, BOUNDARIES>::new());
        let fast = torso_workspace(&task, &q, &v, &tree, &mut fast_rows).unwrap();
        let plain = reference_torso_workspace(&task, &q, &v, &dense, &mut plain_rows).unwrap();
        assert_eq!(fast, plain, "case {case}");
        for (a, b) in fast_rows.rows().iter().zip(plain_rows.rows()) {
            let to_f64 = |x: T| -> f64 { nalgebra::try_convert(x).unwrap() };
            assert_eq!(a.jacobian, b.jacobian);
            let error = to_f64((a.force - b.force).abs()) / (to_f64(b.force.abs()) + 1.0);
            worst = worst.max(error);
            assert!(error <= tolerance, "case {case}: {} vs {}", a.force, b.force);
            active += usize::from(b.activation > T::zero() && b.force != T::zero());
        }
    }
    assert!(active > 30, "rows with force seen: {active}");
    worst
}

#[test]
fn tree_factor_matches_the_reference_f64() {
    let worst = tree_factor_matches_reference::<f64>(1e-12);
    eprintln!("torso tree vs reference, f64: {worst:e}");
}

#[test]
fn tree_factor_matches_the_reference_f32() {
    let worst = tree_factor_matches_reference::<f32>(1e-5);
    eprintln!("torso tree vs reference, f32: {worst:e}");
}
