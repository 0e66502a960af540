//! Wire homing and auto-initialization of the base triangle (paper section 4.3), and the
//! workspace the measured rig can serve.
//!
//! **Homing.** At rest each wire is detached from the thimble and fully wound, its end pulled
//! against its guide ring. Winding a wire at a limited speed until its tension rises and its
//! encoder stops finds the count at which its free length is zero: that wire's encoder zero.
//!
//! **Auto-initialization.** With the three wires connected to the empty thimble, each wire in
//! turn is wound (speed-limited, tension-capped) while the other two pay out at low tension, until
//! the thimble stops against that wire's guide ring. The other two wire lengths are then two sides
//! of the base triangle, so three windings measure each side twice. A wound wire stopped with the
//! thimble at its ring has its end at the ring, exactly as when homed, so each winding also homes
//! its own wire: the procedure needs no encoder zero beforehand, and the lengths of every stop are
//! computed once the three zeros are known. The sides are combined by
//! least squares (for two equally weighted measurements of one side: their mean) and the
//! residuals reported; the guide points follow in the paper's frame (`x0` at the origin, `x1` on
//! the `+x` axis, `x2` in the `z = 0` plane with `y > 0`).
//!
//! [`Procedure`] is a per-period state machine: pure, allocation-free, time as an argument. Each
//! period it reads encoder counts, wire speeds, tensions and the fault inputs and writes a
//! set-point per wire: the force the motor applies to the wire (the runtime turns it into a
//! torque through the transmission, without tension feedback). A wire against its stop is a very
//! stiff load, and the empty thimble pinned at a ring makes the paying-out wires stiff too; a
//! force source is stable on such loads where a tension loop rings. The measured tensions serve
//! to detect the stops and the limits. Any failure ends it
//! with every set-point at the minimum tension and a [`Failure`] that says what went wrong.
//!
//! Lengths here are *free* (unstretched) lengths from the encoders. At the paying-out tension the
//! Kevlar stretches by `T·l/EA` (about 0.03 mm for 0.4 N over 0.5 m); this is left uncorrected.
//!
//! The parts: [`Procedure`], the state machine, runs with [`ProcedureParams`] and a [`Plan`],
//! reads a [`ProcedureInput`] each period and reports its [`Stage`] and [`Status`] (a failure
//! says why with a [`Failure`]); [`solve_base_triangle`] turns the six measured sides into a
//! [`BaseTriangle`]; [`workspace()`] samples what a rig can serve, as defined by a
//! [`WorkspaceSpec`].

mod failure;
mod params;
mod period;
mod procedure;
mod triangle;
mod workspace;

pub use failure::{Failure, Limit, Side};
pub use params::{Plan, ProcedureParams};
pub use period::{ProcedureInput, Stage, Status};
pub use procedure::Procedure;
pub use triangle::{heron_area_m2, solve_base_triangle, BaseTriangle};
pub use workspace::{serves_point, workspace, Workspace, WorkspaceSpec};
