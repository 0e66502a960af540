//! Whole-stack tests of the vision thread on cameras: real frames of a real stereo rig (the
//! shared chessboard set, played by the file camera), calibrated by `videt calibrate-stereo`,
//! rectified, matched and built into reliefs, which the control loop renders on the twin.

#[path = "common/chessboard.rs"]
mod chessboard;

use chessboard::calibrated_chessboard;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant};

use videt_config::Config;
use videt_drivers::camera::file_source::FileStereoSource;
use videt_runtime::snapshot::snapshot_channel;
use videt_service::camera_relief::{
    spawn_camera_updates, CalibratedRig, CameraRelief, CameraSchedule, CameraStats,
};

/// The calibrated chessboard set (as [`calibrated_chessboard`]) and its first `pairs` pairs in colour
/// in `dir/colour`: red the grey level, green half of it, blue a constant 77.
fn colour_rig(dir: &Path, pairs: usize) -> Option<(PathBuf, PathBuf, PathBuf)> {
    let (images, calibration) = calibrated_chessboard(dir)?;
    let colour_dir = dir.join("colour");
    std::fs::create_dir(&colour_dir).unwrap();
    colour_pairs(&images, &colour_dir, pairs);
    Some((images, calibration, colour_dir))
}

fn colour_pairs(images: &Path, dir: &Path, pairs: usize) {
    for k in 1..=pairs {
        for side in ["left", "right"] {
            let grey = image::open(images.join(format!("{side}{k:02}.jpg")))
                .unwrap()
                .to_luma8();
            let colour = image::RgbImage::from_fn(grey.width(), grey.height(), |x, y| {
                let g = grey.get_pixel(x, y)[0];
                image::Rgb([g, g / 2, 77])
            });
            colour.save(dir.join(format!("{side}{k:02}.png"))).unwrap();
        }
    }
}

/// `videtd --sim --scene camera:DIR` for 4 s with `calibration` and `extra` arguments: its
/// standard output and error, once it has succeeded.
fn videtd_on_camera(images: &Path, calibration: &Path, extra: &[&str]) -> (String, String) {
    let out = Command::new(videt_testkit::videtd_bin())
        .arg("--sim")
        .arg("--scene")
        .arg(format!("camera:{}", images.display()))
        .arg("--stereo-calibration")
        .arg(calibration)
        .args(["--duration", "4", "--no-socket"])
        .args(extra)
        .env("RUST_LOG", "info")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    (stdout, stderr)
}

fn camera(images: &Path) -> FileStereoSource {
    FileStereoSource::from_folder(images, Duration::from_millis(200))
        .unwrap()
        .with_colour(false)
}

#[test]
fn camera_frames_become_reliefs_and_a_failing_camera_publishes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let Some((images, calibration)) = calibrated_chessboard(dir.path()) else {
        return;
    };
    let config = Config::default();
    let layout = videt_runtime::setup::relief_layout(&config);
    let rig = CalibratedRig::load(&calibration).unwrap();
    assert_eq!(rig.size_px, [640, 480]);
    let mut relief = CameraRelief::new(
        camera(&images),
        "chessboard".into(),
        rig.clone(),
        64.0,
        layout,
    )
    .unwrap();
    // Two different pairs of the set, each rectified, matched and built.
    let mut builds = Vec::new();
    for _ in 0..2 {
        let (model, build) = relief.rebuild().unwrap();
        assert!(build.segments_3d >= 3, "{} 3D segments", build.segments_3d);
        assert!(build.report.triangles > 0);
        drop(model);
        builds.push((build.matches, build.segments_3d));
    }
    assert_ne!(
        builds[0], builds[1],
        "the second relief is of the next pair"
    );
    assert!(builds[0].1 >= 30, "first pair: {:?}", builds[0]);

    // Frames of another size than the calibration's are refused with a clear message.
    let small = tempfile::tempdir().unwrap();
    let image = image::GrayImage::new(320, 240);
    image.save(small.path().join("left.png")).unwrap();
    image.save(small.path().join("right.png")).unwrap();
    let mut wrong = CameraRelief::new(
        camera(small.path()),
        "small".into(),
        rig.clone(),
        64.0,
        layout,
    )
    .unwrap();
    let e = wrong.rebuild().unwrap_err();
    assert_eq!(
        e,
        "small: the left frame is 320x240 but the stereo calibration is for 640x480 images"
    );

    // A camera that fails (unplugged after its first pair) leaves the published relief alone
    // and is counted; the control loop then fades the stale relief out.
    let mut failing = CameraRelief::new(
        Unplugged {
            camera: camera(&images),
            pairs_left: 1,
        },
        "unplugged".into(),
        rig,
        64.0,
        layout,
    )
    .unwrap();
    let (first, _) = failing.rebuild().unwrap();
    let (writer, mut reader) = snapshot_channel(first);
    let stats = Arc::new(CameraStats::default());
    let stop = Arc::new(AtomicBool::new(false));
    let thread = spawn_camera_updates(
        failing,
        writer,
        schedule(Duration::from_millis(5)),
        None,
        Arc::clone(&stats),
        Arc::clone(&stop),
        None,
    )
    .unwrap();
    let deadline = Instant::now() + Duration::from_secs(20);
    while stats.failures() < 3 {
        assert!(Instant::now() < deadline, "no capture failure counted");
        std::thread::sleep(Duration::from_millis(5));
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    thread.join().unwrap();
    assert_eq!(stats.rebuilds(), 0);
    assert_eq!(
        reader.latest().version,
        0,
        "nothing published after the failure"
    );
}

/// A camera that delivers `pairs_left` pairs, then reports itself disconnected.
struct Unplugged {
    camera: FileStereoSource,
    pairs_left: usize,
}

impl videt_hal::ErrorType for Unplugged {
    type Error = videt_drivers::camera::CameraError;
}

impl videt_hal::StereoCamera for Unplugged {
    fn capture(&mut self, out: &mut videt_hal::StereoFrame) -> Result<(), Self::Error> {
        if self.pairs_left == 0 {
            return Err(videt_drivers::camera::CameraError::Disconnected {
                device: "/dev/video0".into(),
            });
        }
        self.pairs_left -= 1;
        self.camera.capture(out)
    }
}

fn schedule(rebuild_period: Duration) -> CameraSchedule {
    CameraSchedule {
        rebuild_period,
        full_refresh: Duration::from_secs(10),
    }
}

/// A colour camera's left frames are published rectified, for the colour under the finger; a
/// grey camera publishes none.
#[test]
fn a_colour_camera_publishes_its_rectified_left_frames() {
    let dir = tempfile::tempdir().unwrap();
    let Some((images, calibration, colour_dir)) = colour_rig(dir.path(), 2) else {
        return;
    };
    let config = Config::default();
    let layout = videt_runtime::setup::relief_layout(&config);
    let rig = CalibratedRig::load(&calibration).unwrap();
    let colour_camera =
        FileStereoSource::from_folder(&colour_dir, Duration::from_millis(200)).unwrap();
    let (writer, mut frames) = snapshot_channel(videt_hal::RgbFrame::default());
    let mut relief = CameraRelief::new(colour_camera, "colour".into(), rig.clone(), 64.0, layout)
        .unwrap()
        .with_colour(writer);
    let (_, build) = relief.rebuild().unwrap();
    assert!(build.segments_3d >= 3, "{} 3D segments", build.segments_3d);
    let published = frames.latest();
    assert_eq!(published.version, 1);
    let f = &published.value;
    assert_eq!((f.width, f.height, f.data.len()), (640, 480, 640 * 480 * 3));
    // Rectified channel by channel: every pixel with a source keeps the channels' relation
    // (up to the interpolation's rounding); pixels without one are black.
    let mut with_source = 0;
    for p in f.data.chunks_exact(3) {
        if p == [0, 0, 0] {
            continue;
        }
        with_source += 1;
        assert_eq!(p[2], 77, "{p:?}");
        assert!((2 * i32::from(p[1]) - i32::from(p[0])).abs() <= 3, "{p:?}");
    }
    let expected = rig.rectifier.left.valid_fraction() * (640.0 * 480.0);
    assert!(
        (with_source as f64) > 0.98 * expected,
        "{with_source} pixels with a source, {expected} expected"
    );
    // Not the raw frame: rectification moved it.
    let raw = image::open(colour_dir.join("left01.png"))
        .unwrap()
        .to_rgb8();
    assert_ne!(raw.as_raw(), &f.data);

    let (writer, mut frames) = snapshot_channel(videt_hal::RgbFrame::default());
    let mut grey = CameraRelief::new(camera(&images), "grey".into(), rig, 64.0, layout)
        .unwrap()
        .with_colour(writer);
    grey.rebuild().unwrap();
    assert_eq!(
        frames.latest().version,
        0,
        "a grey camera publishes no colour"
    );
}

/// On the twin, the colour under the finger comes from the camera's rectified left frames and
/// is rendered as levels while the operator sweeps the relief.
#[test]
fn videtd_renders_the_colour_of_camera_frames_on_the_twin() {
    let dir = tempfile::tempdir().unwrap();
    let Some((_, calibration, colour_dir)) = colour_rig(dir.path(), 3) else {
        return;
    };
    let (stdout, stderr) = videtd_on_camera(&colour_dir, &calibration, &["--no-telemetry"]);
    // `colour HLL rgb(...)`: the blue channel is 77 everywhere, a low-to-mid level.
    let rendered: Vec<&str> = stdout
        .lines()
        .filter_map(|l| l.split_once("colour ").map(|(_, c)| c))
        .filter(|c| c.contains("rgb("))
        .collect();
    assert!(!rendered.is_empty(), "no colour rendered: {stdout}{stderr}");
    assert!(rendered.iter().all(|c| c.contains(" 77)")), "{rendered:?}");
    assert!(
        stderr.contains("colour thread stopped: vibrotactors off"),
        "{stderr}"
    );
}

#[test]
fn videtd_renders_the_relief_of_camera_frames_on_the_twin() {
    let dir = tempfile::tempdir().unwrap();
    let Some((images, calibration)) = calibrated_chessboard(dir.path()) else {
        return;
    };
    // A camera before a still scene: the set's first pair, frame after frame (the set's
    // other pairs are other poses of the board: a relief made from each would jump under the
    // finger from one frame to the next).
    let still = dir.path().join("still");
    std::fs::create_dir(&still).unwrap();
    for name in ["left01.jpg", "right01.jpg"] {
        std::fs::copy(images.join(name), still.join(name)).unwrap();
    }
    let logs = dir.path().join("logs");
    let telemetry = ["--telemetry-dir", logs.to_str().unwrap()];
    let (stdout, stderr) = videtd_on_camera(&still, &calibration, &telemetry);
    assert!(stderr.contains("relief from the cameras"), "{stderr}");
    // The status lines count the reliefs made from fresh frames: whole images, then updates
    // around the finger while the operator sweeps over the scene.
    let last = stdout
        .lines()
        .chain(stderr.lines())
        .filter_map(|l| l.split_once("| reliefs ").map(|(_, r)| r.to_string()))
        .next_back()
        .unwrap_or_else(|| panic!("no status line with reliefs: {stdout}{stderr}"));
    let words: Vec<&str> = last.split_whitespace().collect();
    let (whole, local): (u64, u64) = (words[0].parse().unwrap(), words[3].parse().unwrap());
    assert!(whole + local >= 3, "{last}");
    assert!(local >= 1, "no update around the finger: {last}");
    assert!(last.contains("(0 failed)"), "{last}");
    let log_file = std::fs::read_dir(&logs)
        .unwrap()
        .map(|e| e.unwrap().path())
        .next()
        .unwrap();
    let log = videt_runtime::telemetry::read_log(&log_file).unwrap();
    let unsafe_state = log.records.iter().find(|r| r.safety.reason().is_some());
    assert!(unsafe_state.is_none(), "{:?}", unsafe_state.map(|r| r.time));
    let contact = log.records.iter().filter(|r| r.in_contact).count();
    assert!(
        contact > log.records.len() / 3,
        "in contact for {contact} of {} periods only",
        log.records.len()
    );
    // Each relief made from a frame is rendered with the frame's age: the frame-to-force
    // latency, as `videt log` reports it.
    let latency = videt_tools::tool::log::FrameToForce::of(&log.records)
        .unwrap_or_else(|| panic!("no frame age in the log: {last}"));
    assert!(latency.frames >= 2, "{latency:?} ({last})");
    assert!(
        latency.p50_ms > 0.0 && latency.max_ms < 5000.0,
        "{latency:?}"
    );
    let out = Command::new(env!("CARGO_BIN_EXE_videt"))
        .arg("log")
        .arg(&log_file)
        .output()
        .unwrap();
    let summary = String::from_utf8_lossy(&out.stdout);
    assert!(summary.contains("frame to force:  p50 "), "{summary}");
}
