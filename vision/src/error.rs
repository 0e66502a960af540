//! Errors of the vision pipeline.

use thiserror::Error;

/// Why a vision operation refused its input.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum VisionError {
    /// An image with no pixels.
    #[error("image is empty ({width}x{height} pixels)")]
    EmptyImage {
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
    },
    /// A pixel buffer whose length does not match its declared size.
    #[error("image buffer holds {actual} bytes, expected {expected}")]
    BufferSize {
        /// Expected length, bytes.
        expected: usize,
        /// Actual length, bytes.
        actual: usize,
    },
    /// Left and right images of different sizes.
    #[error("left image is {left_width}x{left_height} but right image is {right_width}x{right_height}; a rectified pair must have equal sizes")]
    SizeMismatch {
        /// Left width, pixels.
        left_width: usize,
        /// Left height, pixels.
        left_height: usize,
        /// Right width, pixels.
        right_width: usize,
        /// Right height, pixels.
        right_height: usize,
    },
    /// A parameter outside its allowed range.
    #[error("parameter {name} = {value} is outside the allowed range {allowed}")]
    Parameter {
        /// Parameter name.
        name: &'static str,
        /// Offending value.
        value: f64,
        /// Allowed range, human readable.
        allowed: &'static str,
    },
    /// A region of interest that does not intersect the image.
    #[error("region of interest {x},{y} {width}x{height} does not intersect the {image_width}x{image_height} image")]
    RoiOutside {
        /// Region column.
        x: i64,
        /// Region row.
        y: i64,
        /// Region width.
        width: i64,
        /// Region height.
        height: i64,
        /// Image width.
        image_width: usize,
        /// Image height.
        image_height: usize,
    },
    /// A file could not be read or written.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: String,
        /// What went wrong.
        message: String,
    },
}
