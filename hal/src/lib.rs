//! # videt-hal — device capabilities of the VIDET haptic interface
//!
//! One module per device capability. Each capability is a trait over an [`ErrorType`] whose
//! error exposes an [`ErrorKind`] the caller can act on (the embedded-hal 1.0 pattern). This crate
//! holds traits and plain data only: no I/O, no allocation in the real-time methods' contracts.
//!
//! The wire count `N` of the configured device is a const generic of the per-wire capabilities
//! ([`WireDrives`], [`TensionSensors`]): one implementation serves every device.
//!
//! Units are SI everywhere (metres, newtons, newton-metres, seconds, radians); names carry the
//! unit (`tension_n`, `torque_nm`, `position_counts`).
//!
//! Real-time contract: methods marked **RT** may be called from the control thread every cycle.
//! They must not allocate, lock, log with formatting or block (bus I/O excepted). Methods marked
//! **non-RT** may block and allocate.
#![forbid(unsafe_code)]
#![no_std]
#![warn(missing_docs)]

extern crate alloc;

pub mod angle;
pub mod camera;
pub mod clock;
pub mod drive;
pub mod error;
pub mod estop;
pub mod lifecycle;
pub mod tension;
pub mod vibro;

pub use angle::{AngleAxis, AngleSensors};
pub use camera::{GrayFrame, RgbFrame, StereoCamera, StereoFrame};
pub use clock::{Clock, MonoTime};
pub use drive::{DriveSample, DriveState, Transmission, WireDrives};
pub use error::{Error, ErrorKind, ErrorType};
pub use estop::EStop;
pub use lifecycle::{Lifecycle, LifecycleState};
pub use tension::{ConverterModel, TensionSensors};
pub use vibro::Vibrotactors;

/// Number of vibrotactors (one per colour channel: red, green, blue).
pub const VIBROTACTORS: usize = 3;
