//! Local mode equals the whole-image run inside the region of interest: on real pairs, every
//! match of the global run whose left segment lies inside the region is found by the local
//! run with the same segments and disparity, and the local run finds no other match there.

use videt_vision::matching::SegmentMatch;
use videt_vision::segments::Segment;
use videt_vision::{
    GrayView, LocalParams, LocalRegion, PipelineOutput, PixelRect, StereoPipeline, VisionParams,
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

/// Compares one region; returns (global matches inside, found identically, extra local ones).
fn compare(
    pipeline: &mut StereoPipeline,
    lv: &GrayView<'_>,
    rv: &GrayView<'_>,
    params: &VisionParams,
    global: &PipelineOutput,
    region: &LocalRegion,
) -> (usize, usize, usize) {
    let local = pipeline.run_local(lv, rv, None, params, region).unwrap();
    let roi = local.local.unwrap().roi;
    let expected = matches_inside(global, &roi);
    let found = matches_inside(local, &roi);
    let same = |a: &(Segment, Segment, SegmentMatch), b: &(Segment, Segment, SegmentMatch)| {
        same_segment(&a.0, &b.0)
            && same_segment(&a.1, &b.1)
            && (a.2.disparity_px[0] - b.2.disparity_px[0]).abs() < 1e-3
            && (a.2.disparity_px[1] - b.2.disparity_px[1]).abs() < 1e-3
    };
    let identical = expected
        .iter()
        .filter(|e| found.iter().any(|f| same(e, f)))
        .count();
    let extra = found
        .iter()
        .filter(|f| !expected.iter().any(|e| same(e, f)))
        .count();
    (expected.len(), identical, extra)
}

/// Runs the regions on venus and teddy with the given context margin; returns the totals
/// (global matches inside the regions, found identically, extra local ones).
fn run_regions(context_margin_px: usize) -> Option<(usize, usize, usize)> {
    let mut params = VisionParams::default();
    params.local.context_margin_px = context_margin_px;
    let mut totals = (0, 0, 0);
    for name in ["venus", "teddy"] {
        let dir = videt_testdata::data_dir(&format!("stereo/{name}"))?;
        let left = image::open(dir.join("left.ppm")).unwrap().to_luma8();
        let right = image::open(dir.join("right.ppm")).unwrap().to_luma8();
        let lv = GrayView::from_image(&left).unwrap();
        let rv = GrayView::from_image(&right).unwrap();
        let mut pipeline = StereoPipeline::new();
        let global = pipeline.run(&lv, &rv, None, &params).unwrap().clone();
        for (cx, cy, vx, vy) in [
            (150.0, 120.0, 0.0, 0.0),
            (300.0, 200.0, 6.0, -3.0),
            (220.0, 290.0, -5.0, 0.0),
            (380.0, 100.0, 0.0, 8.0),
        ] {
            let region = LocalRegion {
                centre_px: [cx, cy],
                size_px: [100.0, 100.0],
                velocity_px_per_frame: [vx, vy],
            };
            let (n, same, extra) = compare(&mut pipeline, &lv, &rv, &params, &global, &region);
            eprintln!(
                "margin {context_margin_px}: {name} region at ({cx}, {cy}): {n} global matches inside, {same} identical, {extra} extra"
            );
            totals.0 += n;
            totals.1 += same;
            totals.2 += extra;
        }
    }
    eprintln!(
        "margin {context_margin_px}: {} global, {} identical, {} extra",
        totals.0, totals.1, totals.2
    );
    Some(totals)
}

/// With enough context (the propagation radius plus the disparity range), the local run is
/// exactly the global run inside the region.
#[test]
fn with_full_context_local_runs_equal_the_global_run_inside_the_region() {
    let Some((n, same, extra)) = run_regions(140) else {
        return;
    };
    assert!(n > 20, "the regions must contain matches");
    assert_eq!(same, n, "every global match inside the region is found");
    assert_eq!(extra, 0, "no new match inside the region");
}

/// With the default (fast) context margin, an edge chain that runs far beyond the margin is cut
/// at the window border and its polygonal approximation (recursive splitting) can then place
/// its breakpoints differently, and propagation can reach beyond the margin: measured, 79 of
/// 86 global matches are reproduced exactly (the others because their left segment is cut
/// differently or a nearly horizontal match inherits its disparity from another neighbour)
/// and 6 extra appear. Guard: at least 85 % reproduced, at most 10 % extra.
#[test]
fn with_the_default_margin_local_runs_nearly_equal_the_global_run() {
    let Some((n, same, extra)) = run_regions(LocalParams::default().context_margin_px) else {
        return;
    };
    assert!(n > 20, "the regions must contain matches");
    assert!(same * 100 >= n * 85, "{same} of {n} reproduced");
    assert!(extra * 10 < n, "{extra} extra for {n}");
}
