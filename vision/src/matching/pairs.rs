//! Candidate pairs and the constraints on them: the weak constraints a pair of a left and a
//! right segment must meet to be a candidate (the tight ones of prediction among them), and
//! the continuity constraint between the candidates of two neighbouring left segments.

use std::cmp::Ordering;

use super::geometry::{angle_difference, min_max, segment_distance};
use super::params::MatchParams;
use crate::segments::Segment;

pub(super) const NONE: u32 = u32::MAX;

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

/// A candidate pair.
#[derive(Debug, Clone, Copy)]
pub(super) struct Candidate {
    pub(super) left: u32,
    pub(super) right: u32,
    /// Disparity at the left start and end rows.
    pub(super) disparity: [f32; 2],
    pub(super) cost: f32,
    /// Photometric error once measured (`NaN` before, or without images), grey levels.
    pub(super) photometric_error: f32,
    pub(super) tight: bool,
    pub(super) horizontal: bool,
    pub(super) support: u32,
    /// Rows of the right segment the match uses (all rows for nearly horizontal pairs).
    pub(super) rows: [f32; 2],
    /// Second right piece when the right side is two collinear fragments of one edge
    /// ([`NONE`] otherwise), and the rows of it the match uses.
    pub(super) right2: u32,
    pub(super) rows2: [f32; 2],
    /// Left start row, left start column, right start column: the final tie-break.
    pub(super) position: [f32; 3],
}

impl Candidate {
    /// Disparity at parameter `t` in `[0, 1]` along the left segment.
    pub(super) fn disparity_at(&self, t: f32) -> f32 {
        self.disparity[0] + t * (self.disparity[1] - self.disparity[0])
    }

    /// Ranking: more support, then lower cost, then position (independent of list order).
    pub(super) fn better_than(&self, other: &Candidate) -> bool {
        self.rank_cmp(other) == Ordering::Greater
    }

    pub(super) fn rank_cmp(&self, other: &Candidate) -> Ordering {
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
pub(super) struct Neighbour {
    pub(super) other: u32,
    /// Start point of the other segment (order-independent tie-break).
    pub(super) other_start: [f32; 2],
    pub(super) t_self: f32,
    pub(super) t_other: f32,
    pub(super) distance: f32,
}

impl Neighbour {
    /// Segment `b` (index `j`) as a neighbour of `a`, when their closest points are within
    /// `radius`.
    pub(super) fn within(a: &Segment, j: u32, b: &Segment, radius: f32) -> Option<Self> {
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
    pub(super) fn seen_from_other(&self, i: u32, a: &Segment) -> Self {
        Neighbour {
            other: i,
            other_start: a.start,
            t_self: self.t_other,
            t_other: self.t_self,
            distance: self.distance,
        }
    }
}

/// Continuity between candidate `a` (on left segment `n`'s owner) and `b` (on `n.other`).
pub(super) fn continuous(
    a: &Candidate,
    b: &Candidate,
    n: &Neighbour,
    params: &MatchParams,
) -> bool {
    let da = a.disparity_at(n.t_self);
    let db = b.disparity_at(n.t_other);
    (da - db).abs() <= params.disparity_tolerance_px + params.disparity_gradient_limit * n.distance
}

/// Evaluates the pair against the weak constraints; the first one failed when it fails them.
pub(super) fn evaluate_pair(
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
        photometric_error: f32::NAN,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matching::test_support::seg;

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
    fn opposite_polarity_is_rejected() {
        let l = seg(100.0, 10.0, 120.0, 90.0, 1, [50.0, 150.0]);
        let r = seg(90.0, 10.0, 110.0, 90.0, -1, [50.0, 150.0]);
        assert!(evaluate_pair(0, &l, 0, &r, false, &MatchParams::default()).is_err());
    }
}
