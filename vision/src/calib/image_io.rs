//! Loading calibration images as grey frames.

use std::path::Path;

use videt_hal::GrayFrame;

use super::error::CalibError;

/// Decode an image file (PNG, JPEG, PNM) into an 8-bit grey frame (sizes bounded as in
/// [`crate::io::decode_gray_image`]).
pub fn load_gray(path: &Path) -> Result<GrayFrame, CalibError> {
    let bytes = std::fs::read(path).map_err(|e| CalibError::io("read", path, e))?;
    let gray = crate::io::decode_gray_image(&bytes).map_err(|message| CalibError::ImageDecode {
        path: path.to_path_buf(),
        message,
    })?;
    let (width, height) = gray.dimensions();
    Ok(GrayFrame {
        width,
        height,
        data: gray.into_raw(),
    })
}
