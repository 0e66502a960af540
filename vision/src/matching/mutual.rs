//! Left-right consistency by a second run ([`MatchParams::mutual_check`]): the right segments
//! are matched to the left ones by the same algorithm, and a match is kept only when both
//! directions agree.
//!
//! The second run is the first one on the pair mirrored: the right image, flipped
//! left-to-right, becomes the reference and the flipped left image the other view, so that
//! disparities stay positive and every constraint (the asymmetric ones too, such as a
//! fragment of a longer edge or an edge broken in two in the other view) applies with the
//! roles of the images exchanged. A segment is mirrored by `x -> X - x` about a column `X`
//! right of both images: its orientation becomes `pi - angle`, its polarity and its two sides
//! exchange. The smoothed images are mirrored into buffers kept between runs.
//!
//! A match `(left i, right j)` that is not nearly horizontal is kept when the second run
//! matched `j` to `i`, or to another left segment with a disparity within
//! [`MatchParams::mutual_tolerance_px`] of the match's at the middle of their common rows
//! (`i` is then a fragment of the edge the second run matched whole). Nearly horizontal
//! matches take their disparity from their neighbours and are kept.

use super::pairs::NONE;
use super::params::MatchParams;
use super::photometric::{ImagePatch, StereoImages};
use super::workspace::{MatchWorkspace, SegmentMatch};
use crate::segments::Segment;

/// The second run's workspace and buffers, kept between runs.
#[derive(Debug, Default, Clone)]
pub struct MutualCheck {
    reverse: MatchWorkspace,
    /// Mirrored right segments (the second run's reference) and left segments.
    mirrored: [Vec<Segment>; 2],
    /// Mirrored smoothed right and left images.
    images: [Vec<u8>; 2],
    reverse_matches: Vec<SegmentMatch>,
    /// For each right segment, its match in the second run (index into `reverse_matches`).
    match_of_right: Vec<u32>,
}

impl MutualCheck {
    /// An empty check (its buffers grow during the first runs).
    pub fn new() -> Self {
        Self::default()
    }

    /// Runs the second matching of `right` to `left` and drops from `matches` those it does
    /// not confirm (see the module documentation). `matches` are the first run's on the same
    /// segments and images.
    pub fn filter(
        &mut self,
        left: &[Segment],
        right: &[Segment],
        images: Option<&StereoImages<'_>>,
        params: &MatchParams,
        matches: &mut Vec<SegmentMatch>,
    ) {
        // The mirror column: right of every segment and of both images.
        let mut axis = left
            .iter()
            .chain(right)
            .fold(0.0f32, |m, s| m.max(s.start[0]).max(s.end[0]))
            .ceil();
        if let Some(im) = images {
            for p in [&im.left, &im.right] {
                axis = axis.max((p.origin_px.0 + p.width) as f32);
            }
        }
        let [mirrored_right, mirrored_left] = &mut self.mirrored;
        mirror_segments(right, axis, mirrored_right);
        mirror_segments(left, axis, mirrored_left);
        let mirrored_images = images.map(|im| {
            let [right_data, left_data] = &mut self.images;
            StereoImages {
                left: mirror_patch(&im.right, axis, right_data),
                right: mirror_patch(&im.left, axis, left_data),
            }
        });
        // Nearly horizontal matches are not checked: the second run need not make them.
        let reverse_params = MatchParams {
            match_horizontal: false,
            ..*params
        };
        self.reverse.match_segments(
            &self.mirrored[0],
            &self.mirrored[1],
            mirrored_images.as_ref(),
            &reverse_params,
            &mut self.reverse_matches,
        );
        self.match_of_right.clear();
        self.match_of_right.resize(right.len(), NONE);
        for (k, m) in self.reverse_matches.iter().enumerate() {
            self.match_of_right[m.left as usize] = k as u32;
        }
        matches.retain(|m| {
            if m.nearly_horizontal {
                return true;
            }
            let k = self.match_of_right[m.right as usize];
            if k == NONE {
                return false;
            }
            let back = &self.reverse_matches[k as usize];
            back.right == m.left
                || agree(
                    &left[m.left as usize],
                    m.disparity_px,
                    &right[m.right as usize],
                    back.disparity_px,
                    params.mutual_tolerance_px,
                )
        });
    }
}

/// Whether a match of left segment `l` (disparities at its endpoints `dl`) and the second
/// run's match of right segment `r` (disparities at its endpoints `dr`) agree at the middle
/// of their common rows (of `l`'s rows when they share none).
fn agree(l: &Segment, dl: [f32; 2], r: &Segment, dr: [f32; 2], tolerance: f32) -> bool {
    let (top, bottom) = (l.start[1].max(r.start[1]), l.end[1].min(r.end[1]));
    let y = if top <= bottom {
        0.5 * (top + bottom)
    } else {
        0.5 * (l.start[1] + l.end[1])
    };
    let along = |s: &Segment, d: [f32; 2]| {
        let h = s.end[1] - s.start[1];
        if h.abs() < 1e-3 {
            0.5 * (d[0] + d[1])
        } else {
            d[0] + (y - s.start[1]) / h * (d[1] - d[0])
        }
    };
    (along(l, dl) - along(r, dr)).abs() <= tolerance
}

/// `segments` mirrored about column `axis` (into `out`, cleared first).
fn mirror_segments(segments: &[Segment], axis: f32, out: &mut Vec<Segment>) {
    out.clear();
    out.extend(segments.iter().map(|s| Segment {
        start: [axis - s.start[0], s.start[1]],
        end: [axis - s.end[0], s.end[1]],
        angle_rad: if s.angle_rad > 0.0 {
            std::f32::consts::PI - s.angle_rad
        } else {
            0.0
        },
        polarity: -s.polarity,
        side_intensity: [s.side_intensity[1], s.side_intensity[0]],
        ..*s
    }));
}

/// `patch` mirrored about column `axis`, its pixels written to `data`.
fn mirror_patch<'a>(patch: &ImagePatch<'_>, axis: f32, data: &'a mut Vec<u8>) -> ImagePatch<'a> {
    data.clear();
    for row in patch.data.chunks_exact(patch.width).take(patch.height) {
        data.extend(row.iter().rev());
    }
    // The last column `ox + w - 1` lands on `axis - (ox + w - 1)`.
    let origin_x = (axis as usize + 1).saturating_sub(patch.origin_px.0 + patch.width);
    ImagePatch {
        data,
        width: patch.width,
        height: patch.height,
        origin_px: (origin_x, patch.origin_px.1),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matching::test_support::scene;

    #[test]
    fn a_plane_of_segments_is_confirmed_by_the_second_run() {
        let (left, right) = scene(23.0);
        let mut ws = MatchWorkspace::new();
        let mut matches = Vec::new();
        let params = MatchParams::default();
        ws.match_segments(&left, &right, None, &params, &mut matches);
        let before = matches.len();
        assert!(before > 0);
        MutualCheck::new().filter(&left, &right, None, &params, &mut matches);
        assert_eq!(matches.len(), before);
    }

    #[test]
    fn a_match_the_second_run_gives_to_another_left_segment_is_dropped() {
        let (left, right) = scene(23.0);
        let mut ws = MatchWorkspace::new();
        let mut matches = Vec::new();
        let params = MatchParams::default();
        ws.match_segments(&left, &right, None, &params, &mut matches);
        // Claim that left 0 matched the right segment of left 1 with a disparity off by 5 px.
        let victim = matches.iter().position(|m| m.left == 0).unwrap();
        let other = matches.iter().find(|m| m.left == 1).unwrap().right;
        matches[victim].right = other;
        matches[victim].disparity_px = [28.0, 28.0];
        let before = matches.len();
        MutualCheck::new().filter(&left, &right, None, &params, &mut matches);
        assert_eq!(matches.len(), before - 1);
        assert!(matches.iter().all(|m| m.left != 0));
    }

    #[test]
    fn mirroring_twice_gives_the_segments_back() {
        let (left, _) = scene(10.0);
        let (mut once, mut twice) = (Vec::new(), Vec::new());
        mirror_segments(&left, 500.0, &mut once);
        mirror_segments(&once, 500.0, &mut twice);
        for (a, b) in left.iter().zip(&twice) {
            assert_eq!(a.start, b.start);
            assert_eq!(a.polarity, b.polarity);
            assert!((a.angle_rad - b.angle_rad).abs() < 1e-5);
        }
    }

    #[test]
    fn a_mirrored_patch_reads_the_same_pixels_at_mirrored_columns() {
        let data: Vec<u8> = (0..12).collect();
        let patch = ImagePatch {
            data: &data,
            width: 4,
            height: 3,
            origin_px: (10, 5),
        };
        let mut buf = Vec::new();
        let m = mirror_patch(&patch, 20.0, &mut buf);
        // Frame column 10 (value 0 on row 5) lands on column 10 of the mirror: 20 - 10.
        assert_eq!(m.origin_px, (7, 5));
        // Column 13 -> 7 (first of the mirrored row), column 10 -> 10 (last).
        assert_eq!(m.data[0], 3);
        assert_eq!(m.data[3], 0);
    }
}
