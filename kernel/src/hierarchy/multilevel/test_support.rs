//! A compliance stack on the kernel's branched test model (test builds only): level 0 the
//! translation of the TCP (3 rows), level 1 two translation rows of the WRIST, the last level a
//! joint impedance on all coordinates, at a pseudo-random state.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "test support")]

use nalgebra::{Cholesky, RowSVector, SMatrix, SVector};

use super::compliance_stack::{ComplianceRow, ComplianceStack};
use super::config::{DynamicsTerms, MultilevelConfig};
use super::decomposition::{decompose, Decomposition};
use super::error::MultilevelError;
use crate::dynamics::{coriolis_matrix, crba, forward_kinematics, frame_jacobian, frame_jacobian_derivative, gravity};
use crate::math::CholeskyFactor;
use crate::test_models::{branched, state, N, TCP, WRIST};
use crate::Data;

/// Model terms and a stack at one state.
pub struct Fixture<T: nalgebra::RealField> {
    pub q: SVector<T, N>,
    pub velocity: SVector<T, N>,
    pub mass: SMatrix<T, N, N>,
    pub factor: CholeskyFactor<T, N>,
    pub coriolis: SMatrix<T, N, N>,
    pub gravity: SVector<T, N>,
    pub stack: ComplianceStack<T, N, 16>,
}

impl Fixture<f64> {
    /// The state of `seed`; `levels` lists how many rows the task levels above the joint level
    /// have (at most 3 TCP rows, then at most 3 WRIST rows); `&[]` gives the joint level alone.
    pub fn new(seed: u64, levels: &[usize]) -> Self {
        Self::at(&state(seed, 1.2), &state(seed ^ 0x55, 1.5), levels)
    }

    /// The same stack at an explicit state `(q, q̇)` (forces depend only on `levels`).
    pub fn at(q: &SVector<f64, N>, velocity: &SVector<f64, N>, levels: &[usize]) -> Self {
        let model = branched::<f64>();
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, q, velocity).unwrap();
        let mass = *crba(&model, &mut data);
        let coriolis = *coriolis_matrix(&model, &mut data);
        let gravity = *gravity(&model, &mut data);
        let factor = Cholesky::new(mass).unwrap();
        let forces = state(levels.len() as u64 + 17, 10.0);
        let mut stack = ComplianceStack::new();
        for (level, (&rows, frame)) in levels.iter().zip([TCP, WRIST]).enumerate() {
            let mut jacobian = SMatrix::<f64, 6, N>::zeros();
            let mut rate = SMatrix::<f64, 6, N>::zeros();
            frame_jacobian(&model, &data, frame, &mut jacobian).unwrap();
            frame_jacobian_derivative(&model, &data, frame, velocity, &mut rate).unwrap();
            for k in 0..rows {
                let row = ComplianceRow {
                    jacobian: jacobian.row(k).into_owned(),
                    jacobian_rate: rate.row(k).into_owned(),
                    stiffness_force: forces[k],
                    damping_force: -0.3 * forces[(k + 1) % N],
                    potential: 0.1 * forces[k].abs(),
                };
                stack.push(level, row).unwrap();
            }
        }
        for k in 0..N {
            let row = ComplianceRow {
                jacobian: RowSVector::from_fn(|_, c| if c == k { 1.0 } else { 0.0 }),
                jacobian_rate: RowSVector::zeros(),
                stiffness_force: -2.0 * forces[(k + 2) % N],
                damping_force: 0.5 * forces[(k + 3) % N],
                potential: 0.05 * forces[k] * forces[k],
            };
            stack.push(levels.len(), row).unwrap();
        }
        Self { q: *q, velocity: *velocity, mass, factor, coriolis, gravity, stack }
    }

    /// The rows of one level.
    pub fn rows_on(&self, level: usize) -> std::vec::Vec<ComplianceRow<f64, N>> {
        self.stack.level(level).copied().collect()
    }

    /// The same fixture in `f32`.
    pub fn cast_f32(&self) -> Fixture<f32> {
        let mut stack = ComplianceStack::new();
        for (level, row) in self.stack.rows() {
            let row32 = ComplianceRow {
                jacobian: row.jacobian.cast(),
                jacobian_rate: row.jacobian_rate.cast(),
                stiffness_force: row.stiffness_force as f32,
                damping_force: row.damping_force as f32,
                potential: row.potential as f32,
            };
            stack.push(*level, row32).unwrap();
        }
        let mass: SMatrix<f32, N, N> = self.mass.cast();
        Fixture {
            q: self.q.cast(),
            velocity: self.velocity.cast(),
            mass,
            factor: Cholesky::new(mass).unwrap(),
            coriolis: self.coriolis.cast(),
            gravity: self.gravity.cast(),
            stack,
        }
    }
}

impl<T: nalgebra::RealField + Copy> Fixture<T> {
    /// The model terms.
    pub fn terms(&self) -> DynamicsTerms<'_, T, N> {
        DynamicsTerms {
            mass_matrix: &self.mass,
            mass_factor: &self.factor,
            coriolis: &self.coriolis,
            gravity: &self.gravity,
            velocity: &self.velocity,
        }
    }

    /// The decomposition with the default configuration.
    pub fn decompose(&self) -> Result<Decomposition<T, N, 4>, MultilevelError> {
        let mut out = Decomposition::default();
        decompose(&MultilevelConfig::default(), &self.stack, &self.terms(), &mut out)?;
        Ok(out)
    }
}
