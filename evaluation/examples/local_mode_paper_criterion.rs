//! The local mode judged by the paper's criterion ("with respect to the global approach, we do
//! not miss matches nor obtain new errors within the regions of interest") as well as by
//! identity, on the four Middlebury pairs of the shared data: 20 still 100x100 regions per pair
//! on a 5x4 grid; one single pass per fixed context margin given on the command line, then the
//! adaptive mode (context chosen from the data), then the exact mode.
//!
//! Per pair and mode, over the global matches whose left segment lies inside the region (the
//! judging is shared with `tests/local_mode_criterion.rs`, see `tests/paper_criterion/mod.rs`):
//! - `identical`: found locally with the same segments and disparities;
//! - `covered`: not identical, but a local match lies on the same left line over at least half
//!   of the global segment, with disparities within 1 px of the global ones at both ends of the
//!   overlap (nearly horizontal: on the same right line);
//! - `missed`: neither, although the global match is right by the ground truth;
//! - `new errors`: local matches inside the region that are wrong by the ground truth and do
//!   not cover a global match that is wrong too.
//!
//! Times are the median and the 90th percentile over the regions of `run_local` alone, each
//! region's time the median of 5 runs, on this machine; the whole-image run's median over 20
//! runs is printed first for comparison.
//!
//! `cargo run --release -p videt-evaluation --example local_mode_paper_criterion [-- 32 64 96]`

#[path = "../tests/paper_criterion/mod.rs"]
mod paper_criterion;

use paper_criterion::{compare, grid_regions, Tally};
use std::time::Instant;
use videt_evaluation::{load_middlebury_truth, MIDDLEBURY_PAIRS};
use videt_vision::roi::LocalContext;
use videt_vision::{GrayView, StereoPipeline, VisionParams};

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
    // Single passes with each fixed margin, then the adaptive and the exact modes.
    let mut modes: Vec<(String, VisionParams)> = margins
        .iter()
        .map(|&margin| {
            let mut p = VisionParams::default();
            p.local.exact = false;
            p.local.context = LocalContext::Fixed;
            p.local.context_margin_px = margin;
            (format!("single pass, margin {margin} px"), p)
        })
        .collect();
    let mut adaptive = VisionParams::default();
    adaptive.local.exact = false;
    adaptive.local.context = LocalContext::Adaptive;
    modes.push(("adaptive".into(), adaptive));
    modes.push(("exact".into(), VisionParams::default()));
    println!(
        "{:<8} {:<28} {:>6} {:>9} {:>7} {:>6} {:>10} {:>10} {:>8}",
        "pair",
        "mode",
        "global",
        "identical",
        "covered",
        "missed",
        "new errors",
        "median ms",
        "p90 ms"
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
        for (mode, params) in &modes {
            let mut tally = Tally::default();
            let mut times_ms = Vec::new();
            for region in grid_regions(lv.width() as f32, lv.height() as f32) {
                let mut runs: Vec<f64> = (0..5)
                    .map(|_| {
                        let start = Instant::now();
                        pipeline
                            .run_local(&lv, &rv, None, params, &region)
                            .map(|_| start.elapsed().as_secs_f64() * 1e3)
                    })
                    .collect::<Result<_, _>>()?;
                runs.sort_by(f64::total_cmp);
                times_ms.push(runs[runs.len() / 2]);
                tally.add(&compare(
                    &global,
                    pipeline.output(),
                    &truth,
                    &mut Vec::new(),
                ));
            }
            times_ms.sort_by(f64::total_cmp);
            println!(
                "{:<8} {:<28} {:>6} {:>9} {:>7} {:>6} {:>10} {:>10.3} {:>8.3}",
                name,
                mode,
                tally.global,
                tally.identical,
                tally.covered,
                tally.missed,
                tally.new_errors,
                times_ms[times_ms.len() / 2],
                times_ms[times_ms.len() * 9 / 10]
            );
        }
    }
    Ok(())
}
