//! Stereo calibration of the real chessboard rig (OpenCV's sample pairs, 9x6 inner corners) and
//! comparison with the OpenCV 4.10 reference calibration of the same images
//! (`calib/chessboard/reference/run_info.json`: RMS 0.408 / 0.458 px per camera, 0.447 px stereo).

use videt_vision::calib::calibrate_stereo_dir;

/// Reference RMS figures of OpenCV 4.10 on the same set (left, right, stereo), pixels.
const OPENCV_RMS_PX: [f64; 3] = [0.408, 0.458, 0.447];
/// Our RMS may exceed OpenCV's by at most this, pixels.
const RMS_MARGIN_PX: f64 = 0.1;
/// Bound on the mean |y_left - y_right| of the corners after rectification, pixels.
const EPIPOLAR_BOUND_PX: f64 = 0.2;

#[test]
fn real_rig_calibrates_close_to_the_opencv_reference() {
    let Some(dir) = videt_testdata::data_dir("calib/chessboard") else {
        return;
    };
    let (cal, report) = calibrate_stereo_dir(&dir, 9, 6, 1.0).expect("the shared set calibrates");

    // OpenCV finds the board in all 18 images; so must we (all 54 corners, or no detection).
    assert_eq!(report.views.len(), 9);
    for v in &report.views {
        assert!(
            v.left_found && v.right_found,
            "board missed in pair {}",
            v.id
        );
    }
    let ours = [
        report.rms_left_px,
        report.rms_right_px,
        report.rms_stereo_px,
    ];
    eprintln!(
        "RMS left {:.3} right {:.3} stereo {:.3} px (OpenCV {:?}); epipolar mean {:.3} max {:.3} px",
        ours[0], ours[1], ours[2], OPENCV_RMS_PX, report.epipolar_error_mean_px, report.epipolar_error_max_px
    );
    for (name, (o, r)) in ["left", "right", "stereo"]
        .iter()
        .zip(ours.iter().zip(OPENCV_RMS_PX))
    {
        assert!(
            *o <= r + RMS_MARGIN_PX,
            "{name} RMS {o:.3} px exceeds OpenCV's {r} + {RMS_MARGIN_PX}"
        );
        assert!(
            *o > 0.01,
            "{name} RMS {o} px is implausibly small for real corners"
        );
    }
    // Every left corner sits on its right twin's rectified row: the left and right orderings agree
    // corner by corner (a swapped or flipped labelling would be off by whole squares).
    assert!(
        report.epipolar_error_max_px < 2.0,
        "max epipolar {}",
        report.epipolar_error_max_px
    );
    assert!(
        report.epipolar_error_mean_px < EPIPOLAR_BOUND_PX,
        "epipolar error {}",
        report.epipolar_error_mean_px
    );

    // The rig: about 3.3 squares of horizontal baseline, right camera to the right (T.x < 0),
    // nearly parallel cameras; focal lengths near OpenCV's 536 / 542 px.
    assert!(
        (cal.t_m[0] + 3.34).abs() < 0.1 && cal.t_m[1].abs() < 0.2 && cal.t_m[2].abs() < 0.2,
        "{:?}",
        cal.t_m
    );
    assert!((cal.m1[0][0] - 536.0).abs() < 15.0 && (cal.m2[0][0] - 542.0).abs() < 15.0);
    assert!(cal.validate().is_ok());
}
