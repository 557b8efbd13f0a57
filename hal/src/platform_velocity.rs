//! The velocity-controlled mobile base: pose, velocity and leg lengths in,
//! a desired base velocity and leg rates out.
//!
//! The base moves in the plane; its state is `r = (x, y, θ)` in the world
//! frame. It stands on [`LEGS`] steerable wheels, each on a leg of variable
//! length `λ_i`. The legs are indexed in one fixed order that the application
//! and the kernel's platform model agree on.

use crate::error::ErrorType;

/// Number of wheeled legs of the mobile base.
pub const LEGS: usize = 4;

/// One frame of the base's sensors (odometry or localisation, leg encoders).
///
/// ```
/// use hal::{PlatformSample, LEGS};
///
/// let sample = PlatformSample {
///     pose: [1.0_f64, 2.0, 0.5],
///     velocity: [0.1, 0.0, 0.0],
///     leg_lengths: [0.4; LEGS],
///     cycle: 42,
/// };
/// assert_eq!(sample.leg_lengths.len(), 4);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlatformSample<T> {
    /// Base pose in the world frame: `[x (m), y (m), θ (rad)]`. `θ` is
    /// continuous (not wrapped to (−π, π]).
    pub pose: [T; 3],
    /// Base velocity in the world frame: `[ẋ (m/s), ẏ (m/s), θ̇ (rad/s)]`.
    pub velocity: [T; 3],
    /// Leg lengths `λ_i` (m), one per leg.
    pub leg_lengths: [T; LEGS],
    /// Sensor frame counter: increases by one with every new sensor frame and
    /// is unchanged while the frame is not updated.
    pub cycle: u64,
}

/// One command to the base.
///
/// ```
/// use hal::{PlatformCommand, LEGS};
///
/// let stop = PlatformCommand { velocity: [0.0_f32; 3], leg_rates: [0.0; LEGS] };
/// assert!(stop.velocity.iter().chain(&stop.leg_rates).all(|v| *v == 0.0));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlatformCommand<T> {
    /// Desired base velocity `ṙ_des` in the world frame:
    /// `[ẋ (m/s), ẏ (m/s), θ̇ (rad/s)]`.
    pub velocity: [T; 3],
    /// Desired leg length rates `λ̇_i` (m/s), one per leg.
    pub leg_rates: [T; LEGS],
}

/// The velocity-controlled mobile base with variable-length legs.
///
/// One call of [`read`](Self::read) gives the newest sensor frame, one call of
/// [`write_velocity`](Self::write_velocity) sets the velocity the base and its
/// legs track from then on. The application loop reads, runs the controller
/// and writes, once per control cycle.
///
/// # What implementors MUST do
///
/// - `read` returns the newest complete frame, never a mix of two frames,
///   waiting for a due frame for a bounded time only (then
///   [`ErrorKind::Timeout`]).
/// - `cycle` is strictly increasing from one new frame to the next and
///   unchanged when `read` returns the same frame again.
/// - `pose` and `velocity` are in the world frame, with `velocity` the time
///   derivative of `pose`; `θ` is continuous across frames (no jump of 2π).
///   All values of a returned frame are finite.
/// - When the implementation itself judges its newest frame too old to control
///   with, `read` returns [`ErrorKind::Stale`]; before the first frame,
///   [`ErrorKind::NotReady`].
/// - `write_velocity` makes the base track `command.velocity` (world frame)
///   and leg `i` track `command.leg_rates[i]` from the call on until the next
///   successful call. Turning the world-frame velocity into wheel steering
///   angles and wheel speeds (using the current `θ` and leg lengths) is the
///   implementor's job; avoiding the steering singularities is the
///   controller's, so the implementor MUST NOT substitute a different motion.
/// - Limiting velocities and accelerations is the caller's job. The
///   implementor may in addition clamp to its hardware limits (and stop a leg
///   at its end stop), but it MUST NOT ignore a command: a finite command is
///   tracked (possibly clamped) or rejected with an error, never dropped
///   silently.
/// - A non-finite value is never applied: `write_velocity` returns
///   [`ErrorKind::OutOfRange`] and the base takes its documented safe reaction
///   (a controlled stop). The same holds when no write arrives within the
///   implementation's own watchdog time.
/// - A failed `write_velocity` leaves the base in a documented state (the
///   previous command, or the safe reaction), never a partial update.
///
/// [`ErrorKind::Timeout`]: crate::ErrorKind::Timeout
/// [`ErrorKind::Stale`]: crate::ErrorKind::Stale
/// [`ErrorKind::NotReady`]: crate::ErrorKind::NotReady
/// [`ErrorKind::OutOfRange`]: crate::ErrorKind::OutOfRange
///
/// # Example
///
/// A base whose emergency stop is engaged refuses every command:
///
/// ```
/// use hal::{Error, ErrorKind, ErrorType, PlatformCommand, PlatformSample,
///           PlatformVelocityInterface, LEGS};
///
/// struct Stopped;
///
/// impl ErrorType for Stopped {
///     type Error = ErrorKind;
/// }
///
/// impl PlatformVelocityInterface<f32> for Stopped {
///     fn read(&mut self) -> Result<PlatformSample<f32>, ErrorKind> {
///         Ok(PlatformSample {
///             pose: [0.0; 3],
///             velocity: [0.0; 3],
///             leg_lengths: [0.45; LEGS],
///             cycle: 1,
///         })
///     }
///     fn write_velocity(&mut self, _: &PlatformCommand<f32>) -> Result<(), ErrorKind> {
///         Err(ErrorKind::NotReady)
///     }
/// }
///
/// let mut base = Stopped;
/// assert_eq!(base.read()?.leg_lengths, [0.45; LEGS]);
/// let drive = PlatformCommand { velocity: [0.2, 0.0, 0.0], leg_rates: [0.0; LEGS] };
/// let refused = base.write_velocity(&drive);
/// assert_eq!(refused.map_err(|e| e.kind()), Err(ErrorKind::NotReady));
/// # Ok::<(), ErrorKind>(())
/// ```
pub trait PlatformVelocityInterface<T>: ErrorType {
    /// Reads the newest sensor frame (pose, velocity, leg lengths and the
    /// frame counter).
    fn read(&mut self) -> Result<PlatformSample<T>, Self::Error>;

    /// Commands the world-frame base velocity and the leg rates, held until
    /// the next call.
    fn write_velocity(&mut self, command: &PlatformCommand<T>) -> Result<(), Self::Error>;
}

/// A mutable reference to a platform velocity interface is the same
/// interface.
impl<T, I> PlatformVelocityInterface<T> for &mut I
where
    I: PlatformVelocityInterface<T> + ?Sized,
{
    #[inline]
    fn read(&mut self) -> Result<PlatformSample<T>, Self::Error> {
        I::read(self)
    }

    #[inline]
    fn write_velocity(&mut self, command: &PlatformCommand<T>) -> Result<(), Self::Error> {
        I::write_velocity(self, command)
    }
}

#[cfg(test)]
mod tests {
    use super::{PlatformCommand, PlatformSample, PlatformVelocityInterface, LEGS};
    use crate::error::{Error, ErrorKind, ErrorType};
    use core::convert::Infallible;
    use core::ops::{Add, Mul};

    /// An ideal base: tracks the commanded velocity exactly (`ṙ = ṙ_des`) and
    /// each read advances one time step `dt`.
    struct IdealBase<T> {
        frame: PlatformSample<T>,
        command: PlatformCommand<T>,
        dt: T,
    }

    impl<T: Copy + From<f32>> IdealBase<T> {
        fn new(dt: T, leg_length: T) -> Self {
            let zero = T::from(0.0);
            Self {
                frame: PlatformSample {
                    pose: [zero; 3],
                    velocity: [zero; 3],
                    leg_lengths: [leg_length; LEGS],
                    cycle: 0,
                },
                command: PlatformCommand { velocity: [zero; 3], leg_rates: [zero; LEGS] },
                dt,
            }
        }
    }

    impl<T> ErrorType for IdealBase<T> {
        type Error = Infallible;
    }

    impl<T: Copy + Add<Output = T> + Mul<Output = T>> PlatformVelocityInterface<T> for IdealBase<T> {
        fn read(&mut self) -> Result<PlatformSample<T>, Infallible> {
            let dt = self.dt;
            let frame = &mut self.frame;
            frame.velocity = self.command.velocity;
            for (r, v) in frame.pose.iter_mut().zip(self.command.velocity) {
                *r = *r + v * dt;
            }
            for (l, rate) in frame.leg_lengths.iter_mut().zip(self.command.leg_rates) {
                *l = *l + rate * dt;
            }
            frame.cycle += 1;
            Ok(*frame)
        }

        fn write_velocity(&mut self, command: &PlatformCommand<T>) -> Result<(), Infallible> {
            self.command = *command;
            Ok(())
        }
    }

    /// Generic application code: takes the interface by value, so passing
    /// `&mut base` exercises the forwarding impl.
    fn drive<T, P: PlatformVelocityInterface<T>>(
        mut base: P,
        command: PlatformCommand<T>,
        cycles: usize,
    ) -> Result<Option<PlatformSample<T>>, P::Error> {
        let mut last = None;
        for _ in 0..cycles {
            base.write_velocity(&command)?;
            last = Some(base.read()?);
        }
        Ok(last)
    }

    fn ideal_through_mut_ref<T>()
    where
        T: Copy + From<f32> + Add<Output = T> + Mul<Output = T> + PartialEq + core::fmt::Debug,
    {
        let t = T::from;
        let mut base = IdealBase::new(t(0.25), t(0.5));
        let command =
            PlatformCommand { velocity: [t(1.0), t(-0.5), t(0.25)], leg_rates: [t(0.125), t(0.0), t(-0.125), t(0.0)] };
        let Ok(last) = drive(&mut base, command, 4);
        let expected = PlatformSample {
            pose: [t(1.0), t(-0.5), t(0.25)],
            velocity: [t(1.0), t(-0.5), t(0.25)],
            leg_lengths: [t(0.625), t(0.5), t(0.375), t(0.5)],
            cycle: 4,
        };
        assert_eq!(last, Some(expected));
        assert_eq!(base.frame, expected);
    }

    #[test]
    fn ideal_f64() {
        ideal_through_mut_ref::<f64>();
    }

    #[test]
    fn ideal_f32() {
        ideal_through_mut_ref::<f32>();
    }

    /// Errors of the faulty base.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    enum BaseFault {
        EmergencyStop,
        NonFiniteCommand,
    }

    impl Error for BaseFault {
        fn kind(&self) -> ErrorKind {
            match self {
                Self::EmergencyStop => ErrorKind::NotReady,
                Self::NonFiniteCommand => ErrorKind::OutOfRange,
            }
        }
    }

    /// A base that stops itself on a non-finite command and then reports its
    /// emergency stop on every read.
    struct FaultyBase {
        stopped: bool,
        command: PlatformCommand<f32>,
    }

    impl ErrorType for FaultyBase {
        type Error = BaseFault;
    }

    impl PlatformVelocityInterface<f32> for FaultyBase {
        fn read(&mut self) -> Result<PlatformSample<f32>, BaseFault> {
            if self.stopped {
                return Err(BaseFault::EmergencyStop);
            }
            Ok(PlatformSample { pose: [0.0; 3], velocity: self.command.velocity, leg_lengths: [0.5; LEGS], cycle: 1 })
        }

        fn write_velocity(&mut self, command: &PlatformCommand<f32>) -> Result<(), BaseFault> {
            let finite = command.velocity.iter().chain(&command.leg_rates).all(|v| v.is_finite());
            if !finite {
                self.stopped = true;
                self.command = PlatformCommand { velocity: [0.0; 3], leg_rates: [0.0; LEGS] };
                return Err(BaseFault::NonFiniteCommand);
            }
            self.command = *command;
            Ok(())
        }
    }

    #[test]
    fn faulty_base_reports_kinds_through_mut_ref() {
        let mut base =
            FaultyBase { stopped: false, command: PlatformCommand { velocity: [0.0; 3], leg_rates: [0.0; LEGS] } };
        let good = PlatformCommand { velocity: [0.5, 0.0, 0.0], leg_rates: [0.0; LEGS] };
        let velocity = drive(&mut base, good, 2).map(|last| last.map(|s| s.velocity));
        assert_eq!(velocity, Ok(Some([0.5, 0.0, 0.0])));

        let bad = PlatformCommand { velocity: [0.5, f32::INFINITY, 0.0], leg_rates: [0.0; LEGS] };
        let error = drive(&mut base, bad, 1).err();
        assert_eq!(error.map(|e| e.kind()), Some(ErrorKind::OutOfRange));
        assert_eq!(base.command.velocity, [0.0; 3]);

        let read = <&mut FaultyBase as PlatformVelocityInterface<f32>>::read;
        let error = read(&mut &mut base).err();
        assert_eq!(error, Some(BaseFault::EmergencyStop));
        assert_eq!(error.map(|e| e.kind()), Some(ErrorKind::NotReady));
    }
}
