//! Parameters of the matcher: the limits of every stage, their defaults and their check.

use crate::error::VisionError;

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
    /// Checks: a match whose confidence ([`MatchEvidence::confidence`]) is below this is
    /// dropped (0: none is).
    ///
    /// [`MatchEvidence::confidence`]: super::MatchEvidence::confidence
    pub min_confidence: f32,
    /// Checks: drop a match its matched neighbours contradict (see
    /// [`MatchParams::surface_min_disagreeing`]).
    pub surface_check: bool,
    /// Checks: a matched neighbour agrees with a match when their disparities at the closest
    /// points differ by at most this plus [`MatchParams::surface_gradient_limit`] times their
    /// distance, pixels (the matching precision).
    pub surface_tolerance_px: f32,
    /// Checks: allowed disparity change per pixel of distance for an agreeing neighbour.
    pub surface_gradient_limit: f32,
    /// Surface check: a match is contradicted when at least this many matched neighbours
    /// disagree with it ...
    pub surface_min_disagreeing: u32,
    /// ... and fewer than this times as many agree.
    pub surface_min_agreeing_ratio: f32,
    /// Left-right consistency by a second run: the right segments are matched to the left
    /// ones by the same algorithm (the pair mirrored), and a match is kept only when the
    /// right segment's match in that run is the same left segment, or a left segment on the
    /// same rows with a disparity within [`MatchParams::mutual_tolerance_px`].
    pub mutual_check: bool,
    /// Mutual check: largest disparity difference of the two runs' matches, pixels.
    pub mutual_tolerance_px: f32,
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
    /// (beyond the continuity limit) are at most half the agreeing ones. The checks against
    /// wrong matches are off: on the pairs they were judged on (the shared Middlebury pairs,
    /// by the area of relief deviating from the true surface), each costs more relief, through
    /// the correct matches it drops, than it saves; their own limits (surface tolerance 1 px
    /// plus 0.1 px/px, contradicted by >= 2 with fewer than half as many agreeing, left-right
    /// agreement within 1 px) apply when they are switched on.
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
            min_confidence: 0.0,
            surface_check: false,
            surface_tolerance_px: 1.0,
            surface_gradient_limit: 0.1,
            surface_min_disagreeing: 2,
            surface_min_agreeing_ratio: 0.5,
            mutual_check: false,
            mutual_tolerance_px: 1.0,
        }
    }
}

/// The checks against wrong matches a configuration switches (the other limits of the checks
/// stay [`MatchParams`]' own).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchChecks {
    /// [`MatchParams::mutual_check`].
    pub left_right: bool,
    /// [`MatchParams::min_confidence`] (0: no threshold).
    pub min_confidence: f32,
    /// [`MatchParams::surface_check`].
    pub surface: bool,
}

impl MatchChecks {
    /// No check.
    pub const NONE: MatchChecks = MatchChecks {
        left_right: false,
        min_confidence: 0.0,
        surface: false,
    };

    /// The checks `params` switch on.
    pub fn of(params: &MatchParams) -> MatchChecks {
        MatchChecks {
            left_right: params.mutual_check,
            min_confidence: params.min_confidence,
            surface: params.surface_check,
        }
    }

    /// Switches `params`' checks to these.
    pub fn apply(&self, params: &mut MatchParams) {
        params.mutual_check = self.left_right;
        params.min_confidence = self.min_confidence;
        params.surface_check = self.surface;
    }
}

impl std::str::FromStr for MatchChecks {
    type Err = String;

    /// `none`, or a comma-separated list of `left-right`, `surface` and `confidence=T` (T in
    /// 0..=1).
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let mut checks = MatchChecks::NONE;
        if text.trim() == "none" {
            return Ok(checks);
        }
        for item in text.split(',').map(str::trim) {
            match item.split_once('=') {
                None if item == "left-right" => checks.left_right = true,
                None if item == "surface" => checks.surface = true,
                Some(("confidence", value)) => {
                    checks.min_confidence = value
                        .trim()
                        .parse::<f32>()
                        .ok()
                        .filter(|v| (0.0..=1.0).contains(v))
                        .ok_or_else(|| {
                            format!("confidence={value}: the threshold must be in 0..=1")
                        })?;
                }
                _ => {
                    return Err(format!(
                        "unknown check {item:?}: expected none, or a list of left-right, surface, confidence=T"
                    ))
                }
            }
        }
        Ok(checks)
    }
}

impl std::fmt::Display for MatchChecks {
    /// The form [`str::parse`] reads.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut names = Vec::new();
        if self.left_right {
            names.push("left-right".to_string());
        }
        if self.surface {
            names.push("surface".to_string());
        }
        if self.min_confidence > 0.0 {
            names.push(format!("confidence={}", self.min_confidence));
        }
        if names.is_empty() {
            f.write_str("none")
        } else {
            f.write_str(&names.join(","))
        }
    }
}

impl Default for MatchChecks {
    /// The checks of [`MatchParams::default`].
    fn default() -> Self {
        MatchChecks::of(&MatchParams::default())
    }
}

impl MatchParams {
    /// Checks the parameter ranges.
    pub fn validate(&self) -> Result<(), VisionError> {
        let checks: [(&'static str, f32, bool, &'static str); 10] = [
            (
                "matching.min_confidence",
                self.min_confidence,
                (0.0..=1.0).contains(&self.min_confidence),
                "0..=1",
            ),
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checks_are_read_and_written_in_one_form() {
        assert_eq!("none".parse::<MatchChecks>().unwrap(), MatchChecks::NONE);
        let c: MatchChecks = "left-right, confidence=0.25".parse().unwrap();
        assert!(c.left_right && !c.surface && (c.min_confidence - 0.25).abs() < 1e-6);
        assert_eq!(c.to_string().parse::<MatchChecks>().unwrap(), c);
        assert_eq!(MatchChecks::NONE.to_string(), "none");
        assert!("confidence=2"
            .parse::<MatchChecks>()
            .unwrap_err()
            .contains("0..=1"));
        assert!("lr"
            .parse::<MatchChecks>()
            .unwrap_err()
            .contains("left-right"));
    }

    #[test]
    fn a_confidence_threshold_out_of_range_is_refused_by_name() {
        let p = MatchParams {
            min_confidence: 1.5,
            ..MatchParams::default()
        };
        assert!(p
            .validate()
            .unwrap_err()
            .to_string()
            .contains("min_confidence"));
    }
}
