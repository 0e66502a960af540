//! `videt vision` on a real rectified pair: the files it writes are consistent (indices of
//! matches point into segments.json, every 3D segment lies in front of the camera); with a
//! calibration, a real rig's pair is rectified and matched; with `--surface` the bas-relief's
//! mesh and depth image are written and consistent; bad input gets a clear error.

use std::path::PathBuf;
use videt_tools::tool::vision::{run, VisionArgs};

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
        max_disparity: Some(64.0),
        checks: None,
        surface: false,
        relief_depth: 0.08,
    }
}

/// A parsed ASCII PLY: vertices `(x, y, z)` and triangles.
fn parse_ply(text: &str) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("ply"));
    assert_eq!(lines.next(), Some("format ascii 1.0"));
    let (mut n_vertices, mut n_faces) = (None, None);
    for line in lines.by_ref() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["element", "vertex", n] => n_vertices = Some(n.parse::<usize>().unwrap()),
            ["element", "face", n] => n_faces = Some(n.parse::<usize>().unwrap()),
            ["end_header"] => break,
            _ => {}
        }
    }
    let (n_vertices, n_faces) = (n_vertices.unwrap(), n_faces.unwrap());
    let vertices: Vec<[f64; 3]> = lines
        .by_ref()
        .take(n_vertices)
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|w| w.parse().unwrap()).collect();
            assert_eq!(v.len(), 6, "x y z nx ny nz: {l}");
            [v[0], v[1], v[2]]
        })
        .collect();
    let faces: Vec<[usize; 3]> = lines
        .by_ref()
        .take(n_faces)
        .map(|l| {
            let f: Vec<usize> = l.split_whitespace().map(|w| w.parse().unwrap()).collect();
            assert_eq!(f[0], 3, "triangles: {l}");
            [f[1], f[2], f[3]]
        })
        .collect();
    assert_eq!(vertices.len(), n_vertices, "vertex lines");
    assert_eq!(faces.len(), n_faces, "face lines");
    assert!(lines.next().is_none(), "nothing after the faces");
    (vertices, faces)
}

/// The tool's arguments for the shared tsukuba pair, writing into `out`; `None` (the test
/// skips) without the shared data.
fn tsukuba_args(out: &std::path::Path) -> Option<VisionArgs> {
    let dir = videt_testdata::data_dir("stereo/tsukuba")?;
    Some(args(
        dir.join("left.ppm"),
        dir.join("right.ppm"),
        out.to_path_buf(),
        None,
    ))
}

#[test]
fn vision_tool_writes_the_surface_of_a_real_pair() {
    let out = tempfile::tempdir().unwrap();
    let Some(mut a) = tsukuba_args(out.path()) else {
        return;
    };
    a.max_disparity = Some(20.0);
    a.surface = true;
    a.relief_depth = 0.05;
    run(&a).unwrap();
    let (vertices, faces) =
        parse_ply(&std::fs::read_to_string(out.path().join("surface.ply")).unwrap());
    assert!(vertices.len() > 100, "{} vertices", vertices.len());
    assert!(faces.len() > 100, "{} triangles", faces.len());
    // The relief lies between the back plane (0.45 m) and 5 cm in front of it, on a 40 cm wide
    // area with the image's aspect (384 x 288).
    for v in &vertices {
        assert!(v.iter().all(|c| c.is_finite()), "{v:?}");
        assert!(v[2] >= 0.40 - 1e-9 && v[2] <= 0.45 + 1e-9, "z {v:?}");
        assert!((-1e-9..=0.4 + 1e-9).contains(&v[0]), "x {v:?}");
        assert!((-1e-9..=0.3 + 1e-9).contains(&v[1]), "y {v:?}");
    }
    for f in &faces {
        assert!(f.iter().all(|&i| i < vertices.len()), "{f:?}");
    }
    // Real relief, not a flat plane: the scene's depths spread over the range.
    let nearest = vertices.iter().map(|v| v[2]).fold(f64::MAX, f64::min);
    assert!(nearest < 0.43, "nearest vertex at z = {nearest}");
    let png = image::open(out.path().join("surface_depth.png")).unwrap();
    assert_eq!((png.width(), png.height()), (640, 480));

    // Bad relief depth: a clear error naming the value; nothing written.
    let bad_out = tempfile::tempdir().unwrap();
    a.out = bad_out.path().to_path_buf();
    a.relief_depth = 0.5;
    let e = run(&a).unwrap_err().to_string();
    assert!(e.contains("relief depth 0.5"), "{e}");
    assert!(!bad_out.path().join("surface.ply").exists());
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
    videt_tools::tool::calibrate_stereo::run(
        &videt_tools::tool::calibrate_stereo::CalibrateStereoArgs {
            images: rig.clone(),
            board: videt_tools::tool::calibrate_stereo::parse_board("9x6").unwrap(),
            square: 0.025,
            out: calib.clone(),
            alpha: 1.0,
        },
    )
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
    a.max_disparity = Some(250.0);
    run(&a).unwrap();
    let matches: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("out/matches.json")).unwrap(),
    )
    .unwrap();
    assert!(matches["matches"].as_array().unwrap().len() > 20);
}

/// Without `--max-disparity` the bound is measured on the pair: on tsukuba (true disparities
/// 5..14 px) the run keeps its matches, nearly all inside the scene's range and none far
/// beyond it.
#[test]
fn without_max_disparity_the_bound_is_measured_on_the_pair() {
    let out = tempfile::tempdir().unwrap();
    let Some(mut a) = tsukuba_args(out.path()) else {
        return;
    };
    a.max_disparity = None;
    run(&a).unwrap();
    let matches: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.path().join("matches.json")).unwrap())
            .unwrap();
    let matches = matches["matches"].as_array().unwrap();
    assert!(matches.len() > 200, "{} matches", matches.len());
    let disparities: Vec<f64> = matches
        .iter()
        .flat_map(|m| m["disparity"].as_array().unwrap().clone())
        .map(|d| d.as_f64().unwrap())
        .collect();
    let inside = disparities
        .iter()
        .filter(|d| (3.0..=16.0).contains(*d))
        .count();
    // A few percent of the matches are wrong (the held-out figures): they land anywhere in the
    // searched range, which the measured bound keeps small.
    assert!(
        inside * 100 >= disparities.len() * 95,
        "{inside} of {} endpoint disparities in 3..16 px",
        disparities.len()
    );
    let widest = disparities.iter().copied().fold(0.0, f64::max);
    assert!(widest <= 40.0, "a match at {widest} px");
}
