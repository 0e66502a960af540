//! Local mode: the region of interest around the finger's image position, shifted and enlarged
//! along its image-plane velocity, the image windows processed for it, and how those windows
//! grow until edge chains near the region are whole (see `StereoPipeline::run_local`).
//!
//! Three ways to choose the context processed around the region ([`LocalParams`]):
//! - **exact** ([`LocalParams::exact`], the default): the windows grow, pass after pass, until
//!   the matches inside the region are the whole-image run's;
//! - **adaptive** (`exact` off, [`LocalContext::Adaptive`]): one full pass over a context chosen
//!   from the data: the edge chains that cross the region are followed until they are whole,
//!   and the context grows once more where a segment of the region has an acceptable candidate
//!   that propagation did not reach. It meets the paper's criterion (no match of the
//!   whole-image run missed, no new error inside the region) rather than identity;
//! - **fixed** (`exact` off, [`LocalContext::Fixed`]): one pass over the region plus
//!   [`LocalParams::context_margin_px`].

use crate::chains::Chains;
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

/// How a local run without [`LocalParams::exact`] chooses its context.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LocalContext {
    /// From the data, in a few cheap passes before the full one (`StereoPipeline::run_local`):
    /// the left window starts at the region plus two neighbourhood radii of the matcher
    /// (`MatchParams::neighbourhood_radius_px`: a segment's supporting neighbours and theirs);
    /// while an edge chain crossing the region is cut by a window side, that side grows by one
    /// radius (edges and chains of the left image only: the cut chain's segments would differ
    /// from the whole-image run's); after the full pass, if a segment of the region has a
    /// candidate validation would accept but propagation did not reach, the window grows once
    /// by one radius on every side and the full pass is repeated. The right window is the left
    /// one's rows over the disparity range plus half a radius on each side.
    #[default]
    Adaptive,
    /// One pass over the region plus [`LocalParams::context_margin_px`] (right window: the
    /// left one's rows over the disparity range plus a quarter of the margin on each side).
    Fixed,
}

/// Parameters of the local mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalParams {
    /// How many frames ahead the region must cover: the region is shifted by half and enlarged
    /// by all of `velocity * lookahead_frames`.
    pub lookahead_frames: f32,
    /// Context around the region processed but not reported, pixels: the exact mode's initial
    /// context and the fixed context of [`LocalContext::Fixed`] (not used by
    /// [`LocalContext::Adaptive`]).
    pub context_margin_px: usize,
    /// How much a window side grows at a time in the exact mode, pixels (see
    /// [`cut_chain_sides`]).
    pub growth_step_px: usize,
    /// Grow the windows until the matches inside the region are the whole-image run's
    /// (`StereoPipeline::run_local`); when off, one full pass over a context chosen by
    /// [`LocalParams::context`]: faster, and a few matches near the region border can differ
    /// from the whole-image run's.
    pub exact: bool,
    /// The context of a run without [`LocalParams::exact`].
    pub context: LocalContext,
}

impl Default for LocalParams {
    /// Two frames of look-ahead; 32 px of initial context; growth by 48 px; exact (adaptive
    /// context when `exact` is turned off).
    fn default() -> Self {
        Self {
            lookahead_frames: 2.0,
            context_margin_px: 32,
            growth_step_px: 48,
            exact: true,
            context: LocalContext::Adaptive,
        }
    }
}

/// Sides of a window: left, top, right, bottom.
pub type WindowSides = [bool; 4];

/// The sides of `window` (frame pixels) that cut a chain of `chains` (linked in that window,
/// window pixels) which comes into `influence` (frame pixels): the chain passes within
/// `border_px` of a side that is not the frame's border. Such a chain may continue outside the
/// window, and its segments then differ from a whole-image run's.
pub fn cut_chain_sides(
    chains: &Chains,
    window: PixelRect,
    frame_width: usize,
    frame_height: usize,
    border_px: usize,
    influence: PixelRect,
) -> WindowSides {
    let mut sides = [false; 4];
    let open = [
        window.x > 0,
        window.y > 0,
        window.x + window.width < frame_width,
        window.y + window.height < frame_height,
    ];
    if !open.iter().any(|&o| o) {
        return sides;
    }
    let b = border_px;
    let (w, h) = (window.width, window.height);
    for i in 0..chains.len() {
        let mut touches = [false; 4];
        let mut reaches = false;
        for &[x, y] in chains.chain(i) {
            let (x, y) = (x as usize, y as usize);
            touches[0] |= x < b;
            touches[1] |= y < b;
            touches[2] |= x + b >= w;
            touches[3] |= y + b >= h;
            reaches |= influence.contains((window.x + x) as f32, (window.y + y) as f32);
        }
        if reaches {
            for k in 0..4 {
                sides[k] |= touches[k] && open[k];
            }
        }
    }
    sides
}

/// Grows `rect` by `step_px` on the given sides, within the frame.
pub fn grow_window(
    rect: PixelRect,
    sides: WindowSides,
    step_px: usize,
    frame_width: usize,
    frame_height: usize,
) -> PixelRect {
    let x0 = if sides[0] {
        rect.x.saturating_sub(step_px)
    } else {
        rect.x
    };
    let y0 = if sides[1] {
        rect.y.saturating_sub(step_px)
    } else {
        rect.y
    };
    let mut x1 = rect.x + rect.width;
    let mut y1 = rect.y + rect.height;
    if sides[2] {
        x1 = (x1 + step_px).min(frame_width);
    }
    if sides[3] {
        y1 = (y1 + step_px).min(frame_height);
    }
    PixelRect {
        x: x0,
        y: y0,
        width: x1 - x0,
        height: y1 - y0,
    }
}

/// The smallest rectangle holding `a` and `b`.
pub fn union(a: PixelRect, b: PixelRect) -> PixelRect {
    let x0 = a.x.min(b.x);
    let y0 = a.y.min(b.y);
    let x1 = (a.x + a.width).max(b.x + b.width);
    let y1 = (a.y + a.height).max(b.y + b.height);
    PixelRect {
        x: x0,
        y: y0,
        width: x1 - x0,
        height: y1 - y0,
    }
}

/// `rect` enlarged by `by` pixels on every side, clipped to the frame.
pub fn enlarge(rect: PixelRect, by: usize, frame_width: usize, frame_height: usize) -> PixelRect {
    grow_window(rect, [true; 4], by, frame_width, frame_height)
}

/// The right-image columns whose segments can be candidates of left segments in `left`
/// (frame pixels) with disparities `disparity_min_px..=disparity_max_px`, on the same rows,
/// plus `slack_px` on each side.
pub fn right_band(
    left: PixelRect,
    disparity_min_px: f32,
    disparity_max_px: f32,
    slack_px: usize,
    frame_width: usize,
    frame_height: usize,
) -> PixelRect {
    let dmin = disparity_min_px.floor() as i64;
    let dmax = disparity_max_px.ceil() as i64;
    let s = slack_px as i64;
    let rx0 = left.x as i64 - dmax - s;
    let rx1 = (left.x + left.width) as i64 - dmin + s;
    clip(
        rx0,
        left.y as i64,
        rx1 - rx0,
        left.height as i64,
        frame_width,
        frame_height,
    )
    .unwrap_or(left)
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
    let right = right_band(
        left,
        disparity_min_px,
        disparity_max_px,
        params.context_margin_px / 4,
        width,
        height,
    );
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
    fn windows_grow_on_the_requested_sides_within_the_frame() {
        let r = PixelRect {
            x: 10,
            y: 20,
            width: 30,
            height: 40,
        };
        let g = grow_window(r, [true, false, true, true], 16, 50, 70);
        assert_eq!(
            g,
            PixelRect {
                x: 0,
                y: 20,
                width: 50,
                height: 50
            }
        );
        let u = union(
            r,
            PixelRect {
                x: 45,
                y: 0,
                width: 5,
                height: 5,
            },
        );
        assert_eq!((u.x, u.y, u.width, u.height), (10, 0, 40, 60));
        let band = right_band(r, 0.0, 8.0, 2, 100, 100);
        assert_eq!((band.x, band.x + band.width), (0, 42));
        assert_eq!((band.y, band.height), (r.y, r.height));
    }

    #[test]
    fn only_chains_cut_near_the_influence_zone_ask_for_growth() {
        // A 20x20 window at (40, 40) of a 100x100 frame; one chain crosses its right border
        // inside the influence zone, another crosses its top border far from it.
        let mut edges = vec![0u8; 20 * 20];
        for x in 5..20 {
            edges[10 * 20 + x] = crate::canny::EDGE;
        }
        for y in 0..6 {
            edges[y * 20 + 3] = crate::canny::EDGE;
        }
        let mut chains = Chains::new();
        chains.link(&edges, 20, 20, 2);
        let window = PixelRect {
            x: 40,
            y: 40,
            width: 20,
            height: 20,
        };
        let influence = PixelRect {
            x: 50,
            y: 45,
            width: 10,
            height: 10,
        };
        let sides = cut_chain_sides(&chains, window, 100, 100, 2, influence);
        assert_eq!(sides, [false, false, true, false]);
        // At the frame border nothing can be cut.
        let corner = PixelRect {
            x: 80,
            y: 40,
            width: 20,
            height: 20,
        };
        let influence = PixelRect {
            x: 90,
            y: 45,
            width: 10,
            height: 10,
        };
        assert_eq!(
            cut_chain_sides(&chains, corner, 100, 100, 2, influence),
            [false; 4]
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
