//! # videt-relief — the bas-relief the wearer touches (paper sections 2 and 3)
//!
//! From the 3D segments (and points) of the stereo pipeline to a touchable surface:
//! [`build_from_scene`] maps them into the device workspace with the [`SceneMap`]
//! (camera image onto the explorable area, scene depth into the relief range `d_max` along the
//! reference normal `-z`), triangulates their projection on the constant-depth plane with a
//! constrained Delaunay triangulation whose prescribed edges are the matched segments, adds the
//! frame of the area at the back plane, and lifts every vertex to its relief height.
//!
//! The [`ReliefModel`] answers the control thread's queries without allocating (height and
//! interpolated normal, penetration depth, first crossing of a motion, the paper's distance to
//! impact) and implements `videt_control`'s [`Surface`](videt_control::Surface) and
//! [`ReliefSurface`](videt_control::relief::ReliefSurface), so the control step can render it
//! directly or through the god-object proxy.
//!
//! [`SceneMap`]: videt_control::SceneMap

#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod border;
mod build;
mod cell_hash;
mod clip;
pub mod export;
mod grid;
mod input;
mod layout;
mod model;
pub mod region;
mod steps;

pub use build::{
    build_from_device, build_from_scene, BuildError, BuildReport, BuildTimings, InputItem,
    RejectReason, Rejection,
};
pub use grid::TriangleGrid;
pub use input::{
    params_for_view, DeviceSegment, PinholeCamera, ReliefParams, ReliefParamsError, ReliefShape,
    SceneSegment3,
};
pub use layout::ReliefLayout;
pub use model::{Impact, ModelStats, ReliefModel};

#[cfg(test)]
mod tests;
