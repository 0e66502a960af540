//! Approximation of edge chains by straight line segments (recursive splitting at the point of
//! maximum deviation, optional least-squares refit) and the attributes the matcher uses.

use crate::canny::CannyWorkspace;
use crate::chains::Chains;
use crate::error::VisionError;

/// Parameters of the polygonal approximation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentParams {
    /// Chains with fewer pixels are ignored.
    pub min_chain_pixels: usize,
    /// Pieces shorter than this (endpoint distance, pixels) are dropped.
    pub min_length_px: f32,
    /// A piece is split while some pixel deviates more than this from its chord, pixels.
    pub tolerance_px: f32,
    /// Replace each piece's chord by the total-least-squares line through its pixels.
    pub refit: bool,
    /// Distance from the segment at which side intensities are sampled, pixels.
    pub side_offset_px: f32,
}

impl Default for SegmentParams {
    /// Chains of >= 8 px, segments of >= 10 px, 1.5 px tolerance, refit on, sides sampled 2.5 px
    /// away.
    fn default() -> Self {
        Self {
            min_chain_pixels: 8,
            min_length_px: 10.0,
            tolerance_px: 1.5,
            refit: true,
            side_offset_px: 2.5,
        }
    }
}

impl SegmentParams {
    /// Checks the parameter ranges.
    pub fn validate(&self) -> Result<(), VisionError> {
        if !(self.tolerance_px > 0.0 && self.tolerance_px <= 20.0) {
            return Err(VisionError::Parameter {
                name: "segments.tolerance_px",
                value: self.tolerance_px as f64,
                allowed: "(0, 20]",
            });
        }
        if !(self.min_length_px >= 2.0 && self.min_length_px <= 1000.0) {
            return Err(VisionError::Parameter {
                name: "segments.min_length_px",
                value: self.min_length_px as f64,
                allowed: "2..=1000",
            });
        }
        if !(self.side_offset_px >= 1.0 && self.side_offset_px <= 10.0) {
            return Err(VisionError::Parameter {
                name: "segments.side_offset_px",
                value: self.side_offset_px as f64,
                allowed: "1..=10",
            });
        }
        Ok(())
    }
}

/// A straight image segment with the attributes used for matching. Coordinates are in pixels
/// of the full frame; `start` is the upper endpoint (smaller y; for a horizontal segment, the
/// left one).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// Upper endpoint `[x, y]`, pixels.
    pub start: [f32; 2],
    /// Lower endpoint `[x, y]`, pixels.
    pub end: [f32; 2],
    /// Length, pixels.
    pub length_px: f32,
    /// Direction angle of `end - start` in `[0, pi)`: 0 horizontal, pi/2 vertical.
    pub angle_rad: f32,
    /// Sign of the gradient across the segment (+1: brighter on the right of `start -> end`).
    pub polarity: i8,
    /// Mean L1 Sobel magnitude along the segment.
    pub contrast: f32,
    /// Mean smoothed intensity on the left and right of `start -> end`.
    pub side_intensity: [f32; 2],
    /// Index of the chain it came from (within its image).
    pub chain: u32,
}

impl Segment {
    /// Midpoint `[x, y]`, pixels.
    pub fn midpoint(&self) -> [f32; 2] {
        [
            0.5 * (self.start[0] + self.end[0]),
            0.5 * (self.start[1] + self.end[1]),
        ]
    }

    /// Vertical extent `end.y - start.y`, pixels.
    pub fn height_px(&self) -> f32 {
        self.end[1] - self.start[1]
    }

    /// Column where the segment's supporting line crosses row `y` (`None` for a horizontal
    /// line).
    pub fn x_at_row(&self, y: f32) -> Option<f32> {
        let dy = self.end[1] - self.start[1];
        if dy.abs() < 1e-4 {
            return None;
        }
        Some(self.start[0] + (y - self.start[1]) * (self.end[0] - self.start[0]) / dy)
    }

    /// Whether the segment is within `max_angle_rad` of horizontal.
    pub fn is_nearly_horizontal(&self, max_angle_rad: f32) -> bool {
        self.angle_rad < max_angle_rad || self.angle_rad > std::f32::consts::PI - max_angle_rad
    }
}

/// Reusable state of the segment extraction.
#[derive(Debug, Default, Clone)]
pub struct SegmentWorkspace {
    stack: Vec<(usize, usize)>,
    pieces: Vec<(usize, usize)>,
    subpixel: Vec<[f32; 2]>,
}

impl SegmentWorkspace {
    /// An empty workspace.
    pub fn new() -> Self {
        Self::default()
    }

    /// Approximates every chain by segments, appending them to `out` (cleared first). The
    /// chains and the Canny workspace must come from the same image window whose top-left
    /// corner in the frame is `origin_px`.
    pub fn extract(
        &mut self,
        chains: &Chains,
        canny: &CannyWorkspace,
        origin_px: (usize, usize),
        params: &SegmentParams,
        out: &mut Vec<Segment>,
    ) {
        out.clear();
        for c in 0..chains.len() {
            let points = chains.chain(c);
            if points.len() < params.min_chain_pixels.max(2) || !can_reach(points, params) {
                continue;
            }
            split_chain(
                points,
                params.tolerance_px,
                &mut self.stack,
                &mut self.pieces,
            );
            subpixel_positions(points, canny, &mut self.subpixel);
            for &(a, b) in &self.pieces {
                if let Some(seg) = make_segment(
                    points,
                    &self.subpixel,
                    a,
                    b,
                    c as u32,
                    canny,
                    origin_px,
                    params,
                ) {
                    out.push(seg);
                }
            }
        }
    }
}

/// Largest distance between a chain pixel and its sub-pixel position: half a pixel along
/// each axis of a diagonal gradient direction.
const SUBPIXEL_SHIFT_MAX_PX: f32 = std::f32::consts::FRAC_1_SQRT_2;

/// Whether a piece of the chain can be as long as `min_length_px`: no piece is longer than
/// the diagonal of the chain's bounding box plus the sub-pixel shifts of its two endpoints.
fn can_reach(points: &[[u16; 2]], params: &SegmentParams) -> bool {
    let (mut lo, mut hi) = (points[0], points[0]);
    for p in points {
        lo = [lo[0].min(p[0]), lo[1].min(p[1])];
        hi = [hi[0].max(p[0]), hi[1].max(p[1])];
    }
    let (dx, dy) = (f32::from(hi[0] - lo[0]), f32::from(hi[1] - lo[1]));
    (dx * dx + dy * dy).sqrt() + 2.0 * SUBPIXEL_SHIFT_MAX_PX + 0.01 >= params.min_length_px
}

/// Recursive splitting (explicit stack) of `points` into index ranges `(a, b)` whose pixels
/// all lie within `tolerance` of the chord `points[a] -> points[b]`; ranges come out in chain
/// order.
fn split_chain(
    points: &[[u16; 2]],
    tolerance: f32,
    stack: &mut Vec<(usize, usize)>,
    pieces: &mut Vec<(usize, usize)>,
) {
    pieces.clear();
    stack.clear();
    stack.push((0, points.len() - 1));
    while let Some((a, b)) = stack.pop() {
        let (worst, deviation) = max_deviation(points, a, b);
        if deviation > tolerance && worst > a && worst < b {
            // Push the second half first so the first half is processed (and emitted) first.
            stack.push((worst, b));
            stack.push((a, worst));
        } else {
            pieces.push((a, b));
        }
    }
}

/// Index and distance of the pixel of `points[a..=b]` farthest from the chord.
fn max_deviation(points: &[[u16; 2]], a: usize, b: usize) -> (usize, f32) {
    let (ax, ay) = (points[a][0] as i32, points[a][1] as i32);
    let (dx, dy) = (points[b][0] as i32 - ax, points[b][1] as i32 - ay);
    let norm = ((dx * dx + dy * dy) as f32).sqrt();
    let mut worst = a;
    let mut worst_d = 0i32;
    if dx == 0 && dy == 0 {
        // Closed curve: farthest from the common endpoint.
        for (i, p) in points.iter().enumerate().take(b + 1).skip(a) {
            let (px, py) = (p[0] as i32 - ax, p[1] as i32 - ay);
            let d = px * px + py * py;
            if d > worst_d {
                worst_d = d;
                worst = i;
            }
        }
        return (worst, (worst_d as f32).sqrt());
    }
    // |cross| is the distance times the chord length: compare it, divide once.
    for (i, p) in points.iter().enumerate().take(b + 1).skip(a) {
        let (px, py) = (p[0] as i32 - ax, p[1] as i32 - ay);
        let d = (dx * py - dy * px).abs();
        if d > worst_d {
            worst_d = d;
            worst = i;
        }
    }
    (worst, worst_d as f32 / norm)
}

/// Sub-pixel position of every chain pixel: the vertex of the parabola through the gradient
/// magnitudes of the pixel and its two neighbours along the quantised gradient direction
/// (computed during non-maximum suppression).
fn subpixel_positions(points: &[[u16; 2]], canny: &CannyWorkspace, out: &mut Vec<[f32; 2]>) {
    out.clear();
    let w = canny.width();
    for p in points {
        let (x, y) = (p[0] as usize, p[1] as usize);
        let [dx, dy] = canny.subpixel_shift(y * w + x);
        out.push([x as f32 + dx, y as f32 + dy]);
    }
}

/// Total-least-squares line through `points[a..=b]`: centroid and unit direction.
fn fit_line(points: &[[f32; 2]], a: usize, b: usize) -> ([f32; 2], [f32; 2]) {
    let n = (b - a + 1) as f32;
    let (mut sx, mut sy) = (0.0f32, 0.0f32);
    for p in &points[a..=b] {
        sx += p[0];
        sy += p[1];
    }
    let (mx, my) = (sx / n, sy / n);
    let (mut sxx, mut sxy, mut syy) = (0.0f32, 0.0f32, 0.0f32);
    for p in &points[a..=b] {
        let (x, y) = (p[0] - mx, p[1] - my);
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
    }
    let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    ([mx, my], [theta.cos(), theta.sin()])
}

#[allow(clippy::too_many_arguments)]
fn make_segment(
    points: &[[u16; 2]],
    subpixel: &[[f32; 2]],
    a: usize,
    b: usize,
    chain: u32,
    canny: &CannyWorkspace,
    origin_px: (usize, usize),
    params: &SegmentParams,
) -> Option<Segment> {
    let mut p0 = subpixel[a];
    let mut p1 = subpixel[b];
    // Projecting both endpoints on any line cannot lengthen the piece: a chord already too
    // short is dropped without fitting.
    if ((p1[0] - p0[0]).powi(2) + (p1[1] - p0[1]).powi(2)).sqrt() < params.min_length_px {
        return None;
    }
    if params.refit && b > a + 1 {
        let (c, u) = fit_line(subpixel, a, b);
        let project = |p: [f32; 2]| {
            let t = (p[0] - c[0]) * u[0] + (p[1] - c[1]) * u[1];
            [c[0] + t * u[0], c[1] + t * u[1]]
        };
        p0 = project(p0);
        p1 = project(p1);
    }
    let length = ((p1[0] - p0[0]).powi(2) + (p1[1] - p0[1]).powi(2)).sqrt();
    if length < params.min_length_px {
        return None;
    }
    if p1[1] < p0[1] || (p1[1] == p0[1] && p1[0] < p0[0]) {
        std::mem::swap(&mut p0, &mut p1);
    }
    let (dx, dy) = (p1[0] - p0[0], p1[1] - p0[1]);
    let mut angle = dy.atan2(dx);
    if angle >= std::f32::consts::PI {
        angle -= std::f32::consts::PI;
    }
    let w = canny.width();
    let h = canny.height();
    let (gx, gy) = (canny.gx(), canny.gy());
    // Gradient polarity and contrast from at most ~16 pixels spread along the piece.
    let (mut sgx, mut sgy, mut smag, mut count) = (0i32, 0i32, 0i32, 0i32);
    let stride = ((b - a) / 16).max(1);
    for p in points[a..=b].iter().step_by(stride) {
        let i = p[1] as usize * w + p[0] as usize;
        sgx += gx[i] as i32;
        sgy += gy[i] as i32;
        smag += gx[i].unsigned_abs() as i32 + gy[i].unsigned_abs() as i32;
        count += 1;
    }
    let cross = dx * sgy as f32 - dy * sgx as f32;
    let polarity = if cross >= 0.0 { 1 } else { -1 };
    // Normal pointing to the left of start -> end in image coordinates (y down): (dy, -dx).
    let (nx, ny) = (dy / length, -dx / length);
    let smooth = canny.smoothed();
    let samples = ((length / 4.0) as usize).clamp(2, 8);
    let mut sides = [0.0f32; 2];
    for k in 0..samples {
        let t = (k as f32 + 0.5) / samples as f32;
        let (px, py) = (p0[0] + t * dx, p0[1] + t * dy);
        for (side, sign) in [(0usize, 1.0f32), (1, -1.0)] {
            let sx = (px + sign * params.side_offset_px * nx + 0.5).max(0.0) as usize;
            let sy = (py + sign * params.side_offset_px * ny + 0.5).max(0.0) as usize;
            let (sx, sy) = (sx.min(w - 1), sy.min(h - 1));
            sides[side] += smooth[sy * w + sx] as f32;
        }
    }
    let (ox, oy) = (origin_px.0 as f32, origin_px.1 as f32);
    Some(Segment {
        start: [p0[0] + ox, p0[1] + oy],
        end: [p1[0] + ox, p1[1] + oy],
        length_px: length,
        angle_rad: angle,
        polarity,
        contrast: smag as f32 / count as f32,
        side_intensity: [sides[0] / samples as f32, sides[1] / samples as f32],
        chain,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::canny::CannyParams;
    use crate::gray::GrayView;

    #[test]
    fn chains_too_small_for_a_segment_are_recognised_and_long_ones_kept() {
        let params = SegmentParams::default();
        // A closed ring of 6 x 6 pixels: diagonal 7.1 px + 1.4 px of sub-pixel shifts < 10 px.
        let mut ring: Vec<[u16; 2]> = (0..6).map(|x| [x + 3, 3]).collect();
        ring.extend((1..6).map(|y| [8, y + 3]));
        ring.extend((0..5).rev().map(|x| [x + 3, 8]));
        assert!(!can_reach(&ring, &params));
        // 9 px of straight chain can still give a 10 px segment once shifted by sub-pixels.
        let line: Vec<[u16; 2]> = (0..10).map(|x| [x + 3, 3 + x / 3]).collect();
        assert!(can_reach(&line, &params));
    }

    #[test]
    fn an_l_shaped_chain_splits_at_the_corner() {
        let mut points: Vec<[u16; 2]> = (0..20).map(|x| [x + 5, 5]).collect();
        points.extend((1..15).map(|y| [24, 5 + y]));
        let mut stack = Vec::new();
        let mut pieces = Vec::new();
        split_chain(&points, 1.0, &mut stack, &mut pieces);
        assert_eq!(pieces, vec![(0, 19), (19, points.len() - 1)]);
    }

    #[test]
    fn a_straight_chain_is_one_piece_and_refit_recovers_the_line() {
        // Pixels of the line y = 0.25 x + 3 (rounded).
        let points: Vec<[u16; 2]> = (0..40)
            .map(|x| [x as u16 + 2, (0.25 * x as f32 + 3.0).round() as u16])
            .collect();
        let mut stack = Vec::new();
        let mut pieces = Vec::new();
        split_chain(&points, 1.0, &mut stack, &mut pieces);
        assert_eq!(pieces.len(), 1);
        let sub: Vec<[f32; 2]> = points.iter().map(|p| [p[0] as f32, p[1] as f32]).collect();
        let (_, u) = fit_line(&sub, 0, 39);
        assert!((u[1] / u[0] - 0.25).abs() < 0.02);
    }

    #[test]
    fn a_dark_to_bright_vertical_step_gives_a_vertical_segment_with_polarity() {
        let (w, h) = (40, 40);
        let mut data = vec![50u8; w * h];
        for y in 0..h {
            for x in 20..w {
                data[y * w + x] = 180;
            }
        }
        let view = GrayView::new(&data, w, h).unwrap();
        let mut canny = CannyWorkspace::new();
        canny.detect(&view, &CannyParams::default()).unwrap();
        let mut chains = Chains::new();
        chains.link(canny.edges(), w, h, 5);
        let mut ws = SegmentWorkspace::new();
        let mut segs = Vec::new();
        ws.extract(
            &chains,
            &canny,
            (100, 7),
            &SegmentParams::default(),
            &mut segs,
        );
        assert_eq!(segs.len(), 1);
        let s = segs[0];
        assert!((s.angle_rad - std::f32::consts::FRAC_PI_2).abs() < 0.05);
        assert!(s.start[1] < s.end[1]);
        assert!(s.start[0] > 118.0 && s.start[0] < 121.0, "{s:?}");
        // Direction points down (+y); brighter side (+x) is on the left in image coordinates
        // when looking along +y with y down? The polarity only has to be consistent.
        let mirrored: Vec<u8> = data.iter().map(|&v| 230 - v).collect();
        let view2 = GrayView::new(&mirrored, w, h).unwrap();
        canny.detect(&view2, &CannyParams::default()).unwrap();
        chains.link(canny.edges(), w, h, 5);
        let mut segs2 = Vec::new();
        ws.extract(
            &chains,
            &canny,
            (0, 0),
            &SegmentParams::default(),
            &mut segs2,
        );
        assert_eq!(segs2.len(), 1);
        assert_eq!(segs2[0].polarity, -s.polarity);
        assert!(s.side_intensity[0] < 60.0 || s.side_intensity[1] < 60.0);
        assert!((s.side_intensity[0] - s.side_intensity[1]).abs() > 100.0);
    }
}
