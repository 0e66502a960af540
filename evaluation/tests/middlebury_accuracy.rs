//! Matching accuracy on the Middlebury pairs of the shared data (one parameter set, the
//! defaults; every extracted left segment counts in the denominator). The goal is at least
//! 60 % of the left segments matched with at most 2 % of the matches wrong (see
//! `videt_evaluation` for how a match is judged); every pair is held to it (measured:
//! tsukuba 72.6 % / 1.74 %, venus 73.3 % / 0.00 %, cones 60.3 % / 1.72 %, teddy 63.0 % /
//! 1.84 %). The full table: `cargo run --release -p videt-evaluation --example
//! stereo_accuracy`.

use videt_evaluation::{evaluate, load_middlebury_truth};
use videt_vision::{run_pipeline, GrayView, VisionParams};

#[test]
fn every_middlebury_pair_is_matched_reliably() {
    let params = VisionParams::default();
    // (pair, ground-truth scale, minimum fraction matched, maximum fraction wrong)
    for (name, scale, min_matched, max_wrong) in [
        ("tsukuba", 16.0, 0.60, 0.02),
        ("venus", 8.0, 0.60, 0.02),
        ("cones", 4.0, 0.60, 0.02),
        ("teddy", 4.0, 0.60, 0.02),
    ] {
        let Some(dir) = videt_testdata::data_dir(&format!("stereo/{name}")) else {
            return;
        };
        let left = image::open(dir.join("left.ppm")).unwrap().to_luma8();
        let right = image::open(dir.join("right.ppm")).unwrap().to_luma8();
        let truth = load_middlebury_truth(&dir, scale).unwrap();
        let out = run_pipeline(
            &GrayView::from_image(&left).unwrap(),
            &GrayView::from_image(&right).unwrap(),
            None,
            &params,
        )
        .unwrap();
        let report = evaluate(
            &out.left_segments,
            &out.right_segments,
            &out.matches,
            &truth,
        );
        eprintln!("{name}: {report:?}");
        assert!(report.left_segments > 200, "{name}: {report:?}");
        assert!(
            report.matched_fraction() >= min_matched,
            "{name}: {report:?}"
        );
        assert!(report.wrong_fraction() <= max_wrong, "{name}: {report:?}");
    }
}
