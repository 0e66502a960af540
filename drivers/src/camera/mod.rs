//! Stereo cameras: an image-file stereo source for the twin ([`file_source`], always built),
//! V4L2 capture of two devices (`v4l` feature, [`v4l_stereo`]), and the pure pieces they share:
//! timestamp pairing ([`pairing`]) and pixel-format conversion ([`pixel`]). **non-RT**: used by
//! the vision thread.

pub mod file_source;
pub mod pairing;
pub mod pixel;
#[cfg(feature = "v4l")]
pub mod v4l_stereo;

use std::path::PathBuf;

/// A camera error.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    /// A file or device could not be read.
    #[error("{path}: {source}")]
    Io {
        /// File or device.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// An image file could not be decoded.
    #[error("{path}: cannot decode image: {reason}")]
    Decode {
        /// File.
        path: PathBuf,
        /// Decoder message.
        reason: String,
    },
    /// Left and right images differ in size.
    #[error("left image is {left_w}x{left_h} but right image is {right_w}x{right_h}")]
    SizeMismatch {
        /// Left width.
        left_w: u32,
        /// Left height.
        left_h: u32,
        /// Right width.
        right_w: u32,
        /// Right height.
        right_h: u32,
    },
    /// No stereo pair in a folder.
    #[error("{dir}: no stereo pair (expected files named *left*.png|pgm|ppm|jpg with a matching *right* file)")]
    NoPairs {
        /// The folder.
        dir: PathBuf,
    },
    /// The device offers no usable pixel format.
    #[error("{device}: no supported pixel format (needs GREY or YUYV; offered {offered})")]
    Format {
        /// Device.
        device: PathBuf,
        /// What it offered.
        offered: String,
    },
    /// A camera was unplugged (or its driver went away).
    #[error("{device}: camera disconnected")]
    Disconnected {
        /// Device.
        device: PathBuf,
    },
    /// No pair of frames within the pairing tolerance in time.
    #[error("no frame pair within {tolerance_ms} ms after {waited_ms} ms")]
    Timeout {
        /// Pairing tolerance, ms.
        tolerance_ms: u64,
        /// Time waited, ms.
        waited_ms: u64,
    },
}

impl videt_hal::Error for CameraError {
    fn kind(&self) -> videt_hal::ErrorKind {
        use videt_hal::ErrorKind;
        match self {
            CameraError::Io { .. } | CameraError::Disconnected { .. } => ErrorKind::Disconnected,
            CameraError::Decode { .. } | CameraError::NoPairs { .. } => ErrorKind::Other,
            CameraError::SizeMismatch { .. } | CameraError::Format { .. } => ErrorKind::OutOfRange,
            CameraError::Timeout { .. } => ErrorKind::Timeout,
        }
    }
}
