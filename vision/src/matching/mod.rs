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
//! **Checks against wrong matches** (each configurable, off by default): a left-right
//! consistency check by a second run of the whole algorithm on the mirrored pair
//! ([`MutualCheck`]), a confidence threshold on each match's evidence ([`MatchEvidence`]:
//! agreement of its matched neighbours, margin over its best rival, photometric agreement) and
//! a surface check that drops a match its matched neighbours contradict. They run after
//! completion, before the nearly horizontal rounds (which then take their context from the
//! matches kept); the left-right check runs on the final matches.
//!
//! Every ranking ends with a tie-break on image position, so that the result does not depend
//! on the order in which segments were extracted (a local run sees them in another order).

mod candidates;
mod checks;
mod completion;
mod diagnostics;
mod evidence;
mod geometry;
mod horizontal;
mod mutual;
mod pairs;
mod params;
mod photometric;
mod propagation;
mod support;
mod workspace;

pub use diagnostics::{CandidateDiagnosis, PairDiagnosis};
pub use evidence::MatchEvidence;
pub use mutual::MutualCheck;
pub use pairs::PairConstraint;
pub use params::{MatchChecks, MatchParams};
pub use photometric::{ImagePatch, StereoImages};
pub use workspace::{MatchWorkspace, SegmentMatch};

#[cfg(test)]
mod test_support;
