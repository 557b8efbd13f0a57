//! Spatial (6-D) vector algebra in world coordinates (Featherstone's notation).
//!
//! Every spatial quantity of the kernel is expressed in the **world frame at the world origin**,
//! angular part first:
//! - a motion vector (twist) is `(ω; v_O)`, where `v_O` is the velocity of the body point that
//!   currently coincides with the world origin;
//! - a force vector (wrench) is `(n_O; f)`, with the moment `n_O` taken about the world origin.
//!
//! Working at one fixed point makes the tree recursions transform-free: child quantities add to
//! their parents directly, and the Jacobian column of a joint is its motion subspace. Outputs
//! that users read (frame Jacobians, drifts) are converted to the usual "world-aligned at the
//! frame origin, linear rows first" convention at the boundary.

use nalgebra::{IsometryMatrix3, Matrix3, Matrix6, RealField, Vector3, Vector6};

/// Rigid placement of a frame in its parent frame (rotation matrix and translation).
pub type Placement<T> = IsometryMatrix3<T>;
/// Spatial motion vector `(ω; v_O)` (rad/s; m/s), world frame.
pub type Motion<T> = Vector6<T>;
/// Spatial force vector `(n_O; f)` (Nm; N), world frame.
pub type SpatialForce<T> = Vector6<T>;
/// 6×6 spatial operator (inertia, cross-product matrices), world frame.
pub type SpatialMatrix<T> = Matrix6<T>;

/// Angular part `ω` (first three entries) of a spatial vector.
#[inline]
pub fn angular<T: RealField + Copy>(m: &Vector6<T>) -> Vector3<T> {
    Vector3::new(m.x, m.y, m.z)
}

/// Linear part (last three entries) of a spatial vector.
#[inline]
pub fn linear<T: RealField + Copy>(m: &Vector6<T>) -> Vector3<T> {
    Vector3::new(m.w, m.a, m.b)
}

/// Spatial vector from its angular and linear parts.
#[inline]
pub fn spatial<T: RealField + Copy>(angular: &Vector3<T>, linear: &Vector3<T>) -> Vector6<T> {
    Vector6::new(angular.x, angular.y, angular.z, linear.x, linear.y, linear.z)
}

/// Skew-symmetric cross-product matrix `[a]×` with `[a]× b = a × b`.
#[inline]
pub fn skew<T: RealField + Copy>(a: &Vector3<T>) -> Matrix3<T> {
    let z = T::zero();
    Matrix3::new(z, -a.z, a.y, a.z, z, -a.x, -a.y, a.x, z)
}

/// 6×6 matrix from its four 3×3 blocks `[[tl, tr], [bl, br]]`.
#[inline]
pub fn blocks<T: RealField + Copy>(tl: &Matrix3<T>, tr: &Matrix3<T>, bl: &Matrix3<T>, br: &Matrix3<T>) -> Matrix6<T> {
    let mut m = Matrix6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(tl);
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(tr);
    m.fixed_view_mut::<3, 3>(3, 0).copy_from(bl);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(br);
    m
}

/// Motion cross product `m × u = (ω×ω_u; ω×v_u + v×ω_u)` (Featherstone's `×`).
#[inline]
pub fn motion_cross<T: RealField + Copy>(m: &Motion<T>, u: &Motion<T>) -> Motion<T> {
    let (w, v) = (angular(m), linear(m));
    let (wu, vu) = (angular(u), linear(u));
    spatial(&w.cross(&wu), &(w.cross(&vu) + v.cross(&wu)))
}

/// Force cross product `m ×* f = (ω×n + v×f; ω×f)` (Featherstone's `×*`).
#[inline]
pub fn force_cross<T: RealField + Copy>(m: &Motion<T>, f: &SpatialForce<T>) -> SpatialForce<T> {
    let (w, v) = (angular(m), linear(m));
    let (n, fl) = (angular(f), linear(f));
    spatial(&(w.cross(&n) + v.cross(&fl)), &w.cross(&fl))
}

/// Matrix of the motion cross product: `motion_cross_matrix(m) u = m × u`.
#[inline]
pub fn motion_cross_matrix<T: RealField + Copy>(m: &Motion<T>) -> SpatialMatrix<T> {
    let (w, v) = (skew(&angular(m)), skew(&linear(m)));
    blocks(&w, &Matrix3::zeros(), &v, &w)
}

/// Matrix of the force cross product: `force_cross_matrix(m) f = m ×* f` (= −(m×)ᵀ).
#[inline]
pub fn force_cross_matrix<T: RealField + Copy>(m: &Motion<T>) -> SpatialMatrix<T> {
    let (w, v) = (skew(&angular(m)), skew(&linear(m)));
    blocks(&w, &v, &Matrix3::zeros(), &w)
}

/// The "dual" cross-product matrix of a force: `force_bar_matrix(f) u = u ×* f`.
///
/// It is skew-symmetric; it appears in the Christoffel-consistent body Coriolis term
/// (see [`crate::dynamics::coriolis_matrix`]).
#[inline]
pub fn force_bar_matrix<T: RealField + Copy>(f: &SpatialForce<T>) -> SpatialMatrix<T> {
    let (n, fl) = (skew(&angular(f)), skew(&linear(f)));
    blocks(&(-n), &(-fl), &(-fl), &Matrix3::zeros())
}

/// Linear velocity (or any linear part) of a spatial vector moved from the world origin to the
/// point `p`: `v_p = v_O + ω × p`.
#[inline]
pub fn linear_at_point<T: RealField + Copy>(m: &Motion<T>, p: &Vector3<T>) -> Vector3<T> {
    linear(m) + angular(m).cross(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(a: [f64; 6]) -> Vector6<f64> {
        Vector6::from_column_slice(&a)
    }

    #[test]
    fn cross_matrices_agree_with_cross_products() {
        let a = m([0.3, -1.2, 0.7, 2.0, 0.1, -0.4]);
        let b = m([-0.9, 0.5, 1.1, -0.3, 0.8, 1.7]);
        assert!((motion_cross_matrix(&a) * b - motion_cross(&a, &b)).norm() < 1e-14);
        assert!((force_cross_matrix(&a) * b - force_cross(&a, &b)).norm() < 1e-14);
        assert!((force_bar_matrix(&b) * a - force_cross(&a, &b)).norm() < 1e-14);
        assert!((force_cross_matrix(&a) + motion_cross_matrix(&a).transpose()).norm() < 1e-15);
        let bar = force_bar_matrix(&b);
        assert!((bar + bar.transpose()).norm() < 1e-15, "f×̄ must be skew-symmetric");
    }

    #[test]
    fn linear_at_point_moves_a_pure_rotation() {
        // Rotation about z through (1, 0, 0): the twist at the origin is (e_z; p × e_z).
        let p = Vector3::new(1.0, 0.0, 0.0);
        let axis = Vector3::z();
        let twist = spatial(&axis, &p.cross(&axis));
        assert!(linear_at_point(&twist, &p).norm() < 1e-15, "axis points do not move");
        let q = Vector3::new(2.0, 0.0, 0.0);
        assert!((linear_at_point(&twist, &q) - Vector3::new(0.0, 1.0, 0.0)).norm() < 1e-15);
    }
}
