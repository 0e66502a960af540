//! The disparity bound chosen from the data, on a synthetic scene beyond the old fixed bound.

use videt_evaluation::synthetic;
use videt_vision::disparity_range::choose_max_disparity;
use videt_vision::{GrayView, StereoPipeline, VisionParams};

/// A textured scene 90 px away: beyond the old fixed bound of 64 px. The chosen bound
/// covers it and the run with it finds the scene's disparity.
#[test]
fn a_scene_beyond_64_px_gets_a_bound_that_covers_it() {
    let (w, h) = (480usize, 200usize);
    let d_true = 90usize;
    let mut rng = synthetic::Lcg::new(5);
    let plane = synthetic::Layer {
        disparity: [d_true as f32, 0.0, 0.0],
        extent: [0.0, 0.0, w as f32, h as f32],
        texture: synthetic::rectangles(w, h, 140, [6, 40], &mut rng),
    };
    let (left, right, _) = synthetic::render(w, h, &[plane]);
    let (lv, rv) = (
        GrayView::new(&left, w, h).unwrap(),
        GrayView::new(&right, w, h).unwrap(),
    );
    let mut pipeline = StereoPipeline::new();
    let params = VisionParams::default();
    let fixed = pipeline.run(&lv, &rv, None, &params).unwrap();
    let near_truth = |m: &&videt_vision::matching::SegmentMatch| {
        (0.5 * (m.disparity_px[0] + m.disparity_px[1]) - d_true as f32).abs() <= 1.0
    };
    assert_eq!(
        fixed.matches.iter().filter(near_truth).count(),
        0,
        "the fixed 64 px bound cannot reach 90 px"
    );
    let range = choose_max_disparity(&mut pipeline, &lv, &rv, &params).unwrap();
    assert!(
        range.max_px >= d_true as f32 + 2.0 && range.max_px < (w - 1) as f32,
        "{range:?}"
    );
    let mut chosen = params;
    chosen.matching.disparity_max_px = range.max_px;
    let out = pipeline.run(&lv, &rv, None, &chosen).unwrap();
    let right_ones = out.matches.iter().filter(near_truth).count();
    assert!(
        right_ones * 10 >= out.matches.len() * 9 && right_ones >= 20,
        "{right_ones} of {} matches at the true disparity",
        out.matches.len()
    );
}
