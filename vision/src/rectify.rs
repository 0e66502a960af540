//! Rectification of camera frames by precomputed remap tables.
//!
//! For every rectified pixel the table holds the top-left source pixel of its bilinear
//! neighbourhood and the two interpolation weights in 1/256 steps, computed once from a
//! [`StereoCalibration`] (undistortion, rectifying rotation, new projection). Applying a table is
//! a pure integer loop that does not allocate when the destination frame already has the right
//! size, so the vision thread can rectify every captured pair into preallocated frames.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

use nalgebra::{Matrix3, Matrix3x4, Vector3};
use videt_hal::{GrayFrame, StereoFrame};

use crate::calib::{CalibError, CameraIntrinsics, StereoCalibration};

/// Fixed-point scale of the interpolation weights (8 fractional bits).
const WEIGHT_ONE: u32 = 256;

/// Marks a rectified pixel whose source lies outside the camera image (rendered black).
const OUTSIDE: u32 = u32::MAX;

/// One rectified pixel: source offset of the top-left neighbour and the x / y weights of the
/// right / lower neighbours, in 1/256.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct MapEntry {
    offset: u32,
    weight_x: u16,
    weight_y: u16,
}

/// The remap table of one camera.
#[derive(Debug, Clone, PartialEq)]
pub struct RectifyMap {
    width: u32,
    height: u32,
    entries: Vec<MapEntry>,
}

impl RectifyMap {
    /// Table for a `width` x `height` camera with intrinsics `cam`, rectifying rotation `r` and
    /// rectified projection `p` (the rectified image has the camera's size).
    pub fn new(
        cam: &CameraIntrinsics,
        r: &Matrix3<f64>,
        p: &Matrix3x4<f64>,
        width: u32,
        height: u32,
    ) -> Self {
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
                entries.push(entry.unwrap_or(MapEntry {
                    offset: OUTSIDE,
                    weight_x: 0,
                    weight_y: 0,
                }));
            }
        }
        RectifyMap {
            width,
            height,
            entries,
        }
    }

    /// Width of the source and rectified images, pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height of the source and rectified images, pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Fraction of rectified pixels that have a source pixel.
    pub fn valid_fraction(&self) -> f64 {
        let valid = self.entries.iter().filter(|e| e.offset != OUTSIDE).count();
        valid as f64 / self.entries.len().max(1) as f64
    }

    /// Rectify `src` into `dst`. `dst` is resized (allocating) only when its size differs from
    /// the map's; otherwise no allocation happens. Errors when `src` is not the calibrated size.
    pub fn apply(&self, src: &GrayFrame, dst: &mut GrayFrame) -> Result<(), CalibError> {
        let n = self.entries.len();
        if src.width != self.width || src.height != self.height || src.data.len() != n {
            return Err(CalibError::FrameSizeMismatch {
                width: src.width,
                height: src.height,
                expected_width: self.width,
                expected_height: self.height,
            });
        }
        if dst.width != self.width || dst.height != self.height || dst.data.len() != n {
            dst.width = self.width;
            dst.height = self.height;
            dst.data.clear();
            dst.data.resize(n, 0);
        }
        let stride = self.width as usize;
        let pixels = &src.data[..];
        for (out, e) in dst.data.iter_mut().zip(&self.entries) {
            *out = interpolate(pixels, stride, e);
        }
        Ok(())
    }
}

/// Bilinear interpolation of one rectified pixel (0 outside the camera image). The 2x2
/// neighbourhood is read from one slice `stride + 2` bytes long, so a single bounds check
/// covers the four reads.
#[inline]
fn interpolate(pixels: &[u8], stride: usize, e: &MapEntry) -> u8 {
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

/// Remap tables of both cameras of a calibrated pair.
#[derive(Debug, Clone, PartialEq)]
pub struct StereoRectifier {
    /// Left camera table.
    pub left: RectifyMap,
    /// Right camera table.
    pub right: RectifyMap,
}

impl StereoRectifier {
    /// Build both tables from a (validated) calibration.
    pub fn from_calibration(cal: &StereoCalibration) -> Result<Self, CalibError> {
        cal.validate()?;
        if u64::from(cal.image_width) * u64::from(cal.image_height) >= u64::from(u32::MAX) {
            return Err(CalibError::InvalidCalibration {
                field: "image_width x image_height".into(),
                value: format!("{}x{}", cal.image_width, cal.image_height),
                allowed: "fewer than 2^32 pixels",
            });
        }
        let (w, h) = (cal.image_width, cal.image_height);
        Ok(StereoRectifier {
            left: RectifyMap::new(&cal.left(), &cal.r1(), &cal.p1(), w, h),
            right: RectifyMap::new(&cal.right(), &cal.r2(), &cal.p2(), w, h),
        })
    }

    /// Rectify both grey frames of `frame` into `left` and `right` (no allocation when they
    /// already have the calibrated size).
    pub fn apply(
        &self,
        frame: &StereoFrame,
        left: &mut GrayFrame,
        right: &mut GrayFrame,
    ) -> Result<(), CalibError> {
        self.left.apply(&frame.left, left)?;
        self.right.apply(&frame.right, right)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn identity_camera() -> CameraIntrinsics {
        CameraIntrinsics {
            fx: 100.0,
            fy: 100.0,
            cx: 31.5,
            cy: 23.5,
            dist: [0.0; 5],
        }
    }

    fn projection(cam: &CameraIntrinsics) -> Matrix3x4<f64> {
        Matrix3x4::new(
            cam.fx, 0.0, cam.cx, 0.0, 0.0, cam.fy, cam.cy, 0.0, 0.0, 0.0, 1.0, 0.0,
        )
    }

    fn ramp(w: u32, h: u32) -> GrayFrame {
        let data = (0..h)
            .flat_map(|y| (0..w).map(move |x| ((x * 3 + y * 2) % 256) as u8))
            .collect();
        GrayFrame {
            width: w,
            height: h,
            data,
        }
    }

    /// The interpolation written out per pixel with a separate outside test.
    fn reference_apply(map: &RectifyMap, src: &GrayFrame) -> Vec<u8> {
        let stride = map.width as usize;
        let p = &src.data;
        map.entries
            .iter()
            .map(|e| {
                if e.offset == OUTSIDE {
                    return 0;
                }
                let o = e.offset as usize;
                let (wx, wy) = (u32::from(e.weight_x), u32::from(e.weight_y));
                let top = u32::from(p[o]) * (WEIGHT_ONE - wx) + u32::from(p[o + 1]) * wx;
                let bottom = u32::from(p[o + stride]) * (WEIGHT_ONE - wx)
                    + u32::from(p[o + stride + 1]) * wx;
                ((top * (WEIGHT_ONE - wy) + bottom * wy + WEIGHT_ONE * WEIGHT_ONE / 2) >> 16) as u8
            })
            .collect()
    }

    #[test]
    fn distorted_rotated_map_with_outside_pixels_matches_the_per_pixel_formula() {
        let mut cam = identity_camera();
        cam.dist = [-0.3, 0.1, 0.001, -0.002, 0.0];
        let r = nalgebra::Rotation3::from_euler_angles(0.05, -0.08, 0.1).into_inner();
        for (w, h) in [(64u32, 48u32), (2, 2), (3, 7), (65, 33)] {
            let map = RectifyMap::new(&cam, &r, &projection(&cam), w, h);
            let src = GrayFrame {
                width: w,
                height: h,
                data: (0..w * h)
                    .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
                    .collect(),
            };
            let mut dst = GrayFrame::default();
            map.apply(&src, &mut dst).unwrap();
            assert_eq!(dst.data, reference_apply(&map, &src), "{w}x{h}");
            if (w, h) == (64, 48) {
                let valid = map.valid_fraction();
                assert!(valid > 0.5 && valid < 1.0, "valid fraction {valid}");
            }
        }
    }

    #[test]
    fn identity_map_copies_the_frame() {
        let cam = identity_camera();
        let map = RectifyMap::new(&cam, &Matrix3::identity(), &projection(&cam), 64, 48);
        let src = ramp(64, 48);
        let mut dst = GrayFrame::default();
        map.apply(&src, &mut dst).unwrap();
        assert_eq!(dst, src);
        assert!((map.valid_fraction() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn half_pixel_shift_interpolates() {
        let cam = identity_camera();
        // Rectified principal point half a pixel left: rectified u maps to source u + 0.5.
        let mut p = projection(&cam);
        p[(0, 2)] -= 0.5;
        let map = RectifyMap::new(&cam, &Matrix3::identity(), &p, 64, 48);
        let src = ramp(64, 48);
        let mut dst = GrayFrame::default();
        map.apply(&src, &mut dst).unwrap();
        // Source row 10: value 3x + 20; between x and x + 1 the mean is 3x + 21.5 -> 22 rounded half up.
        let y = 10usize;
        for x in 0..20usize {
            let expected = (3.0 * x as f64 + 20.0 + 1.5).round() as u8;
            assert_eq!(dst.data[y * 64 + x], expected, "x {x}");
        }
        // The last column's source lies past the image edge: black.
        assert_eq!(dst.data[y * 64 + 63], 0);
    }

    #[test]
    fn wrong_source_size_is_an_error() {
        let cam = identity_camera();
        let map = RectifyMap::new(&cam, &Matrix3::identity(), &projection(&cam), 64, 48);
        let mut dst = GrayFrame::default();
        let err = map.apply(&ramp(32, 48), &mut dst).unwrap_err();
        assert!(
            matches!(
                err,
                CalibError::FrameSizeMismatch {
                    width: 32,
                    expected_width: 64,
                    ..
                }
            ),
            "{err}"
        );
        let truncated = GrayFrame {
            width: 64,
            height: 48,
            data: vec![0; 10],
        };
        assert!(map.apply(&truncated, &mut dst).is_err());
    }

    #[test]
    fn reuses_the_destination_buffer() {
        let cam = identity_camera();
        let map = RectifyMap::new(&cam, &Matrix3::identity(), &projection(&cam), 64, 48);
        let src = ramp(64, 48);
        let mut dst = GrayFrame {
            width: 64,
            height: 48,
            data: vec![7; 64 * 48],
        };
        let before = (dst.data.as_ptr(), dst.data.capacity());
        map.apply(&src, &mut dst).unwrap();
        assert_eq!((dst.data.as_ptr(), dst.data.capacity()), before);
    }
}
