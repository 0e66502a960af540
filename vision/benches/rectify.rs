//! Rectification of 640x480 grey frames with precomputed bilinear remap tables: one camera, the
//! pair (the compact block table and, as the baseline, the plain per-pixel reference table,
//! which give identical frames), a colour frame of one camera (the colour under the finger), and
//! building the tables from a calibration.

use std::hint::black_box;

mod common;

use criterion::{criterion_group, criterion_main, Criterion};
use videt_hal::{GrayFrame, RgbFrame, StereoFrame};
use videt_vision::rectify::reference::ReferenceMap;
use videt_vision::rectify::{RgbPlanes, StereoRectifier};

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
    let cal = common::rig_calibration();
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
    let colour = RgbFrame {
        width: 640,
        height: 480,
        data: (0..3 * 640u32 * 480)
            .map(|i| ((i * 11 + 5) % 251) as u8)
            .collect(),
    };
    let mut colour_out = RgbFrame::default();
    let mut planes = RgbPlanes::default();
    c.bench_function("rectify_640x480_colour_one_camera", |b| {
        b.iter(|| {
            rectifier
                .left
                .apply_rgb(black_box(&colour), &mut colour_out, &mut planes)
                .expect("sizes match")
        })
    });
    let reference_left = ReferenceMap::new(&cal.left(), &cal.r1(), &cal.p1(), 640, 480);
    let reference_right = ReferenceMap::new(&cal.right(), &cal.r2(), &cal.p2(), 640, 480);
    c.bench_function("rectify_640x480_pair_reference_table", |b| {
        b.iter(|| {
            reference_left
                .apply(black_box(&pair.left), &mut left)
                .expect("sizes match");
            reference_right
                .apply(black_box(&pair.right), &mut right)
                .expect("sizes match")
        })
    });
    c.bench_function("rectify_maps_build_640x480_pair", |b| {
        b.iter(|| StereoRectifier::from_calibration(black_box(&cal)).expect("valid calibration"))
    });
}

criterion_group!(benches, bench_rectify);
criterion_main!(benches);
