//! Matching accuracy on the Middlebury pairs of the shared test data: per pair, the segments
//! extracted, the fraction of left segments matched and the fraction of wrong matches (see
//! `videt_vision::evaluation` for how a match is judged).
//!
//! `cargo run --release -p videt-vision --example stereo_accuracy`

use videt_vision::evaluation::{evaluate, DisparityMap};
use videt_vision::{run_pipeline, GrayView, VisionParams};

/// The pairs and the scale of their 8-bit ground truth.
const PAIRS: [(&str, f32); 4] = [("tsukuba", 16.0), ("venus", 8.0), ("cones", 4.0), ("teddy", 4.0)];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let params = VisionParams::default();
    println!(
        "{:<8} {:>6} {:>6} {:>7} {:>8} {:>6} {:>6} {:>6} {:>8}",
        "pair", "left", "right", "matched", "fraction", "horiz", "wrong", "uneval", "wrong%"
    );
    for (name, scale) in PAIRS {
        let Some(dir) = videt_testdata::data_dir(&format!("stereo/{name}")) else {
            continue;
        };
        let left = image::open(dir.join("left.ppm"))?.to_luma8();
        let right = image::open(dir.join("right.ppm"))?.to_luma8();
        let mut truth = DisparityMap::from_scaled(&image::open(dir.join("disp_left.pgm"))?.to_luma8(), scale);
        let right_truth = dir.join("disp_right.pgm");
        if right_truth.exists() {
            let r = DisparityMap::from_scaled(&image::open(right_truth)?.to_luma8(), scale);
            truth.mask_occlusions(&r, 1.0);
        }
        let out = run_pipeline(
            &GrayView::from_image(&left)?,
            &GrayView::from_image(&right)?,
            None,
            &params,
        )?;
        let r = evaluate(&out.left_segments, out.right_segments.len(), &out.matches, &truth);
        println!(
            "{:<8} {:>6} {:>6} {:>7} {:>7.1}% {:>6} {:>6} {:>6} {:>7.2}%  ({:.2} ms)",
            name,
            r.left_segments,
            r.right_segments,
            r.matches,
            100.0 * r.matched_fraction(),
            r.horizontal_matches,
            r.wrong,
            r.unevaluated,
            100.0 * r.wrong_fraction(),
            out.timings.total.as_secs_f64() * 1e3,
        );
        if std::env::args().any(|a| a == "--detail") {
            detail(&out, &truth);
        }
    }
    Ok(())
}

/// Breakdown of wrong matches (printed with `--detail`).
fn detail(out: &videt_vision::PipelineOutput, truth: &DisparityMap) {
    use videt_vision::evaluation::{judge_match, MatchVerdict};
    let mut table = [[0usize; 3]; 4];
    for m in &out.matches {
        let row = (m.nearly_horizontal as usize) * 2 + m.predicted as usize;
        let v = judge_match(&out.left_segments[m.left as usize], m, truth);
        let col = match v {
            MatchVerdict::Correct => 0,
            MatchVerdict::Wrong => 1,
            MatchVerdict::Unevaluated => 2,
        };
        table[row][col] += 1;
    }
    for (row, name) in ["propagated", "predicted", "horiz", "horiz-pred"].iter().enumerate() {
        println!(
            "    {name:<11} correct {:>4} wrong {:>4} uneval {:>4}",
            table[row][0], table[row][1], table[row][2]
        );
    }
    let t = &out.timings;
    println!(
        "    times ms: edges {:.2} chains {:.2} segments {:.2} matching {:.2}",
        t.edges.as_secs_f64() * 1e3,
        t.chains.as_secs_f64() * 1e3,
        t.segments.as_secs_f64() * 1e3,
        t.matching.as_secs_f64() * 1e3
    );
}
