//! The per-pixel remap table in its plain form: one 8-byte entry per rectified pixel (source
//! offset of the top-left bilinear neighbour and the x / y weights in 1/256, `0..=256`), applied
//! pixel by pixel with a bounds-checked 2x2 window.
//!
//! This is the definition of what rectification computes. [`RectifyMap`](super::RectifyMap)
//! stores the same table in a compact block layout and must produce identical frames; this
//! form is kept as the oracle of its tests and the baseline of the `rectify` bench.

use nalgebra::{Matrix3, Matrix3x4, Vector3};
use videt_hal::GrayFrame;

use crate::calib::{CalibError, CameraIntrinsics};

/// Fixed-point scale of the interpolation weights (8 fractional bits).
pub(crate) const WEIGHT_ONE: u32 = 256;

/// Marks a rectified pixel whose source lies outside the camera image (rendered black).
pub(crate) const OUTSIDE: u32 = u32::MAX;

/// One rectified pixel: source offset of the top-left neighbour and the x / y weights of the
/// right / lower neighbours, in 1/256 (`0..=256`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct MapEntry {
    pub(crate) offset: u32,
    pub(crate) weight_x: u16,
    pub(crate) weight_y: u16,
}

impl MapEntry {
    const OUTSIDE: MapEntry = MapEntry {
        offset: OUTSIDE,
        weight_x: 0,
        weight_y: 0,
    };
}

/// Table entries of a `width` x `height` camera, row by row (see [`ReferenceMap::new`]).
pub(crate) fn table_entries(
    cam: &CameraIntrinsics,
    r: &Matrix3<f64>,
    p: &Matrix3x4<f64>,
    width: u32,
    height: u32,
) -> Vec<MapEntry> {
    let (w, h) = (width as usize, height as usize);
    let (fx, fy, cx, cy) = (p[(0, 0)], p[(1, 1)], p[(0, 2)], p[(1, 2)]);
    let r_inv = r.transpose();
    let mut entries = Vec::with_capacity(w * h);
    for v in 0..h {
        for u in 0..w {
            let ray = r_inv * Vector3::new((u as f64 - cx) / fx, (v as f64 - cy) / fy, 1.0);
            let entry = if ray.z > 0.0 {
                let [xs, ys] = cam.normalised_to_pixel(ray.x / ray.z, ray.y / ray.z);
                bilinear_entry(xs, ys, w, h)
            } else {
                None
            };
            entries.push(entry.unwrap_or(MapEntry::OUTSIDE));
        }
    }
    entries
}

/// Table entry for the source position (xs, ys), or `None` outside the image.
fn bilinear_entry(xs: f64, ys: f64, w: usize, h: usize) -> Option<MapEntry> {
    if w < 2 || h < 2 || !(xs >= 0.0 && ys >= 0.0 && xs <= (w - 1) as f64 && ys <= (h - 1) as f64) {
        return None;
    }
    let x0 = (xs.floor() as usize).min(w - 2);
    let y0 = (ys.floor() as usize).min(h - 2);
    let weight_x = ((xs - x0 as f64) * f64::from(WEIGHT_ONE)).round() as u16;
    let weight_y = ((ys - y0 as f64) * f64::from(WEIGHT_ONE)).round() as u16;
    Some(MapEntry {
        offset: (y0 * w + x0) as u32,
        weight_x,
        weight_y,
    })
}

/// Bilinear interpolation of one rectified pixel (0 outside the camera image). The 2x2
/// neighbourhood is read from one slice `stride + 2` bytes long, so a single bounds check
/// covers the four reads.
#[inline]
pub(crate) fn interpolate(pixels: &[u8], stride: usize, e: &MapEntry) -> u8 {
    let o = e.offset as usize;
    let Some(window) = pixels.get(o..o.wrapping_add(stride + 2)) else {
        // Only OUTSIDE entries (offset u32::MAX) fail: valid offsets are at most
        // (h - 2) * w + w - 2.
        return 0;
    };
    let [top_left, top_right] = [window[0], window[1]].map(u32::from);
    let [bottom_left, bottom_right] = [window[stride], window[stride + 1]].map(u32::from);
    let (wx, wy) = (u32::from(e.weight_x), u32::from(e.weight_y));
    let top = top_left * (WEIGHT_ONE - wx) + top_right * wx;
    let bottom = bottom_left * (WEIGHT_ONE - wx) + bottom_right * wx;
    ((top * (WEIGHT_ONE - wy) + bottom * wy + WEIGHT_ONE * WEIGHT_ONE / 2) >> 16) as u8
}

/// The remap table of one camera in the plain per-pixel layout (about 8 bytes per pixel).
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceMap {
    width: u32,
    height: u32,
    entries: Vec<MapEntry>,
}

impl ReferenceMap {
    /// Table for a `width` x `height` camera with intrinsics `cam`, rectifying rotation `r` and
    /// rectified projection `p` (the rectified image has the camera's size).
    pub fn new(
        cam: &CameraIntrinsics,
        r: &Matrix3<f64>,
        p: &Matrix3x4<f64>,
        width: u32,
        height: u32,
    ) -> Self {
        ReferenceMap {
            width,
            height,
            entries: table_entries(cam, r, p, width, height),
        }
    }

    /// Rectify `src` into `dst`, pixel by pixel. `dst` is resized (allocating) only when its
    /// size differs from the map's. Errors when `src` is not the calibrated size.
    pub fn apply(&self, src: &GrayFrame, dst: &mut GrayFrame) -> Result<(), CalibError> {
        check_sizes(self.width, self.height, src, dst)?;
        let stride = self.width as usize;
        let pixels = &src.data[..];
        for (out, e) in dst.data.iter_mut().zip(&self.entries) {
            *out = interpolate(pixels, stride, e);
        }
        Ok(())
    }
}

/// Check that `src` is `width` x `height` (clear error otherwise) and size `dst` to it, which
/// allocates only when `dst` has another size.
pub(crate) fn check_sizes(
    width: u32,
    height: u32,
    src: &GrayFrame,
    dst: &mut GrayFrame,
) -> Result<(), CalibError> {
    let n = width as usize * height as usize;
    if src.width != width || src.height != height || src.data.len() != n {
        return Err(CalibError::FrameSizeMismatch {
            width: src.width,
            height: src.height,
            expected_width: width,
            expected_height: height,
        });
    }
    if dst.width != width || dst.height != height || dst.data.len() != n {
        dst.width = width;
        dst.height = height;
        dst.data.clear();
        dst.data.resize(n, 0);
    }
    Ok(())
}
