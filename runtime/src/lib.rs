//! # videt-runtime — the core of the VIDET runtime
//!
//! The control cycle and the real-time loop that runs it, the lock-free surface snapshots, the
//! real-time set-up of threads and memory, the session log (its format, writer and reader) and
//! the status the loop reports. Above the math (`videt-control`) and the device traits
//! (`videt-hal`); knows neither the hardware nor the service that assembles it.
#![warn(missing_docs)]

/// The WireMan's three wires (`videt-control`'s). The service runs every configured device as
/// its own monomorphized cycle ([`runtime_device`]); the parts of the runtime only the WireMan
/// has — its procedures (auto-initialization from the base triangle, tension calibration, wire
/// replacement), its device mode and the haptic bench — are written for these three.
pub use videt_control::WIREMAN_WIRES;

/// The WireMan's geometry.
pub type WiremanDevice = videt_control::Rig3;

/// The WireMan's control step.
pub type WiremanStep = videt_control::ControlStep<WIREMAN_WIRES, WiremanDevice>;

/// The WireMan's control cycle.
pub type WiremanCycle = cycle::ControlCycle<WIREMAN_WIRES, WiremanDevice>;

pub mod calibration;
pub mod control_loop;
pub mod cycle;
pub mod drive_train;
pub mod histogram;
pub mod rt;
pub mod runtime_device;
pub mod setup;
pub mod snapshot;
pub mod status;
pub mod telemetry;
pub mod tension_budget;
pub mod thimble;
