//! Digital I/O of the device: the emergency-stop input ([`estop::EStopInput`]) and the three
//! vibrotactor outputs ([`vibro::VibrotactorOutputs`]), generic over embedded-hal 1.0 pins, plus
//! Linux GPIO character-device constructors ([`linux`]).

pub mod estop;
#[cfg(target_os = "linux")]
pub mod linux;
pub mod vibro;

/// A GPIO failure, naming the pin's role.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GpioError {
    /// What the pin does ("e-stop", "vibrotactor 0", ...).
    pub pin: &'static str,
    /// The embedded-hal error kind.
    pub kind: embedded_hal::digital::ErrorKind,
    /// The e-stop reset was refused because the button is still held.
    pub still_held: bool,
}

impl videt_hal::Error for GpioError {
    fn kind(&self) -> videt_hal::ErrorKind {
        if self.still_held {
            videt_hal::ErrorKind::Fault
        } else {
            videt_hal::ErrorKind::Disconnected
        }
    }
}

impl core::fmt::Display for GpioError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        if self.still_held {
            write!(f, "{}: cannot reset while the button is held", self.pin)
        } else {
            write!(f, "{}: GPIO error ({:?})", self.pin, self.kind)
        }
    }
}

impl std::error::Error for GpioError {}
