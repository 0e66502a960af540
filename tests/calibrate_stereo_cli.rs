//! `videt calibrate-stereo` end to end: real image pairs in, validated calibration file out.

use std::process::Command;

use videt_vision::calib::StereoCalibration;

#[test]
fn calibrates_the_shared_rig_and_writes_the_file() {
    let Some(shared) = videt_testdata::data_dir("calib/chessboard") else {
        return;
    };
    // Four of the nine pairs keep the debug-build run short; the library's tests use all nine.
    let dir = tempfile::tempdir().unwrap();
    let images = dir.path().join("pairs");
    std::fs::create_dir(&images).unwrap();
    for i in [1, 3, 5, 7] {
        for side in ["left", "right"] {
            let name = format!("{side}{i:02}.jpg");
            std::fs::copy(shared.join(&name), images.join(&name)).unwrap();
        }
    }
    let out = dir.path().join("stereo.json");
    let output = Command::new(env!("CARGO_BIN_EXE_videt"))
        .args(["calibrate-stereo", "--images"])
        .arg(&images)
        .args(["--board", "9x6", "--square", "0.025", "--out"])
        .arg(&out)
        .output()
        .expect("runs");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "stdout:\n{stdout}\nstderr:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(stdout.contains("RMS reprojection error"), "{stdout}");
    assert!(stdout.contains("epipolar error"), "{stdout}");
    assert_eq!(
        stdout.lines().filter(|l| l.contains("found found")).count(),
        4,
        "{stdout}"
    );
    let cal = StereoCalibration::load(&out).expect("valid file");
    // Square of 25 mm: a baseline of about 3.34 squares is about 84 mm.
    assert!((cal.t_m[0] + 0.0836).abs() < 0.003, "{:?}", cal.t_m);
}

#[test]
fn missing_image_directory_fails_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_videt"))
        .args([
            "calibrate-stereo",
            "--images",
            "/nonexistent/pairs",
            "--board",
            "9x6",
            "--square",
            "0.025",
            "--out",
        ])
        .arg(dir.path().join("stereo.json"))
        .output()
        .expect("runs");
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("/nonexistent/pairs"), "{stderr}");
    assert!(!dir.path().join("stereo.json").exists());
}

#[test]
fn missing_output_directory_is_refused_before_calibrating() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("no-such-dir").join("stereo.json");
    let output = Command::new(env!("CARGO_BIN_EXE_videt"))
        .args(["calibrate-stereo", "--images"])
        .arg(dir.path())
        .args(["--board", "9x6", "--square", "0.025", "--out"])
        .arg(&out)
        .output()
        .expect("runs");
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("no-such-dir") && stderr.contains("does not exist"),
        "{stderr}"
    );
}
