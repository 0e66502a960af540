//! Cost of the exact local mode against the whole-image run and a single local pass, on the
//! 640x480 bench pair (teddy upscaled, disparities up to 96 px) and a still 100x100 region at
//! (400, 260); the three are interleaved in one run (medians of 200 each), then the windows the
//! exact mode grew to are printed.
//!
//! `cargo bench -p videt-vision --bench local_mode_cost`

#[path = "common/mod.rs"]
mod common;

use std::time::Instant;
use videt_vision::{GrayView, LocalRegion, StereoPipeline, VisionParams};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (left, right) = common::vga_pair();
    let (lv, rv) = (GrayView::from_image(&left)?, GrayView::from_image(&right)?);
    let mut exact = VisionParams::default();
    exact.matching.disparity_max_px = 96.0;
    let mut single = exact;
    single.local.exact = false;
    single.local.context = videt_vision::roi::LocalContext::Fixed;
    let region = LocalRegion {
        centre_px: [400.0, 260.0],
        size_px: [100.0, 100.0],
        velocity_px_per_frame: [0.0, 0.0],
    };
    let mut pipeline = StereoPipeline::new();
    let mut times: [Vec<f64>; 3] = Default::default();
    for _ in 0..200 {
        for (mode, t) in times.iter_mut().enumerate() {
            let start = Instant::now();
            match mode {
                0 => pipeline.run(&lv, &rv, None, &exact).map(|_| ())?,
                1 => pipeline
                    .run_local(&lv, &rv, None, &exact, &region)
                    .map(|_| ())?,
                _ => pipeline
                    .run_local(&lv, &rv, None, &single, &region)
                    .map(|_| ())?,
            }
            t.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    for (name, t) in ["whole image", "local, exact", "local, single pass"]
        .iter()
        .zip(times.iter_mut())
    {
        t.sort_by(f64::total_cmp);
        println!("{name:<20} median {:.3} ms", t[t.len() / 2]);
    }
    let windows = pipeline
        .run_local(&lv, &rv, None, &exact, &region)?
        .local
        .ok_or("no windows")?;
    println!(
        "exact windows: left {:?}, right {:?}",
        windows.left, windows.right
    );
    Ok(())
}
