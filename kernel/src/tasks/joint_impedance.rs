//! Joint impedance (posture task): a spring and damper per selected coordinate, one row `e_kᵀ`
//! each (the "full joint impedance" level of Table 4.1, the torso impedance of Sec. 6.2).
//!
//! **Sampling.** The damping `D = diag(d_k)` brakes the robot's modes through the inverse
//! closed-loop inertia `W = M̃⁻¹`: sampled at `Δt`, a mode's speed changes per cycle by the
//! factor `1 − g`, `g` an eigenvalue of `Δt W D`. The plant applies the command one cycle after
//! it sensed the state, through its torque loop, and that delayed loop rings from `g` ≈ 0.18 on
//! and is unstable beyond `g` ≈ 0.88 (`controller::speed_barrier`, "Stable about a fast
//! motion"). A constant `d_k` sized for the joint's own inertia does not bound `g`: when two
//! joint axes line up (arm joints 1 and 3 of a 7-joint arm with joint 2 near zero), the mode in
//! which they turn against each other moves only the light link between them. On Justin's left
//! arm, 48 N on the hand drove joint 2 to 0.038 rad, `1 / W_kk` of joints 1 and 3 fell to 0.011
//! and 0.009 kg m², and their 8 Nms/rad gave `g` ≈ 1.3: a 167 Hz swing that grew by 10 % per
//! period to 1.87 × the speed limit (realistic one-hour soak, seed 4, 1509.5 s). With a
//! [`SampledLoop`] the task lowers each `d_k` so that `Δt λ_max(W D) ≤ κ` ([`sampled_damping`]),
//! at the state of the cycle; where the joints are heavy enough the damping is the configured one.

use nalgebra::{RealField, SMatrix, SVector};

#[cfg(test)]
use super::TaskRows;
use super::{RowSink, TaskError};
use crate::math::sqrt::sqrt;
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

/// The sampled-loop bound of the damping (module docs, "Sampling").
#[derive(Clone, Copy, Debug)]
pub struct SampledLoop<'a, T, const N: usize> {
    /// The inverse closed-loop inertia `W = M̃⁻¹` at this cycle's state (symmetric, positive
    /// definite).
    pub inverse_inertia: &'a SMatrix<T, N, N>,
    /// The control period `Δt` (s).
    pub period_s: T,
    /// The largest loop gain `κ = Δt λ_max(W D)` the damping may reach, `> 0`.
    pub loop_gain: T,
}

/// The damping of `task` bounded by the sampled loop: `d'_k = d_k min(1, κ / r_k)` with the
/// Gershgorin row sum `r_k = Δt √d_k Σ_j √d_j |W_kj|` over the selected coordinates (the
/// others get no damping from this task and keep theirs).
///
/// Why it holds: `W D'` is similar to `S' = D'^{1/2} W D'^{1/2} = Σ^{1/2} S Σ^{1/2}` with
/// `S = D^{1/2} W D^{1/2}` and `Σ = diag(min(1, κ / r_k))`, and `S'` to `Σ S`, whose row `k`
/// sums to `min(1, κ / r_k) r_k / Δt ≤ κ / Δt` in absolute value: by Gershgorin's theorem
/// every eigenvalue `g` of `Δt W D'` satisfies `g ≤ κ` (and `g ≥ 0`, `W` being positive
/// definite). Cost: one pass over the columns of `W` of the selected coordinates (`√d_k` is
/// computed once, in [`JointImpedance::try_new`]).
/// Errors: [`TaskError::NonFinite`] if `W` or the period is not finite, or `κ` is not positive.
pub fn sampled_damping<T: RealField + Copy, const N: usize>(
    task: &JointImpedance<T, N>,
    sampled: &SampledLoop<'_, T, N>,
) -> Result<SVector<T, N>, TaskError> {
    let (period, gain) = (sampled.period_s, sampled.loop_gain);
    if !(period.is_finite() && period > T::zero() && gain.is_finite() && gain > T::zero()) {
        return Err(TaskError::NonFinite);
    }
    let root = &task.root_damping;
    let mut damping = SVector::<T, N>::zeros();
    // `W` is symmetric: its column `k` (contiguous in storage) is its row `k`.
    let columns = sampled.inverse_inertia.as_slice().chunks_exact(N);
    let root = root.as_slice();
    let rows = columns.zip(root).zip(task.config.damping.as_slice()).zip(damping.as_mut_slice());
    for (((w, &root_k), &configured), d) in rows.filter(|(((_, root_k), _), _)| **root_k > T::zero()) {
        let sum = w.iter().zip(root).fold(T::zero(), |s, (w_kj, root_j)| s + w_kj.abs() * *root_j);
        let r = period * root_k * sum;
        if !r.is_finite() {
            return Err(TaskError::NonFinite);
        }
        *d = if r > gain { configured * gain / r } else { configured };
    }
    Ok(damping)
}

/// A validated joint impedance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointImpedance<T, const N: usize> {
    config: JointImpedanceConfig<T, N>,
    /// `√d_k` of the selected coordinates, 0 for the others ([`sampled_damping`]).
    root_damping: SVector<T, N>,
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
        let root_damping = SVector::<T, N>::from_fn(|k, _| {
            let selected = config.selected.get(k).copied().unwrap_or(false);
            if selected {
                config.damping.get(k).map_or(T::zero(), |d| sqrt(*d))
            } else {
                T::zero()
            }
        });
        Ok(Self { config, root_damping })
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
/// With `sampled`, `d_k` is the bounded damping of [`sampled_damping`]; without, the
/// configured one.
///
/// Inputs: `q`, `q̇` (rad, m; rad/s, m/s). Cost O(N²) (the rows are N wide, and the bound).
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
/// joint_impedance(&task, &SVector::from([0.4, 1.0]), &SVector::from([0.5, 0.0]), &target, None, &mut rows).unwrap();
/// // −100·(−0.1) − 4·0.5 = 8 Nm on joint 0 only.
/// assert_eq!(rows.len(), 1);
/// assert!((rows.torque()[0] - 8.0).abs() < 1e-12 && rows.torque()[1] == 0.0);
/// ```
pub fn joint_impedance<T: RealField + Copy, const N: usize, const R: usize>(
    task: &JointImpedance<T, N>,
    q: &SVector<T, N>,
    v: &SVector<T, N>,
    target: &JointTarget<T, N>,
    sampled: Option<&SampledLoop<'_, T, N>>,
    rows: &mut impl RowSink<T, N, R>,
) -> Result<(), TaskError> {
    let inputs = [q, v, &target.position, &target.velocity];
    if !inputs.iter().all(|x| crate::math::all_finite(*x)) {
        return Err(TaskError::NonFinite);
    }
    if rows.len().saturating_add(task.row_count()) > R {
        return Err(TaskError::Capacity { capacity: R });
    }
    // Each row `e_kᵀ` is built in place in its slot (its one column written into the zero row); a
    // failure removes the rows pushed so far, so that `rows` is left unchanged.
    let c = &task.config;
    let damping = match sampled {
        Some(sampled) => sampled_damping(task, sampled)?,
        None => c.damping,
    };
    let half: T = nalgebra::convert(0.5);
    let start = rows.len();
    let inputs =
        q.as_slice().iter().zip(v.as_slice()).zip(target.position.as_slice().iter().zip(target.velocity.as_slice()));
    let gains = c.stiffness.as_slice().iter().zip(damping.as_slice());
    for (k, ((((&qk, &vk), (&qt, &vt)), (&stiffness, &damping)), _)) in
        inputs.zip(gains).zip(c.selected.iter()).enumerate().filter(|(_, (_, &selected))| selected)
    {
        let (error, velocity_error) = (qk - qt, vk - vt);
        let pushed = rows.push_with(k..k + 1, |row| {
            if let Some(j) = row.jacobian.first_mut() {
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
            joint_impedance(&task, &q, &v, &target, None, &mut rows).unwrap();
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
                joint_impedance(&task, q, &SVector::zeros(), &target, None, &mut rows).unwrap();
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
        joint_impedance(&task, &SVector::zeros(), &v, &target, None, &mut rows).unwrap();
        assert_eq!(rows.torque(), SVector::<f64, N>::zeros());
        rows.clear();
        joint_impedance(&task, &SVector::zeros(), &v, &JointTarget::at_rest(SVector::zeros()), None, &mut rows)
            .unwrap();
        let expected = SVector::<f64, N>::from_fn(|k, _| if k == 2 { 0.0 } else { -(1.0 + k as f64) * v[k] });
        assert!((rows.torque() - expected).amax() < 1e-15);
    }

    #[test]
    fn bad_input_is_rejected_and_rows_unchanged() {
        let task = task::<f64>();
        let mut rows = TaskRows::<f64, N, 6>::new();
        let target = JointTarget::at_rest(SVector::zeros());
        joint_impedance(&task, &SVector::zeros(), &SVector::zeros(), &target, None, &mut rows).unwrap();
        let err = joint_impedance(&task, &SVector::zeros(), &SVector::zeros(), &target, None, &mut rows);
        assert_eq!(err, Err(TaskError::Capacity { capacity: 6 }));
        rows.clear();
        let nan = SVector::repeat(f64::NAN);
        assert_eq!(
            joint_impedance(&task, &nan, &SVector::zeros(), &target, None, &mut rows),
            Err(TaskError::NonFinite)
        );
        assert!(rows.is_empty());
        let mut config = *task.config();
        config.damping[0] = -1.0;
        assert_eq!(JointImpedance::try_new(config), Err(TaskError::InvalidParameter { name: "damping" }));
    }

    /// A symmetric positive definite `W` with entries of the order of `scale`.
    fn inverse_inertia(seed: u64, scale: f64) -> nalgebra::SMatrix<f64, N, N> {
        let a = nalgebra::SMatrix::<f64, N, N>::from_fn(|i, j| state(seed + i as u64, 1.0)[j]);
        (a * a.transpose() + nalgebra::SMatrix::identity() * 0.05) * scale
    }

    /// `Δt λ_max(W D)` of a diagonal damping.
    fn loop_gain(w: &nalgebra::SMatrix<f64, N, N>, damping: &SVector<f64, N>, period: f64) -> f64 {
        let root = nalgebra::SMatrix::<f64, N, N>::from_diagonal(&damping.map(f64::sqrt));
        period * (root * w * root).symmetric_eigenvalues().max()
    }

    /// The bounded damping keeps `Δt λ_max(W D)` within `κ` for random inertias and dampings,
    /// never exceeds the configured damping, and equals it where the bound does not bind.
    #[test]
    fn the_sampled_damping_keeps_the_loop_gain_within_its_bound() {
        let (period, kappa) = (1e-3, 0.4);
        let mut bound_binds = 0;
        for seed in 0..200 {
            let w = inverse_inertia(seed, 10.0 + 40.0 * (seed % 7) as f64);
            let task = JointImpedance::try_new(JointImpedanceConfig {
                selected: [true, true, false, true, true, true],
                stiffness: SVector::zeros(),
                damping: state(seed + 11, 5.0).map(|x| x.abs() + 0.5),
            })
            .unwrap();
            let sampled = SampledLoop { inverse_inertia: &w, period_s: period, loop_gain: kappa };
            let damping = sampled_damping(&task, &sampled).unwrap();
            assert!(loop_gain(&w, &damping, period) <= kappa * (1.0 + 1e-12));
            assert_eq!(damping[2], 0.0, "unselected coordinate");
            let configured = task.config().damping;
            let root = SVector::<f64, N>::from_fn(|k, _| if k == 2 { 0.0 } else { configured[k].sqrt() });
            for k in [0, 1, 3, 4, 5] {
                let row = period * root[k] * (0..N).map(|j| w[(k, j)].abs() * root[j]).sum::<f64>();
                if row <= kappa {
                    assert_eq!(damping[k], configured[k]);
                } else {
                    assert!(damping[k] < configured[k] && damping[k] > 0.0);
                    bound_binds += 1;
                }
            }
        }
        assert!(bound_binds > 100 && bound_binds < 900, "{bound_binds} of 1000 rows bound");
    }

    /// Two joints whose axes line up (arm joints 1 and 3 with joint 2 near zero; `1 / W_kk` =
    /// 0.011 and 0.009 kg m², the realistic soak's seed 4): 8 Nms/rad on each gives the delayed
    /// loop `v_{k+1} = v_k − Δt W D v_{k−1}` a gain above 1, and the mode in which they turn
    /// against each other grows; bounded to κ = 0.4 it decays.
    #[test]
    fn the_sampled_damping_stops_the_swing_of_two_aligned_joints() {
        let (m1, m3, correlation) = (0.011, 0.009, 0.95);
        let mut w = nalgebra::SMatrix::<f64, N, N>::identity();
        w[(0, 0)] = 1.0 / m1;
        w[(1, 1)] = 1.0 / m3;
        w[(0, 1)] = -correlation / (m1 * m3).sqrt();
        w[(1, 0)] = w[(0, 1)];
        let task = JointImpedance::try_new(JointImpedanceConfig {
            selected: [true, true, false, false, false, false],
            stiffness: SVector::zeros(),
            damping: SVector::from_fn(|k, _| if k < 2 { 8.0 } else { 0.0 }),
        })
        .unwrap();
        let period = 1e-3;
        let sampled = SampledLoop { inverse_inertia: &w, period_s: period, loop_gain: 0.4 };
        let bounded = sampled_damping(&task, &sampled).unwrap();
        let configured = task.config().damping;
        assert!(loop_gain(&w, &configured, period) > 1.5);
        assert!(loop_gain(&w, &bounded, period) <= 0.4 * (1.0 + 1e-12));
        let swing = |damping: &SVector<f64, N>| {
            let (mut previous, mut v) = (SVector::<f64, N>::zeros(), SVector::<f64, N>::zeros());
            (v[0], v[1]) = (1.0, -1.0);
            for _ in 0..200 {
                let next = v - w * damping.component_mul(&previous) * period;
                (previous, v) = (v, next);
            }
            v.norm() / 2f64.sqrt()
        };
        assert!(swing(&configured) > 1e3, "configured damping: {}", swing(&configured));
        assert!(swing(&bounded) < 0.5, "bounded damping: {}", swing(&bounded));
    }

    #[test]
    fn a_non_finite_inverse_inertia_is_rejected() {
        let task = task::<f64>();
        let mut w = inverse_inertia(3, 10.0);
        w[(1, 4)] = f64::NAN;
        let sampled = SampledLoop { inverse_inertia: &w, period_s: 1e-3, loop_gain: 0.25 };
        assert_eq!(sampled_damping(&task, &sampled), Err(TaskError::NonFinite));
        let mut rows = TaskRows::<f64, N, N>::new();
        let target = JointTarget::at_rest(SVector::zeros());
        let z = SVector::zeros();
        assert_eq!(joint_impedance(&task, &z, &z, &target, Some(&sampled), &mut rows), Err(TaskError::NonFinite));
        assert!(rows.is_empty());
    }
}
