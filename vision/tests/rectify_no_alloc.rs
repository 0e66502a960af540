//! Rectifying into correctly sized frames performs no heap allocation (counted by a global
//! allocator wrapper, per thread).

use nalgebra::{Matrix3, Vector3};
use videt_hal::{GrayFrame, StereoFrame};
use videt_vision::calib::file::QualityFigures;
use videt_vision::calib::{stereo_rectify, CameraIntrinsics, StereoCalibration};
use videt_vision::rectify::StereoRectifier;

#[global_allocator]
static GLOBAL: videt_testkit::CountingAllocator = videt_testkit::CountingAllocator;

/// Allocations made so far on this thread.
fn allocations() -> u64 {
    videt_testkit::this_thread().allocations
}

fn calibration() -> StereoCalibration {
    let left = CameraIntrinsics {
        fx: 536.0,
        fy: 536.0,
        cx: 342.4,
        cy: 235.5,
        dist: [-0.265, -0.047, 0.0018, -0.0003, 0.252],
    };
    let right = CameraIntrinsics {
        fx: 542.3,
        fy: 541.6,
        cx: 328.3,
        cy: 247.0,
        dist: [-0.281, 0.104, -0.0006, 0.0013, -0.024],
    };
    let r = Matrix3::identity();
    let t = Vector3::new(-3.344, 0.0417, 0.0528);
    let rect = stereo_rectify(&left, &right, &r, &t, 640, 480, 1.0);
    let q = QualityFigures {
        rms_left_px: 0.2,
        rms_right_px: 0.2,
        rms_stereo_px: 0.2,
        epipolar_error_px: 0.1,
    };
    StereoCalibration::new(640, 480, &left, &right, &r, &t, &rect, q)
}

#[test]
fn rectifying_into_sized_frames_does_not_allocate() {
    let rectifier = StereoRectifier::from_calibration(&calibration()).unwrap();
    let frame = StereoFrame {
        left: GrayFrame {
            width: 640,
            height: 480,
            data: (0..640 * 480).map(|i| (i % 251) as u8).collect(),
        },
        right: GrayFrame {
            width: 640,
            height: 480,
            data: (0..640 * 480).map(|i| (i % 241) as u8).collect(),
        },
        ..StereoFrame::default()
    };
    let mut left = GrayFrame::default();
    let mut right = GrayFrame::default();
    // First call sizes the outputs (allocates).
    let before = allocations();
    rectifier.apply(&frame, &mut left, &mut right).unwrap();
    assert!(
        allocations() > before,
        "the counter must see the first, sizing call"
    );
    // Later calls reuse them.
    let before = allocations();
    for _ in 0..3 {
        rectifier.apply(&frame, &mut left, &mut right).unwrap();
    }
    assert_eq!(allocations() - before, 0, "rectification allocated");
    assert_eq!(
        (left.width, left.height, left.data.len()),
        (640, 480, 640 * 480)
    );
    assert!(left.data.iter().any(|&p| p != 0) && right.data.iter().any(|&p| p != 0));
}
