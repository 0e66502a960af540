//! Segment matching after Ayache: hypothesis prediction, propagation under the continuity
//! constraint, validation (uniqueness and left-right consistency).
//!
//! On rectified images corresponding segments overlap in their row extents (epipolar
//! constraint). A candidate pair `(left i, right j)` must overlap enough in y, have the same
//! gradient polarity, similar contrast and intensities on at least one side, a disparity within
//! the allowed range that changes plausibly along the segment, agree in orientation and length
//! (weak limits), and, when the smoothed images are given, look alike beside the edge once the
//! right image is shifted by the pair's disparity (photometric check).
//!
//! 1. **Prediction**: pairs that also meet the tight orientation and length limits and have
//!    enough support (neighbouring left segments with a continuity-compatible candidate) are
//!    the hypotheses that seed propagation.
//! 2. **Propagation**: from the hypotheses, best first (support, then cost), matches grow to
//!    neighbouring left segments (the closest ones within a radius) whose candidates meet the
//!    continuity constraint: the disparities at the closest points of the two neighbours
//!    differ by at most a tolerance plus a disparity-gradient limit times their distance.
//! 3. **Validation**: uniqueness (a left segment matches once; a right segment is shared only
//!    by left fragments on disjoint rows), left-right consistency (the pair is the best
//!    candidate of its left segment, and no better candidate of another left segment claims the
//!    same rows of its right segment), required support.
//!
//! Nearly horizontal segments lie along epipolar lines and their disparity is only fixed by
//! their unstable endpoints: they are matched only after propagation, from their closest
//! matched neighbour, to a right segment on the same rows that lies on the left one once
//! shifted by the neighbour's disparity and has an endpoint disparity agreeing with it (that
//! endpoint disparity is the match's). This runs in rounds (the second lets nearly horizontal
//! matches vouch for nearly horizontal neighbours), each decided from the matches before it,
//! so that the result does not depend on the order in which matches were found (a local run
//! finds them in another order). They are flagged [`SegmentMatch::nearly_horizontal`] and
//! never back-projected. A piece of a horizontal edge (neither endpoint agreeing with the
//! context) is matched when it lies within 1 px of the shifted line and overlaps the other by
//! half the shorter column extent, its disparity the context's; several nearly horizontal
//! left pieces may share one right segment on disjoint columns.
//!
//! **Completion** (after propagation, before the nearly horizontal rounds): a left segment
//! that propagation left unmatched may take a pair that fails the candidate limits on
//! orientation, length, row overlap, disparity slope or the photometric check (within wider
//! completion limits) when its matched neighbours vouch for it: enough of them agree tightly
//! with its disparity (within 1 px plus 0.1 px per pixel of distance), on both halves of the
//! segment, a matched neighbour near each end agrees with the disparity there, few contradict
//! it, and the disparity changes little along it. Decided from the matches of propagation only
//! (proposals accepted best first where the right rows are free), so independent of the order
//! of the segments.
//!
//! A match's disparity is taken at the left segment's two endpoints: the right segment's line
//! is intersected with the rows of the left endpoints. On a segment within 30 deg of
//! horizontal these intersections are too sensitive to the orientations for the change along
//! it to be measured: its match reports their mean at both ends.
//!
//! A segment may match part of another (Ayache): a left segment lying within the rows of a
//! longer right segment meets a weaker length limit, and an edge broken into two collinear
//! fragments in the right image (a short gap of rows) is matched as one, the disparity taken
//! from the line joining the fragments; the match then uses rows of both right pieces and
//! reports the longer one.
//!
//! Every ranking ends with a tie-break on image position, so that the result does not depend
//! on the order in which segments were extracted (a local run sees them in another order).

use crate::error::VisionError;
use crate::segments::Segment;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Parameters of the matcher. See the module documentation for the stages.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchParams {
    /// Smallest disparity searched, pixels.
    pub disparity_min_px: f32,
    /// Largest disparity searched, pixels.
    pub disparity_max_px: f32,
    /// Segments within this angle of horizontal are "nearly horizontal", degrees.
    pub horizontal_angle_deg: f32,
    /// Row overlap of a pair divided by the shorter row extent must reach this.
    pub min_row_overlap_ratio: f32,
    /// Prediction: maximum orientation difference, degrees.
    pub predict_max_angle_diff_deg: f32,
    /// Prediction: minimum ratio shorter/longer length.
    pub predict_min_length_ratio: f32,
    /// Prediction: minimum length of both segments, pixels.
    pub predict_min_length_px: f32,
    /// Propagation: maximum orientation difference, degrees.
    pub propagate_max_angle_diff_deg: f32,
    /// Propagation: minimum ratio shorter/longer length.
    pub propagate_min_length_ratio: f32,
    /// Left segments closer than this (closest points) are neighbours, pixels.
    pub neighbourhood_radius_px: f32,
    /// At most this many closest neighbours are kept per segment.
    pub max_neighbours: usize,
    /// Continuity: allowed disparity change per pixel of distance between neighbours.
    pub disparity_gradient_limit: f32,
    /// Continuity: allowed disparity change at zero distance, pixels.
    pub disparity_tolerance_px: f32,
    /// Maximum change of disparity along a segment per pixel of its height (a segment on a
    /// plausible surface, and right/left orientations that agree).
    pub max_disparity_slope: f32,
    /// Maximum difference of mean intensity on the better-agreeing side, grey levels.
    pub max_intensity_diff: f32,
    /// Maximum ratio of the two segments' contrasts.
    pub max_contrast_ratio: f32,
    /// Minimum number of neighbours supporting a hypothesis to seed propagation.
    pub min_seed_support: u32,
    /// Minimum number of neighbours supporting a propagated match.
    pub min_support: u32,
    /// Photometric validation: mean absolute difference (grey levels) between the smoothed
    /// left and right images on 4-px strips beside the segment, the right one shifted by the
    /// match's disparity; the better of the two sides of the edge counts (the other may be
    /// occluded).
    pub max_photometric_error: f32,
    /// Photometric validation compares each sample with the range of the other image's
    /// intensities within half a pixel (Birchfield and Tomasi's sampling-insensitive
    /// dissimilarity) instead of with its value at the exact disparity: on dense texture a
    /// sub-pixel disparity error otherwise costs tens of grey levels.
    pub photometric_sampling_insensitive: bool,
    /// Enforce left-right consistency (mutual best candidate) at validation.
    pub left_right_check: bool,
    /// Match nearly horizontal segments during propagation.
    pub match_horizontal: bool,
    /// Nearly horizontal pairs: largest distance of the left midpoint from the right line
    /// shifted by the context disparity, pixels.
    pub horizontal_line_tolerance_px: f32,
    /// Nearly horizontal pairs: largest difference between an endpoint disparity and the
    /// context disparity, pixels.
    pub horizontal_endpoint_tolerance_px: f32,
    /// Propagation: minimum ratio shorter/longer length when the left segment lies within the
    /// rows of a longer right segment (a fragment of its edge).
    pub contained_min_length_ratio: f32,
    /// Also match a left segment to two collinear right segments (one edge broken into two
    /// fragments in the right image), the disparity taken from the line joining them.
    pub join_right_fragments: bool,
    /// Joined fragments: largest row gap between the two pieces, pixels.
    pub max_fragment_gap_px: f32,
    /// Joined fragments: largest orientation difference of the two pieces, degrees.
    pub max_fragment_angle_diff_deg: f32,
    /// Matches of segments within this angle of horizontal (but not nearly horizontal) report
    /// one disparity along them, the mean of their endpoint disparities: on an oblique segment
    /// the right line's intersections with the endpoint rows are too sensitive to its
    /// orientation for the change along it to be measured, degrees.
    pub single_disparity_angle_deg: f32,
    /// Nearly horizontal pairs: minimum ratio shorter/longer length (they are matched from
    /// their neighbours' context, pieces of an edge included).
    pub horizontal_min_length_ratio: f32,
    /// Nearly horizontal pairs without an endpoint agreeing with the context (pieces of an
    /// edge): the fraction of the shorter column extent that must overlap the other once
    /// shifted (above 1: such pairs are not matched).
    pub horizontal_piece_overlap: f32,
    /// Nearly horizontal pieces: largest distance of the left midpoint from the shifted right
    /// line, pixels.
    pub horizontal_piece_line_tolerance_px: f32,
    /// Completion: after propagation, an unmatched left segment may take a pair meeting only
    /// the completion limits below when enough matched neighbours agree with it.
    pub completion: bool,
    /// Completion: rounds (each decided from the matches before it).
    pub completion_rounds: u32,
    /// Completion: matched neighbours (within the neighbourhood radius) that must meet the
    /// continuity constraint with the pair.
    pub completion_min_agreeing: u32,
    /// Completion: largest number of matched neighbours that may contradict the pair, as a
    /// fraction of the agreeing ones.
    pub completion_max_disagreeing_ratio: f32,
    /// Completion: an agreeing neighbour's disparity (at the closest points) differs by at
    /// most this plus [`MatchParams::completion_gradient_limit`] times the distance, pixels.
    pub completion_tolerance_px: f32,
    /// Completion: allowed disparity change per pixel of distance for an agreeing neighbour.
    pub completion_gradient_limit: f32,
    /// Completion: largest disparity change between the two ends of the pair, pixels.
    pub completion_max_disparity_change_px: f32,
    /// Completion: agreeing neighbours must be found near both halves of the left segment.
    pub completion_both_ends: bool,
    /// Completion: the disparity at each end of the pair must agree with the matched
    /// neighbour closest to that end.
    pub completion_end_context: bool,
    /// Completion: neighbours within this distance of an end give its context, pixels.
    pub completion_end_radius_px: f32,
    /// Completion: maximum orientation difference, degrees.
    pub completion_max_angle_diff_deg: f32,
    /// Completion: minimum ratio shorter/longer length.
    pub completion_min_length_ratio: f32,
    /// Completion: maximum change of disparity along a segment per pixel of its height.
    pub completion_max_disparity_slope: f32,
    /// Completion: photometric error limit, grey levels.
    pub completion_max_photometric_error: f32,
    /// Completion: minimum row overlap ratio.
    pub completion_min_row_overlap_ratio: f32,
}

impl Default for MatchParams {
    /// Disparities 0..64 px; 15 deg horizontal band; overlap >= 50 %; prediction within 8 deg and
    /// length ratio >= 0.7 for segments >= 20 px; propagation within 13 deg and ratio >= 0.4
    /// (>= 0.25 for a left segment within the rows of a longer right one); neighbours within
    /// 50 px (the 24 closest); disparity gradient 0.3 px/px + 1.5 px; intensity within 30 grey
    /// levels, contrast ratio <= 2.5; seeds need 2 supporting neighbours, other matches 1;
    /// photometric error <= 7 grey levels; left-right check on; horizontal segments matched;
    /// right fragments joined across gaps of <= 8 rows when within 6 deg of each other; nearly
    /// horizontal pairs within 2 px of the shifted line, an endpoint disparity within 2.5 px of
    /// the context, pieces (length ratio >= 0.25) within 1 px of it overlapping by half; one
    /// disparity for segments within 30 deg of horizontal. Completion on (one round): pairs
    /// within 25 deg, length ratio >= 0.1, row overlap >= 0.2, slope <= 1, photometric error
    /// <= 9 and a disparity change <= 2.5 px along
    /// the segment, taken when >= 2 matched neighbours agree within 1 px + 0.1 px/px on both
    /// halves, a matched neighbour within 25 px of each end agrees, and contradicting ones
    /// (beyond the continuity limit) are at most half the agreeing ones.
    fn default() -> Self {
        Self {
            disparity_min_px: 0.0,
            disparity_max_px: 64.0,
            horizontal_angle_deg: 15.0,
            min_row_overlap_ratio: 0.5,
            predict_max_angle_diff_deg: 8.0,
            predict_min_length_ratio: 0.7,
            predict_min_length_px: 20.0,
            propagate_max_angle_diff_deg: 13.0,
            propagate_min_length_ratio: 0.4,
            neighbourhood_radius_px: 50.0,
            max_neighbours: 24,
            disparity_gradient_limit: 0.3,
            disparity_tolerance_px: 1.5,
            max_disparity_slope: 0.3,
            max_intensity_diff: 30.0,
            max_contrast_ratio: 2.5,
            min_seed_support: 2,
            min_support: 1,
            max_photometric_error: 7.0,
            photometric_sampling_insensitive: false,
            left_right_check: true,
            match_horizontal: true,
            contained_min_length_ratio: 0.25,
            horizontal_line_tolerance_px: 2.0,
            horizontal_endpoint_tolerance_px: 2.5,
            join_right_fragments: true,
            max_fragment_gap_px: 8.0,
            max_fragment_angle_diff_deg: 6.0,
            single_disparity_angle_deg: 30.0,
            horizontal_min_length_ratio: 0.25,
            horizontal_piece_overlap: 0.5,
            horizontal_piece_line_tolerance_px: 1.0,
            completion: true,
            completion_rounds: 1,
            completion_min_agreeing: 2,
            completion_max_disagreeing_ratio: 0.5,
            completion_tolerance_px: 1.0,
            completion_gradient_limit: 0.1,
            completion_max_disparity_change_px: 2.5,
            completion_both_ends: true,
            completion_end_context: true,
            completion_end_radius_px: 25.0,
            completion_max_angle_diff_deg: 25.0,
            completion_min_length_ratio: 0.1,
            completion_max_disparity_slope: 1.0,
            completion_max_photometric_error: 9.0,
            completion_min_row_overlap_ratio: 0.2,
        }
    }
}

impl MatchParams {
    /// Checks the parameter ranges.
    pub fn validate(&self) -> Result<(), VisionError> {
        let checks: [(&'static str, f32, bool, &'static str); 9] = [
            (
                "matching.disparity_max_px",
                self.disparity_max_px,
                self.disparity_max_px > self.disparity_min_px && self.disparity_max_px <= 4096.0,
                "disparity_min_px < value <= 4096",
            ),
            (
                "matching.horizontal_angle_deg",
                self.horizontal_angle_deg,
                (0.0..=45.0).contains(&self.horizontal_angle_deg),
                "0..=45",
            ),
            (
                "matching.min_row_overlap_ratio",
                self.min_row_overlap_ratio,
                (0.0..=1.0).contains(&self.min_row_overlap_ratio),
                "0..=1",
            ),
            (
                "matching.neighbourhood_radius_px",
                self.neighbourhood_radius_px,
                (0.0..=500.0).contains(&self.neighbourhood_radius_px),
                "0..=500",
            ),
            (
                "matching.propagate_max_angle_diff_deg",
                self.propagate_max_angle_diff_deg,
                self.propagate_max_angle_diff_deg >= self.predict_max_angle_diff_deg
                    && self.propagate_max_angle_diff_deg <= 90.0,
                "predict_max_angle_diff_deg..=90",
            ),
            (
                "matching.max_contrast_ratio",
                self.max_contrast_ratio,
                self.max_contrast_ratio >= 1.0,
                ">= 1",
            ),
            (
                "matching.completion_max_angle_diff_deg",
                self.completion_max_angle_diff_deg,
                self.completion_max_angle_diff_deg >= self.propagate_max_angle_diff_deg
                    && self.completion_max_angle_diff_deg <= 90.0,
                "propagate_max_angle_diff_deg..=90",
            ),
            (
                "matching.completion_min_length_ratio",
                self.completion_min_length_ratio,
                (0.0..=1.0).contains(&self.completion_min_length_ratio),
                "0..=1",
            ),
            (
                "matching.completion_min_row_overlap_ratio",
                self.completion_min_row_overlap_ratio,
                (0.0..=1.0).contains(&self.completion_min_row_overlap_ratio),
                "0..=1",
            ),
        ];
        for (name, value, ok, allowed) in checks {
            if !ok {
                return Err(VisionError::Parameter {
                    name,
                    value: value as f64,
                    allowed,
                });
            }
        }
        Ok(())
    }
}

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
}

/// The weak constraint a pair fails (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum PairConstraint {
    /// Opposite gradient polarity.
    Polarity,
    /// Disparity outside the searched range.
    DisparityRange,
    /// Contrasts too different.
    Contrast,
    /// Intensities differ on both sides.
    Intensity,
    /// Orientations too different.
    Orientation,
    /// Lengths too different.
    Length,
    /// Nearly horizontal pair on different rows.
    HorizontalRows,
    /// Too little row overlap.
    RowOverlap,
    /// Disparity changes too fast along the segment.
    DisparitySlope,
}

/// How the matcher treated one pair of segments (a diagnostic, see
/// [`MatchWorkspace::diagnose_pair`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PairDiagnosis {
    /// The pair fails a weak constraint.
    Constraint(PairConstraint),
    /// The pair fails the photometric check with this error, grey levels.
    Photometric(f32),
    /// The pair meets the weak constraints and no photometric check applies to it (a nearly
    /// horizontal pair, or no images), yet it is not a candidate.
    Unlisted,
    /// The pair is a candidate (the right segment alone or as a joined fragment).
    Candidate(CandidateDiagnosis),
}

/// A candidate's state at the end of the last [`MatchWorkspace::match_segments`] run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CandidateDiagnosis {
    /// Disparity at the left segment's endpoints, pixels.
    pub disparity_px: [f32; 2],
    /// Supporting neighbours.
    pub support: u32,
    /// Meets the prediction constraints.
    pub tight: bool,
    /// Nearly horizontal left segment.
    pub horizontal: bool,
    /// The best candidate of its left segment.
    pub best_of_left: bool,
    /// Passes the left-right consistency check.
    pub consistent: bool,
    /// Its right rows were still free at the end.
    pub right_free: bool,
    /// Some matched neighbour is continuous with it (propagation could reach it).
    pub reached: bool,
    /// The accepted match of its left segment.
    pub accepted: bool,
    /// Number of candidates of its left segment.
    pub rivals: u32,
}

/// A candidate pair.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    left: u32,
    right: u32,
    /// Disparity at the left start and end rows.
    disparity: [f32; 2],
    cost: f32,
    tight: bool,
    horizontal: bool,
    support: u32,
    /// Rows of the right segment the match uses (all rows for nearly horizontal pairs).
    rows: [f32; 2],
    /// Second right piece when the right side is two collinear fragments of one edge
    /// ([`NONE`] otherwise), and the rows of it the match uses.
    right2: u32,
    rows2: [f32; 2],
    /// Left start row, left start column, right start column: the final tie-break.
    position: [f32; 3],
}

impl Candidate {
    /// Disparity at parameter `t` in `[0, 1]` along the left segment.
    fn disparity_at(&self, t: f32) -> f32 {
        self.disparity[0] + t * (self.disparity[1] - self.disparity[0])
    }

    /// Ranking: more support, then lower cost, then position (independent of list order).
    fn better_than(&self, other: &Candidate) -> bool {
        self.rank_cmp(other) == Ordering::Greater
    }

    fn rank_cmp(&self, other: &Candidate) -> Ordering {
        self.support
            .cmp(&other.support)
            .then_with(|| other.cost.total_cmp(&self.cost))
            .then_with(|| other.position[0].total_cmp(&self.position[0]))
            .then_with(|| other.position[1].total_cmp(&self.position[1]))
            .then_with(|| other.position[2].total_cmp(&self.position[2]))
    }
}

/// Two neighbouring left segments and the parameters of their closest points.
#[derive(Debug, Clone, Copy)]
struct Neighbour {
    other: u32,
    /// Start point of the other segment (order-independent tie-break).
    other_start: [f32; 2],
    t_self: f32,
    t_other: f32,
    distance: f32,
}

impl Neighbour {
    /// Segment `b` (index `j`) as a neighbour of `a`, when their closest points are within
    /// `radius`.
    fn within(a: &Segment, j: u32, b: &Segment, radius: f32) -> Option<Self> {
        let (distance, t_self, t_other) = segment_distance(a, b);
        (distance <= radius).then_some(Neighbour {
            other: j,
            other_start: b.start,
            t_self,
            t_other,
            distance,
        })
    }

    /// The same pair seen from the other segment: `a` (index `i`) as its neighbour.
    fn seen_from_other(&self, i: u32, a: &Segment) -> Self {
        Neighbour {
            other: i,
            other_start: a.start,
            t_self: self.t_other,
            t_other: self.t_self,
            distance: self.distance,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Queued {
    support: u32,
    cost: f32,
    position: [f32; 3],
    candidate: u32,
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

/// Reusable buffers of the matcher.
#[derive(Debug, Default, Clone)]
pub struct MatchWorkspace {
    right_order: Vec<u32>,
    /// The first constraints of each right segment, in `right_order`.
    right_keys: Vec<RightKey>,
    /// Row and column extents of each left segment, in `left_order`.
    left_extents: Vec<Extent>,
    candidates: Vec<Candidate>,
    candidate_start: Vec<u32>,
    neighbours: Vec<Neighbour>,
    neighbour_start: Vec<u32>,
    neighbour_pairs: Vec<(u32, Neighbour)>,
    left_order: Vec<u32>,
    best_for_left: Vec<u32>,
    by_right_start: Vec<u32>,
    by_right: Vec<u32>,
    right_fill: Vec<u32>,
    right_taken: Vec<[[f32; 2]; MAX_PIECES_PER_RIGHT]>,
    right_taken_len: Vec<u8>,
    /// Columns of each right segment taken by nearly horizontal matches.
    right_columns: Vec<[[f32; 2]; MAX_PIECES_PER_RIGHT]>,
    right_columns_len: Vec<u8>,
    left_used: Vec<bool>,
    accepted_candidate: Vec<u32>,
    heap: BinaryHeap<Queued>,
    /// Nearly horizontal proposals of a round: candidate, measured disparity, distance to the
    /// neighbour giving the context.
    proposals: Vec<(u32, f32, f32)>,
    /// Pairs of collinear right fragments: the virtual segment joining them and the two
    /// pieces (the longer first) with their rows; sorted by the virtual segment's upper row.
    fragments: Vec<JoinedFragments>,
    /// Pairs meeting only the completion limits, grouped by left segment, with their
    /// photometric error when known (`NaN` otherwise).
    loose: Vec<(Candidate, f32)>,
    loose_start: Vec<u32>,
    /// Positions gathered by a search before its exact tests: in `right_keys`, the right
    /// segments passing the candidate search's first tests; in `left_order`, the segments
    /// whose boxes come within the neighbourhood radius.
    key_survivors: Vec<u32>,
    /// Left segments matched by completion.
    completed: Vec<bool>,
    /// Completion: the matched segments (extent, index, accepted candidate) by upper row, and
    /// the running maximum of their lower rows.
    matched_sorted: Vec<(Extent, u32, u32)>,
    matched_reach: Vec<f32>,
    /// Matched neighbours of the segment being completed.
    matched_near: Vec<(Neighbour, u32)>,
    /// Completion: matched neighbours near an end of the segment being completed (end, their
    /// disparity there, distance).
    end_context: Vec<(u8, f32, f32)>,
    /// Completion proposals: candidate, agreeing neighbours.
    completion_proposals: Vec<(Candidate, u32)>,
}

const NONE: u32 = u32::MAX;

/// Row extent `[start, end]` and column extent `[min, max]` of a segment, pixels.
#[derive(Debug, Clone, Copy)]
struct Extent {
    rows: [f32; 2],
    columns: [f32; 2],
}

impl Extent {
    fn of(s: &Segment) -> Self {
        let (x0, x1) = min_max(s.start[0], s.end[0]);
        Self {
            rows: [s.start[1], s.end[1]],
            columns: [x0, x1],
        }
    }

    /// Squared distance between this box and `other` (0 when they overlap).
    fn gap_squared(&self, other: &Extent) -> f32 {
        let gap_x = (self.columns[0] - other.columns[1])
            .max(other.columns[0] - self.columns[1])
            .max(0.0);
        let gap_y = (self.rows[0] - other.rows[1])
            .max(other.rows[0] - self.rows[1])
            .max(0.0);
        gap_x * gap_x + gap_y * gap_y
    }
}

/// What the candidate search tests first of a right segment, stored contiguously.
#[derive(Debug, Clone, Copy)]
struct RightKey {
    extent: Extent,
    polarity: i8,
    index: u32,
}

/// Two right segments that are fragments of one straight edge.
#[derive(Debug, Clone, Copy)]
struct JoinedFragments {
    /// The segment joining the outer endpoints.
    joined: Segment,
    /// The longer piece and its rows.
    main: (u32, [f32; 2]),
    /// The shorter piece and its rows.
    other: (u32, [f32; 2]),
}

/// Rounds of nearly horizontal matching (the second lets nearly horizontal matches vouch for
/// their nearly horizontal neighbours).
const HORIZONTAL_ROUNDS: usize = 2;

/// How many left fragments may share one right segment (on disjoint rows).
const MAX_PIECES_PER_RIGHT: usize = 4;

/// Whether two row intervals overlap by more than one pixel.
fn rows_overlap(a: [f32; 2], b: [f32; 2]) -> bool {
    a[1].min(b[1]) - a[0].max(b[0]) > 1.0
}

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
        self.grow(left, right, images, params);
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
            });
        }
    }

    fn build_candidates(
        &mut self,
        left: &[Segment],
        right: &[Segment],
        images: Option<&StereoImages<'_>>,
        params: &MatchParams,
    ) {
        self.candidates.clear();
        self.candidate_start.clear();
        self.right_order.clear();
        self.right_order.extend(0..right.len() as u32);
        self.right_order.sort_unstable_by(|&a, &b| {
            right[a as usize].start[1].total_cmp(&right[b as usize].start[1])
        });
        self.right_keys.clear();
        let mut tallest = 0.0f32;
        for &j in &self.right_order {
            let r = &right[j as usize];
            tallest = tallest.max(r.height_px());
            self.right_keys.push(RightKey {
                extent: Extent::of(r),
                polarity: r.polarity,
                index: j,
            });
        }
        let horizontal = params.horizontal_angle_deg.to_radians();
        self.join_fragments(right, horizontal, params);
        let (dmin, dmax) = (params.disparity_min_px, params.disparity_max_px);
        let loose_params = MatchParams {
            propagate_max_angle_diff_deg: params.completion_max_angle_diff_deg,
            propagate_min_length_ratio: params.completion_min_length_ratio,
            contained_min_length_ratio: params
                .contained_min_length_ratio
                .min(params.completion_min_length_ratio),
            max_disparity_slope: params.completion_max_disparity_slope,
            min_row_overlap_ratio: params.completion_min_row_overlap_ratio,
            ..*params
        };
        self.loose.clear();
        self.loose_start.clear();
        let mut survivors = std::mem::take(&mut self.key_survivors);
        survivors.clear();
        survivors.resize(self.right_keys.len(), 0);
        for (i, l) in left.iter().enumerate() {
            self.candidate_start.push(self.candidates.len() as u32);
            self.loose_start.push(self.loose.len() as u32);
            let l_horizontal = l.is_nearly_horizontal(horizontal);
            let complete = params.completion && !l_horizontal;
            if l_horizontal && !params.match_horizontal {
                continue;
            }
            // Right segments starting above the left segment's lower end (plus slack for
            // horizontal segments whose rows must agree within 2 px) and, being at most
            // `tallest` high, not ending (with a pixel's margin) above its upper end.
            let slack = if l_horizontal { 2.0 } else { 0.0 };
            let upper = l.end[1] + slack;
            let lower = l.start[1] - slack - tallest - 1.0;
            let keys = &self.right_keys;
            let first = keys.partition_point(|k| k.extent.rows[0] < lower);
            let count = keys.partition_point(|k| k.extent.rows[0] <= upper);
            let (lx0, lx1) = min_max(l.start[0], l.end[0]);
            // The first tests of `evaluate_pair`, on contiguous data and without a branch per
            // right segment (most fail them, in no predictable pattern): the positions of the
            // ones that pass are gathered first.
            let mut passed = 0;
            for (k, key) in keys.iter().enumerate().take(count).skip(first) {
                let [rx0, rx1] = key.extent.columns;
                let fail = (key.extent.rows[1] + slack < l.start[1])
                    | (key.polarity != l.polarity)
                    | (lx0 - rx1 > dmax + 1.0)
                    | (lx1 - rx0 < dmin - 1.0);
                survivors[passed] = k as u32;
                passed += usize::from(!fail);
            }
            for &k in &survivors[..passed] {
                let j = keys[k as usize].index;
                let r = &right[j as usize];
                let c = match evaluate_pair(i as u32, l, j, r, l_horizontal, params) {
                    Ok(c) => c,
                    // Completion pairs: the geometric limits only (the photometric check
                    // comes last, for the few that neighbours vouch for).
                    Err(
                        PairConstraint::Orientation
                        | PairConstraint::Length
                        | PairConstraint::RowOverlap
                        | PairConstraint::DisparitySlope,
                    ) if complete => {
                        if let Ok(c) = evaluate_pair(i as u32, l, j, r, false, &loose_params) {
                            self.loose.push((Candidate { tight: false, ..c }, f32::NAN));
                        }
                        continue;
                    }
                    Err(_) => continue,
                };
                if let Some(images) = images {
                    if !c.horizontal {
                        let error = photometric_error(
                            l,
                            &c,
                            images,
                            params.photometric_sampling_insensitive,
                        );
                        if error > params.max_photometric_error {
                            if complete {
                                self.loose.push((Candidate { tight: false, ..c }, error));
                            }
                            continue;
                        }
                    }
                }
                self.candidates.push(c);
            }
            if !l_horizontal && params.join_right_fragments {
                self.fragment_candidates(i as u32, l, images, params);
            }
        }
        self.candidate_start.push(self.candidates.len() as u32);
        self.loose_start.push(self.loose.len() as u32);
        self.key_survivors = survivors;
    }

    /// Pairs of right segments that are two fragments of one straight edge broken by a short
    /// gap (same polarity and similar sides, collinear, on consecutive rows). A left segment
    /// spanning both is matched to the pair, its disparity taken from the joined line.
    fn join_fragments(&mut self, right: &[Segment], horizontal: f32, params: &MatchParams) {
        self.fragments.clear();
        if !params.join_right_fragments {
            return;
        }
        // `right_order` is sorted by upper row.
        for (oa, &a) in self.right_order.iter().enumerate() {
            let sa = &right[a as usize];
            if sa.is_nearly_horizontal(horizontal) {
                continue;
            }
            for &b in &self.right_order[oa + 1..] {
                let sb = &right[b as usize];
                if sb.start[1] > sa.end[1] + params.max_fragment_gap_px {
                    break;
                }
                if sb.start[1] < sa.end[1] - 1.0
                    || sb.polarity != sa.polarity
                    || sb.is_nearly_horizontal(horizontal)
                {
                    continue;
                }
                if angle_difference(sa, sb).to_degrees() > params.max_fragment_angle_diff_deg
                    || line_distance(sa, sb.start) > params.disparity_tolerance_px
                    || line_distance(sb, sa.end) > params.disparity_tolerance_px
                    || (sa.side_intensity[0] - sb.side_intensity[0]).abs()
                        > params.max_intensity_diff
                    || (sa.side_intensity[1] - sb.side_intensity[1]).abs()
                        > params.max_intensity_diff
                {
                    continue;
                }
                let (start, end) = (sa.start, sb.end);
                let (dx, dy) = (end[0] - start[0], end[1] - start[1]);
                let mut angle = dy.atan2(dx);
                if angle >= std::f32::consts::PI {
                    angle -= std::f32::consts::PI;
                }
                if angle < 0.0 {
                    angle += std::f32::consts::PI;
                }
                let (wa, wb) = (sa.length_px, sb.length_px);
                let w = (wa + wb).max(1e-3);
                let joined = Segment {
                    start,
                    end,
                    length_px: (dx * dx + dy * dy).sqrt(),
                    angle_rad: angle,
                    polarity: sa.polarity,
                    contrast: (wa * sa.contrast + wb * sb.contrast) / w,
                    side_intensity: [
                        (wa * sa.side_intensity[0] + wb * sb.side_intensity[0]) / w,
                        (wa * sa.side_intensity[1] + wb * sb.side_intensity[1]) / w,
                    ],
                    chain: sa.chain,
                };
                let (pa, pb) = ((a, [sa.start[1], sa.end[1]]), (b, [sb.start[1], sb.end[1]]));
                let (main, other) = if sb.length_px > sa.length_px {
                    (pb, pa)
                } else {
                    (pa, pb)
                };
                self.fragments.push(JoinedFragments {
                    joined,
                    main,
                    other,
                });
            }
        }
        // Order-independent: by upper row, then by the pieces' positions.
        self.fragments.sort_unstable_by(|x, y| {
            let (p, q) = (&x.joined, &y.joined);
            p.start[1]
                .total_cmp(&q.start[1])
                .then(p.start[0].total_cmp(&q.start[0]))
                .then(p.end[1].total_cmp(&q.end[1]))
                .then(p.end[0].total_cmp(&q.end[0]))
        });
    }

    /// Candidates of left segment `i` on joined right fragments covering rows of both pieces.
    fn fragment_candidates(
        &mut self,
        i: u32,
        l: &Segment,
        images: Option<&StereoImages<'_>>,
        params: &MatchParams,
    ) {
        let count = self
            .fragments
            .partition_point(|f| f.joined.start[1] <= l.end[1]);
        for f in 0..count {
            let JoinedFragments {
                joined,
                main,
                other,
            } = self.fragments[f];
            if joined.end[1] < l.start[1] {
                continue;
            }
            // Both pieces must lie on rows of the left segment.
            let on_left = |rows: [f32; 2]| [rows[0].max(l.start[1]), rows[1].min(l.end[1])];
            let (rows, rows2) = (on_left(main.1), on_left(other.1));
            if rows[1] - rows[0] <= 1.0 || rows2[1] - rows2[0] <= 1.0 {
                continue;
            }
            let Ok(mut c) = evaluate_pair(i, l, main.0, &joined, false, params) else {
                continue;
            };
            c.rows = rows;
            c.rows2 = rows2;
            c.right2 = other.0;
            if let Some(images) = images {
                if photometric_error(l, &c, images, params.photometric_sampling_insensitive)
                    > params.max_photometric_error
                {
                    continue;
                }
            }
            self.candidates.push(c);
        }
    }

    /// Neighbours of each left segment: the `max_neighbours` closest segments within the
    /// radius (ties broken by position, so that the result does not depend on the order of
    /// the segments).
    fn build_neighbours(&mut self, left: &[Segment], params: &MatchParams) {
        let radius = params.neighbourhood_radius_px;
        self.neighbour_pairs.clear();
        // Segments without candidates neither support nor receive matches: leave them out.
        self.left_order.clear();
        self.left_order.extend(
            (0..left.len() as u32).filter(|&i| {
                self.candidate_start[i as usize] < self.candidate_start[i as usize + 1]
            }),
        );
        self.left_order.sort_unstable_by(|&a, &b| {
            left[a as usize].start[1].total_cmp(&left[b as usize].start[1])
        });
        self.left_extents.clear();
        self.left_extents.extend(
            self.left_order
                .iter()
                .map(|&i| Extent::of(&left[i as usize])),
        );
        // Segments whose bounding boxes are farther apart than this cannot be neighbours (a
        // pixel's margin over the radius for rounding).
        let reach_sq = (radius + 1.0) * (radius + 1.0);
        let mut near = std::mem::take(&mut self.key_survivors);
        near.clear();
        near.resize(self.left_order.len(), 0);
        for (oi, &i) in self.left_order.iter().enumerate() {
            let a = &left[i as usize];
            let ea = self.left_extents[oi];
            let [ax0, ax1] = ea.columns;
            // Segments starting within reach below (the order is by upper row); of those,
            // the ones whose boxes come within reach are gathered without a branch each.
            let later = &self.left_extents[oi + 1..];
            let end = later.partition_point(|eb| eb.rows[0] <= ea.rows[1] + radius);
            let mut found = 0;
            for (k, eb) in later[..end].iter().enumerate() {
                let [bx0, bx1] = eb.columns;
                let fail = (eb.rows[1] < ea.rows[0] - radius)
                    | (bx0 > ax1 + radius)
                    | (bx1 < ax0 - radius)
                    | (eb.gap_squared(&ea) > reach_sq);
                near[found] = (oi + 1 + k) as u32;
                found += usize::from(!fail);
            }
            for &ob in &near[..found] {
                let j = self.left_order[ob as usize];
                let b = &left[j as usize];
                if let Some(n) = Neighbour::within(a, j, b, radius) {
                    self.neighbour_pairs.push((i, n));
                    self.neighbour_pairs.push((j, n.seen_from_other(i, a)));
                }
            }
        }
        self.key_survivors = near;
        // Group by owner (counting sort), keep the closest ones.
        let n = left.len();
        self.neighbour_start.clear();
        self.neighbour_start.resize(n + 1, 0);
        for p in &self.neighbour_pairs {
            self.neighbour_start[p.0 as usize + 1] += 1;
        }
        for i in 0..n {
            self.neighbour_start[i + 1] += self.neighbour_start[i];
        }
        self.neighbours.clear();
        self.neighbours.resize(
            self.neighbour_pairs.len(),
            Neighbour {
                other: 0,
                other_start: [0.0; 2],
                t_self: 0.0,
                t_other: 0.0,
                distance: 0.0,
            },
        );
        self.right_fill.clear();
        self.right_fill
            .extend_from_slice(&self.neighbour_start[..n]);
        for p in &self.neighbour_pairs {
            let slot = &mut self.right_fill[p.0 as usize];
            self.neighbours[*slot as usize] = p.1;
            *slot += 1;
        }
        // Compact: keep at most `max_neighbours` per owner.
        let keep = params.max_neighbours;
        let mut write = 0usize;
        for i in 0..n {
            let (s0, s1) = (
                self.neighbour_start[i] as usize,
                self.neighbour_start[i + 1] as usize,
            );
            let group = &mut self.neighbours[s0..s1];
            let order = |a: &Neighbour, b: &Neighbour| {
                a.distance
                    .total_cmp(&b.distance)
                    .then(a.other_start[1].total_cmp(&b.other_start[1]))
                    .then(a.other_start[0].total_cmp(&b.other_start[0]))
            };
            if group.len() > keep {
                group.select_nth_unstable_by(keep, order);
            }
            let count = group.len().min(keep);
            group[..count].sort_unstable_by(order);
            self.neighbours.copy_within(s0..s0 + count, write);
            self.neighbour_start[i] = write as u32;
            write += count;
        }
        self.neighbour_start[n] = write as u32;
        self.neighbours.truncate(write);
    }

    /// Whether some left segment for which `inside` holds was left unmatched (or matched only
    /// by completion) although it has a candidate that validation would accept (the best of its segment, not beaten on its
    /// right segment's rows, enough support): propagation did not reach it from the matches
    /// found. Call after [`MatchWorkspace::match_segments`] with the same segments.
    pub fn has_unreached(
        &self,
        left: &[Segment],
        params: &MatchParams,
        inside: impl Fn(&Segment) -> bool,
    ) -> bool {
        (0..left.len()).any(|i| {
            (self.accepted_candidate.get(i) == Some(&NONE) || self.completed[i])
                && inside(&left[i])
                && self.candidates_of(i as u32).any(|k| {
                    let c = &self.candidates[k];
                    !c.horizontal && c.support >= params.min_support && self.consistent(k, params)
                })
        })
    }

    /// How the last [`MatchWorkspace::match_segments`] run (with the same segments, images and
    /// parameters) treated the pair `(left[i], right[j])`: the weak constraint or photometric
    /// check it fails, or its state as a candidate (when `j` is a piece of joined fragments,
    /// the joined candidate). Diagnostics only: not used by the matcher.
    pub fn diagnose_pair(
        &self,
        left: &[Segment],
        right: &[Segment],
        images: Option<&StereoImages<'_>>,
        params: &MatchParams,
        i: u32,
        j: u32,
    ) -> PairDiagnosis {
        let l = &left[i as usize];
        let horizontal = l.is_nearly_horizontal(params.horizontal_angle_deg.to_radians());
        let found = self
            .candidates_of(i)
            .find(|&k| self.candidates[k].right == j || self.candidates[k].right2 == j);
        let Some(k) = found else {
            return match evaluate_pair(i, l, j, &right[j as usize], horizontal, params) {
                Err(e) => PairDiagnosis::Constraint(e),
                Ok(c) => match images {
                    Some(images) if !horizontal => PairDiagnosis::Photometric(photometric_error(
                        l,
                        &c,
                        images,
                        params.photometric_sampling_insensitive,
                    )),
                    _ => PairDiagnosis::Unlisted,
                },
            };
        };
        let c = self.candidates[k];
        let reached = self.neighbours_of(i).any(|n| {
            let nb = self.neighbours[n];
            let a = self.accepted_candidate[nb.other as usize];
            a != NONE && continuous(&c, &self.candidates[a as usize], &nb, params)
        });
        PairDiagnosis::Candidate(CandidateDiagnosis {
            disparity_px: c.disparity,
            support: c.support,
            tight: c.tight,
            horizontal: c.horizontal,
            best_of_left: self.best_for_left[i as usize] == k as u32,
            consistent: self.consistent(k, params),
            right_free: self.right_free(&c),
            reached,
            accepted: self.accepted_candidate[i as usize] == k as u32,
            rivals: self.candidates_of(i).len() as u32,
        })
    }

    /// For a nearly horizontal pair, how the right segment fits the left one shifted by each
    /// matched neighbour's context disparity (after the last run): per neighbour, the context
    /// disparity, the distance of the left midpoint from the shifted right line, the two
    /// endpoint disparities, and the column overlap divided by the shorter column extent.
    /// Diagnostics only: not used by the matcher.
    pub fn diagnose_horizontal(
        &self,
        left: &[Segment],
        right: &[Segment],
        i: u32,
        j: u32,
    ) -> Vec<[f32; 5]> {
        let (l, r) = (&left[i as usize], &right[j as usize]);
        self.neighbours_of(i)
            .filter_map(|n| {
                let nb = self.neighbours[n];
                let a = self.accepted_candidate[nb.other as usize];
                (a != NONE).then(|| {
                    let context = self.candidates[a as usize].disparity_at(nb.t_other);
                    let (dx, dy) = (r.end[0] - r.start[0], r.end[1] - r.start[1]);
                    let m = l.midpoint();
                    let (px, py) = (m[0] - (r.start[0] + context), m[1] - r.start[1]);
                    let distance = (dx * py - dy * px).abs() / r.length_px.max(1e-3);
                    let (a0, a1) = min_max(l.start[0], l.end[0]);
                    let (b0, b1) = min_max(r.start[0] + context, r.end[0] + context);
                    let overlap = (a1.min(b1) - a0.max(b0)) / (a1 - a0).min(b1 - b0).max(1e-3);
                    [
                        context,
                        distance,
                        l.start[0] - r.start[0],
                        l.end[0] - r.end[0],
                        overlap,
                    ]
                })
            })
            .collect()
    }

    fn candidates_of(&self, left: u32) -> std::ops::Range<usize> {
        self.candidate_start[left as usize] as usize
            ..self.candidate_start[left as usize + 1] as usize
    }

    fn neighbours_of(&self, left: u32) -> std::ops::Range<usize> {
        self.neighbour_start[left as usize] as usize
            ..self.neighbour_start[left as usize + 1] as usize
    }

    /// Support of each candidate: neighbouring left segments (not nearly horizontal) having a
    /// non-horizontal candidate compatible under the continuity constraint.
    fn compute_support(&mut self, params: &MatchParams) {
        for c in 0..self.candidates.len() {
            let cand = self.candidates[c];
            if cand.horizontal {
                continue;
            }
            let mut support = 0;
            for n in self.neighbours_of(cand.left) {
                let nb = self.neighbours[n];
                let compatible = self.candidates_of(nb.other).any(|k| {
                    let other = &self.candidates[k];
                    !other.horizontal
                        && other.right != cand.right
                        && continuous(&cand, other, &nb, params)
                });
                if compatible {
                    support += 1;
                }
            }
            self.candidates[c].support = support;
        }
    }

    fn best_candidates(&mut self, n_left: usize, n_right: usize) {
        self.best_for_left.clear();
        self.best_for_left.resize(n_left, NONE);
        for (k, c) in self.candidates.iter().enumerate() {
            if c.horizontal {
                continue;
            }
            let bl = &mut self.best_for_left[c.left as usize];
            if *bl == NONE || c.better_than(&self.candidates[*bl as usize]) {
                *bl = k as u32;
            }
        }
        // Candidates grouped by right segment (counting sort).
        self.by_right_start.clear();
        self.by_right_start.resize(n_right + 1, 0);
        for c in &self.candidates {
            self.by_right_start[c.right as usize + 1] += 1;
        }
        for j in 0..n_right {
            self.by_right_start[j + 1] += self.by_right_start[j];
        }
        self.by_right.clear();
        self.by_right.resize(self.candidates.len(), 0);
        self.right_fill.clear();
        self.right_fill
            .extend_from_slice(&self.by_right_start[..n_right]);
        for (k, c) in self.candidates.iter().enumerate() {
            let slot = &mut self.right_fill[c.right as usize];
            self.by_right[*slot as usize] = k as u32;
            *slot += 1;
        }
    }

    /// Left-right consistency: the candidate is the best of its left segment, and no other
    /// left segment's candidate on the same rows of the same right segment is better.
    fn consistent(&self, k: usize, params: &MatchParams) -> bool {
        let c = &self.candidates[k];
        if !params.left_right_check || c.horizontal {
            return true;
        }
        if self.best_for_left[c.left as usize] != k as u32 {
            return false;
        }
        let range = self.by_right_start[c.right as usize] as usize
            ..self.by_right_start[c.right as usize + 1] as usize;
        !self.by_right[range].iter().any(|&o| {
            let other = &self.candidates[o as usize];
            other.left != c.left
                && !other.horizontal
                && rows_overlap(other.rows, c.rows)
                && other.better_than(c)
        })
    }

    /// Whether the rows of `c` on its right segment are still free.
    /// Whether completion may take candidate `c`: not nearly horizontal, a disparity change
    /// along it within the completion limit, and its right segment free.
    fn completion_possible(&self, c: &Candidate, params: &MatchParams) -> bool {
        !c.horizontal
            && (c.disparity[1] - c.disparity[0]).abs() <= params.completion_max_disparity_change_px
            && self.right_free(c)
    }

    fn right_free(&self, c: &Candidate) -> bool {
        self.rows_free(c.right, c.rows) && (c.right2 == NONE || self.rows_free(c.right2, c.rows2))
    }

    fn rows_free(&self, j: u32, rows: [f32; 2]) -> bool {
        let j = j as usize;
        let n = self.right_taken_len[j] as usize;
        if n >= MAX_PIECES_PER_RIGHT {
            return false;
        }
        !self.right_taken[j][..n]
            .iter()
            .any(|&taken| rows_overlap(taken, rows))
    }

    fn take_right(&mut self, c: &Candidate) {
        self.take_rows(c.right, c.rows);
        if c.right2 != NONE {
            self.take_rows(c.right2, c.rows2);
        }
    }

    fn take_rows(&mut self, j: u32, rows: [f32; 2]) {
        let j = j as usize;
        let n = self.right_taken_len[j] as usize;
        if n < MAX_PIECES_PER_RIGHT {
            self.right_taken[j][n] = rows;
            self.right_taken_len[j] += 1;
        }
    }

    /// Whether right segment `j` is free for a nearly horizontal match on `columns` of it: no
    /// other match uses its rows, nearly horizontal ones only other columns.
    fn horizontal_free(&self, j: u32, columns: [f32; 2]) -> bool {
        let j = j as usize;
        let n = self.right_columns_len[j] as usize;
        self.right_taken_len[j] == 0
            && n < MAX_PIECES_PER_RIGHT
            && !self.right_columns[j][..n]
                .iter()
                .any(|&taken| rows_overlap(taken, columns))
    }

    fn take_columns(&mut self, j: u32, columns: [f32; 2]) {
        let j = j as usize;
        let n = self.right_columns_len[j] as usize;
        if n < MAX_PIECES_PER_RIGHT {
            self.right_columns[j][n] = columns;
            self.right_columns_len[j] += 1;
        }
    }

    fn grow(
        &mut self,
        left: &[Segment],
        right: &[Segment],
        images: Option<&StereoImages<'_>>,
        params: &MatchParams,
    ) {
        let (n_left, n_right) = (left.len(), right.len());
        self.left_used.clear();
        self.left_used.resize(n_left, false);
        self.right_taken.clear();
        self.right_taken
            .resize(n_right, [[0.0; 2]; MAX_PIECES_PER_RIGHT]);
        self.right_taken_len.clear();
        self.right_taken_len.resize(n_right, 0);
        self.right_columns.clear();
        self.right_columns
            .resize(n_right, [[0.0; 2]; MAX_PIECES_PER_RIGHT]);
        self.right_columns_len.clear();
        self.right_columns_len.resize(n_right, 0);
        self.accepted_candidate.clear();
        self.accepted_candidate.resize(n_left, NONE);
        self.heap.clear();
        // Prediction: seeds.
        for (k, c) in self.candidates.iter().enumerate() {
            if c.tight && !c.horizontal && c.support >= params.min_seed_support {
                self.heap.push(Queued {
                    support: c.support,
                    cost: c.cost,
                    position: c.position,
                    candidate: k as u32,
                });
            }
        }
        // Propagation, best first.
        while let Some(q) = self.heap.pop() {
            let k = q.candidate as usize;
            let cand = self.candidates[k];
            if self.left_used[cand.left as usize] || !self.right_free(&cand) {
                continue;
            }
            if !self.consistent(k, params) {
                continue;
            }

            self.left_used[cand.left as usize] = true;
            self.take_right(&cand);
            self.accepted_candidate[cand.left as usize] = k as u32;
            for n in self.neighbours_of(cand.left) {
                let nb = self.neighbours[n];
                if self.left_used[nb.other as usize] {
                    continue;
                }
                let mut best: Option<usize> = None;
                for m in self.candidates_of(nb.other) {
                    let other = &self.candidates[m];
                    if other.horizontal
                        || other.support < params.min_support
                        || !self.right_free(other)
                        || !continuous(&cand, other, &nb, params)
                    {
                        continue;
                    }
                    if best.is_none_or(|b| other.better_than(&self.candidates[b])) {
                        best = Some(m);
                    }
                }
                if let Some(m) = best {
                    let other = &self.candidates[m];
                    self.heap.push(Queued {
                        support: other.support,
                        cost: other.cost,
                        position: other.position,
                        candidate: m as u32,
                    });
                }
            }
        }
        self.completed.clear();
        self.completed.resize(n_left, false);
        if params.completion {
            for _ in 0..params.completion_rounds {
                if !self.complete(left, images, params) {
                    break;
                }
            }
        }
        if params.match_horizontal {
            for _ in 0..HORIZONTAL_ROUNDS {
                if !self.match_horizontal_round(left, right, params) {
                    break;
                }
            }
        }
    }

    /// Completion: each left segment left unmatched by propagation (not nearly horizontal)
    /// proposes its candidate or completion pair (see [`MatchParams::completion`]) with the
    /// most matched neighbours meeting the continuity constraint with it, when they are enough,
    /// few contradict it, and its right rows are free; proposals are accepted best first where
    /// the right rows are still free. Decided from the matches of propagation only, so the
    /// result does not depend on the order of the segments.
    fn complete(
        &mut self,
        left: &[Segment],
        images: Option<&StereoImages<'_>>,
        params: &MatchParams,
    ) -> bool {
        let radius = params.neighbourhood_radius_px;
        let horizontal = params.horizontal_angle_deg.to_radians();
        // The matched segments (not nearly horizontal) sorted by upper row, and the running
        // maximum of their lower rows (to skip those ending above a segment's reach).
        self.matched_sorted.clear();
        for (&j, ej) in self.left_order.iter().zip(&self.left_extents) {
            let a = self.accepted_candidate[j as usize];
            if a != NONE && !self.candidates[a as usize].horizontal {
                self.matched_sorted.push((*ej, j, a));
            }
        }
        self.matched_reach.clear();
        let mut lowest = f32::NEG_INFINITY;
        for m in &self.matched_sorted {
            lowest = lowest.max(m.0.rows[1]);
            self.matched_reach.push(lowest);
        }
        let reach_sq = (radius + 1.0) * (radius + 1.0);
        self.completion_proposals.clear();
        for i in 0..left.len() {
            if self.left_used[i] {
                continue;
            }
            let l = &left[i];
            if l.is_nearly_horizontal(horizontal) {
                continue;
            }
            let strict = self.candidates_of(i as u32);
            let loose = self.loose_start[i] as usize..self.loose_start[i + 1] as usize;
            // Only pairs with a small disparity change along them and free right rows can be
            // taken: skip the neighbour search when there is none.
            if !strict
                .clone()
                .any(|k| self.completion_possible(&self.candidates[k], params))
                && !loose
                    .clone()
                    .any(|k| self.completion_possible(&self.loose[k].0, params))
            {
                continue;
            }
            // Matched neighbours within the radius.
            self.matched_near.clear();
            let e = Extent::of(l);
            let first = self
                .matched_reach
                .partition_point(|&y| y < e.rows[0] - radius - 1.0);
            for &(ej, j, a) in &self.matched_sorted[first..] {
                if ej.rows[0] > e.rows[1] + radius {
                    break;
                }
                if ej.gap_squared(&e) > reach_sq {
                    continue;
                }
                if let Some(n) = Neighbour::within(l, j, &left[j as usize], radius) {
                    self.matched_near.push((n, a));
                }
            }
            if (self.matched_near.len() as u32) < params.completion_min_agreeing {
                continue;
            }
            // Each end of the segment, the matched neighbours near it: their disparity at the
            // point closest to the end, and the distance.
            self.end_context.clear();
            for &(nb, a) in &self.matched_near {
                let o = &left[nb.other as usize];
                for (e, p) in [l.start, l.end].into_iter().enumerate() {
                    let t = project_param(o, p);
                    let q = lerp(o, t);
                    let d = ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt();
                    if d <= params.completion_end_radius_px {
                        self.end_context.push((
                            e as u8,
                            self.candidates[a as usize].disparity_at(t),
                            d,
                        ));
                    }
                }
            }
            if params.completion_end_context
                && !(0..2u8).all(|e| self.end_context.iter().any(|x| x.0 == e))
            {
                continue;
            }
            let mut best: Option<(Candidate, u32)> = None;
            let n_strict = strict.len();
            for k in 0..n_strict + loose.len() {
                let (c, known_error) = if k < n_strict {
                    (self.candidates[strict.start + k], 0.0)
                } else {
                    self.loose[loose.start + k - n_strict]
                };
                if !self.completion_possible(&c, params) {
                    continue;
                }
                let ends_agree = (0..2u8).all(|e| {
                    self.end_context.iter().any(|&(end, context, d)| {
                        end == e
                            && (c.disparity[e as usize] - context).abs()
                                <= params.completion_tolerance_px
                                    + params.completion_gradient_limit * d
                    })
                });
                if params.completion_end_context && !ends_agree {
                    continue;
                }
                let (mut agree, mut disagree) = (0u32, 0u32);
                let mut ends = [false; 2];
                for &(nb, a) in &self.matched_near {
                    let other = &self.candidates[a as usize];
                    let change = (c.disparity_at(nb.t_self) - other.disparity_at(nb.t_other)).abs();
                    if change
                        <= params.completion_tolerance_px
                            + params.completion_gradient_limit * nb.distance
                    {
                        agree += 1;
                        ends[0] |= nb.t_self <= 0.5;
                        ends[1] |= nb.t_self >= 0.5;
                    } else if !continuous(&c, other, &nb, params) {
                        disagree += 1;
                    }
                }
                if (params.completion_both_ends && !(ends[0] && ends[1]))
                    || agree < params.completion_min_agreeing
                    || disagree as f32 > params.completion_max_disagreeing_ratio * agree as f32
                {
                    continue;
                }
                // Completion pairs are checked photometrically last (the costliest test).
                if let Some(images) = images {
                    let error = if known_error.is_nan() {
                        photometric_error(l, &c, images, params.photometric_sampling_insensitive)
                    } else {
                        known_error
                    };
                    if error > params.completion_max_photometric_error {
                        continue;
                    }
                }
                let better = best.is_none_or(|(b, b_agree)| {
                    agree
                        .cmp(&b_agree)
                        .then_with(|| b.cost.total_cmp(&c.cost))
                        .then_with(|| b.position[2].total_cmp(&c.position[2]))
                        == Ordering::Greater
                });
                if better {
                    best = Some((c, agree));
                }
            }
            if let Some(p) = best {
                self.completion_proposals.push(p);
            }
        }
        self.completion_proposals.sort_unstable_by(|a, b| {
            b.1.cmp(&a.1)
                .then_with(|| a.0.cost.total_cmp(&b.0.cost))
                .then_with(|| a.0.position[0].total_cmp(&b.0.position[0]))
                .then_with(|| a.0.position[1].total_cmp(&b.0.position[1]))
                .then_with(|| a.0.position[2].total_cmp(&b.0.position[2]))
        });
        let mut accepted = false;
        for p in 0..self.completion_proposals.len() {
            let (mut c, agree) = self.completion_proposals[p];
            if !self.right_free(&c) {
                continue;
            }
            c.support = agree;
            self.left_used[c.left as usize] = true;
            self.completed[c.left as usize] = true;
            self.take_right(&c);
            self.accepted_candidate[c.left as usize] = self.candidates.len() as u32;
            self.candidates.push(c);
            accepted = true;
        }
        accepted
    }

    /// One round of matching nearly horizontal left segments from the matches accepted before
    /// the round: each unmatched one takes its context disparity from its closest matched
    /// neighbour (a nearly horizontal neighbour only if matched in an earlier round) and
    /// proposes its best candidate lying on it once shifted by that disparity; proposals are
    /// then accepted best first where the right segment is still free. The result depends
    /// only on the matches before the round, not on the order of the segments. Returns whether
    /// anything was accepted.
    fn match_horizontal_round(
        &mut self,
        left: &[Segment],
        right: &[Segment],
        params: &MatchParams,
    ) -> bool {
        self.proposals.clear();
        for h in 0..left.len() as u32 {
            if self.left_used[h as usize] {
                continue;
            }
            let cands = self.candidates_of(h);
            if cands.is_empty() || !self.candidates[cands.start].horizontal {
                continue;
            }
            // Neighbours are sorted closest first (ties by position).
            for n in self.neighbours_of(h) {
                let nb = self.neighbours[n];
                let a = self.accepted_candidate[nb.other as usize];
                if a == NONE {
                    continue;
                }
                let context = self.candidates[a as usize].disparity_at(nb.t_other);
                let mut best: Option<(usize, f32)> = None;
                for m in self.candidates_of(h) {
                    let c = &self.candidates[m];
                    let Some(measured) =
                        fits_shifted(&left[h as usize], &right[c.right as usize], context, params)
                    else {
                        continue;
                    };
                    let columns =
                        shifted_columns(&left[h as usize], &right[c.right as usize], measured);
                    if !self.horizontal_free(c.right, columns) {
                        continue;
                    }
                    if best.is_none_or(|(b, _)| c.better_than(&self.candidates[b])) {
                        best = Some((m, measured));
                    }
                }
                if let Some((m, measured)) = best {
                    self.proposals.push((m as u32, measured, nb.distance));
                    break;
                }
            }
        }
        let candidates = &self.candidates;
        self.proposals.sort_unstable_by(|a, b| {
            let (ca, cb) = (&candidates[a.0 as usize], &candidates[b.0 as usize]);
            a.2.total_cmp(&b.2)
                .then_with(|| cb.rank_cmp(ca))
                .then_with(|| a.0.cmp(&b.0))
        });
        let mut accepted = false;
        for p in 0..self.proposals.len() {
            let (m, measured, _) = self.proposals[p];
            let c = self.candidates[m as usize];
            let columns =
                shifted_columns(&left[c.left as usize], &right[c.right as usize], measured);
            if !self.horizontal_free(c.right, columns) {
                continue;
            }
            self.candidates[m as usize].disparity = [measured; 2];
            self.left_used[c.left as usize] = true;
            self.take_columns(c.right, columns);
            self.accepted_candidate[c.left as usize] = m;
            accepted = true;
        }
        accepted
    }
}

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

/// Photometric error of a candidate (see [`MatchParams::max_photometric_error`] and
/// [`MatchParams::photometric_sampling_insensitive`]).
fn photometric_error(
    l: &Segment,
    c: &Candidate,
    images: &StereoImages<'_>,
    sampling_insensitive: bool,
) -> f32 {
    const SAMPLES: usize = 12;
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

/// Continuity between candidate `a` (on left segment `n`'s owner) and `b` (on `n.other`).
fn continuous(a: &Candidate, b: &Candidate, n: &Neighbour, params: &MatchParams) -> bool {
    let da = a.disparity_at(n.t_self);
    let db = b.disparity_at(n.t_other);
    (da - db).abs() <= params.disparity_tolerance_px + params.disparity_gradient_limit * n.distance
}

/// Distance of point `p` from the supporting line of `s`, pixels.
fn line_distance(s: &Segment, p: [f32; 2]) -> f32 {
    let (dx, dy) = (s.end[0] - s.start[0], s.end[1] - s.start[1]);
    let (px, py) = (p[0] - s.start[0], p[1] - s.start[1]);
    (dx * py - dy * px).abs() / s.length_px.max(1e-3)
}

fn min_max(a: f32, b: f32) -> (f32, f32) {
    if a < b {
        (a, b)
    } else {
        (b, a)
    }
}

/// Evaluates the pair against the weak constraints; the first one failed when it fails them.
fn evaluate_pair(
    i: u32,
    l: &Segment,
    j: u32,
    r: &Segment,
    l_horizontal: bool,
    params: &MatchParams,
) -> Result<Candidate, PairConstraint> {
    if l.polarity != r.polarity {
        return Err(PairConstraint::Polarity);
    }
    // Cheap disparity-range test on the column extents before anything else.
    let (lx0, lx1) = min_max(l.start[0], l.end[0]);
    let (rx0, rx1) = min_max(r.start[0], r.end[0]);
    if lx0 - rx1 > params.disparity_max_px + 1.0 || lx1 - rx0 < params.disparity_min_px - 1.0 {
        return Err(PairConstraint::DisparityRange);
    }
    let contrast_ratio = l.contrast.max(r.contrast) / l.contrast.min(r.contrast).max(1e-3);
    if contrast_ratio > params.max_contrast_ratio {
        return Err(PairConstraint::Contrast);
    }
    let di0 = (l.side_intensity[0] - r.side_intensity[0]).abs();
    let di1 = (l.side_intensity[1] - r.side_intensity[1]).abs();
    if di0.min(di1) > params.max_intensity_diff {
        return Err(PairConstraint::Intensity);
    }
    let angle_diff_deg = angle_difference(l, r).to_degrees();
    if angle_diff_deg > params.propagate_max_angle_diff_deg {
        return Err(PairConstraint::Orientation);
    }
    let length_ratio = l.length_px.min(r.length_px) / l.length_px.max(r.length_px);
    // A left segment lying within the rows of a longer right one may be a fragment of its
    // edge (Ayache: a segment matches part of another); its disparity is interpolated on the
    // right line, so a weaker length limit applies.
    let contained = !l_horizontal
        && l.start[1] >= r.start[1] - 1.0
        && l.end[1] <= r.end[1] + 1.0
        && r.length_px > l.length_px;
    let min_length_ratio = if l_horizontal {
        params.horizontal_min_length_ratio
    } else if contained {
        params.contained_min_length_ratio
    } else {
        params.propagate_min_length_ratio
    };
    if length_ratio < min_length_ratio {
        return Err(PairConstraint::Length);
    }
    let (dmin, dmax) = (params.disparity_min_px, params.disparity_max_px);
    let disparity = if l_horizontal {
        // Rows must agree (within 2 px) and some disparity in range must make the columns
        // overlap; the disparity itself is inherited during propagation.
        if l.start[1].max(r.start[1]) > l.end[1].min(r.end[1]) + 2.0 {
            return Err(PairConstraint::HorizontalRows);
        }
        let (a0, a1) = min_max(l.start[0], l.end[0]);
        let (b0, b1) = min_max(r.start[0], r.end[0]);
        let lo = (a0 - b1).max(dmin);
        let hi = (a1 - b0).min(dmax);
        if lo > hi {
            return Err(PairConstraint::DisparityRange);
        }
        [0.5 * (lo + hi); 2]
    } else {
        let y0 = l.start[1].max(r.start[1]);
        let y1 = l.end[1].min(r.end[1]);
        let overlap = y1 - y0;
        if overlap <= 0.0
            || overlap < params.min_row_overlap_ratio * l.height_px().min(r.height_px())
        {
            return Err(PairConstraint::RowOverlap);
        }
        let (Some(xr0), Some(xr1)) = (r.x_at_row(l.start[1]), r.x_at_row(l.end[1])) else {
            return Err(PairConstraint::RowOverlap);
        };
        let d = [l.start[0] - xr0, l.end[0] - xr1];
        if (d[1] - d[0]).abs() > 1.0 + params.max_disparity_slope * l.height_px() {
            return Err(PairConstraint::DisparitySlope);
        }
        // The disparity must be in range over the overlapping rows.
        let (Some(xa), Some(xb)) = (l.x_at_row(y0), l.x_at_row(y1)) else {
            return Err(PairConstraint::RowOverlap);
        };
        let (Some(ra), Some(rb)) = (r.x_at_row(y0), r.x_at_row(y1)) else {
            return Err(PairConstraint::RowOverlap);
        };
        for dd in [xa - ra, xb - rb] {
            if dd < dmin - 0.5 || dd > dmax + 0.5 {
                return Err(PairConstraint::DisparityRange);
            }
        }
        d
    };
    let mean_d = 0.5 * (disparity[0] + disparity[1]);
    if mean_d < dmin - 0.5 || mean_d > dmax + 0.5 {
        return Err(PairConstraint::DisparityRange);
    }
    let tight = angle_diff_deg <= params.predict_max_angle_diff_deg
        && length_ratio >= params.predict_min_length_ratio
        && l.length_px.min(r.length_px) >= params.predict_min_length_px
        && di0.max(di1) <= params.max_intensity_diff;
    let cost = angle_diff_deg / params.propagate_max_angle_diff_deg
        + (1.0 - length_ratio)
        + (di0 + di1) / (2.0 * params.max_intensity_diff);
    Ok(Candidate {
        left: i,
        right: j,
        disparity,
        cost,
        tight,
        horizontal: l_horizontal,
        support: 0,
        position: [l.start[1], l.start[0], r.start[0]],
        right2: NONE,
        rows2: [0.0; 2],
        rows: if l_horizontal {
            [f32::NEG_INFINITY, f32::INFINITY]
        } else {
            [l.start[1].max(r.start[1]), l.end[1].min(r.end[1])]
        },
    })
}

/// Whether the right segment `r` shifted right by the context `disparity` lies on the left
/// segment `l` (nearly horizontal pairs): the left midpoint within the continuity tolerance of
/// the shifted line, the columns overlapping by at least half the shorter extent, and an
/// endpoint disparity agreeing with the context. Returns the measured disparity.
fn fits_shifted(l: &Segment, r: &Segment, disparity: f32, params: &MatchParams) -> Option<f32> {
    let (dx, dy) = (r.end[0] - r.start[0], r.end[1] - r.start[1]);
    let m = l.midpoint();
    let (px, py) = (m[0] - (r.start[0] + disparity), m[1] - r.start[1]);
    let distance = (dx * py - dy * px).abs() / r.length_px.max(1e-3);
    if distance > params.horizontal_line_tolerance_px {
        return None;
    }
    // The measured disparity: the mean of the endpoint disparities that agree with the
    // context (at least one must, typically the corner shared with the neighbour).
    let (mut sum, mut count) = (0.0f32, 0u32);
    for (a, b) in [(l.start, r.start), (l.end, r.end)] {
        let d = a[0] - b[0];
        if (d - disparity).abs() <= params.horizontal_endpoint_tolerance_px {
            sum += d;
            count += 1;
        }
    }
    let (a0, a1) = min_max(l.start[0], l.end[0]);
    let (b0, b1) = min_max(r.start[0] + disparity, r.end[0] + disparity);
    let overlap = a1.min(b1) - a0.max(b0);
    if count == 0 {
        // A piece of the edge: the shorter one lies within the other once shifted, on the
        // line; the context is the disparity.
        let inside = overlap >= params.horizontal_piece_overlap * (a1 - a0).min(b1 - b0);
        return (params.horizontal_piece_overlap <= 1.0
            && distance <= params.horizontal_piece_line_tolerance_px
            && inside)
            .then_some(disparity);
    }
    (overlap >= 0.5 * (a1 - a0).min(b1 - b0)).then_some(sum / count as f32)
}

/// The columns of right segment `r` covered by left segment `l` shifted left by `disparity`.
fn shifted_columns(l: &Segment, r: &Segment, disparity: f32) -> [f32; 2] {
    let (a0, a1) = min_max(l.start[0] - disparity, l.end[0] - disparity);
    let (b0, b1) = min_max(r.start[0], r.end[0]);
    [a0.max(b0), a1.min(b1)]
}

/// Distance between two segments and the parameters (0 at `start`, 1 at `end`) of the closest
/// points.
/// Angle between the directions of two segments, radians in `[0, pi/2]`.
fn angle_difference(a: &Segment, b: &Segment) -> f32 {
    let difference = (a.angle_rad - b.angle_rad).abs();
    if difference > std::f32::consts::FRAC_PI_2 {
        std::f32::consts::PI - difference
    } else {
        difference
    }
}

fn segment_distance(a: &Segment, b: &Segment) -> (f32, f32, f32) {
    let mut best = (f32::INFINITY, 0.0, 0.0);
    // Segments that do not cross are closest at an endpoint of one of them.
    for (p, on_a, t_fixed) in [
        (a.start, false, 0.0),
        (a.end, false, 1.0),
        (b.start, true, 0.0),
        (b.end, true, 1.0),
    ] {
        let s = if on_a { a } else { b };
        let t = project_param(s, p);
        let q = lerp(s, t);
        let d = ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt();
        if d < best.0 {
            best = if on_a {
                (d, t, t_fixed)
            } else {
                (d, t_fixed, t)
            };
        }
    }
    best
}

fn project_param(s: &Segment, p: [f32; 2]) -> f32 {
    let (dx, dy) = (s.end[0] - s.start[0], s.end[1] - s.start[1]);
    let len2 = dx * dx + dy * dy;
    if len2 < 1e-9 {
        return 0.0;
    }
    (((p[0] - s.start[0]) * dx + (p[1] - s.start[1]) * dy) / len2).clamp(0.0, 1.0)
}

fn lerp(s: &Segment, t: f32) -> [f32; 2] {
    [
        s.start[0] + t * (s.end[0] - s.start[0]),
        s.start[1] + t * (s.end[1] - s.start[1]),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seg(x0: f32, y0: f32, x1: f32, y1: f32, polarity: i8, sides: [f32; 2]) -> Segment {
        let (mut s, mut e) = ([x0, y0], [x1, y1]);
        if e[1] < s[1] {
            std::mem::swap(&mut s, &mut e);
        }
        let (dx, dy) = (e[0] - s[0], e[1] - s[1]);
        let mut angle = dy.atan2(dx);
        if angle >= std::f32::consts::PI {
            angle -= std::f32::consts::PI;
        }
        Segment {
            start: s,
            end: e,
            length_px: (dx * dx + dy * dy).sqrt(),
            angle_rad: angle,
            polarity,
            contrast: 100.0,
            side_intensity: sides,
            chain: 0,
        }
    }

    /// A synthetic scene: a fan of segments on a fronto-parallel plane at disparity `d`.
    fn scene(d: f32) -> (Vec<Segment>, Vec<Segment>) {
        let mut left = Vec::new();
        let mut right = Vec::new();
        for k in 0..12 {
            let x = 80.0 + 17.0 * k as f32;
            let y = 40.0 + 6.0 * (k % 3) as f32;
            let slant = 0.15 * (k % 4) as f32;
            let sides = [40.0 + 12.0 * k as f32, 200.0 - 9.0 * k as f32];
            let pol = if k % 2 == 0 { 1 } else { -1 };
            let l = seg(
                x,
                y,
                x + 40.0 * slant,
                y + 40.0 + 3.0 * k as f32,
                pol,
                sides,
            );
            let mut r = l;
            r.start[0] -= d;
            r.end[0] -= d;
            left.push(l);
            right.push(r);
        }
        (left, right)
    }

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

    #[test]
    fn endpoint_disparity_comes_from_the_right_line_at_the_left_rows() {
        // Right segment is shorter (fragmented) but on the same line shifted by 10 px.
        let l = seg(100.0, 10.0, 120.0, 90.0, 1, [50.0, 150.0]);
        let r = seg(92.5, 20.0, 107.5, 80.0, 1, [50.0, 150.0]);
        let c = evaluate_pair(0, &l, 0, &r, false, &MatchParams::default()).unwrap();
        assert!((c.disparity[0] - 10.0).abs() < 1e-3, "{:?}", c.disparity);
        assert!((c.disparity[1] - 10.0).abs() < 1e-3);
    }

    #[test]
    fn a_left_segment_within_a_longer_right_one_is_a_candidate() {
        let params = MatchParams::default();
        let r = seg(90.0, 10.0, 90.0, 70.0, 1, [50.0, 150.0]);
        // 16 px within the right segment's rows: ratio 0.27, accepted as a fragment.
        let inside = seg(100.0, 30.0, 100.0, 46.0, 1, [50.0, 150.0]);
        let c = evaluate_pair(0, &inside, 0, &r, false, &params).unwrap();
        assert!((c.disparity[0] - 10.0).abs() < 1e-3);
        // The same length reaching beyond the right segment's rows is not.
        let beyond = seg(100.0, 60.0, 100.0, 76.0, 1, [50.0, 150.0]);
        assert!(evaluate_pair(0, &beyond, 0, &r, false, &params).is_err());
    }

    #[test]
    fn an_edge_broken_in_two_on_the_right_is_matched_across_the_gap() {
        let (left, mut right) = scene(23.0);
        // Right segment 5 (55 px) broken into two 20-px pieces 6.6 rows apart: each alone is
        // too short for the length limit.
        let whole = right[5];
        let at = |t: f32| {
            [
                whole.start[0] + t * (whole.end[0] - whole.start[0]),
                whole.start[1] + t * (whole.end[1] - whole.start[1]),
            ]
        };
        let piece = |t0: f32, t1: f32| {
            let (a, b) = (at(t0), at(t1));
            let mut s = seg(a[0], a[1], b[0], b[1], whole.polarity, whole.side_intensity);
            s.contrast = whole.contrast;
            s
        };
        right[5] = piece(0.02, 0.38);
        right.push(piece(0.5, 0.86));
        let mut ws = MatchWorkspace::new();
        let mut out = Vec::new();
        // (Completion would take one piece on the neighbours' word: off here.)
        let mut params = MatchParams {
            join_right_fragments: false,
            completion: false,
            ..MatchParams::default()
        };
        ws.match_segments(&left, &right, None, &params, &mut out);
        assert!(out.iter().all(|m| m.left != 5));
        params.join_right_fragments = true;
        ws.match_segments(&left, &right, None, &params, &mut out);
        let m = out.iter().find(|m| m.left == 5).expect("left 5 matched");
        assert!(m.right == 5 || m.right as usize == right.len() - 1);
        assert!((m.disparity_px[0] - 23.0).abs() < 1e-2, "{m:?}");
        assert!((m.disparity_px[1] - 23.0).abs() < 1e-2, "{m:?}");
        assert_eq!(out.len(), left.len());
    }

    #[test]
    fn a_pair_beyond_the_candidate_limits_is_completed_when_neighbours_vouch_for_it() {
        let (left, mut right) = scene(23.0);
        // Right segment 5 keeps only 30 % of its edge: too short for the length limits.
        let whole = right[5];
        let at = |t: f32| {
            [
                whole.start[0] + t * (whole.end[0] - whole.start[0]),
                whole.start[1] + t * (whole.end[1] - whole.start[1]),
            ]
        };
        let (a, b) = (at(0.35), at(0.65));
        right[5] = seg(a[0], a[1], b[0], b[1], whole.polarity, whole.side_intensity);
        let mut ws = MatchWorkspace::new();
        let mut out = Vec::new();
        let mut params = MatchParams {
            completion: false,
            ..MatchParams::default()
        };
        ws.match_segments(&left, &right, None, &params, &mut out);
        assert!(out.iter().all(|m| m.left != 5));
        params.completion = true;
        ws.match_segments(&left, &right, None, &params, &mut out);
        let m = out.iter().find(|m| m.left == 5).expect("left 5 completed");
        assert_eq!(m.right, 5);
        assert!((m.disparity_px[0] - 23.0).abs() < 1e-2, "{m:?}");
        assert!((m.disparity_px[1] - 23.0).abs() < 1e-2, "{m:?}");
        assert_eq!(out.len(), left.len());
        // The same piece 4 px further right (disparity 19, off the neighbours' 23): not taken.
        right[5].start[0] += 4.0;
        right[5].end[0] += 4.0;
        ws.match_segments(&left, &right, None, &params, &mut out);
        assert!(out.iter().all(|m| m.left != 5), "{out:?}");
    }

    #[test]
    fn opposite_polarity_is_rejected() {
        let l = seg(100.0, 10.0, 120.0, 90.0, 1, [50.0, 150.0]);
        let r = seg(90.0, 10.0, 110.0, 90.0, -1, [50.0, 150.0]);
        assert!(evaluate_pair(0, &l, 0, &r, false, &MatchParams::default()).is_err());
    }

    #[test]
    fn closest_points_of_two_segments() {
        let a = seg(0.0, 0.0, 0.0, 10.0, 1, [0.0, 0.0]);
        let b = seg(3.0, 12.0, 3.0, 20.0, 1, [0.0, 0.0]);
        let (d, ta, tb) = segment_distance(&a, &b);
        assert!((d - (9.0f32 + 4.0).sqrt()).abs() < 1e-5);
        assert_eq!((ta, tb), (1.0, 0.0));
    }
}
