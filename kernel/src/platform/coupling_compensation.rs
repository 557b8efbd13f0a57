//! Compensation of the dynamic couplings between the admittance-controlled platform and the
//! torque-controlled upper body, (5.13)–(5.14).
//!
//! With the platform row replaced by the admittance (5.1), the robot's dynamics are (5.6)
//!
//! `[M_adm 0; M_qr M_qq] (r̈; q̈) + [D_adm 0; C_qr C_qq] (ṙ; q̇) + (0; g_q) = (τ_r,vir; τ_q) + τ_ext`,
//!
//! whose inertia matrix is not symmetric: the impedance (5.12) alone can destabilise it
//! (Fig. 5.3b). The control law (5.13) adds
//!
//! `τ_comp = (0; M_qr r̈ + C_qr ṙ + g_q)` (5.14)
//!
//! with `r̈` from the admittance (5.15), so that the closed loop takes the standard form
//! `M ÿ + C ẏ + D ẏ = τ_imp + τ_ext` with `M = blockdiag(M_adm, M_qq)` (5.16)–(5.20).
//!
//! The three terms are returned separately so that an experiment can switch them
//! ([`CompensationSwitch`]): the "compensation OFF" runs of Sec. 5.1.4 drop the couplings
//! `M_qr r̈ + C_qr ṙ`. The thesis puts `g_q` into `τ_comp` as well; a robot whose upper body
//! holds a TCP against gravity (Fig. 5.5 with compensation off still tracks its reference)
//! keeps the gravity term, so it has its own switch.

use nalgebra::{RealField, SVector, Vector3};

use super::{PlatformError, PlatformLayout};
use crate::model::{Data, Model};

/// Which parts of `τ_comp` (5.14) a controller applies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CompensationSwitch {
    /// The couplings `M_qr r̈ + C_qr ṙ` (what Sec. 5.1.4 switches "ON"/"OFF").
    pub coupling: bool,
    /// The gravity torque `g_q`.
    pub gravity: bool,
}

impl CompensationSwitch {
    /// The full compensation (5.14).
    pub const ON: Self = Self { coupling: true, gravity: true };
    /// "Compensation OFF" of Sec. 5.1.4: gravity only, no inertia or Coriolis couplings.
    pub const OFF: Self = Self { coupling: false, gravity: true };
}

/// The terms of `τ_comp` (5.14) as generalized forces on all `N` coordinates; the platform
/// entries are zero.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CouplingTerms<T, const N: usize> {
    /// `(0; M_qr r̈)` (Nm, N).
    pub inertia: SVector<T, N>,
    /// `(0; C_qr ṙ)` (Nm, N).
    pub coriolis: SVector<T, N>,
    /// `(0; g_q)` (Nm, N).
    pub gravity: SVector<T, N>,
}

impl<T: RealField + Copy, const N: usize> CouplingTerms<T, N> {
    /// All terms zero.
    pub fn zeros() -> Self {
        Self { inertia: SVector::zeros(), coriolis: SVector::zeros(), gravity: SVector::zeros() }
    }

    /// The compensation torque the switch selects.
    pub fn torque(&self, switch: CompensationSwitch) -> SVector<T, N> {
        let mut tau = SVector::zeros();
        if switch.coupling {
            tau += self.inertia + self.coriolis;
        }
        if switch.gravity {
            tau += self.gravity;
        }
        tau
    }
}

/// Coupling compensation (5.14): `τ_comp = (0; M_qr r̈ + C_qr ṙ + g_q)`.
///
/// Reads `data.mass_matrix` (from [`crate::dynamics::crba`]), `data.coriolis`
/// ([`crate::dynamics::coriolis_matrix`], with `Ṁ = C + Cᵀ`), `data.gravity_torque`
/// ([`crate::dynamics::gravity`]) and the platform velocity `ṙ` from `data.v` (the velocities of
/// the last [`crate::dynamics::forward_kinematics`]), all at the same state. `base_acceleration`
/// is `r̈ = (ẍ, ÿ, θ̈)` from the admittance (5.15), world frame; its entries for locked or absent
/// axes are ignored (`r̈_i = 0`). Rows and columns of every platform coordinate of `layout`
/// are the `r` block; all other coordinates are `q`.
///
/// Errors: a non-finite acceleration. Cost O(N).
///
/// ```
/// use kernel::dynamics::{coriolis_matrix, crba, forward_kinematics, gravity};
/// use kernel::model::{Inertia, JointDrive, JointKind, ModelBuilder, Placement};
/// use kernel::platform::coupling_compensation::{coupling_compensation, CompensationSwitch};
/// use kernel::platform::{PlatformAxis, PlatformLayout};
/// use nalgebra::{SVector, Vector3};
/// // Linear model of Fig. 5.2: three 1 kg masses on a line (Table 5.1), M_qr = (2, 1) kg.
/// let mut b = ModelBuilder::<f64, 3, 3, 0>::new(Vector3::new(0.0, 0.0, -9.81));
/// let mut parent = None;
/// for k in 0..3 {
///     parent = Some(b.add_body(parent, Placement::identity(), JointKind::Prismatic { axis: Vector3::x_axis() },
///         JointDrive::actuated(k), Inertia::point_mass(1.0, Vector3::zeros())).unwrap());
/// }
/// let model = b.try_build().unwrap();
/// let mut data = kernel::Data::new(&model);
/// forward_kinematics(&model, &mut data, &SVector::zeros(), &SVector::zeros()).unwrap();
/// crba(&model, &mut data);
/// coriolis_matrix(&model, &mut data);
/// gravity(&model, &mut data);
/// let layout = PlatformLayout::try_new::<3>([PlatformAxis::Admitted(0), PlatformAxis::Absent, PlatformAxis::Absent]).unwrap();
/// let terms = coupling_compensation(&data, &layout, &Vector3::new(0.5, 0.0, 0.0)).unwrap();
/// assert_eq!(terms.torque(CompensationSwitch::ON), SVector::<f64, 3>::new(0.0, 1.0, 0.5));
/// ```
pub fn coupling_compensation<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    data: &Data<T, N, B, F>,
    layout: &PlatformLayout,
    base_acceleration: &Vector3<T>,
) -> Result<CouplingTerms<T, N>, PlatformError> {
    compensation_terms(data, layout, base_acceleration, |i| {
        let mut coriolis = T::zero();
        for c in layout.axes().iter().filter_map(|axis| axis.coordinate()) {
            let rate = data.v.get(c).copied().unwrap_or_else(T::zero);
            coriolis += data.coriolis.get((i, c)).copied().unwrap_or_else(T::zero) * rate;
        }
        coriolis
    })
}

/// Coupling compensation (5.14) as [`coupling_compensation`], with `C_qr ṙ = C (0; ṙ)` from
/// the tree pass [`crate::dynamics::coriolis_product`] instead of the columns of
/// `data.coriolis`: needs [`crate::dynamics::forward_kinematics`], `crba` and `gravity` at the
/// same state, not `coriolis_matrix`. Errors: a non-finite acceleration. Cost O(B).
///
/// `fixed_base`: the model has no platform coordinates (every axis of `layout` absent; the
/// controller knows it at compile time). A fixed base has no couplings: the terms are `g_q`
/// alone and the tree pass, which would multiply by a zero platform rate, does not run (cost
/// O(N)).
pub fn coupling_compensation_recursive<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    data: &Data<T, N, B, F>,
    layout: &PlatformLayout,
    base_acceleration: &Vector3<T>,
    fixed_base: bool,
) -> Result<CouplingTerms<T, N>, PlatformError> {
    if fixed_base {
        return compensation_terms(data, layout, base_acceleration, |_| T::zero());
    }
    let mut platform_rate = SVector::<T, N>::zeros();
    for c in layout.axes().iter().filter_map(|axis| axis.coordinate()) {
        if let (Some(slot), Some(rate)) = (platform_rate.get_mut(c), data.v.get(c)) {
            *slot = *rate;
        }
    }
    let product = crate::dynamics::coriolis_product(model, data, &platform_rate);
    compensation_terms(data, layout, base_acceleration, |i| product.get(i).copied().unwrap_or_else(T::zero))
}

/// The terms of (5.14) with row `i` of `C_qr ṙ` from `coriolis_row(i)`.
fn compensation_terms<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    data: &Data<T, N, B, F>,
    layout: &PlatformLayout,
    base_acceleration: &Vector3<T>,
    coriolis_row: impl Fn(usize) -> T,
) -> Result<CouplingTerms<T, N>, PlatformError> {
    if !crate::math::all_finite(base_acceleration) {
        return Err(PlatformError::NonFinite { input: "base_acceleration" });
    }
    let mut terms = CouplingTerms::<T, N>::zeros();
    for (i, ((inertia, coriolis), gravity)) in
        terms.inertia.iter_mut().zip(terms.coriolis.iter_mut()).zip(terms.gravity.iter_mut()).enumerate()
    {
        if layout.is_platform(i) {
            continue;
        }
        *gravity = data.gravity_torque.get(i).copied().unwrap_or_else(T::zero);
        *coriolis = coriolis_row(i);
        for (axis, acceleration) in layout.axes().iter().zip(base_acceleration.iter()) {
            let Some(c) = axis.coordinate() else { continue };
            if axis.is_admitted() {
                *inertia += data.mass_matrix.get((i, c)).copied().unwrap_or_else(T::zero) * *acceleration;
            }
        }
    }
    Ok(terms)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::dynamics::{coriolis_matrix, crba, forward_kinematics, gravity, rnea};
    use crate::platform::PlatformAxis;
    use crate::test_models::{branched, state, N};

    /// On the branched test model (prismatic root = a one-axis platform) the compensation equals
    /// the upper-body rows of RNEA's `M q̈ + C q̇ + g` with `q̈ = (r̈, 0)` and `q̇ = (ṙ, 0)` … plus
    /// the `C_qq q̇` part, which must be absent: checked as `rnea(q̈=(r̈,0), q̇) − C_qq q̇`.
    fn matches_rnea<T: RealField + Copy>(tolerance: f64) {
        let model = branched::<T>();
        let layout =
            PlatformLayout::try_new::<N>([PlatformAxis::Admitted(0), PlatformAxis::Absent, PlatformAxis::Absent])
                .unwrap();
        for seed in 0..10 {
            let q: SVector<T, N> = state(seed, 1.5).cast();
            let v: SVector<T, N> = state(seed + 50, 1.0).cast();
            let acceleration = Vector3::new(nalgebra::convert::<f64, T>(0.7 - 0.1 * seed as f64), T::zero(), T::zero());
            let mut data = crate::Data::new(&model);
            forward_kinematics(&model, &mut data, &q, &v).unwrap();
            crba(&model, &mut data);
            coriolis_matrix(&model, &mut data);
            gravity(&model, &mut data);
            let terms = coupling_compensation(&data, &layout, &acceleration).unwrap();
            let mut qdd = SVector::<T, N>::zeros();
            qdd[0] = acceleration.x;
            let mut upper_v = v;
            upper_v[0] = T::zero();
            let c_qq = data.coriolis * upper_v;
            let reference = *rnea(&model, &mut data, &qdd).unwrap() - c_qq;
            let tau = terms.torque(CompensationSwitch::ON);
            let recursive = coupling_compensation_recursive(&model, &data, &layout, &acceleration, false).unwrap();
            assert_eq!((recursive.inertia, recursive.gravity), (terms.inertia, terms.gravity));
            let scale = nalgebra::convert::<f64, T>(tolerance * 1e-2) * (T::one() + terms.coriolis.amax());
            assert!((recursive.coriolis - terms.coriolis).amax() <= scale, "seed {seed}: C_qr ṙ");
            assert_eq!(tau[0], T::zero());
            let error = (tau.rows(1, N - 1) - reference.rows(1, N - 1)).amax();
            assert!(error < nalgebra::convert(tolerance), "seed {seed}: {error}");
            assert_eq!(terms.torque(CompensationSwitch::OFF), terms.gravity);
        }
    }

    #[test]
    fn equals_the_coupling_rows_of_the_rigid_body_dynamics_f64() {
        matches_rnea::<f64>(1e-10);
    }

    #[test]
    fn equals_the_coupling_rows_of_the_rigid_body_dynamics_f32() {
        matches_rnea::<f32>(1e-3);
    }

    /// On a fixed base the terms are the gravity torque alone and the tree pass is skipped: with
    /// non-finite body velocities in `data` (which the pass reads and a zero platform rate does
    /// not cancel, `NaN · 0 = NaN`) the couplings stay exactly zero; without the skip the same
    /// data gives NaN.
    #[test]
    fn a_fixed_base_has_gravity_only_and_runs_no_tree_pass() {
        let model = branched::<f64>();
        let mut data = crate::Data::new(&model);
        forward_kinematics(&model, &mut data, &state(5, 1.0), &state(6, 1.0)).unwrap();
        crba(&model, &mut data);
        gravity(&model, &mut data);
        let fixed = PlatformLayout::try_new::<N>([PlatformAxis::Absent; 3]).unwrap();
        let acceleration = Vector3::new(0.4, -0.2, 0.1);
        let finite = coupling_compensation_recursive(&model, &data, &fixed, &acceleration, true).unwrap();
        assert_eq!(finite.torque(CompensationSwitch::ON), data.gravity_torque);
        assert!(data.gravity_torque.amax() > 0.1, "{}", data.gravity_torque);
        for velocity in data.body_velocities.iter_mut() {
            *velocity = nalgebra::Vector6::repeat(f64::NAN);
        }
        let poisoned = coupling_compensation_recursive(&model, &data, &fixed, &acceleration, true).unwrap();
        assert_eq!(poisoned, finite);
        let unskipped = coupling_compensation_recursive(&model, &data, &fixed, &acceleration, false).unwrap();
        assert!(unskipped.coriolis.iter().all(|x| x.is_nan()), "{}", unskipped.coriolis);
    }

    #[test]
    fn locked_axes_contribute_no_inertia_and_bad_input_is_refused() {
        let model = branched::<f64>();
        let mut data = crate::Data::new(&model);
        forward_kinematics(&model, &mut data, &state(3, 1.0), &state(4, 1.0)).unwrap();
        crba(&model, &mut data);
        coriolis_matrix(&model, &mut data);
        let locked =
            PlatformLayout::try_new::<N>([PlatformAxis::Locked(0), PlatformAxis::Absent, PlatformAxis::Absent])
                .unwrap();
        let terms = coupling_compensation(&data, &locked, &Vector3::new(3.0, 0.0, 0.0)).unwrap();
        assert_eq!(terms.inertia, SVector::<f64, N>::zeros());
        assert_eq!(
            coupling_compensation(&data, &locked, &Vector3::new(f64::NAN, 0.0, 0.0)),
            Err(PlatformError::NonFinite { input: "base_acceleration" })
        );
    }
}
