//! CiA 402 wire drives: the power state machine ([`state`]), the process data ([`pdo`]),
//! configuration ([`config`]), errors ([`error`]), the set of one drive per wire implementing
//! the HAL for any wire count ([`drive_set`]), the drives' analog inputs it receives
//! ([`analog`]); the drive's units read from its device description are
//! `videt-drive-description`'s ([`DriveResolution`]).

pub mod analog;
pub mod compat;
pub mod config;
pub mod drive_set;
pub mod error;
pub mod identity;
pub mod pdo;
pub mod state;

#[cfg(test)]
mod scripted_tests;
#[cfg(test)]
mod sim_tests;

pub use analog::{AnalogSample, DriveAnalogInputs};
pub use config::{ConfigError, DriveSetConfig};
pub use drive_set::{wire_length_m, Cia402DriveSet};
pub use error::DriveError;
pub use identity::{DriveIdentity, SharedStartupReport, StartupNote, StartupReport};
pub use pdo::AnalogInputObject;
pub use state::{PowerGoal, PowerSequencer, PowerState};
pub use videt_drive_description::{DriveResolution, Origin, Sourced, TorqueUnit};
