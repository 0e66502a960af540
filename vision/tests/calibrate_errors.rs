//! Bad inputs to the stereo calibration give clear errors, never panics.

use std::path::Path;

use videt_vision::calib::{calibrate_stereo_dir, CalibError};

fn write_png(path: &Path, width: u32, height: u32, value: u8) {
    image::GrayImage::from_pixel(width, height, image::Luma([value]))
        .save(path)
        .expect("write png");
}

#[test]
fn missing_directory_is_an_io_error_naming_it() {
    let err =
        calibrate_stereo_dir(Path::new("/nonexistent/calib-images"), 9, 6, 0.025).unwrap_err();
    assert!(matches!(err, CalibError::Io { .. }), "{err:?}");
    assert!(
        err.to_string().contains("/nonexistent/calib-images"),
        "{err}"
    );
}

#[test]
fn directory_without_pairs_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("left01.png"), 64, 48, 0);
    write_png(&dir.path().join("notes.png"), 64, 48, 0);
    let err = calibrate_stereo_dir(dir.path(), 9, 6, 0.025).unwrap_err();
    assert!(matches!(err, CalibError::NoImagePairs { .. }), "{err:?}");
}

#[test]
fn images_without_a_board_are_skipped_then_too_few_views() {
    let dir = tempfile::tempdir().unwrap();
    for i in 1..=3 {
        write_png(&dir.path().join(format!("left{i:02}.png")), 64, 48, 100);
        write_png(&dir.path().join(format!("right{i:02}.png")), 64, 48, 100);
    }
    let err = calibrate_stereo_dir(dir.path(), 9, 6, 0.025).unwrap_err();
    assert!(
        matches!(
            err,
            CalibError::TooFewViews {
                found: 0,
                needed: 3,
                ..
            }
        ),
        "{err:?}"
    );
    assert!(err.to_string().contains("found in 0 view"), "{err}");
}

#[test]
fn mismatched_image_sizes_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("left01.png"), 64, 48, 0);
    write_png(&dir.path().join("right01.png"), 80, 48, 0);
    let err = calibrate_stereo_dir(dir.path(), 9, 6, 0.025).unwrap_err();
    match err {
        CalibError::ImageSizeMismatch {
            width: 80,
            height: 48,
            expected_width: 64,
            expected_height: 48,
            ..
        } => {}
        other => panic!("unexpected {other:?}"),
    }
}

#[test]
fn undecodable_image_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("left01.jpg"), b"not a jpeg").unwrap();
    write_png(&dir.path().join("right01.png"), 64, 48, 0);
    let err = calibrate_stereo_dir(dir.path(), 9, 6, 0.025).unwrap_err();
    assert!(matches!(err, CalibError::ImageDecode { .. }), "{err:?}");
}

#[test]
fn bad_board_description_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    for (cols, rows, square, field) in [
        (1, 6, 0.02, "cols"),
        (9, 0, 0.02, "rows"),
        (9, 6, -1.0, "square_m"),
        (9, 6, f64::NAN, "square_m"),
    ] {
        match calibrate_stereo_dir(dir.path(), cols, rows, square).unwrap_err() {
            CalibError::InvalidBoard { field: f, .. } => assert_eq!(f, field),
            other => panic!("unexpected {other:?}"),
        }
    }
}

#[test]
fn rectification_alpha_out_of_range_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    for alpha in [-0.1, 1.5, f64::NAN] {
        let err =
            videt_vision::calib::calibrate_stereo_dir_with_alpha(dir.path(), 9, 6, 0.025, alpha)
                .unwrap_err();
        assert!(
            matches!(
                err,
                CalibError::InvalidOption {
                    field: "rectify_alpha",
                    ..
                }
            ),
            "{err:?}"
        );
    }
}
