//! The closed loop of the compensated mobile impedance, (5.16)–(5.22): its inertia, its storage
//! function and rate, and a passivity monitor for telemetry.
//!
//! With the coupling compensation (5.13)–(5.14) the closed loop is
//! `M ÿ + C ẏ + D ẏ = τ_imp + τ_rq,ext` (5.16) with `M = blockdiag(M_adm, M_qq)` (5.17),
//! `C = blockdiag(0, C_qq)` (5.18), `D = blockdiag(D_adm, D_qq)` (5.19). Its storage function
//!
//! `V(x̃, ẏ) = ½ ẏᵀ M ẏ + V_imp(x̃)` (5.21)
//!
//! has the rate `V̇ = ẏᵀ τ_rq,ext − ẏᵀ D ẏ` (5.22) (with `Ṁ = C + Cᵀ`, which holds blockwise),
//! so the closed loop is strictly output passive. "The storage function (5.21) does not match
//! the real physical energy due to the use of the admittance inertia" (footnote 3). Without the
//! compensation nothing bounds `V`: the [`PassivityMonitor`] flags it when it grows by more
//! than the energy supplied from outside.

use nalgebra::{RealField, SMatrix, SVector, Vector3};

use super::{PlatformError, PlatformLayout};

/// Closed-loop inertia `M = blockdiag(M_adm, M_qq)` (5.17) from the physical `M(y)`.
///
/// The rows and columns of every platform coordinate are cleared (the couplings `M_qr`,
/// `M_rq` and the physical platform inertia are replaced); an admitted axis gets its admittance
/// inertia `m_i,adm` on the diagonal. A **locked** axis is not part of `y` (its velocity is
/// zero); it keeps its physical diagonal entry so that the matrix stays positive definite and,
/// used for a damping design, sees the platform's real inertia. Cost O(N).
///
/// ```
/// use kernel::platform::{storage::closed_loop_inertia, PlatformAxis, PlatformLayout};
/// use nalgebra::{Matrix3, Vector3};
/// let physical = Matrix3::new(3.0, 2.0, 1.0, 2.0, 2.0, 1.0, 1.0, 1.0, 1.0_f64); // Fig. 5.2
/// let layout = PlatformLayout::try_new::<3>([PlatformAxis::Admitted(0), PlatformAxis::Absent, PlatformAxis::Absent]).unwrap();
/// let m = closed_loop_inertia(&physical, &layout, &Vector3::new(0.8, 1.0, 1.0));
/// assert_eq!(m, Matrix3::new(0.8, 0.0, 0.0, 0.0, 2.0, 1.0, 0.0, 1.0, 1.0));
/// ```
pub fn closed_loop_inertia<T: RealField + Copy, const N: usize>(
    mass_matrix: &SMatrix<T, N, N>,
    layout: &PlatformLayout,
    admittance_mass: &Vector3<T>,
) -> SMatrix<T, N, N> {
    let mut m = *mass_matrix;
    clear_platform(&mut m, mass_matrix, layout, admittance_mass);
    m
}

/// [`closed_loop_inertia`] (5.17) written into `out` (one copy of `M(y)`, no temporary).
pub fn closed_loop_inertia_into<T: RealField + Copy, const N: usize>(
    mass_matrix: &SMatrix<T, N, N>,
    layout: &PlatformLayout,
    admittance_mass: &Vector3<T>,
    out: &mut SMatrix<T, N, N>,
) {
    out.copy_from(mass_matrix);
    clear_platform(out, mass_matrix, layout, admittance_mass);
}

/// Clears the rows and columns of the platform coordinates of `m` (a copy of `mass_matrix`)
/// and sets their diagonal as [`closed_loop_inertia`] does.
#[inline(always)]
fn clear_platform<T: RealField + Copy, const N: usize>(
    m: &mut SMatrix<T, N, N>,
    mass_matrix: &SMatrix<T, N, N>,
    layout: &PlatformLayout,
    admittance_mass: &Vector3<T>,
) {
    for (axis, adm) in layout.axes().iter().zip(admittance_mass.iter()) {
        let Some(c) = axis.coordinate() else { continue };
        let diagonal = if axis.is_admitted() { *adm } else { mass_matrix.get((c, c)).copied().unwrap_or_else(T::one) };
        for k in 0..N {
            if let Some(x) = m.get_mut((c, k)) {
                *x = T::zero();
            }
            if let Some(x) = m.get_mut((k, c)) {
                *x = T::zero();
            }
        }
        if let Some(x) = m.get_mut((c, c)) {
            *x = diagonal;
        }
    }
}

/// The storage function (5.21) split into its parts (J).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Storage<T> {
    /// `½ ẏᵀ M ẏ` with the closed-loop inertia (5.17).
    pub kinetic: T,
    /// `V_imp(x̃)` and every other potential of the control law.
    pub potential: T,
    /// `V = kinetic + potential` (5.21).
    pub total: T,
}

/// Storage function `V(x̃, ẏ) = ½ ẏᵀ M ẏ + V_imp(x̃)` (5.21) with `M` from
/// [`closed_loop_inertia`], `ẏ = (ṙ, q̇)` (locked axes at rest) and the potential `V_imp` (J) of
/// the impedance (plus any further potential the controller adds, e.g. a posture spring).
/// Errors: a non-finite input. Cost O(N²).
///
/// ```
/// use kernel::platform::storage::storage_function;
/// use nalgebra::{Matrix2, Vector2};
/// // M = blockdiag(m_adm = 3 kg, M_qq = 2 kg), ẏ = (1, 0.5) m/s, V_imp = 0.25 J.
/// let v = storage_function(&Matrix2::new(3.0, 0.0, 0.0, 2.0_f64), &Vector2::new(1.0, 0.5), 0.25).unwrap();
/// assert_eq!((v.kinetic, v.total), (1.75, 2.0));
/// ```
pub fn storage_function<T: RealField + Copy, const N: usize>(
    closed_loop_inertia: &SMatrix<T, N, N>,
    velocity: &SVector<T, N>,
    potential: T,
) -> Result<Storage<T>, PlatformError> {
    if !(crate::math::all_finite(velocity) && potential.is_finite()) {
        return Err(PlatformError::NonFinite { input: "velocity or potential" });
    }
    let kinetic = velocity.dot(&(closed_loop_inertia * velocity)) * nalgebra::convert::<f64, T>(0.5);
    if !kinetic.is_finite() {
        return Err(PlatformError::NonFinite { input: "closed_loop_inertia" });
    }
    Ok(Storage { kinetic, potential, total: kinetic + potential })
}

/// Rate of the storage function predicted by (5.22), `V̇ = ẏᵀ τ_rq,ext − ẏᵀ D ẏ` (W), from the
/// damping torque `D ẏ` (`(D_adm ṙ; D_qq q̇)`, (5.19)) and the external generalized force
/// `τ_rq,ext` (5.20). It holds for the compensated closed loop (5.16); comparing it with the
/// measured rate shows how well the compensation works.
pub fn storage_rate<T: RealField + Copy, const N: usize>(
    velocity: &SVector<T, N>,
    damping_torque: &SVector<T, N>,
    external_force: &SVector<T, N>,
) -> T {
    velocity.dot(external_force) - velocity.dot(damping_torque)
}

/// Settings of the [`PassivityMonitor`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PassivityMonitorConfig<T> {
    /// Largest tolerated growth of the storage beyond the supplied energy (J), `> 0`: covers
    /// discretisation, model errors and unmeasured inputs such as a short push.
    pub tolerance: T,
}

/// What one [`PassivityMonitor::update`] found.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PassivityReport<T> {
    /// Measured rate of the storage, `(V_k − V_{k−1}) / Δt` (W); zero at the first update.
    pub rate: T,
    /// `V − V_0 − ∫ P_supplied dt` (J): energy created inside the loop. A passive loop keeps it
    /// non-increasing (dissipation makes it fall).
    pub excess: T,
    /// `excess − min_{past} excess` (J): how much energy the loop created since its best state.
    pub growth: T,
    /// `true` while `growth > tolerance`.
    pub violated: bool,
    /// `true` once `violated` has been seen (latched until [`PassivityMonitor::reset`]).
    pub latched: bool,
}

/// Flags sustained growth of a storage function.
///
/// A passive closed loop only loses energy apart from what the ports supply
/// (`V(t) − V(0) ≤ ∫ P_supplied dt`, (5.22)). The monitor integrates the supplied power it is
/// given (e.g. `ẏᵀ τ_ext` from a measured force, or the power `−x̃ᵀ K ẋ_des` a moving desired
/// pose injects), tracks the energy the loop created, `excess = V − V_0 − ∫ P dt`, and its
/// lowest value so far; it flags a violation when the excess has risen more than `tolerance`
/// above that minimum. A transient input that is not measured (a push) raises the excess by at
/// most the energy it injected; an instability raises it without bound. State O(1).
///
/// ```
/// use kernel::platform::storage::{PassivityMonitor, PassivityMonitorConfig};
/// let mut monitor = PassivityMonitor::try_new(PassivityMonitorConfig { tolerance: 0.5_f64 }).unwrap();
/// monitor.update(2.0, 0.0, 0.01).unwrap();
/// assert!(!monitor.update(1.8, 0.0, 0.01).unwrap().violated); // dissipating
/// assert!(!monitor.update(2.7, 100.0, 0.01).unwrap().violated); // supplied 1 J
/// assert!(monitor.update(3.6, 0.0, 0.01).unwrap().violated); // created 0.9 J > 0.5 J
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassivityMonitor<T> {
    config: PassivityMonitorConfig<T>,
    started: bool,
    initial: T,
    previous: T,
    supplied: T,
    minimum_excess: T,
    latched: bool,
}

impl<T: RealField + Copy> PassivityMonitor<T> {
    /// Validates the tolerance (finite, `> 0`).
    pub fn try_new(config: PassivityMonitorConfig<T>) -> Result<Self, PlatformError> {
        if !(config.tolerance.is_finite() && config.tolerance > T::zero()) {
            return Err(PlatformError::InvalidParameter { name: "tolerance" });
        }
        let zero = T::zero();
        Ok(Self {
            config,
            started: false,
            initial: zero,
            previous: zero,
            supplied: zero,
            minimum_excess: zero,
            latched: false,
        })
    }

    /// Forgets the history; the next update starts a new record.
    pub fn reset(&mut self) {
        self.started = false;
        self.latched = false;
    }

    /// Records the storage `storage` (J) after a period `dt` (s) during which the ports supplied
    /// the power `supplied_power` (W). Errors: non-finite input or `dt ≤ 0` (state unchanged).
    pub fn update(&mut self, storage: T, supplied_power: T, dt: T) -> Result<PassivityReport<T>, PlatformError> {
        if !(storage.is_finite() && supplied_power.is_finite()) {
            return Err(PlatformError::NonFinite { input: "storage or power" });
        }
        if !(dt.is_finite() && dt > T::zero()) {
            return Err(PlatformError::InvalidParameter { name: "dt" });
        }
        if !self.started {
            self.started = true;
            self.initial = storage;
            self.previous = storage;
            self.supplied = T::zero();
            self.minimum_excess = T::zero();
            return Ok(PassivityReport {
                rate: T::zero(),
                excess: T::zero(),
                growth: T::zero(),
                violated: false,
                latched: self.latched,
            });
        }
        let rate = (storage - self.previous) / dt;
        self.previous = storage;
        self.supplied += supplied_power * dt;
        let excess = storage - self.initial - self.supplied;
        self.minimum_excess = self.minimum_excess.min(excess);
        let growth = excess - self.minimum_excess;
        let violated = growth > self.config.tolerance;
        self.latched |= violated;
        Ok(PassivityReport { rate, excess, growth, violated, latched: self.latched })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::platform::PlatformAxis;
    use nalgebra::Matrix3;

    /// A damped 1-DOF oscillator integrated exactly enough: V falls, V̇ from (5.22) matches the
    /// measured rate, and the monitor stays quiet; with negative damping it flags the growth.
    fn oscillator<T: RealField + Copy>(tolerance: f64) {
        let (m, k): (T, T) = (nalgebra::convert(2.0), nalgebra::convert(50.0));
        for (d, unstable) in [(1.5_f64, false), (-0.8, true)] {
            let d: T = nalgebra::convert(d);
            let inertia = SMatrix::<T, 1, 1>::new(m);
            let mut monitor =
                PassivityMonitor::try_new(PassivityMonitorConfig { tolerance: nalgebra::convert(0.05) }).unwrap();
            let (mut x, mut v): (T, T) = (nalgebra::convert(0.2), T::zero());
            let dt: T = nalgebra::convert(1e-4);
            let mut flagged = false;
            for _ in 0..40_000 {
                let velocity = SVector::<T, 1>::new(v);
                let storage = storage_function(&inertia, &velocity, k * x * x * nalgebra::convert(0.5)).unwrap();
                let predicted = storage_rate(&velocity, &SVector::<T, 1>::new(d * v), &SVector::zeros());
                let report = monitor.update(storage.total, T::zero(), dt).unwrap();
                flagged |= report.violated;
                // Semi-implicit Euler.
                v += (-(k * x) - d * v) / m * dt;
                x += v * dt;
                let next =
                    storage_function(&inertia, &SVector::<T, 1>::new(v), k * x * x * nalgebra::convert(0.5)).unwrap();
                let measured = (next.total - storage.total) / dt;
                // Symplectic Euler: the rate error is O(Δt ω³ V) ≈ 0.01 W here.
                assert!(
                    (measured - predicted).abs() < nalgebra::convert::<f64, T>(tolerance),
                    "{measured} vs {predicted}"
                );
            }
            assert_eq!(flagged, unstable);
        }
    }

    #[test]
    fn storage_falls_with_damping_and_the_monitor_flags_growth_f64() {
        oscillator::<f64>(0.05);
    }

    #[test]
    fn storage_falls_with_damping_and_the_monitor_flags_growth_f32() {
        oscillator::<f32>(0.05);
    }

    #[test]
    fn closed_loop_inertia_of_a_locked_axis_keeps_its_diagonal() {
        let physical = Matrix3::new(3.0, 2.0, 1.0, 2.0, 2.0, 1.0, 1.0, 1.0, 1.0_f32);
        let layout =
            PlatformLayout::try_new::<3>([PlatformAxis::Locked(0), PlatformAxis::Absent, PlatformAxis::Admitted(2)])
                .unwrap();
        let m = closed_loop_inertia(&physical, &layout, &Vector3::new(7.0, 7.0, 0.5));
        assert_eq!(m, Matrix3::new(3.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.5));
        let s = storage_function(&m, &SVector::<f32, 3>::new(0.0, 1.0, 2.0), 0.25).unwrap();
        assert_eq!((s.kinetic, s.total), (2.0, 2.25));
        assert!(storage_function(&m, &SVector::<f32, 3>::new(0.0, f32::NAN, 0.0), 0.0).is_err());
    }

    #[test]
    fn monitor_rejects_bad_input() {
        assert_eq!(
            PassivityMonitor::try_new(PassivityMonitorConfig { tolerance: 0.0_f64 }),
            Err(PlatformError::InvalidParameter { name: "tolerance" })
        );
        let mut monitor = PassivityMonitor::try_new(PassivityMonitorConfig { tolerance: 1.0_f64 }).unwrap();
        assert!(monitor.update(f64::NAN, 0.0, 0.1).is_err());
        assert!(monitor.update(1.0, 0.0, -0.1).is_err());
        let first = monitor.update(1.0, 0.0, 0.1).unwrap();
        assert_eq!((first.rate, first.excess, first.violated), (0.0, 0.0, false));
        assert!(monitor.update(3.5, 0.0, 0.1).unwrap().latched);
        assert!(monitor.update(0.0, 0.0, 0.1).unwrap().latched);
        monitor.reset();
        assert!(!monitor.update(0.0, 0.0, 0.1).unwrap().latched);
    }
}
