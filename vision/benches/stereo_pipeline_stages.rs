//! Time of each stage of the stereo pipeline, of the whole pipeline (rectified images to 3D
//! segments, and raw camera frames through rectification to 3D segments) on a 640x480 pair, and
//! of local runs on 100x100 regions.
//!
//! The 640x480 pair is the shared Middlebury teddy pair (450x375) upscaled bilinearly with
//! `image::imageops::resize` (`common::vga_pair`; disparities scale by 640/450, up to ~80 px,
//! hence a search up to 96 px), or a synthetic textured pair when the shared data is absent.
//!
//! `cargo bench -p videt-vision --bench stereo_pipeline_stages`; the adaptive local mode alone:
//! `cargo bench -p videt-vision --bench stereo_pipeline_stages -- local_region_100x100_adaptive_640x480`

mod common;

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use videt_hal::{GrayFrame, StereoFrame};
use videt_vision::canny::CannyWorkspace;
use videt_vision::chains::Chains;
use videt_vision::matching::MatchWorkspace;
use videt_vision::rectify::StereoRectifier;
use videt_vision::roi::LocalContext;
use videt_vision::segments::SegmentWorkspace;
use videt_vision::{GrayView, LocalRegion, RectifiedGeometry, StereoPipeline, VisionParams};

fn geometry() -> RectifiedGeometry {
    RectifiedGeometry {
        focal_px: 600.0,
        cx_px: 320.0,
        cy_px: 240.0,
        baseline_m: 0.12,
    }
}

fn params() -> VisionParams {
    let mut p = VisionParams::default();
    // Teddy upscaled to 640 px has disparities up to ~80 px.
    p.matching.disparity_max_px = 96.0;
    p
}

fn stages(c: &mut Criterion) {
    let (left, right) = common::vga_pair();
    let lv = GrayView::from_image(&left).unwrap();
    let rv = GrayView::from_image(&right).unwrap();
    let params = params();
    let (w, h) = (lv.width(), lv.height());

    // The detector runs on the left and the right image in turn: on one image over and over,
    // its data-dependent branches would be learnt by the branch predictor, which no sequence
    // of camera frames allows.
    let views = [lv, rv];
    let mut calls = 0usize;
    let mut canny = CannyWorkspace::new();
    c.bench_function("canny_640x480", |b| {
        b.iter(|| {
            calls += 1;
            canny
                .detect(black_box(&views[calls % 2]), &params.canny)
                .unwrap()
        })
    });

    canny.detect(&lv, &params.canny).unwrap();
    let mut chains = Chains::new();
    c.bench_function("chain_linking_640x480", |b| {
        b.iter(|| {
            chains.link(
                black_box(canny.edges()),
                w,
                h,
                params.segments.min_chain_pixels,
            )
        })
    });

    chains.link(canny.edges(), w, h, params.segments.min_chain_pixels);
    let mut segments_ws = SegmentWorkspace::new();
    let mut segments = Vec::new();
    c.bench_function("segment_approximation_640x480", |b| {
        b.iter(|| {
            segments_ws.extract(
                black_box(&chains),
                &canny,
                (0, 0),
                &params.segments,
                &mut segments,
            )
        })
    });

    let mut pipeline = StereoPipeline::new();
    pipeline.run(&lv, &rv, None, &params).unwrap();
    let out = pipeline.output().clone();
    let mut matcher = MatchWorkspace::new();
    let mut matches = Vec::new();
    c.bench_function("segment_matching_640x480_no_photometric", |b| {
        b.iter(|| {
            matcher.match_segments(
                black_box(&out.left_segments),
                &out.right_segments,
                None,
                &params.matching,
                &mut matches,
            )
        })
    });

    let g = geometry();
    c.bench_function("whole_pipeline_640x480", |b| {
        b.iter(|| {
            pipeline
                .run(black_box(&lv), black_box(&rv), Some(&g), &params)
                .unwrap()
                .segments_3d
                .len()
        })
    });

    // From raw camera frames: both rectified with the remap tables of the rig calibration, then
    // the pipeline (the raw frames are the bench pair as that rig would see it).
    let rectifier = StereoRectifier::from_calibration(&common::rig_calibration()).unwrap();
    let (raw_left, raw_right) = common::raw_vga_pair();
    let frame = |img: &image::GrayImage| GrayFrame {
        width: img.width(),
        height: img.height(),
        data: img.as_raw().clone(),
    };
    let raw = StereoFrame {
        left: frame(&raw_left),
        right: frame(&raw_right),
        ..StereoFrame::default()
    };
    let (mut rect_left, mut rect_right) = (GrayFrame::default(), GrayFrame::default());
    let mut from_raw = || {
        rectifier
            .apply(black_box(&raw), &mut rect_left, &mut rect_right)
            .unwrap();
        let l = GrayView::new(&rect_left.data, 640, 480).unwrap();
        let r = GrayView::new(&rect_right.data, 640, 480).unwrap();
        pipeline
            .run(&l, &r, Some(&g), &params)
            .unwrap()
            .segments_3d
            .len()
    };
    c.bench_function("raw_frames_to_3d_640x480", |b| b.iter(&mut from_raw));
    let from_raw_median = per_call_median_ms(|| {
        from_raw();
    });
    // The raw frames rectify to a pair blurred by two interpolations, with fewer segments
    // than the bench pair. The conservative figure: both raw frames rectified (a cost that
    // does not depend on the content), then the whole pipeline on the sharp bench pair.
    let mut rectify_and_sharp = || {
        rectifier
            .apply(black_box(&raw), &mut rect_left, &mut rect_right)
            .unwrap();
        black_box((&rect_left.data, &rect_right.data));
        pipeline
            .run(black_box(&lv), black_box(&rv), Some(&g), &params)
            .unwrap()
            .segments_3d
            .len()
    };
    c.bench_function("rectify_and_bench_pair_to_3d_640x480", |b| {
        b.iter(&mut rectify_and_sharp)
    });
    let rectify_and_sharp_median = per_call_median_ms(|| {
        rectify_and_sharp();
    });

    let region = LocalRegion {
        centre_px: [400.0, 260.0],
        size_px: [100.0, 100.0],
        velocity_px_per_frame: [0.0, 0.0],
    };
    c.bench_function("local_region_100x100", |b| {
        b.iter(|| {
            pipeline
                .run_local(black_box(&lv), black_box(&rv), Some(&g), &params, &region)
                .unwrap()
                .segments_3d
                .len()
        })
    });
    // The single pass over the region plus its fixed context margin (not grown until the
    // matches equal the whole-image run's): exact except near chains cut by the window.
    let mut single_pass = params;
    single_pass.local.exact = false;
    single_pass.local.context = LocalContext::Fixed;
    c.bench_function("local_region_100x100_single_pass", |b| {
        b.iter(|| {
            pipeline
                .run_local(
                    black_box(&lv),
                    black_box(&rv),
                    Some(&g),
                    &single_pass,
                    &region,
                )
                .unwrap()
                .segments_3d
                .len()
        })
    });
    // Per-call medians: robust to other processes preempting the bench on a shared machine.
    let mut medians = Vec::new();
    medians.push((
        "canny_640x480 (one image)",
        per_call_median_ms(|| {
            calls += 1;
            canny.detect(&views[calls % 2], &params.canny).unwrap()
        }),
    ));
    canny.detect(&lv, &params.canny).unwrap();
    medians.push((
        "chain_linking_640x480",
        per_call_median_ms(|| chains.link(canny.edges(), w, h, params.segments.min_chain_pixels)),
    ));
    medians.push((
        "segment_approximation_640x480",
        per_call_median_ms(|| {
            segments_ws.extract(&chains, &canny, (0, 0), &params.segments, &mut segments)
        }),
    ));
    medians.push((
        "whole_pipeline_640x480",
        per_call_median_ms(|| {
            pipeline.run(&lv, &rv, Some(&g), &params).unwrap();
        }),
    ));
    medians.push(("raw_frames_to_3d_640x480", from_raw_median));
    medians.push((
        "rectify_and_bench_pair_to_3d_640x480",
        rectify_and_sharp_median,
    ));
    let stage = pipeline.output().timings;
    medians.push((
        "  of which matching (last run)",
        stage.matching.as_secs_f64() * 1e3,
    ));
    medians.push((
        "local_region_100x100",
        per_call_median_ms(|| {
            pipeline
                .run_local(&lv, &rv, Some(&g), &params, &region)
                .unwrap();
        }),
    ));
    medians.push((
        "local_region_100x100_single_pass",
        per_call_median_ms(|| {
            pipeline
                .run_local(&lv, &rv, Some(&g), &single_pass, &region)
                .unwrap();
        }),
    ));
    for (name, ms) in medians {
        eprintln!("per-call median {name:<34} {ms:8.3} ms");
    }
    let out = pipeline.run(&lv, &rv, Some(&g), &params).unwrap();
    eprintln!(
        "640x480 pair: {} left / {} right segments, {} matches, {} 3D segments",
        out.left_segments.len(),
        out.right_segments.len(),
        out.matches.len(),
        out.segments_3d.len()
    );
}

/// The adaptive local mode (context chosen from the data, see `StereoPipeline::run_local`) on
/// the 640x480 pair: 48 still 100x100 regions on an 8x6 grid over the whole image, one region
/// per iteration in turn, so criterion's figures are per region over all of them. Then the
/// median over the regions of each region's per-call median, with the 90th percentile and the
/// largest, and the same for the exact mode and a fixed 96 px margin.
fn local_modes(c: &mut Criterion) {
    let (left, right) = common::vga_pair();
    let lv = GrayView::from_image(&left).unwrap();
    let rv = GrayView::from_image(&right).unwrap();
    let exact = params();
    let mut adaptive = exact;
    adaptive.local.exact = false;
    adaptive.local.context = LocalContext::Adaptive;
    let mut fixed = adaptive;
    fixed.local.context = LocalContext::Fixed;
    fixed.local.context_margin_px = 96;
    let regions: Vec<LocalRegion> = (0..48)
        .map(|k| LocalRegion {
            centre_px: [50.0 + (k % 8) as f32 * 77.0, 50.0 + (k / 8) as f32 * 76.0],
            size_px: [100.0, 100.0],
            velocity_px_per_frame: [0.0, 0.0],
        })
        .collect();
    let mut pipeline = StereoPipeline::new();
    let g = geometry();
    let mut next = 0usize;
    c.bench_function("local_region_100x100_adaptive_640x480", |b| {
        b.iter(|| {
            next = (next + 1) % regions.len();
            pipeline
                .run_local(
                    black_box(&lv),
                    black_box(&rv),
                    Some(&g),
                    &adaptive,
                    &regions[next],
                )
                .unwrap()
                .segments_3d
                .len()
        })
    });
    for (name, p) in [
        ("adaptive", &adaptive),
        ("exact", &exact),
        ("fixed 96 px", &fixed),
    ] {
        let mut medians: Vec<f64> = regions
            .iter()
            .map(|region| {
                per_call_median_ms_of(20, || {
                    pipeline.run_local(&lv, &rv, Some(&g), p, region).unwrap();
                })
            })
            .collect();
        medians.sort_by(f64::total_cmp);
        eprintln!(
            "local_region_100x100 {name:<12} over {} regions of 640x480: median {:.3} ms, p90 {:.3} ms, max {:.3} ms",
            medians.len(),
            medians[medians.len() / 2],
            medians[medians.len() * 9 / 10],
            medians[medians.len() - 1]
        );
    }
}

/// Median of 200 single calls after 20 warm-up calls, milliseconds.
fn per_call_median_ms(f: impl FnMut()) -> f64 {
    per_call_median_ms_of(200, f)
}

/// Median of `calls` single calls after a tenth as many warm-up calls (at least one),
/// milliseconds.
fn per_call_median_ms_of(calls: usize, mut f: impl FnMut()) -> f64 {
    for _ in 0..(calls / 10).max(1) {
        f();
    }
    let mut times: Vec<f64> = (0..calls)
        .map(|_| {
            let t = std::time::Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[calls / 2]
}

criterion_group!(benches, stages, local_modes);
criterion_main!(benches);
