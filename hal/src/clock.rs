//! A monotonic tick counter for timing the control loop.
//!
//! The application loop uses it to pace cycles, to measure how long a
//! controller step took and to detect overruns. The kernel itself takes the
//! control period as a parameter and never reads a clock.

use crate::error::ErrorType;

/// A monotonic, 64-bit tick counter with a fixed tick rate.
///
/// # What implementors MUST do
///
/// - `now` returns a count that never decreases from one call to the next
///   (two calls within one tick may return the same count). A hardware counter
///   narrower than 64 bits (for example a 32-bit cycle counter, which wraps
///   after about 25 s at 168 MHz) is extended to 64 bits by the
///   implementation, so that the count never wraps in practice.
/// - `now` does not block; it fails only when the counter cannot be read
///   (for example [`ErrorKind::Communication`] for an external timer or
///   [`ErrorKind::NotReady`] before the timer runs).
/// - `ticks_per_second` is non-zero and the same for every call on one
///   clock: elapsed seconds are `(later − earlier) / ticks_per_second`.
///
/// [`ErrorKind::Communication`]: crate::ErrorKind::Communication
/// [`ErrorKind::NotReady`]: crate::ErrorKind::NotReady
///
/// # Example
///
/// A clock that advances by one millisecond per read:
///
/// ```
/// use core::convert::Infallible;
/// use hal::{CycleClock, ErrorType};
///
/// struct Stepping(u64);
///
/// impl ErrorType for Stepping {
///     type Error = Infallible;
/// }
///
/// impl CycleClock for Stepping {
///     fn now(&mut self) -> Result<u64, Infallible> {
///         self.0 += 1_000;
///         Ok(self.0)
///     }
///     fn ticks_per_second(&self) -> u32 {
///         1_000_000
///     }
/// }
///
/// let mut clock = Stepping(0);
/// let start = clock.now()?;
/// let end = clock.now()?;
/// let elapsed_s = (end - start) as f64 / f64::from(clock.ticks_per_second());
/// assert_eq!(elapsed_s, 0.001);
/// # Ok::<(), Infallible>(())
/// ```
pub trait CycleClock: ErrorType {
    /// The current tick count, monotonically non-decreasing.
    fn now(&mut self) -> Result<u64, Self::Error>;

    /// Ticks per second of [`now`](Self::now): constant and non-zero.
    fn ticks_per_second(&self) -> u32;
}

/// A mutable reference to a clock is the same clock.
impl<I: CycleClock + ?Sized> CycleClock for &mut I {
    #[inline]
    fn now(&mut self) -> Result<u64, Self::Error> {
        I::now(self)
    }

    #[inline]
    fn ticks_per_second(&self) -> u32 {
        I::ticks_per_second(self)
    }
}

#[cfg(test)]
mod tests {
    use super::CycleClock;
    use crate::error::{Error, ErrorKind, ErrorType};
    use core::convert::Infallible;

    /// An ideal clock: a simulated counter that advances by `step` ticks
    /// between two reads (time passes while the loop runs).
    struct SimClock {
        ticks: u64,
        step: u64,
    }

    impl ErrorType for SimClock {
        type Error = Infallible;
    }

    impl CycleClock for SimClock {
        fn now(&mut self) -> Result<u64, Infallible> {
            let now = self.ticks;
            self.ticks += self.step;
            Ok(now)
        }

        fn ticks_per_second(&self) -> u32 {
            1_000
        }
    }

    /// Generic loop code: ticks elapsed between two reads and the tick rate,
    /// taking the clock by value so that `&mut clock` exercises the
    /// forwarding impl.
    fn measure<C: CycleClock>(mut clock: C) -> Result<(u64, u32), C::Error> {
        let start = clock.now()?;
        let end = clock.now()?;
        Ok((end.saturating_sub(start), clock.ticks_per_second()))
    }

    #[test]
    fn ideal_through_mut_ref() {
        let mut clock = SimClock { ticks: 5, step: 3 };
        let Ok((elapsed, rate)) = measure(&mut clock);
        assert_eq!((elapsed, rate), (3, 1_000));
        // The clock behind the reference advanced too.
        let Ok(now) = clock.now();
        assert_eq!(now, 11);
    }

    #[test]
    fn ideal_is_non_decreasing_in_f64_and_f32_seconds() {
        let mut clock = SimClock { ticks: 0, step: 0 };
        let mut previous = 0;
        for step in [0_u64, 1, 0, 250, 999] {
            clock.step = step;
            let Ok(now) = clock.now();
            assert!(now >= previous);
            previous = now;
        }
        // The last read returned the count before its own step.
        assert_eq!(previous, 251);
        let rate = clock.ticks_per_second();
        #[allow(clippy::cast_precision_loss, reason = "small exact tick counts in a test")]
        let (seconds_f64, seconds_f32) = (previous as f64 / f64::from(rate), previous as f32 / rate as f32);
        assert!((seconds_f64 - 0.251).abs() < 1e-12);
        assert!((seconds_f32 - 0.251).abs() < 1e-6);
    }

    /// An external timer on a bus that has gone away.
    struct LostTimer;

    #[derive(Debug)]
    struct NoAck;

    impl Error for NoAck {
        fn kind(&self) -> ErrorKind {
            ErrorKind::Communication
        }
    }

    impl ErrorType for LostTimer {
        type Error = NoAck;
    }

    impl CycleClock for LostTimer {
        fn now(&mut self) -> Result<u64, NoAck> {
            Err(NoAck)
        }

        fn ticks_per_second(&self) -> u32 {
            32_768
        }
    }

    #[test]
    fn faulty_reports_communication_through_mut_ref() {
        let mut timer = LostTimer;
        let result = measure(&mut timer);
        assert_eq!(result.map_err(|e| e.kind()), Err(ErrorKind::Communication));
        assert_eq!(<&mut LostTimer as CycleClock>::ticks_per_second(&&mut timer), 32_768);
    }
}
