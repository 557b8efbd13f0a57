//! Chapter 2 properties of the rigid-body dynamics on every fixture model (random states,
//! proptest): `M(q)` symmetric positive definite; `Ṁ − 2C` skew-symmetric with `Ṁ` from
//! central differences ((2.7)); `RNEA(q, q̇, 0) = C q̇ + g`; the `f32` evaluation within a
//! stated tolerance of the `f64` one.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "test code")]

use kernel::dynamics::{coriolis_matrix, crba, forward_kinematics, gravity, rnea};
use kernel::{Data, Model};
use nalgebra::{SMatrix, SVector};
use proptest::prelude::*;

/// Relative tolerance of `f32` against `f64` for M, C and g: single precision resolves
/// 1.2e-7; the recursions accumulate a few hundred roundings on the 20-DOF model.
const F32_RELATIVE: f64 = 1e-4;

struct Evaluated<const N: usize> {
    m: SMatrix<f64, N, N>,
    c: SMatrix<f64, N, N>,
    g: SVector<f64, N>,
    bias: SVector<f64, N>,
}

fn evaluate<const N: usize, const B: usize, const F: usize>(
    model: &Model<f64, N, B, F>,
    q: &SVector<f64, N>,
    v: &SVector<f64, N>,
) -> Evaluated<N> {
    let mut data = Data::new(model);
    forward_kinematics(model, &mut data, q, v).unwrap();
    let m = *crba(model, &mut data);
    let c = *coriolis_matrix(model, &mut data);
    let g = *gravity(model, &mut data);
    let bias = *rnea(model, &mut data, &SVector::zeros()).unwrap();
    Evaluated { m, c, g, bias }
}

fn check_model<const N: usize, const B: usize, const F: usize>(
    model: &Model<f64, N, B, F>,
    model32: &Model<f32, N, B, F>,
    q: &SVector<f64, N>,
    v: &SVector<f64, N>,
) -> Result<(), TestCaseError> {
    let e = evaluate(model, q, v);
    prop_assert!((e.m - e.m.transpose()).amax() <= 1e-12 * e.m.amax());
    prop_assert!(nalgebra::Cholesky::new(e.m).is_some(), "M not positive definite");

    let h = 1e-6;
    let m_dot = (evaluate(model, &(q + v * h), v).m - evaluate(model, &(q - v * h), v).m) / (2.0 * h);
    let n = m_dot - e.c * 2.0;
    let scale = 1.0 + m_dot.amax();
    prop_assert!((n + n.transpose()).amax() <= 1e-6 * scale, "Ṁ − 2C not skew: {}", (n + n.transpose()).amax());

    let residual = (e.c * v + e.g - e.bias).amax();
    prop_assert!(residual <= 1e-10 * (1.0 + e.bias.amax()), "RNEA(q, q̇, 0) − C q̇ − g = {residual}");

    let mut data32 = Data::new(model32);
    forward_kinematics(model32, &mut data32, &q.cast(), &v.cast()).unwrap();
    let m32 = crba(model32, &mut data32).cast::<f64>();
    let c32 = coriolis_matrix(model32, &mut data32).cast::<f64>();
    let g32 = gravity(model32, &mut data32).cast::<f64>();
    prop_assert!((m32 - e.m).amax() <= F32_RELATIVE * (1.0 + e.m.amax()));
    prop_assert!((c32 - e.c).amax() <= F32_RELATIVE * (1.0 + e.c.amax()));
    prop_assert!((g32 - e.g).amax() <= F32_RELATIVE * (1.0 + e.g.amax()));
    Ok(())
}

fn vector<const N: usize>(range: f64) -> impl Strategy<Value = SVector<f64, N>> {
    proptest::collection::vec(-range..range, N).prop_map(|x| SVector::from_column_slice(&x))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn planar_four_dof(q in vector::<4>(3.0), v in vector::<4>(3.0)) {
        let (m, m32) = (fixtures::planar::four_dof::<f64>().unwrap(), fixtures::planar::four_dof::<f32>().unwrap());
        check_model(&m, &m32, &q, &v)?;
    }

    #[test]
    fn planar_three_dof(q in vector::<3>(3.0), v in vector::<3>(3.0)) {
        let (m, m32) = (fixtures::planar::three_dof::<f64>().unwrap(), fixtures::planar::three_dof::<f32>().unwrap());
        check_model(&m, &m32, &q, &v)?;
    }

    #[test]
    fn linear_mobile_three_dof(q in vector::<3>(1.0), v in vector::<3>(1.0)) {
        let (m, m32) = (fixtures::mobile::three_dof::<f64>().unwrap(), fixtures::mobile::three_dof::<f32>().unwrap());
        check_model(&m, &m32, &q, &v)?;
    }

    #[test]
    fn justin(offset in vector::<20>(0.5), v in vector::<20>(1.0)) {
        let (m, m32) = (fixtures::justin::model::<f64>().unwrap(), fixtures::justin::model::<f32>().unwrap());
        let q = fixtures::justin::home_configuration::<f64>() + offset;
        check_model(&m, &m32, &q, &v)?;
    }
}
