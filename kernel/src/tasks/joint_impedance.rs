//! Joint impedance (posture task): a spring and damper per selected coordinate, one row `e_kᵀ`
//! each (the "full joint impedance" level of Table 4.1, the torso impedance of Sec. 6.2).

use nalgebra::{RealField, SVector};

#[cfg(test)]
use super::TaskRows;
use super::{RowSink, TaskError};
#[cfg(test)]
use {super::TaskRow, nalgebra::RowSVector};

/// Parameters of a joint impedance over the coordinates selected by `selected`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointImpedanceConfig<T, const N: usize> {
    /// Coordinates that get a row (`true`); the others are left free.
    pub selected: [bool; N],
    /// Stiffness `k_k ≥ 0` per coordinate (Nm/rad or N/m).
    pub stiffness: SVector<T, N>,
    /// Damping `d_k ≥ 0` per coordinate (Nms/rad or Ns/m).
    pub damping: SVector<T, N>,
}

/// Desired joint positions and velocities (rad, m; rad/s, m/s), e.g. from a posture planner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointTarget<T, const N: usize> {
    /// `q_des`.
    pub position: SVector<T, N>,
    /// `q̇_des` (velocity feed-forward: damping acts on `q̇ − q̇_des`).
    pub velocity: SVector<T, N>,
}

impl<T: RealField + Copy, const N: usize> JointTarget<T, N> {
    /// A constant posture `q_des` (`q̇_des = 0`).
    pub fn at_rest(position: SVector<T, N>) -> Self {
        Self { position, velocity: SVector::zeros() }
    }
}

/// A validated joint impedance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointImpedance<T, const N: usize> {
    config: JointImpedanceConfig<T, N>,
}

impl<T: RealField + Copy, const N: usize> JointImpedance<T, N> {
    /// Validates `config`: stiffness and damping finite and `≥ 0`.
    /// Errors: [`TaskError::InvalidParameter`] (`"stiffness"`, `"damping"`).
    pub fn try_new(config: JointImpedanceConfig<T, N>) -> Result<Self, TaskError> {
        let valid = |x: &SVector<T, N>| x.iter().all(|v| v.is_finite() && *v >= T::zero());
        if !valid(&config.stiffness) {
            return Err(TaskError::InvalidParameter { name: "stiffness" });
        }
        if !valid(&config.damping) {
            return Err(TaskError::InvalidParameter { name: "damping" });
        }
        Ok(Self { config })
    }

    /// The validated parameters.
    pub fn config(&self) -> &JointImpedanceConfig<T, N> {
        &self.config
    }

    /// Number of rows [`joint_impedance`] emits (the selected coordinates).
    pub fn row_count(&self) -> usize {
        self.config.selected.iter().filter(|s| **s).count()
    }

    /// The rows `e_kᵀ` of the selected coordinates, each built whole (the plain form that
    /// [`joint_impedance`]'s in-place rows are tested against).
    #[cfg(test)]
    fn rows<'a>(
        &'a self,
        q: &'a SVector<T, N>,
        v: &'a SVector<T, N>,
        target: &'a JointTarget<T, N>,
    ) -> impl Iterator<Item = TaskRow<T, N>> + 'a {
        let c = &self.config;
        let half: T = nalgebra::convert(0.5);
        (0..N).filter_map(move |k| {
            if !c.selected.get(k).copied().unwrap_or(false) {
                return None;
            }
            let error = *q.get(k)? - *target.position.get(k)?;
            let velocity_error = *v.get(k)? - *target.velocity.get(k)?;
            let (stiffness, damping) = (*c.stiffness.get(k)?, *c.damping.get(k)?);
            Some(TaskRow {
                jacobian: RowSVector::from_fn(|_, column| if column == k { T::one() } else { T::zero() }),
                force: -stiffness * error - damping * velocity_error,
                potential: half * stiffness * error * error,
                activation: T::one(),
            })
        })
    }
}

/// Joint impedance: appends, for each selected coordinate `k` (in coordinate order), the row
/// `j = e_kᵀ`, `f = −k_k (q_k − q_des,k) − d_k (q̇_k − q̇_des,k)`,
/// `V_k = ½ k_k (q_k − q_des,k)²`, activation 1. Used alone,
/// `τ = −K (q − q_des) − D (q̇ − q̇_des) = −(∂V/∂q)ᵀ − D (q̇ − q̇_des)` — the impedance (3.54)
/// written in joint coordinates (`x = q`).
///
/// Inputs: `q`, `q̇` (rad, m; rad/s, m/s). Cost O(N²) (the rows are N wide).
/// Errors (rows unchanged): [`TaskError::NonFinite`], [`TaskError::Capacity`].
///
/// ```
/// use kernel::tasks::{joint_impedance::*, TaskRows};
/// use nalgebra::SVector;
/// let task = JointImpedance::try_new(JointImpedanceConfig {
///     selected: [true, false], stiffness: SVector::from([100.0, 100.0]), damping: SVector::from([4.0, 4.0]),
/// }).unwrap();
/// let mut rows = TaskRows::<f64, 2, 2>::new();
/// let target = JointTarget::at_rest(SVector::from([0.5, 0.0]));
/// joint_impedance(&task, &SVector::from([0.4, 1.0]), &SVector::from([0.5, 0.0]), &target, &mut rows).unwrap();
/// // −100·(−0.1) − 4·0.5 = 8 Nm on joint 0 only.
/// assert_eq!(rows.len(), 1);
/// assert!((rows.torque()[0] - 8.0).abs() < 1e-12 && rows.torque()[1] == 0.0);
/// ```
pub fn joint_impedance<T: RealField + Copy, const N: usize, const R: usize>(
    task: &JointImpedance<T, N>,
    q: &SVector<T, N>,
    v: &SVector<T, N>,
    target: &JointTarget<T, N>,
    rows: &mut impl RowSink<T, N, R>,
) -> Result<(), TaskError> {
    let inputs = [q, v, &target.position, &target.velocity];
    if !inputs.iter().all(|x| crate::math::all_finite(*x)) {
        return Err(TaskError::NonFinite);
    }
    if rows.len().saturating_add(task.row_count()) > R {
        return Err(TaskError::Capacity { capacity: R });
    }
    // Each row `e_kᵀ` is built in place in its slot (one entry written into the zero row); a
    // failure removes the rows pushed so far, so that `rows` is left unchanged.
    let c = &task.config;
    let half: T = nalgebra::convert(0.5);
    let start = rows.len();
    let inputs =
        q.as_slice().iter().zip(v.as_slice()).zip(target.position.as_slice().iter().zip(target.velocity.as_slice()));
    let gains = c.stiffness.as_slice().iter().zip(c.damping.as_slice());
    for (k, ((((&qk, &vk), (&qt, &vt)), (&stiffness, &damping)), _)) in
        inputs.zip(gains).zip(c.selected.iter()).enumerate().filter(|(_, (_, &selected))| selected)
    {
        let (error, velocity_error) = (qk - qt, vk - vt);
        let pushed = rows.push_with(|row| {
            if let Some(j) = row.jacobian.get_mut(k) {
                *j = T::one();
            }
            row.force = -stiffness * error - damping * velocity_error;
            row.potential = half * stiffness * error * error;
            row.activation = T::one();
        });
        if let Err(e) = pushed {
            rows.truncate(start);
            return Err(e);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::test_models::{state, N};

    fn task<T: RealField + Copy>() -> JointImpedance<T, N> {
        let c = |x: f64| nalgebra::convert::<f64, T>(x);
        JointImpedance::try_new(JointImpedanceConfig {
            selected: [true, true, false, true, true, true],
            stiffness: SVector::from_fn(|k, _| c(20.0 + 30.0 * k as f64)),
            damping: SVector::from_fn(|k, _| c(1.0 + k as f64)),
        })
        .unwrap()
    }

    /// The rows built in place equal the plain rows (`e_kᵀ`, built whole and copied) bit for
    /// bit, in f64 and f32, after rows already in the list.
    #[test]
    fn in_place_rows_equal_the_plain_rows() {
        fn check<T: RealField + Copy>(seed: u64) {
            let task = task::<T>();
            let q: SVector<T, N> = state(seed, 2.0).cast();
            let v: SVector<T, N> = state(seed + 7, 1.0).cast();
            let target = JointTarget { position: state(seed + 3, 1.0).cast(), velocity: state(seed + 5, 1.0).cast() };
            let mut rows = TaskRows::<T, N, 8>::new();
            let first = TaskRow {
                jacobian: RowSVector::repeat(T::one()),
                force: T::one(),
                potential: T::zero(),
                activation: T::one(),
            };
            rows.push(first).unwrap();
            joint_impedance(&task, &q, &v, &target, &mut rows).unwrap();
            let expected: std::vec::Vec<_> = core::iter::once(first).chain(task.rows(&q, &v, &target)).collect();
            assert_eq!(rows.rows(), expected.as_slice());
            assert_eq!(rows.len(), 1 + task.row_count());
        }
        for seed in 0..20 {
            check::<f64>(seed);
            check::<f32>(seed);
        }
    }

    fn gradient_check<T: RealField + Copy>(h: f64, tolerance: f64) {
        let task = task::<T>();
        for seed in 0..50 {
            let q: SVector<T, N> = state(seed, 2.0).cast();
            let target = JointTarget::at_rest(state(seed ^ 9, 2.0).cast());
            let potential = |q: &SVector<T, N>| {
                let mut rows = TaskRows::<T, N, N>::new();
                joint_impedance(&task, q, &SVector::zeros(), &target, &mut rows).unwrap();
                rows
            };
            let rows = potential(&q);
            assert_eq!(rows.len(), 5);
            let tau = rows.torque();
            let hh: T = nalgebra::convert(h);
            let fd = SVector::<T, N>::from_fn(|k, _| {
                let mut e = SVector::<T, N>::zeros();
                e[k] = hh;
                (potential(&(q + e)).potential() - potential(&(q - e)).potential()) / (hh + hh)
            });
            assert!((tau + fd).amax() <= nalgebra::convert::<f64, T>(tolerance) * (T::one() + tau.amax()));
            assert_eq!(tau[2], T::zero(), "unselected coordinate is free");
        }
    }

    #[test]
    fn force_is_the_negative_gradient() {
        gradient_check::<f64>(1e-6, 1e-6);
        // f32: h = 1e-2 (the potential is quadratic, so only rounding ≈ ε·V/h matters).
        gradient_check::<f32>(1e-2, 1e-4);
    }

    #[test]
    fn damping_acts_on_the_velocity_error() {
        let task = task::<f64>();
        let v = state(1, 1.0);
        let target = JointTarget { position: SVector::zeros(), velocity: v };
        let mut rows = TaskRows::<f64, N, N>::new();
        joint_impedance(&task, &SVector::zeros(), &v, &target, &mut rows).unwrap();
        assert_eq!(rows.torque(), SVector::<f64, N>::zeros());
        rows.clear();
        joint_impedance(&task, &SVector::zeros(), &v, &JointTarget::at_rest(SVector::zeros()), &mut rows).unwrap();
        let expected = SVector::<f64, N>::from_fn(|k, _| if k == 2 { 0.0 } else { -(1.0 + k as f64) * v[k] });
        assert!((rows.torque() - expected).amax() < 1e-15);
    }

    #[test]
    fn bad_input_is_rejected_and_rows_unchanged() {
        let task = task::<f64>();
        let mut rows = TaskRows::<f64, N, 6>::new();
        let target = JointTarget::at_rest(SVector::zeros());
        joint_impedance(&task, &SVector::zeros(), &SVector::zeros(), &target, &mut rows).unwrap();
        let err = joint_impedance(&task, &SVector::zeros(), &SVector::zeros(), &target, &mut rows);
        assert_eq!(err, Err(TaskError::Capacity { capacity: 6 }));
        rows.clear();
        let nan = SVector::repeat(f64::NAN);
        assert_eq!(joint_impedance(&task, &nan, &SVector::zeros(), &target, &mut rows), Err(TaskError::NonFinite));
        assert!(rows.is_empty());
        let mut config = *task.config();
        config.damping[0] = -1.0;
        assert_eq!(JointImpedance::try_new(config), Err(TaskError::InvalidParameter { name: "damping" }));
    }
}
