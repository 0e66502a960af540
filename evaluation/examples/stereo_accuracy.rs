//! Matching accuracy on the Middlebury pairs of the shared test data: per pair, the segments
//! extracted, the fraction of left segments matched (every extracted left segment counts,
//! nearly horizontal ones included) and the fraction of wrong matches (see
//! `videt_evaluation` for how a match is judged), and whether the goal (>= 60 %
//! matched, <= 2 % wrong) is met.
//!
//! `cargo run --release -p videt-evaluation --example stereo_accuracy`

use videt_evaluation::{evaluate, load_middlebury_truth, DisparityMap, MIDDLEBURY_PAIRS};
use videt_vision::{run_pipeline, GrayView, VisionParams};

thread_local! {
    static RAW: std::cell::RefCell<Option<DisparityMap>> = const { std::cell::RefCell::new(None) };
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut params = VisionParams::default();
    for arg in std::env::args().skip(1).filter(|a| a.contains('=')) {
        let (key, value) = arg.split_once('=').unwrap_or_default();
        override_param(&mut params, key, value.parse()?)?;
    }
    println!(
        "{:<8} {:>6} {:>6} {:>7} {:>8} {:>6} {:>6} {:>6} {:>8} {:>12} {:>5}",
        "pair",
        "left",
        "right",
        "matched",
        "fraction",
        "horiz",
        "wrong",
        "uneval",
        "wrong%",
        "horiz-d>1px",
        "goal"
    );
    for (name, scale) in MIDDLEBURY_PAIRS {
        let Some(dir) = videt_testdata::data_dir(&format!("stereo/{name}")) else {
            continue;
        };
        let left = image::open(dir.join("left.ppm"))?.to_luma8();
        let right = image::open(dir.join("right.ppm"))?.to_luma8();
        let raw =
            DisparityMap::from_scaled(&image::open(dir.join("disp_left.pgm"))?.to_luma8(), scale);
        RAW.with(|r| *r.borrow_mut() = Some(raw));
        let truth = load_middlebury_truth(&dir, scale)?;
        let out = run_pipeline(
            &GrayView::from_image(&left)?,
            &GrayView::from_image(&right)?,
            None,
            &params,
        )?;
        let r = evaluate(
            &out.left_segments,
            &out.right_segments,
            &out.matches,
            &truth,
        );
        println!(
            "{:<8} {:>6} {:>6} {:>7} {:>7.1}% {:>6} {:>6} {:>6} {:>7.2}% {:>12} {:>5}  ({:.2} ms)",
            name,
            r.left_segments,
            r.right_segments,
            r.matches,
            100.0 * r.matched_fraction(),
            r.horizontal_matches,
            r.wrong,
            r.unevaluated,
            100.0 * r.wrong_fraction(),
            r.horizontal_disparity_wrong,
            if r.matched_fraction() >= 0.6 && r.wrong_fraction() <= 0.02 {
                "met"
            } else {
                "not"
            },
            out.timings.total.as_secs_f64() * 1e3,
        );
        let horizontal = params.matching.horizontal_angle_deg.to_radians();
        let left_horizontal = out
            .left_segments
            .iter()
            .filter(|s| s.is_nearly_horizontal(horizontal))
            .count();
        let left_other = r.left_segments - left_horizontal;
        let matched_other = r.matches - r.horizontal_matches;
        println!(
            "    every match judged by endpoint disparity: {:.2}% wrong; without nearly horizontal \
             segments: {}/{} = {:.1}% matched, {:.2}% wrong",
            100.0 * r.disparity_wrong_fraction_all(),
            matched_other,
            left_other,
            100.0 * matched_other as f64 / left_other.max(1) as f64,
            100.0 * r.wrong_fraction_not_horizontal(),
        );
        if std::env::args().any(|a| a == "--timing") {
            let mut pipeline = videt_vision::StereoPipeline::new();
            let (lv, rv) = (GrayView::from_image(&left)?, GrayView::from_image(&right)?);
            let mut best = [f64::INFINITY; 5];
            for _ in 0..30 {
                let t = pipeline.run(&lv, &rv, None, &params)?.timings;
                for (b, v) in best
                    .iter_mut()
                    .zip([t.edges, t.chains, t.segments, t.matching, t.total])
                {
                    *b = b.min(v.as_secs_f64() * 1e3);
                }
            }
            println!(
                "    best of 30, ms: edges {:.3} chains {:.3} segments {:.3} matching {:.3} total {:.3}",
                best[0], best[1], best[2], best[3], best[4]
            );
        }
        if std::env::args().any(|a| a == "--detail") {
            detail(&out, &truth);
        }
    }
    Ok(())
}

/// Breakdown of wrong matches (printed with `--detail`).
fn detail(out: &videt_vision::PipelineOutput, truth: &DisparityMap) {
    use videt_evaluation::{judge_correspondence, judge_match, MatchVerdict};
    let mut table = [[0usize; 3]; 4];
    for m in &out.matches {
        let row = (m.nearly_horizontal as usize) * 2 + m.predicted as usize;
        let v = if m.nearly_horizontal {
            judge_correspondence(
                &out.left_segments[m.left as usize],
                &out.right_segments[m.right as usize],
                truth,
            )
        } else {
            judge_match(&out.left_segments[m.left as usize], m, truth)
        };
        let col = match v {
            MatchVerdict::Correct => 0,
            MatchVerdict::Wrong => 1,
            MatchVerdict::Unevaluated => 2,
        };
        table[row][col] += 1;
        if v == MatchVerdict::Wrong
            && (m.nearly_horizontal == std::env::var("DUMP").is_ok_and(|d| d == "h"))
            && std::env::var("DUMP").is_ok()
        {
            let l = &out.left_segments[m.left as usize];
            let r = &out.right_segments[m.right as usize];
            let mid = l.midpoint();
            let gt = truth.at(mid[0].round() as i64, mid[1].round() as i64);
            let raw = RAW.with(|r| {
                r.borrow()
                    .as_ref()
                    .and_then(|t: &DisparityMap| t.at(mid[0].round() as i64, mid[1].round() as i64))
            });
            println!(
                "      L{} ({:.0},{:.0})-({:.0},{:.0}) len {:.0} ang {:.0} | R{} ({:.0},{:.0})-({:.0},{:.0}) len {:.0} ang {:.0} | d {:.1},{:.1} gt {:?} raw {:?} sup {} pred {} sides {:.0},{:.0} vs {:.0},{:.0}",
                m.left, l.start[0], l.start[1], l.end[0], l.end[1], l.length_px, l.angle_rad.to_degrees(),
                m.right, r.start[0], r.start[1], r.end[0], r.end[1], r.length_px, r.angle_rad.to_degrees(),
                m.disparity_px[0], m.disparity_px[1], gt, raw, m.support, m.predicted,
                l.side_intensity[0], l.side_intensity[1], r.side_intensity[0], r.side_intensity[1]
            );
        }
    }
    for (row, name) in ["propagated", "predicted", "horiz", "horiz-pred"]
        .iter()
        .enumerate()
    {
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

/// `name=value` overrides for exploring parameters (`cargo run ... -- matching.min_support=2`).
fn override_param(p: &mut VisionParams, key: &str, v: f64) -> Result<(), String> {
    let m = &mut p.matching;
    match key {
        "canny.sigma_px" => p.canny.sigma_px = v as f32,
        "canny.low_threshold" => p.canny.low_threshold = v as u16,
        "canny.high_threshold" => p.canny.high_threshold = v as u16,
        "segments.min_length_px" => p.segments.min_length_px = v as f32,
        "segments.tolerance_px" => p.segments.tolerance_px = v as f32,
        "segments.min_chain_pixels" => p.segments.min_chain_pixels = v as usize,
        "matching.horizontal_angle_deg" => m.horizontal_angle_deg = v as f32,
        "matching.min_row_overlap_ratio" => m.min_row_overlap_ratio = v as f32,
        "matching.predict_max_angle_diff_deg" => m.predict_max_angle_diff_deg = v as f32,
        "matching.predict_min_length_ratio" => m.predict_min_length_ratio = v as f32,
        "matching.predict_min_length_px" => m.predict_min_length_px = v as f32,
        "matching.propagate_max_angle_diff_deg" => m.propagate_max_angle_diff_deg = v as f32,
        "matching.propagate_min_length_ratio" => m.propagate_min_length_ratio = v as f32,
        "matching.neighbourhood_radius_px" => m.neighbourhood_radius_px = v as f32,
        "matching.disparity_gradient_limit" => m.disparity_gradient_limit = v as f32,
        "matching.disparity_tolerance_px" => m.disparity_tolerance_px = v as f32,
        "matching.max_disparity_slope" => m.max_disparity_slope = v as f32,
        "matching.max_photometric_error" => m.max_photometric_error = v as f32,
        "matching.photometric_sampling_insensitive" => {
            m.photometric_sampling_insensitive = v != 0.0
        }
        "matching.max_neighbours" => m.max_neighbours = v as usize,
        "matching.max_intensity_diff" => m.max_intensity_diff = v as f32,
        "matching.max_contrast_ratio" => m.max_contrast_ratio = v as f32,
        "matching.min_seed_support" => m.min_seed_support = v as u32,
        "matching.min_support" => m.min_support = v as u32,
        "matching.left_right_check" => m.left_right_check = v != 0.0,
        "matching.match_horizontal" => m.match_horizontal = v != 0.0,
        "matching.join_right_fragments" => m.join_right_fragments = v != 0.0,
        "matching.horizontal_line_tolerance_px" => m.horizontal_line_tolerance_px = v as f32,
        "matching.horizontal_endpoint_tolerance_px" => {
            m.horizontal_endpoint_tolerance_px = v as f32
        }
        "matching.contained_min_length_ratio" => m.contained_min_length_ratio = v as f32,
        "matching.max_fragment_gap_px" => m.max_fragment_gap_px = v as f32,
        "matching.max_fragment_angle_diff_deg" => m.max_fragment_angle_diff_deg = v as f32,
        "matching.completion" => m.completion = v != 0.0,
        "matching.single_disparity_angle_deg" => m.single_disparity_angle_deg = v as f32,
        "matching.horizontal_min_length_ratio" => m.horizontal_min_length_ratio = v as f32,
        "matching.horizontal_piece_overlap" => m.horizontal_piece_overlap = v as f32,
        "matching.horizontal_piece_line_tolerance_px" => {
            m.horizontal_piece_line_tolerance_px = v as f32
        }
        "matching.completion_rounds" => m.completion_rounds = v as u32,
        "matching.completion_end_radius_px" => m.completion_end_radius_px = v as f32,
        "matching.completion_end_context" => m.completion_end_context = v != 0.0,
        "matching.completion_max_disparity_change_px" => {
            m.completion_max_disparity_change_px = v as f32
        }
        "matching.completion_both_ends" => m.completion_both_ends = v != 0.0,
        "matching.completion_tolerance_px" => m.completion_tolerance_px = v as f32,
        "matching.completion_gradient_limit" => m.completion_gradient_limit = v as f32,
        "matching.completion_min_agreeing" => m.completion_min_agreeing = v as u32,
        "matching.completion_max_disagreeing_ratio" => {
            m.completion_max_disagreeing_ratio = v as f32
        }
        "matching.completion_max_angle_diff_deg" => m.completion_max_angle_diff_deg = v as f32,
        "matching.completion_min_length_ratio" => m.completion_min_length_ratio = v as f32,
        "matching.completion_max_disparity_slope" => m.completion_max_disparity_slope = v as f32,
        "matching.completion_max_photometric_error" => {
            m.completion_max_photometric_error = v as f32
        }
        "matching.completion_min_row_overlap_ratio" => {
            m.completion_min_row_overlap_ratio = v as f32
        }
        _ => return Err(format!("unknown parameter {key}")),
    }
    Ok(())
}
