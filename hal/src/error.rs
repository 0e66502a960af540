//! Error kinds shared by every capability, after embedded-hal 1.0's `Error`/`ErrorType` pattern.

use core::fmt::Debug;

/// What went wrong, in terms a caller can act on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum ErrorKind {
    /// The device did not answer in time (heartbeat, SDO, frame, sample).
    Timeout,
    /// The device reports a fault of its own (drive fault, EMCY, sensor saturation).
    Fault,
    /// The device or its bus is gone (unplugged, bus-off, wire broken).
    Disconnected,
    /// A value outside its allowed range was requested or measured.
    OutOfRange,
    /// The device is not in a lifecycle state that allows the call.
    NotReady,
    /// Anything else; see the concrete error.
    Other,
}

impl ErrorKind {
    /// A short, stable, lower-case name for logs and the control socket.
    pub const fn as_str(self) -> &'static str {
        match self {
            ErrorKind::Timeout => "timeout",
            ErrorKind::Fault => "fault",
            ErrorKind::Disconnected => "disconnected",
            ErrorKind::OutOfRange => "out-of-range",
            ErrorKind::NotReady => "not-ready",
            ErrorKind::Other => "other",
        }
    }
}

impl core::fmt::Display for ErrorKind {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A device error: anything that can say what kind of failure it is, and tell it in words a
/// technician can act on (`Display`; `Debug` is for developers).
pub trait Error: Debug + core::fmt::Display {
    /// The kind of failure, for the caller's reaction (safe state, retry, report).
    fn kind(&self) -> ErrorKind;
}

impl Error for ErrorKind {
    fn kind(&self) -> ErrorKind {
        *self
    }
}

/// Associates an error type with a device, shared by all its capabilities.
pub trait ErrorType {
    /// The device's error type.
    type Error: Error;
}

impl<T: ErrorType + ?Sized> ErrorType for &mut T {
    type Error = T::Error;
}
