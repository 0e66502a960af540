//! VIDET vision: camera calibration and rectification, and the stereo pipeline from rectified
//! images to 3D line segments (paper section 3): Canny edges, polygonal approximation, Ayache's
//! segment matching, back-projection.
//!
//! The crate contains no `unsafe` code of its own (`unsafe_code` is denied). The exemption is the
//! run-time CPU-feature dispatch that the `multiversion` crate generates for the hot image loops
//! (Canny's stages, the rectification inner loop in [`rectify`]); each such function carries a
//! local `allow`.
#![deny(unsafe_code)]

pub mod calib;
pub mod rectify;

pub mod canny;
pub mod chains;
pub mod disparity_range;
pub mod error;
pub mod gray;
pub mod io;
pub mod matching;
pub mod patch_stereo;
pub mod pipeline;
pub mod reconstruct;
pub mod roi;
pub mod segments;

pub use error::VisionError;
pub use gray::{GrayView, PixelRect};
pub use pipeline::{run_pipeline, PipelineOutput, StageTimings, StereoPipeline, VisionParams};
pub use reconstruct::{RectifiedGeometry, Segment3d};
pub use roi::{LocalParams, LocalRegion};
