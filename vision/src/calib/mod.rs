//! Stereo camera calibration from chessboard views: corner detection, per-camera (Zhang +
//! Levenberg–Marquardt) and stereo calibration, Bouguet rectification, and the calibration file.

pub mod camera_model;
pub mod error;
pub mod geometry;
pub mod intrinsic;
pub mod lm;

pub use camera_model::CameraIntrinsics;
pub use error::CalibError;
pub use intrinsic::{calibrate_camera, MonoCalibration, Pose};
pub mod chessboard;
pub mod corner_response;
pub mod image_io;
pub mod subpixel;
