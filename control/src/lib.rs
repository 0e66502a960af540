//! # videt-control — the control core of the VIDET haptic interface
//!
//! Pure, allocation-free math over nalgebra fixed-size types: kinematics of the wire device
//! (paper eqs. 1-6), contact and force fields, projection of the desired force onto the forces
//! the wires can make (algorithms P1, P2, ...), and the PI tension loop. No I/O and no clock
//! reads: time comes in as an argument. Every controller is a plain struct whose `update`
//! writes into an output that already exists.
//!
//! Frame (the paper's): the guide points lie in the `z = 0` plane; the thimble works at `z > 0`
//! in front of the frame. SI units everywhere.
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(any(test, feature = "std"))]
extern crate std;

pub mod blend;
pub mod distribution;
pub mod kinematics;
pub mod proxy;
pub mod relief;
pub mod safety;
pub mod scene_map;
pub mod step;
pub mod surface;
pub mod tension_pi;

pub use distribution::{Algorithm, Distribution, ForceLimits};
pub use kinematics::{ForwardSolution, Rig3, RigError};
pub use safety::{SafetyInput, SafetyLimits, SafetyReason, SafetyState, SafetySupervisor};
pub use scene_map::SceneMap;
pub use step::{ControlParams, ControlStep, StepInput, StepOutput};
pub use surface::{Contact, FreeSpace, Plane, Surface};
pub use tension_pi::{TensionPi, TensionPiGains};

/// 3-vector of `f64` (positions in metres, forces in newtons).
pub type Vec3 = nalgebra::Vector3<f64>;
/// Number of wires of the device.
pub const WIRES: usize = 3;
