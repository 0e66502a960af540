//! # videt-vision — the stereo vision of VIDET
//!
//! Camera calibration and rectification ([`calib`], [`rectify`]), and the stereo pipeline that
//! turns a rectified pair into the bas-relief surface the wires let the user touch.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod calib;
pub mod rectify;
