//! Once warm, the Canny detector and the whole stereo pipeline (whole-image and local runs,
//! with every check against wrong matches on) perform no heap allocation per frame (counted by
//! a global allocator wrapper, per thread).

use videt_vision::canny::{CannyParams, CannyWorkspace};
use videt_vision::matching::MatchChecks;
use videt_vision::{GrayView, LocalRegion, RectifiedGeometry, StereoPipeline, VisionParams};

#[global_allocator]
static GLOBAL: videt_testkit::CountingAllocator = videt_testkit::CountingAllocator;

/// Allocations made so far on this thread.
fn allocations() -> u64 {
    videt_testkit::this_thread().allocations
}

#[test]
fn warm_canny_and_pipeline_do_not_allocate() {
    let Some(dir) = videt_testdata::data_dir("stereo/venus") else {
        return;
    };
    let left = image::open(dir.join("left.ppm")).unwrap().to_luma8();
    let right = image::open(dir.join("right.ppm")).unwrap().to_luma8();
    let lv = GrayView::from_image(&left).unwrap();
    let rv = GrayView::from_image(&right).unwrap();

    let mut canny = CannyWorkspace::new();
    canny.detect(&lv, &CannyParams::default()).unwrap();
    let before = allocations();
    for _ in 0..3 {
        canny.detect(&lv, &CannyParams::default()).unwrap();
        canny.detect(&rv, &CannyParams::default()).unwrap();
    }
    assert_eq!(allocations(), before, "Canny allocated once warm");

    // Every check against wrong matches on: the left-right check's second run and mirrored
    // images reuse their buffers too.
    let mut params = VisionParams::default();
    MatchChecks {
        left_right: true,
        min_confidence: 0.2,
        surface: true,
    }
    .apply(&mut params.matching);
    let geometry = RectifiedGeometry {
        focal_px: 3740.0,
        cx_px: 216.5,
        cy_px: 191.0,
        baseline_m: 0.16,
    };
    let region = LocalRegion {
        centre_px: [300.0, 200.0],
        size_px: [100.0, 100.0],
        velocity_px_per_frame: [4.0, 0.0],
    };
    let mut pipeline = StereoPipeline::new();
    // Warm: the same frames twice (buffers grow to their working size).
    for _ in 0..2 {
        pipeline.run(&lv, &rv, Some(&geometry), &params).unwrap();
        pipeline
            .run_local(&lv, &rv, Some(&geometry), &params, &region)
            .unwrap();
    }
    let before = allocations();
    for _ in 0..3 {
        let matches = pipeline
            .run(&lv, &rv, Some(&geometry), &params)
            .unwrap()
            .matches
            .len();
        assert!(matches > 100);
        pipeline
            .run_local(&lv, &rv, Some(&geometry), &params, &region)
            .unwrap();
    }
    assert_eq!(allocations(), before, "the pipeline allocated once warm");
}
