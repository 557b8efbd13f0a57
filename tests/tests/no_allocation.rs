//! The kernel's algorithms never allocate: a counting global allocator sees zero allocations
//! while every dynamics algorithm runs on the Justin-like model (f64 and f32).
//!
//! A separate test binary, because the global allocator is process-wide. The count is kept per
//! thread, so tests running in parallel (and the harness's own threads) do not see each
//! other's allocations.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "test code")]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use fixtures::justin;
use kernel::dynamics::{
    coriolis_matrix, crba, forward_dynamics, forward_kinematics, frame_drift, frame_jacobian, gravity, kinetic_energy,
    potential_energy, rnea,
};
use kernel::Data;
use nalgebra::{RealField, SMatrix, SVector};

struct Counting;

thread_local! {
    /// Allocations made by this thread. `const`-initialised and without a destructor, so the
    /// allocator may touch it at any time without allocating itself.
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

/// Number of allocations this thread has made so far.
fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

// SAFETY: forwards to the system allocator unchanged; only counts calls.
#[allow(unsafe_code, reason = "a GlobalAlloc impl is unsafe by definition")]
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|count| count.set(count.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn run_all<T: RealField + Copy>() -> usize {
    let model = justin::model::<T>().unwrap();
    let mut data = Box::new(Data::new(&model));
    let q = justin::home_configuration::<T>();
    let v = SVector::<T, { justin::N }>::repeat(nalgebra::convert(0.3));
    let tau = SVector::<T, { justin::N }>::repeat(nalgebra::convert(1.0));
    let mut jacobian = SMatrix::<T, 6, { justin::N }>::zeros();

    let before = allocations();
    forward_kinematics(&model, &mut data, &q, &v).unwrap();
    crba(&model, &mut data);
    coriolis_matrix(&model, &mut data);
    gravity(&model, &mut data);
    rnea(&model, &mut data, &tau).unwrap();
    frame_jacobian(&model, &data, justin::RIGHT_TCP, &mut jacobian).unwrap();
    frame_drift(&model, &data, justin::LEFT_TCP).unwrap();
    kinetic_energy(&model, &data);
    potential_energy(&model, &data);
    forward_dynamics(&model, &mut data, &tau).unwrap();
    allocations() - before
}

#[test]
fn dynamics_algorithms_do_not_allocate() {
    assert_eq!(run_all::<f64>(), 0, "f64 dynamics allocated");
    assert_eq!(run_all::<f32>(), 0, "f32 dynamics allocated");
}

/// The Chapter 3 task rows (Cartesian impedance, joint impedance, end stops incl. the coupled
/// torso joint q_t4 = −(q_t2 + q_t3), manipulability with its analytic Jacobian derivative) on
/// the Justin-like model: configuration built first, then every row producer counted.
mod chapter3_tasks {
    use super::allocations;

    use fixtures::justin;
    use kernel::dynamics::{crba, forward_kinematics, frame_jacobian_derivative};
    use kernel::tasks::cartesian_impedance::{
        cartesian_impedance, AxisMask, CartesianImpedance, CartesianImpedanceConfig, CartesianTarget, StiffnessFrame,
    };
    use kernel::tasks::end_stops::{end_stops, EndStop, EndStopConfig};
    use kernel::tasks::joint_impedance::{joint_impedance, JointImpedance, JointImpedanceConfig, JointTarget};
    use kernel::tasks::manipulability::{manipulability_avoidance, Manipulability, ManipulabilityConfig};
    use kernel::tasks::TaskRows;
    use kernel::Data;
    use nalgebra::{convert, Matrix3, RealField, SMatrix, SVector, Vector3, Vector6};

    const N: usize = justin::N;

    fn run<T: RealField + Copy>() -> usize {
        let c = |x: f64| convert::<f64, T>(x);
        let model = justin::model::<T>().unwrap();
        let mut data = Box::new(Data::new(&model));
        let q = justin::home_configuration::<T>();
        let v = SVector::<T, N>::repeat(c(0.3));
        let cartesian = CartesianImpedance::try_new(CartesianImpedanceConfig {
            frame: justin::RIGHT_TCP,
            axes: AxisMask::ALL,
            stiffness_frame: StiffnessFrame::Desired,
            translational_stiffness: Matrix3::from_diagonal(&Vector3::new(c(100.0), c(500.0), c(1000.0))),
            rotational_stiffness: Matrix3::from_diagonal(&Vector3::new(c(500.0), c(10.0), c(10.0))),
            damping_ratio: c(0.7),
            force_lower: Vector6::repeat(c(f64::NEG_INFINITY)),
            force_upper: Vector6::new(
                c(10.0),
                c(f64::INFINITY),
                c(f64::INFINITY),
                c(f64::INFINITY),
                c(f64::INFINITY),
                c(f64::INFINITY),
            ),
            fallback_damping: Vector6::repeat(c(20.0)),
        })
        .unwrap();
        let posture = JointImpedance::try_new(JointImpedanceConfig {
            selected: [true; N],
            stiffness: SVector::repeat(c(50.0)),
            damping: SVector::repeat(c(5.0)),
        })
        .unwrap();
        let mut stops: Vec<EndStop<T, N>> = (3..N)
            .map(|k| {
                let (lower, upper) = (model.limits.position_lower[k], model.limits.position_upper[k]);
                EndStop::try_new(EndStopConfig::coordinate(k, lower, upper, c(0.1), c(200.0), c(2.0))).unwrap()
            })
            .collect();
        let chest = model.frame(justin::TORSO_LINK4).unwrap().parent.unwrap();
        let q_t4 = &model.body(chest).unwrap().drive;
        stops.push(EndStop::try_new(EndStopConfig::drive(q_t4, c(-2.356), c(0.0), c(0.1), c(200.0), c(2.0))).unwrap());
        let mut arm = [false; N];
        arm[justin::RIGHT_ARM_COORDINATES].fill(true);
        let singularity = Manipulability::try_new(ManipulabilityConfig {
            frame: justin::RIGHT_TCP,
            rows: AxisMask::ALL,
            coordinates: arm,
            threshold: c(0.1),
            full_activation: c(0.02),
            stiffness: c(100.0),
            damping: c(1.0),
        })
        .unwrap();
        let mut rows = Box::new(TaskRows::<T, N, 48>::new());
        let mut derivative = SMatrix::<T, 6, N>::zeros();

        // Three passes: the first also covers any lazy initialisation; every pass must be free of
        // allocations.
        let mut most = 0;
        for _ in 0..3 {
            rows.clear();
            let before = allocations();
            forward_kinematics(&model, &mut data, &q, &v).unwrap();
            crba(&model, &mut data);
            let target = CartesianTarget::at_rest(data.frame_placements[justin::RIGHT_TCP.0]);
            let report = cartesian_impedance(&model, &data, &cartesian, &target, &mut *rows).unwrap();
            joint_impedance(&posture, &q, &v, &JointTarget::at_rest(q), None, &mut *rows).unwrap();
            end_stops(&stops, &q, &v, &mut *rows).unwrap();
            let measure = manipulability_avoidance(&model, &data, &singularity, &mut *rows).unwrap();
            frame_jacobian_derivative(&model, &data, justin::LEFT_TCP, &v, &mut derivative).unwrap();
            let _ = rows.torque();
            most = most.max(allocations() - before);
            assert_eq!(rows.len(), 6 + N + (N - 3 + 1) + 1);
            assert_eq!(report.damping_fallback, None, "double diagonalisation on the Justin model");
            assert!(!measure.singular && measure.manipulability > T::zero());
        }
        most
    }

    #[test]
    fn chapter3_tasks_do_not_allocate() {
        assert_eq!(run::<f64>(), 0, "f64 task rows allocated");
        assert_eq!(run::<f32>(), 0, "f32 task rows allocated");
    }
}

/// The torso-workspace rows (Sec. 3.3, (3.53)) on the Justin-like model, including the
/// Cholesky factor of M for their damping; configuration built first.
mod torso_workspace_rows {
    use super::allocations;

    use fixtures::justin;
    use kernel::dynamics::{crba, forward_kinematics, mass_matrix_cholesky};
    use kernel::tasks::torso_workspace::{
        torso_workspace, RepulsionGains, TorqueLimits, TorsoLoad, TorsoWorkspace, TorsoWorkspaceConfig, BOUNDARIES,
    };
    use kernel::tasks::TaskRows;
    use kernel::Data;
    use nalgebra::{convert, RealField, SVector};

    const N: usize = justin::N;

    fn run<T: RealField + Copy>() -> usize {
        let model = justin::model::<T>().unwrap();
        let mut data = Box::new(Data::new(&model));
        // Torso leaning forward into the joint-3 band of 800 N (q_t2 + q_t3 = 80°).
        let mut q = justin::home_configuration::<T>();
        q[4] = convert(0.3);
        q[5] = convert(1.1);
        let v = SVector::<T, N>::repeat(convert(0.3));
        let mut task = TorsoWorkspace::<T, N>::try_new(TorsoWorkspaceConfig {
            geometry: justin::torso_geometry(),
            torque_limits: TorqueLimits::symmetric(230.0),
            load: TorsoLoad::from_degrees(550.0, 90.0),
            gains: RepulsionGains::thesis_experiment(),
            coordinates: [4, 5],
        })
        .unwrap();
        let mut rows = Box::new(TaskRows::<T, N, BOUNDARIES>::new());
        let mut most = 0;
        for _ in 0..3 {
            rows.clear();
            let before = allocations();
            task.set_load(TorsoLoad::from_degrees(800.0, 90.0)).unwrap();
            forward_kinematics(&model, &mut data, &q, &v).unwrap();
            crba(&model, &mut data);
            let inertia = mass_matrix_cholesky(&data).unwrap();
            let report = torso_workspace(&task, &q, &v, &inertia, &mut *rows).unwrap();
            let _ = rows.torque();
            most = most.max(allocations() - before);
            assert_eq!(rows.len(), BOUNDARIES);
            assert!(!report.dynamically_feasible && report.nearest().is_some());
        }
        most
    }

    #[test]
    fn torso_workspace_rows_do_not_allocate() {
        assert_eq!(run::<f64>(), 0, "f64 torso-workspace rows allocated");
        assert_eq!(run::<f32>(), 0, "f32 torso-workspace rows allocated");
    }
}

/// One self-collision cycle of the Justin-like robot (world update, distances of all 214
/// enabled pairs, pair Jacobians, reflected masses, damping, rows) with the data preallocated.
fn run_self_collision<T: RealField + Copy>() -> usize {
    use kernel::tasks::collision::{self_collision_rows, CollisionData, CollisionParameters};
    let model = justin::model::<T>().unwrap();
    let collision = justin::collision::collision_model(&model).unwrap();
    let mut data = Box::new(Data::new(&model));
    let mut collision_data = Box::new(CollisionData::new(&collision));
    let mut rows = Box::new(kernel::tasks::TaskRows::<T, { justin::N }, 64>::new());
    let c = |x: f64| nalgebra::convert::<f64, T>(x);
    // d0 = 1 m: most pairs are active, so the row path runs many times.
    let parameters = CollisionParameters::try_new(c(25.0), c(1.0), c(0.7), c(0.0), c(1.0)).unwrap();
    let q = justin::home_configuration::<T>();
    let v = SVector::<T, { justin::N }>::repeat(c(0.3));

    let before = allocations();
    forward_kinematics(&model, &mut data, &q, &v).unwrap();
    crba(&model, &mut data);
    let factor = kernel::dynamics::mass_matrix_cholesky(&data).unwrap();
    let report =
        self_collision_rows(&collision, &mut collision_data, &model, &data, &factor, &parameters, &mut rows).unwrap();
    let allocations = allocations() - before;
    assert!(report.rows > 30, "{report:?}");
    allocations
}

#[test]
fn self_collision_rows_do_not_allocate() {
    assert_eq!(run_self_collision::<f64>(), 0, "f64 self-collision allocated");
    assert_eq!(run_self_collision::<f32>(), 0, "f32 self-collision allocated");
}

/// The multi-level compliance controller (Sec. 5.2, (5.58)–(5.60)) on the 20-DOF Justin-like
/// robot with the Table 5.6 hierarchy: dynamics terms, decomposition with `Ż`, projected
/// torques, `τ_μ` and storage functions. The task stack is built before counting.
#[test]
fn multilevel_control_does_not_allocate() {
    use host_sim::scenarios::multilevel_arm::ArmHierarchy;
    use kernel::hierarchy::multilevel::{multilevel_control, DynamicsTerms, MultilevelConfig, MultilevelData};
    use kernel::model::Placement;
    use nalgebra::{Translation3, Vector3};

    let model = justin::model::<f64>().unwrap();
    let mut data = Box::new(Data::new(&model));
    let q = justin::home_configuration::<f64>();
    let v = SVector::<f64, { justin::N }>::repeat(0.2);
    forward_kinematics(&model, &mut data, &q, &v).unwrap();
    let pose = data.frame_placements[justin::RIGHT_TCP.0];
    let target = Placement::from_parts(
        Translation3::from(pose.translation.vector + Vector3::new(0.05, 0.0, 0.0)),
        pose.rotation,
    );
    let mut controller = ArmHierarchy::new(model.clone(), justin::RIGHT_TCP, target, q).unwrap();
    controller.step(&q, &v).unwrap();
    let stack = controller.stack().clone();
    let config = MultilevelConfig::default();
    let mut out = Box::new(MultilevelData::<f64, { justin::N }, 3>::default());

    let before = allocations();
    forward_kinematics(&model, &mut data, &q, &v).unwrap();
    let mass = *crba(&model, &mut data);
    let coriolis = *coriolis_matrix(&model, &mut data);
    let g = *gravity(&model, &mut data);
    let factor = kernel::dynamics::mass_matrix_cholesky(&data).unwrap();
    let terms =
        DynamicsTerms { mass_matrix: &mass, mass_factor: &factor, coriolis: &coriolis, gravity: &g, velocity: &v };
    let torque = *multilevel_control(&config, &stack, &terms, &mut out).unwrap();
    assert_eq!(allocations() - before, 0, "multi-level control allocated");
    assert!(torque.iter().all(|t| t.is_finite()));
}

/// The whole-body controller's `step` and the planner channel (`apply`, encode/decode) on the
/// Justin-like model with every collision pair: zero allocations per cycle.
fn run_controller<T: kernel::controller::messages::WireScalar>() -> usize {
    use hal::{JointSample, PlatformSample};
    use justin::whole_body;
    use kernel::controller::config::ArmId;
    use kernel::controller::messages::{decode_command, encode_command, Command, Pose};
    use kernel::controller::{Controller, SensorFrame};

    let model = justin::model::<T>().unwrap();
    let collision = justin::collision::collision_model(&model).unwrap();
    let config = whole_body::controller_config::<T>().unwrap();
    let mut controller = Box::new(
        Controller::<
            T,
            { justin::N },
            { justin::BODIES },
            { justin::FRAMES },
            { justin::UPPER_DOF },
            { justin::collision::VOLUMES },
            { justin::collision::PAIRS },
            { whole_body::ARMS },
        >::try_new(model, collision, config, &whole_body::fig_6_3_hierarchy(ArmId::RIGHT))
        .unwrap(),
    );
    let q = justin::home_configuration::<T>();
    let frame = |cycle: u64, velocity: T| SensorFrame {
        joints: JointSample {
            position: core::array::from_fn(|i| q[i + 3]),
            velocity: [velocity; justin::UPPER_DOF],
            torque: [T::zero(); justin::UPPER_DOF],
            cycle,
        },
        platform: PlatformSample {
            pose: [T::zero(); 3],
            velocity: [T::zero(); 3],
            leg_lengths: [nalgebra::convert(justin::LEG_LENGTH_NOMINAL); 4],
            cycle,
        },
    };
    controller.step(&frame(1, T::zero()));
    let goal = Command::TcpGoal {
        hand: ArmId::RIGHT,
        pose: Pose {
            position: [nalgebra::convert(0.6), nalgebra::convert(-0.2), nalgebra::convert(0.9)],
            orientation: [T::one(), T::zero(), T::zero(), T::zero()],
        },
        duration_s: nalgebra::convert(1.0),
    };
    let mut buffer = [0u8; 256];

    let before = allocations();
    let bytes = encode_command(&goal, &mut buffer).unwrap();
    let decoded: Command<T> = decode_command(bytes).unwrap();
    controller.apply(&decoded).unwrap();
    for cycle in 2..20 {
        let out = controller.step(&frame(cycle, nalgebra::convert(0.01)));
        assert!(out.torque.iter().all(|t| t.is_finite()));
    }
    // A faulty frame takes the safe-output path.
    controller.step(&frame(20, nalgebra::convert(f64::NAN)));
    allocations() - before
}

#[test]
fn controller_step_and_planner_channel_do_not_allocate() {
    assert_eq!(run_controller::<f64>(), 0);
    assert_eq!(run_controller::<f32>(), 0);
}
