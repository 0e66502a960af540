//! Runs one stage or the whole pipeline many times on the 640x480 bench pair (teddy upscaled)
//! so that its CPU time can be read with `perf stat -e task-clock` on a shared machine, where
//! wall-clock figures include time taken by other processes:
//!
//! `perf stat -e task-clock cargo bench -p videt-vision --bench pipeline_timing -- whole 500`
//!
//! Modes: `canny` (one image per run, the left and the right image in turn), `whole` (both
//! images to 3D segments), `whole_alternating` (as `whole`, but every other run processes
//! another scene, cones, which is not timed: the teddy runs then find no branch history of
//! the previous run's images), `local` (100x100 region,
//! exact: equal to the whole-image run inside it), `local_single_pass` (one pass, not grown),
//! `rectify_whole` (the whole pipeline from raw camera frames: both frames rectified with the
//! remap tables of a calibration shaped like the real 640x480 rig's, then `whole`; the raw frames
//! are the bench pair as that rig would see it, so the rectified pair is the bench pair again,
//! though blurred by the two interpolations), `rectify_and_bench_pair` (both raw frames
//! rectified, then `whole` on the sharp bench pair: the conservative figure, since the cost of
//! rectification does not depend on the content), `rectify_compare` (as `rectify_whole`, but odd runs
//! rectify with the plain per-pixel reference tables instead: both tables timed in one run under
//! the same cache conditions). A third argument sets the checks against wrong matches
//! (`whole 300 left-right,confidence=0.2`; default: the defaults'). Prints the wall-clock median and minimum of each run
//! and, for the pipeline modes, of each stage.

#[path = "common/mod.rs"]
mod common;

use std::time::Instant;
use videt_hal::{GrayFrame, StereoFrame};
use videt_vision::canny::CannyWorkspace;
use videt_vision::rectify::reference::ReferenceMap;
use videt_vision::rectify::StereoRectifier;
use videt_vision::{GrayView, LocalRegion, RectifiedGeometry, StereoPipeline, VisionParams};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // (`cargo bench` adds `--bench`.)
    let mut args = std::env::args().skip(1).filter(|a| !a.starts_with("--"));
    let mode = args.next().unwrap_or_else(|| "whole".into());
    let iterations: usize = args.next().map(|n| n.parse()).transpose()?.unwrap_or(200);
    let (left, right) = common::vga_pair();
    let (lv, rv) = (GrayView::from_image(&left)?, GrayView::from_image(&right)?);
    let (other_left, other_right) = common::vga_pair_of("cones");
    let other = (
        GrayView::from_image(&other_left)?,
        GrayView::from_image(&other_right)?,
    );
    let mut params = VisionParams::default();
    params.matching.disparity_max_px = 96.0;
    // Third argument: the checks against wrong matches (`none`, or a list of `left-right`,
    // `surface`, `confidence=T`; default: the defaults').
    if let Some(checks) = args.next() {
        checks
            .parse::<videt_vision::matching::MatchChecks>()?
            .apply(&mut params.matching);
    }
    let mut single_pass = params;
    single_pass.local.exact = false;
    single_pass.local.context = videt_vision::roi::LocalContext::Fixed;
    let geometry = RectifiedGeometry {
        focal_px: 600.0,
        cx_px: 320.0,
        cy_px: 240.0,
        baseline_m: 0.12,
    };
    let region = LocalRegion {
        centre_px: [400.0, 260.0],
        size_px: [100.0, 100.0],
        velocity_px_per_frame: [0.0, 0.0],
    };
    let mut pipeline = StereoPipeline::new();
    let mut canny = CannyWorkspace::new();
    let calibration = common::rig_calibration();
    let rectifier = StereoRectifier::from_calibration(&calibration)?;
    let (w, h) = (calibration.image_width, calibration.image_height);
    let reference = [
        ReferenceMap::new(
            &calibration.left(),
            &calibration.r1(),
            &calibration.p1(),
            w,
            h,
        ),
        ReferenceMap::new(
            &calibration.right(),
            &calibration.r2(),
            &calibration.p2(),
            w,
            h,
        ),
    ];
    let frame = |img: &image::GrayImage| GrayFrame {
        width: img.width(),
        height: img.height(),
        data: img.as_raw().clone(),
    };
    // Raw frames that rectify back to the bench pair, so that the rectifying modes run the
    // pipeline on the same scene as `whole`.
    let (raw_left, raw_right) = common::raw_vga_pair();
    let raw = StereoFrame {
        left: frame(&raw_left),
        right: frame(&raw_right),
        ..StereoFrame::default()
    };
    let (mut rect_left, mut rect_right) = (GrayFrame::default(), GrayFrame::default());
    let mut times = Vec::with_capacity(iterations);
    let mut rectify_times = Vec::with_capacity(iterations);
    let mut reference_times = Vec::with_capacity(iterations);
    let mut stages: Vec<[f64; 5]> = Vec::with_capacity(iterations);
    for run in 0..iterations {
        let t = Instant::now();
        match mode.as_str() {
            // Left and right images in turn: a detector run on one image over and over would
            // let the branch predictor learn that image, which no camera frame allows.
            "canny" if run % 2 == 0 => canny.detect(&lv, &params.canny)?,
            "canny" => canny.detect(&rv, &params.canny)?,
            "whole" => {
                pipeline.run(&lv, &rv, Some(&geometry), &params)?;
            }
            "whole_alternating" => {
                if run % 2 == 0 {
                    pipeline.run(&other.0, &other.1, Some(&geometry), &params)?;
                    continue;
                }
                pipeline.run(&lv, &rv, Some(&geometry), &params)?;
            }
            "rectify_whole" => {
                rectifier.apply(&raw, &mut rect_left, &mut rect_right)?;
                rectify_times.push(t.elapsed().as_secs_f64() * 1e3);
                let l = GrayView::new(&rect_left.data, 640, 480)?;
                let r = GrayView::new(&rect_right.data, 640, 480)?;
                pipeline.run(&l, &r, Some(&geometry), &params)?;
            }
            "rectify_and_bench_pair" => {
                rectifier.apply(&raw, &mut rect_left, &mut rect_right)?;
                rectify_times.push(t.elapsed().as_secs_f64() * 1e3);
                std::hint::black_box((&rect_left.data, &rect_right.data));
                pipeline.run(&lv, &rv, Some(&geometry), &params)?;
            }
            "rectify_compare" => {
                if run % 2 == 1 {
                    reference[0].apply(&raw.left, &mut rect_left)?;
                    reference[1].apply(&raw.right, &mut rect_right)?;
                    reference_times.push(t.elapsed().as_secs_f64() * 1e3);
                } else {
                    rectifier.apply(&raw, &mut rect_left, &mut rect_right)?;
                    rectify_times.push(t.elapsed().as_secs_f64() * 1e3);
                }
                let l = GrayView::new(&rect_left.data, 640, 480)?;
                let r = GrayView::new(&rect_right.data, 640, 480)?;
                pipeline.run(&l, &r, Some(&geometry), &params)?;
            }
            "local" => {
                pipeline.run_local(&lv, &rv, Some(&geometry), &params, &region)?;
            }
            "local_single_pass" => {
                pipeline.run_local(&lv, &rv, Some(&geometry), &single_pass, &region)?;
            }
            other => {
                return Err(format!(
                    "unknown mode {other} (canny, whole, whole_alternating, local, \
                     local_single_pass, rectify_whole, rectify_and_bench_pair, rectify_compare)"
                )
                .into())
            }
        }
        times.push(t.elapsed().as_secs_f64() * 1e3);
        let s = pipeline.output().timings;
        stages.push(
            [s.edges, s.chains, s.segments, s.matching, s.reconstruction]
                .map(|d| d.as_secs_f64() * 1e3),
        );
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        (v[v.len() / 2], v[0])
    };
    let (med, min) = median(times);
    println!("{mode}: {iterations} runs, wall-clock median {med:.3} ms, min {min:.3} ms");
    if !rectify_times.is_empty() {
        let (med, min) = median(rectify_times);
        println!(
            "  stage {:<15} median {med:.3} ms, min {min:.3} ms",
            "rectify"
        );
    }
    if !reference_times.is_empty() {
        let (med, min) = median(reference_times);
        println!(
            "  stage {:<15} median {med:.3} ms, min {min:.3} ms",
            "rectify (reference table)"
        );
    }
    if mode != "canny" {
        let names = ["edges", "chains", "segments", "matching", "reconstruction"];
        for (k, name) in names.iter().enumerate() {
            let (med, min) = median(stages.iter().map(|s| s[k]).collect());
            println!("  stage {name:<15} median {med:.3} ms, min {min:.3} ms");
        }
        let out = pipeline.output();
        println!(
            "  last run: {} left / {} right segments, {} matches, {} 3D segments",
            out.left_segments.len(),
            out.right_segments.len(),
            out.matches.len(),
            out.segments_3d.len()
        );
    }
    Ok(())
}
