//! Cartesian impedance (3.54) of a frame with a trajectory, double-diagonalisation damping and
//! per-axis force limits (Table 7.1), as up to six task rows.
//!
//! # Task coordinates
//! The stiffness is expressed in a [`StiffnessFrame`] with world orientation `A` (`A = I` for
//! [`StiffnessFrame::World`], `A = R_des` for [`StiffnessFrame::Desired`]). With the frame's pose
//! `(p, R)` and the desired pose `(p_des, R_des)` the six task coordinates are
//! - translation `e_t = Aᵀ (p − p_des)` (m);
//! - rotation `e_r = 2 Aᵀ ε`, where `(η, ε)` is the unit quaternion of the world-frame relative
//!   rotation `R R_desᵀ`, sign chosen with `η ≥ 0` (rad for small angles: `2ε = θ·axis + O(θ³)`).
//!
//! Each selected axis is one row whose coordinate is `e_i`, with the **exact** Jacobian row
//! `j_i = ∂e_i/∂q`: `J_t = Aᵀ J_v` and `J_r = Aᵀ (η I − [ε]×) J_ω` (from the quaternion
//! kinematics `ε̇ = ½ (η I − [ε]×) ω`), `J_v`, `J_ω` the rows of the world-aligned frame
//! Jacobian.
//!
//! # Potential and force
//! `V = ½ eᵀ K e` with `K = blockdiag(K_t, K_r)` restricted to the selected axes (`K_sel =
//! P K P`, so the potential does not depend on a free axis). Rotationally it is the quaternion
//! potential `2 εᵀ A K_r Aᵀ ε` (used by \[Ott08\] and DLR's Cartesian impedance); for `K_r = k I`
//! it is `V_rot = 2k sin²(θ/2) = k (1 − cos θ)`, the restoring torque is `k sin θ` about the
//! error axis, and `θ = π` is an unstable equilibrium (where the sign choice `η ≥ 0` flips
//! `e_r` and `J_r` together, so the torque stays continuous). Because every row is a true
//! coordinate, `f_i = −∂V/∂e_i = −(K_sel e)_i` is the exact gradient along the row and
//! `Σ j_iᵀ f_i = −(∂V/∂q)ᵀ`. A row's potential share is `½ e_i (K_sel e)_i` (shares of a
//! non-diagonal `K` may be negative; they sum to `V`).
//!
//! # Damping and trajectory
//! Damping acts on the error rate `ė = J_x q̇ + ∂e/∂t`, which contains the desired twist as
//! velocity feed-forward (and, in the desired frame, the rotation of the frame itself). The
//! damping matrix is designed by double diagonalisation (\[ASOFH03\], Sec. 5.1.4) for the reflected
//! inertia `Λ⁻¹ = J_x M⁻¹ J_xᵀ` of the selected rows, stiffness `K_sel` and one damping ratio
//! `ξ`, so the linearised closed loop `Λ ë + D ė + K e = 0` has modal damping ratio `ξ` in
//! every stiff mode. If `M` is not positive definite, `Λ⁻¹` is numerically singular (the
//! selected axes lose independence: a kinematic singularity) or the design fails, the task falls
//! back to the diagonal damping `fallback_damping` in task coordinates and reports it
//! ([`CartesianReport::damping_fallback`]). The switch makes the damping force discontinuous
//! there; the singularity avoidance (3.55)–(3.57) is what keeps an arm away from it.
//!
//! # Force limits
//! Each row's spring force `−(K_sel e)_i` is clamped to `[force_lower_i, force_upper_i]`
//! (Table 7.1, e.g. `(−∞/+10, ±∞, ±∞)` N to press with at most 10 N); the damping force is added
//! after the clamp, `f_i = clamp(−(K_sel e)_i) − (D ė)_i`. The limits are there so that "the
//! error between the actual and the desired TCP position/orientation does not lead to
//! infeasible control inputs" (Sec. 5.1): they bound what the *error* commands. The damping is
//! not clamped: clamping the total force would take the damping away exactly while the limit
//! holds a contact, leaving the contact undamped (on the simulated Justin the brush of
//! `clean_mug` then rang at ≈ 6 Hz with ±10 N around the limit). In a contact the force peaks at
//! the deepest point, where `ė` along the normal vanishes, so the damping does not raise the
//! peak. A clamped force is no longer the gradient of `V`: the report flags each saturated row,
//! whose potential share is still the unsaturated `½ e_i (K e)_i`. Clamping the spring force
//! towards zero never adds energy to the virtual spring, and the damping only dissipates.

use heapless::Vec;
use nalgebra::{Matrix3, Matrix6, RealField, RowSVector, SMatrix, SVector, UnitQuaternion, Vector3, Vector6};

use super::{TaskError, TaskRow, TaskRows};
use crate::dynamics::{frame_jacobian, DynamicsError, TreeFactorization};
use crate::math::cholesky::{cholesky_in_place, solve_lower_in_place};
use crate::math::damping::{double_diagonalization_factored, DampingError, ReflectedInertia};
use crate::math::spatial::{skew, Placement};
use crate::model::{Data, FrameId, Model};

/// The frame whose axes the stiffness, the axis mask and the force limits refer to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StiffnessFrame {
    /// World axes (`A = I`).
    World,
    /// Axes of the desired frame `R_des` (the tool frame at equilibrium, as in Table 7.1).
    Desired,
}

/// Which of the six task axes `(x, y, z, rx, ry, rz)` of the stiffness frame get a row.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AxisMask {
    axes: [bool; 6],
}

impl AxisMask {
    /// All six axes.
    pub const ALL: Self = Self { axes: [true; 6] };
    /// Translation only `(x, y, z)`.
    pub const TRANSLATION: Self = Self { axes: [true, true, true, false, false, false] };
    /// Rotation only `(rx, ry, rz)`.
    pub const ROTATION: Self = Self { axes: [false, false, false, true, true, true] };

    /// A mask from flags `(x, y, z, rx, ry, rz)`.
    pub const fn new(axes: [bool; 6]) -> Self {
        Self { axes }
    }

    /// `true` if axis `axis` (0–5) is selected.
    pub fn contains(&self, axis: usize) -> bool {
        self.axes.get(axis).copied().unwrap_or(false)
    }

    /// Number of selected axes (rows).
    pub fn count(&self) -> usize {
        self.axes.iter().filter(|a| **a).count()
    }

    /// The flags `(x, y, z, rx, ry, rz)`.
    pub fn axes(&self) -> [bool; 6] {
        self.axes
    }
}

/// One sample of the desired trajectory: pose and twist of the desired frame (world).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CartesianTarget<T: RealField> {
    /// Desired pose `(R_des, p_des)` in the world (m).
    pub pose: Placement<T>,
    /// Velocity of the desired origin `ṗ_des`, world axes (m/s).
    pub linear_velocity: Vector3<T>,
    /// Angular velocity `ω_des` of the desired frame, world axes (rad/s).
    pub angular_velocity: Vector3<T>,
}

impl<T: RealField + Copy> CartesianTarget<T> {
    /// A constant desired pose (zero twist).
    pub fn at_rest(pose: Placement<T>) -> Self {
        Self { pose, linear_velocity: Vector3::zeros(), angular_velocity: Vector3::zeros() }
    }
}

/// Parameters of a Cartesian impedance. Validate with [`CartesianImpedance::try_new`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CartesianImpedanceConfig<T: RealField> {
    /// The controlled frame (its origin and orientation).
    pub frame: FrameId,
    /// Axes that get a row; the others are free (no stiffness, no damping).
    pub axes: AxisMask,
    /// Frame of the stiffness, the mask and the force limits.
    pub stiffness_frame: StiffnessFrame,
    /// Translational stiffness `K_t` (N/m), symmetric positive semidefinite.
    pub translational_stiffness: Matrix3<T>,
    /// Rotational stiffness `K_r` (Nm/rad), symmetric positive semidefinite.
    pub rotational_stiffness: Matrix3<T>,
    /// Damping ratio `ξ ≥ 0` of every mode (e.g. 0.7, Table 5.2).
    pub damping_ratio: T,
    /// Lower force bound per axis (N, Nm), `≤ 0`, may be `−∞`.
    pub force_lower: Vector6<T>,
    /// Upper force bound per axis (N, Nm), `≥ 0`, may be `+∞`.
    pub force_upper: Vector6<T>,
    /// Diagonal task-space damping (Ns/m, Nms/rad), `≥ 0`, used when the double
    /// diagonalisation is impossible (singular `M` or task Jacobian).
    pub fallback_damping: Vector6<T>,
}

/// Why the task used its fallback damping.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DampingFallback {
    /// The mass matrix failed its Cholesky factorization (was `crba` called?).
    MassMatrixNotPositiveDefinite,
    /// `Λ⁻¹ = J_x M⁻¹ J_xᵀ` is numerically singular (a Cholesky pivot at rounding level): the
    /// selected axes are not independent at this configuration (kinematic singularity, or more
    /// axes than the frame has joints).
    TaskJacobianSingular,
    /// The double diagonalisation failed.
    Design(DampingError),
}

/// What one call of [`cartesian_impedance`] found, per axis `(x, y, z, rx, ry, rz)` of the
/// stiffness frame (zero / `false` for unselected axes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CartesianReport<T> {
    /// Task error `e = (Aᵀ (p − p_des), 2 Aᵀ ε)` (m, rad-like).
    pub error: Vector6<T>,
    /// Error rate `ė = J_x q̇ + ∂e/∂t` (m/s, rad/s-like).
    pub error_rate: Vector6<T>,
    /// Force before the limits, `−K e − D ė` (N, Nm).
    pub unsaturated_force: Vector6<T>,
    /// Its damping part `−D ė` (N, Nm), which the limits do not clamp.
    pub damping_force: Vector6<T>,
    /// `true` where the force limit clamped the row's spring force.
    pub saturated: [bool; 6],
    /// `Some` if the fallback damping was used instead of the double diagonalisation.
    pub damping_fallback: Option<DampingFallback>,
}

/// A validated Cartesian impedance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CartesianImpedance<T: RealField> {
    config: CartesianImpedanceConfig<T>,
    stiffness: Matrix6<T>,
}

impl<T: RealField + Copy> CartesianImpedance<T> {
    /// Validates `config`: stiffness matrices finite, symmetric and positive semidefinite; `ξ`
    /// finite and `≥ 0`; force bounds not NaN with `lower ≤ 0 ≤ upper` (so that zero force, the
    /// equilibrium, is admissible); fallback damping finite and `≥ 0`.
    /// Errors: [`TaskError::InvalidParameter`] naming the field.
    pub fn try_new(config: CartesianImpedanceConfig<T>) -> Result<Self, TaskError> {
        let invalid = |name| Err(TaskError::InvalidParameter { name });
        if !stiffness_is_valid(&config.translational_stiffness) {
            return invalid("translational_stiffness");
        }
        if !stiffness_is_valid(&config.rotational_stiffness) {
            return invalid("rotational_stiffness");
        }
        if !(config.damping_ratio.is_finite() && config.damping_ratio >= T::zero()) {
            return invalid("damping_ratio");
        }
        if !config.force_lower.iter().all(|x| *x <= T::zero()) {
            return invalid("force_lower");
        }
        if !config.force_upper.iter().all(|x| *x >= T::zero()) {
            return invalid("force_upper");
        }
        if !config.fallback_damping.iter().all(|x| x.is_finite() && *x >= T::zero()) {
            return invalid("fallback_damping");
        }
        let mut stiffness = Matrix6::zeros();
        stiffness.fixed_view_mut::<3, 3>(0, 0).copy_from(&symmetric_part(&config.translational_stiffness));
        stiffness.fixed_view_mut::<3, 3>(3, 3).copy_from(&symmetric_part(&config.rotational_stiffness));
        let mask = Vector6::from_fn(|i, _| if config.axes.contains(i) { T::one() } else { T::zero() });
        let selector = Matrix6::from_diagonal(&mask);
        Ok(Self { config, stiffness: selector * stiffness * selector })
    }

    /// The validated parameters.
    pub fn config(&self) -> &CartesianImpedanceConfig<T> {
        &self.config
    }

    /// The task stiffness `K_sel = P blockdiag(K_t, K_r) P` (N/m, Nm/rad) in task coordinates.
    pub fn stiffness(&self) -> &Matrix6<T> {
        &self.stiffness
    }
}

fn symmetric_part<T: RealField + Copy>(k: &Matrix3<T>) -> Matrix3<T> {
    (k + k.transpose()) * nalgebra::convert::<f64, T>(0.5)
}

fn stiffness_is_valid<T: RealField + Copy>(k: &Matrix3<T>) -> bool {
    if !crate::math::all_finite(k) {
        return false;
    }
    let tolerance = nalgebra::convert::<f64, T>(1e3) * T::default_epsilon() * (k.amax() + T::one());
    if (k - k.transpose()).amax() > tolerance {
        return false;
    }
    let (eigenvalues, _) = crate::math::eigen::symmetric_eigen(&symmetric_part(k));
    eigenvalues.iter().all(|l| *l >= -tolerance)
}

/// Task coordinates of the frame: error `e` and `∂e/∂t`; the frame Jacobian is turned into
/// `J_x = ∂e/∂q` (6×N) in place.
struct TaskKinematics<T> {
    error: Vector6<T>,
    time_derivative: Vector6<T>,
}

/// `e`, `∂e/∂t` and, in place of the world-aligned frame Jacobian `(J_v; J_ω)` in `jacobian`,
/// `J_x = (Aᵀ J_v; Aᵀ E J_ω)` with `E = η I − [ε]×` (module docs), column by column.
fn task_kinematics<T: RealField + Copy, const N: usize>(
    placement: &Placement<T>,
    jacobian: &mut SMatrix<T, 6, N>,
    target: &CartesianTarget<T>,
    stiffness_frame: StiffnessFrame,
) -> TaskKinematics<T> {
    let two: T = nalgebra::convert(2.0);
    let desired_rotation = target.pose.rotation;
    // A and its angular velocity ω_A (Ȧᵀ = −Aᵀ [ω_A]×).
    let (a, omega_a) = match stiffness_frame {
        StiffnessFrame::World => (Matrix3::identity(), Vector3::zeros()),
        StiffnessFrame::Desired => (*desired_rotation.matrix(), target.angular_velocity),
    };
    let at = a.transpose();
    let offset = placement.translation.vector - target.pose.translation.vector;
    // Relative rotation R R_desᵀ (world), its quaternion with η ≥ 0.
    let relative = placement.rotation * desired_rotation.inverse();
    let quaternion = UnitQuaternion::from_rotation_matrix(&relative);
    let (mut eta, mut epsilon) = (quaternion.w, quaternion.imag());
    if eta < T::zero() {
        eta = -eta;
        epsilon = -epsilon;
    }
    // ∂(2ε)/∂ω for the spatial angular velocity of R R_desᵀ: E = η I − [ε]×.
    let e_matrix = Matrix3::identity() * eta - skew(&epsilon);
    let translation = at * offset;
    let rotation = at * epsilon * two;
    let rotation_map = at * e_matrix;
    let apply = |m: &Matrix3<T>, x: &[T]| -> [T; 3] {
        let (x0, x1, x2) = (
            x.first().copied().unwrap_or_else(T::zero),
            x.get(1).copied().unwrap_or_else(T::zero),
            x.get(2).copied().unwrap_or_else(T::zero),
        );
        let m = m.as_slice();
        let e = |i: usize| m.get(i).copied().unwrap_or_else(T::zero);
        [e(0) * x0 + e(3) * x1 + e(6) * x2, e(1) * x0 + e(4) * x1 + e(7) * x2, e(2) * x0 + e(5) * x1 + e(8) * x2]
    };
    for column in jacobian.as_mut_slice().chunks_exact_mut(6) {
        let Some((linear, angular)) = column.split_at_mut_checked(3) else { continue };
        let new_linear = apply(&at, linear);
        let new_angular = apply(&rotation_map, angular);
        for (x, y) in linear.iter_mut().zip(new_linear).chain(angular.iter_mut().zip(new_angular)) {
            *x = y;
        }
    }
    // ∂e_t/∂t = −Aᵀ (ṗ_des + ω_A × (p − p_des)). At fixed q, R R_desᵀ turns with the spatial
    // angular velocity −R R_desᵀ ω_des, so ∂e_r/∂t = −2 Aᵀ (ω_A × ε) − Aᵀ E R R_desᵀ ω_des.
    let translation_rate = -(at * (target.linear_velocity + omega_a.cross(&offset)));
    let rotation_rate = -(at * (omega_a.cross(&epsilon) * two + e_matrix * (relative * target.angular_velocity)));
    let stack = |t: &Vector3<T>, r: &Vector3<T>| Vector6::new(t.x, t.y, t.z, r.x, r.y, r.z);
    TaskKinematics { error: stack(&translation, &rotation), time_derivative: stack(&translation_rate, &rotation_rate) }
}

/// Cartesian impedance (3.54) of a frame: appends one row per selected axis (in the order
/// `x, y, z, rx, ry, rz` of the stiffness frame) with `j_i = ∂e_i/∂q`,
/// `f_i = clamp(−(K e)_i, lower_i, upper_i) − (D ė)_i`, `V_i = ½ e_i (K e)_i`, activation 1;
/// see the module docs for the coordinates, the potential, the damping and the limits. Used
/// alone and unsaturated, `τ = Σ j_iᵀ f_i = −(∂V/∂q)ᵀ − J_xᵀ D ė`.
///
/// Preconditions: [`crate::dynamics::forward_kinematics`] at `(q, q̇)` and
/// [`crate::dynamics::crba`] at `q` (the damping design reads `data.mass_matrix`).
/// Inputs: `target` (m, rad, m/s, rad/s). Cost O(N³) for the Cholesky factor of `M` plus
/// O(N) rows of width N. Returns the per-axis [`CartesianReport`].
/// Errors (the row list is unchanged): [`TaskError::Dynamics`] for an unknown frame,
/// [`TaskError::NonFinite`] for a non-finite target or result, [`TaskError::Capacity`].
///
/// ```
/// # use kernel::model::{Data, Inertia, JointDrive, JointKind, ModelBuilder, Placement};
/// # use kernel::dynamics::{crba, forward_kinematics};
/// # use kernel::tasks::{cartesian_impedance::*, TaskRows};
/// # use nalgebra::{Matrix3, SVector, Unit, Vector3, Vector6};
/// // A 1 kg point on a prismatic joint along x, held at x_des = 0.1 m with 400 N/m.
/// let mut b = ModelBuilder::<f64, 1, 1, 1>::new(Vector3::zeros());
/// let slider = b.add_body(None, Placement::identity(),
///     JointKind::Prismatic { axis: Unit::new_normalize(Vector3::x()) }, JointDrive::actuated(0),
///     Inertia::point_mass(1.0, Vector3::zeros())).unwrap();
/// let tool = b.add_frame(Some(slider), Placement::identity()).unwrap();
/// let model = b.try_build().unwrap();
/// let mut data = Data::new(&model);
/// forward_kinematics(&model, &mut data, &SVector::zeros(), &SVector::zeros()).unwrap();
/// crba(&model, &mut data);
/// let task = CartesianImpedance::try_new(CartesianImpedanceConfig {
///     frame: tool, axes: AxisMask::new([true, false, false, false, false, false]),
///     stiffness_frame: StiffnessFrame::World,
///     translational_stiffness: Matrix3::identity() * 400.0, rotational_stiffness: Matrix3::zeros(),
///     damping_ratio: 0.7, force_lower: Vector6::repeat(f64::NEG_INFINITY),
///     force_upper: Vector6::repeat(f64::INFINITY), fallback_damping: Vector6::zeros(),
/// }).unwrap();
/// let target = CartesianTarget::at_rest(Placement::translation(0.1, 0.0, 0.0));
/// let mut rows = TaskRows::<f64, 1, 6>::new();
/// let report = cartesian_impedance(&model, &data, &task, &target, &mut rows).unwrap();
/// assert!((rows.rows()[0].force - 40.0).abs() < 1e-12 && (rows.potential() - 2.0).abs() < 1e-12);
/// assert_eq!(report.damping_fallback, None);
/// ```
pub fn cartesian_impedance<T: RealField + Copy, const N: usize, const B: usize, const F: usize, const R: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    task: &CartesianImpedance<T>,
    target: &CartesianTarget<T>,
    rows: &mut TaskRows<T, N, R>,
) -> Result<CartesianReport<T>, TaskError> {
    evaluate(model, data, MassFactor::Dense, task, target, rows)
}

/// [`cartesian_impedance`] with the damping design on a tree-sparse factor `M = Lᵀ L` of
/// `data.mass_matrix` computed by the caller ([`TreeFactorization::factorize`], shared by
/// every Cartesian task of a cycle; `None` when `M` is not positive definite, which selects
/// the configured fallback damping as [`cartesian_impedance`] does). `Λ⁻¹ = (J_x L⁻¹)(J_x L⁻¹)ᵀ`
/// costs O(Σ depth) per axis over the support path of the frame instead of a dense O(N³)
/// factor and O(N²) substitutions. Same rows as [`cartesian_impedance`] to rounding.
pub fn cartesian_impedance_factored<
    T: RealField + Copy,
    const N: usize,
    const B: usize,
    const F: usize,
    const R: usize,
>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    mass: Option<&TreeFactorization<T, N>>,
    task: &CartesianImpedance<T>,
    target: &CartesianTarget<T>,
    rows: &mut TaskRows<T, N, R>,
) -> Result<CartesianReport<T>, TaskError> {
    evaluate(model, data, MassFactor::Tree(mass), task, target, rows)
}

/// Where the damping design gets `M⁻¹` from.
#[derive(Clone, Copy)]
enum MassFactor<'a, T: RealField, const N: usize> {
    /// Its own dense Cholesky factor of `data.mass_matrix`.
    Dense,
    /// The caller's tree-sparse factor (`None`: `M` not positive definite).
    Tree(Option<&'a TreeFactorization<T, N>>),
}

fn evaluate<T: RealField + Copy, const N: usize, const B: usize, const F: usize, const R: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    mass: MassFactor<'_, T, N>,
    task: &CartesianImpedance<T>,
    target: &CartesianTarget<T>,
    rows: &mut TaskRows<T, N, R>,
) -> Result<CartesianReport<T>, TaskError> {
    let config = &task.config;
    let pose_finite = crate::math::all_finite(target.pose.rotation.matrix())
        && crate::math::all_finite(&target.pose.translation.vector);
    if !(pose_finite
        && crate::math::all_finite(&target.linear_velocity)
        && crate::math::all_finite(&target.angular_velocity))
    {
        return Err(TaskError::NonFinite);
    }
    if rows.len().saturating_add(config.axes.count()) > R {
        return Err(TaskError::Capacity { capacity: R });
    }
    let mut jacobian = SMatrix::<T, 6, N>::zeros();
    frame_jacobian(model, data, config.frame, &mut jacobian)?;
    let placement = data.frame_placements.get(config.frame.0).ok_or(DynamicsError::UnknownFrame)?;
    let kinematics = task_kinematics(placement, &mut jacobian, target, config.stiffness_frame);

    // The axis mask P: unselected rows of J_x, e and ė are zero.
    let selected = config.axes.axes();
    for column in jacobian.as_mut_slice().chunks_exact_mut(6) {
        for (x, s) in column.iter_mut().zip(selected.iter()) {
            if !s {
                *x = T::zero();
            }
        }
    }
    let task_jacobian = &jacobian;
    let mask = |v: Vector6<T>| v.zip_map(&Vector6::from(selected), |x, s| if s { x } else { T::zero() });
    let error = mask(kinematics.error);
    // ė = J_x q̇ + ∂e/∂t, column by column (the platform columns see q̇ = 0, (5.11)).
    let mut rate = kinematics.time_derivative;
    for (column, v) in task_jacobian.as_slice().chunks_exact(6).zip(data.v.as_slice().iter()) {
        if *v != T::zero() {
            for (r, j) in rate.as_mut_slice().iter_mut().zip(column.iter()) {
                *r += *j * *v;
            }
        }
    }
    let error_rate = mask(rate);
    let design = match mass {
        MassFactor::Dense => damping_matrix(data, task, task_jacobian, &selected),
        MassFactor::Tree(factor) => damping_matrix_tree(factor, task, task_jacobian, &selected),
    };
    let (damping, damping_fallback) = match design {
        Ok(d) => (d, None),
        Err(reason) => (Matrix6::from_diagonal(&mask(config.fallback_damping)), Some(reason)),
    };
    let spring = symmetric_times(&task.stiffness, &error);
    let damping_force = -symmetric_times(&damping, &error_rate);
    let unsaturated_force = damping_force - spring;

    let half: T = nalgebra::convert(0.5);
    let mut saturated = [false; 6];
    let mut pending: Vec<TaskRow<T, N>, 6> = Vec::new();
    let finite_jacobian = task_jacobian.as_slice().iter().all(|x| x.is_finite());
    for (axis, flag) in saturated.iter_mut().enumerate() {
        if !config.axes.contains(axis) {
            continue;
        }
        let entry = |v: &Vector6<T>| v.get(axis).copied().unwrap_or_else(T::zero);
        let raw = -entry(&spring);
        let (lower, upper) = (entry(&config.force_lower), entry(&config.force_upper));
        *flag = raw < lower || raw > upper;
        let mut row_jacobian = RowSVector::<T, N>::zeros();
        for (x, column) in row_jacobian.as_mut_slice().iter_mut().zip(task_jacobian.as_slice().chunks_exact(6)) {
            *x = column.get(axis).copied().unwrap_or_else(T::zero);
        }
        let row = TaskRow {
            jacobian: row_jacobian,
            force: raw.max(lower).min(upper) + entry(&damping_force),
            potential: half * entry(&error) * entry(&spring),
            activation: T::one(),
        };
        let finite = row.force.is_finite() && row.potential.is_finite() && finite_jacobian;
        if !finite || pending.push(row).is_err() {
            return Err(TaskError::NonFinite);
        }
    }
    // By reference: consuming a heapless vector drops its iterator through a slice index.
    for row in &pending {
        rows.push(*row)?;
    }
    Ok(CartesianReport { error, error_rate, unsaturated_force, damping_force, saturated, damping_fallback })
}

/// `S x` for a 6×6 matrix `S` as a loop over its columns.
fn symmetric_times<T: RealField + Copy>(s: &Matrix6<T>, x: &Vector6<T>) -> Vector6<T> {
    let mut y = Vector6::zeros();
    for (column, xj) in s.as_slice().chunks_exact(6).zip(x.iter()) {
        if *xj != T::zero() {
            for (yi, sij) in y.iter_mut().zip(column.iter()) {
                *yi += *sij * *xj;
            }
        }
    }
    y
}

/// `D` by double diagonalisation for `Λ⁻¹ = J_x M⁻¹ J_xᵀ` (unselected rows of `J_x` are zero;
/// their diagonal entry of `Λ⁻¹` is set to 1 so the matrix stays invertible, and as they have no
/// stiffness they get no damping). `Λ⁻¹` counts as singular if a pivot of its Cholesky factor
/// has `L_ii² ≤ 100 ε max_i Λ⁻¹_ii`.
///
/// With `M = L Lᵀ`: `Y = L⁻¹ J_xᵀ` by forward substitution of the selected rows only (tight
/// loops on the column-major factor, [`crate::math::cholesky::solve_lower_in_place`]) and
/// `Λ⁻¹ = Yᵀ Y` (exactly symmetric). The factor of `Λ⁻¹` that checks the pivots is handed to
/// [`crate::math::damping::double_diagonalization_factored`].
fn damping_matrix<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    data: &Data<T, N, B, F>,
    task: &CartesianImpedance<T>,
    task_jacobian: &SMatrix<T, 6, N>,
    selected: &[bool; 6],
) -> Result<Matrix6<T>, DampingFallback> {
    let mut factor = data.mass_matrix;
    if !cholesky_in_place(factor.as_mut_slice(), N) {
        return Err(DampingFallback::MassMatrixNotPositiveDefinite);
    }
    // Y = L⁻¹ J_xᵀ, one column per selected row (zero for the others).
    let mut reduced = SMatrix::<T, N, 6>::zeros();
    for (axis, (column, flag)) in reduced.as_mut_slice().chunks_exact_mut(N).zip(selected.iter()).enumerate() {
        if !flag {
            continue;
        }
        for (y, j) in column.iter_mut().zip(task_jacobian.as_slice().chunks_exact(6)) {
            *y = j.get(axis).copied().unwrap_or_else(T::zero);
        }
        if !solve_lower_in_place(factor.as_slice(), column) {
            return Err(DampingFallback::MassMatrixNotPositiveDefinite);
        }
    }
    let mut inverse_inertia = Matrix6::<T>::identity();
    for (i, (yi, si)) in reduced.as_slice().chunks_exact(N).zip(selected.iter()).enumerate() {
        if !si {
            continue;
        }
        for (j, (yj, sj)) in reduced.as_slice().chunks_exact(N).zip(selected.iter()).enumerate().take(i + 1) {
            if !sj {
                continue;
            }
            let dot = yi.iter().zip(yj.iter()).fold(T::zero(), |s, (a, b)| s + *a * *b);
            if let Some(x) = inverse_inertia.get_mut((i, j)) {
                *x = dot;
            }
            if let Some(x) = inverse_inertia.get_mut((j, i)) {
                *x = dot;
            }
        }
    }
    design_from_inverse_inertia(task, &inverse_inertia)
}

/// [`damping_matrix`] on the tree-sparse factor `M = Lᵀ L`: `X = J_x L⁻¹`
/// ([`TreeFactorization::right_solve_mut`], only the support-path columns of `J_x` are
/// touched) and `Λ⁻¹ = X Xᵀ` summed over the nonzero columns of `X`, unselected diagonal
/// entries set to 1; then the same pivot check and double diagonalisation.
fn damping_matrix_tree<T: RealField + Copy, const N: usize>(
    factor: Option<&TreeFactorization<T, N>>,
    task: &CartesianImpedance<T>,
    task_jacobian: &SMatrix<T, 6, N>,
    selected: &[bool; 6],
) -> Result<Matrix6<T>, DampingFallback> {
    let factor = factor.ok_or(DampingFallback::MassMatrixNotPositiveDefinite)?;
    let mut reduced = *task_jacobian;
    factor.right_solve_mut(&mut reduced);
    let mut inverse_inertia = Matrix6::<T>::zeros();
    for column in reduced.as_slice().chunks_exact(6) {
        if column.iter().all(|x| *x == T::zero()) {
            continue;
        }
        for (target, xj) in inverse_inertia.as_mut_slice().chunks_exact_mut(6).zip(column.iter()) {
            if *xj != T::zero() {
                for (t, xi) in target.iter_mut().zip(column.iter()) {
                    *t += *xi * *xj;
                }
            }
        }
    }
    for (i, s) in selected.iter().enumerate() {
        if !s {
            if let Some(x) = inverse_inertia.get_mut((i, i)) {
                *x = T::one();
            }
        }
    }
    design_from_inverse_inertia(task, &inverse_inertia)
}

/// The pivot check of `Λ⁻¹` and the double diagonalisation (shared by both damping designs).
fn design_from_inverse_inertia<T: RealField + Copy>(
    task: &CartesianImpedance<T>,
    inverse_inertia: &Matrix6<T>,
) -> Result<Matrix6<T>, DampingFallback> {
    // A rounding-level pivot would pass the factorization inside the design but give a
    // meaningless (huge) damping along the lost direction: treat it as singular.
    let mut pivots = *inverse_inertia;
    if !cholesky_in_place(pivots.as_mut_slice(), 6) {
        return Err(DampingFallback::TaskJacobianSingular);
    }
    let floor = nalgebra::convert::<f64, T>(100.0) * T::default_epsilon() * inverse_inertia.diagonal().amax();
    if pivots.diagonal().iter().any(|l| *l * *l <= floor) {
        return Err(DampingFallback::TaskJacobianSingular);
    }
    if !inverse_inertia.as_slice().iter().all(|x| x.is_finite()) {
        return Err(DampingFallback::Design(DampingError::NonFinite));
    }
    let ratios = SVector::<T, 6>::repeat(task.config.damping_ratio);
    double_diagonalization_factored(ReflectedInertia::Inverse(&pivots), &task.stiffness, &ratios)
        .map_err(DampingFallback::Design)
}

/// The plain implementation (nalgebra products, the mask as a diagonal matrix, nalgebra's
/// `Cholesky`, `solve` and [`double_diagonalization`]): the reference of the tests for the loops
/// above.
#[cfg(test)]
mod reference {
    #![allow(clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::dynamics::mass_matrix_cholesky;
    use crate::math::damping::double_diagonalization;

    struct TaskKinematics<T, const N: usize> {
        error: Vector6<T>,
        jacobian: SMatrix<T, 6, N>,
        time_derivative: Vector6<T>,
    }

    fn task_kinematics<T: RealField + Copy, const N: usize>(
        placement: &Placement<T>,
        frame_jacobian: &SMatrix<T, 6, N>,
        target: &CartesianTarget<T>,
        stiffness_frame: StiffnessFrame,
    ) -> TaskKinematics<T, N> {
        let two: T = nalgebra::convert(2.0);
        let desired_rotation = target.pose.rotation;
        // A and its angular velocity ω_A (Ȧᵀ = −Aᵀ [ω_A]×).
        let (a, omega_a) = match stiffness_frame {
            StiffnessFrame::World => (Matrix3::identity(), Vector3::zeros()),
            StiffnessFrame::Desired => (*desired_rotation.matrix(), target.angular_velocity),
        };
        let at = a.transpose();
        let offset = placement.translation.vector - target.pose.translation.vector;
        // Relative rotation R R_desᵀ (world), its quaternion with η ≥ 0.
        let relative = placement.rotation * desired_rotation.inverse();
        let quaternion = UnitQuaternion::from_rotation_matrix(&relative);
        let (mut eta, mut epsilon) = (quaternion.w, quaternion.imag());
        if eta < T::zero() {
            eta = -eta;
            epsilon = -epsilon;
        }
        // ∂(2ε)/∂ω for the spatial angular velocity of R R_desᵀ: E = η I − [ε]×.
        let e_matrix = Matrix3::identity() * eta - skew(&epsilon);
        let translation = at * offset;
        let rotation = at * epsilon * two;
        let mut jacobian = SMatrix::<T, 6, N>::zeros();
        jacobian.fixed_rows_mut::<3>(0).copy_from(&(at * frame_jacobian.fixed_rows::<3>(0)));
        jacobian.fixed_rows_mut::<3>(3).copy_from(&(at * e_matrix * frame_jacobian.fixed_rows::<3>(3)));
        // ∂e_t/∂t = −Aᵀ (ṗ_des + ω_A × (p − p_des)). At fixed q, R R_desᵀ turns with the spatial
        // angular velocity −R R_desᵀ ω_des, so ∂e_r/∂t = −2 Aᵀ (ω_A × ε) − Aᵀ E R R_desᵀ ω_des.
        let translation_rate = -(at * (target.linear_velocity + omega_a.cross(&offset)));
        let rotation_rate = -(at * (omega_a.cross(&epsilon) * two + e_matrix * (relative * target.angular_velocity)));
        let stack = |t: &Vector3<T>, r: &Vector3<T>| Vector6::new(t.x, t.y, t.z, r.x, r.y, r.z);
        TaskKinematics {
            error: stack(&translation, &rotation),
            jacobian,
            time_derivative: stack(&translation_rate, &rotation_rate),
        }
    }

    pub fn cartesian_impedance<T: RealField + Copy, const N: usize, const B: usize, const F: usize, const R: usize>(
        model: &Model<T, N, B, F>,
        data: &Data<T, N, B, F>,
        task: &CartesianImpedance<T>,
        target: &CartesianTarget<T>,
        rows: &mut TaskRows<T, N, R>,
    ) -> Result<CartesianReport<T>, TaskError> {
        let config = &task.config;
        let pose_finite = crate::math::all_finite(target.pose.rotation.matrix())
            && crate::math::all_finite(&target.pose.translation.vector);
        if !(pose_finite
            && crate::math::all_finite(&target.linear_velocity)
            && crate::math::all_finite(&target.angular_velocity))
        {
            return Err(TaskError::NonFinite);
        }
        if rows.len().saturating_add(config.axes.count()) > R {
            return Err(TaskError::Capacity { capacity: R });
        }
        let mut jacobian = SMatrix::<T, 6, N>::zeros();
        frame_jacobian(model, data, config.frame, &mut jacobian)?;
        let placement = data.frame_placements.get(config.frame.0).ok_or(DynamicsError::UnknownFrame)?;
        let kinematics = task_kinematics(placement, &jacobian, target, config.stiffness_frame);

        let mask = Vector6::from_fn(|i, _| if config.axes.contains(i) { T::one() } else { T::zero() });
        let selector = Matrix6::from_diagonal(&mask);
        let task_jacobian = selector * kinematics.jacobian;
        let error = selector * kinematics.error;
        let error_rate = selector * (kinematics.jacobian * data.v + kinematics.time_derivative);
        let (damping, damping_fallback) = match damping_matrix(data, task, &task_jacobian, &mask) {
            Ok(d) => (d, None),
            Err(reason) => (Matrix6::from_diagonal(&config.fallback_damping.component_mul(&mask)), Some(reason)),
        };
        let spring = task.stiffness * error;
        let damping_force = -(damping * error_rate);
        let unsaturated_force = damping_force - spring;

        let half: T = nalgebra::convert(0.5);
        let mut saturated = [false; 6];
        let mut pending: Vec<TaskRow<T, N>, 6> = Vec::new();
        for (axis, flag) in saturated.iter_mut().enumerate() {
            if !config.axes.contains(axis) {
                continue;
            }
            let entry = |v: &Vector6<T>| v.get(axis).copied().unwrap_or_else(T::zero);
            let raw = -entry(&spring);
            let (lower, upper) = (entry(&config.force_lower), entry(&config.force_upper));
            *flag = raw < lower || raw > upper;
            let row = TaskRow {
                jacobian: RowSVector::from_fn(|_, k| task_jacobian.get((axis, k)).copied().unwrap_or_else(T::zero)),
                force: raw.max(lower).min(upper) + entry(&damping_force),
                potential: half * entry(&error) * entry(&spring),
                activation: T::one(),
            };
            let finite = row.force.is_finite() && row.potential.is_finite() && crate::math::all_finite(&row.jacobian);
            if !finite || pending.push(row).is_err() {
                return Err(TaskError::NonFinite);
            }
        }
        // By reference: consuming a heapless vector drops its iterator through a slice index.
        for row in &pending {
            rows.push(*row)?;
        }
        Ok(CartesianReport { error, error_rate, unsaturated_force, damping_force, saturated, damping_fallback })
    }

    /// `D` by double diagonalisation for `Λ⁻¹ = J_x M⁻¹ J_xᵀ` (unselected rows of `J_x` are zero;
    /// their diagonal entry of `Λ⁻¹` is set to 1 so the matrix stays invertible, and as they have no
    /// stiffness they get no damping). `Λ⁻¹` counts as singular if a pivot of its Cholesky factor
    /// has `L_ii² ≤ 100 ε max_i Λ⁻¹_ii`.
    fn damping_matrix<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
        data: &Data<T, N, B, F>,
        task: &CartesianImpedance<T>,
        task_jacobian: &SMatrix<T, 6, N>,
        mask: &Vector6<T>,
    ) -> Result<Matrix6<T>, DampingFallback> {
        let factor = mass_matrix_cholesky(data).map_err(|_| DampingFallback::MassMatrixNotPositiveDefinite)?;
        let mobility = task_jacobian * factor.solve(&task_jacobian.transpose());
        let half: T = nalgebra::convert(0.5);
        let unselected = Matrix6::from_diagonal(&mask.map(|m| T::one() - m));
        let inverse_inertia = (mobility + mobility.transpose()) * half + unselected;
        // A rounding-level pivot would pass the factorization inside the design but give a
        // meaningless (huge) damping along the lost direction: treat it as singular.
        let pivots = nalgebra::Cholesky::new(inverse_inertia).ok_or(DampingFallback::TaskJacobianSingular)?;
        let floor = nalgebra::convert::<f64, T>(100.0) * T::default_epsilon() * inverse_inertia.diagonal().amax();
        if pivots.l_dirty().diagonal().iter().any(|l| *l * *l <= floor) {
            return Err(DampingFallback::TaskJacobianSingular);
        }
        let ratios = SVector::<T, 6>::repeat(task.config.damping_ratio);
        double_diagonalization(ReflectedInertia::Inverse(&inverse_inertia), &task.stiffness, &ratios)
            .map_err(DampingFallback::Design)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::dynamics::{crba, forward_kinematics};
    use crate::test_models::{branched, state, Branched, N, TCP, WRIST};
    use nalgebra::{Rotation3, Translation3};

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
            let mut error =
                scale((fast.error - plain.error).amax()) + scale((fast.error_rate - plain.error_rate).amax());
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
        let task =
            CartesianImpedance::try_new(config::<f64>(WRIST, AxisMask::TRANSLATION, StiffnessFrame::World)).unwrap();
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
        assert_eq!(
            cartesian_impedance(&model, &data, &task, &target, &mut rows),
            Err(TaskError::Capacity { capacity: 8 })
        );
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
}
