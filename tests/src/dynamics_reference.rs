//! The kernel's fast rigid-body algorithms (ten-parameter inertias, written-out spatial
//! algebra, ancestor walks) against the plain matrix-based reference algorithms
//! (`kernel/src/dynamics/reference.rs`, the kernel's original implementation) on Justin and the
//! planar and mobile fixtures at random states: forward kinematics, `M` (CRBA) and the composite
//! inertias `I^c`, `C` and the composite operators `B^c`, the matrix-free products `C x` and
//! `Cᵀ q̇` (against the reference `C` times the vector; also both velocity products of one fused
//! pass after the velocity-level kinematics pass), `g`, RNEA and every frame Jacobian; f64
//! to rounding, f32 within single-precision accumulation of the f64 reference.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic, reason = "test code")]

/// The reference algorithms, shared with the kernel's own tests.
#[allow(dead_code, reason = "test reference")]
mod reference {
    include!("../../kernel/src/dynamics/reference.rs");
}

use kernel::dynamics::{
    composite_coriolis_operators, composite_inertia_matrices, coriolis_matrix, coriolis_product,
    coriolis_transpose_velocity, coriolis_velocity_products, crba, forward_kinematics, frame_jacobian, gravity,
    kinematics as kinematics_pass, placement_kinematics, rnea, support_kinematics, KinematicsLevel,
};
use kernel::model::FrameId;
use kernel::{Data, Model};
use nalgebra::{DVector, RealField, SVector};
use proptest::prelude::*;

/// Every output, flattened to f64, in one fixed order per output name.
type Outputs = Vec<(&'static str, DVector<f64>)>;

fn to_f64<T: RealField + Copy>(x: &[T]) -> DVector<f64> {
    DVector::from_iterator(x.len(), x.iter().map(|e| nalgebra::try_convert::<T, f64>(*e).unwrap()))
}

fn kinematics<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    data: &Data<T, N, B, F>,
) -> DVector<f64> {
    let mut out = Vec::new();
    for i in 0..B {
        out.extend(to_f64(data.body_placements[i].to_homogeneous().as_slice()).iter());
        out.extend(to_f64(data.motion_subspaces[i].as_slice()).iter());
        out.extend(to_f64(data.body_velocities[i].as_slice()).iter());
        out.extend(to_f64(data.body_drift_accelerations[i].as_slice()).iter());
        out.extend(to_f64(data.body_inertias[i].as_slice()).iter());
    }
    for f in &data.frame_placements {
        out.extend(to_f64(f.to_homogeneous().as_slice()).iter());
    }
    DVector::from_vec(out)
}

/// What [`KinematicsLevel::Velocities`] writes that the reference writes too: placements,
/// subspaces, velocities, drifts of every body and the frame placements, flattened.
fn motion_kinematics<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    data: &Data<T, N, B, F>,
) -> DVector<f64> {
    let mut out = Vec::new();
    for i in 0..B {
        out.extend(to_f64(data.body_placements[i].to_homogeneous().as_slice()).iter());
        out.extend(to_f64(data.motion_subspaces[i].as_slice()).iter());
        out.extend(to_f64(data.body_velocities[i].as_slice()).iter());
        out.extend(to_f64(data.body_drift_accelerations[i].as_slice()).iter());
    }
    for f in &data.frame_placements {
        out.extend(to_f64(f.to_homogeneous().as_slice()).iter());
    }
    DVector::from_vec(out)
}

fn fast<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    q: &SVector<f64, N>,
    v: &SVector<f64, N>,
    a: &SVector<f64, N>,
) -> Outputs {
    let cast = |x: &SVector<f64, N>| x.map(|e| nalgebra::convert::<f64, T>(e));
    let mut data = Data::new(model);
    forward_kinematics(model, &mut data, &cast(q), &cast(v)).unwrap();
    // The matrix-free products, from the kinematics alone (before any other algorithm ran).
    let c_a = to_f64(coriolis_product(model, &data, &cast(a)).as_slice());
    let ct_v = to_f64(coriolis_transpose_velocity(model, &data).as_slice());
    // The controller's pass (velocities, no 6×6 inertias) on a fresh workspace, and the fused
    // `C q̇`, `Cᵀ q̇` on it.
    let mut moving = Data::new(model);
    kinematics_pass(model, &mut moving, &cast(q), KinematicsLevel::Velocities(&cast(v))).unwrap();
    let (fused_c_v, fused_ct_v) = coriolis_velocity_products(model, &moving);
    let mut out = vec![("kinematics", kinematics(&data)), ("velocity kinematics", motion_kinematics(&moving))];
    out.push(("fused C q̇", to_f64(fused_c_v.as_slice())));
    out.push(("fused Cᵀ q̇", to_f64(fused_ct_v.as_slice())));
    out.push(("M", to_f64(crba(model, &mut data).as_slice())));
    for ic in composite_inertia_matrices(&mut data) {
        out.push(("I^c", to_f64(ic.as_slice())));
    }
    out.push(("C", to_f64(coriolis_matrix(model, &mut data).as_slice())));
    for bc in composite_coriolis_operators(&mut data) {
        out.push(("B^c", to_f64(bc.as_slice())));
    }
    out.push(("C a", c_a));
    out.push(("Cᵀ q̇", ct_v));
    out.push(("g", to_f64(gravity(model, &mut data).as_slice())));
    out.push(("rnea", to_f64(rnea(model, &mut data, &cast(a)).unwrap().as_slice())));
    for k in 0..model.frames().len() {
        let mut j = nalgebra::SMatrix::<T, 6, N>::zeros();
        frame_jacobian(model, &data, FrameId(k), &mut j).unwrap();
        out.push(("J", to_f64(j.as_slice())));
    }
    out
}

fn plain<const N: usize, const B: usize, const F: usize>(
    model: &Model<f64, N, B, F>,
    q: &SVector<f64, N>,
    v: &SVector<f64, N>,
    a: &SVector<f64, N>,
) -> Outputs {
    let mut data = Data::new(model);
    reference::forward_kinematics(model, &mut data, q, v);
    let (c, bc) = reference::coriolis(model, &data);
    let mut out = vec![("kinematics", kinematics(&data)), ("velocity kinematics", motion_kinematics(&data))];
    out.push(("fused C q̇", to_f64((c * v).as_slice())));
    out.push(("fused Cᵀ q̇", to_f64((c.transpose() * v).as_slice())));
    out.push(("M", to_f64(reference::crba(model, &data).as_slice())));
    for ic in &reference::composites(model, &data.body_inertias) {
        out.push(("I^c", to_f64(ic.as_slice())));
    }
    out.push(("C", to_f64(c.as_slice())));
    for b in &bc {
        out.push(("B^c", to_f64(b.as_slice())));
    }
    out.push(("C a", to_f64((c * a).as_slice())));
    out.push(("Cᵀ q̇", to_f64((c.transpose() * v).as_slice())));
    let mut at_rest = Data::new(model);
    reference::forward_kinematics(model, &mut at_rest, q, &SVector::zeros());
    out.push(("g", to_f64(reference::rnea(model, &at_rest, &SVector::zeros()).as_slice())));
    out.push(("rnea", to_f64(reference::rnea(model, &data, a).as_slice())));
    for (k, frame) in model.frames().iter().enumerate() {
        let j = match frame.parent {
            Some(body) => {
                let p = data.frame_placements[k].translation.vector;
                reference::point_jacobian(model, &data, body, &p)
            }
            None => nalgebra::SMatrix::zeros(),
        };
        out.push(("J", to_f64(j.as_slice())));
    }
    out
}

/// The outputs that need positions only, after the position-only passes on fresh workspaces:
/// `M` and `g` after `placement_kinematics`, every frame Jacobian after `placement_kinematics`
/// and again after `support_kinematics` of the frame's body alone.
fn positions_only<T: RealField + Copy, const N: usize, const B: usize, const F: usize>(
    model: &Model<T, N, B, F>,
    q: &SVector<f64, N>,
) -> Outputs {
    let q = q.map(|e| nalgebra::convert::<f64, T>(e));
    let mut data = Data::new(model);
    placement_kinematics(model, &mut data, &q).unwrap();
    let mut out = vec![("M", to_f64(crba(model, &mut data).as_slice()))];
    out.push(("g", to_f64(gravity(model, &mut data).as_slice())));
    for k in 0..model.frames().len() {
        let mut j = nalgebra::SMatrix::<T, 6, N>::zeros();
        frame_jacobian(model, &data, FrameId(k), &mut j).unwrap();
        out.push(("J", to_f64(j.as_slice())));
    }
    for (k, frame) in model.frames().iter().enumerate() {
        let mut support = Data::new(model);
        if let Some(body) = frame.parent {
            support_kinematics(model, &mut support, &q, body).unwrap();
        }
        let mut j = nalgebra::SMatrix::<T, 6, N>::from_element(T::one());
        frame_jacobian(model, &support, FrameId(k), &mut j).unwrap();
        out.push(("J (support)", to_f64(j.as_slice())));
    }
    out
}

/// The reference outputs matching [`positions_only`].
fn plain_positions_only<const N: usize, const B: usize, const F: usize>(
    model: &Model<f64, N, B, F>,
    q: &SVector<f64, N>,
) -> Outputs {
    let all = plain(model, q, &SVector::zeros(), &SVector::zeros());
    let pick = |name: &str| all.iter().filter(|(n, _)| *n == name).cloned().collect::<Vec<_>>();
    let jacobians = pick("J");
    let mut out = pick("M");
    out.extend(pick("g"));
    out.extend(jacobians.iter().cloned());
    out.extend(jacobians.into_iter().map(|(_, j)| ("J (support)", j)));
    out
}

/// Each fast output within `tol · (1 + max |reference|)` of the reference.
fn check(fast: &Outputs, reference: &Outputs, tol: f64) -> Result<(), TestCaseError> {
    prop_assert_eq!(fast.len(), reference.len());
    for ((name, a), (_, b)) in fast.iter().zip(reference) {
        let scale = 1.0 + b.amax();
        let d = (a - b).amax();
        prop_assert!(d <= tol * scale, "{}: difference {:e} (scale {:e})", name, d, scale);
    }
    Ok(())
}

/// f64 agreement (rounding only) and f32 agreement with the f64 reference.
const F64_RELATIVE: f64 = 1e-12;
const F32_RELATIVE: f64 = 1e-4;

fn vector<const N: usize>(range: f64) -> impl Strategy<Value = SVector<f64, N>> {
    proptest::collection::vec(-range..range, N).prop_map(|x| SVector::from_column_slice(&x))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn justin_fast_equals_reference(offset in vector::<20>(0.5), v in vector::<20>(1.0), a in vector::<20>(2.0)) {
        let (m64, m32) = (fixtures::justin::model::<f64>().unwrap(), fixtures::justin::model::<f32>().unwrap());
        let q = fixtures::justin::home_configuration::<f64>() + offset;
        let reference = plain(&m64, &q, &v, &a);
        check(&fast(&m64, &q, &v, &a), &reference, F64_RELATIVE)?;
        check(&fast(&m32, &q, &v, &a), &reference, F32_RELATIVE)?;
    }

    /// `placement_kinematics` and `support_kinematics` (positions only, fresh workspaces) give
    /// the reference `M`, `g` and frame Jacobians on Justin.
    #[test]
    fn justin_position_kinematics_equal_reference(offset in vector::<20>(0.5)) {
        let (m64, m32) = (fixtures::justin::model::<f64>().unwrap(), fixtures::justin::model::<f32>().unwrap());
        let q = fixtures::justin::home_configuration::<f64>() + offset;
        let reference = plain_positions_only(&m64, &q);
        check(&positions_only(&m64, &q), &reference, F64_RELATIVE)?;
        check(&positions_only(&m32, &q), &reference, F32_RELATIVE)?;
    }

    #[test]
    fn planar_fast_equals_reference(q in vector::<4>(3.0), v in vector::<4>(3.0), a in vector::<4>(3.0)) {
        let (m64, m32) = (fixtures::planar::four_dof::<f64>().unwrap(), fixtures::planar::four_dof::<f32>().unwrap());
        let reference = plain(&m64, &q, &v, &a);
        check(&fast(&m64, &q, &v, &a), &reference, F64_RELATIVE)?;
        check(&fast(&m32, &q, &v, &a), &reference, F32_RELATIVE)?;
    }

    #[test]
    fn mobile_fast_equals_reference(q in vector::<3>(1.0), v in vector::<3>(1.0), a in vector::<3>(3.0)) {
        let (m64, m32) = (fixtures::mobile::three_dof::<f64>().unwrap(), fixtures::mobile::three_dof::<f32>().unwrap());
        let reference = plain(&m64, &q, &v, &a);
        check(&fast(&m64, &q, &v, &a), &reference, F64_RELATIVE)?;
        check(&fast(&m32, &q, &v, &a), &reference, F32_RELATIVE)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Justin's tree-sparse `M = Lᵀ L` (`kernel::dynamics::TreeFactorization`) against nalgebra's
    /// dense Cholesky: `LᵀL = M`, equal solves (f64 tight, f32 loose), and branch-induced
    /// sparsity (the elimination tree is not one chain; `L` is zero between the arms).
    #[test]
    fn justin_tree_factorization_matches_dense_cholesky(offset in vector::<20>(0.5), b in vector::<20>(10.0)) {
        use kernel::dynamics::TreeFactorization;
        let q = fixtures::justin::home_configuration::<f64>() + offset;
        let model = fixtures::justin::model::<f64>().unwrap();
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &q, &SVector::zeros()).unwrap();
        let m = *crba(&model, &mut data);
        let mut tree = TreeFactorization::new(&model);
        tree.factorize(&m).unwrap();
        let l = tree.lower();
        prop_assert!((l.transpose() * l - m).amax() < 1e-12 * m.amax());
        let dense = nalgebra::Cholesky::new(m).unwrap().solve(&b);
        let mut x = b;
        tree.solve_mut(&mut x);
        prop_assert!((x - dense).amax() < 1e-9 * (1.0 + dense.amax()), "{}", (x - dense).amax());
        let branches = tree.parents().iter().enumerate().filter(|(k, p)| **p != k.checked_sub(1)).count();
        prop_assert!(branches >= 1, "no branch point in the elimination tree {:?}", tree.parents());
        let zeros = (0..20).flat_map(|r| (0..r).map(move |c| (r, c))).filter(|&(r, c)| l[(r, c)] == 0.0).count();
        prop_assert!(zeros > 0, "no branch-induced zeros in L");

        let model32 = fixtures::justin::model::<f32>().unwrap();
        let mut data32 = Data::new(&model32);
        forward_kinematics(&model32, &mut data32, &q.cast(), &SVector::zeros()).unwrap();
        let m32 = *crba(&model32, &mut data32);
        let mut tree32 = TreeFactorization::new(&model32);
        tree32.factorize(&m32).unwrap();
        let mut x32 = b.cast::<f32>();
        tree32.solve_mut(&mut x32);
        let dense32 = nalgebra::Cholesky::new(m32.cast::<f64>()).unwrap().solve(&b);
        prop_assert!((x32.cast::<f64>() - dense32).amax() < 1e-3 * (1.0 + dense32.amax()), "{}", (x32.cast::<f64>() - dense32).amax());
    }
}
