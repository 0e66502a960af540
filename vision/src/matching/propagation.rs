//! Propagation and validation: matches grow best first from the seeds to the neighbouring left
//! segments under the continuity constraint, each checked for uniqueness (the right rows it
//! uses still free) and left-right consistency.

use super::geometry::rows_overlap;
use super::pairs::{continuous, Candidate, NONE};
use super::params::MatchParams;
use super::workspace::{MatchWorkspace, Queued, MAX_PIECES_PER_RIGHT};

impl MatchWorkspace {
    /// The best candidate of each left segment, and the candidates grouped by right segment
    /// (what left-right consistency compares).
    pub(super) fn best_candidates(&mut self, n_left: usize, n_right: usize) {
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
    pub(super) fn consistent(&self, k: usize, params: &MatchParams) -> bool {
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
    pub(super) fn right_free(&self, c: &Candidate) -> bool {
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

    pub(super) fn take_right(&mut self, c: &Candidate) {
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

    /// Prediction and propagation: the seeds, then matches grown from them best first.
    pub(super) fn grow(&mut self, n_left: usize, n_right: usize, params: &MatchParams) {
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
    }
}
