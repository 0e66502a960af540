//! VIDET vision: camera calibration and rectification, and the stereo pipeline from rectified
//! images to 3D line segments (paper section 3): Canny edges, polygonal approximation, Ayache's
//! segment matching, back-projection.
// `unsafe` appears only in the CPU-feature dispatch that `multiversion` generates for the
// hot image loops (each such function carries a local `allow`).
#![deny(unsafe_code)]

pub mod calib;
pub mod rectify;

pub mod canny;
pub mod chains;
pub mod error;
pub mod evaluation;
pub mod gray;
pub mod io;
pub mod matching;
pub mod pipeline;
pub mod reconstruct;
pub mod roi;
pub mod segments;

pub use error::VisionError;
pub use gray::{GrayView, PixelRect};
pub use pipeline::{run_pipeline, PipelineOutput, StageTimings, StereoPipeline, VisionParams};
pub use reconstruct::{RectifiedGeometry, Segment3d};
pub use roi::{LocalParams, LocalRegion};
pub mod surface;
