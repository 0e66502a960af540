//! Candidate generation: the pairs of each left segment that meet the weak constraints and the
//! photometric check, with the right segments alone or as two joined fragments of one edge,
//! and the pairs kept for completion.

use super::geometry::{angle_difference, line_distance, min_max, Extent};
use super::pairs::{evaluate_pair, Candidate, PairConstraint};
use super::params::MatchParams;
use super::photometric::{photometric_error_within, StereoImages};
use super::workspace::{JoinedFragments, MatchWorkspace, RightKey};
use crate::segments::Segment;

impl MatchWorkspace {
    /// The candidates of every left segment, grouped by left segment, and the completion pairs.
    pub(super) fn build_candidates(
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
                let mut c = match evaluate_pair(i as u32, l, j, r, l_horizontal, params) {
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
                        // Beyond both limits the exact error is not needed.
                        let error = photometric_error_within(
                            l,
                            &c,
                            images,
                            params.photometric_sampling_insensitive,
                            if complete {
                                params
                                    .max_photometric_error
                                    .max(params.completion_max_photometric_error)
                            } else {
                                params.max_photometric_error
                            },
                        );
                        if error > params.max_photometric_error {
                            if complete {
                                self.loose.push((Candidate { tight: false, ..c }, error));
                            }
                            continue;
                        }
                        c.photometric_error = error;
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
                let error = photometric_error_within(
                    l,
                    &c,
                    images,
                    params.photometric_sampling_insensitive,
                    params.max_photometric_error,
                );
                if error > params.max_photometric_error {
                    continue;
                }
                c.photometric_error = error;
            }
            self.candidates.push(c);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matching::test_support::{scene, seg};

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
}
