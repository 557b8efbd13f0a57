#![allow(clippy::indexing_slicing, reason = "tests")]
use super::*;
use crate::dynamics::mass_matrix_cholesky;
use crate::math::damping::{double_diagonalization, ReflectedInertia};
use heapless::Vec;
use nalgebra::{RowSVector, SVector};

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
