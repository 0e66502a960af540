//! Wire homing, auto-initialization and wire replacement on the hardware (or the twin).
//!
//! The procedure itself is `videt_control::autoinit`'s pure state machine; this module runs it
//! period by period on the HAL ([`runner`]), asks the technician for the manual steps
//! ([`session::Technician`]), turns the result into a calibration file
//! (`videt_config::calibration`), and keeps other processes off the motors meanwhile
//! ([`lock`]). [`twin`] builds the digital twin a `--sim` run rehearses on. [`commission`]
//! checks a newly assembled rig's wiring and names the fixes.

pub mod commission;
pub mod corrected;
pub mod daemon;
pub mod lock;
pub mod params;
pub mod procedure_port;
pub mod remote;
pub mod runner;
pub mod session;
pub mod tension;
pub mod twin;

pub use lock::{LockError, MotorsLock};
pub use session::{InitError, InitOutcome, Request, Technician};
