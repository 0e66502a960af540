//! Rectification of 640x480 grey frames with precomputed bilinear remap tables: one camera, the
//! pair, and building the tables from a calibration.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::{Matrix3, Vector3};
use videt_hal::{GrayFrame, StereoFrame};
use videt_vision::calib::file::QualityFigures;
use videt_vision::calib::{stereo_rectify, CameraIntrinsics, StereoCalibration};
use videt_vision::rectify::StereoRectifier;

/// A calibration shaped like the real 640x480 rig's.
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
    let r = Matrix3::new(
        0.99998, 0.00413, 0.00352, -0.00413, 0.99999, -0.0003, -0.00353, 0.00029, 0.99999,
    );
    let r = videt_vision::calib::geometry::nearest_rotation(&r);
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

fn frame(seed: u32) -> GrayFrame {
    GrayFrame {
        width: 640,
        height: 480,
        data: (0..640u32 * 480)
            .map(|i| ((i * 7 + seed) % 253) as u8)
            .collect(),
    }
}

fn bench_rectify(c: &mut Criterion) {
    let cal = calibration();
    let rectifier = StereoRectifier::from_calibration(&cal).expect("valid calibration");
    let pair = StereoFrame {
        left: frame(1),
        right: frame(2),
        ..StereoFrame::default()
    };
    let mut left = GrayFrame::default();
    let mut right = GrayFrame::default();
    rectifier
        .apply(&pair, &mut left, &mut right)
        .expect("sizes match");

    c.bench_function("rectify_640x480_one_camera", |b| {
        b.iter(|| {
            rectifier
                .left
                .apply(black_box(&pair.left), &mut left)
                .expect("sizes match")
        })
    });
    c.bench_function("rectify_640x480_pair", |b| {
        b.iter(|| {
            rectifier
                .apply(black_box(&pair), &mut left, &mut right)
                .expect("sizes match")
        })
    });
    c.bench_function("rectify_maps_build_640x480_pair", |b| {
        b.iter(|| StereoRectifier::from_calibration(black_box(&cal)).expect("valid calibration"))
    });
}

criterion_group!(benches, bench_rectify);
criterion_main!(benches);
