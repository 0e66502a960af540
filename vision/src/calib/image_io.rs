//! Loading calibration images as grey frames.

use std::path::Path;

use videt_hal::GrayFrame;

use super::error::CalibError;

/// Decode an image file (PNG, JPEG, PNM) into an 8-bit grey frame.
pub fn load_gray(path: &Path) -> Result<GrayFrame, CalibError> {
    let bytes = std::fs::read(path).map_err(|e| CalibError::io("read", path, e))?;
    let decoded = image::load_from_memory(&bytes).map_err(|e| CalibError::ImageDecode {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let gray = decoded.to_luma8();
    let (width, height) = gray.dimensions();
    Ok(GrayFrame {
        width,
        height,
        data: gray.into_raw(),
    })
}
