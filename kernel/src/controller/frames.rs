//! The controller's I/O at the step boundary: one [`SensorFrame`] in, one [`ActuatorFrame`] out
//! per cycle ([`super::Controller::step`]).

use nalgebra::{RealField, SVector};

use hal::{JointSample, PlatformCommand, PlatformSample, LEGS};

/// Number of platform coordinates `r = (x, y, θ)`; they come first in `q`.
pub const PLATFORM_DOF: usize = 3;

/// One cycle's sensor input: the upper body's `U` joints and the platform.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorFrame<T, const U: usize> {
    /// Joint positions, velocities and torques of coordinates `3..3+U`.
    pub joints: JointSample<T, U>,
    /// Platform pose `(x, y, θ)` (coordinates `0..3`), velocity and leg lengths.
    pub platform: PlatformSample<T>,
}

/// The output the controller wrote in a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(serde::Serialize, serde::Deserialize)]
pub enum SafeOutput {
    /// Normal operation: the whole-body control torque.
    Normal,
    /// Gravity compensation with joint damping, platform stopping ([`super::faults`]).
    Hold,
    /// [`SafeOutput::Hold`] plus a brake request: the fault persisted.
    Brake,
}

/// One cycle's output.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ActuatorFrame<T, const U: usize> {
    /// Joint torques (Nm, N), within the effort and rate limits.
    pub torque: [T; U],
    /// Platform velocity command and leg rates.
    pub platform: PlatformCommand<T>,
    /// `true` requests the brakes (a persistent fault).
    pub brake: bool,
    /// Which output this is.
    pub mode: SafeOutput,
}

impl<T: RealField + Copy, const U: usize> SensorFrame<T, U> {
    /// `y = (r, q)` and `ẏ` (5.7): the platform's `platform_coordinates` first (3, or 0 for a
    /// fixed base), then the joints'.
    pub(super) fn coordinates<const N: usize>(&self, platform_coordinates: usize) -> (SVector<T, N>, SVector<T, N>) {
        let mut q = SVector::<T, N>::zeros();
        let mut v = SVector::<T, N>::zeros();
        // The platform's three coordinates first, then the joints (slice copies).
        for (target, (platform, joints)) in [q.as_mut_slice(), v.as_mut_slice()]
            .into_iter()
            .zip([(&self.platform.pose, &self.joints.position), (&self.platform.velocity, &self.joints.velocity)])
        {
            let split = target.len().min(platform.len()).min(platform_coordinates);
            let Some((head, tail)) = target.split_at_mut_checked(split) else { continue };
            for (x, p) in head.iter_mut().zip(platform.iter()) {
                *x = *p;
            }
            for (x, j) in tail.iter_mut().zip(joints.iter()) {
                *x = *j;
            }
        }
        (q, v)
    }
}

impl<T: RealField + Copy, const U: usize> ActuatorFrame<T, U> {
    /// The output before the first cycle: zero torque, the platform at rest, no brake.
    pub(super) fn initial() -> Self {
        Self {
            torque: [T::zero(); U],
            platform: PlatformCommand { velocity: [T::zero(); 3], leg_rates: [T::zero(); LEGS] },
            brake: false,
            mode: SafeOutput::Hold,
        }
    }
}
