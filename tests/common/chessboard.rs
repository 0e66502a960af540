//! The shared chessboard stereo set, calibrated by the `videt` tool.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The chessboard set's folder (`None`, with the reason printed, where the data is absent)
/// and its stereo calibration, written into `dir` by `videt calibrate-stereo`.
pub fn calibrated_chessboard(dir: &Path) -> Option<(PathBuf, PathBuf)> {
    let images = videt_testdata::data_dir("calib/chessboard")?;
    let calibration = dir.join("stereo.json");
    let out = Command::new(env!("CARGO_BIN_EXE_videt"))
        .args(["calibrate-stereo", "--images"])
        .arg(&images)
        .args(["--board", "9x6", "--square", "0.025", "--out"])
        .arg(&calibration)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    Some((images, calibration))
}
