//! Hardware lifecycle (after ros2_control's hardware interface).
//!
//! `Unconfigured --configure--> Inactive --activate--> Active --deactivate--> Inactive`.
//! In `Inactive` the state is readable but no command moves a motor; in `Active` commands are
//! accepted. Every transition is **non-RT**: it may block on the bus and allocate.

use crate::ErrorType;

/// Lifecycle state of a piece of hardware.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LifecycleState {
    /// Nothing is set up yet.
    Unconfigured,
    /// Communication is up and state readable; outputs are off.
    Inactive,
    /// Powered and accepting commands.
    Active,
    /// A fault took the device out of service; `deactivate` then `configure` to recover.
    Faulted,
}

/// Lifecycle transitions of a device. All methods are **non-RT**.
pub trait Lifecycle: ErrorType {
    /// Bring communication up and make state readable; no command is accepted yet.
    fn configure(&mut self) -> Result<(), Self::Error>;
    /// Power the outputs and accept commands.
    fn activate(&mut self) -> Result<(), Self::Error>;
    /// Remove power from the outputs (safe state); state stays readable.
    fn deactivate(&mut self) -> Result<(), Self::Error>;
    /// The current lifecycle state.
    fn lifecycle_state(&self) -> LifecycleState;
}
