//! `videt colour` end to end: the trainer's aid on a synthetic image and on a real one.

use std::process::Command;

use videt_colour::training::{load_rgb, write_png};
use videt_hal::RgbFrame;

fn videt() -> Command {
    Command::new(env!("CARGO_BIN_EXE_videt"))
}

/// A 3x2 image of swatches: saturated red, near-black, mid grey on the top row; white, green,
/// blue below. Read with a 1-pixel window.
fn synthetic(dir: &std::path::Path) -> std::path::PathBuf {
    let pixels: [[u8; 3]; 6] = [
        [250, 10, 20],
        [12, 10, 8],
        [128, 128, 128],
        [255, 255, 255],
        [20, 230, 30],
        [10, 20, 240],
    ];
    let frame = RgbFrame {
        width: 3,
        height: 2,
        data: pixels.concat(),
    };
    let path = dir.join("swatches.png");
    write_png(&frame, &path).unwrap();
    path
}

#[test]
fn json_reading_at_a_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let img = synthetic(dir.path());
    let expect = [
        (
            (0, 0),
            r#"{"rgb": [250, 10, 20], "levels": ["high", "low", "low"]}"#,
        ),
        (
            (1, 0),
            r#"{"rgb": [12, 10, 8], "levels": ["low", "low", "low"]}"#,
        ),
        (
            (2, 0),
            r#"{"rgb": [128, 128, 128], "levels": ["mid", "mid", "mid"]}"#,
        ),
        (
            (0, 1),
            r#"{"rgb": [255, 255, 255], "levels": ["high", "high", "high"]}"#,
        ),
        (
            (1, 1),
            r#"{"rgb": [20, 230, 30], "levels": ["low", "high", "low"]}"#,
        ),
        (
            (2, 1),
            r#"{"rgb": [10, 20, 240], "levels": ["low", "low", "high"]}"#,
        ),
    ];
    for ((x, y), json) in expect {
        let out = videt()
            .args(["colour", "--image"])
            .arg(&img)
            .args(["--at", &format!("{x},{y}"), "--window", "1", "--json"])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(String::from_utf8(out.stdout).unwrap().trim_end(), json);
    }
}

#[test]
fn level_image_and_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let img = synthetic(dir.path());
    let png = dir.path().join("levels.png");
    let out = videt()
        .args(["colour", "--image"])
        .arg(&img)
        .args(["--window", "1", "--out"])
        .arg(&png)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let levels = load_rgb(&png).unwrap();
    assert_eq!(
        levels.data,
        [
            [255, 0, 0],
            [0, 0, 0],
            [128, 128, 128],
            [255, 255, 255],
            [0, 255, 0],
            [0, 0, 255]
        ]
        .concat()
    );

    let err = |args: &[&str]| {
        let out = videt().args(args).output().unwrap();
        assert!(!out.status.success(), "{args:?} should fail");
        String::from_utf8(out.stderr).unwrap()
    };
    let img = img.to_str().unwrap();
    assert!(err(&["colour", "--image", img, "--at", "3,0"]).contains("--at 3,0 is outside"));
    assert!(err(&["colour", "--image", img, "--at", "a,b"]).contains("--at must be X,Y"));
    assert!(
        err(&["colour", "--image", img, "--at", "0,0", "--window", "8"]).contains("window_px = 8")
    );
    assert!(
        err(&["colour", "--image", "/no/such.png", "--at", "0,0"]).contains("cannot read image")
    );
    let junk = dir.path().join("junk.ppm");
    std::fs::write(&junk, "P6\n2 2\n255\nxx").unwrap();
    assert!(
        err(&["colour", "--image", junk.to_str().unwrap(), "--at", "0,0"])
            .contains("cannot decode")
    );
    assert!(err(&["colour", "--image", img]).contains("--at"));
}

#[test]
fn real_image_red_cone() {
    let Some(dir) = videt_testdata::data_dir("stereo/cones") else {
        return;
    };
    let out = videt()
        .args(["colour", "--image"])
        .arg(dir.join("left.ppm"))
        .args(["--at", "140,175", "--json"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.ends_with("\"levels\": [\"high\", \"low\", \"low\"]}\n"),
        "{text}"
    );
}

/// The levels shown are those of the configuration's `[colour]` section; the flags override it,
/// and a bad section is refused with the field named.
#[test]
fn the_configuration_sets_the_levels_shown() {
    let dir = tempfile::tempdir().unwrap();
    let img = synthetic(dir.path());
    let config = dir.path().join("videt.toml");
    // `videt colour --config ... --json` on `image` at `at`: the exit status and the output.
    let read = |image: &std::path::Path, at: &str, extra: &[&str]| {
        let out = videt()
            .args(["colour", "--image"])
            .arg(image)
            .arg("--config")
            .arg(&config)
            .args(["--at", at, "--json"])
            .args(extra)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        (
            out.status.success(),
            text + &String::from_utf8_lossy(&out.stderr),
        )
    };
    // Plain RGB, High from 200: the mid grey (128) is Mid.
    std::fs::write(
        &config,
        "[colour]\nspace = \"rgb\"\nlow_mid = 100.0\nmid_high = 200.0\nwindow_px = 1\n",
    )
    .unwrap();
    let (ok, text) = read(&img, "2,0", &[]);
    assert!(ok && text.contains(r#"["mid", "mid", "mid"]"#), "{text}");
    // A red of 190 is Mid in RGB space; in chromaticity (the flag) it is nearly full brightness.
    let red = dir.path().join("red-190.png");
    write_png(
        &RgbFrame {
            width: 1,
            height: 1,
            data: vec![190, 10, 10],
        },
        &red,
    )
    .unwrap();
    let (ok, text) = read(&red, "0,0", &[]);
    assert!(ok && text.contains(r#"["mid", "low", "low"]"#), "{text}");
    let (ok, text) = read(&red, "0,0", &["--space", "chromaticity"]);
    assert!(ok && text.contains(r#"["high", "low", "low"]"#), "{text}");

    std::fs::write(&config, "[colour]\nlow_mid = 300.0\n").unwrap();
    let (ok, text) = read(&img, "0,0", &[]);
    assert!(!ok && text.contains("colour.low_mid"), "{text}");
}
