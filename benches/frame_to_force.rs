//! From a camera frame to the control thread, on the twin's camera scenes played by the file
//! camera, turned into reliefs by the camera vision thread's code and taken by the control
//! thread's relief feed:
//! - `chessboard`: the shared chessboard set, a real 640 x 480 stereo rig, calibrated here as
//!   `videt calibrate-stereo` does (a sparse scene: a board before a wall);
//! - `teddy_rig`: Middlebury teddy upscaled to 640 x 480 and seen through a rig shaped like the
//!   real one (raw, distorted frames: `vision/benches/common`), a dense scene.
//!
//! Per scene:
//! - `frame_to_force_local_640x480`: capture, rectify, re-match the region under the finger,
//!   merge, rebuild, publish (with the session log's copy), and the control side's take of the
//!   new version: what each frame costs while the finger is over the scene. The finger sweeps
//!   across the scene between iterations.
//! - `frame_to_force_whole_640x480`: the same with a whole-image run (every
//!   `vision.full_refresh_s` while the finger is over the scene, every
//!   `vision.rebuild_period_s` while it is not).
//!
//! The stage medians of the local path are printed first. The latency distribution of a running
//! service is in its session log (`videt log` prints its p50 / p99).
//!
//! `cargo bench --bench frame_to_force` (needs the shared data; skips with a reason without it)

#[path = "../vision/benches/common/mod.rs"]
mod common;

use std::hint::black_box;
use std::path::Path;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use videt_drivers::camera::file_source::FileStereoSource;
use videt_runtime::snapshot::SurfaceFeed;
use videt_service::camera_relief::{CalibratedRig, CameraRelief};

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort_unstable();
    v[v.len() / 2]
}

fn bench_frame_to_force(c: &mut Criterion) {
    let config = videt_config::Config::default();
    match videt_testdata::data_dir("calib/chessboard") {
        Some(images) => {
            let (calibration, _) = videt_vision::calib::calibrate_stereo_dir(&images, 9, 6, 0.025)
                .expect("calibration");
            let rig = CalibratedRig::from_calibration(&calibration).expect("rig");
            scene(
                c,
                "chessboard",
                &images,
                rig,
                config.vision.max_disparity_px as f32,
                Variant::Default,
            );
        }
        None => {
            eprintln!("frame_to_force: chessboard skipped: the shared chessboard set is absent")
        }
    }
    let dir = tempfile::tempdir().expect("temporary directory");
    let (left, right) = common::raw_vga_pair();
    left.save(dir.path().join("left.png")).expect("write");
    right.save(dir.path().join("right.png")).expect("write");
    // Teddy upscaled to 640 px has disparities up to ~80 px.
    for variant in [Variant::Default, Variant::Paper] {
        let rig = CalibratedRig::from_calibration(&common::rig_calibration()).expect("rig");
        scene(c, "teddy_rig", dir.path(), rig, 96.0, variant);
    }
}

/// The relief's settings benched.
#[derive(Clone, Copy, PartialEq)]
enum Variant {
    /// The configuration's defaults: the stepped relief with depth from patches every 12 px.
    Default,
    /// The paper's relief of the segments alone (`vision.relief_shape = "interpolated"`,
    /// `vision.patch_spacing_px = 0`).
    Paper,
}

/// The benches of one scene: the pairs of `images` through `rig`.
fn scene(
    c: &mut Criterion,
    name: &str,
    images: &Path,
    rig: CalibratedRig,
    max_disparity_px: f32,
    variant: Variant,
) {
    let mut config = videt_config::Config::default();
    if variant == Variant::Paper {
        config.vision.relief_shape = videt_config::ReliefShapeName::Interpolated;
        config.vision.patch_spacing_px = 0;
    }
    let name = match variant {
        Variant::Default => name.to_string(),
        Variant::Paper => format!("{name}_interpolated"),
    };
    let name = name.as_str();
    let layout = videt_runtime::setup::relief_layout(&config);
    let camera = FileStereoSource::from_folder(images, Duration::from_millis(66))
        .expect("camera")
        .with_colour(false)
        .unpaced();
    let mut relief = CameraRelief::new(camera, name.into(), rig, max_disparity_px, layout)
        .expect("camera relief")
        .with_live_settings(videt_service::stereo_relief::LiveSettings {
            patch_spacing_px: config.vision.patch_spacing_px,
            ..Default::default()
        });
    let (model, first) = relief.rebuild().expect("first relief");
    eprintln!(
        "{name}: {} matches, {} 3D segments, {} triangles; whole-image pipeline {:?}, build {:?}",
        first.matches,
        first.segments_3d,
        first.report.triangles,
        first.pipeline_time,
        first.build_time
    );
    let (mut writer, mut feed) =
        videt_service::relief_feed::relief_channel_for(&config, model).expect("relief channel");
    // The finger sweeping across the scene, 2 mm between frames.
    let [cx, cy] = layout.centre_m;
    let positions: Vec<[f64; 3]> = (0..70)
        .map(|k| [cx - 0.07 + 0.002 * k as f64, cy + 0.01, 0.34])
        .collect();

    // Stage medians of the local path.
    let mut stages: [Vec<Duration>; 5] = Default::default();
    for k in 0..60 {
        let t = Instant::now();
        let captured = relief.capture().expect("capture");
        stages[0].push(t.elapsed());
        let (model, update) = relief
            .update_around(positions[k % positions.len()], [0.03, 0.0, 0.0])
            .expect("update")
            .expect("the finger is over the scene");
        stages[1].push(update.match_time);
        stages[2].push(update.merge_time);
        stages[3].push(update.build_time);
        let t = Instant::now();
        writer.publish_captured_with(Some(captured), |slot| *slot = model);
        black_box(feed.current().frame_age_ns);
        stages[4].push(t.elapsed());
    }
    let [capture, matching, merge, build, publish] = stages.map(median);
    eprintln!(
        "{name}: local path stage medians: capture+rectify {capture:?}, match {matching:?}, merge {merge:?}, rebuild {build:?}, publish+take {publish:?}"
    );

    let mut k = 0;
    c.bench_function(&format!("frame_to_force_local_640x480_{name}"), |b| {
        b.iter(|| {
            k = (k + 1) % positions.len();
            let captured = relief.capture().unwrap();
            let (model, _) = relief
                .update_around(black_box(positions[k]), [0.03, 0.0, 0.0])
                .unwrap()
                .unwrap();
            writer.publish_captured_with(Some(captured), |slot| *slot = model);
            feed.current().frame_age_ns
        })
    });
    c.bench_function(&format!("frame_to_force_whole_640x480_{name}"), |b| {
        b.iter(|| {
            let captured = relief.capture().unwrap();
            let (model, _) = relief.build_whole().unwrap();
            writer.publish_captured_with(Some(captured), |slot| *slot = model);
            feed.current().frame_age_ns
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(Duration::from_secs(8));
    targets = bench_frame_to_force
}
criterion_main!(benches);
