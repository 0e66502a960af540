//! # videt-assembly — the device's parts, real or simulated
//!
//! Opens what the control cycle runs on: the device's hardware in device mode (CiA 402 drives
//! on SocketCAN, strain-gauge converters, e-stop), or the digital twin for `--sim` (the HAL
//! twin, or its motors behind simulated drives on a CAN bus), with the twins' fault injection.
//! Above the core runtime; knows nothing of the service that runs it.
#![warn(missing_docs)]

/// The WireMan's digital twin.
pub type WiremanTwin =
    videt_sim::Twin<{ videt_runtime::WIREMAN_WIRES }, videt_runtime::WiremanDevice>;

pub mod as_built;
pub mod bus_budget;
pub mod can_twin;
pub mod drive_dictionary;
pub mod hardware;
pub mod sim_faults;
pub mod twin_rt;
pub mod twin_scene;
