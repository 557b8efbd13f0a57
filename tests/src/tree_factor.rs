//! The tree-sparse inertia factor `M = Lᵀ L` (`kernel::dynamics::TreeFactorization`) and its
//! consumers against the dense references on the fixtures' models (Justin, the mobile and the
//! planar ones), f64 and f32: the factor, solves, `M⁻¹`, the closed-loop factor decoupled from
//! the factor of `M`, and on Justin the Cartesian damping design, the collision rows' reflected
//! masses (3.20) and the torso workspace rows.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]

use crate::support::Rng;
use fixtures::justin::{self, collision as jc};
use kernel::dynamics::{crba, forward_kinematics, TreeFactorization};
use kernel::model::{Data, Model};
use kernel::platform::storage::{closed_loop_inertia, closed_loop_inertia_into};
use kernel::platform::{PlatformAxis, PlatformLayout};
use kernel::tasks::cartesian_impedance::{
    cartesian_impedance, cartesian_impedance_factored, AxisMask, CartesianImpedance, CartesianImpedanceConfig,
    CartesianTarget, StiffnessFrame,
};
use kernel::tasks::collision::{self_collision_rows, CollisionData, CollisionParameters};
use kernel::tasks::torso_workspace::{
    torso_workspace, RepulsionGains, TorqueLimits, TorsoLoad, TorsoWorkspace, TorsoWorkspaceConfig,
};
use kernel::tasks::TaskRows;
use nalgebra::{convert, try_convert, Cholesky, Matrix3, RealField, SVector, Vector3, Vector6};

fn f64_of<T: RealField + Copy>(x: T) -> f64 {
    try_convert(x).unwrap()
}

/// A state inside the position limits.
fn sample<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    rng: &mut Rng,
) -> SVector<T, N> {
    SVector::from_fn(|i, _| {
        let (lo, hi) = (f64_of(model.limits.position_lower[i]), f64_of(model.limits.position_upper[i]));
        let (lo, hi) = (lo.max(-3.0), hi.min(3.0));
        convert(rng.uniform(lo, hi))
    })
}

/// `LᵀL = M`, `M⁻¹` and the solve against the dense inverse, and the closed-loop factor decoupled
/// from the factor of `M` (coordinates `platform` cleared to new diagonals) against the dense
/// inverse of the closed-loop inertia (`closed_loop_inertia` when a layout is given).
fn factor_matches<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    layout: Option<PlatformLayout>,
    tolerance: f64,
) {
    let mut data = Data::new(model);
    let mut rng = Rng(0x7EE5_FAC7);
    let mut tree = TreeFactorization::new(model);
    for case in 0..30 {
        let q = sample(model, &mut rng);
        forward_kinematics(model, &mut data, &q, &SVector::zeros()).unwrap();
        let m = *crba(model, &mut data);
        tree.factorize(&m).unwrap();
        let m64 = m.map(f64_of);
        let l = tree.lower().map(f64_of);
        let scale = m64.amax();
        assert!((l.transpose() * l - m64).amax() <= tolerance * scale, "case {case}: LᵀL");
        let dense_inverse = m64.try_inverse().unwrap();
        let inverse_scale = dense_inverse.amax();
        let inverse = tree.inverse().map(f64_of);
        assert!((inverse - dense_inverse).amax() <= 1e3 * tolerance * inverse_scale, "case {case}: M⁻¹");
        // In place over a stale matrix: every entry overwritten, the same bits as `inverse`.
        let mut in_place = nalgebra::SMatrix::<T, N, N>::from_element(T::one() / T::zero());
        tree.inverse_into(&mut in_place);
        assert_eq!(in_place, tree.inverse(), "case {case}: inverse_into");
        let b = SVector::<f64, N>::from_fn(|_, _| rng.uniform(-5.0, 5.0));
        let mut x = b.map(convert::<f64, T>);
        tree.solve_mut(&mut x);
        let reference = dense_inverse * b;
        assert!((x.map(f64_of) - reference).amax() <= 1e3 * tolerance * (1.0 + reference.amax()), "case {case}");
        let Some(layout) = layout else { continue };
        let closed = closed_loop_inertia(&m, &layout, &Vector3::new(convert(0.8), convert(1.5), convert(0.3)));
        let mut closed_in_place = nalgebra::SMatrix::<T, N, N>::from_element(T::one() / T::zero());
        let admittance = Vector3::new(convert(0.8), convert(1.5), convert(0.3));
        closed_loop_inertia_into(&m, &layout, &admittance, &mut closed_in_place);
        assert_eq!(closed_in_place, closed, "case {case}: closed_loop_inertia_into");
        let mut decoupled = [false; N];
        for c in layout.axes().iter().filter_map(|a| a.coordinate()) {
            decoupled[c] = true;
        }
        let mut closed_tree = tree.clone();
        closed_tree.decouple(&decoupled, &closed).unwrap();
        let mut refactored = TreeFactorization::new(model);
        refactored.factorize(&closed).unwrap();
        assert_eq!(closed_tree.lower(), refactored.lower(), "case {case}: decoupled = refactored");
        let dense = closed.map(f64_of).try_inverse().unwrap();
        let error = (closed_tree.inverse().map(f64_of) - dense).amax();
        assert!(error <= 1e3 * tolerance * dense.amax(), "case {case}: closed-loop M⁻¹ {error:e}");
    }
}

#[test]
fn tree_factor_matches_dense_on_the_fixture_models() {
    let justin_layout = PlatformLayout::try_new::<{ justin::N }>([
        PlatformAxis::Admitted(0),
        PlatformAxis::Admitted(1),
        PlatformAxis::Locked(2),
    ])
    .unwrap();
    factor_matches(&justin::model::<f64>().unwrap(), Some(justin_layout), 1e-12);
    factor_matches(&justin::model::<f32>().unwrap(), Some(justin_layout), 1e-5);
    let mobile_layout =
        PlatformLayout::try_new::<3>([PlatformAxis::Admitted(0), PlatformAxis::Absent, PlatformAxis::Absent]).unwrap();
    factor_matches(&fixtures::mobile::three_dof::<f64>().unwrap(), Some(mobile_layout), 1e-12);
    factor_matches(&fixtures::mobile::three_dof::<f32>().unwrap(), Some(mobile_layout), 1e-5);
    factor_matches(&fixtures::planar::four_dof::<f64>().unwrap(), None, 1e-12);
    factor_matches(&fixtures::planar::four_dof::<f32>().unwrap(), None, 1e-5);
    factor_matches(&fixtures::planar::three_dof::<f64>().unwrap(), None, 1e-12);
    factor_matches(&fixtures::planar::three_dof::<f32>().unwrap(), None, 1e-5);
}

/// Justin: the Cartesian damping design on the tree factor of `M` against the task's dense
/// design, the collision rows and the torso rows on the tree factor against the dense Cholesky
/// factor, at random states and velocities.
fn justin_consumers_match<T: RealField + Copy>(tolerance: f64) {
    let model = justin::model::<T>().unwrap();
    let collision = jc::collision_model(&model).unwrap();
    let mut cd = CollisionData::new(&collision);
    let mut data = Data::new(&model);
    let mut tree = TreeFactorization::new(&model);
    let mut rng = Rng(0x0A57_1A11);
    let parameters =
        CollisionParameters::try_new(convert(150.0), convert(0.3), convert(0.7), convert(0.0), convert(0.4)).unwrap();
    let (mut cartesian_compared, mut collision_rows, mut torso_rows) = (0, 0, 0);
    for case in 0..40 {
        let q = sample(&model, &mut rng);
        let v = SVector::<T, { justin::N }>::from_fn(|_, _| convert(rng.uniform(-1.0, 1.0)));
        forward_kinematics(&model, &mut data, &q, &v).unwrap();
        crba(&model, &mut data);
        tree.factorize(&data.mass_matrix).unwrap();
        let dense = Cholesky::new(data.mass_matrix).unwrap();
        // Cartesian impedance on both TCPs.
        for frame in [justin::RIGHT_TCP, justin::LEFT_TCP] {
            let task = CartesianImpedance::try_new(CartesianImpedanceConfig {
                frame,
                axes: if case % 3 == 0 { AxisMask::TRANSLATION } else { AxisMask::ALL },
                stiffness_frame: StiffnessFrame::World,
                translational_stiffness: Matrix3::from_diagonal(&Vector3::new(800.0, 500.0, 300.0)).map(convert),
                rotational_stiffness: Matrix3::from_diagonal(&Vector3::new(60.0, 40.0, 30.0)).map(convert),
                damping_ratio: convert(0.7),
                force_lower: Vector6::repeat(convert(f64::NEG_INFINITY)),
                force_upper: Vector6::repeat(convert(f64::INFINITY)),
                fallback_damping: Vector6::repeat(convert(10.0)),
            })
            .unwrap();
            let mut pose = data.frame_placements[frame.0];
            pose.translation.vector += Vector3::new(convert(0.05), convert(-0.03), convert(0.02));
            let target = CartesianTarget::at_rest(pose);
            let (mut a, mut b) = (TaskRows::<T, { justin::N }, 6>::new(), TaskRows::<T, { justin::N }, 6>::new());
            let fast = cartesian_impedance_factored(&model, &data, Some(&tree), &task, &target, &mut a).unwrap();
            let reference = cartesian_impedance(&model, &data, &task, &target, &mut b).unwrap();
            assert_eq!(fast.damping_fallback, reference.damping_fallback, "case {case}");
            let scale = f64_of(reference.damping_force.amax()) + 1.0;
            let error = f64_of((fast.damping_force - reference.damping_force).amax()) / scale;
            assert!(error <= tolerance, "case {case}: Cartesian damping {error:e}");
            for (x, y) in a.rows().iter().zip(b.rows()) {
                assert!(f64_of((x.force - y.force).abs()) / (f64_of(y.force.abs()) + 1.0) <= tolerance, "case {case}");
            }
            cartesian_compared += 1;
        }
        // Collision rows (reflected masses (3.20)).
        let (mut a, mut b) = (TaskRows::<T, { justin::N }, 24>::new(), TaskRows::<T, { justin::N }, 24>::new());
        let ra = self_collision_rows(&collision, &mut cd, &model, &data, &tree, &parameters, &mut a).unwrap();
        let rb = self_collision_rows(&collision, &mut cd, &model, &data, &dense, &parameters, &mut b).unwrap();
        assert_eq!(ra, rb, "case {case}");
        for (x, y) in a.rows().iter().zip(b.rows()) {
            assert_eq!(x.jacobian, y.jacobian);
            let error = f64_of((x.force - y.force).abs()) / (f64_of(y.force.abs()) + 1.0);
            assert!(error <= tolerance, "case {case}: collision row {error:e}");
        }
        collision_rows += a.len();
        // Torso workspace rows (the 2 × 2 block of M⁻¹), at a torso state near its limits.
        let torso = TorsoWorkspace::<T, { justin::N }>::try_new(TorsoWorkspaceConfig {
            geometry: justin::torso_geometry(),
            torque_limits: TorqueLimits::symmetric(convert(230.0)),
            load: TorsoLoad::from_degrees(convert(rng.uniform(300.0, 900.0)), convert(rng.uniform(0.0, 360.0))),
            gains: RepulsionGains::thesis_experiment(),
            coordinates: [justin::TORSO_COORDINATES.start + 1, justin::TORSO_COORDINATES.start + 2],
        })
        .unwrap();
        let (mut a, mut b) = (TaskRows::<T, { justin::N }, 12>::new(), TaskRows::<T, { justin::N }, 12>::new());
        let ra = torso_workspace(&torso, &data.q, &data.v, &tree, &mut a).unwrap();
        let rb = torso_workspace(&torso, &data.q, &data.v, &dense, &mut b).unwrap();
        assert_eq!(ra, rb, "case {case}");
        for (x, y) in a.rows().iter().zip(b.rows()) {
            let error = f64_of((x.force - y.force).abs()) / (f64_of(y.force.abs()) + 1.0);
            assert!(error <= tolerance, "case {case}: torso row {error:e}");
            torso_rows += usize::from(y.force != T::zero());
        }
    }
    assert_eq!(cartesian_compared, 80);
    assert!(collision_rows > 20, "collision rows compared: {collision_rows}");
    assert!(torso_rows > 0, "torso rows with force: {torso_rows}");
}

#[test]
fn justin_consumers_on_the_tree_factor_match_the_dense_reference_f64() {
    justin_consumers_match::<f64>(1e-9);
}

#[test]
fn justin_consumers_on_the_tree_factor_match_the_dense_reference_f32() {
    justin_consumers_match::<f32>(2e-3);
}

/// Justin, the speed barrier's two sources of the closed-loop `M̃⁻¹`
/// (`kernel::controller::speed_barrier::InverseInertia`): the dense inverse of the decoupled
/// tree factor (what the step forms for the projection) against the factor itself (chain
/// mobilities and solves), at random states: the mobilities `(M̃⁻¹)_ii` (also against the plain
/// dense inverse), `M̃⁻¹ τ` of an upper-body torque, and the barrier torques of every upper-body
/// joint between its onset and past its speed limit. `tolerance` bounds the two sources
/// against each other, `accuracy` the factor against the plain `f64` inverse of the same matrix
/// (both relative to `max|M̃⁻¹|`): the latter is the factor's own rounding on matrices with
/// `κ₁(M̃) ≈ 10⁴`, whose backward-error bound `ε κ₁` (Higham, Sec. 10.1) is ≈ 1.3e-3 in `f32`;
/// observed at most 1.02e-5 in `f32`.
fn justin_barrier_inverse_matches<T: RealField + Copy>(tolerance: f64, accuracy: f64) {
    use kernel::controller::speed_barrier::{
        speed_barrier, BarrierHold, InverseInertia, JointLimits, SpeedBarrierParameters,
    };
    const N: usize = justin::N;
    let model = justin::model::<T>().unwrap();
    let layout =
        PlatformLayout::try_new::<N>([PlatformAxis::Admitted(0), PlatformAxis::Admitted(1), PlatformAxis::Locked(2)])
            .unwrap();
    let mut decoupled = [false; N];
    for c in layout.axes().iter().filter_map(|a| a.coordinate()) {
        decoupled[c] = true;
    }
    let upper = decoupled.map(|d| !d);
    let parameters = SpeedBarrierParameters {
        onset: convert(0.5),
        full: convert(0.9),
        braking_time_s: convert(0.002),
        max_torque_fraction: convert(0.25),
    };
    let mut data = Data::new(&model);
    let mut tree = TreeFactorization::new(&model);
    let mut rng = Rng(0xBA44_1E57);
    for case in 0..30 {
        let q = sample(&model, &mut rng);
        forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
        let m = *crba(&model, &mut data);
        tree.factorize(&m).unwrap();
        let closed = closed_loop_inertia(&m, &layout, &Vector3::new(convert(0.8), convert(1.5), convert(0.3)));
        tree.decouple(&decoupled, &closed).unwrap();
        let inverse = tree.inverse();
        let (dense, factor) = (InverseInertia::Dense(&inverse), InverseInertia::Factor(&tree));
        let plain = closed.map(f64_of).try_inverse().unwrap();
        let scale = plain.amax();
        for i in 0..N {
            let (fast, reference) = (f64_of(dense.mobility(i)), f64_of(factor.mobility(i)));
            assert!((fast - reference).abs() <= tolerance * scale, "case {case}, joint {i}: {fast} vs {reference}");
            assert!((reference - plain[(i, i)]).abs() <= accuracy * scale, "case {case}, joint {i}");
        }
        let torque = SVector::<f64, N>::from_fn(|i, _| if upper[i] { rng.uniform(-50.0, 50.0) } else { 0.0 });
        let (fast, reference) = (dense.apply(&torque.map(convert)), factor.apply(&torque.map(convert)));
        let (fast, reference) = (fast.map(f64_of), reference.map(f64_of));
        let bound = tolerance * scale * 50.0 * N as f64;
        assert!((fast - reference).amax() <= bound, "case {case}: M̃⁻¹ τ");
        assert!((reference - plain * torque).amax() <= bound, "case {case}: M̃⁻¹ τ against the plain inverse");
        // Every upper-body joint at 0.6 to 1.2 times its speed limit.
        let v = SVector::<T, N>::from_fn(|i, _| {
            let sign = if rng.uniform(-1.0, 1.0) < 0.0 { -1.0 } else { 1.0 };
            convert(sign * rng.uniform(0.6, 1.2) * f64_of(model.limits.velocity[i]))
        });
        let limits = JointLimits { speed: &model.limits.velocity, effort: &model.limits.effort };
        let task = torque.map(convert::<f64, T>);
        let barrier = |source: InverseInertia<'_, T, N>| {
            let drive = |t: &SVector<T, N>| source.apply(&(task + t));
            speed_barrier(&parameters, &v, limits, |i| source.mobility(i), drive, &upper, &mut BarrierHold::new())
                .map(f64_of)
        };
        let (fast, reference) = (barrier(dense), barrier(factor));
        let effort = model.limits.effort.map(f64_of).amax();
        assert!(reference.amax() > 0.0, "case {case}: the barrier acts");
        let error = (fast - reference).amax();
        assert!(error <= 10.0 * tolerance * effort, "case {case}: barrier torques differ by {error:e}");
    }
}

#[test]
fn justin_speed_barrier_dense_inverse_matches_the_factor() {
    justin_barrier_inverse_matches::<f64>(1e-12, 1e-12);
    justin_barrier_inverse_matches::<f32>(1e-5, 2e-5);
}
