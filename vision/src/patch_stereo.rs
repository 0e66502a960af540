//! Depth from small image patches, where the segments say too little: which side of an edge is
//! the near surface, and the depth of the textured surfaces between the segments.
//!
//! **Sides.** An edge at a depth step (an occluding contour) belongs to the nearer surface: the
//! image on its near side moves with it between the two views, the image on its far side moves
//! less (the background's smaller disparity). A texture edge or a crease has the same disparity
//! on both sides. So each side's own disparity, found by matching a small patch beside the
//! segment along the epipolar line, tells which side the relief must step down on and how far,
//! which the segments alone cannot: a triangulation between two occluding edges does not know
//! whether the object or the background lies between them. [`far_side_segments`] turns a
//! measured step into a 3-D segment beside the edge, at the far side's depth, so that the relief
//! builder holds the far surface up to a wall at the edge instead of a ramp across it.
//!
//! The patch of a side facing the image's left is taken in the right image and searched in the
//! left one, that of a side facing the right in the left image: the band of background beside
//! an object that only one camera sees (the half-occlusion) is then never the reference.
//!
//! **Support points.** Between the segments, the relief would interpolate over whatever the
//! segments enclose: the background between two leaves at the leaves' height, a wall without
//! edges as a ramp. [`support_points`] matches textured patches on a grid over the left image,
//! keeps those whose match is unique and found back from the right image, and gives their
//! depths to the builder as points. Untextured patches are not matched: there the segments'
//! interpolation stands.
//!
//! Both search a patch's normalized cross-correlation over the disparity range along one band
//! of rows, read once (see `patch_disparity`).

use crate::gray::{GrayView, PixelRect};
use crate::matching::SegmentMatch;
use crate::pipeline::PipelineOutput;
use crate::reconstruct::{RectifiedGeometry, Segment3d};
use crate::segments::Segment;

/// Settings of the side measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchParams {
    /// Half the side of the square patch matched on each side, pixels (>= 1).
    pub patch_radius_px: usize,
    /// Distance of the patch's centre from the segment, pixels (> `patch_radius_px`, so that
    /// the patch stays off the edge itself).
    pub offset_px: f32,
    /// Patches per side along the segment (>= 1), spread over its middle 80 %.
    pub samples: usize,
    /// Least normalized cross-correlation of an accepted patch match, in (0, 1].
    pub min_correlation: f32,
    /// Least standard deviation of a patch's grey levels (a patch with less texture is not
    /// matched), grey levels (>= 0).
    pub min_texture: f32,
    /// A side steps down when its disparity is below the segment's by more than this, pixels
    /// (> 0).
    pub min_step_px: f32,
    /// Least fraction of a side's accepted patches that must agree on the step, in (0, 1].
    pub min_agreement: f32,
    /// Distance of a far-side segment from its edge, pixels (> 0): the wall's width in the image.
    pub wall_px: f32,
    /// Spacing of the support points' grid, pixels (>= 2).
    pub spacing_px: usize,
    /// The patches are searched up to the largest disparity of the run's matches plus this,
    /// pixels (> 0; see [`search_bound_px`]): a surface nearer than every matched edge by more
    /// than this is not looked for.
    pub search_margin_px: f32,
}

impl Default for PatchParams {
    /// 7 x 7 patches, correlation 0.8 or more on at least 4 grey levels of texture. Sides:
    /// 5 px from the edge, 6 a side, a step when two thirds of them see the side 1.5 px
    /// farther; walls 3 px wide. Support points every 12 px. The search up to 8 px past the
    /// largest matched disparity.
    fn default() -> Self {
        PatchParams {
            patch_radius_px: 3,
            offset_px: 5.0,
            samples: 6,
            min_correlation: 0.8,
            min_texture: 4.0,
            min_step_px: 1.5,
            min_agreement: 0.66,
            wall_px: 3.0,
            spacing_px: 12,
            search_margin_px: 8.0,
        }
    }
}

/// The largest disparity the patches of a run are searched at: the largest disparity of its
/// `matches` plus `margin_px`, or `disparity_max_px` when that is smaller or nothing matched.
/// The matched edges bound the scene's nearest surfaces; the configured range beyond them is
/// most of what a search would otherwise cover.
pub fn search_bound_px(matches: &[SegmentMatch], disparity_max_px: f32, margin_px: f32) -> f32 {
    let largest = matches
        .iter()
        .flat_map(|m| m.disparity_px)
        .filter(|d| d.is_finite())
        .reduce(f32::max);
    match largest {
        Some(d) => disparity_max_px.min(d + margin_px.max(0.0)),
        None => disparity_max_px,
    }
}

/// A side of a segment, seen along `start -> end` in the image (`y` down).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// The side of the normal `(-dy, dx)`.
    Positive,
    /// The opposite side.
    Negative,
}

impl Side {
    fn sign(self) -> f32 {
        match self {
            Side::Positive => 1.0,
            Side::Negative => -1.0,
        }
    }
}

/// A side of a match that steps down to a farther surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SideStep {
    /// Index of the match.
    pub match_index: u32,
    /// The side that steps down.
    pub side: Side,
    /// How much smaller the far side's disparity is than the segment's (median over the
    /// agreeing patches), pixels (> 0).
    pub disparity_drop_px: f32,
    /// Patches that agreed on the step.
    pub agreeing: u32,
}

/// What the side measurement saw, for reports.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SideCounts {
    /// Sides measured (two per back-projected match).
    pub sides: u32,
    /// Sides with no patch accepted (no texture, off the image, no clear match).
    pub unmeasured: u32,
    /// Sides found to step down.
    pub steps: u32,
}

/// Measure both sides of every back-projectable match; the sides that step down are appended
/// to `out` (cleared first). `disparity_max_px` bounds the search.
pub fn side_steps(
    left: &GrayView<'_>,
    right: &GrayView<'_>,
    left_segments: &[Segment],
    matches: &[SegmentMatch],
    disparity_max_px: f32,
    params: &PatchParams,
    out: &mut Vec<SideStep>,
) -> SideCounts {
    out.clear();
    let mut counts = SideCounts::default();
    let mut drops = Vec::with_capacity(params.samples);
    let mut scratch = PatchScratch::default();
    for (k, m) in matches.iter().enumerate() {
        if m.nearly_horizontal {
            continue;
        }
        let s = &left_segments[m.left as usize];
        let (dir, len) = direction_and_length(s);
        if len < 1.0 {
            continue;
        }
        let normal = [-dir[1] / len, dir[0] / len];
        for side in [Side::Positive, Side::Negative] {
            counts.sides += 1;
            drops.clear();
            let mut accepted = 0u32;
            for j in 0..params.samples {
                let t = 0.1 + 0.8 * (j as f32 + 0.5) / params.samples as f32;
                let p = [s.start[0] + t * dir[0], s.start[1] + t * dir[1]];
                let seg_d = m.disparity_px[0] + t * (m.disparity_px[1] - m.disparity_px[0]);
                let o = side.sign() * params.offset_px;
                let c = [p[0] + o * normal[0], p[1] + o * normal[1]];
                let faces_left = side.sign() * normal[0] < 0.0;
                let found = if faces_left {
                    // The patch in the right image, where the left pixel `c` is seen at
                    // `c.x - seg_d`; searched in the left image at `+ d`.
                    patch_disparity(
                        right,
                        left,
                        [c[0] - seg_d, c[1]],
                        1.0,
                        disparity_max_px,
                        params,
                        &mut scratch,
                    )
                } else {
                    patch_disparity(left, right, c, -1.0, disparity_max_px, params, &mut scratch)
                };
                if let Some(d) = found {
                    accepted += 1;
                    drops.push(seg_d - d);
                }
            }
            if accepted == 0 {
                counts.unmeasured += 1;
                continue;
            }
            drops.retain(|&drop| drop > params.min_step_px);
            if (drops.len() as f32) < params.min_agreement * accepted as f32 || drops.len() < 2 {
                continue;
            }
            drops.sort_by(f32::total_cmp);
            counts.steps += 1;
            out.push(SideStep {
                match_index: k as u32,
                side,
                disparity_drop_px: drops[drops.len() / 2],
                agreeing: drops.len() as u32,
            });
        }
    }
    counts
}

/// A segment's `end - start` in the image, and its length, pixels.
fn direction_and_length(s: &Segment) -> ([f32; 2], f32) {
    let dir = [s.end[0] - s.start[0], s.end[1] - s.start[1]];
    (dir, dir[0].hypot(dir[1]))
}

/// Reusable buffers of the patch search.
#[derive(Debug, Default, Clone)]
struct PatchScratch {
    /// The patch's rows of the other image, as floats: `side` rows of `span` values.
    rows: Vec<f32>,
    /// Per column of the span: the sum and the sum of squares over the patch's rows.
    column_sum: Vec<f32>,
    column_squares: Vec<f32>,
    /// Per window start: the cross-correlation sum, then the score.
    cross: Vec<f32>,
}

/// The disparity of the patch of `reference` centred at `c` (rounded to a pixel), searched in
/// `other` at `c.x + direction * d` for `d` in `[0, disparity_max_px]`: the best normalized
/// cross-correlation, refined to a fraction of a pixel; `None` when the patch leaves an image,
/// has too little texture, or the best match is weak or not unique.
///
/// All candidate windows lie on one band of `other`'s rows: the band is read once, and every
/// sum runs along it, over all candidates at a time.
fn patch_disparity(
    reference: &GrayView<'_>,
    other: &GrayView<'_>,
    c: [f32; 2],
    direction: f32,
    disparity_max_px: f32,
    params: &PatchParams,
    scratch: &mut PatchScratch,
) -> Option<f32> {
    let r = params.patch_radius_px as i64;
    let (cx, cy) = (c[0].round() as i64, c[1].round() as i64);
    let (w, h) = (reference.width() as i64, reference.height() as i64);
    if cx - r < 0 || cy - r < 0 || cx + r >= w || cy + r >= h || other.height() as i64 != h {
        return None;
    }
    let side = (2 * r + 1) as usize;
    if side > 15 {
        return None;
    }
    let n = (side * side) as f32;
    let mut patch = [0f32; 15 * 15];
    let mut sum = 0.0;
    for (i, y) in (cy - r..=cy + r).enumerate() {
        let row = &reference.row(y as usize)[(cx - r) as usize..=(cx + r) as usize];
        for (j, &v) in row.iter().enumerate() {
            patch[i * side + j] = v as f32;
            sum += v as f32;
        }
    }
    let mean = sum / n;
    let mut var = 0.0;
    for v in &mut patch[..side * side] {
        *v -= mean;
        var += *v * *v;
    }
    if (var / n).sqrt() < params.min_texture {
        return None;
    }
    // The candidates whose window lies inside `other`: d in 0..=d_hi.
    let ow = other.width() as i64;
    let room = if direction > 0.0 {
        ow - 1 - r - cx
    } else {
        cx - r
    };
    let d_hi = (disparity_max_px.max(0.0).ceil() as i64).min(room).min(511);
    if d_hi < 2 {
        return None;
    }
    let count = (d_hi + 1) as usize;
    let span = count + side - 1;
    let x0 = if direction > 0.0 {
        cx - r
    } else {
        cx - d_hi - r
    } as usize;
    scratch.rows.clear();
    for y in cy - r..=cy + r {
        let row = &other.row(y as usize)[x0..x0 + span];
        scratch.rows.extend(row.iter().map(|&v| v as f32));
    }
    scratch.column_sum.clear();
    scratch.column_sum.resize(span, 0.0);
    scratch.column_squares.clear();
    scratch.column_squares.resize(span, 0.0);
    for row in scratch.rows.chunks_exact(span) {
        for ((s, q), &v) in scratch
            .column_sum
            .iter_mut()
            .zip(scratch.column_squares.iter_mut())
            .zip(row)
        {
            *s += v;
            *q += v * v;
        }
    }
    scratch.cross.clear();
    scratch.cross.resize(count, 0.0);
    for (i, row) in scratch.rows.chunks_exact(span).enumerate() {
        for j in 0..side {
            let weight = patch[i * side + j];
            for (acc, &v) in scratch.cross.iter_mut().zip(&row[j..j + count]) {
                *acc += weight * v;
            }
        }
    }
    // Window start k: its sums, then its score in place of its cross sum.
    let (mut s, mut s2) = (0.0f32, 0.0f32);
    for j in 0..side {
        s += scratch.column_sum[j];
        s2 += scratch.column_squares[j];
    }
    for k in 0..count {
        if k > 0 {
            s += scratch.column_sum[k + side - 1] - scratch.column_sum[k - 1];
            s2 += scratch.column_squares[k + side - 1] - scratch.column_squares[k - 1];
        }
        let other_var = s2 - s * s / n;
        scratch.cross[k] = if other_var > 1e-3 {
            scratch.cross[k] / (var * other_var).sqrt()
        } else {
            f32::NEG_INFINITY
        };
    }
    // Disparity of window start k.
    let disparity = |k: usize| if direction > 0.0 { k } else { count - 1 - k };
    let scores = &scratch.cross;
    let (best_k, &best_score) = scores
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))?;
    if best_score < params.min_correlation {
        return None;
    }
    // Unique: no other peak (2 px or more away) nearly as good.
    let rival = scores
        .iter()
        .enumerate()
        .filter(|(k, _)| k.abs_diff(best_k) >= 2)
        .map(|(_, &s)| s)
        .fold(f32::NEG_INFINITY, f32::max);
    if rival > best_score - 0.05 {
        return None;
    }
    let mut d = disparity(best_k) as f32;
    if best_k > 0 && best_k + 1 < count {
        // The scores at d - 1 and d + 1 (k runs against d when searching leftwards).
        let (a, c) = if direction > 0.0 {
            (scores[best_k - 1], scores[best_k + 1])
        } else {
            (scores[best_k + 1], scores[best_k - 1])
        };
        let denom = a - 2.0 * best_score + c;
        if a.is_finite() && c.is_finite() && denom < -1e-6 {
            d += (0.5 * (a - c) / denom).clamp(-0.5, 0.5);
        }
    }
    Some(d)
}

/// Disparities of textured patches on a grid over the left image, every
/// [`PatchParams::spacing_px`] pixels (the grid is the whole frame's; with `region`, only its
/// nodes inside the region): `(x, y, d)` of each patch whose match is accepted both ways (the
/// left patch found in the right image at `d`, and that right patch found back in the left
/// within a pixel), appended to `out` (cleared first).
pub fn support_points(
    left: &GrayView<'_>,
    right: &GrayView<'_>,
    disparity_max_px: f32,
    region: Option<PixelRect>,
    params: &PatchParams,
    out: &mut Vec<[f32; 3]>,
) {
    out.clear();
    let mut scratch = PatchScratch::default();
    let r = params.patch_radius_px;
    let step = params.spacing_px.max(2);
    let first = r + step / 2;
    let (x_end, y_end) = (
        left.width().saturating_sub(r),
        left.height().saturating_sub(r),
    );
    let (x_range, y_range) = match region {
        Some(rect) => (
            (rect.x, (rect.x + rect.width).min(x_end)),
            (rect.y, (rect.y + rect.height).min(y_end)),
        ),
        None => ((0, x_end), (0, y_end)),
    };
    // The first grid node at or after `from`.
    let node_from = |from: usize| {
        if from <= first {
            first
        } else {
            first + (from - first).div_ceil(step) * step
        }
    };
    let mut y = node_from(y_range.0);
    while y < y_range.1 {
        let mut x = node_from(x_range.0);
        while x < x_range.1 {
            let c = [x as f32, y as f32];
            let found =
                patch_disparity(left, right, c, -1.0, disparity_max_px, params, &mut scratch);
            if let Some(d) = found {
                let back = patch_disparity(
                    right,
                    left,
                    [c[0] - d.round(), c[1]],
                    1.0,
                    disparity_max_px,
                    params,
                    &mut scratch,
                );
                if back.is_some_and(|b| (b - d).abs() <= 1.0) {
                    out.push([c[0], c[1], d]);
                }
            }
            x += step;
        }
        y += step;
    }
}

/// For every side step, a 3-D segment beside its edge at the far side's depth: the left
/// segment moved `wall_px` towards the stepping side and shortened by `wall_px` at each end,
/// with the match's disparity less the step's drop (appended to `out`, not cleared; the
/// segment keeps its match's index). Drops that would leave no positive disparity are skipped.
pub fn far_side_segments(
    geometry: &RectifiedGeometry,
    left_segments: &[Segment],
    matches: &[SegmentMatch],
    steps: &[SideStep],
    wall_px: f32,
    sigma_d_px: f64,
    out: &mut Vec<Segment3d>,
) {
    for step in steps {
        let m = &matches[step.match_index as usize];
        let s = &left_segments[m.left as usize];
        let (dir, len) = direction_and_length(s);
        if len <= 2.0 * wall_px {
            continue;
        }
        let unit = [dir[0] / len, dir[1] / len];
        let o = step.side.sign() * wall_px;
        let shift = [-unit[1] * o, unit[0] * o];
        let t0 = wall_px / len;
        let t1 = 1.0 - t0;
        let end = |t: f32| {
            let d = m.disparity_px[0] + t * (m.disparity_px[1] - m.disparity_px[0])
                - step.disparity_drop_px;
            let p = [
                s.start[0] + t * dir[0] + shift[0],
                s.start[1] + t * dir[1] + shift[1],
            ];
            geometry.back_project(p[0] as f64, p[1] as f64, d as f64, sigma_d_px)
        };
        if let (Some((a, sa)), Some((b, sb))) = (end(t0), end(t1)) {
            out.push(Segment3d {
                match_index: step.match_index,
                start_m: a,
                end_m: b,
                start_sigma_m: sa,
                end_sigma_m: sb,
            });
        }
    }
}

/// What the patches add to a pipeline run's segments, with the buffers of the measurement.
#[derive(Debug, Default, Clone)]
pub struct PatchDepth {
    /// The far sides of the occluding edges, as 3-D segments (each with its match's index).
    pub far_sides: Vec<Segment3d>,
    /// The support points, left camera frame `(X, Y, Z)`, metres.
    pub points: Vec<[f64; 3]>,
    steps: Vec<SideStep>,
    grid: Vec<[f32; 3]>,
}

impl PatchDepth {
    /// Measure the sides of `output`'s matches and the support points (inside `region` when
    /// given) on the rectified pair `left`, `right` that `output` was run on.
    #[allow(clippy::too_many_arguments)]
    pub fn measure(
        &mut self,
        left: &GrayView<'_>,
        right: &GrayView<'_>,
        geometry: &RectifiedGeometry,
        output: &PipelineOutput,
        disparity_max_px: f32,
        sigma_d_px: f64,
        region: Option<PixelRect>,
        params: &PatchParams,
    ) {
        let disparity_max_px =
            search_bound_px(&output.matches, disparity_max_px, params.search_margin_px);
        side_steps(
            left,
            right,
            &output.left_segments,
            &output.matches,
            disparity_max_px,
            params,
            &mut self.steps,
        );
        self.far_sides.clear();
        far_side_segments(
            geometry,
            &output.left_segments,
            &output.matches,
            &self.steps,
            params.wall_px,
            sigma_d_px,
            &mut self.far_sides,
        );
        support_points(
            left,
            right,
            disparity_max_px,
            region,
            params,
            &mut self.grid,
        );
        self.points.clear();
        for &[x, y, d] in &self.grid {
            if let Some((p, _)) = geometry.back_project(x as f64, y as f64, d as f64, sigma_d_px) {
                self.points.push([p.x, p.y, p.z]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matching::MatchEvidence;

    /// A textured background at disparity `far`, a textured square object at `near` over
    /// columns `x0..x1` (left image) and rows 20..100.
    fn scene(far: usize, near: usize, x0: usize, x1: usize) -> (Vec<u8>, Vec<u8>, usize, usize) {
        let (w, h) = (160usize, 120usize);
        let texture = |x: i64, y: i64, seed: i64| {
            let v = (x * 7919 + y * 104729 + seed * 1299709).rem_euclid(9973);
            (v % 200 + 28) as u8
        };
        let mut left = vec![0u8; w * h];
        let mut right = vec![0u8; w * h];
        for y in 0..h {
            for x in 0..w {
                let on_object = |xl: usize| (20..100).contains(&y) && (x0..x1).contains(&xl);
                // Left pixel x: the object's texture in object coordinates, the background's
                // in background coordinates.
                left[y * w + x] = if on_object(x) {
                    texture(x as i64 - x0 as i64, y as i64, 1)
                } else {
                    texture(x as i64, y as i64, 2)
                };
                // Right pixel x sees the object at x + near, the background at x + far.
                right[y * w + x] = if on_object(x + near) {
                    texture((x + near) as i64 - x0 as i64, y as i64, 1)
                } else {
                    texture((x + far) as i64, y as i64, 2)
                };
            }
        }
        (left, right, w, h)
    }

    fn vertical_match(x: f32, d: f32) -> (Segment, SegmentMatch) {
        let s = Segment {
            start: [x, 25.0],
            end: [x, 95.0],
            length_px: 70.0,
            angle_rad: std::f32::consts::FRAC_PI_2,
            polarity: 1,
            contrast: 50.0,
            side_intensity: [0.0, 0.0],
            chain: 0,
        };
        let m = SegmentMatch {
            left: 0,
            right: 0,
            disparity_px: [d, d],
            support: 0,
            predicted: false,
            nearly_horizontal: false,
            evidence: MatchEvidence::default(),
        };
        (s, m)
    }

    fn views<'a>(l: &'a [u8], r: &'a [u8], w: usize, h: usize) -> (GrayView<'a>, GrayView<'a>) {
        (
            GrayView::new(l, w, h).unwrap(),
            GrayView::new(r, w, h).unwrap(),
        )
    }

    /// The side steps of one vertical match at `edge_x` of disparity `d`, with the defaults.
    fn sides_of(
        (lv, rv): (GrayView<'_>, GrayView<'_>),
        edge_x: f32,
        d: f32,
    ) -> (Vec<SideStep>, SideCounts) {
        let (s, m) = vertical_match(edge_x, d);
        let mut out = Vec::new();
        let counts = side_steps(
            &lv,
            &rv,
            &[s],
            &[m],
            24.0,
            &PatchParams::default(),
            &mut out,
        );
        (out, counts)
    }

    #[test]
    fn an_occluding_edge_steps_down_on_the_background_side_only() {
        let (far, near) = (4usize, 16usize);
        let (l, r, w, h) = scene(far, near, 60, 110);
        for edge_x in [59.5f32, 109.5] {
            let (out, counts) = sides_of(views(&l, &r, w, h), edge_x, near as f32);
            assert_eq!(counts.sides, 2);
            assert_eq!(out.len(), 1, "edge at {edge_x}: {out:?}");
            // start -> end runs down: the positive normal (-dy, dx) points to the image's left.
            let background = if edge_x < 80.0 {
                Side::Positive
            } else {
                Side::Negative
            };
            assert_eq!(out[0].side, background, "edge at {edge_x}");
            let drop = out[0].disparity_drop_px;
            assert!(
                (drop - (near - far) as f32).abs() < 0.6,
                "edge at {edge_x}: drop {drop}"
            );
        }
    }

    #[test]
    fn a_texture_edge_does_not_step() {
        let (l, r, w, h) = scene(10, 10, 60, 110);
        let (out, counts) = sides_of(views(&l, &r, w, h), 59.5, 10.0);
        assert!(out.is_empty(), "{out:?}");
        assert_eq!(counts.unmeasured, 0);
    }

    #[test]
    fn a_far_side_segment_lies_beside_the_edge_at_the_far_depth() {
        let geometry = RectifiedGeometry {
            focal_px: 100.0,
            cx_px: 80.0,
            cy_px: 60.0,
            baseline_m: 0.1,
        };
        let (s, m) = vertical_match(59.5, 16.0);
        let step = SideStep {
            match_index: 0,
            side: Side::Positive,
            disparity_drop_px: 12.0,
            agreeing: 6,
        };
        let mut out = Vec::new();
        far_side_segments(&geometry, &[s], &[m], &[step], 3.0, 0.5, &mut out);
        assert_eq!(out.len(), 1);
        // Disparity 4 px: Z = f B / d = 2.5 m; 3 px to the image's left of the edge.
        for p in [out[0].start_m, out[0].end_m] {
            assert!((p.z - 2.5).abs() < 1e-9, "{p:?}");
            let u = p.x * geometry.focal_px / p.z + geometry.cx_px;
            assert!((u - 56.5).abs() < 1e-4, "{u}");
        }
        let v0 = out[0].start_m.y * geometry.focal_px / out[0].start_m.z + geometry.cy_px;
        assert!((v0 - 28.0).abs() < 1e-4, "{v0}");
    }

    #[test]
    fn support_points_find_the_object_and_the_background_at_their_disparities() {
        let (far, near) = (4usize, 16usize);
        let (l, r, w, h) = scene(far, near, 60, 110);
        let (lv, rv) = views(&l, &r, w, h);
        let params = PatchParams {
            spacing_px: 8,
            ..PatchParams::default()
        };
        let mut out = Vec::new();
        support_points(&lv, &rv, 24.0, None, &params, &mut out);
        let (mut on_object, mut on_background) = (0, 0);
        for &[x, y, d] in &out {
            // Patches wholly on the object or wholly on the background (7 x 7).
            let object = (63.0..=106.0).contains(&x) && (23.0..=96.0).contains(&y);
            let background = !((53.0..=116.0).contains(&x) && (13.0..=106.0).contains(&y));
            if object {
                on_object += 1;
                assert!((d - near as f32).abs() < 0.6, "({x}, {y}): {d}");
            } else if background {
                on_background += 1;
                assert!((d - far as f32).abs() < 0.6, "({x}, {y}): {d}");
            }
        }
        assert!(
            on_object >= 30 && on_background >= 30,
            "{on_object} {on_background}"
        );
        // A region takes the whole frame's grid nodes inside it.
        let rect = PixelRect {
            x: 40,
            y: 30,
            width: 50,
            height: 40,
        };
        let mut inside = Vec::new();
        support_points(&lv, &rv, 24.0, Some(rect), &params, &mut inside);
        let expected: Vec<_> = out
            .iter()
            .filter(|p| rect.contains(p[0], p[1]))
            .copied()
            .collect();
        assert!(!inside.is_empty());
        assert_eq!(inside, expected);
    }

    #[test]
    fn the_search_stops_a_margin_past_the_largest_matched_disparity() {
        let (_, near) = vertical_match(59.5, 16.0);
        let (_, far) = vertical_match(109.5, 4.0);
        assert_eq!(search_bound_px(&[far, near], 97.0, 8.0), 24.0);
        assert_eq!(search_bound_px(&[far, near], 20.0, 8.0), 20.0);
        // Nothing matched: nothing bounds the scene.
        assert_eq!(search_bound_px(&[], 97.0, 8.0), 97.0);
        // Only the background's edge matched: the object 12 px nearer is past the bound, and
        // its patches are not found at the object's disparity.
        let (l, r, w, h) = scene(4, 16, 60, 110);
        let (lv, rv) = views(&l, &r, w, h);
        let params = PatchParams {
            spacing_px: 8,
            ..PatchParams::default()
        };
        let bound = search_bound_px(&[far], 24.0, params.search_margin_px);
        assert_eq!(bound, 12.0);
        let mut out = Vec::new();
        support_points(&lv, &rv, bound, None, &params, &mut out);
        assert!(!out.is_empty());
        assert!(out.iter().all(|p| p[2] <= bound), "{out:?}");
    }
}
