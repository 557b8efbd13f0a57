#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
use super::*;
use crate::dynamics::{crba, forward_kinematics};
use crate::test_models::{branched, state, Branched, N, TCP, WRIST};
use nalgebra::{Rotation3, SVector, Translation3};

fn c<T: RealField + Copy>(x: f64) -> T {
    nalgebra::convert(x)
}

fn config<T: RealField + Copy>(
    frame: FrameId,
    axes: AxisMask,
    stiffness_frame: StiffnessFrame,
) -> CartesianImpedanceConfig<T> {
    let kt = Matrix3::new(800.0, 100.0, -50.0, 100.0, 500.0, 30.0, -50.0, 30.0, 300.0);
    let kr = Matrix3::new(60.0, 5.0, 0.0, 5.0, 40.0, -8.0, 0.0, -8.0, 30.0);
    CartesianImpedanceConfig {
        frame,
        axes,
        stiffness_frame,
        translational_stiffness: kt.map(c),
        rotational_stiffness: kr.map(c),
        damping_ratio: c(0.7),
        force_lower: Vector6::repeat(c(f64::NEG_INFINITY)),
        force_upper: Vector6::repeat(c(f64::INFINITY)),
        fallback_damping: Vector6::repeat(c(10.0)),
    }
}

/// A target with a sizeable error: the frame pose at `q`, moved and turned.
fn offset_target<T: RealField + Copy>(
    model: &Branched<T>,
    frame: FrameId,
    q: &SVector<T, N>,
    seed: u64,
) -> CartesianTarget<T> {
    let mut data = Data::new(model);
    forward_kinematics(model, &mut data, q, &SVector::zeros()).unwrap();
    let s = state(seed, 1.0);
    let shift = Placement::<f64>::from_parts(
        Translation3::new(0.3 * s[0], 0.3 * s[1], 0.3 * s[2]),
        Rotation3::from_scaled_axis(Vector3::new(s[3], s[4], s[5]) * 1.2),
    );
    CartesianTarget::at_rest(nalgebra::convert::<_, Placement<T>>(shift) * data.frame_placements[frame.0])
}

fn evaluate<T: RealField + Copy>(
    model: &Branched<T>,
    task: &CartesianImpedance<T>,
    target: &CartesianTarget<T>,
    q: &SVector<T, N>,
    v: &SVector<T, N>,
) -> (TaskRows<T, N, 6>, CartesianReport<T>) {
    let mut data = Data::new(model);
    forward_kinematics(model, &mut data, q, v).unwrap();
    crba(model, &mut data);
    let mut rows = TaskRows::new();
    let report = cartesian_impedance(model, &data, task, target, &mut rows).unwrap();
    (rows, report)
}

/// Σ jᵀ f at v = 0 against central differences of the rows' potential, for both frames,
/// both stiffness frames and several axis masks (a masked axis must not leak into V).
fn gradient_check<T: RealField + Copy>(h: f64, tolerance: f64) -> f64 {
    let model = branched::<T>();
    let masks = [
        AxisMask::ALL,
        AxisMask::ROTATION,
        AxisMask::new([true, false, true, false, true, false]),
        AxisMask::new([false, false, false, false, false, true]),
    ];
    let mut worst = 0.0_f64;
    for seed in 0..40_u64 {
        let frame = if seed % 2 == 0 { TCP } else { WRIST };
        let stiffness_frame = if seed % 3 == 0 { StiffnessFrame::World } else { StiffnessFrame::Desired };
        let task =
            CartesianImpedance::try_new(config::<T>(frame, masks[(seed % 4) as usize], stiffness_frame)).unwrap();
        let q: SVector<T, N> = state(seed, 2.0).cast();
        let target = offset_target(&model, frame, &q, seed ^ 77);
        let (rows, _) = evaluate(&model, &task, &target, &q, &SVector::zeros());
        let tau = rows.torque();
        let hh: T = c(h);
        let fd = SVector::<T, N>::from_fn(|k, _| {
            let mut e = SVector::<T, N>::zeros();
            e[k] = hh;
            let plus = evaluate(&model, &task, &target, &(q + e), &SVector::zeros()).0.potential();
            let minus = evaluate(&model, &task, &target, &(q - e), &SVector::zeros()).0.potential();
            (plus - minus) / (hh + hh)
        });
        let relative: f64 = nalgebra::try_convert((tau + fd).amax() / (tau.amax() + c(1e-3))).unwrap();
        worst = worst.max(relative);
        assert!(relative <= tolerance, "seed {seed}: relative error {relative}");
    }
    worst
}

/// The loops of [`cartesian_impedance`] (or, with `factored`, [`cartesian_impedance_factored`]
/// on the tree-sparse factor of `M`) against the plain [`reference::cartesian_impedance`] on
/// random states, frames, masks and stiffness frames (and the fallbacks), f64 and f32.
fn fast_matches_reference<T: RealField + Copy>(tolerance: f64, factored: bool) -> f64 {
    let model = branched::<T>();
    let masks = [
        AxisMask::new([true, true, true, false, false, true]),
        AxisMask::new([true, false, true, true, false, true]),
        AxisMask::ROTATION,
        AxisMask::TRANSLATION,
        AxisMask::ALL,
    ];
    let mut worst = 0.0_f64;
    for seed in 0..60_u64 {
        let frame = if seed % 2 == 0 { TCP } else { WRIST };
        let stiffness_frame = if seed % 3 == 0 { StiffnessFrame::World } else { StiffnessFrame::Desired };
        let mut cfg = config::<T>(frame, masks[(seed % 5) as usize], stiffness_frame);
        cfg.force_upper = Vector6::repeat(c(15.0));
        let task = CartesianImpedance::try_new(cfg).unwrap();
        let (q, v): (SVector<T, N>, SVector<T, N>) = (state(seed, 2.0).cast(), state(seed ^ 9, 1.5).cast());
        let mut target = offset_target(&model, frame, &q, seed ^ 31);
        target.linear_velocity = Vector3::new(c(0.2), c(-0.1), c(0.3));
        target.angular_velocity = Vector3::new(c(-0.3), c(0.5), c(0.1));
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &q, &v).unwrap();
        if seed % 11 != 5 {
            crba(&model, &mut data); // else M = 0: the fallback
        }
        let (mut fast_rows, mut reference_rows) = (TaskRows::<T, N, 6>::new(), TaskRows::<T, N, 6>::new());
        let mut tree = TreeFactorization::new(&model);
        let fast = if factored {
            let mass = tree.factorize(&data.mass_matrix).is_ok().then_some(&tree);
            assert_eq!(mass.is_none(), seed % 11 == 5, "seed {seed}");
            cartesian_impedance_factored(&model, &data, mass, &task, &target, &mut fast_rows).unwrap()
        } else {
            cartesian_impedance(&model, &data, &task, &target, &mut fast_rows).unwrap()
        };
        let plain = reference::cartesian_impedance(&model, &data, &task, &target, &mut reference_rows).unwrap();
        assert_eq!(fast.damping_fallback, plain.damping_fallback, "seed {seed}");
        assert_eq!(fast.saturated, plain.saturated, "seed {seed}");
        assert_eq!(fast_rows.len(), reference_rows.len());
        let scale = |x: T| -> f64 { nalgebra::try_convert(x).unwrap() };
        let force_scale = scale(plain.unsaturated_force.amax()) + 1.0;
        let mut error = scale((fast.error - plain.error).amax()) + scale((fast.error_rate - plain.error_rate).amax());
        error = error.max(scale((fast.damping_force - plain.damping_force).amax()) / force_scale);
        error = error.max(scale((fast.unsaturated_force - plain.unsaturated_force).amax()) / force_scale);
        for (a, b) in fast_rows.rows().iter().zip(reference_rows.rows()) {
            error = error.max(scale((a.jacobian - b.jacobian).amax()));
            error = error.max(scale((a.force - b.force).abs()) / force_scale);
            error = error.max(scale((a.potential - b.potential).abs()) / (scale(b.potential.abs()) + 1.0));
        }
        worst = worst.max(error);
        assert!(error <= tolerance, "seed {seed}: relative difference {error:e}");
    }
    worst
}

#[test]
fn loops_match_the_reference_f64() {
    let worst = fast_matches_reference::<f64>(1e-10, false);
    eprintln!("cartesian fast vs reference, f64: {worst:e}");
}

#[test]
fn tree_factored_damping_matches_the_reference_f64() {
    let worst = fast_matches_reference::<f64>(1e-10, true);
    eprintln!("cartesian tree-factored vs reference, f64: {worst:e}");
}

#[test]
fn tree_factored_damping_matches_the_reference_f32() {
    let worst = fast_matches_reference::<f32>(1e-4, true);
    eprintln!("cartesian tree-factored vs reference, f32: {worst:e}");
}

#[test]
fn loops_match_the_reference_f32() {
    let worst = fast_matches_reference::<f32>(1e-4, false);
    eprintln!("cartesian fast vs reference, f32: {worst:e}");
}

#[test]
fn force_is_the_negative_gradient_f64() {
    let worst = gradient_check::<f64>(1e-6, 1e-6);
    eprintln!("cartesian f64 worst relative gradient error {worst:e}");
}

#[test]
fn force_is_the_negative_gradient_f32() {
    // f32: h = 1e-2 rad/m, error ≈ ε·V/h + h²·V'''; stated tolerance 2e-3 relative.
    let worst = gradient_check::<f32>(1e-2, 2e-3);
    eprintln!("cartesian f32 worst relative gradient error {worst:e}");
}

/// The reported ė is the total time derivative of e along q(t) = q + t q̇ while the target
/// moves with its twist (velocity feed-forward), for both stiffness frames.
#[test]
fn error_rate_includes_the_desired_twist() {
    let model = branched::<f64>();
    for (seed, stiffness_frame) in
        [(1_u64, StiffnessFrame::World), (2, StiffnessFrame::Desired), (3, StiffnessFrame::Desired)]
    {
        let task = CartesianImpedance::try_new(config::<f64>(TCP, AxisMask::ALL, stiffness_frame)).unwrap();
        let (q, v) = (state(seed, 2.0), state(seed ^ 5, 1.0));
        let mut target = offset_target(&model, TCP, &q, seed);
        target.linear_velocity = Vector3::new(0.3, -0.2, 0.5);
        target.angular_velocity = Vector3::new(-0.4, 0.7, 0.2);
        let at = |t: f64| {
            let moved = CartesianTarget {
                pose: Placement::from_parts(
                    Translation3::from(target.pose.translation.vector + target.linear_velocity * t),
                    Rotation3::from_scaled_axis(target.angular_velocity * t) * target.pose.rotation,
                ),
                ..target
            };
            evaluate(&model, &task, &moved, &(q + v * t), &v).1
        };
        let h = 1e-6;
        let fd = (at(h).error - at(-h).error) / (2.0 * h);
        let rate = at(0.0).error_rate;
        assert!((fd - rate).amax() < 1e-7 * (1.0 + rate.amax()), "{stiffness_frame:?}: {}", (fd - rate).amax());
    }
}

/// Eigenvalues λ of the joint-space linearisation around the equilibrium
/// `M δq̈ + D_q δq̇ + K_q δq = 0` with `K_q = J_xᵀ K J_x` and `D_q` read from the rows'
/// response to unit velocities. The task modes must have ζ = −Re λ/|λ| = ξ; the remaining
/// eigenvalues (null-space motion, no stiffness) are zero.
fn closed_loop_damping_ratios(
    frame: FrameId,
    axes: AxisMask,
    stiffness_frame: StiffnessFrame,
    xi: f64,
) -> std::vec::Vec<f64> {
    let model = branched::<f64>();
    let mut cfg = config::<f64>(frame, axes, stiffness_frame);
    cfg.damping_ratio = xi;
    let task = CartesianImpedance::try_new(cfg).unwrap();
    let q = state(21, 1.5);
    let mut data = Data::new(&model);
    forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
    let target = CartesianTarget::at_rest(data.frame_placements[frame.0]);
    let (rows, report) = evaluate(&model, &task, &target, &q, &SVector::zeros());
    assert_eq!(report.damping_fallback, None);
    assert!(report.error.amax() < 1e-12);
    let selected: std::vec::Vec<usize> = (0..6).filter(|i| axes.contains(*i)).collect();
    let mut k_q = SMatrix::<f64, N, N>::zeros();
    for (a, ra) in rows.rows().iter().enumerate() {
        for (b, rb) in rows.rows().iter().enumerate() {
            k_q += ra.jacobian.transpose() * rb.jacobian * task.stiffness()[(selected[a], selected[b])];
        }
    }
    let mut d_q = SMatrix::<f64, N, N>::zeros();
    for k in 0..N {
        let e = SVector::<f64, N>::from_fn(|r, _| if r == k { 1.0 } else { 0.0 });
        d_q.set_column(k, &(-evaluate(&model, &task, &target, &q, &e).0.torque()));
    }
    crba(&model, &mut data);
    let m_inv = data.mass_matrix.try_inverse().unwrap();
    let mut a = SMatrix::<f64, { 2 * N }, { 2 * N }>::zeros();
    a.fixed_view_mut::<N, N>(0, N).copy_from(&SMatrix::<f64, N, N>::identity());
    a.fixed_view_mut::<N, N>(N, 0).copy_from(&(-m_inv * k_q));
    a.fixed_view_mut::<N, N>(N, N).copy_from(&(-m_inv * d_q));
    let eigenvalues = a.complex_eigenvalues();
    let task_modes: std::vec::Vec<_> = eigenvalues.iter().filter(|l| l.re.hypot(l.im) > 1e-3).collect();
    assert_eq!(task_modes.len(), 2 * selected.len(), "{eigenvalues}");
    task_modes.iter().map(|l| -l.re / l.re.hypot(l.im)).collect()
}

#[test]
fn double_diagonalisation_realises_the_damping_ratio() {
    // TCP and WRIST of the branched model have 4 joints each: select 4 independent axes.
    for (frame, axes, stiffness_frame) in [
        (TCP, AxisMask::new([true, true, true, false, false, true]), StiffnessFrame::World),
        (WRIST, AxisMask::new([true, false, true, true, false, true]), StiffnessFrame::Desired),
    ] {
        for xi in [0.3, 0.7] {
            let ratios = closed_loop_damping_ratios(frame, axes, stiffness_frame, xi);
            let worst = ratios.iter().map(|z| (z - xi).abs()).fold(0.0, f64::max);
            eprintln!("{frame:?} ξ = {xi}: ζ = {ratios:?}, worst deviation {worst:e}");
            assert!(worst < 1e-9, "{ratios:?}");
        }
    }
}

#[test]
fn force_limits_clamp_each_row() {
    let model = branched::<f64>();
    let mut cfg = config::<f64>(TCP, AxisMask::ALL, StiffnessFrame::Desired);
    // Table 7.1, "Wipe the window!": x in (−∞, +10] N; plus ±2 Nm on the rotations.
    cfg.force_upper = Vector6::new(10.0, f64::INFINITY, f64::INFINITY, 2.0, 2.0, 2.0);
    cfg.force_lower = Vector6::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY, -2.0, -2.0, -2.0);
    let task = CartesianImpedance::try_new(cfg).unwrap();
    let mut saturations = 0;
    for seed in 0..20 {
        let (q, v) = (state(seed, 2.0), state(seed ^ 1, 3.0));
        let mut target = offset_target(&model, TCP, &q, seed + 100);
        target.pose.translation.vector += target.pose.rotation * Vector3::new(2.0, 0.0, 0.0); // pulls +x hard
        let (rows, report) = evaluate(&model, &task, &target, &q, &v);
        let selected = rows.rows();
        for (axis, row) in selected.iter().enumerate() {
            // The spring part is clamped, the damping part added unclamped.
            let spring = row.force - report.damping_force[axis];
            assert!(spring <= cfg.force_upper[axis] + 1e-12 && spring >= cfg.force_lower[axis] - 1e-12);
            let raw = report.unsaturated_force[axis];
            assert_eq!(report.saturated[axis], (raw - row.force).abs() > 1e-12);
            saturations += usize::from(report.saturated[axis]);
        }
        let spring_x = selected[0].force - report.damping_force[0];
        assert!(
            report.saturated[0] && (spring_x - 10.0).abs() < 1e-12,
            "x is pulled towards +∞: {}",
            report.unsaturated_force[0]
        );
        assert!(report.damping_force.iter().any(|d| d.abs() > 1e-3), "the state moves: the damping acts");
    }
    assert!(saturations > 40);
}

#[test]
fn singular_mass_matrix_falls_back_to_the_configured_damping() {
    let model = branched::<f64>();
    let task = CartesianImpedance::try_new(config::<f64>(WRIST, AxisMask::TRANSLATION, StiffnessFrame::World)).unwrap();
    let q = state(4, 1.0);
    let v = state(5, 1.0);
    let mut data = Data::new(&model);
    forward_kinematics(&model, &mut data, &q, &v).unwrap(); // no crba: M = 0
    let target = CartesianTarget::at_rest(data.frame_placements[WRIST.0]);
    let mut rows = TaskRows::<f64, N, 6>::new();
    let report = cartesian_impedance(&model, &data, &task, &target, &mut rows).unwrap();
    assert_eq!(report.damping_fallback, Some(DampingFallback::MassMatrixNotPositiveDefinite));
    for (axis, row) in rows.rows().iter().enumerate() {
        assert!((row.force + 10.0 * report.error_rate[axis]).abs() < 1e-12);
    }
}

#[test]
fn dependent_axes_fall_back_to_the_configured_damping() {
    // Six axes on a branch with four joints: Λ⁻¹ has rank 4.
    let model = branched::<f64>();
    let task = CartesianImpedance::try_new(config::<f64>(TCP, AxisMask::ALL, StiffnessFrame::World)).unwrap();
    let (q, v) = (state(6, 1.0), state(7, 1.0));
    let target = offset_target(&model, TCP, &q, 3);
    let (rows, report) = evaluate(&model, &task, &target, &q, &v);
    assert_eq!(report.damping_fallback, Some(DampingFallback::TaskJacobianSingular));
    let spring = task.stiffness() * report.error;
    for (axis, row) in rows.rows().iter().enumerate() {
        assert!((row.force + spring[axis] + 10.0 * report.error_rate[axis]).abs() < 1e-9);
    }
}

#[test]
fn invalid_parameters_and_inputs_are_rejected() {
    let good = config::<f64>(TCP, AxisMask::ALL, StiffnessFrame::World);
    let check = |cfg: CartesianImpedanceConfig<f64>, name| {
        assert_eq!(CartesianImpedance::try_new(cfg), Err(TaskError::InvalidParameter { name }))
    };
    check(
        CartesianImpedanceConfig {
            translational_stiffness: Matrix3::new(1.0, 2.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
            ..good
        },
        "translational_stiffness",
    );
    check(
        CartesianImpedanceConfig {
            rotational_stiffness: Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, 1.0)),
            ..good
        },
        "rotational_stiffness",
    );
    check(CartesianImpedanceConfig { damping_ratio: f64::NAN, ..good }, "damping_ratio");
    check(CartesianImpedanceConfig { force_lower: Vector6::repeat(1.0), ..good }, "force_lower");
    check(CartesianImpedanceConfig { force_upper: Vector6::repeat(f64::NAN), ..good }, "force_upper");
    check(CartesianImpedanceConfig { fallback_damping: Vector6::repeat(-1.0), ..good }, "fallback_damping");

    let model = branched::<f64>();
    let task = CartesianImpedance::try_new(good).unwrap();
    let mut data = Data::new(&model);
    forward_kinematics(&model, &mut data, &state(1, 1.0), &SVector::zeros()).unwrap();
    crba(&model, &mut data);
    let mut rows = TaskRows::<f64, N, 8>::new();
    let mut target = CartesianTarget::at_rest(Placement::identity());
    cartesian_impedance(&model, &data, &task, &target, &mut rows).unwrap();
    assert_eq!(cartesian_impedance(&model, &data, &task, &target, &mut rows), Err(TaskError::Capacity { capacity: 8 }));
    rows.clear();
    target.linear_velocity.x = f64::NAN;
    assert_eq!(cartesian_impedance(&model, &data, &task, &target, &mut rows), Err(TaskError::NonFinite));
    let unknown = CartesianImpedance::try_new(CartesianImpedanceConfig { frame: FrameId(7), ..good }).unwrap();
    assert_eq!(
        cartesian_impedance(&model, &data, &unknown, &CartesianTarget::at_rest(Placement::identity()), &mut rows),
        Err(TaskError::Dynamics(DynamicsError::UnknownFrame))
    );
    assert!(rows.is_empty());
}

/// [`cartesian_impedance_with_jacobian`] with the frame Jacobian of [`frame_jacobian`] gives the
/// rows and report of [`cartesian_impedance_factored`] bit for bit (the controller shares the
/// TCP Jacobians of the contact-force limiter with the Cartesian tasks).
fn shared_jacobian_is_bit_identical<T: RealField + Copy>() {
    let model = branched::<T>();
    for seed in 0..30_u64 {
        let frame = if seed % 2 == 0 { TCP } else { WRIST };
        let stiffness_frame = if seed % 3 == 0 { StiffnessFrame::World } else { StiffnessFrame::Desired };
        let axes = if seed % 4 == 0 { AxisMask::TRANSLATION } else { AxisMask::ALL };
        let task = CartesianImpedance::try_new(config::<T>(frame, axes, stiffness_frame)).unwrap();
        let (q, v): (SVector<T, N>, SVector<T, N>) = (state(seed, 2.0).cast(), state(seed ^ 9, 1.5).cast());
        let target = offset_target(&model, frame, &q, seed ^ 31);
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &q, &v).unwrap();
        crba(&model, &mut data);
        let mut tree = TreeFactorization::new(&model);
        let mass = tree.factorize(&data.mass_matrix).is_ok().then_some(&tree);
        let mut world = SMatrix::<T, 6, N>::zeros();
        frame_jacobian(&model, &data, frame, &mut world).unwrap();
        let (mut own_rows, mut shared_rows) = (TaskRows::<T, N, 6>::new(), TaskRows::<T, N, 6>::new());
        let own = cartesian_impedance_factored(&model, &data, mass, &task, &target, &mut own_rows).unwrap();
        let shared =
            cartesian_impedance_with_jacobian(&model, &data, mass, &task, &target, &world, &mut shared_rows).unwrap();
        assert_eq!(own, shared, "seed {seed}");
        assert_eq!(own_rows.rows(), shared_rows.rows(), "seed {seed}");
        assert_eq!(own_rows.len(), axes.count(), "seed {seed}");
    }
}

#[test]
fn shared_jacobian_is_bit_identical_f64() {
    shared_jacobian_is_bit_identical::<f64>();
}

#[test]
fn shared_jacobian_is_bit_identical_f32() {
    shared_jacobian_is_bit_identical::<f32>();
}
