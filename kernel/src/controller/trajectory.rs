//! Goals as trajectories: "The geometric, six-DOF trajectory consists of simple third-order
//! polynomials" (Sec. 6.2, experiment #4).
//!
//! A goal is reached along the cubic `s(τ) = 3τ² − 2τ³`, `τ = t / T ∈ [0, 1]`, which starts and
//! ends at rest: the position is `p₀ + s (p₁ − p₀)`, the orientation `R₀ exp(s θ [n]×)` with the
//! axis–angle `(n, θ)` of `R₀ᵀ R₁`, joint values `q₀ + s (q₁ − q₀)`.

use nalgebra::{convert, RealField, Rotation3, SVector, Unit, UnitQuaternion, Vector3};

use crate::math::Placement;
use crate::tasks::cartesian_impedance::CartesianTarget;

/// `(s, ds/dt)` of the cubic at `elapsed` of `duration` (s). A non-positive duration means
/// "already there".
fn cubic<T: RealField + Copy>(elapsed: T, duration: T) -> (T, T) {
    let moving = duration > T::zero() && elapsed < duration;
    if !moving {
        return (T::one(), T::zero());
    }
    let tau = (elapsed / duration).max(T::zero());
    let (two, three, six): (T, T, T) = (convert(2.0), convert(3.0), convert(6.0));
    (tau * tau * (three - two * tau), six * tau * (T::one() - tau) / duration)
}

/// A TCP moving from `start` to `goal` in `duration` seconds along the cubic, or following a
/// streamed target sample (`duration = 0`, `start = goal`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseTrajectory<T: RealField> {
    start: Placement<T>,
    goal: Placement<T>,
    axis: Vector3<T>,
    angle: T,
    duration: T,
    elapsed: T,
    streamed: Option<CartesianTarget<T>>,
}

impl<T: RealField + Copy> PoseTrajectory<T> {
    /// Resting at `pose`.
    pub fn hold(pose: Placement<T>) -> Self {
        Self::towards(pose, pose, T::zero())
    }

    /// From `start` to `goal` in `duration` (s).
    pub fn towards(start: Placement<T>, goal: Placement<T>, duration: T) -> Self {
        // Through the quaternion: `Rotation3::axis_angle` takes `acos` of a trace that rounding
        // can push past 1 (NaN in f32 for nearly equal orientations).
        // The sign with `w ≥ 0` is the short way (angle ≤ π).
        let mut relative = UnitQuaternion::from_rotation_matrix(&(start.rotation.inverse() * goal.rotation));
        if relative.w < T::zero() {
            relative = UnitQuaternion::new_unchecked(-relative.into_inner());
        }
        let (axis, angle) =
            relative.axis_angle().map_or((Vector3::z(), T::zero()), |(a, angle)| (a.into_inner(), angle));
        Self { start, goal, axis, angle, duration, elapsed: T::zero(), streamed: None }
    }

    /// Follows a target sample from the planner (pose and twist), until the next goal.
    pub fn streamed(target: CartesianTarget<T>) -> Self {
        Self { streamed: Some(target), ..Self::hold(target.pose) }
    }

    /// The goal pose.
    pub fn goal(&self) -> Placement<T> {
        self.streamed.map_or(self.goal, |s| s.pose)
    }

    /// Advances by `dt` (s).
    pub fn advance(&mut self, dt: T) {
        self.elapsed = (self.elapsed + dt).min(self.duration.max(T::zero()));
    }

    /// `true` once the goal is reached (always for a streamed sample).
    pub fn finished(&self) -> bool {
        self.elapsed >= self.duration
    }

    /// The desired pose and twist now.
    pub fn sample(&self) -> CartesianTarget<T> {
        if let Some(streamed) = self.streamed {
            return streamed;
        }
        let (s, ds) = cubic(self.elapsed, self.duration);
        let translation =
            self.start.translation.vector + (self.goal.translation.vector - self.start.translation.vector) * s;
        let axis = Unit::new_unchecked(self.axis);
        let rotation = self.start.rotation * Rotation3::from_axis_angle(&axis, self.angle * s);
        CartesianTarget {
            pose: Placement::from_parts(translation.into(), rotation),
            linear_velocity: (self.goal.translation.vector - self.start.translation.vector) * ds,
            angular_velocity: self.start.rotation * (self.axis * (self.angle * ds)),
        }
    }
}

/// Joint values moving from `start` to `goal` in `duration` seconds along the cubic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointTrajectory<T, const N: usize> {
    start: SVector<T, N>,
    goal: SVector<T, N>,
    duration: T,
    elapsed: T,
}

impl<T: RealField + Copy, const N: usize> JointTrajectory<T, N> {
    /// Resting at `q`.
    pub fn hold(q: SVector<T, N>) -> Self {
        Self::towards(q, q, T::zero())
    }

    /// From `start` to `goal` in `duration` (s).
    pub fn towards(start: SVector<T, N>, goal: SVector<T, N>, duration: T) -> Self {
        Self { start, goal, duration, elapsed: T::zero() }
    }

    /// The goal.
    pub fn goal(&self) -> &SVector<T, N> {
        &self.goal
    }

    /// Advances by `dt` (s).
    pub fn advance(&mut self, dt: T) {
        self.elapsed = (self.elapsed + dt).min(self.duration.max(T::zero()));
    }

    /// Desired values and rates now.
    pub fn sample(&self) -> (SVector<T, N>, SVector<T, N>) {
        let (s, ds) = cubic(self.elapsed, self.duration);
        let delta = self.goal - self.start;
        (self.start + delta * s, delta * ds)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;

    #[test]
    fn pose_cubic_starts_and_ends_at_rest_and_matches_its_derivative() {
        let start = Placement::from_parts(Vector3::new(0.1, 0.2, 0.3).into(), Rotation3::identity());
        let goal =
            Placement::from_parts(Vector3::new(1.1, -0.2, 0.5).into(), Rotation3::from_euler_angles(0.3, -0.2, 0.9));
        let mut trajectory = PoseTrajectory::towards(start, goal, 2.0_f64);
        assert_eq!(trajectory.sample().linear_velocity, Vector3::zeros());
        let dt = 1e-4;
        for _ in 0..20_100 {
            let before = trajectory.sample();
            trajectory.advance(dt);
            let after = trajectory.sample();
            let fd = (after.pose.translation.vector - before.pose.translation.vector) / dt;
            let mid = (after.linear_velocity + before.linear_velocity) * 0.5;
            assert!((fd - mid).norm() < 1e-6);
            let rotation = after.pose.rotation * before.pose.rotation.inverse();
            // Through the quaternion: `Rotation3::scaled_axis` rounds rotations of 1e-8 rad to 0.
            let omega = UnitQuaternion::from_rotation_matrix(&rotation).scaled_axis() / dt;
            assert!((omega - (after.angular_velocity + before.angular_velocity) * 0.5).norm() < 1e-5);
        }
        assert!(trajectory.finished());
        let end = trajectory.sample();
        assert!((end.pose.translation.vector - goal.translation.vector).norm() < 1e-12);
        assert!((end.pose.rotation.inverse() * goal.rotation).angle() < 1e-12);
        assert_eq!(end.linear_velocity, Vector3::zeros());
    }

    #[test]
    fn joint_cubic_reaches_the_goal_in_f32() {
        let mut trajectory =
            JointTrajectory::towards(SVector::<f32, 2>::new(0.0, 1.0), SVector::<f32, 2>::new(1.0, -1.0), 0.5);
        trajectory.advance(0.25);
        let (q, v) = trajectory.sample();
        assert!((q[0] - 0.5).abs() < 1e-6 && (v[0] - 3.0).abs() < 1e-5);
        trajectory.advance(1.0);
        assert_eq!(trajectory.sample(), (SVector::<f32, 2>::new(1.0, -1.0), SVector::zeros()));
    }
}
