//! Torso workspace (Sec. 3.3, App. A) on the Justin-like robot: the repulsion rows are the
//! negative gradient of their potential at random torso states of the full 20-DOF model, the
//! torso plane of the task is the one of the robot model, and the `torso_workspace` scenario
//! reproduces the claims of Fig. 3.16.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    reason = "test code: a failure is a test failure"
)]

use fixtures::justin;
use host_sim::scenarios::{torso_workspace as scenario, RunOptions};
use kernel::dynamics::{crba, forward_kinematics, mass_matrix_cholesky};
use kernel::tasks::torso_workspace::{
    torso_workspace, RepulsionGains, TorqueLimits, TorsoLoad, TorsoWorkspace, TorsoWorkspaceConfig, BOUNDARIES,
};
use kernel::tasks::TaskRows;
use kernel::Data;
use nalgebra::{RealField, SVector, Vector3};

const N: usize = justin::N;

fn task<T: RealField + Copy>(force: f64, angle_deg: f64) -> TorsoWorkspace<T, N> {
    TorsoWorkspace::try_new(TorsoWorkspaceConfig {
        geometry: justin::torso_geometry(),
        torque_limits: TorqueLimits::symmetric(230.0),
        load: TorsoLoad::from_degrees(force, angle_deg),
        gains: RepulsionGains::thesis_experiment(),
        coordinates: [justin::TORSO_COORDINATES.start + 1, justin::TORSO_COORDINATES.start + 2],
    })
    .unwrap()
}

/// Deterministic uniform numbers in [0, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1_u64 << 53) as f64
    }
}

/// Home pose with a random torso inside Table 3.2 (and random yaw q_t1, base pose).
fn random_state(rng: &mut Lcg) -> SVector<f64, N> {
    let g = justin::torso_geometry::<f64>();
    let mut q = justin::home_configuration::<f64>();
    loop {
        let q2 = g.joint2.min + (g.joint2.max - g.joint2.min) * rng.next();
        let q3 = g.joint3.min + (g.joint3.max - g.joint3.min) * rng.next();
        if g.contains(q2, q3) {
            q[0] = rng.next() - 0.5;
            q[2] = 6.0 * rng.next() - 3.0;
            q[3] = 4.0 * rng.next() - 2.0;
            q[4] = q2;
            q[5] = q3;
            return q;
        }
    }
}

fn potential<T: RealField + Copy>(
    task: &TorsoWorkspace<T, N>,
    q: &SVector<T, N>,
    inertia: &nalgebra::Cholesky<T, nalgebra::Const<N>>,
) -> T {
    let mut rows = TaskRows::<T, N, BOUNDARIES>::new();
    torso_workspace(task, q, &SVector::zeros(), inertia, &mut rows).unwrap();
    rows.potential()
}

/// Largest relative error of `Σ jᵀ f` (q̇ = 0) against central differences of `V_tws` over all
/// 20 coordinates, at `samples` random states; and the number of rows with a potential.
fn gradient_check<T: RealField + Copy>(h: f64, samples: usize) -> (f64, usize) {
    let model = justin::model::<T>().unwrap();
    let mut data = Box::new(Data::new(&model));
    let task = task::<T>(800.0, 70.0);
    let mut rng = Lcg(2015);
    let (mut worst, mut active) = (0.0_f64, 0);
    for _ in 0..samples {
        let q: SVector<T, N> = random_state(&mut rng).cast();
        forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
        crba(&model, &mut data);
        let inertia = mass_matrix_cholesky(&data).unwrap();
        let mut rows = TaskRows::<T, N, BOUNDARIES>::new();
        torso_workspace(&task, &q, &SVector::zeros(), &inertia, &mut rows).unwrap();
        active += rows.rows().iter().filter(|r| r.potential > T::zero()).count();
        let tau = rows.torque();
        let hh: T = nalgebra::convert(h);
        let fd = SVector::<T, N>::from_fn(|k, _| {
            let mut e = SVector::<T, N>::zeros();
            e[k] = hh;
            (potential(&task, &(q + e), &inertia) - potential(&task, &(q - e), &inertia)) / (hh + hh)
        });
        let err: f64 = nalgebra::try_convert((tau + fd).amax()).unwrap();
        let scale: f64 = nalgebra::try_convert(tau.amax()).unwrap();
        worst = worst.max(err / scale.max(1.0));
    }
    (worst, active)
}

#[test]
fn repulsion_is_the_negative_potential_gradient_on_justin_f64() {
    let (err, active) = gradient_check::<f64>(1e-6, 300);
    println!("torso workspace, Justin, f64: largest relative FD error {err:.2e} ({active} active rows)");
    assert!(err < 1e-6, "{err}");
    assert!(active > 200, "{active}");
}

#[test]
fn repulsion_is_the_negative_potential_gradient_on_justin_f32() {
    // f32: positions carry ≈ 4e-8 m of rounding, times forces up to 50 N, so V errs by ≈ 1e-6 J
    // and the central difference by ≈ 1e-3 at h = 1e-3 rad; near corners of the workspace the
    // truncation error is of the same order (observed 4e-3). Stated tolerance 1e-2 relative;
    // the kernel's unit tests compare f32 rows with f64 rows to 1e-4.
    let (err, _) = gradient_check::<f32>(1e-3, 300);
    println!("torso workspace, Justin, f32: largest relative FD error {err:.2e}");
    assert!(err < 1e-2, "{err}");
}

/// The task's torso plane is the robot model's: `p_t` from (3.42) equals the position of the
/// torso centre frame relative to the `q_t2` axis, in the plane turned by the base yaw and
/// `q_t1` (x forward, z up).
#[test]
fn torso_plane_is_that_of_the_robot_model() {
    let model = justin::model::<f64>().unwrap();
    let mut data = Box::new(Data::new(&model));
    let g = justin::torso_geometry::<f64>();
    let mut rng = Lcg(7);
    for _ in 0..50 {
        let q = random_state(&mut rng);
        forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
        let axis = data.frame_placements[justin::TORSO_LINK2.0].translation.vector;
        let center = data.frame_placements[justin::TORSO_CENTER.0].translation.vector;
        let yaw = q[2] + q[3];
        let forward = Vector3::new(yaw.cos(), yaw.sin(), 0.0);
        let relative = center - axis;
        let expected = g.center(q[4], q[5]);
        assert!((relative.dot(&forward) - expected.x).abs() < 1e-12, "{q:?}");
        assert!((relative.z - expected.y).abs() < 1e-12);
        assert!(relative.dot(&Vector3::new(-yaw.sin(), yaw.cos(), 0.0)).abs() < 1e-12);
    }
}

/// The thesis' statements about Fig. 3.16, quantified (see the scenario docs), and the region
/// map written for inspection.
#[test]
fn torso_workspace_scenario_reproduces_fig_3_16() {
    let outcome = scenario::simulate(&RunOptions::default()).unwrap();
    let s = &outcome.summary;
    assert!(s.failed_claims().is_empty(), "{:?}", s.failed_claims());
    assert_eq!(s.passed_claims().len(), 7);
    for case in scenario::CASES {
        let p = format!("case_{}", case.label);
        println!(
            "Fig. 3.16{} ({} N, {}°): excluded {:.1} % (joint 2 {:.1} %, joint 3 {:.1} %), feasible {:.4} m²",
            case.label,
            case.force_n,
            case.angle_deg,
            100.0 * s.get(&format!("{p}_excluded_fraction")).unwrap(),
            100.0 * s.get(&format!("{p}_excluded_by_joint2_fraction")).unwrap(),
            100.0 * s.get(&format!("{p}_excluded_by_joint3_fraction")).unwrap(),
            s.get(&format!("{p}_feasible_area_m2")).unwrap()
        );
    }
    // Joint 3 vanishes at 550 N and exists at 800 N (Fig. 3.16d vs a).
    assert_eq!(s.get("case_d_excluded_by_joint3_fraction"), Some(0.0));
    assert!(s.get("case_a_excluded_by_joint3_fraction").unwrap() > 0.2);
    // 1200 N excludes most of the workspace (Fig. 3.16c).
    assert!(s.get("case_c_excluded_fraction").unwrap() > 0.75);
    // The kinematic area: ∫∫ l² sin q_t3 over Table 3.2 = l² (1 + (π/2)(1 + 1/√2)) = 0.3313 m².
    let exact = 0.09 * (1.0 + core::f64::consts::FRAC_PI_2 * (1.0 + core::f64::consts::FRAC_1_SQRT_2));
    let area = s.get("kinematic_area_m2").unwrap();
    println!("kinematic workspace area: grid {area:.4} m², exact {exact:.4} m²");
    assert!((area / exact - 1.0).abs() < 0.01);
    assert!(outcome.series.rows().len() > 10_000);

    let dir = std::env::temp_dir().join("torso_workspace");
    std::fs::create_dir_all(&dir).unwrap();
    assert_eq!(scenario::write_files(&dir, &outcome).unwrap(), [scenario::REGION_MAP_FILE]);
    println!("region map: {}", dir.join(scenario::REGION_MAP_FILE).display());
}
