//! Errors shared by every interface of this crate.
//!
//! Each implementation picks its own error type (`ErrorType::Error`), so a
//! board driver can carry bus-specific detail. Generic code — the application
//! loop, the fault handling — only looks at the portable [`ErrorKind`] that
//! every such error reports through [`Error::kind`].
//!
//! An ideal implementation that cannot fail (a simulator, a test double) uses
//! [`core::convert::Infallible`]; the compiler then knows that the `Err` arm
//! never happens.

use core::fmt;

/// Portable classification of an interface error.
///
/// The set is `#[non_exhaustive]`: match it with a wildcard arm, typically
/// mapping unknown kinds to the same reaction as [`ErrorKind::Other`].
///
/// ```
/// use hal::ErrorKind;
///
/// let kind = ErrorKind::Stale;
/// let reaction = match kind {
///     ErrorKind::Stale | ErrorKind::Timeout => "skip this cycle",
///     _ => "go to the safe output",
/// };
/// assert_eq!(reaction, "skip this cycle");
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ErrorKind {
    /// The device did not answer within the implementor's deadline.
    Timeout,
    /// The sensor frame was not updated for longer than the implementor
    /// tolerates: the data exist but are too old to control with.
    Stale,
    /// A value is outside what the device accepts or can represent
    /// (including non-finite values such as NaN or ±∞).
    OutOfRange,
    /// The transport to the device failed (bus error, checksum mismatch,
    /// lost link).
    Communication,
    /// The device is not (yet, or no longer) operational: not powered, not
    /// enabled, no first frame received, emergency stop engaged.
    NotReady,
    /// Any other failure; see the implementation's own error for detail.
    Other,
}

impl ErrorKind {
    /// A short lowercase description, the same text as [`fmt::Display`].
    ///
    /// ```
    /// assert_eq!(hal::ErrorKind::Timeout.as_str(), "device did not answer in time");
    /// ```
    #[must_use]
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::Timeout => "device did not answer in time",
            Self::Stale => "sensor frame not updated",
            Self::OutOfRange => "value out of range",
            Self::Communication => "communication with the device failed",
            Self::NotReady => "device not ready",
            Self::Other => "other device error",
        }
    }
}

impl fmt::Display for ErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl core::error::Error for ErrorKind {}

/// An error of one of this crate's interfaces.
///
/// Implementors MUST return a [`ErrorKind`] that describes the failure as
/// closely as the set allows, and [`ErrorKind::Other`] only when no other kind
/// fits.
pub trait Error: fmt::Debug {
    /// The portable kind of this error.
    fn kind(&self) -> ErrorKind;
}

/// An [`ErrorKind`] is itself an error, for implementations that have no
/// detail to add.
///
/// ```
/// use hal::{Error, ErrorKind};
///
/// assert_eq!(ErrorKind::NotReady.kind(), ErrorKind::NotReady);
/// ```
impl Error for ErrorKind {
    fn kind(&self) -> ErrorKind {
        *self
    }
}

/// The error of an ideal implementation that cannot fail.
impl Error for core::convert::Infallible {
    fn kind(&self) -> ErrorKind {
        match *self {}
    }
}

/// Names the error type of an interface implementation.
///
/// Every interface trait of this crate has `ErrorType` as its supertrait, so
/// one device that implements several interfaces has one error type.
pub trait ErrorType {
    /// The error returned by every fallible method of the implementation.
    type Error: Error;
}

/// A mutable reference to an interface is the same interface.
impl<I: ErrorType + ?Sized> ErrorType for &mut I {
    type Error = I::Error;
}

#[cfg(test)]
mod tests {
    use super::{Error, ErrorKind, ErrorType};
    use core::convert::Infallible;

    const ALL: [ErrorKind; 6] = [
        ErrorKind::Timeout,
        ErrorKind::Stale,
        ErrorKind::OutOfRange,
        ErrorKind::Communication,
        ErrorKind::NotReady,
        ErrorKind::Other,
    ];

    #[test]
    fn kind_of_a_kind_is_itself() {
        for kind in ALL {
            assert_eq!(kind.kind(), kind);
        }
    }

    #[test]
    fn display_matches_as_str_and_is_distinct() {
        for (i, a) in ALL.iter().enumerate() {
            assert_eq!(format!("{a}"), a.as_str());
            assert!(!a.as_str().is_empty());
            for b in ALL.iter().skip(i + 1) {
                assert_ne!(a.as_str(), b.as_str());
            }
        }
    }

    #[test]
    fn kind_is_a_core_error() {
        fn takes(_: &dyn core::error::Error) {}
        takes(&ErrorKind::Communication);
    }

    /// A driver-specific error carrying detail beyond the kind.
    #[derive(Debug, PartialEq)]
    struct BusError {
        code: u8,
    }

    impl Error for BusError {
        fn kind(&self) -> ErrorKind {
            match self.code {
                0x10 => ErrorKind::Communication,
                _ => ErrorKind::Other,
            }
        }
    }

    struct Device;
    impl ErrorType for Device {
        type Error = BusError;
    }

    struct Ideal;
    impl ErrorType for Ideal {
        type Error = Infallible;
    }

    fn kind_through<D: ErrorType>(_: &D, error: &D::Error) -> ErrorKind {
        error.kind()
    }

    #[test]
    fn error_type_forwards_through_mut_ref() {
        let mut device = Device;
        let by_ref = &mut device;
        assert_eq!(kind_through(&by_ref, &BusError { code: 0x10 }), ErrorKind::Communication);
        assert_eq!(kind_through(&by_ref, &BusError { code: 1 }), ErrorKind::Other);

        // An ideal implementation stays infallible by reference.
        fn infallible<D: ErrorType<Error = Infallible>>() {}
        infallible::<&mut Ideal>();
        infallible::<&mut &mut Ideal>();
    }
}
