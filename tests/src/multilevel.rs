//! Multi-objective compliance control (Sec. 5.2, (5.40)–(5.68)): properties of the hierarchical
//! dynamics representation on random states of the Justin-like robot (20 DOF) and the planar
//! 4-DOF arm, the exactness of the time derivative `Ż`, the 7-DOF arm model, and the
//! scenarios `multilevel_sim1` … `multilevel_sim3` and `multilevel_arm` against the thesis'
//! claims.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    reason = "test code: a failure is a test failure"
)]

use fixtures::{justin, planar};
use host_sim::scenarios::{multilevel_arm, multilevel_sim1, multilevel_sim2, multilevel_sim3, RunOptions};
use kernel::dynamics::{coriolis_matrix, crba, forward_kinematics, frame_jacobian, frame_jacobian_derivative, gravity};
use kernel::hierarchy::multilevel::{
    coriolis_decoupling, decompose, task_space_coriolis, ComplianceRow, ComplianceStack, Decomposition, DynamicsTerms,
    MultilevelConfig,
};
use kernel::hierarchy::{project, HierarchyConfig, HierarchyData, Recursion, Shaping, Stack, Weighting};
use kernel::math::CholeskyFactor;
use kernel::model::{FrameId, Model};
use kernel::tasks::cartesian_impedance::{
    cartesian_impedance, AxisMask, CartesianImpedance, CartesianImpedanceConfig, CartesianTarget, StiffnessFrame,
};
use kernel::tasks::{TaskRow, TaskRows};
use kernel::Data;
use nalgebra::{Cholesky, Matrix3, RowSVector, SMatrix, SVector, Vector6};
use proptest::prelude::*;

/// One task level: rows `rows` of the 6×N Jacobian of `frame` (linear rows first).
struct Task {
    frame: FrameId,
    rows: &'static [usize],
}

/// Model terms, decomposition inputs and the decomposition at one state.
struct State<const N: usize> {
    mass: SMatrix<f64, N, N>,
    factor: CholeskyFactor<f64, N>,
    coriolis: SMatrix<f64, N, N>,
    gravity: SVector<f64, N>,
    velocity: SVector<f64, N>,
    stack: ComplianceStack<f64, N, 48>,
    out: Decomposition<f64, N, 8>,
}

impl<const N: usize> State<N> {
    fn terms(&self) -> DynamicsTerms<'_, f64, N> {
        DynamicsTerms {
            mass_matrix: &self.mass,
            mass_factor: &self.factor,
            coriolis: &self.coriolis,
            gravity: &self.gravity,
            velocity: &self.velocity,
        }
    }
}

/// The tasks on levels `0 … tasks.len() − 1`, a joint impedance on every coordinate as the last
/// level; forces are arbitrary (they do not enter the decomposition).
fn state<const N: usize, const B: usize, const F: usize>(
    model: &Model<f64, N, B, F>,
    tasks: &[Task],
    q: &SVector<f64, N>,
    v: &SVector<f64, N>,
) -> Option<State<N>> {
    let mut data = Data::new(model);
    forward_kinematics(model, &mut data, q, v).unwrap();
    let mass = *crba(model, &mut data);
    let coriolis = *coriolis_matrix(model, &mut data);
    let gravity = *gravity(model, &mut data);
    let factor = Cholesky::new(mass).unwrap();
    let mut stack = ComplianceStack::new();
    for (level, task) in tasks.iter().enumerate() {
        let (mut j, mut rate) = (SMatrix::<f64, 6, N>::zeros(), SMatrix::<f64, 6, N>::zeros());
        frame_jacobian(model, &data, task.frame, &mut j).unwrap();
        frame_jacobian_derivative(model, &data, task.frame, v, &mut rate).unwrap();
        for (k, &r) in task.rows.iter().enumerate() {
            let row = ComplianceRow {
                jacobian: j.row(r).into_owned(),
                jacobian_rate: rate.row(r).into_owned(),
                stiffness_force: 3.0 * (k as f64 + 1.0),
                damping_force: -1.0,
                potential: 0.5,
            };
            stack.push(level, row).unwrap();
        }
    }
    for k in 0..N {
        let row = ComplianceRow {
            jacobian: RowSVector::from_fn(|_, c| f64::from(u8::from(c == k))),
            jacobian_rate: RowSVector::zeros(),
            stiffness_force: (k as f64 * 0.7).sin(),
            damping_force: 0.2,
            potential: 0.1,
        };
        stack.push(tasks.len(), row).unwrap();
    }
    let mut out = Decomposition::default();
    // A random state may be singular for the hierarchy: skip it (the caller counts).
    decompose(
        &MultilevelConfig::default(),
        &stack,
        &DynamicsTerms {
            mass_matrix: &mass,
            mass_factor: &factor,
            coriolis: &coriolis,
            gravity: &gravity,
            velocity: v,
        },
        &mut out,
    )
    .ok()?;
    Some(State { mass, factor, coriolis, gravity, velocity: *v, stack, out })
}

/// The properties asked by Sec. 5.2: `J̄ J̄⁻¹ = I` (5.52), block-diagonal `Λ` (5.55), (5.50)
/// `J̄_iᵀ Z_i J_iᵀ = N_i J_iᵀ`, skew couplings `μ_ij = −μ_jiᵀ`, zero power `τ_μᵀ q̇`.
fn check_properties<const N: usize>(s: &State<N>) -> Result<(), TestCaseError> {
    let (z, jbar) = (s.out.basis(), s.out.extended_jacobian());
    let identity = SMatrix::<f64, N, N>::identity();
    prop_assert!(
        (jbar * z.transpose() - identity).amax() < 1e-9,
        "J̄ Zᵀ − I = {}",
        (jbar * z.transpose() - identity).amax()
    );
    prop_assert!((z.transpose() * jbar - identity).amax() < 1e-9);
    let lambda = z * s.mass * z.transpose();
    let mu = task_space_coriolis(&s.out, &s.terms());
    let (mut lambda_off, mut mu_off) = (lambda, mu);
    for span in s.out.levels() {
        lambda_off.view_mut((span.start, span.start), (span.len, span.len)).fill(0.0);
        mu_off.view_mut((span.start, span.start), (span.len, span.len)).fill(0.0);
    }
    prop_assert!(lambda_off.amax() <= 1e-9 * lambda.amax(), "off-diagonal blocks of Λ: {}", lambda_off.amax());
    let skew = (mu_off + mu_off.transpose()).amax();
    prop_assert!(skew <= 1e-9 * (1.0 + mu.amax()), "μ_ij + μ_jiᵀ = {skew}");
    let tau = coriolis_decoupling(&s.out, &s.terms());
    let power = tau.dot(&s.velocity);
    prop_assert!(power.abs() <= 1e-9 * (1.0 + tau.norm() * s.velocity.norm()), "τ_μᵀ q̇ = {power}");

    for level in 0..s.out.level_count() {
        let mut above = Stack::<f64, N, 48>::new();
        for (l, row) in s.stack.rows().iter().filter(|(l, _)| *l < level) {
            above.push(*l, TaskRow { jacobian: row.jacobian, force: 0.0, potential: 0.0, activation: 1.0 }).unwrap();
        }
        let config = HierarchyConfig {
            recursion: Recursion::Augmented,
            weighting: Weighting::Inertia(&s.factor),
            shaping: Shaping::Continuous { singular_full: 1e-7, singular_start: 2e-7 },
            diagnose_last_level: true,
        };
        let mut data = HierarchyData::<f64, N, 48, 8>::default();
        project(&config, &above, &mut data).unwrap();
        let map: SMatrix<f64, N, N> = s.out.level_rows(level).iter().map(|r| r.jacobian.transpose() * r.basis).sum();
        for row in s.stack.level(level) {
            let jt = row.jacobian.transpose();
            let error = (map * jt - data.projector * jt).amax();
            prop_assert!(error <= 1e-9 * (1.0 + jt.amax()), "(5.50) level {level}: {error}");
        }
    }
    Ok(())
}

const JUSTIN_TASKS: [Task; 3] = [
    Task { frame: justin::RIGHT_TCP, rows: &[0, 1, 2] },
    Task { frame: justin::RIGHT_TCP, rows: &[3, 4, 5] },
    Task { frame: justin::LEFT_TCP, rows: &[0, 1, 2, 3, 4, 5] },
];
const PLANAR_TASKS: [Task; 2] =
    [Task { frame: planar::PLANAR4_TCP, rows: &[0, 1] }, Task { frame: planar::PLANAR4_TCP, rows: &[5] }];

fn vector<const N: usize>(range: f64) -> impl Strategy<Value = SVector<f64, N>> {
    proptest::collection::vec(-range..range, N).prop_map(|x| SVector::from_column_slice(&x))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Justin: right TCP translation, right TCP rotation, left TCP pose, all 20 joints (an
    /// 8-dimensional last level), around the home configuration.
    #[test]
    fn justin_hierarchy_properties(dq in vector::<{ justin::N }>(0.4), v in vector::<{ justin::N }>(1.0)) {
        let model = justin::model::<f64>().unwrap();
        let q = justin::home_configuration::<f64>() + dq;
        if let Some(s) = state(&model, &JUSTIN_TASKS, &q, &v) {
            prop_assert_eq!(s.out.levels().iter().map(|l| l.len).collect::<Vec<_>>(), vec![3, 3, 6, 8]);
            check_properties(&s)?;
        }
    }

    /// The planar arm with the Table 5.4 hierarchy (x, y; Σq (the rotation row); q₁ → the last,
    /// one-dimensional level).
    #[test]
    fn planar_hierarchy_properties(q in vector::<4>(2.5), v in vector::<4>(3.0)) {
        let model = planar::four_dof::<f64>().unwrap();
        if let Some(s) = state(&model, &PLANAR_TASKS, &q, &v) {
            check_properties(&s)?;
        }
    }
}

/// Most random states are regular: the properties are not checked on an empty set.
#[test]
fn random_states_are_mostly_regular() {
    let model = justin::model::<f64>().unwrap();
    let regular = (0..20)
        .filter(|k| {
            let dq = SVector::<f64, { justin::N }>::from_fn(|i, _| 0.4 * ((i * 7 + k * 13) as f64).sin());
            state(&model, &JUSTIN_TASKS, &(justin::home_configuration() + dq), &SVector::repeat(0.5)).is_some()
        })
        .count();
    assert!(regular >= 18, "{regular} of 20");
}

/// `Ż` from the forward-mode recursion against a central difference of `Z` along the motion on
/// Justin (20 DOF, 12 task rows + 8 null space rows); prints the measured error.
#[test]
fn basis_rate_is_the_derivative_along_the_motion() {
    let model = justin::model::<f64>().unwrap();
    let (mut worst_z, mut worst_jbar): (f64, f64) = (0.0, 0.0);
    let h = 1e-6;
    for k in 0..10 {
        let dq = SVector::<f64, { justin::N }>::from_fn(|i, _| 0.3 * ((i * 5 + k * 11) as f64).cos());
        let v = SVector::<f64, { justin::N }>::from_fn(|i, _| 0.8 * ((i * 3 + k * 7) as f64).sin());
        let q = justin::home_configuration() + dq;
        let s = state(&model, &JUSTIN_TASKS, &q, &v).unwrap();
        let (plus, minus) = (
            state(&model, &JUSTIN_TASKS, &(q + v * h), &v).unwrap(),
            state(&model, &JUSTIN_TASKS, &(q - v * h), &v).unwrap(),
        );
        let fd = (plus.out.basis() - minus.out.basis()) / (2.0 * h);
        let rate = s.out.basis_rate();
        let scale = 1.0 + rate.amax();
        // The pivot choice of the last level is the same at q ± h q̇ (else the basis jumps).
        assert!((plus.out.basis() - minus.out.basis()).amax() < 1e-3, "pivot switched");
        worst_z = worst_z.max((fd - rate).amax() / scale);
        let jbar = s.out.extended_jacobian();
        let analytic = -jbar * rate.transpose() * jbar;
        let fd_jbar = (plus.out.extended_jacobian() - minus.out.extended_jacobian()) / (2.0 * h);
        worst_jbar = worst_jbar.max((fd_jbar - analytic).amax() / (1.0 + fd_jbar.amax()));
    }
    println!("Ż vs central difference (h = 1e-6): max relative error {worst_z:.2e}; J̄̇ = −J̄ Żᵀ J̄: {worst_jbar:.2e}");
    assert!(worst_z < 1e-6 && worst_jbar < 1e-6, "Ż error {worst_z}, J̄̇ error {worst_jbar}");
}

/// The rate of the quaternion rotation rows of the Cartesian task against a central difference.
#[test]
fn rotation_row_rates_match_a_central_difference() {
    let (model, tcp) = multilevel_arm::right_arm_model().unwrap();
    let task = CartesianImpedance::try_new(CartesianImpedanceConfig {
        frame: tcp,
        axes: AxisMask::ROTATION,
        stiffness_frame: StiffnessFrame::World,
        translational_stiffness: Matrix3::zeros(),
        rotational_stiffness: Matrix3::identity() * 30.0,
        damping_ratio: 0.0,
        force_lower: Vector6::repeat(f64::NEG_INFINITY),
        force_upper: Vector6::repeat(f64::INFINITY),
        fallback_damping: Vector6::zeros(),
    })
    .unwrap();
    let mut data = Data::new(&model);
    let q0 = multilevel_arm::arm_home();
    forward_kinematics(&model, &mut data, &q0, &SVector::zeros()).unwrap();
    let target = CartesianTarget::at_rest(multilevel_arm::stepped_target(&data.frame_placements[tcp.0]));
    let rows_at = |q: &SVector<f64, 7>| -> SMatrix<f64, 3, 7> {
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, q, &SVector::zeros()).unwrap();
        crba(&model, &mut data);
        let mut rows = TaskRows::<f64, 7, 3>::new();
        cartesian_impedance(&model, &data, &task, &target, &mut rows).unwrap();
        SMatrix::from_fn(|r, c| rows.rows()[r].jacobian[c])
    };
    for k in 0..5 {
        let q = q0 + SVector::<f64, 7>::from_fn(|i, _| 0.2 * ((i + 3 * k) as f64).sin());
        let v = SVector::<f64, 7>::from_fn(|i, _| ((2 * i + k) as f64).cos());
        forward_kinematics(&model, &mut data, &q, &v).unwrap();
        let (mut j, mut j_rate) = (SMatrix::<f64, 6, 7>::zeros(), SMatrix::<f64, 6, 7>::zeros());
        frame_jacobian(&model, &data, tcp, &mut j).unwrap();
        frame_jacobian_derivative(&model, &data, tcp, &v, &mut j_rate).unwrap();
        let rates = multilevel_arm::rotation_row_rates(
            data.frame_placements[tcp.0].rotation.matrix(),
            target.pose.rotation.matrix(),
            &j,
            &j_rate,
            &v,
        );
        let h = 1e-6;
        let fd = (rows_at(&(q + v * h)) - rows_at(&(q - v * h))) / (2.0 * h);
        assert!((fd - rates).amax() < 1e-7 * (1.0 + fd.amax()), "case {k}: {}", (fd - rates).amax());
    }
}

/// The 7-DOF arm is the right-arm block of the 20-DOF robot with the rest frozen at home.
#[test]
fn right_arm_model_is_the_frozen_block_of_the_robot() {
    let (arm, tcp) = multilevel_arm::right_arm_model().unwrap();
    let robot = justin::model::<f64>().unwrap();
    let (mut arm_data, mut robot_data) = (Data::new(&arm), Data::new(&robot));
    let block = justin::RIGHT_ARM_COORDINATES;
    for k in 0..5 {
        let qa = multilevel_arm::arm_home() + SVector::<f64, 7>::from_fn(|i, _| 0.3 * ((i * 2 + k) as f64).sin());
        let mut q = justin::home_configuration::<f64>();
        q.rows_mut(block.start, 7).copy_from(&qa);
        forward_kinematics(&arm, &mut arm_data, &qa, &SVector::zeros()).unwrap();
        forward_kinematics(&robot, &mut robot_data, &q, &SVector::zeros()).unwrap();
        let m = *crba(&robot, &mut robot_data);
        assert!((crba(&arm, &mut arm_data) - m.view((block.start, block.start), (7, 7))).amax() < 1e-12);
        let g = *gravity(&robot, &mut robot_data);
        assert!((gravity(&arm, &mut arm_data) - g.rows(block.start, 7)).amax() < 1e-10);
        let (a, b) = (arm_data.frame_placements[tcp.0], robot_data.frame_placements[justin::RIGHT_TCP.0]);
        assert!((a.translation.vector - b.translation.vector).amax() < 1e-12);
        assert!((a.rotation.matrix() - b.rotation.matrix()).amax() < 1e-12);
    }
    assert_eq!(arm.limits.effort.as_slice(), &robot.limits.effort.as_slice()[block]);
}

fn columns_present(series: &host_sim::output::TimeSeries, names: &[&str]) {
    for name in names {
        assert!(series.column(name).is_some(), "missing column {name}");
    }
}

#[test]
fn simulation_1_converges_within_half_a_second_with_a_strict_hierarchy() {
    let outcome = multilevel_sim1::simulate(&RunOptions::default()).unwrap();
    let s = &outcome.summary;
    assert!(s.failed_claims().is_empty(), "{:?}", s.failed_claims());
    assert!(s.get("settle_time_max_s").unwrap() < 0.5);
    assert!(s.get("cross_acceleration_max").unwrap() < 1e-9);
    columns_present(&outcome.series, &["e1.x", "e1.y", "e2.rot", "e3.q1", "S1", "S2", "S3"]);
    // Table 5.4: initial errors (x − x_des) = (−0.06, 0.16) m, 0.2 rad, 0.05 rad.
    let first = |c: &str| outcome.series.column(c).unwrap()[0];
    assert!((first("e1.x") + 0.06).abs() < 1e-12 && (first("e1.y") - 0.16).abs() < 1e-12);
    assert!((first("e2.rot") - 0.2).abs() < 1e-12 && (first("e3.q1") - 0.05).abs() < 1e-12);
}

#[test]
fn simulation_2_energies_converge_in_priority_order() {
    let outcome = multilevel_sim2::simulate(&RunOptions::default()).unwrap();
    let s = &outcome.summary;
    assert!(s.failed_claims().is_empty(), "{:?}", s.failed_claims());
    let (t1, t2, t3) = (
        s.get("s1_almost_zero_time_s").unwrap(),
        s.get("s2_almost_zero_time_s").unwrap(),
        s.get("s3_almost_zero_time_s").unwrap(),
    );
    assert!(t1 < 0.3 && t1 < t2 && t2 < t3, "{t1} {t2} {t3}");
    // Initial potentials of THESIS-NUMBERS §5.2: 7.3 J, 12 J, 0.75 J.
    let first = |c: &str| outcome.series.column(c).unwrap()[0];
    assert!((first("S1") - 7.3).abs() < 1e-9 && (first("S2") - 12.0).abs() < 1e-9 && (first("S3") - 0.75).abs() < 1e-9);
    // The model-based rate (5.65) is the derivative of the sampled storage functions.
    for level in 1..=3 {
        assert!(s.get(&format!("sdot{level}_model_vs_numeric_rel")).unwrap() < 0.05);
    }
}

#[test]
fn simulation_3_is_robust_to_the_wrong_inertia() {
    let outcome = multilevel_sim3::simulate(&RunOptions::default()).unwrap();
    let s = &outcome.summary;
    assert!(s.failed_claims().is_empty(), "{:?}", s.failed_claims());
    assert!(s.get("deviation_from_sim2_max_rel").unwrap() < 0.25);
    // Fig. 5.19: about ±6 m/s² (level 1) and ±1.5 rad/s² (level 2) from the level-3 torque.
    let (a1, a2) = (s.get("max_acc_level1_by_level3_mps2").unwrap(), s.get("max_acc_level2_by_level3_radps2").unwrap());
    assert!((2.0..12.0).contains(&a1) && (0.5..3.0).contains(&a2), "{a1} m/s², {a2} rad/s²");
}

#[test]
fn arm_experiment_reaches_a_constrained_minimum_and_tau_mu_is_small() {
    let outcome = multilevel_arm::simulate(&RunOptions::default()).unwrap();
    let s = &outcome.summary;
    assert!(s.failed_claims().is_empty(), "{:?}", s.failed_claims());
    assert!(s.get("tau_mu_over_tau1p").unwrap() < 0.2);
    assert!(s.get("v3_final_j").unwrap() > 0.1);
    columns_present(&outcome.series, &["S1", "S2", "S3", "Sdot1", "e1.norm", "e2.angle", "e3.norm", "tau_mu.1"]);
}
