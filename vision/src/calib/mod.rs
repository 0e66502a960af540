//! Stereo camera calibration from chessboard views: corner detection, per-camera (Zhang +
//! Levenberg–Marquardt) and stereo calibration, Bouguet rectification, and the calibration file.
//!
//! Pure math ([`geometry`], [`camera_model`], [`lm`], [`intrinsic`], [`stereo`],
//! [`rectification`], [`chessboard`]) is kept apart from I/O ([`image_io`], [`file`](mod@file),
//! [`workflow`]).
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod camera_model;
pub mod chessboard;
pub mod corner_response;
pub mod error;
pub mod file;
pub mod geometry;
pub mod image_io;
pub mod intrinsic;
pub mod lm;
pub mod rectification;
pub mod stereo;
pub mod subpixel;
pub mod workflow;

pub use camera_model::CameraIntrinsics;
pub use chessboard::{find_chessboard, find_chessboard_in_frame, BoardSize};
pub use error::CalibError;
pub use file::StereoCalibration;
pub use intrinsic::{calibrate_camera, MonoCalibration, Pose};
pub use rectification::{stereo_rectify, Rectification};
pub use stereo::{calibrate_stereo, StereoExtrinsics};
pub use workflow::{
    calibrate_stereo_dir, calibrate_stereo_dir_with_alpha, CalibrationReport, ViewReport,
};
