//! Photometric evidence: the smoothed images a pair's segments were extracted from, and how
//! alike they look beside the edge once the right one is shifted by the pair's disparity.

use super::pairs::Candidate;
use crate::segments::Segment;

/// A smoothed image (or window of one) that segments were extracted from.
#[derive(Debug, Clone, Copy)]
pub struct ImagePatch<'a> {
    /// Row-major pixels.
    pub data: &'a [u8],
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Top-left corner in the frame, pixels.
    pub origin_px: (usize, usize),
}

impl<'a> ImagePatch<'a> {
    /// The row nearest to frame row `y` (rounded); `None` outside.
    fn row(&self, y: f32) -> Option<PatchRow<'a>> {
        let yl = (y - self.origin_px.1 as f32).round();
        if yl < 0.0 || yl >= self.height as f32 {
            return None;
        }
        let start = yl as usize * self.width;
        Some(PatchRow {
            pixels: &self.data[start..start + self.width],
            origin_x: self.origin_px.0 as f32,
            x_limit: self.width.saturating_sub(1) as f32,
        })
    }
}

/// One row of an [`ImagePatch`].
#[derive(Debug, Clone, Copy)]
struct PatchRow<'a> {
    pixels: &'a [u8],
    /// Frame column of the first pixel.
    origin_x: f32,
    /// Columns at or right of this (relative to the patch) cannot be interpolated.
    x_limit: f32,
}

impl PatchRow<'_> {
    /// Intensity at frame column `x` (interpolated linearly); `None` outside.
    fn sample(&self, x: f32) -> Option<f32> {
        let xl = x - self.origin_x;
        if xl < 0.0 || xl >= self.x_limit {
            return None;
        }
        let x0 = xl as usize;
        let f = xl - x0 as f32;
        let a = self.pixels[x0] as f32;
        let b = self.pixels[x0 + 1] as f32;
        Some(a + f * (b - a))
    }
}

/// The smoothed left and right images of a pair.
#[derive(Debug, Clone, Copy)]
pub struct StereoImages<'a> {
    /// Left image.
    pub left: ImagePatch<'a>,
    /// Right image.
    pub right: ImagePatch<'a>,
}

/// Photometric error of a candidate (see
/// [`MatchParams::max_photometric_error`](super::params::MatchParams::max_photometric_error)
/// and [`MatchParams::photometric_sampling_insensitive`](super::params::MatchParams::photometric_sampling_insensitive)).
pub(super) fn photometric_error(
    l: &Segment,
    c: &Candidate,
    images: &StereoImages<'_>,
    sampling_insensitive: bool,
) -> f32 {
    photometric_error_within(l, c, images, sampling_insensitive, f32::INFINITY)
}

/// As [`photometric_error`], but it stops as soon as the error must exceed `limit` and then
/// returns a lower bound of it (above `limit`): the sums only grow, and each side's mean is
/// at least its sum over the most samples it can have.
pub(super) fn photometric_error_within(
    l: &Segment,
    c: &Candidate,
    images: &StereoImages<'_>,
    sampling_insensitive: bool,
    limit: f32,
) -> f32 {
    const SAMPLES: usize = 12;
    const MOST_PER_SIDE: f32 = (SAMPLES * 4) as f32;
    let mut sums = [0.0f32; 2];
    let mut counts = [0u32; 2];
    for k in 0..SAMPLES {
        let t = (k as f32 + 0.5) / SAMPLES as f32;
        let x = l.start[0] + t * (l.end[0] - l.start[0]);
        let y = l.start[1] + t * (l.end[1] - l.start[1]);
        let d = c.disparity_at(t);
        // Both images are sampled on the row nearest to `y`.
        let (Some(left_row), Some(right_row)) = (images.left.row(y), images.right.row(y)) else {
            continue;
        };
        for (side, offsets) in [
            (0usize, [-4.0f32, -3.0, -2.0, -1.0]),
            (1, [1.0, 2.0, 3.0, 4.0]),
        ] {
            for o in offsets {
                let (xl, xr) = (x + o, x - d + o);
                if let (Some(a), Some(b)) = (left_row.sample(xl), right_row.sample(xr)) {
                    sums[side] += if sampling_insensitive {
                        distance_to_range(a, &right_row, xr, b)
                            .min(distance_to_range(b, &left_row, xl, a))
                    } else {
                        (a - b).abs()
                    };
                    counts[side] += 1;
                }
            }
        }
        let at_least = sums[0].min(sums[1]) / MOST_PER_SIDE;
        if at_least > limit {
            return at_least;
        }
    }
    let mut best = f32::INFINITY;
    for side in 0..2 {
        if counts[side] >= (SAMPLES * 2) as u32 {
            best = best.min(sums[side] / counts[side] as f32);
        }
    }
    best
}

/// How far `value` lies outside the range of `row`'s intensities within half a pixel of `x`
/// (where the row reads `at_x`): 0 inside it.
fn distance_to_range(value: f32, row: &PatchRow<'_>, x: f32, at_x: f32) -> f32 {
    let (mut lo, mut hi) = (at_x, at_x);
    for v in [row.sample(x - 0.5), row.sample(x + 0.5)]
        .into_iter()
        .flatten()
    {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    (lo - value).max(value - hi).max(0.0)
}
