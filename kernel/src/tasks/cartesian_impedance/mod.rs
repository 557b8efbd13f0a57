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

use nalgebra::{Matrix3, Matrix6, RealField, SMatrix, UnitQuaternion, Vector3, Vector6};

use super::{RowSink, TaskError};
#[cfg(test)]
use super::{TaskRow, TaskRows};
use crate::dynamics::{frame_jacobian, DynamicsError, TreeFactorization};
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
    // m x for the column arrays of m.
    let apply = |m: &Matrix3<T>, x0: T, x1: T, x2: T| -> [T; 3] {
        let [[e0, e1, e2], [e3, e4, e5], [e6, e7, e8]] = m.data.0;
        [e0 * x0 + e3 * x1 + e6 * x2, e1 * x0 + e4 * x1 + e7 * x2, e2 * x0 + e5 * x1 + e8 * x2]
    };
    for column in jacobian.data.0.iter_mut() {
        let [x0, x1, x2, x3, x4, x5] = *column;
        let [l0, l1, l2] = apply(&at, x0, x1, x2);
        let [r0, r1, r2] = apply(&rotation_map, x3, x4, x5);
        *column = [l0, l1, l2, r0, r1, r2];
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
    rows: &mut impl RowSink<T, N, R>,
) -> Result<CartesianReport<T>, TaskError> {
    evaluate(model, data, MassFactor::Dense, task, target, None, rows)
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
    rows: &mut impl RowSink<T, N, R>,
) -> Result<CartesianReport<T>, TaskError> {
    evaluate(model, data, MassFactor::Tree(mass), task, target, None, rows)
}

/// [`cartesian_impedance_factored`] with the world-aligned Jacobian `(J_v; J_ω)` of the task's
/// frame given by the caller: `jacobian` is what [`frame_jacobian`] writes for `task`'s frame at
/// `data` (the controller computes it once per cycle for the contact-force limiter and the
/// task). The same rows, bit for bit, as [`cartesian_impedance_factored`] for that Jacobian.
pub fn cartesian_impedance_with_jacobian<
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
    jacobian: &SMatrix<T, 6, N>,
    rows: &mut impl RowSink<T, N, R>,
) -> Result<CartesianReport<T>, TaskError> {
    evaluate(model, data, MassFactor::Tree(mass), task, target, Some(jacobian), rows)
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
    world_jacobian: Option<&SMatrix<T, 6, N>>,
    rows: &mut impl RowSink<T, N, R>,
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
    let mut jacobian = match world_jacobian {
        Some(given) => *given,
        None => {
            let mut computed = SMatrix::<T, 6, N>::zeros();
            frame_jacobian(model, data, config.frame, &mut computed)?;
            computed
        }
    };
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
        MassFactor::Dense => damping_matrix(data, &task.stiffness, task.config.damping_ratio, task_jacobian, &selected),
        MassFactor::Tree(factor) => {
            damping_matrix_tree(factor, &task.stiffness, task.config.damping_ratio, task_jacobian, &selected)
        }
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
    let finite_jacobian = task_jacobian.as_slice().iter().all(|x| x.is_finite());
    // Each row is written whole in place in its slot of `rows`; a non-finite row removes the
    // rows pushed so far, so that `rows` is left unchanged.
    let start = rows.len();
    for (axis, flag) in saturated.iter_mut().enumerate() {
        if !config.axes.contains(axis) {
            continue;
        }
        let entry = |v: &Vector6<T>| v.get(axis).copied().unwrap_or_else(T::zero);
        let raw = -entry(&spring);
        let (lower, upper) = (entry(&config.force_lower), entry(&config.force_upper));
        *flag = raw < lower || raw > upper;
        let pushed = rows.push_with_metric(|row| {
            for (x, column) in row.jacobian.as_mut_slice().iter_mut().zip(task_jacobian.as_slice().chunks_exact(6)) {
                *x = column.get(axis).copied().unwrap_or_else(T::zero);
            }
            row.force = raw.max(lower).min(upper) + entry(&damping_force);
            row.potential = half * entry(&error) * entry(&spring);
            row.activation = T::one();
            None
        });
        if !finite_jacobian || pushed.is_err() {
            rows.truncate(start);
            return Err(TaskError::NonFinite);
        }
    }
    Ok(CartesianReport { error, error_rate, unsaturated_force, damping_force, saturated, damping_fallback })
}

mod damping;
pub use damping::DampingFallback;
use damping::{damping_matrix, damping_matrix_tree, symmetric_times};

/// The plain implementation (nalgebra products, the mask as a diagonal matrix, nalgebra's
/// `Cholesky`, `solve` and [`double_diagonalization`]): the reference of the tests for the loops
/// above.
#[cfg(test)]
mod reference;

#[cfg(test)]
mod tests;
