//! The stereo pipeline from a rectified pair to 3D segments, whole-image or local, with
//! per-stage timings. [`StereoPipeline`] keeps every buffer between frames; [`run_pipeline`]
//! is the one-shot convenience.

use crate::canny::{CannyParams, CannyWorkspace, KeptSmoothed};
use crate::chains::Chains;
use crate::error::VisionError;
use crate::gray::{GrayView, PixelRect};
use crate::matching::{
    ImagePatch, MatchParams, MatchWorkspace, MutualCheck, SegmentMatch, StereoImages,
};
use crate::reconstruct::{back_project_matches, RectifiedGeometry, Segment3d};
use crate::roi::{
    cut_chain_sides, enlarge, grow_window, local_windows, right_band, union, LocalContext,
    LocalParams, LocalRegion, LocalWindows, WindowSides,
};
use crate::segments::{Segment, SegmentParams, SegmentWorkspace};
use std::time::{Duration, Instant};

/// All parameters of the pipeline. The defaults are one set tuned on the Middlebury pairs
/// (tsukuba, venus, cones, teddy) and meant for indoor scenes at 320x240..640x480.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VisionParams {
    /// Edge detection.
    pub canny: CannyParams,
    /// Polygonal approximation.
    pub segments: SegmentParams,
    /// Matching.
    pub matching: MatchParams,
    /// Disparity error assumed for the 3D uncertainty, pixels (default 0.5).
    pub disparity_sigma_px: f64,
    /// Local mode.
    pub local: LocalParams,
    /// The right image's hysteresis thresholds are the left's times this, in `(0, 1]`. The
    /// left image is the reference (its segments are the ones back-projected); the right one
    /// is only searched for their partners, and a partner whose edge is a little weaker in the
    /// right view is lost at the left's thresholds. The extra right segments a lower ratio
    /// keeps are only candidates: they are matched to nothing unless a left segment takes
    /// them.
    pub right_threshold_ratio: f32,
}

impl Default for VisionParams {
    fn default() -> Self {
        Self {
            // A lower high threshold than the detector's own default: more of the weaker
            // edges of the right image survive, so more left segments find their partner.
            canny: CannyParams {
                high_threshold: 80,
                ..CannyParams::default()
            },
            segments: SegmentParams::default(),
            matching: MatchParams::default(),
            disparity_sigma_px: 0.5,
            local: LocalParams::default(),
            right_threshold_ratio: 1.0,
        }
    }
}

impl VisionParams {
    /// Checks every parameter's range.
    pub fn validate(&self) -> Result<(), VisionError> {
        self.canny.validate()?;
        self.segments.validate()?;
        self.matching.validate()?;
        if !(self.disparity_sigma_px > 0.0 && self.disparity_sigma_px <= 10.0) {
            return Err(VisionError::Parameter {
                name: "disparity_sigma_px",
                value: self.disparity_sigma_px,
                allowed: "(0, 10]",
            });
        }
        if !(self.right_threshold_ratio > 0.0 && self.right_threshold_ratio <= 1.0) {
            return Err(VisionError::Parameter {
                name: "right_threshold_ratio",
                value: f64::from(self.right_threshold_ratio),
                allowed: "(0, 1]",
            });
        }
        Ok(())
    }
}

/// Wall-clock time of each stage of the last run.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimings {
    /// Canny on both images.
    pub edges: Duration,
    /// Chain linking on both images.
    pub chains: Duration,
    /// Segment approximation on both images.
    pub segments: Duration,
    /// Matching.
    pub matching: Duration,
    /// Back-projection.
    pub reconstruction: Duration,
    /// Whole run.
    pub total: Duration,
}

/// Results of a run (reused between runs by [`StereoPipeline`]).
#[derive(Debug, Clone, Default)]
pub struct PipelineOutput {
    /// Segments of the left image (frame pixels).
    pub left_segments: Vec<Segment>,
    /// Segments of the right image (frame pixels).
    pub right_segments: Vec<Segment>,
    /// Accepted matches (indices into the segment lists).
    pub matches: Vec<SegmentMatch>,
    /// Back-projected matches (only when a geometry was given).
    pub segments_3d: Vec<Segment3d>,
    /// Stage timings.
    pub timings: StageTimings,
    /// The windows of a local run (`None` for a whole-image run).
    pub local: Option<LocalWindows>,
}

/// The stereo pipeline with all its reusable buffers.
#[derive(Debug, Default, Clone)]
pub struct StereoPipeline {
    /// One detector for both images: the right image reuses the buffers the left one has just
    /// left in cache; only the left smoothed image, which matching reads, is kept apart.
    canny: CannyWorkspace,
    left_smoothed: KeptSmoothed,
    chains: Chains,
    segments: SegmentWorkspace,
    matcher: MatchWorkspace,
    mutual: MutualCheck,
    output: PipelineOutput,
}

impl StereoPipeline {
    /// A pipeline with empty buffers (they grow during the first frames).
    pub fn new() -> Self {
        Self::default()
    }

    /// The results of the last run.
    pub fn output(&self) -> &PipelineOutput {
        &self.output
    }

    /// Whole-image run on a rectified pair.
    pub fn run(
        &mut self,
        left: &GrayView<'_>,
        right: &GrayView<'_>,
        geometry: Option<&RectifiedGeometry>,
        params: &VisionParams,
    ) -> Result<&PipelineOutput, VisionError> {
        check_pair(left, right)?;
        params.validate()?;
        self.output.local = None;
        self.process(left, right, geometry, params, None)?;
        Ok(&self.output)
    }

    /// Local run: only the windows around `region` are processed (see [`local_windows`]);
    /// matches whose left segment does not touch the region of interest are dropped. How the
    /// context around the region is chosen depends on [`LocalParams::exact`] and
    /// [`LocalParams::context`].
    ///
    /// **Exact** (the default): the windows start at the region plus the context margin and
    /// grow (by [`LocalParams::growth_step_px`], up to the whole frame) while
    /// - an edge chain cut by a window border comes within the neighbourhood radius of the
    ///   region (right image: within the columns where candidates of those left segments can
    ///   lie): its segments would differ from the whole-image run's;
    /// - a left segment in the region stays unmatched although it has a candidate validation
    ///   would accept: propagation may reach it from outside the window.
    ///
    /// With whole chains, matching decisions that do not depend on the order of the segments,
    /// and propagation that cannot come from outside, the matches inside the region are the
    /// whole-image run's (checked on real pairs by `tests/local_mode.rs`). The price: where
    /// long chains run near the region, most of the frame may be processed, in several passes.
    ///
    /// **Adaptive** (`exact` off, [`LocalContext::Adaptive`]): the paper's criterion instead of
    /// identity: inside the region no match of the whole-image run is missed (a local match on
    /// the same line with the same disparities over at least half of it counts) and there is
    /// no new error. The context is chosen from the data, with `r` the matcher's neighbourhood
    /// radius:
    /// - the left window starts at the region plus `2 r`: the neighbours that support a
    ///   segment of the region, and the neighbours that support those;
    /// - while an edge chain that crosses the region itself is cut by a window side, that side
    ///   grows by `r` (a pass of edges and chains of the left image only). Splitting a chain
    ///   into segments depends on its whole length, and cut chains are what changes segments
    ///   of the region most; chains that only pass near the region are not followed (their
    ///   segments change the support of the region's candidates far less than the exact mode
    ///   assumes, and following them is what makes it slow);
    /// - after the full pass, if a segment of the region is left unmatched although it has a
    ///   candidate validation would accept (propagation did not reach it from the seeds in
    ///   the window), the window grows once by `r` on every side and the full pass is run
    ///   again.
    ///
    /// The right window is the left one's rows over the disparity range plus `r / 2` on each
    /// side. Checked on every shared Middlebury pair by `tests/local_mode_criterion.rs`.
    ///
    /// **Fixed** (`exact` off, [`LocalContext::Fixed`]): one pass over the region plus
    /// [`LocalParams::context_margin_px`].
    pub fn run_local(
        &mut self,
        left: &GrayView<'_>,
        right: &GrayView<'_>,
        geometry: Option<&RectifiedGeometry>,
        params: &VisionParams,
        region: &LocalRegion,
    ) -> Result<&PipelineOutput, VisionError> {
        check_pair(left, right)?;
        params.validate()?;
        let (frame_width, frame_height) = (left.width(), left.height());
        let m = &params.matching;
        let windows = local_windows(
            region,
            &params.local,
            frame_width,
            frame_height,
            m.disparity_min_px,
            m.disparity_max_px,
        )?;
        let start = Instant::now();
        let windows = match (params.local.exact, params.local.context) {
            (true, _) => self.exact_passes(left, right, params, windows)?,
            (false, LocalContext::Adaptive) => {
                self.adaptive_passes(left, right, params, windows)?
            }
            (false, LocalContext::Fixed) => {
                self.process_windows(left, right, params, &windows, None)?;
                windows
            }
        };
        let roi = windows.roi;
        let left_segments = &self.output.left_segments;
        self.output
            .matches
            .retain(|m| touches(&left_segments[m.left as usize], &roi));
        if let Some(g) = geometry {
            let t = Instant::now();
            back_project_matches(
                g,
                &self.output.left_segments,
                &self.output.matches,
                params.disparity_sigma_px,
                &mut self.output.segments_3d,
            );
            self.output.timings.reconstruction = t.elapsed();
        }
        self.output.timings.total = start.elapsed();
        self.output.local = Some(windows);
        Ok(&self.output)
    }

    /// The exact mode's passes (see [`StereoPipeline::run_local`]); returns the final windows.
    fn exact_passes(
        &mut self,
        left: &GrayView<'_>,
        right: &GrayView<'_>,
        params: &VisionParams,
        mut windows: LocalWindows,
    ) -> Result<LocalWindows, VisionError> {
        let (frame_width, frame_height) = (left.width(), left.height());
        let m = &params.matching;
        // Chains cut by a window border near the region are followed by growing the windows
        // until they are whole (then their segments are the whole-image run's).
        let left_reach = enlarge(
            windows.roi,
            m.neighbourhood_radius_px.ceil() as usize,
            frame_width,
            frame_height,
        );
        let check = CutCheck {
            frame: (frame_width, frame_height),
            border_px: params.canny.kernel_radius() + 3,
            influence: [
                left_reach,
                right_band(
                    left_reach,
                    m.disparity_min_px,
                    m.disparity_max_px,
                    0,
                    frame_width,
                    frame_height,
                ),
            ],
            follow_right: true,
        };
        let step = params.local.growth_step_px.max(1);
        // Every pass that does not end the loop grows a window side by `step` (a side at the
        // frame border is never asked to grow), so the frame is reached within this many.
        let max_passes = 4 * ((frame_width + frame_height) / step + 2);
        for pass in 0..max_passes {
            if pass + 1 == max_passes {
                // Unreachable by the argument above; stay complete regardless.
                windows.left = enlarge(
                    windows.left,
                    frame_width.max(frame_height),
                    frame_width,
                    frame_height,
                );
                windows.right = windows.left;
            }
            let mut cut = self.process_windows(left, right, params, &windows, Some(&check))?;
            // A match inside the region that propagation might reach from outside the window
            // (checked once the pass is complete, i.e. no chain was cut).
            let roi = windows.roi;
            if !cut.iter().flatten().any(|&c| c)
                && self
                    .matcher
                    .has_unreached(&self.output.left_segments, m, |s| touches(s, &roi))
            {
                cut[0] = [true; 4];
            }
            let open = windows.left != whole_frame(frame_width, frame_height);
            if !cut.iter().flatten().any(|&c| c) || (!open && !cut[1].iter().any(|&c| c)) {
                break;
            }
            windows.left = grow_window(windows.left, cut[0], step, frame_width, frame_height);
            windows.right = union(
                grow_window(windows.right, cut[1], step, frame_width, frame_height),
                right_band(
                    windows.left,
                    m.disparity_min_px,
                    m.disparity_max_px,
                    params.local.context_margin_px / 4,
                    frame_width,
                    frame_height,
                ),
            );
        }
        Ok(windows)
    }

    /// The adaptive mode's passes (see [`StereoPipeline::run_local`]); `windows.roi` is the
    /// region, the other windows are chosen here. Returns the final windows.
    fn adaptive_passes(
        &mut self,
        left: &GrayView<'_>,
        right: &GrayView<'_>,
        params: &VisionParams,
        mut windows: LocalWindows,
    ) -> Result<LocalWindows, VisionError> {
        let (frame_width, frame_height) = (left.width(), left.height());
        let m = &params.matching;
        let radius = (m.neighbourhood_radius_px.ceil() as usize).max(1);
        let band = |left: PixelRect| {
            right_band(
                left,
                m.disparity_min_px,
                m.disparity_max_px,
                radius / 2,
                frame_width,
                frame_height,
            )
        };
        windows.left = enlarge(windows.roi, 2 * radius, frame_width, frame_height);
        windows.right = band(windows.left);
        // Only chains crossing the region are followed, in the left image.
        let check = CutCheck {
            frame: (frame_width, frame_height),
            border_px: params.canny.kernel_radius() + 3,
            influence: [windows.roi, windows.roi],
            follow_right: false,
        };
        let mut reach_grown = false;
        // Each pass but the last grows the left window by `radius` on at least one side that
        // is not at the frame border (a side at the border is never reported cut), so the
        // whole frame, where no chain is cut, is reached within this many.
        let max_passes = 2 * ((frame_width + frame_height) / radius + 4);
        for _ in 0..max_passes {
            let cut = self.process_windows(left, right, params, &windows, Some(&check))?;
            let grow = if cut[0].iter().any(|&c| c) {
                cut[0]
            } else {
                let roi = windows.roi;
                if reach_grown
                    || windows.left == whole_frame(frame_width, frame_height)
                    || !self
                        .matcher
                        .has_unreached(&self.output.left_segments, m, |s| touches(s, &roi))
                {
                    break;
                }
                reach_grown = true;
                [true; 4]
            };
            windows.left = grow_window(windows.left, grow, radius, frame_width, frame_height);
            windows.right = band(windows.left);
        }
        Ok(windows)
    }

    /// One pass over `windows`, with `cut_check` as in `process`.
    fn process_windows(
        &mut self,
        left: &GrayView<'_>,
        right: &GrayView<'_>,
        params: &VisionParams,
        windows: &LocalWindows,
        cut_check: Option<&CutCheck>,
    ) -> Result<[WindowSides; 2], VisionError> {
        let empty = || VisionError::EmptyImage {
            width: 0,
            height: 0,
        };
        let left_view = left.window(windows.left).ok_or_else(empty)?;
        let right_view = right.window(windows.right).ok_or_else(empty)?;
        self.process(&left_view, &right_view, None, params, cut_check)
    }

    fn process(
        &mut self,
        left: &GrayView<'_>,
        right: &GrayView<'_>,
        geometry: Option<&RectifiedGeometry>,
        params: &VisionParams,
        cut_check: Option<&CutCheck>,
    ) -> Result<[WindowSides; 2], VisionError> {
        let start = Instant::now();
        let mut cut = [[false; 4]; 2];
        let mut timings = StageTimings::default();
        let out = &mut self.output;
        for (side, (view, segments)) in [
            (left, &mut out.left_segments),
            (right, &mut out.right_segments),
        ]
        .into_iter()
        .enumerate()
        {
            let canny = &mut self.canny;
            if side == 1 {
                canny.keep_smoothed(&mut self.left_smoothed);
            }
            let t = Instant::now();
            let canny_params = if side == 1 {
                right_canny(&params.canny, params.right_threshold_ratio)
            } else {
                params.canny
            };
            canny.detect(view, &canny_params)?;
            timings.edges += t.elapsed();
            let t = Instant::now();
            self.chains.link(
                canny.edges(),
                view.width(),
                view.height(),
                params.segments.min_chain_pixels,
            );
            timings.chains += t.elapsed();
            if let Some(check) = cut_check.filter(|c| side == 0 || c.follow_right) {
                let (x, y) = view.origin_px();
                let rect = PixelRect {
                    x,
                    y,
                    width: view.width(),
                    height: view.height(),
                };
                cut[side] = cut_chain_sides(
                    &self.chains,
                    rect,
                    check.frame.0,
                    check.frame.1,
                    check.border_px,
                    check.influence[side],
                );
            }
            if cut.iter().flatten().any(|&c| c) {
                // The windows will grow: segments and matches of this pass are not needed, nor
                // the right image's chains when they are not followed.
                segments.clear();
                if cut_check.is_some_and(|c| !c.follow_right) {
                    break;
                }
                continue;
            }
            let t = Instant::now();
            self.segments.extract(
                &self.chains,
                canny,
                view.origin_px(),
                &params.segments,
                segments,
            );
            timings.segments += t.elapsed();
        }
        if cut.iter().flatten().any(|&c| c) {
            out.right_segments.clear();
            out.matches.clear();
            out.segments_3d.clear();
            out.timings = timings;
            return Ok(cut);
        }
        let t = Instant::now();
        let images = StereoImages {
            left: patch(
                self.left_smoothed.data(),
                (self.left_smoothed.width(), self.left_smoothed.height()),
                left,
            ),
            right: patch(
                self.canny.smoothed(),
                (self.canny.width(), self.canny.height()),
                right,
            ),
        };
        self.matcher.match_segments(
            &out.left_segments,
            &out.right_segments,
            Some(&images),
            &params.matching,
            &mut out.matches,
        );
        if params.matching.mutual_check {
            self.mutual.filter(
                &out.left_segments,
                &out.right_segments,
                Some(&images),
                &params.matching,
                &mut out.matches,
            );
        }
        timings.matching = t.elapsed();
        out.segments_3d.clear();
        if let Some(g) = geometry {
            g.validate()?;
            let t = Instant::now();
            back_project_matches(
                g,
                &out.left_segments,
                &out.matches,
                params.disparity_sigma_px,
                &mut out.segments_3d,
            );
            timings.reconstruction = t.elapsed();
        }
        timings.total = start.elapsed();
        out.timings = timings;
        Ok(cut)
    }
}

/// What a local run checks for chains cut by its window borders.
struct CutCheck {
    /// Frame size, pixels.
    frame: (usize, usize),
    /// Chains this close to a window border may be cut there, pixels.
    border_px: usize,
    /// Left and right: where cut chains matter (frame pixels).
    influence: [PixelRect; 2],
    /// Whether the right image's chains are checked too; when not, a pass whose left window
    /// cuts a chain stops before the right image.
    follow_right: bool,
}

/// The whole `width x height` frame.
fn whole_frame(width: usize, height: usize) -> PixelRect {
    PixelRect {
        x: 0,
        y: 0,
        width,
        height,
    }
}

/// A smoothed image of `size` (width, height) made from the view `v`.
fn patch<'a>(data: &'a [u8], (width, height): (usize, usize), v: &GrayView<'_>) -> ImagePatch<'a> {
    ImagePatch {
        data,
        width,
        height,
        origin_px: v.origin_px(),
    }
}

/// The right image's edge detection: the left's thresholds times `ratio` (at least 1).
fn right_canny(left: &CannyParams, ratio: f32) -> CannyParams {
    let scale = |t: u16| ((f32::from(t) * ratio).round() as u16).max(1);
    CannyParams {
        low_threshold: scale(left.low_threshold),
        high_threshold: scale(left.high_threshold),
        ..*left
    }
}

/// Whether any part of `s` lies inside `roi` (sampled every pixel along the segment).
fn touches(s: &Segment, roi: &PixelRect) -> bool {
    let steps = s.length_px.ceil().max(1.0) as usize;
    (0..=steps).any(|k| {
        let t = k as f32 / steps as f32;
        roi.contains(
            s.start[0] + t * (s.end[0] - s.start[0]),
            s.start[1] + t * (s.end[1] - s.start[1]),
        )
    })
}

fn check_pair(left: &GrayView<'_>, right: &GrayView<'_>) -> Result<(), VisionError> {
    if left.width() != right.width() || left.height() != right.height() {
        return Err(VisionError::SizeMismatch {
            left_width: left.width(),
            left_height: left.height(),
            right_width: right.width(),
            right_height: right.height(),
        });
    }
    if left.width() < 8 || left.height() < 8 {
        return Err(VisionError::EmptyImage {
            width: left.width(),
            height: left.height(),
        });
    }
    Ok(())
}

/// One-shot whole-image run (allocates its buffers; use [`StereoPipeline`] for video).
pub fn run_pipeline(
    left: &GrayView<'_>,
    right: &GrayView<'_>,
    geometry: Option<&RectifiedGeometry>,
    params: &VisionParams,
) -> Result<PipelineOutput, VisionError> {
    let mut pipeline = StereoPipeline::new();
    pipeline.run(left, right, geometry, params)?;
    Ok(pipeline.output)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A textured synthetic pair: random rectangles at two depths.
    fn synthetic_pair(w: usize, h: usize, d_back: usize, d_front: usize) -> (Vec<u8>, Vec<u8>) {
        let mut state = 12345u64;
        let mut rnd = move |n: u64| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) % n
        };
        let mut back = vec![0u8; w * h];
        let mut front = vec![0u8; w * h];
        for layer in [&mut back, &mut front] {
            for _ in 0..40 {
                let (x0, y0) = (rnd(w as u64) as usize, rnd(h as u64) as usize);
                let (rw, rh) = (8 + rnd(40) as usize, 8 + rnd(40) as usize);
                let v = 20 + rnd(220) as u8;
                for y in y0..(y0 + rh).min(h) {
                    for x in x0..(x0 + rw).min(w) {
                        layer[y * w + x] = v;
                    }
                }
            }
        }
        let mut left = vec![0u8; w * h];
        let mut right = vec![0u8; w * h];
        // Front layer is a central square.
        let inside = |x: usize, y: usize| (60..160).contains(&x) && (40..140).contains(&y);
        for y in 0..h {
            for x in 0..w {
                left[y * w + x] = if inside(x, y) {
                    front[y * w + x]
                } else {
                    back[y * w + x]
                };
                let xb = x + d_back;
                let xf = x + d_front;
                right[y * w + x] = if xf < w && inside(xf, y) {
                    front[y * w + xf]
                } else if xb < w {
                    back[y * w + xb]
                } else {
                    0
                };
            }
        }
        (left, right)
    }

    #[test]
    fn synthetic_two_depth_scene_is_matched_with_correct_disparities() {
        let (w, h) = (220, 180);
        let (l, r) = synthetic_pair(w, h, 6, 18);
        let lv = GrayView::new(&l, w, h).unwrap();
        let rv = GrayView::new(&r, w, h).unwrap();
        let g = RectifiedGeometry {
            focal_px: 400.0,
            cx_px: 110.0,
            cy_px: 90.0,
            baseline_m: 0.12,
        };
        let out = run_pipeline(&lv, &rv, Some(&g), &VisionParams::default()).unwrap();
        assert!(out.left_segments.len() > 30, "{}", out.left_segments.len());
        let matched = out.matches.len() as f32 / out.left_segments.len() as f32;
        assert!(matched > 0.4, "matched {matched}");
        let wrong = out
            .matches
            .iter()
            .filter(|m| {
                let d = 0.5 * (m.disparity_px[0] + m.disparity_px[1]);
                (d - 6.0).abs() > 1.0 && (d - 18.0).abs() > 1.0
            })
            .count();
        assert!(
            wrong * 20 <= out.matches.len(),
            "{wrong} wrong of {}",
            out.matches.len()
        );
        assert!(!out.segments_3d.is_empty());
        for s in &out.segments_3d {
            assert!(s.start_m.z > 0.0 && s.start_sigma_m.z > 0.0);
        }
    }

    #[test]
    fn tiny_and_border_regions_do_not_panic() {
        let (w, h) = (120, 90);
        let (l, r) = synthetic_pair(w, h, 4, 9);
        let lv = GrayView::new(&l, w, h).unwrap();
        let rv = GrayView::new(&r, w, h).unwrap();
        let mut params = VisionParams::default();
        let mut pipeline = StereoPipeline::new();
        for (margin, exact, context) in [
            (0, true, LocalContext::Fixed),
            (1, true, LocalContext::Fixed),
            (32, true, LocalContext::Fixed),
            (0, false, LocalContext::Fixed),
            (32, false, LocalContext::Adaptive),
        ] {
            params.local.context_margin_px = margin;
            params.local.exact = exact;
            params.local.context = context;
            for (cx, cy, size) in [
                (0.0, 0.0, 1.0),
                (119.0, 89.0, 2.0),
                (60.0, 45.0, 3.0),
                (-3.0, 40.0, 8.0),
                (60.0, 45.0, 500.0),
            ] {
                let region = LocalRegion {
                    centre_px: [cx, cy],
                    size_px: [size, size],
                    velocity_px_per_frame: [30.0, -20.0],
                };
                match pipeline.run_local(&lv, &rv, None, &params, &region) {
                    Ok(out) => assert!(out.local.is_some()),
                    Err(e) => assert!(matches!(e, VisionError::RoiOutside { .. }), "{e}"),
                }
            }
        }
    }

    #[test]
    fn mismatched_sizes_are_an_error() {
        let a = vec![0u8; 100];
        let b = vec![0u8; 120];
        let lv = GrayView::new(&a, 10, 10).unwrap();
        let rv = GrayView::new(&b, 12, 10).unwrap();
        let e = run_pipeline(&lv, &rv, None, &VisionParams::default()).unwrap_err();
        assert!(e.to_string().contains("10x10"), "{e}");
    }
}
