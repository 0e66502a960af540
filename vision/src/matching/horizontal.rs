//! Nearly horizontal segments: matched after propagation, in rounds, from the disparity of
//! their closest matched neighbour, to a right segment lying on them once shifted by it.

use super::geometry::{min_max, rows_overlap};
use super::pairs::NONE;
use super::params::MatchParams;
use super::workspace::{MatchWorkspace, MAX_PIECES_PER_RIGHT};
use crate::segments::Segment;

impl MatchWorkspace {
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

    /// One round of matching nearly horizontal left segments from the matches accepted before
    /// the round: each unmatched one takes its context disparity from its closest matched
    /// neighbour (a nearly horizontal neighbour only if matched in an earlier round) and
    /// proposes its best candidate lying on it once shifted by that disparity; proposals are
    /// then accepted best first where the right segment is still free. The result depends
    /// only on the matches before the round, not on the order of the segments. Returns whether
    /// anything was accepted.
    pub(super) fn match_horizontal_round(
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
