//! Errors of the calibration workflow: each names the file, field or value at fault.

use std::path::PathBuf;

/// Why a calibration step failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CalibError {
    /// A file or directory could not be read or written.
    #[error("{action} {path}: {source}")]
    Io {
        /// What was being done ("read", "write", "rename", ...).
        action: &'static str,
        /// The path concerned.
        path: PathBuf,
        /// The operating-system error.
        #[source]
        source: std::io::Error,
    },
    /// An image file could not be decoded.
    #[error("cannot decode image {path}: {message}")]
    ImageDecode {
        /// The image file.
        path: PathBuf,
        /// The decoder's message.
        message: String,
    },
    /// The image directory holds no left/right pairs.
    #[error(
        "no stereo image pairs in {dir}: expected files named left<ID>.<png|jpg|jpeg|pgm> with a matching right<ID>.<ext>"
    )]
    NoImagePairs {
        /// The directory searched.
        dir: PathBuf,
    },
    /// Images of one calibration set do not all have the same size.
    #[error(
        "image {path} is {width}x{height} px but the set is {expected_width}x{expected_height} px"
    )]
    ImageSizeMismatch {
        /// The image that differs.
        path: PathBuf,
        /// Its width in pixels.
        width: u32,
        /// Its height in pixels.
        height: u32,
        /// The width of the first image of the set.
        expected_width: u32,
        /// The height of the first image of the set.
        expected_height: u32,
    },
    /// The board description is unusable.
    #[error("invalid board: {field} = {value} ({allowed})")]
    InvalidBoard {
        /// The field at fault ("cols", "rows", "square_m").
        field: &'static str,
        /// Its value as given.
        value: String,
        /// The allowed range.
        allowed: &'static str,
    },
    /// A calibration option is out of range.
    #[error("invalid option: {field} = {value} ({allowed})")]
    InvalidOption {
        /// The option at fault.
        field: &'static str,
        /// Its value as given.
        value: String,
        /// The allowed range.
        allowed: &'static str,
    },
    /// Too few views with a detected board to calibrate.
    #[error("{what}: the board was found in {found} view(s), at least {needed} are needed")]
    TooFewViews {
        /// Which calibration ("left camera", "right camera", "stereo pairs").
        what: &'static str,
        /// Views with a detected board.
        found: usize,
        /// Minimum required.
        needed: usize,
    },
    /// The numerical solution failed (degenerate views, no convergence).
    #[error("calibration failed: {0}")]
    Numerical(String),
    /// A calibration file is not valid JSON of the expected shape (truncated, corrupt).
    #[error("calibration file {path} is corrupt or truncated: {message}")]
    CorruptFile {
        /// The file.
        path: PathBuf,
        /// The parser's message.
        message: String,
    },
    /// A calibration holds a value outside its allowed range.
    #[error("invalid calibration: {field} = {value} ({allowed})")]
    InvalidCalibration {
        /// The field at fault (for example `m1.fx`).
        field: String,
        /// Its value.
        value: String,
        /// The allowed range.
        allowed: &'static str,
    },
    /// A frame given to the rectifier does not have the calibrated size.
    #[error("frame is {width}x{height} px but the rectification maps are for {expected_width}x{expected_height} px")]
    FrameSizeMismatch {
        /// Frame width in pixels.
        width: u32,
        /// Frame height in pixels.
        height: u32,
        /// Calibrated width in pixels.
        expected_width: u32,
        /// Calibrated height in pixels.
        expected_height: u32,
    },
}

impl CalibError {
    /// An I/O error on `path`.
    pub(crate) fn io(
        action: &'static str,
        path: impl Into<PathBuf>,
        source: std::io::Error,
    ) -> Self {
        CalibError::Io {
            action,
            path: path.into(),
            source,
        }
    }
}
