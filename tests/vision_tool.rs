//! `videt vision` on a real rectified pair: the files it writes are consistent (indices of
//! matches point into segments.json, every 3D segment lies in front of the camera); with a
//! calibration, a real rig's pair is rectified and matched; bad input gets a clear error.

use std::path::PathBuf;
use videt::tool::vision::{run, VisionArgs};

fn args(left: PathBuf, right: PathBuf, out: PathBuf, roi: Option<[u32; 4]>) -> VisionArgs {
    VisionArgs {
        left,
        right,
        calib: None,
        rectified: true,
        focal: Some(3740.0),
        baseline: Some(0.16),
        out,
        roi,
        max_disparity: 64.0,
    }
}

#[test]
fn vision_tool_writes_consistent_results() {
    let Some(dir) = videt_testdata::data_dir("stereo/venus") else {
        return;
    };
    let out = tempfile::tempdir().unwrap();
    run(&args(
        dir.join("left.ppm"),
        dir.join("right.ppm"),
        out.path().to_path_buf(),
        None,
    ))
    .unwrap();
    let read = |name: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(out.path().join(name)).unwrap()).unwrap()
    };
    let segments = read("segments.json");
    let matches = read("matches.json");
    let segments_3d = read("segments3d.json");
    let n_left = segments["left"].as_array().unwrap().len();
    let n_right = segments["right"].as_array().unwrap().len();
    let list = matches["matches"].as_array().unwrap();
    assert!(
        n_left > 100 && list.len() > n_left / 3,
        "{n_left} segments, {} matches",
        list.len()
    );
    for m in list {
        assert!((m["left"].as_u64().unwrap() as usize) < n_left);
        assert!((m["right"].as_u64().unwrap() as usize) < n_right);
        assert_eq!(m["disparity"].as_array().unwrap().len(), 2);
    }
    let s3 = segments_3d["segments"].as_array().unwrap();
    assert!(!s3.is_empty());
    for s in s3 {
        assert!(s["start_m"][2].as_f64().unwrap() > 0.0);
        assert!(s["end_sigma_m"][2].as_f64().unwrap() > 0.0);
    }
    for png in ["left_segments.png", "right_segments.png", "matches.png"] {
        assert!(image::open(out.path().join(png)).is_ok(), "{png}");
    }
    // Local mode on a region.
    let roi_out = tempfile::tempdir().unwrap();
    run(&args(
        dir.join("left.ppm"),
        dir.join("right.ppm"),
        roi_out.path().to_path_buf(),
        Some([150, 100, 100, 100]),
    ))
    .unwrap();
    assert!(roi_out.path().join("matches.json").exists());
}

#[test]
fn vision_tool_rejects_bad_images() {
    let Some(venus) = videt_testdata::data_dir("stereo/venus") else {
        return;
    };
    let Some(tsukuba) = videt_testdata::data_dir("stereo/tsukuba") else {
        return;
    };
    let out = tempfile::tempdir().unwrap();
    let e = run(&args(
        venus.join("left.ppm"),
        tsukuba.join("right.ppm"),
        out.path().into(),
        None,
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("equal sizes"), "{e}");
    let empty = out.path().join("empty.png");
    std::fs::write(&empty, b"").unwrap();
    let e = run(&args(
        venus.join("left.ppm"),
        empty,
        out.path().into(),
        None,
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("empty"), "{e}");
    let mut calib = args(
        venus.join("left.ppm"),
        venus.join("right.ppm"),
        out.path().into(),
        None,
    );
    calib.calib = Some(out.path().join("no-such-rig.json"));
    calib.rectified = false;
    let e = run(&calib).unwrap_err().to_string();
    assert!(e.contains("no-such-rig.json"), "{e}");
}

#[test]
fn vision_tool_rectifies_with_a_calibration() {
    let Some(rig) = videt_testdata::data_dir("calib/chessboard") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let calib = dir.path().join("rig.json");
    videt::tool::calibrate_stereo::run(&videt::tool::calibrate_stereo::CalibrateStereoArgs {
        images: rig.clone(),
        board: videt::tool::calibrate_stereo::parse_board("9x6").unwrap(),
        square: 0.025,
        out: calib.clone(),
        alpha: 1.0,
    })
    .unwrap();
    let mut a = args(
        rig.join("left03.jpg"),
        rig.join("right03.jpg"),
        dir.path().join("out"),
        None,
    );
    a.calib = Some(calib);
    a.rectified = false;
    a.focal = None;
    a.baseline = None;
    a.max_disparity = 250.0;
    run(&a).unwrap();
    let matches: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("out/matches.json")).unwrap(),
    )
    .unwrap();
    assert!(matches["matches"].as_array().unwrap().len() > 20);
}
