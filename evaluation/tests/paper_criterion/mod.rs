//! The paper's criterion for the local mode ("with respect to the global approach, we do not
//! miss matches nor obtain new errors within the regions of interest"), shared by the test
//! `local_mode_criterion` and the example `local_mode_paper_criterion`.
//!
//! Over the global matches whose left segment lies inside the region of interest:
//! - `identical`: found locally with the same segments and disparities;
//! - `covered`: not identical, but a local match lies on the same left line over at least half
//!   of the global segment, with disparities within 1 px of the global ones at both ends of the
//!   overlap (nearly horizontal: on the same right line);
//! - `missed`: neither, although the global match is right by the ground truth (or cannot be
//!   judged by it);
//! - `new_errors`: local matches inside the region that are wrong by the ground truth and do not
//!   cover a global match that is wrong too.
//!
//! The criterion holds when nothing is missed and there is no new error.
#![allow(dead_code)]

use videt_evaluation::{judge, DisparityMap, MatchVerdict};
use videt_vision::matching::SegmentMatch;
use videt_vision::segments::Segment;
use videt_vision::{LocalRegion, PipelineOutput, PixelRect};

/// A match with its two segments.
#[derive(Debug, Clone, Copy)]
pub struct Found<'a> {
    /// Left segment.
    pub left: &'a Segment,
    /// Right segment.
    pub right: &'a Segment,
    /// The match.
    pub m: &'a SegmentMatch,
}

impl Found<'_> {
    /// Same segments and disparities.
    pub fn identical(&self, o: &Found<'_>) -> bool {
        same_segment(self.left, o.left)
            && same_segment(self.right, o.right)
            && (0..2).all(|k| (self.m.disparity_px[k] - o.m.disparity_px[k]).abs() < 1e-3)
    }

    /// Whether `o` lies on this match's left line over at least half of it with the same
    /// disparities (nearly horizontal: on the same right line).
    pub fn covered_by(&self, o: &Found<'_>) -> bool {
        let g = self.left;
        if line_distance(o.left.start, g) > 1.5 || line_distance(o.left.end, g) > 1.5 {
            return false;
        }
        let (a, b) = (along(o.left.start, g), along(o.left.end, g));
        let (lo, hi) = (a.min(b).max(0.0), a.max(b).min(1.0));
        if hi - lo < 0.5 {
            return false;
        }
        if self.m.nearly_horizontal {
            return line_distance(o.right.start, self.right) <= 1.5
                && line_distance(o.right.end, self.right) <= 1.5;
        }
        [lo, hi].into_iter().all(|t| {
            let p = [
                g.start[0] + t * (g.end[0] - g.start[0]),
                g.start[1] + t * (g.end[1] - g.start[1]),
            ];
            (disparity_at(self.m, t) - disparity_at(o.m, along(p, o.left))).abs() <= 1.0
        })
    }

    /// Wrong by the ground truth.
    pub fn wrong(&self, truth: &DisparityMap) -> bool {
        judge(self.left, self.right, self.m, truth) == MatchVerdict::Wrong
    }
}

fn same_segment(a: &Segment, b: &Segment) -> bool {
    (0..2).all(|k| (a.start[k] - b.start[k]).abs() < 1e-3 && (a.end[k] - b.end[k]).abs() < 1e-3)
}

/// Distance from `p` to the line through `s`.
fn line_distance(p: [f32; 2], s: &Segment) -> f32 {
    let (dx, dy) = (s.end[0] - s.start[0], s.end[1] - s.start[1]);
    let norm = (dx * dx + dy * dy).sqrt().max(1e-6);
    ((p[0] - s.start[0]) * dy - (p[1] - s.start[1]) * dx).abs() / norm
}

/// Position of the projection of `p` along `s`: 0 at its start, 1 at its end.
fn along(p: [f32; 2], s: &Segment) -> f32 {
    let (dx, dy) = (s.end[0] - s.start[0], s.end[1] - s.start[1]);
    ((p[0] - s.start[0]) * dx + (p[1] - s.start[1]) * dy) / (dx * dx + dy * dy).max(1e-6)
}

fn disparity_at(m: &SegmentMatch, t: f32) -> f32 {
    m.disparity_px[0] + t * (m.disparity_px[1] - m.disparity_px[0])
}

/// The matches of `out` whose left segment lies inside `roi`.
pub fn inside<'a>(out: &'a PipelineOutput, roi: &PixelRect) -> Vec<Found<'a>> {
    out.matches
        .iter()
        .map(|m| Found {
            left: &out.left_segments[m.left as usize],
            right: &out.right_segments[m.right as usize],
            m,
        })
        .filter(|f| {
            roi.contains(f.left.start[0], f.left.start[1])
                && roi.contains(f.left.end[0], f.left.end[1])
        })
        .collect()
}

/// Counts over one or more regions.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Tally {
    /// Global matches inside the regions.
    pub global: usize,
    /// Of which found identically.
    pub identical: usize,
    /// Of which covered by a different local match.
    pub covered: usize,
    /// Of which missed although right (or unjudged) by the ground truth.
    pub missed: usize,
    /// Local matches inside the regions wrong by the ground truth and not a global error.
    pub new_errors: usize,
}

impl Tally {
    /// Adds the counts of `o`.
    pub fn add(&mut self, o: &Tally) {
        self.global += o.global;
        self.identical += o.identical;
        self.covered += o.covered;
        self.missed += o.missed;
        self.new_errors += o.new_errors;
    }

    /// Whether the paper's criterion holds: nothing missed, no new error.
    pub fn holds(&self) -> bool {
        self.missed == 0 && self.new_errors == 0
    }
}

/// Judges the local run `local` (its region of interest is the one it reports) against the
/// whole-image run `global`; the descriptions of the missed matches and new errors are pushed
/// to `faults`.
pub fn compare(
    global: &PipelineOutput,
    local: &PipelineOutput,
    truth: &DisparityMap,
    faults: &mut Vec<String>,
) -> Tally {
    let roi = local.local.expect("a local run reports its windows").roi;
    let expected = inside(global, &roi);
    let found = inside(local, &roi);
    let mut t = Tally::default();
    for g in &expected {
        t.global += 1;
        if found.iter().any(|f| g.identical(f)) {
            t.identical += 1;
        } else if found.iter().any(|f| g.covered_by(f)) {
            t.covered += 1;
        } else if !g.wrong(truth) {
            t.missed += 1;
            faults.push(format!(
                "missed global match {:?} -> {:?}, disparities {:?}",
                g.left.start_end(),
                g.right.start_end(),
                g.m.disparity_px
            ));
        }
    }
    for f in &found {
        if f.wrong(truth) && !expected.iter().any(|g| f.covered_by(g) && g.wrong(truth)) {
            t.new_errors += 1;
            faults.push(format!(
                "new error {:?} -> {:?}, disparities {:?}",
                f.left.start_end(),
                f.right.start_end(),
                f.m.disparity_px
            ));
        }
    }
    t
}

/// Endpoints of a segment, for messages.
trait StartEnd {
    fn start_end(&self) -> [[f32; 2]; 2];
}

impl StartEnd for Segment {
    fn start_end(&self) -> [[f32; 2]; 2] {
        [self.start, self.end]
    }
}

/// A still `size x size` region centred at `(x, y)`.
pub fn still(x: f32, y: f32, size: f32) -> LocalRegion {
    LocalRegion {
        centre_px: [x, y],
        size_px: [size, size],
        velocity_px_per_frame: [0.0, 0.0],
    }
}

/// The 20 still 100x100 regions of a 5x4 grid over a `width x height` image, each inside it.
pub fn grid_regions(width: f32, height: f32) -> Vec<LocalRegion> {
    (0..20)
        .map(|k| {
            let (fx, fy) = ((k % 5) as f32 / 4.0, (k / 5) as f32 / 3.0);
            still(
                50.0 + fx * (width - 100.0),
                50.0 + fy * (height - 100.0),
                100.0,
            )
        })
        .collect()
}
