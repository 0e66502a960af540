//! # videt-sim — the digital twin of the VIDET device
//!
//! A physics model of the wire-driven haptic device that implements the `videt-hal` traits, so the
//! real runtime and the real control code run on it unchanged:
//!
//! - [`plant`]: three guide points in the `z = 0` plane, a thimble point mass, elastic
//!   tension-only wires wound by motors through a worm gear onto pulleys; fixed-step integration
//!   at >= 10 kHz inside;
//! - [`operator`]: a virtual operator whose finger follows a scripted path through a
//!   spring-damper hand, so it pushes into surfaces and slides along them as a person would;
//! - [`twin`]: the plant behind the HAL — drives with quadrature encoders, strain-gauge tension
//!   sensors with offset, gain error and seeded noise, an e-stop, recording vibrotactors, and a
//!   clock that is either simulated (faster than real time, deterministic) or real time;
//! - [`converter`]: the strain-gauge converters' timing (data rate, digital filter,
//!   quantization, held samples) the twin's sensors go through when configured;
//! - [`angle_sensors`]: the one-wire device's azimuth and elevation sensors, 14-bit like the
//!   real encoders, from a thimble position, with fault injection.
//!
//! Protocol-level twins of devices, so the real drivers run end to end without hardware:
//!
//! - [`as5048a_encoder`]: a simulated AS5048A angle encoder on SPI, at the one-wire device's
//!   thimble position, for the real angle driver;
//! - [`can_bus`]: a userspace CAN bus (in-process, or across processes over loopback UDP) with
//!   fault injection;
//! - [`cia402_node`]: a simulated CiA 402 drive node on that bus, its motor given by a plant;
//! - [`twin_plant`]: the whole twin as those nodes' motors, on the wall clock, for a drive
//!   process serving a real CAN interface.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod angle_sensors;
pub mod as5048a_encoder;
pub mod can_bus;
pub mod cia402_node;
pub mod converter;
mod fault;
pub mod fault_inbox;
pub mod operator;
pub mod plant;
pub mod twin;
pub mod twin_plant;
pub mod wiring;

pub use angle_sensors::{
    AngleFaults, AngleSensorFault, AngleSensorTwin, AngleTwinError, AngleTwinFault, PositionSource,
    SharedPosition,
};
pub use converter::ConverterModel;
pub use fault::TwinFault;
pub use fault_inbox::{FaultInbox, InboxFault};
pub use operator::{VirtualOperator, Waypoint};
pub use plant::{Plant, PlantParams, WireModules, GRAVITY_M_S2};
pub use twin::{quantize_torque, ClockMode, SensorModel, Twin, TwinError};
pub use wiring::Wiring;

/// 3-vector of `f64`.
pub type Vec3 = nalgebra::Vector3<f64>;
