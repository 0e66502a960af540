//! A drive's description: the reader for CANopen electronic data sheets and device
//! configuration files ([`eds`]), and the CiA 402 units a description gives ([`units`]: rated
//! torque, torque limit, encoder resolution, gear, SI units). Pure, and below both the drivers
//! that talk to the drives and the configuration that names their files: **non-RT**
//! (allocates).

#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod eds;
pub mod units;

pub use eds::{Eds, EdsError};
pub use units::{DriveResolution, Origin, Sourced, TorqueUnit};
