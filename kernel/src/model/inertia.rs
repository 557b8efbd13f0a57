//! Rigid-body inertia: mass, centre of mass and rotational inertia about the centre of mass.

use nalgebra::{Matrix3, RealField, Vector3};

use crate::math::spatial::{blocks, skew, Placement, SpatialMatrix};

/// Inertia of one rigid body, expressed in the body's own frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inertia<T> {
    /// Mass `m` (kg).
    pub mass: T,
    /// Centre of mass `c` in the body frame (m).
    pub com: Vector3<T>,
    /// Rotational inertia about the centre of mass, body axes (kg m²).
    pub rotational: Matrix3<T>,
}

impl<T: RealField + Copy> Inertia<T> {
    /// A massless body.
    pub fn zero() -> Self {
        Self { mass: T::zero(), com: Vector3::zeros(), rotational: Matrix3::zeros() }
    }

    /// A point mass `mass` at `com`.
    pub fn point_mass(mass: T, com: Vector3<T>) -> Self {
        Self { mass, com, rotational: Matrix3::zeros() }
    }

    /// `true` if the values describe a physical body: finite, `m ≥ 0`, symmetric rotational
    /// inertia with non-negative principal moments satisfying the triangle inequality.
    pub fn is_physical(&self) -> bool {
        let finite = self.mass.is_finite()
            && self.com.iter().all(|x| x.is_finite())
            && self.rotational.iter().all(|x| x.is_finite());
        if !finite || self.mass < T::zero() {
            return false;
        }
        let scale = self.rotational.norm() + T::one();
        let tol = scale * nalgebra::convert::<f64, T>(1e-9);
        if (self.rotational - self.rotational.transpose()).norm() > tol {
            return false;
        }
        let eig = self.rotational.symmetric_eigenvalues();
        let (a, b, c) = (eig.x, eig.y, eig.z);
        a >= -tol && b >= -tol && c >= -tol && a + b >= c - tol && b + c >= a - tol && a + c >= b - tol
    }

    /// The same body seen from a frame in which the body frame has placement `placement`.
    pub fn transformed(&self, placement: &Placement<T>) -> Self {
        let r = placement.rotation.matrix();
        Self {
            mass: self.mass,
            com: placement.rotation * self.com + placement.translation.vector,
            rotational: r * self.rotational * r.transpose(),
        }
    }

    /// The inertia of two bodies rigidly joined, both expressed in the same frame.
    ///
    /// Used to lump fixed links (hands, flanges, sensors) into their parent body.
    pub fn combined(&self, other: &Self) -> Self {
        let mass = self.mass + other.mass;
        if mass <= T::zero() {
            return Self::zero();
        }
        let com = (self.com * self.mass + other.com * other.mass) / mass;
        let shift = |i: &Self| {
            let d = i.com - com;
            // Parallel axis theorem: I_c' = I_c + m (|d|² 1 − d dᵀ).
            i.rotational + (Matrix3::identity() * d.norm_squared() - d * d.transpose()) * i.mass
        };
        Self { mass, com, rotational: shift(self) + shift(other) }
    }

    /// 6×6 spatial inertia about the world origin, for a body whose frame has world placement
    /// `placement`: `[[I_c − m [c]×[c]×, m [c]×], [−m [c]×, m 1]]` (Featherstone, (2.63)).
    pub fn spatial_matrix(&self, placement: &Placement<T>) -> SpatialMatrix<T> {
        let r = placement.rotation.matrix();
        let c = placement.rotation * self.com + placement.translation.vector;
        let rotational = r * self.rotational * r.transpose();
        let cx = skew(&c);
        let m = self.mass;
        blocks(&(rotational - cx * cx * m), &(cx * m), &(-cx * m), &(Matrix3::identity() * m))
    }
}
