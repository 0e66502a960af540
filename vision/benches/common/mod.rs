//! Bench inputs: a 640x480 rectified pair made from a Middlebury pair of the shared data
//! (teddy, bilinearly upscaled from 450x375; disparities scale by 640/450), or a synthetic
//! textured pair when the data is absent; and a calibration shaped like the real rig's.
//!
//! Shared by several bench and example targets, each of which uses part of it.
#![allow(dead_code)]

use image::{imageops::FilterType, GrayImage};
use nalgebra::{Matrix3, Vector3};
use videt_vision::calib::file::QualityFigures;
use videt_vision::calib::{stereo_rectify, CameraIntrinsics, StereoCalibration};

/// The 640x480 bench pair (left, right).
pub fn vga_pair() -> (GrayImage, GrayImage) {
    vga_pair_of("teddy")
}

/// The Middlebury pair `name` of the shared data upscaled to 640x480 (left, right), or the
/// synthetic pair when the data is absent.
pub fn vga_pair_of(name: &str) -> (GrayImage, GrayImage) {
    if let Some(dir) = videt_testdata::data_dir(&format!("stereo/{name}")) {
        let load = |name: &str| {
            let img = image::open(dir.join(name))
                .expect("readable bench image")
                .to_luma8();
            image::imageops::resize(&img, 640, 480, FilterType::Triangle)
        };
        return (load("left.ppm"), load("right.ppm"));
    }
    synthetic_pair(640, 480, 20)
}

/// A deterministic textured pair with a constant disparity.
pub fn synthetic_pair(w: u32, h: u32, disparity: u32) -> (GrayImage, GrayImage) {
    let mut state = 7u64;
    let mut left = GrayImage::new(w + disparity, h);
    for _ in 0..400 {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let x0 = (state >> 33) as u32 % (w + disparity);
        let y0 = (state >> 17) as u32 % h;
        let v = (state >> 50) as u8;
        for y in y0..(y0 + 24).min(h) {
            for x in x0..(x0 + 30).min(w + disparity) {
                left.put_pixel(x, y, image::Luma([v]));
            }
        }
    }
    let l = image::imageops::crop_imm(&left, disparity, 0, w, h).to_image();
    let r = image::imageops::crop_imm(&left, 0, 0, w, h).to_image();
    (l, r)
}

/// A calibration shaped like the real 640x480 rig's.
pub fn rig_calibration() -> StereoCalibration {
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

/// Raw (distorted, unrectified) 640x480 camera frames of the bench pair as the rig of
/// [`rig_calibration`] would see it: every raw pixel takes the bench pair's value (bilinear) at
/// the rectified position the calibration maps it to, 0 where that falls outside. Rectifying
/// them gives back the bench pair (blurred by the two interpolations).
pub fn raw_vga_pair() -> (GrayImage, GrayImage) {
    let (left, right) = vga_pair();
    let cal = rig_calibration();
    let unrectify = |rectified: &GrayImage,
                     cam: CameraIntrinsics,
                     r: Matrix3<f64>,
                     p: nalgebra::Matrix3x4<f64>| {
        let (w, h) = rectified.dimensions();
        GrayImage::from_fn(w, h, |u, v| {
            let (xn, yn) = cam.pixel_to_normalised([f64::from(u), f64::from(v)]);
            let ray = r * Vector3::new(xn, yn, 1.0);
            let x = p[(0, 0)] * ray.x / ray.z + p[(0, 2)];
            let y = p[(1, 1)] * ray.y / ray.z + p[(1, 2)];
            if !(x >= 0.0 && y >= 0.0 && x < f64::from(w - 1) && y < f64::from(h - 1)) {
                return image::Luma([0]);
            }
            let (x0, y0) = (x.floor(), y.floor());
            let (fx, fy) = (x - x0, y - y0);
            let at = |dx: u32, dy: u32| {
                f64::from(rectified.get_pixel(x0 as u32 + dx, y0 as u32 + dy)[0])
            };
            let top = at(0, 0) * (1.0 - fx) + at(1, 0) * fx;
            let bottom = at(0, 1) * (1.0 - fx) + at(1, 1) * fx;
            image::Luma([(top * (1.0 - fy) + bottom * fy).round() as u8])
        })
    };
    (
        unrectify(&left, cal.left(), cal.r1(), cal.p1()),
        unrectify(&right, cal.right(), cal.r2(), cal.p2()),
    )
}
