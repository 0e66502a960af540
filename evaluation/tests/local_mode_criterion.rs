//! The adaptive local mode meets the paper's criterion ("with respect to the global approach,
//! we do not miss matches nor obtain new errors within the regions of interest") on every
//! shared Middlebury pair, over 40 regions of 100x100 each: a 5x4 grid of still regions inside
//! the image, and a 5x4 grid of moving-finger regions whose centres run from 20-30 px off the
//! image border, so that most are cut by it. The local run is compared with the whole-image
//! run; the judging (identical, covered, missed, new errors) is the one of the example
//! `local_mode_paper_criterion` (see `paper_criterion/mod.rs`).

mod paper_criterion;

use paper_criterion::{compare, grid_regions, Tally};
use videt_evaluation::{load_middlebury_truth, MIDDLEBURY_PAIRS};
use videt_vision::matching::MatchChecks;
use videt_vision::roi::LocalContext;
use videt_vision::{GrayView, LocalRegion, StereoPipeline, VisionParams};

/// The still grid, then the moving-finger grid reaching the image border.
fn regions(width: f32, height: f32) -> Vec<LocalRegion> {
    let mut out = grid_regions(width, height);
    for k in 0..20 {
        let (fx, fy) = ((k % 5) as f32 / 4.0, (k / 5) as f32 / 3.0);
        out.push(LocalRegion {
            centre_px: [30.0 + fx * (width - 60.0), 20.0 + fy * (height - 40.0)],
            size_px: [100.0, 100.0],
            velocity_px_per_frame: [4.0 * (fx - 0.5), -3.0 * (fy - 0.5)],
        });
    }
    out
}

fn adaptive() -> VisionParams {
    let mut params = VisionParams::default();
    params.local.exact = false;
    params.local.context = LocalContext::Adaptive;
    params
}

#[test]
fn the_adaptive_local_mode_misses_no_match_and_adds_no_error() {
    let Some((total, faults)) = over_every_pair(&adaptive()) else {
        return;
    };
    assert!(faults.is_empty(), "{}", faults.join("\n"));
    assert!(
        total.global > 800,
        "the regions must hold matches ({})",
        total.global
    );
}

/// With every check against wrong matches on, a check's decision depends on matches beyond
/// the window (the neighbours it counts, the second run of the left-right check): the adaptive
/// mode then still adds no error, and misses at most 1 % of the whole-image run's matches in
/// the regions (measured: 2 of 1894, in one teddy region).
#[test]
fn with_the_checks_the_adaptive_mode_adds_no_error_and_misses_little() {
    let mut params = adaptive();
    MatchChecks {
        left_right: true,
        min_confidence: 0.2,
        surface: true,
    }
    .apply(&mut params.matching);
    let Some((total, faults)) = over_every_pair(&params) else {
        return;
    };
    eprintln!("with the checks: {total:?}");
    assert_eq!(total.new_errors, 0, "{}", faults.join("\n"));
    assert!(total.missed * 100 <= total.global, "{}", faults.join("\n"));
    assert!(total.global > 800, "{total:?}");
}

/// The local runs on every region of every shared pair against the whole-image run: the
/// tally and the faults (`None` when the data is absent).
fn over_every_pair(params: &VisionParams) -> Option<(Tally, Vec<String>)> {
    let params = *params;
    let mut faults = Vec::new();
    let mut total = Tally::default();
    let mut regions_seen = 0;
    for (name, scale) in MIDDLEBURY_PAIRS {
        let dir = videt_testdata::data_dir(&format!("stereo/{name}"))?;
        let left = image::open(dir.join("left.ppm")).unwrap().to_luma8();
        let right = image::open(dir.join("right.ppm")).unwrap().to_luma8();
        let truth = load_middlebury_truth(&dir, scale).unwrap();
        let lv = GrayView::from_image(&left).unwrap();
        let rv = GrayView::from_image(&right).unwrap();
        let mut pipeline = StereoPipeline::new();
        let global = pipeline.run(&lv, &rv, None, &params).unwrap().clone();
        let mut clipped = 0;
        for region in regions(lv.width() as f32, lv.height() as f32) {
            let local = pipeline
                .run_local(&lv, &rv, None, &params, &region)
                .unwrap();
            let windows = local.local.unwrap();
            let roi = windows.roi;
            clipped += usize::from(
                roi.x == 0
                    || roi.y == 0
                    || roi.x + roi.width == lv.width()
                    || roi.y + roi.height == lv.height(),
            );
            let mut region_faults = Vec::new();
            total.add(&compare(&global, local, &truth, &mut region_faults));
            faults.extend(
                region_faults
                    .into_iter()
                    .map(|f| format!("{name}, region {roi:?}: {f}")),
            );
            regions_seen += 1;
        }
        assert!(clipped >= 10, "{name}: {clipped} regions cut by the border");
    }
    eprintln!("{regions_seen} regions: {total:?}");
    Some((total, faults))
}

/// The comparison can fail: a local run over the region alone (no context) misses matches of
/// the whole-image run on the same regions.
#[test]
fn the_criterion_fails_without_context() {
    let mut params = adaptive();
    params.local.context = LocalContext::Fixed;
    params.local.context_margin_px = 0;
    let Some(dir) = videt_testdata::data_dir("stereo/teddy") else {
        return;
    };
    let left = image::open(dir.join("left.ppm")).unwrap().to_luma8();
    let right = image::open(dir.join("right.ppm")).unwrap().to_luma8();
    let truth = load_middlebury_truth(&dir, 4.0).unwrap();
    let lv = GrayView::from_image(&left).unwrap();
    let rv = GrayView::from_image(&right).unwrap();
    let mut pipeline = StereoPipeline::new();
    let global = pipeline.run(&lv, &rv, None, &params).unwrap().clone();
    let mut total = Tally::default();
    for region in grid_regions(lv.width() as f32, lv.height() as f32) {
        let local = pipeline
            .run_local(&lv, &rv, None, &params, &region)
            .unwrap();
        total.add(&compare(&global, local, &truth, &mut Vec::new()));
    }
    assert!(!total.holds(), "{total:?}");
}
