//! The manipulability gradient of the kernel (one walk over the kinematic tree, (3.55)–(3.57))
//! on the Justin model, for both TCPs with the selections of the whole-body configuration
//! (translational rows of each 7-joint arm) and with all six rows: against a plain reference
//! built from the public Jacobian and its directional derivative
//! (`∂m/∂q_k = m tr((J Jᵀ)⁻¹ (∂J/∂q_k) Jᵀ)`, dense determinant), against central differences
//! of `m`, and f32 against f64.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "test code")]

use fixtures::justin::{self, whole_body, JustinModel, N};
use kernel::controller::config::{ArmId, JointGroup};
use kernel::dynamics::{forward_kinematics, frame_jacobian, frame_jacobian_derivative};
use kernel::model::FrameId;
use kernel::tasks::cartesian_impedance::AxisMask;
use kernel::tasks::manipulability::manipulability;
use kernel::Data;
use nalgebra::{DMatrix, RowSVector, SMatrix, SVector};

use crate::support::Rng;

/// (frame, rows, coordinates): the configured singularity tasks of both arms, then the same
/// arms with all six rows.
fn selections() -> std::vec::Vec<(FrameId, AxisMask, [bool; N])> {
    let config = whole_body::controller_config::<f64>().unwrap();
    let mut out = std::vec::Vec::new();
    for rows in [config.singularity.rows, AxisMask::ALL] {
        for hand in [ArmId::RIGHT, ArmId::LEFT] {
            out.push((config.layout.tcp[hand.index()], rows, config.layout.coordinates(JointGroup::Arm(hand))));
        }
    }
    assert_eq!(out[0].0, justin::RIGHT_TCP);
    assert_eq!(out[1].0, justin::LEFT_TCP);
    out
}

/// A random configuration within the limits (platform within ±1 m, ±π), the torso's coupled
/// bound `0 ≤ q_t2 + q_t3 ≤ 135°` respected.
fn random_state(model: &JustinModel<f64>, rng: &mut Rng) -> SVector<f64, N> {
    let mut q = SVector::from_fn(|k, _| {
        let (lower, upper) = (model.limits.position_lower[k], model.limits.position_upper[k]);
        if k < justin::BASE_DOF {
            rng.uniform(-1.0, 1.0)
        } else {
            rng.uniform(lower, upper)
        }
    });
    let (t2, t3) = (justin::TORSO_COORDINATES.start + 1, justin::TORSO_COORDINATES.start + 2);
    let bound = 135f64.to_radians();
    q[t3] = rng.uniform((-q[t2]).max(0.0), (bound - q[t2]).min(bound));
    q
}

/// The selected rows and columns of a 6×N matrix (dense, r×n).
fn select(j: &SMatrix<f64, 6, N>, rows: AxisMask, columns: &[bool; N]) -> DMatrix<f64> {
    let r: std::vec::Vec<usize> = (0..6).filter(|i| rows.contains(*i)).collect();
    let c: std::vec::Vec<usize> = (0..N).filter(|k| columns[*k]).collect();
    DMatrix::from_fn(r.len(), c.len(), |a, b| j[(r[a], c[b])])
}

/// Plain reference: `m = √det(J Jᵀ)` and `∂m/∂q_k = m tr((J Jᵀ)⁻¹ (∂J/∂q_k) Jᵀ)` with
/// `∂J/∂q_k` from `frame_jacobian_derivative` along `e_k`, dense inverse; also the squared
/// condition `c² = (σ_min / σ_max)²` of the selected Jacobian, by which rounding errors of `m`
/// and its gradient are amplified.
fn reference(
    model: &JustinModel<f64>,
    q: &SVector<f64, N>,
    s: &(FrameId, AxisMask, [bool; N]),
) -> (f64, RowSVector<f64, N>, f64) {
    let mut data = Data::new(model);
    forward_kinematics(model, &mut data, q, &SVector::zeros()).unwrap();
    let mut j = SMatrix::<f64, 6, N>::zeros();
    frame_jacobian(model, &data, s.0, &mut j).unwrap();
    let js = select(&j, s.1, &s.2);
    let gram = &js * js.transpose();
    let m = gram.determinant().sqrt();
    let inverse = gram.try_inverse().unwrap();
    let mut dj = SMatrix::<f64, 6, N>::zeros();
    let gradient = RowSVector::<f64, N>::from_fn(|_, k| {
        let e = SVector::<f64, N>::from_fn(|r, _| if r == k { 1.0 } else { 0.0 });
        frame_jacobian_derivative(model, &data, s.0, &e, &mut dj).unwrap();
        m * (&inverse * select(&dj, s.1, &s.2) * js.transpose()).trace()
    });
    let sigma = js.singular_values();
    (m, gradient, (sigma.min() / sigma.max()).powi(2))
}

fn fast<T: nalgebra::RealField + Copy>(
    model: &JustinModel<T>,
    q: &SVector<f64, N>,
    s: &(FrameId, AxisMask, [bool; N]),
) -> (f64, RowSVector<f64, N>) {
    let mut data = Data::new(model);
    forward_kinematics(model, &mut data, &q.cast(), &SVector::zeros()).unwrap();
    let measure = manipulability(model, &data, s.0, s.1, &s.2).unwrap();
    assert!(!measure.singular);
    let f64_of = |x: T| -> f64 { nalgebra::try_convert(x).unwrap() };
    (f64_of(measure.value), measure.gradient.map(f64_of))
}

/// f64: the fast gradient equals the reference to 1e-13 of its scale (over `c²`, see
/// [`reference`]) and central differences (h = 1e-6) to 1e-6; only the coordinates on the TCP's support path (platform, torso, that
/// arm) can be non-zero, and the other arm's are exactly 0.
#[test]
fn justin_gradient_matches_reference_and_finite_differences() {
    let model = justin::model::<f64>().unwrap();
    let mut rng = Rng(0x5eed_1234);
    let (mut worst_reference, mut worst_fd) = (0.0_f64, 0.0_f64);
    for trial in 0..25 {
        let q = if trial == 0 { justin::home_configuration() } else { random_state(&model, &mut rng) };
        for (index, s) in selections().iter().enumerate() {
            let (m, g) = fast(&model, &q, s);
            let (m_ref, g_ref, c2) = reference(&model, &q, s);
            let scale = g_ref.amax() + 1e-3;
            assert!((m - m_ref).abs() * c2 <= 1e-12 * m_ref, "trial {trial} {index}: {m} vs {m_ref}");
            let err = (g - g_ref).amax() * c2;
            worst_reference = worst_reference.max(err / scale);
            assert!(err <= 1e-13 * scale, "trial {trial} selection {index}: {err} vs {scale}");
            let h = 1e-6;
            let fd = RowSVector::<f64, N>::from_fn(|_, k| {
                let e = SVector::<f64, N>::from_fn(|r, _| if r == k { h } else { 0.0 });
                (fast(&model, &(q + e), s).0 - fast(&model, &(q - e), s).0) / (2.0 * h)
            });
            let err = (fd - g).amax();
            worst_fd = worst_fd.max(err / scale);
            assert!(err <= 1e-6 * scale, "trial {trial} selection {index}: fd {err} vs {scale}");
            let other =
                if s.0 == justin::RIGHT_TCP { justin::LEFT_ARM_COORDINATES } else { justin::RIGHT_ARM_COORDINATES };
            assert!(other.clone().all(|k| g[k] == 0.0), "trial {trial}: the other arm moves the TCP");
            assert!(g.iter().any(|x| *x != 0.0));
        }
    }
    println!("Justin manipulability gradient: vs reference {worst_reference:e}, vs central differences {worst_fd:e}");
}

/// f32 against the f64 reference on the same states: `m` to 1e-5 and the gradient to 1e-5 of
/// its scale, both over `c²` (see [`reference`]): the f32 Jacobian is resolved to ≈ 1e-7
/// relative, and `(J Jᵀ)⁻¹` amplifies it by its condition.
#[test]
fn justin_gradient_f32_matches_f64_reference() {
    let (model, model32) = (justin::model::<f64>().unwrap(), justin::model::<f32>().unwrap());
    let mut rng = Rng(0xfeed_0042);
    let mut worst = 0.0_f64;
    for trial in 0..25 {
        let q = if trial == 0 { justin::home_configuration() } else { random_state(&model, &mut rng) };
        for (index, s) in selections().iter().enumerate() {
            let (m, g) = fast(&model32, &q, s);
            let (m_ref, g_ref, c2) = reference(&model, &q, s);
            let scale = g_ref.amax() + 1e-3;
            assert!((m - m_ref).abs() * c2 <= 1e-5 * m_ref, "trial {trial} {index}: {m} vs {m_ref}");
            let err = (g - g_ref).amax() * c2;
            worst = worst.max(err / scale);
            assert!(err <= 1e-5 * scale, "trial {trial} selection {index}: {err} vs {scale}");
        }
    }
    println!("Justin manipulability gradient f32 vs f64 reference: {worst:e}");
}
