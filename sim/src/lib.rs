//! # videt-sim — the digital twin
//!
//! Protocol-level twins of devices: a userspace CAN bus ([`can_bus`]) and a simulated
//! CiA 402 drive node ([`cia402_node`]) so the real drive driver runs end to end without
//! hardware.

pub mod can_bus;
pub mod cia402_node;
