//! # videt — the VIDET runtime
//!
//! Threads, scheduling, snapshots and the command-line tools of the VIDET haptic interface. The
//! math lives in `videt-control`, the device traits in `videt-hal`, the digital twin in
//! `videt-sim`; this crate wires them together for the `videtd` service and the `videt` tool.
#![warn(missing_docs)]

/// The WireMan's three wires. The service runs every configured device as its own
/// monomorphized cycle (`runtime_device`); the parts of the runtime only the WireMan has — its
/// procedures (auto-initialization from the base triangle, tension calibration, wire
/// replacement), its device mode and the haptic bench — are written for these three.
pub const WIREMAN_WIRES: usize = 3;

/// The WireMan's geometry.
pub type WiremanDevice = videt_control::Rig3;

/// The WireMan's control step.
pub type WiremanStep = videt_control::ControlStep<WIREMAN_WIRES, WiremanDevice>;

/// The WireMan's control cycle.
pub type WiremanCycle = cycle::ControlCycle<WIREMAN_WIRES, WiremanDevice>;

/// The WireMan's digital twin.
pub type WiremanTwin = videt_sim::Twin<WIREMAN_WIRES, WiremanDevice>;

pub mod bus_budget;
pub mod camera_relief;
pub mod can_twin;
pub mod colour_thread;
pub mod control_loop;
pub mod cycle;
pub mod drive_dictionary;
pub mod drive_report;
pub mod haptic_bench;
pub mod hardware;
pub mod histogram;
pub mod init;
pub mod plotting;
pub mod procedure_stream;
pub mod relief_feed;
pub mod relief_scene;
pub mod replay;
pub mod rt;
pub mod runtime_device;
pub mod service;
pub mod setup;
pub mod sim_faults;
pub mod snapshot;
pub mod socket;
pub mod status;
pub mod stereo_relief;
pub mod telemetry;
pub mod tension_budget;
pub mod tool;
pub mod twin_rt;
