//! Prediction: the neighbourhoods of the left segments, and the support of each candidate (the
//! neighbours having a candidate continuous with it) that ranks hypotheses and seeds
//! propagation.

use super::geometry::Extent;
use super::pairs::{continuous, Neighbour};
use super::params::MatchParams;
use super::workspace::MatchWorkspace;
use crate::segments::Segment;

impl MatchWorkspace {
    /// Neighbours of each left segment: the `max_neighbours` closest segments within the
    /// radius (ties broken by position, so that the result does not depend on the order of
    /// the segments).
    pub(super) fn build_neighbours(&mut self, left: &[Segment], params: &MatchParams) {
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

    /// Support of each candidate: neighbouring left segments (not nearly horizontal) having a
    /// non-horizontal candidate compatible under the continuity constraint.
    pub(super) fn compute_support(&mut self, params: &MatchParams) {
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
}
