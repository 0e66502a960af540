//! The local mode judged by the paper's criterion ("with respect to the global approach, we do
//! not miss matches nor obtain new errors within the regions of interest") as well as by
//! identity, on the four Middlebury pairs of the shared data: 20 still 100x100 regions per pair
//! on a 5x4 grid, one single pass per context margin given on the command line, then the exact
//! mode.
//!
//! Per pair and mode, over the global matches whose left segment lies inside the region:
//! - `identical`: found locally with the same segments and disparities;
//! - `covered`: not identical, but a local match lies on the same left line over at least half
//!   of the global segment, with disparities within 1 px of the global ones at both ends of the
//!   overlap (nearly horizontal: on the same right line);
//! - `missed`: neither, although the global match is right by the ground truth;
//! - `new errors`: local matches inside the region that are wrong by the ground truth and do
//!   not cover a global match that is wrong too.
//!
//! Times are medians over the regions of `run_local` alone, on this machine; the whole-image
//! run's median over 20 runs is printed first for comparison.
//!
//! `cargo run --release -p videt-vision --example local_mode_paper_criterion [-- 32 64 96]`

use std::time::Instant;
use videt_vision::evaluation::{
    judge, load_middlebury_truth, DisparityMap, MatchVerdict, MIDDLEBURY_PAIRS,
};
use videt_vision::matching::SegmentMatch;
use videt_vision::segments::Segment;
use videt_vision::{
    GrayView, LocalRegion, PipelineOutput, PixelRect, StereoPipeline, VisionParams,
};

/// A match with its two segments.
struct Found<'a> {
    left: &'a Segment,
    right: &'a Segment,
    m: &'a SegmentMatch,
}

impl Found<'_> {
    fn identical(&self, o: &Found<'_>) -> bool {
        same_segment(self.left, o.left)
            && same_segment(self.right, o.right)
            && (0..2).all(|k| (self.m.disparity_px[k] - o.m.disparity_px[k]).abs() < 1e-3)
    }

    /// Whether `o` lies on this match's left line over at least half of it with the same
    /// disparities (nearly horizontal: on the same right line).
    fn covered_by(&self, o: &Found<'_>) -> bool {
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

    fn wrong(&self, truth: &DisparityMap) -> bool {
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

fn inside<'a>(out: &'a PipelineOutput, roi: &PixelRect) -> Vec<Found<'a>> {
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

/// Counts over the regions of one pair: global, identical, covered, missed, new errors.
#[derive(Default)]
struct Tally {
    global: usize,
    identical: usize,
    covered: usize,
    missed: usize,
    new_errors: usize,
    times_ms: Vec<f64>,
}

fn compare(global: &PipelineOutput, local: &PipelineOutput, truth: &DisparityMap, t: &mut Tally) {
    let roi = local.local.expect("a local run reports its windows").roi;
    let expected = inside(global, &roi);
    let found = inside(local, &roi);
    for g in &expected {
        t.global += 1;
        if found.iter().any(|f| g.identical(f)) {
            t.identical += 1;
        } else if found.iter().any(|f| g.covered_by(f)) {
            t.covered += 1;
        } else if !g.wrong(truth) {
            t.missed += 1;
        }
    }
    t.new_errors += found
        .iter()
        .filter(|f| f.wrong(truth))
        .filter(|f| !expected.iter().any(|g| f.covered_by(g) && g.wrong(truth)))
        .count();
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let margins: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse())
        .collect::<Result<_, _>>()?;
    let margins = if margins.is_empty() {
        vec![32, 64, 96]
    } else {
        margins
    };
    // Single passes with each margin, then the exact mode with the default margin.
    let mut modes: Vec<(String, VisionParams)> = margins
        .iter()
        .map(|&margin| {
            let mut p = VisionParams::default();
            p.local.exact = false;
            p.local.context_margin_px = margin;
            (format!("single pass, margin {margin} px"), p)
        })
        .collect();
    modes.push(("exact".into(), VisionParams::default()));
    println!(
        "{:<8} {:<28} {:>6} {:>9} {:>7} {:>6} {:>10} {:>10}",
        "pair", "mode", "global", "identical", "covered", "missed", "new errors", "median ms"
    );
    for (name, scale) in MIDDLEBURY_PAIRS {
        let Some(dir) = videt_testdata::data_dir(&format!("stereo/{name}")) else {
            continue;
        };
        let left = image::open(dir.join("left.ppm"))?.to_luma8();
        let right = image::open(dir.join("right.ppm"))?.to_luma8();
        let truth = load_middlebury_truth(&dir, scale)?;
        let (lv, rv) = (GrayView::from_image(&left)?, GrayView::from_image(&right)?);
        let mut pipeline = StereoPipeline::new();
        let global = pipeline
            .run(&lv, &rv, None, &VisionParams::default())?
            .clone();
        let mut whole_ms: Vec<f64> = (0..20)
            .map(|_| {
                let start = Instant::now();
                pipeline
                    .run(&lv, &rv, None, &VisionParams::default())
                    .map(|_| start.elapsed().as_secs_f64() * 1e3)
            })
            .collect::<Result<_, _>>()?;
        whole_ms.sort_by(f64::total_cmp);
        println!(
            "{:<8} {:<28} {:>54.3}",
            name,
            "whole image, for reference",
            whole_ms[whole_ms.len() / 2]
        );
        let (w, h) = (lv.width() as f32, lv.height() as f32);
        for (mode, params) in &modes {
            let mut tally = Tally::default();
            for k in 0..20 {
                let (fx, fy) = ((k % 5) as f32 / 4.0, (k / 5) as f32 / 3.0);
                let region = LocalRegion {
                    centre_px: [50.0 + fx * (w - 100.0), 50.0 + fy * (h - 100.0)],
                    size_px: [100.0, 100.0],
                    velocity_px_per_frame: [0.0, 0.0],
                };
                let start = Instant::now();
                pipeline.run_local(&lv, &rv, None, params, &region)?;
                tally.times_ms.push(start.elapsed().as_secs_f64() * 1e3);
                compare(&global, pipeline.output(), &truth, &mut tally);
            }
            tally.times_ms.sort_by(f64::total_cmp);
            println!(
                "{:<8} {:<28} {:>6} {:>9} {:>7} {:>6} {:>10} {:>10.3}",
                name,
                mode,
                tally.global,
                tally.identical,
                tally.covered,
                tally.missed,
                tally.new_errors,
                tally.times_ms[tally.times_ms.len() / 2]
            );
        }
    }
    Ok(())
}
