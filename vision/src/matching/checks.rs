//! Checks against wrong matches, run on the matches of prediction, propagation and completion
//! (before the nearly horizontal rounds, which then take their context from the matches
//! kept):
//!
//! - the **evidence** of each match is gathered from the whole set, before any match is
//!   dropped, so that the result does not depend on the order of the segments: how many of
//!   its matched neighbours agree with its disparity within the matching precision (and how
//!   many contradict it), the best rival candidate of its left segment (another disparity),
//!   and its photometric error;
//! - a **confidence** in `[0, 1]` is made of it ([`MatchEvidence::confidence`]); a match below
//!   [`MatchParams::min_confidence`] is dropped;
//! - the **surface check** ([`MatchParams::surface_check`]) drops a match its neighbourhood
//!   contradicts: at least [`MatchParams::surface_min_disagreeing`] matched neighbours disagree
//!   with it and fewer agree than [`MatchParams::surface_min_agreeing_ratio`] times those.
//!   Such a match is an isolated 3-D segment off the surface around it: it would become a
//!   ridge or a hole in the relief.
//!
//! Nearly horizontal matches take their disparity from a neighbour: they are neither checked
//! nor counted as a neighbour's evidence.

use super::evidence::MatchEvidence;
use super::pairs::{Candidate, NONE};
use super::params::MatchParams;
use super::workspace::MatchWorkspace;

/// Whether two candidates' disparities at the closest points of their left segments agree
/// within the surface check's precision.
fn agree(a: &Candidate, b: &Candidate, t_a: f32, t_b: f32, distance: f32, p: &MatchParams) -> bool {
    (a.disparity_at(t_a) - b.disparity_at(t_b)).abs()
        <= p.surface_tolerance_px + p.surface_gradient_limit * distance
}

impl MatchWorkspace {
    /// Gathers the evidence of every accepted match (into `evidence`, by left segment), then
    /// drops those the confidence threshold or the surface check reject.
    pub(super) fn check_matches(&mut self, n_left: usize, params: &MatchParams) {
        self.evidence.clear();
        self.evidence.resize(n_left, MatchEvidence::default());
        for i in 0..n_left {
            let k = self.accepted_candidate[i];
            if k == NONE {
                continue;
            }
            let c = self.candidates[k as usize];
            if c.horizontal {
                continue;
            }
            let mut e = MatchEvidence {
                completed: self.completed[i],
                ..MatchEvidence::default()
            };
            for n in self.neighbours_of(i as u32) {
                let nb = self.neighbours[n];
                let a = self.accepted_candidate[nb.other as usize];
                if a == NONE {
                    continue;
                }
                let other = &self.candidates[a as usize];
                if other.horizontal {
                    continue;
                }
                if agree(&c, other, nb.t_self, nb.t_other, nb.distance, params) {
                    e.agreeing = e.agreeing.saturating_add(1);
                } else {
                    e.disagreeing = e.disagreeing.saturating_add(1);
                }
            }
            let middle = c.disparity_at(0.5);
            for m in self.candidates_of(i as u32) {
                let r = &self.candidates[m];
                if m == k as usize
                    || r.horizontal
                    || (r.disparity_at(0.5) - middle).abs() <= params.surface_tolerance_px
                {
                    continue;
                }
                if e.rival_support.is_none_or(|s| r.support > s) {
                    e.rival_support = Some(r.support);
                }
            }
            // Measured when the pair became a candidate or a completion pair (`NaN` without
            // images).
            e.photometric_error = c.photometric_error;
            self.evidence[i] = e;
        }
        if params.min_confidence <= 0.0 && !params.surface_check {
            return;
        }
        for i in 0..n_left {
            let k = self.accepted_candidate[i];
            if k == NONE || self.candidates[k as usize].horizontal {
                continue;
            }
            let e = &self.evidence[i];
            let support = self.candidates[k as usize].support;
            if e.confidence(support, params) < params.min_confidence
                || (params.surface_check && e.contradicted(params))
            {
                self.accepted_candidate[i] = NONE;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matching::test_support::{scene, seg};
    use crate::matching::SegmentMatch;
    use crate::segments::Segment;

    /// The fan of [`scene`] on a plane at 23 px, and one more segment among it whose partner
    /// lies 12 px off the plane (an edge the matcher would turn into a spike). Seeds need no
    /// support, so that the lone pair is matched without the checks.
    fn scene_with_a_lone_pair() -> (Vec<Segment>, Vec<Segment>, MatchParams) {
        let (mut left, mut right) = scene(23.0);
        let lone = seg(150.0, 48.0, 150.0, 90.0, 1, [5.0, 250.0]);
        let mut partner = lone;
        partner.start[0] -= 35.0;
        partner.end[0] -= 35.0;
        left.push(lone);
        right.push(partner);
        let mut params = MatchParams {
            min_seed_support: 0,
            ..MatchParams::default()
        };
        super::super::MatchChecks::NONE.apply(&mut params);
        (left, right, params)
    }

    fn run(left: &[Segment], right: &[Segment], params: &MatchParams) -> Vec<SegmentMatch> {
        let mut out = Vec::new();
        MatchWorkspace::new().match_segments(left, right, None, params, &mut out);
        out
    }

    #[test]
    fn a_lone_match_off_the_surface_is_dropped_by_the_surface_check() {
        let (left, right, params) = scene_with_a_lone_pair();
        let lone = (left.len() - 1) as u32;
        let without = run(&left, &right, &params);
        let m = without.iter().find(|m| m.left == lone).expect("matched");
        assert!(
            m.evidence.agreeing == 0 && m.evidence.disagreeing >= 2,
            "{m:?}"
        );
        assert!(m.evidence.contradicted(&params));
        let checked = run(
            &left,
            &right,
            &MatchParams {
                surface_check: true,
                ..params
            },
        );
        assert!(checked.iter().all(|m| m.left != lone));
        assert_eq!(checked.len(), without.len() - 1, "only the lone match goes");
    }

    #[test]
    fn a_confidence_threshold_drops_the_lone_match_first() {
        let (left, right, params) = scene_with_a_lone_pair();
        let lone = (left.len() - 1) as u32;
        let without = run(&left, &right, &params);
        let confidence = |m: &SegmentMatch| m.evidence.confidence(m.support, &params);
        let lone_confidence = confidence(without.iter().find(|m| m.left == lone).unwrap());
        let lowest_other = without
            .iter()
            .filter(|m| m.left != lone)
            .map(confidence)
            .fold(f32::INFINITY, f32::min);
        assert!(
            lone_confidence < lowest_other,
            "{lone_confidence} {lowest_other}"
        );
        let threshold = 0.5 * (lone_confidence + lowest_other);
        let checked = run(
            &left,
            &right,
            &MatchParams {
                min_confidence: threshold,
                ..params
            },
        );
        assert!(checked.iter().all(|m| m.left != lone));
        assert_eq!(checked.len(), without.len() - 1);
    }

    #[test]
    fn confidence_is_the_product_of_its_three_factors() {
        let p = MatchParams::default();
        let clean = MatchEvidence {
            agreeing: 8,
            disagreeing: 0,
            rival_support: None,
            photometric_error: 0.0,
            completed: false,
        };
        assert!((clean.confidence(5, &p) - 0.9).abs() < 1e-6);
        // A rival as well supported halves the margin factor.
        let rivalled = MatchEvidence {
            rival_support: Some(5),
            ..clean
        };
        assert!((rivalled.confidence(5, &p) - 0.45).abs() < 1e-6);
        // A photometric error at twice the completion limit leaves nothing.
        let unlike = MatchEvidence {
            photometric_error: 2.0 * p.completion_max_photometric_error,
            ..clean
        };
        assert_eq!(unlike.confidence(5, &p), 0.0);
        // Unknown photometry does not count against a match.
        let unknown = MatchEvidence {
            photometric_error: f32::NAN,
            ..clean
        };
        assert_eq!(unknown.confidence(5, &p), clean.confidence(5, &p));
    }

    #[test]
    fn a_match_at_a_depth_step_with_agreeing_neighbours_is_not_contradicted() {
        let p = MatchParams::default();
        let step = MatchEvidence {
            agreeing: 3,
            disagreeing: 5,
            ..MatchEvidence::default()
        };
        assert!(!step.contradicted(&p));
        let isolated = MatchEvidence {
            agreeing: 1,
            disagreeing: 5,
            ..MatchEvidence::default()
        };
        assert!(isolated.contradicted(&p));
    }
}
