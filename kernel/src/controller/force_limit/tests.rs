//! The limiter against its plain reference (nalgebra products and solves) and its closed-loop
//! behaviour on small models.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "test code: failures should panic")]

use nalgebra::{Cholesky, Const, Matrix3, RealField, SMatrix, SVector, Vector6};

use super::{governor_step, CommandLimit, ForceLimitParameters, ForceLimiter, HandLimits, Stacked};
use crate::controller::layout::RobotLayout;
use crate::dynamics::{frame_jacobian, DynamicsError, TreeFactorization};
use crate::model::{Data, Model};

macro_rules! for_scalars {
    ($name:ident, $body:ident) => {
        mod $name {
            #[test]
            fn f64() {
                super::$body::<f64>();
            }
            #[test]
            fn f32() {
                super::$body::<f32>();
            }
        }
    };
}

fn c<T: RealField + Copy>(x: f64) -> T {
    nalgebra::convert(x)
}

/// The plain limiter (nalgebra products, `Cholesky::new`/`solve`, 12 full solves with the
/// N × N factor): the reference for the loops of [`ForceLimiter::update`] and
/// [`ForceLimiter::limit_command`].
struct Reference<T: RealField, const N: usize>(ForceLimiter<T, N, 2>);

/// The limiter's stacked `J_u` of two hands as the 12 × N matrix.
fn stacked_matrix<T: RealField + Copy, const N: usize>(stacked: &[Stacked<T, 2>; N]) -> SMatrix<T, 12, N> {
    SMatrix::from_fn(|i, k| stacked[k].as_flattened()[i])
}

impl<T: RealField + Copy, const N: usize> Reference<T, N> {
    fn bounds(&self, index: usize, lower: &Vector6<T>, upper: &Vector6<T>) -> (Vector6<T>, Vector6<T>) {
        self.0.bounds(index, lower, upper)
    }
    #[allow(clippy::too_many_arguments)]
    fn update<const B: usize, const F: usize>(
        &mut self,
        parameters: &ForceLimitParameters<T>,
        model: &Model<T, N, B, F>,
        data: &Data<T, N, B, F>,
        layout: &RobotLayout<N, 2>,
        residual: &SVector<T, N>,
        hands: &[Option<HandLimits<T>>; 2],
        dt: T,
    ) -> Result<(), DynamicsError> {
        let mut full = [SMatrix::<T, 6, N>::zeros(); 2];
        let mut upper = [SMatrix::<T, 6, N>::zeros(); 2];
        for ((tcp, limits), (jacobian, upper_body)) in
            layout.tcp.iter().zip(hands.iter()).zip(full.iter_mut().zip(upper.iter_mut()))
        {
            let axes = limits.map_or_else(Matrix3::identity, |l| l.axes);
            let mut world = SMatrix::<T, 6, N>::zeros();
            frame_jacobian(model, data, *tcp, &mut world)?;
            let at = axes.transpose();
            jacobian.fixed_rows_mut::<3>(0).copy_from(&(at * world.fixed_rows::<3>(0)));
            jacobian.fixed_rows_mut::<3>(3).copy_from(&(at * world.fixed_rows::<3>(3)));
            *upper_body = *jacobian;
            for (k, mut column) in upper_body.column_iter_mut().enumerate() {
                if layout.platform.is_platform(k) {
                    column.fill(T::zero());
                }
            }
        }
        // Constant offsets only: a run-time offset into `fixed_rows` keeps nalgebra's bounds
        // assertion (a panic path) in the image.
        let [right, left] = &upper;
        let mut stacked = SMatrix::<T, 12, N>::zeros();
        stacked.fixed_rows_mut::<6>(0).copy_from(right);
        stacked.fixed_rows_mut::<6>(6).copy_from(left);
        let gram = stacked * stacked.transpose() + SMatrix::<T, 12, 12>::identity() * parameters.regularisation;
        self.0.stacked =
            core::array::from_fn(|k| core::array::from_fn(|h| core::array::from_fn(|i| stacked[(6 * h + i, k)])));
        self.0.effective = [None; 2];
        let Some(factor) = Cholesky::new(gram) else {
            self.0.applied = [Vector6::zeros(); 2];
            self.0.relief = SVector::zeros();
            return Ok(());
        };
        let external = factor.solve(&(stacked * residual));
        if !crate::math::all_finite(&external) {
            self.0.applied = [Vector6::zeros(); 2];
            self.0.relief = SVector::zeros();
            return Ok(());
        }
        self.0.relief = SVector::zeros();
        let step = parameters.gain * dt;
        let wrenches: [Vector6<T>; 2] =
            [external.fixed_rows::<6>(0).into_owned(), external.fixed_rows::<6>(6).into_owned()];
        for (h, ((limits, jacobian), wrench)) in hands.iter().zip(full.iter()).zip(wrenches).enumerate() {
            let applied = -wrench;
            if let Some(a) = self.0.applied.get_mut(h) {
                *a = applied;
            }
            let Some(correction) = self.0.correction.get_mut(h) else { continue };
            let Some(limits) = limits.filter(|_| parameters.enabled) else {
                *correction = Vector6::zeros();
                continue;
            };
            let share = T::one() - parameters.margin;
            let limits = HandLimits { lower: limits.lower * share, upper: limits.upper * share, ..limits };
            let mut reaction = Vector6::zeros();
            for axis in 0..6 {
                let get = |v: &Vector6<T>| v.get(axis).copied().unwrap_or_else(T::zero);
                let (a, lower, upper) = (get(&applied), get(&limits.lower), get(&limits.upper));
                let lower = Some(lower).filter(|x| x.is_finite());
                let upper = Some(upper).filter(|x| x.is_finite());
                if let Some(c) = correction.get_mut(axis) {
                    *c = governor_step(*c, a, lower, upper, step, parameters.max_correction);
                }
                let pressing = (upper.is_some() && a > T::zero()) || (lower.is_some() && a < T::zero());
                if let (true, Some(r)) = (pressing, reaction.get_mut(axis)) {
                    *r = get(&wrench);
                }
            }
            let bounds = self.bounds(h, &limits.lower, &limits.upper);
            if let Some(e) = self.0.effective.get_mut(h) {
                *e = Some(bounds);
            }
            let torque = jacobian.transpose() * reaction;
            for (k, (r, t)) in self.0.relief.iter_mut().zip(torque.iter()).enumerate() {
                if layout.platform.is_platform(k) {
                    *r += *t;
                }
            }
        }
        Ok(())
    }

    fn limit_command(
        &self,
        regularisation: T,
        task_torque: &SVector<T, N>,
        factor: &Cholesky<T, Const<N>>,
        damping: &[Vector6<T>; 2],
    ) -> CommandLimit<T, N, 2> {
        let none = CommandLimit { torque: SVector::zeros(), limited: [[false; 6]; 2] };
        // The limited rows L: an axis of a hand with an enabled limit and a finite bound.
        let mut selected = [false; 12];
        for (h, bounds) in self.0.effective.iter().enumerate() {
            let Some((lower, upper)) = bounds else { continue };
            for (axis, (low, high)) in lower.iter().zip(upper.iter()).enumerate() {
                if let Some(s) = selected.get_mut(6 * h + axis) {
                    *s = low.is_finite() || high.is_finite();
                }
            }
        }
        if !selected.iter().any(|s| *s) {
            return none;
        }
        // M⁻¹ J_uᵀ, then the reflected inertia of L (identity on the other rows) and J_L M⁻¹ τ.
        let stacked = stacked_matrix(&self.0.stacked);
        let mobility = factor.solve(&stacked.transpose());
        let mut reflected = stacked * mobility;
        let mut rhs = mobility.transpose() * task_torque;
        for (i, mut row) in reflected.row_iter_mut().enumerate() {
            let row_selected = selected.get(i).copied().unwrap_or(false);
            for (j, x) in row.iter_mut().enumerate() {
                let both = row_selected && selected.get(j).copied().unwrap_or(false);
                *x = match (i == j, both) {
                    (true, true) => *x + regularisation,
                    (true, false) => T::one(),
                    (false, true) => *x,
                    (false, false) => T::zero(),
                };
            }
        }
        for (r, s) in rhs.iter_mut().zip(selected.iter()) {
            if !s {
                *r = T::zero();
            }
        }
        let Some(force) = Cholesky::new(reflected).map(|f| f.solve(&rhs)).filter(crate::math::all_finite) else {
            return none;
        };
        let mut excess = SVector::<T, 12>::zeros();
        let mut limited = [[false; 6]; 2];
        for (h, ((bounds, flags), damping)) in
            self.0.effective.iter().zip(limited.iter_mut()).zip(damping.iter()).enumerate()
        {
            let Some((lower, upper)) = bounds else { continue };
            for (axis, flag) in flags.iter_mut().enumerate() {
                let row = 6 * h + axis;
                let get = |v: &Vector6<T>| v.get(axis).copied().unwrap_or_else(T::zero);
                let (Some(f), Some(e)) = (force.get(row), excess.get_mut(row)) else { continue };
                let d = get(damping);
                let (low, high) = (get(lower) + d.max(T::zero()), get(upper) + d.min(T::zero()));
                let over = *f - f.max(low).min(high);
                *e = over;
                *flag = over != T::zero();
            }
        }
        CommandLimit { torque: -(stacked.transpose() * excess), limited }
    }
}

/// A quasi-static contact: the applied force is the (effective) bound plus a disturbance
/// `d` the task cannot see, seen through the observer's first-order lag `K_O`.
fn governor_settles_at_the_limit<T: RealField + Copy>() {
    let (k_o, dt, limit, d) = (c::<T>(50.0), c::<T>(1e-3), c::<T>(10.0), c::<T>(3.0));
    let (mut correction, mut estimate) = (T::zero(), T::zero());
    let mut peak = T::zero();
    for _ in 0..2000 {
        let applied = limit - correction.max(T::zero()) + d;
        estimate += k_o * dt * (applied - estimate);
        correction = governor_step(correction, estimate, None, Some(limit), k_o / c(4.0) * dt, c(20.0));
        peak = peak.max(applied);
    }
    let applied = limit - correction + d;
    assert!((applied - limit).abs() < c(1e-2), "settles at the limit");
    assert!((correction - d).abs() < c(1e-2));
    assert!(peak <= limit + d + c(1e-3), "no overshoot beyond the first excess");
    // Disturbance gone: relaxes back to zero.
    for _ in 0..2000 {
        let applied = limit - correction.max(T::zero());
        estimate += k_o * dt * (applied - estimate);
        correction = governor_step(correction, estimate, None, Some(limit), k_o / c(4.0) * dt, c(20.0));
    }
    assert!(correction.abs() < c(1e-2));
}
for_scalars!(settles, governor_settles_at_the_limit);

fn governor_sides_and_bounds<T: RealField + Copy>() {
    let step = c::<T>(0.1);
    // Inside both bounds at zero: stays zero; unlimited axes are never governed.
    assert_eq!(governor_step(T::zero(), c(5.0), Some(c(-20.0)), Some(c(20.0)), step, c(10.0)), T::zero());
    assert_eq!(governor_step(c(3.0), c(50.0), None, None, step, c(10.0)), T::zero());
    // Above the upper bound: positive, clamped to the maximum.
    assert_eq!(governor_step(T::zero(), c(30.0), None, Some(c(20.0)), step, c(10.0)), c(1.0));
    assert_eq!(governor_step(c(9.5), c(30.0), None, Some(c(20.0)), step, c(10.0)), c(10.0));
    // Below the lower bound: negative.
    assert_eq!(governor_step(T::zero(), c(-30.0), Some(c(-20.0)), None, step, c(10.0)), c(-1.0));
    // Relaxation stops at zero, never crosses to the other side.
    assert_eq!(governor_step(c(0.5), c(0.0), Some(c(-20.0)), Some(c(20.0)), step, c(10.0)), T::zero());
    let limiter = ForceLimiter::<T, 3, 2> {
        correction: [Vector6::new(c(2.0), c(-1.0), T::zero(), T::zero(), T::zero(), T::zero()), Vector6::zeros()],
        ..ForceLimiter::new()
    };
    let (lower, upper) = limiter.bounds(0, &Vector6::repeat(c(-20.0)), &Vector6::repeat(c(20.0)));
    assert_eq!((lower[0], upper[0]), (c(-20.0), c(18.0)));
    assert_eq!((lower[1], upper[1]), (c(-19.0), c(20.0)));
    assert_eq!(limiter.bounds(7, &lower, &upper), (lower, upper));
}
for_scalars!(sides, governor_sides_and_bounds);

/// The estimate on a 3-DOF model: platform slider x, an upper-body slider x and one along z,
/// TCP on the last body. A wrench on the TCP gives `τ_ext = Jᵀ F`; the platform column is
/// not observed; the estimate recovers the observable forces and the relief is their
/// reaction on the platform along the limited axis.
/// A 3-DOF model: platform slider x, an upper-body slider x and one along z, 1 kg on each
/// body, TCP on the last one (both hands' frame); kinematics and `M` at rest.
fn sliders<T: RealField + Copy>() -> (Model<T, 3, 3, 1>, Data<T, 3, 3, 1>, RobotLayout<3, 2>) {
    use crate::dynamics::{crba, forward_kinematics};
    use crate::math::Placement;
    use crate::model::{Inertia, JointDrive, JointKind, ModelBuilder};
    use crate::platform::{PlatformAxis, PlatformLayout};
    use nalgebra::{Unit, Vector3};
    let mut b = ModelBuilder::<T, 3, 3, 1>::new(Vector3::zeros());
    let mut parent = None;
    for (i, axis) in [Vector3::x(), Vector3::x(), Vector3::z()].into_iter().enumerate() {
        parent = Some(
            b.add_body(
                parent,
                Placement::identity(),
                JointKind::Prismatic { axis: Unit::new_normalize(axis) },
                JointDrive::actuated(i),
                Inertia::point_mass(c(1.0), Vector3::zeros()),
            )
            .unwrap(),
        );
    }
    let tcp = b.add_frame(parent, Placement::identity()).unwrap();
    let model = b.try_build().unwrap();
    let mut data = Data::new(&model);
    forward_kinematics(&model, &mut data, &SVector::zeros(), &SVector::zeros()).unwrap();
    crba(&model, &mut data);
    let platform =
        PlatformLayout::try_new::<3>([PlatformAxis::Admitted(0), PlatformAxis::Absent, PlatformAxis::Absent]).unwrap();
    (model, data, RobotLayout { tcp: [tcp, tcp], platform, torso: None, arms: [[false, true, true], [false; 3]] })
}

/// The loops of [`ForceLimiter::update`] and [`ForceLimiter::limit_command`] against the
/// plain [`Reference`] on the branched test model (platform slider 0, both TCP frames,
/// turned desired frames), over 40 governed cycles with random residuals, torques, limits
/// and damping: same estimate, corrections, relief, flags and command torque (the command
/// also on the tree-sparse factor).
fn loops_match_the_reference<T: RealField + Copy>(regularisation: f64, tolerance: f64) {
    use crate::dynamics::{crba, forward_kinematics};
    use crate::platform::{PlatformAxis, PlatformLayout};
    use crate::test_models::{branched, state, N, TCP, WRIST};
    use nalgebra::Rotation3;
    let model = branched::<T>();
    let platform =
        PlatformLayout::try_new::<N>([PlatformAxis::Admitted(0), PlatformAxis::Absent, PlatformAxis::Absent]).unwrap();
    let layout = RobotLayout {
        tcp: [TCP, WRIST],
        platform,
        torso: Some([false, true, true, false, false, false]),
        arms: [[false, false, false, true, false, false], [false, false, false, false, true, true]],
    };
    let (mut fast, mut plain) = (ForceLimiter::<T, N, 2>::new(), Reference(ForceLimiter::<T, N, 2>::new()));
    let parameters = ForceLimitParameters {
        enabled: true,
        margin: c(0.1),
        gain: c(20.0),
        max_correction: c(15.0),
        regularisation: c(regularisation),
    };
    let to_f64 = |x: T| -> f64 { nalgebra::try_convert(x).unwrap() };
    let mut worst = 0.0_f64;
    let mut limited_rows = 0;
    for cycle in 0..40_u64 {
        let q: SVector<T, N> = state(cycle, 1.5).cast();
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
        crba(&model, &mut data);
        let factor = Cholesky::new(data.mass_matrix).unwrap();
        let residual: SVector<T, N> = (state(cycle ^ 3, 40.0) - state(cycle ^ 5, 40.0)).cast();
        let hand = |seed: u64| {
            let s = state(seed, 1.0);
            let mut upper = Vector6::repeat(f64::INFINITY);
            let mut lower = Vector6::repeat(f64::NEG_INFINITY);
            upper[(seed % 6) as usize] = 5.0;
            lower[((seed + 2) % 6) as usize] = -3.0;
            if seed % 4 == 0 {
                upper[((seed + 4) % 6) as usize] = 2.0;
            }
            HandLimits {
                axes: Rotation3::from_scaled_axis(nalgebra::Vector3::new(s[0], s[1], s[2])).into_inner(),
                lower,
                upper,
            }
            .cast_limits::<T>()
        };
        let hands = [Some(hand(cycle * 7 + 1)), if cycle % 3 == 0 { None } else { Some(hand(cycle * 5 + 2)) }];
        let dt = c(1e-3);
        fast.update(&parameters, &model, &data, &layout, &residual, &hands, dt).unwrap();
        plain.update(&parameters, &model, &data, &layout, &residual, &hands, dt).unwrap();
        let scale = to_f64(residual.amax()) + 1.0;
        for h in 0..2 {
            worst = worst.max(to_f64((fast.applied[h] - plain.0.applied[h]).amax()) / scale);
            worst = worst.max(to_f64((fast.correction[h] - plain.0.correction[h]).amax()) / scale);
        }
        worst = worst.max(to_f64((fast.relief - plain.0.relief).amax()) / scale);
        worst = worst.max(to_f64((stacked_matrix(&fast.stacked) - stacked_matrix(&plain.0.stacked)).amax()));
        let torque: SVector<T, N> = (state(cycle ^ 11, 60.0) - state(cycle ^ 13, 60.0)).cast();
        let damping = [Vector6::from_fn(|i, _| c((i as f64 - 2.5) * 0.7)), Vector6::zeros()];
        let a = fast.limit_command(parameters.regularisation, &torque, &factor, &damping);
        let b = plain.limit_command(parameters.regularisation, &torque, &factor, &damping);
        assert_eq!(a.limited, b.limited, "cycle {cycle}");
        limited_rows += a.limited.iter().flatten().filter(|f| **f).count();
        let command = to_f64((a.torque - b.torque).amax()) / (to_f64(b.torque.amax()) + 1.0);
        worst = worst.max(command);
        // The same limit on the tree-sparse factor M = LᵀL.
        let mut tree = TreeFactorization::new(&model);
        tree.factorize(&data.mass_matrix).unwrap();
        let t = fast.limit_command(parameters.regularisation, &torque, &tree, &damping);
        assert_eq!(t.limited, b.limited, "tree, cycle {cycle}");
        worst = worst.max(to_f64((t.torque - b.torque).amax()) / (to_f64(b.torque.amax()) + 1.0));
        assert!(worst <= tolerance, "cycle {cycle}: relative difference {worst:e}");
    }
    assert!(limited_rows > 10, "the command-side limit acted ({limited_rows} rows)");
    eprintln!("force limiter fast vs reference: {worst:e}");
}

impl HandLimits<f64> {
    fn cast_limits<T: RealField + Copy>(&self) -> HandLimits<T> {
        HandLimits { axes: self.axes.cast(), lower: self.lower.cast(), upper: self.upper.cast() }
    }
}

#[test]
fn loops_match_the_reference_f64() {
    loops_match_the_reference::<f64>(1e-4, 1e-10);
}

#[test]
fn loops_match_the_reference_f32() {
    // μ = 1e-2: the Gram matrix of the 5 upper-body columns has rank 5 of 12, its condition
    // is about 1/μ (and that of J_L M⁻¹ J_Lᵀ + μ I similar): f32 rounding of both versions
    // scales with it; a wrong entry would differ by O(1).
    loops_match_the_reference::<f32>(1e-2, 1e-3);
}

/// `+10 N` on the right TCP's x, nothing else.
fn wiper_limits<T: RealField + Copy>() -> HandLimits<T> {
    let mut upper = Vector6::repeat(c(f64::INFINITY));
    upper[0] = c(10.0);
    HandLimits { axes: Matrix3::identity(), lower: Vector6::repeat(c(f64::NEG_INFINITY)), upper }
}

fn estimate_recovers_the_contact<T: RealField + Copy>() {
    let (model, data, layout) = sliders::<T>();
    // The window pushes back with 30 N along −x on a TCP pressing along +x.
    let residual = SVector::<T, 3>::new(T::zero(), c(-30.0), c(0.0));
    let limits = wiper_limits::<T>();
    let parameters = ForceLimitParameters {
        enabled: true,
        margin: c(0.0),
        gain: c(12.5),
        max_correction: c(10.0),
        regularisation: c(1e-6),
    };
    let mut limiter = ForceLimiter::<T, 3, 2>::new();
    limiter.update(&parameters, &model, &data, &layout, &residual, &[Some(limits), None], c(1e-3)).unwrap();
    // Both hands share the frame here: the estimate splits the 30 N between them (15 N each, over the 10 N limit).
    let total = limiter.applied()[0][0] + limiter.applied()[1][0];
    assert!((total - c(30.0)).abs() < c(1e-3), "{total}");
    assert!(limiter.correction()[0][0] > T::zero());
    assert_eq!(limiter.correction()[1], Vector6::zeros());
    // Relief: the reaction of the right hand's share on the platform x, zero elsewhere.
    assert!((limiter.platform_relief()[0] + limiter.applied()[0][0]).abs() < c(1e-3));
    assert_eq!(limiter.platform_relief()[1], T::zero());
    // Disabled: estimate only, no correction, no relief.
    let disabled = ForceLimitParameters { enabled: false, ..parameters };
    limiter.update(&disabled, &model, &data, &layout, &residual, &[Some(limits), None], c(1e-3)).unwrap();
    assert_eq!(limiter.correction()[0], Vector6::zeros());
    assert_eq!(limiter.platform_relief()[0], T::zero());
    limiter.reset();
    assert_eq!(limiter, ForceLimiter::new());
}
for_scalars!(estimate, estimate_recovers_the_contact);

/// The command-side limit on the sliders: `M = [[3, 2, 0], [2, 2, 0], [0, 0, 1]]`, the TCP x
/// row of `J_u` is `(0, 1, 0)` (platform column zero), so a task torque `τ` presses a rigid
/// contact along x with `λ = (J M⁻¹ Jᵀ)⁻¹ J M⁻¹ τ = τ₁` (z decoupled). The returned torque puts
/// the rigid-contact force of the limited torque exactly on the bound (checked with `M⁻¹`
/// computed independently), leaves the unlimited axis alone, keeps the damping that pulls
/// away from the bound, applies the margin, and is zero below the bound and when disabled.
fn command_side_limit_puts_the_contact_force_on_the_bound<T: RealField + Copy>() {
    let (model, data, layout) = sliders::<T>();
    let factor = Cholesky::new(data.mass_matrix).unwrap();
    let inverse = data.mass_matrix.try_inverse().unwrap();
    let row = nalgebra::RowVector3::new(T::zero(), T::one(), T::zero());
    let contact = |tau: &SVector<T, 3>| (row * inverse * tau)[0] / (row * inverse * row.transpose())[0];
    let run = |margin: f64, enabled: bool, tau: SVector<T, 3>, damping_x: f64| {
        let parameters = ForceLimitParameters {
            enabled,
            margin: c(margin),
            gain: c(3.0),
            max_correction: c(10.0),
            regularisation: c(1e-6),
        };
        let mut limiter = ForceLimiter::<T, 3, 2>::new();
        limiter
            .update(&parameters, &model, &data, &layout, &SVector::zeros(), &[Some(wiper_limits()), None], c(1e-3))
            .unwrap();
        let mut damping = [Vector6::zeros(); 2];
        damping[0][0] = c(damping_x);
        limiter.limit_command(parameters.regularisation, &tau, &factor, &damping)
    };
    let close = |a: T, b: f64| (a - c(b)).abs() < c(1e-3);
    let tau = SVector::<T, 3>::new(T::zero(), c(30.0), c(5.0));
    assert!(close(contact(&tau), 30.0));
    let limit = run(0.0, true, tau, 0.0);
    assert!(close(contact(&(tau + limit.torque)), 10.0), "{}", contact(&(tau + limit.torque)));
    assert!(close(limit.torque[1], -20.0) && limit.torque[0] == T::zero() && close(limit.torque[2], 0.0));
    assert_eq!(limit.limited[0], [true, false, false, false, false, false]);
    assert_eq!(limit.limited[1], [false; 6]);
    // Damping pushing towards the bound is dropped: the total is held at the bound.
    assert!(close(contact(&(tau + run(0.0, true, tau, 3.0).torque)), 10.0));
    // Damping pulling away from it acts on top of the bound: 10 − 3 N in total.
    assert!(close(contact(&(tau + run(0.0, true, tau, -3.0).torque)), 7.0));
    // The margin shrinks the bound to (1 − m) · 10 N.
    assert!(close(contact(&(tau + run(0.1, true, tau, 0.0).torque)), 9.0));
    // Below the bound, or disabled: nothing.
    let below = SVector::<T, 3>::new(T::zero(), c(6.0), c(5.0));
    assert_eq!(run(0.0, true, below, 0.0).torque, SVector::<T, 3>::zeros());
    assert_eq!(run(0.0, false, tau, 0.0), CommandLimit { torque: SVector::zeros(), limited: [[false; 6]; 2] });
}
for_scalars!(command_side, command_side_limit_puts_the_contact_force_on_the_bound);
