//! The CAN seam the drive driver runs on: `embedded-can`'s blocking trait plus a receive with
//! a timeout (which `embedded-can` lacks), and whether the controller is bus-off.
//!
//! Implementations: SocketCAN ([`socketcan_port::SocketCanPort`], Linux) and the twin's
//! userspace bus (`videt-sim`'s endpoints; adapted where the two crates meet).

#[cfg(target_os = "linux")]
pub mod socketcan_port;

use core::time::Duration;

/// A CAN port the drive driver can run a control cycle on.
pub trait CanPort: embedded_can::blocking::Can {
    /// Receive the next frame, waiting at most `timeout`; `Ok(None)` when none arrived in time.
    /// **RT**: the one blocking call of the cycle besides transmit; never waits past `timeout`.
    fn receive_timeout(&mut self, timeout: Duration) -> Result<Option<Self::Frame>, Self::Error>;

    /// Whether the controller is bus-off (after a transmit or receive error). **RT**.
    fn is_bus_off(&self) -> bool {
        false
    }

    /// The operating system's error number behind `error`, when it has one (an interface
    /// gone down, a removed device): kept so the cause can be told in words off the real-time
    /// path. **RT**.
    fn os_error(error: &Self::Error) -> Option<i32> {
        let _ = error;
        None
    }
}
