//! Local mode equals the whole-image run inside the region of interest: on the four real
//! Middlebury pairs, for regions spread over the image (still and moving finger, regions cut
//! by the image border), the matches of the global run whose left segment lies inside the
//! region are exactly the local run's there: same left and right segments, same disparities,
//! nothing missing and nothing extra.

use videt_vision::matching::MatchChecks;
use videt_vision::matching::SegmentMatch;
use videt_vision::segments::Segment;
use videt_vision::{
    GrayView, LocalRegion, PipelineOutput, PixelRect, StereoPipeline, VisionParams,
};

fn inside(s: &Segment, roi: &PixelRect) -> bool {
    roi.contains(s.start[0], s.start[1]) && roi.contains(s.end[0], s.end[1])
}

fn same_segment(a: &Segment, b: &Segment) -> bool {
    (0..2).all(|k| (a.start[k] - b.start[k]).abs() < 1e-3 && (a.end[k] - b.end[k]).abs() < 1e-3)
}

/// Matches of `out` whose left segment lies inside `roi`, as (left, right, match).
fn matches_inside(out: &PipelineOutput, roi: &PixelRect) -> Vec<(Segment, Segment, SegmentMatch)> {
    out.matches
        .iter()
        .filter(|m| inside(&out.left_segments[m.left as usize], roi))
        .map(|m| {
            (
                out.left_segments[m.left as usize],
                out.right_segments[m.right as usize],
                *m,
            )
        })
        .collect()
}

fn same_match(a: &(Segment, Segment, SegmentMatch), b: &(Segment, Segment, SegmentMatch)) -> bool {
    same_segment(&a.0, &b.0)
        && same_segment(&a.1, &b.1)
        && (a.2.disparity_px[0] - b.2.disparity_px[0]).abs() < 1e-3
        && (a.2.disparity_px[1] - b.2.disparity_px[1]).abs() < 1e-3
        && a.2.nearly_horizontal == b.2.nearly_horizontal
}

/// Regions: a coarse grid over the frame with a moving finger, and a few still ones.
fn regions(width: f32, height: f32) -> Vec<LocalRegion> {
    let mut out = Vec::new();
    for fx in [0.15, 0.5, 0.85] {
        for fy in [0.2, 0.75] {
            out.push(LocalRegion {
                centre_px: [fx * width, fy * height],
                size_px: [100.0, 100.0],
                velocity_px_per_frame: [3.0, -2.0],
            });
        }
    }
    for (cx, cy) in [(0.35, 0.45), (0.65, 0.5), (0.98, 0.05)] {
        out.push(LocalRegion {
            centre_px: [cx * width, cy * height],
            size_px: [100.0, 100.0],
            velocity_px_per_frame: [0.0, 0.0],
        });
    }
    out
}

#[test]
fn local_runs_equal_the_global_run_inside_the_region() {
    let Some(total) = local_equals_global(&VisionParams::default()) else {
        return;
    };
    eprintln!("{total} global matches inside the regions, all found identically");
    assert!(total > 200, "the regions must hold matches ({total})");
}

/// The same with every check against wrong matches on: the windows grow until the region's
/// matches are the whole-image run's, whatever decides them.
#[test]
fn with_the_checks_local_runs_equal_the_global_run_inside_the_region() {
    let mut params = VisionParams::default();
    MatchChecks {
        left_right: true,
        min_confidence: 0.2,
        surface: true,
    }
    .apply(&mut params.matching);
    let Some(total) = local_equals_global(&params) else {
        return;
    };
    eprintln!("with the checks: {total} global matches inside the regions, all found identically");
    assert!(total > 200, "the regions must hold matches ({total})");
}

/// Runs every region of every shared pair locally and asserts its matches are the whole-image
/// run's inside the region; returns how many whole-image matches the regions held (`None` when
/// the data is absent).
fn local_equals_global(params: &VisionParams) -> Option<usize> {
    let params = *params;
    let mut total = 0;
    for name in ["tsukuba", "venus", "cones", "teddy"] {
        let dir = videt_testdata::data_dir(&format!("stereo/{name}"))?;
        let left = image::open(dir.join("left.ppm")).unwrap().to_luma8();
        let right = image::open(dir.join("right.ppm")).unwrap().to_luma8();
        let lv = GrayView::from_image(&left).unwrap();
        let rv = GrayView::from_image(&right).unwrap();
        let mut pipeline = StereoPipeline::new();
        let global = pipeline.run(&lv, &rv, None, &params).unwrap().clone();
        for region in regions(lv.width() as f32, lv.height() as f32) {
            let local = pipeline
                .run_local(&lv, &rv, None, &params, &region)
                .unwrap();
            let roi = local.local.unwrap().roi;
            let expected = matches_inside(&global, &roi);
            let found = matches_inside(local, &roi);
            for e in &expected {
                assert!(
                    found.iter().any(|f| same_match(e, f)),
                    "{name}, region {roi:?}: global match {:?} -> {:?} ({:?}) not found locally",
                    e.0,
                    e.1,
                    e.2
                );
            }
            for f in &found {
                assert!(
                    expected.iter().any(|e| same_match(e, f)),
                    "{name}, region {roi:?}: local match {:?} -> {:?} ({:?}) is not the global run's",
                    f.0,
                    f.1,
                    f.2
                );
            }
            total += expected.len();
        }
    }
    Some(total)
}

/// Without growth (one pass over the region plus its context margin) chains cut by the window
/// border change segments near the region, which is what the exact mode repairs: on the same
/// regions some global matches are missed or differ.
#[test]
fn a_single_pass_over_a_fixed_window_is_not_exact() {
    let mut params = VisionParams::default();
    params.local.exact = false;
    params.local.context = videt_vision::roi::LocalContext::Fixed;
    let Some(dir) = videt_testdata::data_dir("stereo/teddy") else {
        return;
    };
    let left = image::open(dir.join("left.ppm")).unwrap().to_luma8();
    let right = image::open(dir.join("right.ppm")).unwrap().to_luma8();
    let lv = GrayView::from_image(&left).unwrap();
    let rv = GrayView::from_image(&right).unwrap();
    let mut pipeline = StereoPipeline::new();
    let global = pipeline.run(&lv, &rv, None, &params).unwrap().clone();
    let (mut expected_total, mut differing) = (0, 0);
    for region in regions(lv.width() as f32, lv.height() as f32) {
        let local = pipeline
            .run_local(&lv, &rv, None, &params, &region)
            .unwrap();
        let roi = local.local.unwrap().roi;
        let expected = matches_inside(&global, &roi);
        let found = matches_inside(local, &roi);
        expected_total += expected.len();
        differing += expected
            .iter()
            .filter(|e| !found.iter().any(|f| same_match(e, f)))
            .count();
    }
    assert!(expected_total > 50, "{expected_total}");
    assert!(differing > 0, "the fixed window happened to be exact");
}
