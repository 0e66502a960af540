//! Diagnostics of the last run, not used by the matcher: how it treated a pair, and whether it
//! left reachable segments unmatched.

use super::geometry::min_max;
use super::pairs::{continuous, evaluate_pair, PairConstraint, NONE};
use super::params::MatchParams;
use super::photometric::{photometric_error, StereoImages};
use super::workspace::MatchWorkspace;
use crate::segments::Segment;

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

impl MatchWorkspace {
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
}
