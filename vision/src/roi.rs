//! Local mode: the region of interest around the finger's image position, shifted and enlarged
//! along its image-plane velocity, and the image windows processed for it.

use crate::error::VisionError;
use crate::gray::PixelRect;

/// Where the finger is looked at in the left rectified image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalRegion {
    /// Centre of the region, pixels `[x, y]`.
    pub centre_px: [f32; 2],
    /// Size of the region when the finger is still, pixels `[width, height]`.
    pub size_px: [f32; 2],
    /// Image-plane velocity of the finger, pixels per frame `[vx, vy]`.
    pub velocity_px_per_frame: [f32; 2],
}

/// Parameters of the local mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalParams {
    /// How many frames ahead the region must cover: the region is shifted by half and enlarged
    /// by all of `velocity * lookahead_frames`.
    pub lookahead_frames: f32,
    /// Context around the region processed but not reported, pixels: edges, chains and
    /// neighbours crossing the region border are then seen as in a whole-image run.
    pub context_margin_px: usize,
}

impl Default for LocalParams {
    /// Two frames of look-ahead; 32 px of context.
    fn default() -> Self {
        Self {
            lookahead_frames: 2.0,
            context_margin_px: 32,
        }
    }
}

/// The rectangles a local run works on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalWindows {
    /// The region whose results are reported (left image).
    pub roi: PixelRect,
    /// The region plus context, processed in the left image.
    pub left: PixelRect,
    /// The right-image search band: the left window's rows, its columns shifted by the
    /// disparity range, plus a quarter of the context margin on each side (right segments
    /// crossing the band border keep most of their length).
    pub right: PixelRect,
}

/// Computes the windows for `region` in a `width x height` pair searched over disparities
/// `disparity_min_px..=disparity_max_px`.
pub fn local_windows(
    region: &LocalRegion,
    params: &LocalParams,
    width: usize,
    height: usize,
    disparity_min_px: f32,
    disparity_max_px: f32,
) -> Result<LocalWindows, VisionError> {
    let finite = region.centre_px.iter().all(|v| v.is_finite())
        && region.velocity_px_per_frame.iter().all(|v| v.is_finite());
    if !finite {
        return Err(VisionError::Parameter {
            name: "local.region",
            value: f64::NAN,
            allowed: "finite centre and velocity",
        });
    }
    for s in region.size_px {
        if !(1.0..=1.0e5).contains(&s) {
            return Err(VisionError::Parameter {
                name: "local.region.size_px",
                value: s as f64,
                allowed: "1..=100000",
            });
        }
    }
    let ahead = [
        region.velocity_px_per_frame[0] * params.lookahead_frames,
        region.velocity_px_per_frame[1] * params.lookahead_frames,
    ];
    let cx = region.centre_px[0] + 0.5 * ahead[0];
    let cy = region.centre_px[1] + 0.5 * ahead[1];
    let w = region.size_px[0] + ahead[0].abs();
    let h = region.size_px[1] + ahead[1].abs();
    let x0 = (cx - 0.5 * w).round() as i64;
    let y0 = (cy - 0.5 * h).round() as i64;
    let (wi, hi) = (w.round() as i64, h.round() as i64);
    let roi = clip(x0, y0, wi, hi, width, height).ok_or(VisionError::RoiOutside {
        x: x0,
        y: y0,
        width: wi,
        height: hi,
        image_width: width,
        image_height: height,
    })?;
    let m = params.context_margin_px as i64;
    let left = clip(
        roi.x as i64 - m,
        roi.y as i64 - m,
        roi.width as i64 + 2 * m,
        roi.height as i64 + 2 * m,
        width,
        height,
    )
    .unwrap_or(roi);
    let dmin = disparity_min_px.floor() as i64;
    let dmax = disparity_max_px.ceil() as i64;
    let rx0 = left.x as i64 - dmax - m / 4;
    let rx1 = (left.x + left.width) as i64 - dmin + m / 4;
    let right = clip(
        rx0,
        left.y as i64,
        rx1 - rx0,
        left.height as i64,
        width,
        height,
    )
    .unwrap_or(left);
    Ok(LocalWindows { roi, left, right })
}

/// Clips a signed rectangle to the frame.
fn clip(x: i64, y: i64, w: i64, h: i64, width: usize, height: usize) -> Option<PixelRect> {
    let x0 = x.max(0);
    let y0 = y.max(0);
    let x1 = (x + w).min(width as i64);
    let y1 = (y + h).min(height as i64);
    if x1 <= x0 || y1 <= y0 {
        return None;
    }
    Some(PixelRect {
        x: x0 as usize,
        y: y0 as usize,
        width: (x1 - x0) as usize,
        height: (y1 - y0) as usize,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_still_finger_gives_a_centred_region() {
        let r = LocalRegion {
            centre_px: [200.0, 150.0],
            size_px: [100.0, 100.0],
            velocity_px_per_frame: [0.0, 0.0],
        };
        let w = local_windows(&r, &LocalParams::default(), 640, 480, 0.0, 64.0).unwrap();
        assert_eq!(
            w.roi,
            PixelRect {
                x: 150,
                y: 100,
                width: 100,
                height: 100
            }
        );
        assert_eq!(w.left.x, 118);
        assert_eq!(w.left.width, 164);
        // Right band: from 118 - 64 - 8 to 282 + 8.
        assert_eq!(w.right.x, 46);
        assert_eq!(w.right.x + w.right.width, 290);
        assert_eq!((w.right.y, w.right.height), (w.left.y, w.left.height));
    }

    #[test]
    fn a_moving_finger_shifts_and_enlarges_the_region() {
        let r = LocalRegion {
            centre_px: [200.0, 150.0],
            size_px: [100.0, 100.0],
            velocity_px_per_frame: [10.0, -5.0],
        };
        let w = local_windows(&r, &LocalParams::default(), 640, 480, 0.0, 64.0).unwrap();
        // Look-ahead 2 frames: shift (10, -5), enlarge (20, 10).
        assert_eq!(
            w.roi,
            PixelRect {
                x: 150,
                y: 90,
                width: 120,
                height: 110
            }
        );
    }

    #[test]
    fn regions_outside_the_image_are_an_error_and_edges_are_clipped() {
        let mut r = LocalRegion {
            centre_px: [-500.0, 150.0],
            size_px: [100.0, 100.0],
            velocity_px_per_frame: [0.0, 0.0],
        };
        assert!(local_windows(&r, &LocalParams::default(), 640, 480, 0.0, 64.0).is_err());
        r.centre_px = [10.0, 470.0];
        let w = local_windows(&r, &LocalParams::default(), 640, 480, 0.0, 64.0).unwrap();
        assert_eq!((w.roi.x, w.roi.y), (0, 420));
        assert_eq!(w.roi.x + w.roi.width, 60);
        assert_eq!(w.roi.y + w.roi.height, 480);
        r.size_px = [f32::NAN, 3.0];
        assert!(local_windows(&r, &LocalParams::default(), 640, 480, 0.0, 64.0).is_err());
    }
}
