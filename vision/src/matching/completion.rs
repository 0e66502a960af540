//! Completion: after propagation, a left segment left unmatched may take a pair beyond the
//! candidate limits when its matched neighbours vouch for it.

use std::cmp::Ordering;

use super::geometry::{lerp, project_param, Extent};
use super::pairs::{continuous, Candidate, Neighbour, NONE};
use super::params::MatchParams;
use super::photometric::{photometric_error, StereoImages};
use super::workspace::MatchWorkspace;
use crate::segments::Segment;

impl MatchWorkspace {
    /// Whether completion may take candidate `c`: not nearly horizontal, a disparity change
    /// along it within the completion limit, and its right segment free.
    fn completion_possible(&self, c: &Candidate, params: &MatchParams) -> bool {
        !c.horizontal
            && (c.disparity[1] - c.disparity[0]).abs() <= params.completion_max_disparity_change_px
            && self.right_free(c)
    }

    /// Completion: each left segment left unmatched by propagation (not nearly horizontal)
    /// proposes its candidate or completion pair (see [`MatchParams::completion`]) with the
    /// most matched neighbours meeting the continuity constraint with it, when they are enough,
    /// few contradict it, and its right rows are free; proposals are accepted best first where
    /// the right rows are still free. Decided from the matches of propagation only, so the
    /// result does not depend on the order of the segments.
    pub(super) fn complete(
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
                let (mut c, known_error) = if k < n_strict {
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
                // (A candidate passed the stricter candidate limit: its known error is 0 here
                // and it keeps the error it was measured with.)
                if let Some(images) = images {
                    let error = if known_error.is_nan() {
                        photometric_error(l, &c, images, params.photometric_sampling_insensitive)
                    } else {
                        known_error
                    };
                    if error > params.completion_max_photometric_error {
                        continue;
                    }
                    if k >= n_strict {
                        c.photometric_error = error;
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matching::test_support::{scene, seg};

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
}
