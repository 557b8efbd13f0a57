//! The torque-controlled upper body: joint state and torque sensing in,
//! joint torque commands out.
//!
//! The `N` joints are indexed in one fixed order that the application and the
//! kernel's robot model agree on (the model's generalised coordinates). Every
//! array of a [`JointSample`] and every torque command uses that order.

use crate::error::ErrorType;

/// One frame of the upper body's joint sensors.
///
/// `T` is the scalar type (`f32` on the board, `f64` or `f32` on the host),
/// `N` the number of torque-controlled joints. Joint `i` of every array is the
/// same physical joint.
///
/// ```
/// use hal::JointSample;
///
/// let sample = JointSample {
///     position: [0.1_f32, -0.2],
///     velocity: [0.0, 0.5],
///     torque: [1.5, -3.0],
///     cycle: 7,
/// };
/// assert_eq!(sample.torque, [1.5, -3.0]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct JointSample<T, const N: usize> {
    /// Joint positions `q`: rad for revolute joints, m for prismatic ones.
    pub position: [T; N],
    /// Joint velocities `q̇`: rad/s (m/s for prismatic joints).
    pub velocity: [T; N],
    /// Measured joint torques: Nm (N for prismatic joints), positive in the
    /// direction of positive joint motion.
    pub torque: [T; N],
    /// Sensor frame counter: increases by one with every new sensor frame and
    /// is unchanged while the frame is not updated.
    pub cycle: u64,
}

/// The torque-controlled joints of the upper body.
///
/// One call of [`read`](Self::read) gives the newest sensor frame, one call of
/// [`write_torque`](Self::write_torque) sets the torque every joint applies
/// from then on. The application loop reads, runs the controller and writes,
/// once per control cycle.
///
/// # What implementors MUST do
///
/// - `read` returns the newest complete frame the implementation has, never a
///   mix of two frames. It may wait for a frame that is due, but for a bounded
///   time only (a deadline of its own, then [`ErrorKind::Timeout`]).
/// - `cycle` is strictly increasing from one new frame to the next and
///   unchanged when `read` returns the same frame again, so the caller can tell
///   a fresh frame from a repeated one. It starts at any value and never wraps
///   in practice (`u64`).
/// - When the implementation itself judges its newest frame too old to control
///   with (its own watchdog), `read` returns an error of kind
///   [`ErrorKind::Stale`] instead of the frame. Before the first frame it
///   returns [`ErrorKind::NotReady`].
/// - All values of a returned frame are finite.
/// - `write_torque` applies `torque[i]` (Nm, N for prismatic joints) to joint
///   `i` from the call on until the next successful call. Values are
///   desired joint torques, not motor currents: gear ratios, motor constants
///   and friction compensation of the drive are the implementor's business.
/// - Saturation is the caller's job (the controller knows the limits). The
///   implementor may in addition clamp to its hardware limits, but it MUST NOT
///   ignore a command: a finite command is applied (possibly clamped) or
///   rejected with an error, never dropped silently.
/// - A non-finite value (NaN, ±∞) is never applied: `write_torque` returns an
///   error of kind [`ErrorKind::OutOfRange`] and the implementation takes its
///   documented safe reaction (for example brakes) instead of holding the old
///   torque forever. The same holds when no write arrives within the
///   implementation's own watchdog time.
/// - A failed `write_torque` leaves the joints in a documented state (the
///   previous command, or the safe reaction), never a partial update of some
///   joints.
///
/// [`ErrorKind::Timeout`]: crate::ErrorKind::Timeout
/// [`ErrorKind::Stale`]: crate::ErrorKind::Stale
/// [`ErrorKind::NotReady`]: crate::ErrorKind::NotReady
/// [`ErrorKind::OutOfRange`]: crate::ErrorKind::OutOfRange
///
/// # Example
///
/// An ideal two-joint body whose torque sensors measure exactly the commanded
/// torque:
///
/// ```
/// use core::convert::Infallible;
/// use hal::{ErrorType, JointSample, JointTorqueInterface};
///
/// struct Ideal {
///     frame: JointSample<f64, 2>,
/// }
///
/// impl ErrorType for Ideal {
///     type Error = Infallible;
/// }
///
/// impl JointTorqueInterface<f64, 2> for Ideal {
///     fn read(&mut self) -> Result<JointSample<f64, 2>, Infallible> {
///         self.frame.cycle += 1;
///         Ok(self.frame)
///     }
///     fn write_torque(&mut self, torque: &[f64; 2]) -> Result<(), Infallible> {
///         self.frame.torque = *torque;
///         Ok(())
///     }
/// }
///
/// let mut body = Ideal {
///     frame: JointSample { position: [0.0; 2], velocity: [0.0; 2], torque: [0.0; 2], cycle: 0 },
/// };
/// body.write_torque(&[2.0, -1.0])?;
/// let sample = body.read()?;
/// assert_eq!(sample.torque, [2.0, -1.0]);
/// assert_eq!(sample.cycle, 1);
/// # Ok::<(), Infallible>(())
/// ```
pub trait JointTorqueInterface<T, const N: usize>: ErrorType {
    /// Reads the newest sensor frame (positions, velocities, measured torques
    /// and the frame counter).
    fn read(&mut self) -> Result<JointSample<T, N>, Self::Error>;

    /// Commands the joint torques `torque` (Nm, N for prismatic joints), held
    /// until the next call.
    fn write_torque(&mut self, torque: &[T; N]) -> Result<(), Self::Error>;
}

/// A mutable reference to a joint torque interface is the same interface.
impl<T, const N: usize, I> JointTorqueInterface<T, N> for &mut I
where
    I: JointTorqueInterface<T, N> + ?Sized,
{
    #[inline]
    fn read(&mut self) -> Result<JointSample<T, N>, Self::Error> {
        I::read(self)
    }

    #[inline]
    fn write_torque(&mut self, torque: &[T; N]) -> Result<(), Self::Error> {
        I::write_torque(self, torque)
    }
}

#[cfg(test)]
mod tests {
    use super::{JointSample, JointTorqueInterface};
    use crate::error::{Error, ErrorKind, ErrorType};
    use core::convert::Infallible;

    /// Ideal joints: each read is a new frame whose measured torque is the
    /// last command, and the command integrates to velocity with unit inertia
    /// over a time step `dt`.
    struct IdealJoints<T, const N: usize> {
        frame: JointSample<T, N>,
        command: [T; N],
        dt: T,
    }

    impl<T: Copy + From<f32>, const N: usize> IdealJoints<T, N> {
        fn new(dt: T) -> Self {
            let zero = T::from(0.0);
            Self {
                frame: JointSample { position: [zero; N], velocity: [zero; N], torque: [zero; N], cycle: 0 },
                command: [zero; N],
                dt,
            }
        }
    }

    impl<T, const N: usize> ErrorType for IdealJoints<T, N> {
        type Error = Infallible;
    }

    impl<T, const N: usize> JointTorqueInterface<T, N> for IdealJoints<T, N>
    where
        T: Copy + core::ops::Add<Output = T> + core::ops::Mul<Output = T>,
    {
        fn read(&mut self) -> Result<JointSample<T, N>, Infallible> {
            let dt = self.dt;
            let frame = &mut self.frame;
            for ((q, dq), tau) in frame.position.iter_mut().zip(frame.velocity.iter_mut()).zip(self.command) {
                *dq = *dq + tau * dt;
                *q = *q + *dq * dt;
            }
            frame.torque = self.command;
            frame.cycle += 1;
            Ok(*frame)
        }

        fn write_torque(&mut self, torque: &[T; N]) -> Result<(), Infallible> {
            self.command = *torque;
            Ok(())
        }
    }

    /// The application loop as generic code sees it: takes the interface by
    /// value, so passing `&mut body` exercises the forwarding impl.
    fn run_cycles<T: Copy, const N: usize, J: JointTorqueInterface<T, N>>(
        mut joints: J,
        torque: [T; N],
        cycles: usize,
    ) -> Result<JointSample<T, N>, J::Error> {
        joints.write_torque(&torque)?;
        let mut last = joints.read()?;
        for _ in 1..cycles {
            joints.write_torque(&torque)?;
            let sample = joints.read()?;
            assert!(sample.cycle > last.cycle, "cycle must increase");
            last = sample;
        }
        Ok(last)
    }

    fn ideal_through_mut_ref<T>(expected_velocity: [T; 2], expected_position: [T; 2])
    where
        T: Copy + From<f32> + core::ops::Add<Output = T> + core::ops::Mul<Output = T> + PartialEq + core::fmt::Debug,
    {
        let mut body = IdealJoints::<T, 2>::new(T::from(0.5));
        let Ok(sample) = run_cycles(&mut body, [T::from(1.0), T::from(-2.0)], 2);
        assert_eq!(sample.cycle, 2);
        assert_eq!(sample.torque, [T::from(1.0), T::from(-2.0)]);
        assert_eq!(sample.velocity, expected_velocity);
        assert_eq!(sample.position, expected_position);
        // The body itself saw the same frames.
        assert_eq!(body.frame, sample);
    }

    #[test]
    fn ideal_f64() {
        // Two semi-implicit Euler steps of q̈ = τ with dt = 0.5 (exact in binary):
        // q̇ = 2·0.5·τ, q = 0.5·(0.5 + 1.0)·τ.
        ideal_through_mut_ref::<f64>([1.0, -2.0], [0.75, -1.5]);
    }

    #[test]
    fn ideal_f32() {
        ideal_through_mut_ref::<f32>([1.0, -2.0], [0.75, -1.5]);
    }

    /// Error of the faulty bus: the kind plus the frame it happened at.
    #[derive(Debug, Clone, Copy, PartialEq)]
    struct BusFault {
        kind: ErrorKind,
        cycle: u64,
    }

    impl Error for BusFault {
        fn kind(&self) -> ErrorKind {
            self.kind
        }
    }

    /// A bus that delivers `frames` frames and then stops updating, and that
    /// rejects non-finite torque commands.
    struct FaultyBus {
        frames: u64,
        cycle: u64,
        applied: [f64; 3],
    }

    impl ErrorType for FaultyBus {
        type Error = BusFault;
    }

    impl JointTorqueInterface<f64, 3> for FaultyBus {
        fn read(&mut self) -> Result<JointSample<f64, 3>, BusFault> {
            if self.cycle >= self.frames {
                return Err(BusFault { kind: ErrorKind::Stale, cycle: self.cycle });
            }
            self.cycle += 1;
            Ok(JointSample { position: [0.0; 3], velocity: [0.0; 3], torque: self.applied, cycle: self.cycle })
        }

        fn write_torque(&mut self, torque: &[f64; 3]) -> Result<(), BusFault> {
            if torque.iter().any(|t| !t.is_finite()) {
                self.applied = [0.0; 3];
                return Err(BusFault { kind: ErrorKind::OutOfRange, cycle: self.cycle });
            }
            self.applied = *torque;
            Ok(())
        }
    }

    #[test]
    fn faulty_read_reports_stale_through_mut_ref() {
        let mut bus = FaultyBus { frames: 3, cycle: 0, applied: [0.0; 3] };
        // Three frames, then the fourth read of five cycles fails.
        let error = run_cycles(&mut bus, [1.0, 2.0, 3.0], 5).err();
        assert_eq!(error.map(|e| e.kind()), Some(ErrorKind::Stale));
        assert_eq!(error.map(|e| e.cycle), Some(3));
        assert_eq!(bus.applied, [1.0, 2.0, 3.0]);
    }

    #[test]
    fn faulty_write_rejects_non_finite() {
        let mut bus = FaultyBus { frames: 10, cycle: 0, applied: [0.0; 3] };
        // By value, so `&mut bus` goes through the forwarding impl.
        fn write<J: JointTorqueInterface<f64, 3>>(mut joints: J, torque: [f64; 3]) -> Result<(), J::Error> {
            joints.write_torque(&torque)
        }
        assert_eq!(write(&mut bus, [1.0, 1.0, 1.0]), Ok(()));
        assert_eq!(bus.applied, [1.0, 1.0, 1.0]);
        let result = write(&mut bus, [1.0, f64::NAN, 1.0]);
        assert_eq!(result.map_err(|e| e.kind()), Err(ErrorKind::OutOfRange));
        // The safe reaction, never a partial update.
        assert_eq!(bus.applied, [0.0; 3]);
    }
}
