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
//!
//! - Devices: [`Rig3`] (three wires, guides anywhere in `z = 0`), [`RigPlanar`] (the two-wire
//!   x-z device of the paper's experiments), [`polar`] (the one-wire device, eq. 7), [`Rig4`]
//!   (four wires around the workspace). [`device::WireDevice`] is what the step needs of each:
//!   the wire count is a const generic, chosen once when the runtime starts.
//! - Force: [`contact`] (spring-damper along the normal), [`field`] (constant-direction and
//!   bisector fields, free-space pull), [`distribution`] (P1, P2, F1, F2 and QP projections onto
//!   `F = { V t : t_min <= t_i <= t_max }`, continuous and within the felt bound of [`felt`]),
//!   [`measures`] (index V, isotropic force limit).
//! - [`step`]: one control period; [`analysis`]: the designer's sweeps behind `videt analyze`.
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(any(test, feature = "std"))]
extern crate std;

mod algorithm;
/// The WireMan's three wires: its base triangle (auto-initialization measures it), the wires
/// of what only the WireMan has (its procedures, its device mode, the haptic bench), and the
/// per-wire slots of a period's record and of the session log (a device's wires fill the first
/// ones, the rest stay zero; a cycle for more wires does not compile).
pub const WIREMAN_WIRES: usize = 3;

pub mod analysis;
pub mod autoinit;
pub mod blend;
mod box_qp;
pub mod contact;
pub mod device;
pub mod distribution;
pub mod felt;
pub mod field;
pub mod kinematics;
pub mod measures;
pub mod planar;
pub mod polar;
pub mod profile;
pub mod proxy;
pub mod relief;
pub mod safety;
pub mod scene_map;
pub mod spidar;
pub mod step;
pub mod surface;
pub mod tension_loop;
pub mod tension_pi;
mod wire_device;
pub mod wire_map;

pub use contact::{contact_force, ContactModel};
pub use device::{
    minimum_tensions, DeviceForces, DeviceKind, ForceSettings, PlanarDevice, PolarDevice,
    PolarError, Sensed, WireDevice, WireTensions,
};
pub use distribution::{
    distribute, project, Algorithm, Distribution, FieldRule, ForceLimits, LimitsError, Projection,
};
pub use felt::{FeltPeriod, FeltTally, FELT_MARGIN_N};
pub use field::{field_force, free_space_force, ForceField};
pub use kinematics::{ForwardSolution, Rig3, RigError};
pub use measures::{isotropic_force_limit_n, v_index};
pub use planar::{PlanarForward, RigPlanar, Vec2};
pub use polar::{one_wire_distribute, polar_forward, polar_inverse, PolarCoordinates};
pub use profile::{Profile, ProfileError, SolidSide};
pub use safety::{SafetyInput, SafetyLimits, SafetyReason, SafetyState, SafetySupervisor};
pub use scene_map::SceneMap;
pub use spidar::Rig4;
pub use step::{ControlParams, ControlStep, StepInput, StepOutput, WireStretch};
pub use surface::{Contact, FreeSpace, Plane, Surface};
pub use tension_pi::{TensionPi, TensionPiGains};
pub use wire_map::WireMap;

/// 3-vector of `f64` (positions in metres, forces in newtons).
pub type Vec3 = nalgebra::Vector3<f64>;
