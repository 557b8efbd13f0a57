//! Rigid-body inertia: mass, centre of mass and rotational inertia about the centre of mass.

use nalgebra::{Matrix3, RealField, Vector3, Vector6};

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
    ///
    /// Each test allows `tol = (‖I‖ + 1) · max(1e-9, 64 ε)`, `ε` the scalar's machine epsilon:
    /// 1e-9 in `f64`; in `f32` the rounding of the stored moments and of the eigenvalues
    /// (a few `ε ‖I‖`), so that a body on the triangle inequality's edge in the URDF (TIAGo++'s
    /// `arm_*_1_link`) is physical in both scalars.
    pub fn is_physical(&self) -> bool {
        let finite = self.mass.is_finite()
            && self.com.iter().all(|x| x.is_finite())
            && self.rotational.iter().all(|x| x.is_finite());
        if !finite || self.mass < T::zero() {
            return false;
        }
        let scale = self.rotational.norm() + T::one();
        let tol =
            scale * nalgebra::convert::<f64, T>(1e-9).max(T::default_epsilon() * nalgebra::convert::<f64, T>(64.0));
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

/// Spatial inertia about the world origin in its ten parameters (Featherstone (2.63)):
/// `I = [[Ī, [h]×], [−[h]×, m 1]]` with first moment `h = m c` and the symmetric rotational
/// inertia about the origin `Ī = R I_c Rᵀ − m [c]×[c]×`.
///
/// The dynamics algorithms work on this form instead of the 6×6 matrix: sums over subtrees add
/// ten numbers instead of 36 and `I s` costs 24 multiplications instead of 36. The same
/// structure also holds the time derivative `İ` of such an inertia (then `mass = 0`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldInertia<T> {
    /// Mass `m` (kg).
    pub mass: T,
    /// First moment `h = m c` about the world origin (kg m).
    pub first_moment: [T; 3],
    /// Rotational inertia `Ī` about the world origin, entries `[xx, yy, zz, xy, xz, yz]`.
    pub rotational: [T; 6],
}

impl<T: RealField + Copy> WorldInertia<T> {
    /// The zero inertia.
    pub fn zero() -> Self {
        let z = T::zero();
        Self { mass: z, first_moment: [z; 3], rotational: [z; 6] }
    }

    /// The world inertia of a body with inertia `inertia` (body frame) whose frame has world
    /// placement `placement`: `c = R c_b + p`, `Ī = R I_c Rᵀ + m (|c|² 1 − c cᵀ)`.
    #[inline]
    pub fn from_body(inertia: &Inertia<T>, placement: &Placement<T>) -> Self {
        // Row-major rows of R (nalgebra stores columns).
        let [[r00, r10, r20], [r01, r11, r21], [r02, r12, r22]] = placement.rotation.matrix().data.0;
        let rows = [[r00, r01, r02], [r10, r11, r12], [r20, r21, r22]];
        let [[i00, i10, i20], [_, i11, i21], [_, _, i22]] = inertia.rotational.data.0;
        let ic = [[i00, i10, i20], [i10, i11, i21], [i20, i21, i22]];
        let [cb0, cb1, cb2] = inertia.com.data.0[0];
        let [t0, t1, t2] = placement.translation.vector.data.0[0];
        let [ra, rb, rc] = rows;
        let c = [dot3(&ra, &[cb0, cb1, cb2]) + t0, dot3(&rb, &[cb0, cb1, cb2]) + t1, dot3(&rc, &[cb0, cb1, cb2]) + t2];
        // P = R I_c (rows), then (R I_c Rᵀ)_ij = P_i · R_j.
        let p = |r: &[T; 3]| {
            let [a, b, d] = ic;
            [dot3(r, &[a[0], b[0], d[0]]), dot3(r, &[a[1], b[1], d[1]]), dot3(r, &[a[2], b[2], d[2]])]
        };
        let (pa, pb, pc) = (p(&ra), p(&rb), p(&rc));
        let m = inertia.mass;
        let [c0, c1, c2] = c;
        let c2n = c0 * c0 + c1 * c1 + c2 * c2;
        Self {
            mass: m,
            first_moment: [c0 * m, c1 * m, c2 * m],
            rotational: [
                dot3(&pa, &ra) + m * (c2n - c0 * c0),
                dot3(&pb, &rb) + m * (c2n - c1 * c1),
                dot3(&pc, &rc) + m * (c2n - c2 * c2),
                dot3(&pa, &rb) - m * c0 * c1,
                dot3(&pa, &rc) - m * c0 * c2,
                dot3(&pb, &rc) - m * c1 * c2,
            ],
        }
    }

    /// `self += other`.
    #[inline]
    pub fn add(&mut self, other: &Self) {
        let [h0, h1, h2] = other.first_moment;
        let [xx, yy, zz, xy, xz, yz] = other.rotational;
        let [a0, a1, a2] = self.first_moment;
        let [b0, b1, b2, b3, b4, b5] = self.rotational;
        self.mass += other.mass;
        self.first_moment = [a0 + h0, a1 + h1, a2 + h2];
        self.rotational = [b0 + xx, b1 + yy, b2 + zz, b3 + xy, b4 + xz, b5 + yz];
    }

    /// `I s` for a motion `s = (ω; u)`: `(Ī ω + h × u; m u − h × ω)`.
    #[inline]
    pub fn apply(&self, s: &Vector6<T>) -> Vector6<T> {
        let [w0, w1, w2, u0, u1, u2] = s.data.0[0];
        let [h0, h1, h2] = self.first_moment;
        let [xx, yy, zz, xy, xz, yz] = self.rotational;
        let m = self.mass;
        Vector6::new(
            xx * w0 + xy * w1 + xz * w2 + (h1 * u2 - h2 * u1),
            xy * w0 + yy * w1 + yz * w2 + (h2 * u0 - h0 * u2),
            xz * w0 + yz * w1 + zz * w2 + (h0 * u1 - h1 * u0),
            m * u0 - (h1 * w2 - h2 * w1),
            m * u1 - (h2 * w0 - h0 * w2),
            m * u2 - (h0 * w1 - h1 * w0),
        )
    }

    /// The time derivative `İ = (v ×*) I − I (v ×)` of this inertia for a body moving with the
    /// spatial velocity `v = (ω; u)`: `ḣ = ω × h + m u`,
    /// `dĪ/dt = [ω]× Ī − Ī [ω]× − (u hᵀ + h uᵀ) + 2 (u · h) 1` (mass part zero).
    #[inline]
    pub fn rate(&self, v: &Vector6<T>) -> Self {
        let [w0, w1, w2, u0, u1, u2] = v.data.0[0];
        let [h0, h1, h2] = self.first_moment;
        let [xx, yy, zz, xy, xz, yz] = self.rotational;
        let m = self.mass;
        // A = [ω]× Ī (rows); [ω]× Ī − Ī [ω]× = A + Aᵀ since Ī is symmetric.
        let a = |r: [T; 3]| [w1 * r[2] - w2 * r[1], w2 * r[0] - w0 * r[2], w0 * r[1] - w1 * r[0]];
        // Columns of Ī are its rows (symmetric); A_ij = (ω × Ī_:j)_i.
        let c0 = a([xx, xy, xz]);
        let c1 = a([xy, yy, yz]);
        let c2 = a([xz, yz, zz]);
        let uh = u0 * h0 + u1 * h1 + u2 * h2;
        let two = T::one() + T::one();
        Self {
            mass: T::zero(),
            first_moment: [w1 * h2 - w2 * h1 + m * u0, w2 * h0 - w0 * h2 + m * u1, w0 * h1 - w1 * h0 + m * u2],
            rotational: [
                two * (c0[0] - u0 * h0 + uh),
                two * (c1[1] - u1 * h1 + uh),
                two * (c2[2] - u2 * h2 + uh),
                c1[0] + c0[1] - u0 * h1 - h0 * u1,
                c2[0] + c0[2] - u0 * h2 - h0 * u2,
                c2[1] + c1[2] - u1 * h2 - h1 * u2,
            ],
        }
    }

    /// The 6×6 matrix `[[Ī, [h]×], [−[h]×, m 1]]`.
    pub fn matrix(&self) -> SpatialMatrix<T> {
        let [h0, h1, h2] = self.first_moment;
        let [xx, yy, zz, xy, xz, yz] = self.rotational;
        let (m, z) = (self.mass, T::zero());
        // Column-major storage: one array per column.
        SpatialMatrix::from_data(nalgebra::ArrayStorage([
            [xx, xy, xz, z, -h2, h1],
            [xy, yy, yz, h2, z, -h0],
            [xz, yz, zz, -h1, h0, z],
            [z, h2, -h1, m, z, z],
            [-h2, z, h0, z, m, z],
            [h1, -h0, z, z, z, m],
        ]))
    }
}

#[inline]
fn dot3<T: RealField + Copy>(a: &[T; 3], b: &[T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[cfg(test)]
mod tests {
    use nalgebra::{Matrix3, RealField, Vector3};

    use super::Inertia;

    /// A body with principal moments `(a, b, c)` about its centre of mass.
    fn body<T: RealField + Copy>(a: f64, b: f64, c: f64) -> Inertia<T> {
        let rotational = Matrix3::from_diagonal(&Vector3::new(a, b, c)).map(nalgebra::convert::<f64, T>);
        Inertia { mass: T::one(), com: Vector3::zeros(), rotational }
    }

    fn physical_bodies<T: RealField + Copy>() {
        // On the triangle inequality's edge by 1.5e-12 kg m², as TIAGo++'s `arm_*_1_link`.
        assert!(body::<T>(0.01, 0.004, 0.006 - 1.5e-12).is_physical());
        // Violating it by 1 % of the moments, a negative moment, a negative mass, NaN.
        assert!(!body::<T>(0.01, 0.004, 0.0059).is_physical());
        assert!(!body::<T>(0.01, 0.01, -1e-3).is_physical());
        assert!(!Inertia { mass: -T::one(), ..body::<T>(0.01, 0.01, 0.01) }.is_physical());
        assert!(!body::<T>(f64::NAN, 0.01, 0.01).is_physical());
        // An asymmetric rotational inertia.
        let mut skew = body::<T>(0.01, 0.01, 0.01);
        skew.rotational.m12 = nalgebra::convert(1e-3);
        assert!(!skew.is_physical());
    }

    #[test]
    fn physical_bodies_f64() {
        physical_bodies::<f64>();
    }

    #[test]
    fn physical_bodies_f32() {
        physical_bodies::<f32>();
    }
}
