//! The matcher's workspace: its reusable buffers, and the run of the stages from candidate
//! pairs to validated matches.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use super::evidence::MatchEvidence;
use super::geometry::Extent;
use super::pairs::{Candidate, Neighbour, NONE};
use super::params::MatchParams;
use super::photometric::StereoImages;
use crate::segments::Segment;

/// An accepted correspondence between a left and a right segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentMatch {
    /// Index into the left segments.
    pub left: u32,
    /// Index into the right segments.
    pub right: u32,
    /// Disparity at the left segment's `start` and `end`, pixels (`x_left - x_right`).
    pub disparity_px: [f32; 2],
    /// Number of neighbouring left segments with a continuity-compatible candidate.
    pub support: u32,
    /// Whether the pair met the tight prediction constraints.
    pub predicted: bool,
    /// Whether the left segment is nearly horizontal (matched, but not back-projected).
    pub nearly_horizontal: bool,
    /// What speaks for and against the match (default for nearly horizontal matches).
    pub evidence: MatchEvidence,
}

/// Reusable buffers of the matcher.
#[derive(Debug, Default, Clone)]
pub struct MatchWorkspace {
    pub(super) right_order: Vec<u32>,
    /// The first constraints of each right segment, in `right_order`.
    pub(super) right_keys: Vec<RightKey>,
    /// Row and column extents of each left segment, in `left_order`.
    pub(super) left_extents: Vec<Extent>,
    pub(super) candidates: Vec<Candidate>,
    pub(super) candidate_start: Vec<u32>,
    pub(super) neighbours: Vec<Neighbour>,
    pub(super) neighbour_start: Vec<u32>,
    pub(super) neighbour_pairs: Vec<(u32, Neighbour)>,
    pub(super) left_order: Vec<u32>,
    pub(super) best_for_left: Vec<u32>,
    pub(super) by_right_start: Vec<u32>,
    pub(super) by_right: Vec<u32>,
    pub(super) right_fill: Vec<u32>,
    pub(super) right_taken: Vec<[[f32; 2]; MAX_PIECES_PER_RIGHT]>,
    pub(super) right_taken_len: Vec<u8>,
    /// Columns of each right segment taken by nearly horizontal matches.
    pub(super) right_columns: Vec<[[f32; 2]; MAX_PIECES_PER_RIGHT]>,
    pub(super) right_columns_len: Vec<u8>,
    pub(super) left_used: Vec<bool>,
    pub(super) accepted_candidate: Vec<u32>,
    pub(super) heap: BinaryHeap<Queued>,
    /// Nearly horizontal proposals of a round: candidate, measured disparity, distance to the
    /// neighbour giving the context.
    pub(super) proposals: Vec<(u32, f32, f32)>,
    /// Pairs of collinear right fragments: the virtual segment joining them and the two
    /// pieces (the longer first) with their rows; sorted by the virtual segment's upper row.
    pub(super) fragments: Vec<JoinedFragments>,
    /// Pairs meeting only the completion limits, grouped by left segment, with their
    /// photometric error when known (`NaN` otherwise).
    pub(super) loose: Vec<(Candidate, f32)>,
    pub(super) loose_start: Vec<u32>,
    /// Positions gathered by a search before its exact tests: in `right_keys`, the right
    /// segments passing the candidate search's first tests; in `left_order`, the segments
    /// whose boxes come within the neighbourhood radius.
    pub(super) key_survivors: Vec<u32>,
    /// Left segments matched by completion.
    pub(super) completed: Vec<bool>,
    /// Completion: the matched segments (extent, index, accepted candidate) by upper row, and
    /// the running maximum of their lower rows.
    pub(super) matched_sorted: Vec<(Extent, u32, u32)>,
    pub(super) matched_reach: Vec<f32>,
    /// Matched neighbours of the segment being completed.
    pub(super) matched_near: Vec<(Neighbour, u32)>,
    /// Completion: matched neighbours near an end of the segment being completed (end, their
    /// disparity there, distance).
    pub(super) end_context: Vec<(u8, f32, f32)>,
    /// Completion proposals: candidate, agreeing neighbours.
    pub(super) completion_proposals: Vec<(Candidate, u32)>,
    /// Evidence of each left segment's match (see the checks).
    pub(super) evidence: Vec<MatchEvidence>,
}

/// A candidate waiting in propagation's queue, popped best first (support, then cost, then
/// position).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Queued {
    pub(super) support: u32,
    pub(super) cost: f32,
    pub(super) position: [f32; 3],
    pub(super) candidate: u32,
}

impl Eq for Queued {}

impl Ord for Queued {
    fn cmp(&self, other: &Self) -> Ordering {
        self.support
            .cmp(&other.support)
            .then_with(|| other.cost.total_cmp(&self.cost))
            .then_with(|| other.position[0].total_cmp(&self.position[0]))
            .then_with(|| other.position[1].total_cmp(&self.position[1]))
            .then_with(|| other.position[2].total_cmp(&self.position[2]))
            .then_with(|| other.candidate.cmp(&self.candidate))
    }
}

impl PartialOrd for Queued {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// What the candidate search tests first of a right segment, stored contiguously.
#[derive(Debug, Clone, Copy)]
pub(super) struct RightKey {
    pub(super) extent: Extent,
    pub(super) polarity: i8,
    pub(super) index: u32,
}

/// Two right segments that are fragments of one straight edge.
#[derive(Debug, Clone, Copy)]
pub(super) struct JoinedFragments {
    /// The segment joining the outer endpoints.
    pub(super) joined: Segment,
    /// The longer piece and its rows.
    pub(super) main: (u32, [f32; 2]),
    /// The shorter piece and its rows.
    pub(super) other: (u32, [f32; 2]),
}

/// Rounds of nearly horizontal matching (the second lets nearly horizontal matches vouch for
/// their nearly horizontal neighbours).
const HORIZONTAL_ROUNDS: usize = 2;

/// How many left fragments may share one right segment (on disjoint rows).
pub(super) const MAX_PIECES_PER_RIGHT: usize = 4;

impl MatchWorkspace {
    /// An empty workspace.
    pub fn new() -> Self {
        Self::default()
    }

    /// Matches `left` against `right` segments, writing the accepted matches to `out`
    /// (cleared first), sorted by left index.
    ///
    /// With `images`, a match is also validated photometrically (see
    /// [`MatchParams::max_photometric_error`]).
    pub fn match_segments(
        &mut self,
        left: &[Segment],
        right: &[Segment],
        images: Option<&StereoImages<'_>>,
        params: &MatchParams,
        out: &mut Vec<SegmentMatch>,
    ) {
        out.clear();
        self.build_candidates(left, right, images, params);
        self.build_neighbours(left, params);
        self.compute_support(params);
        self.best_candidates(left.len(), right.len());
        self.grow(left.len(), right.len(), params);
        if params.completion {
            for _ in 0..params.completion_rounds {
                if !self.complete(left, images, params) {
                    break;
                }
            }
        }
        self.check_matches(left.len(), params);
        if params.match_horizontal {
            for _ in 0..HORIZONTAL_ROUNDS {
                if !self.match_horizontal_round(left, right, params) {
                    break;
                }
            }
        }
        let flat = params.single_disparity_angle_deg.to_radians();
        for (i, &c) in self.accepted_candidate.iter().enumerate() {
            if c == NONE {
                continue;
            }
            let cand = self.candidates[c as usize];
            debug_assert_eq!(cand.left as usize, i);
            let mut disparity = cand.disparity;
            if !cand.horizontal && left[i].is_nearly_horizontal(flat) {
                // The change along an oblique segment is not measurable: its mean.
                disparity = [0.5 * (disparity[0] + disparity[1]); 2];
            }
            out.push(SegmentMatch {
                left: cand.left,
                right: cand.right,
                disparity_px: disparity,
                support: cand.support,
                predicted: cand.tight,
                nearly_horizontal: cand.horizontal,
                evidence: self.evidence[i],
            });
        }
    }

    /// The positions in `candidates` of left segment `left`'s candidates.
    pub(super) fn candidates_of(&self, left: u32) -> std::ops::Range<usize> {
        self.candidate_start[left as usize] as usize
            ..self.candidate_start[left as usize + 1] as usize
    }

    /// The positions in `neighbours` of left segment `left`'s neighbours.
    pub(super) fn neighbours_of(&self, left: u32) -> std::ops::Range<usize> {
        self.neighbour_start[left as usize] as usize
            ..self.neighbour_start[left as usize + 1] as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matching::test_support::scene;

    #[test]
    fn a_plane_of_segments_is_matched_exactly() {
        let (left, right) = scene(23.0);
        let mut ws = MatchWorkspace::new();
        let mut out = Vec::new();
        ws.match_segments(&left, &right, None, &MatchParams::default(), &mut out);
        assert_eq!(out.len(), left.len());
        for m in &out {
            assert_eq!(m.left, m.right);
            assert!((m.disparity_px[0] - 23.0).abs() < 1e-3);
            assert!((m.disparity_px[1] - 23.0).abs() < 1e-3);
        }
    }

    #[test]
    fn disparity_outside_the_range_is_not_matched() {
        let (left, right) = scene(80.0);
        let mut ws = MatchWorkspace::new();
        let mut out = Vec::new();
        ws.match_segments(&left, &right, None, &MatchParams::default(), &mut out);
        assert!(out.is_empty());
    }
}
