//! VIDET's Canny against OpenCV's single-thread Canny on the same 640x480 images, measured in
//! one run: the median of VIDET's detector (smoothing included) is taken before and after
//! `vision/bench/opencv_canny.py` measures OpenCV (GaussianBlur + Canny, and Canny alone) and
//! the ratio is printed. Without Python/OpenCV only VIDET's time is reported.
//!
//! Both detectors run on the left and the right image of the bench pair in turn, one image
//! per timed call: run on one image over and over, a detector's data-dependent branches are
//! learnt by the branch predictor, which no sequence of camera frames allows.
//!
//! `cargo bench -p videt-vision --bench canny_vs_opencv`

mod common;

use criterion::Criterion;
use std::hint::black_box;
use std::path::Path;
use std::process::Command;
use std::time::Instant;
use videt_vision::canny::{CannyParams, CannyWorkspace, EDGE};
use videt_vision::GrayView;

fn median_ms(
    ws: &mut CannyWorkspace,
    views: &[GrayView<'_>; 2],
    params: &CannyParams,
    n: usize,
) -> f64 {
    for k in 0..20 {
        ws.detect(&views[k % 2], params).unwrap();
    }
    let mut times: Vec<f64> = (0..n)
        .map(|k| {
            let t = Instant::now();
            ws.detect(black_box(&views[k % 2]), params).unwrap();
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[n / 2]
}

fn main() {
    let (left, right) = common::vga_pair();
    let view = GrayView::from_image(&left).unwrap();
    let views = [view, GrayView::from_image(&right).unwrap()];
    let params = CannyParams::default();
    let mut ws = CannyWorkspace::new();

    let mut criterion = Criterion::default().configure_from_args();
    let mut calls = 0usize;
    criterion.bench_function("canny_640x480_videt", |b| {
        b.iter(|| {
            calls += 1;
            ws.detect(black_box(&views[calls % 2]), &params).unwrap()
        })
    });

    let dir = std::env::temp_dir().join("videt-canny-bench");
    std::fs::create_dir_all(&dir).unwrap();
    let image_path = dir.join("canny_640x480.png");
    left.save(&image_path).unwrap();
    let other_image_path = dir.join("canny_640x480_other.png");
    right.save(&other_image_path).unwrap();
    ws.detect(&view, &params).unwrap();
    let edges = image::GrayImage::from_fn(left.width(), left.height(), |x, y| {
        let e = ws.edges()[(y * left.width() + x) as usize] == EDGE;
        image::Luma([if e { 255 } else { 0 }])
    });
    let edges_path = dir.join("canny_640x480_videt_edges.png");
    edges.save(&edges_path).unwrap();

    let before = median_ms(&mut ws, &views, &params, 300);
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("bench/opencv_canny.py");
    let opencv = Command::new("python3")
        .arg(&script)
        .arg("--image")
        .arg(&image_path)
        .arg("--other-image")
        .arg(&other_image_path)
        .arg("--videt-edges")
        .arg(&edges_path)
        .args(["--sigma", &params.sigma_px.to_string()])
        .args(["--low", &params.low_threshold.to_string()])
        .args(["--high", &params.high_threshold.to_string()])
        .output();
    let after = median_ms(&mut ws, &views, &params, 300);
    let videt = 0.5 * (before + after);
    println!("videt Canny (smoothing included), median: {videt:.3} ms ({before:.3} before, {after:.3} after OpenCV)");
    match opencv {
        Ok(out) if out.status.success() => {
            let text = String::from_utf8_lossy(&out.stdout);
            println!("opencv: {}", text.trim());
            let value: serde_json::Value = serde_json::from_str(text.trim()).unwrap();
            let blur_canny = value["blur_canny_ms_median"].as_f64().unwrap();
            let canny_only = value["canny_only_ms_median"].as_f64().unwrap();
            println!(
                "ratio videt / opencv (GaussianBlur + Canny): {:.2}; videt / opencv (Canny alone): {:.2}",
                videt / blur_canny,
                videt / canny_only
            );
        }
        Ok(out) => println!(
            "OpenCV comparison skipped: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        ),
        Err(e) => println!("OpenCV comparison skipped: python3 not runnable ({e})"),
    }
    criterion.final_summary();
}
