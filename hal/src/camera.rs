//! The stereo camera pair. **non-RT**: used by the vision thread only.

use alloc::vec::Vec;

use crate::{ErrorType, MonoTime};

/// An 8-bit grey image, row-major, `data.len() == width * height`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct GrayFrame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixels, row-major.
    pub data: Vec<u8>,
}

/// An 8-bit RGB image, row-major, `data.len() == 3 * width * height`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RgbFrame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixels as R, G, B bytes, row-major.
    pub data: Vec<u8>,
}

/// One synchronised capture of both cameras.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StereoFrame {
    /// Left camera, grey.
    pub left: GrayFrame,
    /// Right camera, grey.
    pub right: GrayFrame,
    /// Left camera in colour, when the camera delivers colour (for colour-to-touch).
    pub left_rgb: Option<RgbFrame>,
    /// Capture time of the left frame.
    pub left_stamp: MonoTime,
    /// Capture time of the right frame.
    pub right_stamp: MonoTime,
}

/// A stereo camera pair that delivers frame pairs captured within a pairing tolerance.
pub trait StereoCamera: ErrorType {
    /// Capture the next pair into `out`, reusing its buffers. Blocks until a pair is ready.
    fn capture(&mut self, out: &mut StereoFrame) -> Result<(), Self::Error>;
}
