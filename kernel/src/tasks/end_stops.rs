//! Avoidance of mechanical end stops (Sec. 3.4.3, (3.58)–(3.59)) as unilateral task rows, and
//! the continuous activation (4.65)/(4.68) shared by the unilateral tasks.
//!
//! An end stop bounds a linear combination of coordinates `s = c q + s₀` to `[s_min, s_max]`.
//! For an ordinary joint `c = e_kᵀ`; for Justin's passive torso joint `q_t4 = −(q_t2 + q_t3)`
//! (3.41) the combination is `c = −(e_t2 + e_t3)ᵀ` ([`EndStopConfig::drive`] builds it from the
//! joint's drive). The repulsive potential (3.58) starts a `margin` inside each stop, at
//! `s_lower = s_min + margin` and `s_upper = s_max − margin`.
//!
//! **Unilateral-row convention.** Every end stop always emits exactly one row, so the row count
//! (and the cost) of a step does not depend on the state and the hierarchy sees each constraint
//! fade in through its activation. Inside the free range `s_lower < s < s_upper` the row has
//! activation 0, force 0 and potential 0. Within the margin the activation rises with the
//! cubic (4.68) from 0 at the start of the potential to 1 at the mechanical stop; damping acts
//! only in proportion to the activation, so the force stays continuous.

use nalgebra::{RealField, RowSVector, SVector};

#[cfg(test)]
use super::TaskRows;
use super::{RowEntries, RowSink, TaskError, TaskRow};
use crate::model::JointDrive;

use crate::math::switching::transition_activation;

/// Parameters of one end stop (Sec. 3.4.3): the constrained combination `s = c q + s₀`, its
/// mechanical range and the potential's gains. Validate with [`EndStop::try_new`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EndStopConfig<T, const N: usize> {
    /// Combination `c` (1×N, dimensionless): the row's Jacobian `j = c`.
    pub combination: RowSVector<T, N>,
    /// Offset `s₀` (rad or m).
    pub offset: T,
    /// Mechanical lower stop `s_min` (rad or m); `−∞` for none.
    pub lower: T,
    /// Mechanical upper stop `s_max` (rad or m); `+∞` for none.
    pub upper: T,
    /// Distance from each stop at which the potential starts (rad or m), `> 0`:
    /// `s_lower = s_min + margin`, `s_upper = s_max − margin`.
    pub margin: T,
    /// Stiffness `k_mes` of (3.58), `V = k_mes (s − s_lower)²` (J/rad² or J/m²); note the
    /// thesis' potential has no factor ½, so the spring rate is `2 k_mes`.
    pub stiffness: T,
    /// Damping `d` (Nms/rad or Ns/m) of (3.59) along the row, applied as `a·d·ṡ`.
    pub damping: T,
}

impl<T: RealField + Copy, const N: usize> EndStopConfig<T, N> {
    /// An end stop of coordinate `coordinate` (`c = e_kᵀ`, `s₀ = 0`). A coordinate `≥ N`
    /// gives a zero combination, which [`EndStop::try_new`] rejects.
    pub fn coordinate(coordinate: usize, lower: T, upper: T, margin: T, stiffness: T, damping: T) -> Self {
        let combination = RowSVector::from_fn(|_, k| if k == coordinate { T::one() } else { T::zero() });
        Self { combination, offset: T::zero(), lower, upper, margin, stiffness, damping }
    }

    /// An end stop of a (possibly coupled) joint's value `q_joint = Σ c_k q_k + offset`, from its
    /// [`JointDrive`]; e.g. Justin's `q_t4 = −(q_t2 + q_t3)` (3.41) gives `c = −(e_t2 + e_t3)ᵀ`.
    pub fn drive(drive: &JointDrive<T>, lower: T, upper: T, margin: T, stiffness: T, damping: T) -> Self {
        let mut combination = RowSVector::<T, N>::zeros();
        for term in drive.terms() {
            if let Some(c) = combination.get_mut(term.coordinate) {
                *c += term.coefficient;
            }
        }
        Self { combination, offset: drive.offset(), lower, upper, margin, stiffness, damping }
    }
}

/// A validated end stop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EndStop<T, const N: usize> {
    config: EndStopConfig<T, N>,
    /// `(first, end)`: the entries of `c` outside `first..end` are zero.
    support: (usize, usize),
}

impl<T: RealField + Copy, const N: usize> EndStop<T, N> {
    /// Validates `config`: finite nonzero combination, finite offset, `margin > 0`, stops not
    /// NaN (infinite allowed) with `s_min + margin ≤ s_max − margin`, finite `k_mes ≥ 0` and
    /// `d ≥ 0`. Errors: [`TaskError::InvalidParameter`] naming the field.
    pub fn try_new(config: EndStopConfig<T, N>) -> Result<Self, TaskError> {
        let invalid = |name| Err(TaskError::InvalidParameter { name });
        let c = &config;
        if !crate::math::all_finite(&c.combination) || c.combination.iter().all(|x| *x == T::zero()) {
            return invalid("combination");
        }
        if !c.offset.is_finite() {
            return invalid("offset");
        }
        if !(c.margin.is_finite() && c.margin > T::zero()) {
            return invalid("margin");
        }
        // Stops may be infinite (a one-sided or no stop) but not NaN, not `+∞` below or `−∞`
        // above, and must leave room for both margins.
        let lower_ok = c.lower.is_finite() || c.lower < T::zero();
        let upper_ok = c.upper.is_finite() || c.upper > T::zero();
        if !(lower_ok && upper_ok && c.lower + c.margin + c.margin <= c.upper) {
            return invalid("limits");
        }
        if !(c.stiffness.is_finite() && c.stiffness >= T::zero()) {
            return invalid("stiffness");
        }
        if !(c.damping.is_finite() && c.damping >= T::zero()) {
            return invalid("damping");
        }
        let combination = config.combination.as_slice();
        let first = combination.iter().position(|x| *x != T::zero()).unwrap_or(0);
        let end = combination.iter().rposition(|x| *x != T::zero()).map_or(first, |last| last + 1);
        Ok(Self { config, support: (first, end) })
    }

    /// The validated parameters.
    pub fn config(&self) -> &EndStopConfig<T, N> {
        &self.config
    }

    /// The row of this end stop at `(q, q̇)`: `s = c q + s₀`, `ṡ = c q̇`, penetration
    /// `Δ = s − s_lower` below `s_lower`, `Δ = s − s_upper` above `s_upper`, else 0;
    /// potential `V = k_mes Δ²` (3.58), force `f = −2 k_mes Δ − a d ṡ` (3.59), activation `a`
    /// ([`transition_activation`] of the distance to the nearer stop, full at the stop, zero
    /// where the potential starts).
    pub fn row(&self, q: &SVector<T, N>, v: &SVector<T, N>) -> TaskRow<T, N> {
        let (force, potential, activation) = self.terms(q, v);
        TaskRow { jacobian: self.config.combination, force, potential, activation }
    }

    /// Force, potential and activation of [`Self::row`] ((3.58), (3.59), (4.68)); `c q` and
    /// `c q̇` run over the nonzero entries of `c` only (one for an ordinary joint), within its
    /// support `first..end`.
    fn terms(&self, q: &SVector<T, N>, v: &SVector<T, N>) -> (T, T, T) {
        let c = &self.config;
        let (mut cq, mut rate) = (T::zero(), T::zero());
        let (first, end) = self.support;
        let combination = c.combination.as_slice().get(first..end).unwrap_or(&[]);
        let (q, v) = (q.as_slice().iter().skip(first), v.as_slice().iter().skip(first));
        for ((&ck, &qk), &vk) in combination.iter().zip(q).zip(v) {
            if ck != T::zero() {
                cq += ck * qk;
                rate += ck * vk;
            }
        }
        let s = cq + c.offset;
        let (s_lower, s_upper) = (c.lower + c.margin, c.upper - c.margin);
        let penetration = if s < s_lower {
            s - s_lower
        } else if s > s_upper {
            s - s_upper
        } else {
            T::zero()
        };
        let activation = transition_activation(s - c.lower, T::zero(), c.margin).max(transition_activation(
            c.upper - s,
            T::zero(),
            c.margin,
        ));
        let two: T = nalgebra::convert(2.0);
        (
            -two * c.stiffness * penetration - activation * c.damping * rate,
            c.stiffness * penetration * penetration,
            activation,
        )
    }

    /// Writes [`Self::row`] into the entries of its support columns (`row.jacobian` holds the
    /// columns `first..end` of [`Self::support`], zero): only the nonzero entries of `c` are
    /// written.
    fn fill(&self, q: &SVector<T, N>, v: &SVector<T, N>, row: &mut RowEntries<'_, T>) {
        let (force, potential, activation) = self.terms(q, v);
        let (first, end) = self.support;
        let combination = self.config.combination.as_slice().get(first..end).unwrap_or(&[]);
        for (j, &ck) in row.jacobian.iter_mut().zip(combination) {
            if ck != T::zero() {
                *j = ck;
            }
        }
        row.force = force;
        row.potential = potential;
        row.activation = activation;
    }
}

/// End-stop avoidance (3.58)–(3.59): appends one row per end stop in `stops` (see the module
/// docs for the unilateral-row convention). Used alone, `τ = Σ cᵀ f = −(∂Σ V_mes/∂q)ᵀ − D q̇`
/// with `D = Σ a d cᵀ c`.
///
/// Inputs: coordinates `q` and velocities `q̇` (rad, m; rad/s, m/s). Cost O(N) per stop.
/// Errors (the row list is unchanged): [`TaskError::NonFinite`] for a non-finite state or row,
/// [`TaskError::Capacity`] if the rows do not fit.
///
/// ```
/// use kernel::tasks::{end_stops::{end_stops, EndStop, EndStopConfig}, TaskRows};
/// use nalgebra::SVector;
/// // Joint 0 in [−1, 1] rad, margin 0.2 rad, k = 50 Nm/rad²: at q = 0.9 the potential is
/// // 50·0.1² = 0.5 J and the force −2·50·0.1 = −10 Nm.
/// let stop = EndStop::try_new(EndStopConfig::coordinate(0, -1.0, 1.0, 0.2, 50.0, 0.0)).unwrap();
/// let mut rows = TaskRows::<f64, 2, 4>::new();
/// end_stops(&[stop], &SVector::from([0.9, 0.0]), &SVector::zeros(), &mut rows).unwrap();
/// assert!((rows.rows()[0].force + 10.0).abs() < 1e-12 && (rows.potential() - 0.5).abs() < 1e-12);
/// ```
pub fn end_stops<T: RealField + Copy, const N: usize, const R: usize>(
    stops: &[EndStop<T, N>],
    q: &SVector<T, N>,
    v: &SVector<T, N>,
    rows: &mut impl RowSink<T, N, R>,
) -> Result<(), TaskError> {
    if !(crate::math::all_finite(q) && crate::math::all_finite(v)) {
        return Err(TaskError::NonFinite);
    }
    if rows.len().saturating_add(stops.len()) > R {
        return Err(TaskError::Capacity { capacity: R });
    }
    // Each row is built in place in its slot; a failure removes the rows pushed so far, so
    // that `rows` is left unchanged.
    let start = rows.len();
    for stop in stops {
        let (first, end) = stop.support;
        if let Err(e) = rows.push_with(first..end, |row| stop.fill(q, v, row)) {
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
    use crate::model::BodyId;
    use crate::test_models::{branched, state, N};

    /// Stops of the branched test model: two coordinate stops and the coupled joint
    /// `q_passive = −(q2 + q3) + 0.1` (body 4), like Justin's q_t4.
    fn stops<T: RealField + Copy>() -> [EndStop<T, N>; 3] {
        let c = |x: f64| nalgebra::convert::<f64, T>(x);
        let model = branched::<T>();
        let coupled = &model.body(BodyId(4)).unwrap().drive;
        [
            EndStop::try_new(EndStopConfig::coordinate(1, c(-1.0), c(1.2), c(0.3), c(40.0), c(2.0))).unwrap(),
            EndStop::try_new(EndStopConfig::coordinate(3, c(-0.5), c(f64::INFINITY), c(0.2), c(80.0), c(1.0))).unwrap(),
            EndStop::try_new(EndStopConfig::drive(coupled, c(-0.8), c(0.7), c(0.25), c(60.0), c(3.0))).unwrap(),
        ]
    }

    fn potential<T: RealField + Copy>(stops: &[EndStop<T, N>], q: &SVector<T, N>) -> T {
        let mut rows = TaskRows::<T, N, 4>::new();
        end_stops(stops, q, &SVector::zeros(), &mut rows).unwrap();
        rows.potential()
    }

    /// Σ jᵀ f (v = 0) against central differences of Σ V over q, at states that put the stops
    /// in every region.
    fn gradient_check<T: RealField + Copy>(h: f64, tolerance: f64) {
        let stops = stops::<T>();
        let mut active = 0;
        for seed in 0..200 {
            let q: SVector<T, N> = state(seed, 1.4).cast();
            let mut rows = TaskRows::<T, N, 4>::new();
            end_stops(&stops, &q, &SVector::zeros(), &mut rows).unwrap();
            active += rows.rows().iter().filter(|r| r.activation > T::zero()).count();
            let tau = rows.torque();
            let hh: T = nalgebra::convert(h);
            let fd = SVector::<T, N>::from_fn(|k, _| {
                let mut e = SVector::<T, N>::zeros();
                e[k] = hh;
                (potential(&stops, &(q + e)) - potential(&stops, &(q - e))) / (hh + hh)
            });
            let err = (tau + fd).amax();
            let scale = tau.amax() + T::one();
            assert!(err <= nalgebra::convert::<f64, T>(tolerance) * scale, "seed {seed}: {err} vs {scale}");
        }
        assert!(active > 50, "the states must exercise the stops ({active})");
    }

    #[test]
    fn force_is_the_negative_gradient_f64() {
        gradient_check::<f64>(1e-6, 1e-6);
    }

    #[test]
    fn force_is_the_negative_gradient_f32() {
        // f32: h = 1e-3 rad, rounding error ≈ ε·V/h; stated tolerance 1e-3 of the torque scale.
        gradient_check::<f32>(1e-3, 1e-3);
    }

    #[test]
    fn coupled_stop_row_is_minus_the_sum_of_the_driving_coordinates() {
        let stops = stops::<f64>();
        let j = stops[2].config().combination;
        let mut expected = RowSVector::<f64, N>::zeros();
        expected[2] = -1.0;
        expected[3] = -1.0;
        assert_eq!(j, expected);
        assert_eq!(stops[2].config().offset, 0.1);
        // s = −(q2 + q3) + 0.1 = 0.6 > s_upper = 0.45: pushed down with 2·60·0.15 = 18.
        let mut q = SVector::<f64, N>::zeros();
        q[2] = -0.3;
        q[3] = -0.2;
        let row = stops[2].row(&q, &SVector::zeros());
        assert!((row.force + 18.0).abs() < 1e-12, "{}", row.force);
        // τ = jᵀ f pushes q2 and q3 up (s down).
        assert!(row.jacobian[2] * row.force > 0.0);
    }

    #[test]
    fn inside_the_free_range_the_row_is_inactive() {
        let stop = EndStop::try_new(EndStopConfig::coordinate(0, -1.0, 1.0, 0.2, 50.0, 5.0)).unwrap();
        let row = stop.row(&SVector::<f64, 1>::new(0.5), &SVector::<f64, 1>::new(3.0));
        assert_eq!((row.activation, row.force, row.potential), (0.0, 0.0, 0.0));
        // At the mechanical stop the activation is 1 and the damping acts fully.
        let row = stop.row(&SVector::<f64, 1>::new(-1.0), &SVector::<f64, 1>::new(-2.0));
        assert_eq!(row.activation, 1.0);
        assert!((row.force - (2.0 * 50.0 * 0.2 + 5.0 * 2.0)).abs() < 1e-12);
    }

    /// (3.58) is C¹ at s_lower and s_upper: value and slope are continuous (both → 0), the
    /// second derivative jumps from 0 to 2k (the thesis does not claim C²). The activation and
    /// hence the damping force are C¹ as well.
    #[test]
    fn potential_and_activation_are_c1_at_the_boundaries() {
        let k = 50.0;
        let stop = EndStop::try_new(EndStopConfig::coordinate(0, -1.0, 1.0, 0.2, k, 5.0)).unwrap();
        let at = |s: f64| stop.row(&SVector::<f64, 1>::new(s), &SVector::zeros());
        for boundary in [-0.8, 0.8] {
            for delta in [1e-4, 1e-6] {
                let (inner, outer) = if boundary < 0.0 {
                    (boundary + delta, boundary - delta)
                } else {
                    (boundary - delta, boundary + delta)
                };
                let (a, b) = (at(inner), at(outer));
                assert!((a.potential - b.potential).abs() <= k * delta * delta * 1.000_001);
                assert!((a.force - b.force).abs() <= 2.0 * k * delta * 1.000_001);
                assert!((a.activation - b.activation).abs() < 10.0 * delta * delta / 0.04);
            }
            // Second derivative of V: 0 inside, 2k outside (finite differences of the force).
            let h = 1e-5;
            let side = boundary.signum();
            let outside = (at(boundary + side * 3.0 * h).force - at(boundary + side * h).force) / (2.0 * h);
            let inside = (at(boundary - side * 3.0 * h).force - at(boundary - side * h).force) / (2.0 * h);
            assert!((outside.abs() - 2.0 * k).abs() < 1e-6 && inside == 0.0);
        }
        // Activation slope is zero at both ends of the transition (σ = 0 and σ = 1).
        let slope =
            |t: f64| (transition_activation(t + 1e-7, 0.0, 0.2) - transition_activation(t - 1e-7, 0.0, 0.2)) / 2e-7;
        assert!(slope(0.0).abs() < 1e-5 && slope(0.2).abs() < 1e-5);
        assert!((slope(0.1) + 1.5 / 0.2).abs() < 1e-6, "largest slope N'max = 1.5/(ϑ₂ − ϑ₁) (4.69)");
    }

    #[test]
    fn rows_built_in_place_equal_the_plain_rows() {
        fn check<T: RealField + Copy>(seed: u64, tolerance: f64) {
            let stops = stops::<T>();
            let q: SVector<T, N> = state(seed, 3.0).cast();
            let v: SVector<T, N> = state(seed + 11, 2.0).cast();
            let mut rows = TaskRows::<T, N, 4>::new();
            end_stops(&stops, &q, &v, &mut rows).unwrap();
            for (row, stop) in rows.rows().iter().zip(&stops) {
                assert_eq!(*row, stop.row(&q, &v));
                // Against the dense products `c q + s₀`, `c q̇` of (3.58)–(3.59).
                let c = stop.config();
                let s = (c.combination * q).x + c.offset;
                let rate = (c.combination * v).x;
                let (s_lower, s_upper) = (c.lower + c.margin, c.upper - c.margin);
                let penetration = if s < s_lower {
                    s - s_lower
                } else if s > s_upper {
                    s - s_upper
                } else {
                    T::zero()
                };
                let two: T = nalgebra::convert(2.0);
                let force = -two * c.stiffness * penetration - row.activation * c.damping * rate;
                let scale = T::one() + force.abs();
                assert!((row.force - force).abs() <= nalgebra::convert::<f64, T>(tolerance) * scale, "seed {seed}");
            }
            assert_eq!(rows.len(), stops.len());
        }
        for seed in 0..50 {
            check::<f64>(seed, 1e-12);
            check::<f32>(seed, 1e-4);
        }
    }

    #[test]
    fn a_non_finite_row_removes_the_rows_pushed_before_it() {
        let stops = stops::<f64>();
        let overflow = EndStop::try_new(EndStopConfig::coordinate(0, -1.0, 1.0, 0.2, f64::MAX, 1.0)).unwrap();
        let mut q = SVector::<f64, N>::zeros();
        q[0] = 0.95;
        let mut rows = TaskRows::<f64, N, 8>::new();
        end_stops(&stops[..1], &q, &SVector::zeros(), &mut rows).unwrap();
        let before = rows.clone();
        let list = [stops[1], stops[2], overflow];
        assert_eq!(end_stops(&list, &q, &SVector::zeros(), &mut rows), Err(TaskError::NonFinite));
        assert_eq!(rows, before);
    }

    #[test]
    fn errors_leave_the_rows_unchanged() {
        let stops = stops::<f64>();
        let q = state(3, 1.0);
        let mut rows = TaskRows::<f64, N, 4>::new();
        end_stops(&stops[..2], &q, &SVector::zeros(), &mut rows).unwrap();
        assert_eq!(end_stops(&stops, &q, &SVector::zeros(), &mut rows), Err(TaskError::Capacity { capacity: 4 }));
        let mut bad = q;
        bad[0] = f64::NAN;
        assert_eq!(end_stops(&stops, &bad, &SVector::zeros(), &mut rows), Err(TaskError::NonFinite));
        assert_eq!(rows.len(), 2);
        let invalid = |c: EndStopConfig<f64, N>| EndStop::try_new(c).err();
        let good = EndStopConfig::coordinate(0, -1.0, 1.0, 0.2, 1.0, 1.0);
        assert_eq!(
            invalid(EndStopConfig::coordinate(N, -1.0, 1.0, 0.2, 1.0, 1.0)),
            Some(TaskError::InvalidParameter { name: "combination" })
        );
        assert_eq!(
            invalid(EndStopConfig { margin: 0.0, ..good }),
            Some(TaskError::InvalidParameter { name: "margin" })
        );
        assert_eq!(
            invalid(EndStopConfig { margin: 1.1, ..good }),
            Some(TaskError::InvalidParameter { name: "limits" })
        );
        assert_eq!(invalid(EndStopConfig { lower: 2.0, ..good }), Some(TaskError::InvalidParameter { name: "limits" }));
        assert_eq!(
            invalid(EndStopConfig { upper: f64::NAN, ..good }),
            Some(TaskError::InvalidParameter { name: "limits" })
        );
        assert_eq!(
            invalid(EndStopConfig { stiffness: -1.0, ..good }),
            Some(TaskError::InvalidParameter { name: "stiffness" })
        );
        assert_eq!(
            invalid(EndStopConfig { damping: f64::INFINITY, ..good }),
            Some(TaskError::InvalidParameter { name: "damping" })
        );
    }
}
