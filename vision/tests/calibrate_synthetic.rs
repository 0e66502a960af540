//! End to end on rendered images: a known stereo rig photographs a chessboard; the calibration
//! from the images recovers the rig, and a pair without a board is reported and skipped.

use std::path::Path;

use nalgebra::{Matrix3, Vector3};
use videt_vision::calib::geometry::rodrigues_to_matrix;
use videt_vision::calib::{calibrate_stereo_dir, CameraIntrinsics};

const WIDTH: u32 = 320;
const HEIGHT: u32 = 240;
const COLS: usize = 7;
const ROWS: usize = 5;

/// Render the board (square side 1, dark square between corners (0,0) and (1,1), one-square
/// white margin, grey background) seen by a distortion-free camera `k` at pose (r, t).
fn render(path: &Path, k: &Matrix3<f64>, r: &Matrix3<f64>, t: &Vector3<f64>) {
    let h = k * Matrix3::from_columns(&[r.column(0).into_owned(), r.column(1).into_owned(), *t]);
    let h_inv = h.try_inverse().unwrap();
    let img = image::GrayImage::from_fn(WIDTH, HEIGHT, |x, y| {
        let mut acc = 0.0f64;
        for sy in 0..2 {
            for sx in 0..2 {
                let p = h_inv
                    * Vector3::new(
                        x as f64 + 0.25 + 0.5 * sx as f64 - 0.5,
                        y as f64 + 0.25 + 0.5 * sy as f64 - 0.5,
                        1.0,
                    );
                let (bx, by) = (p.x / p.z, p.y / p.z);
                let (c, r) = ((bx + 1.0).floor(), (by + 1.0).floor());
                acc += if c >= 0.0 && r >= 0.0 && c <= COLS as f64 && r <= ROWS as f64 {
                    if (c + r) as i64 % 2 == 0 {
                        30.0
                    } else {
                        220.0
                    }
                } else if bx > -2.0 && by > -2.0 && bx < COLS as f64 + 1.0 && by < ROWS as f64 + 1.0
                {
                    220.0
                } else {
                    110.0
                };
            }
        }
        image::Luma([(acc / 4.0).round() as u8])
    });
    img.save(path).unwrap();
}

#[test]
fn rendered_rig_is_recovered_and_blank_pair_skipped() {
    let left = CameraIntrinsics {
        fx: 400.0,
        fy: 400.0,
        cx: 158.0,
        cy: 121.0,
        dist: [0.0; 5],
    };
    let right = CameraIntrinsics {
        fx: 405.0,
        fy: 405.0,
        cx: 162.0,
        cy: 118.0,
        dist: [0.0; 5],
    };
    let r_lr = rodrigues_to_matrix(&Vector3::new(0.002, -0.01, 0.003));
    let t_lr = Vector3::new(-1.5, 0.02, 0.01);
    let dir = tempfile::tempdir().unwrap();
    let poses = [
        ([0.15, -0.25, 0.05], [-2.5, -2.0, 14.0]),
        ([-0.3, 0.2, -0.1], [-2.5, -2.0, 13.0]),
        ([0.25, 0.3, 0.15], [-3.5, -2.0, 15.0]),
        ([-0.2, -0.35, 0.0], [-2.0, -2.0, 14.0]),
        ([0.4, 0.05, -0.2], [-2.5, -2.5, 14.0]),
    ];
    for (i, (rv, tv)) in poses.iter().enumerate() {
        let r = rodrigues_to_matrix(&Vector3::new(rv[0], rv[1], rv[2]));
        let t = Vector3::new(tv[0], tv[1], tv[2]);
        render(
            &dir.path().join(format!("left{:02}.png", i + 1)),
            &left.matrix(),
            &r,
            &t,
        );
        render(
            &dir.path().join(format!("right{:02}.png", i + 1)),
            &right.matrix(),
            &(r_lr * r),
            &(r_lr * t + t_lr),
        );
    }
    // A pair in which the board is missing.
    for side in ["left", "right"] {
        image::GrayImage::from_pixel(WIDTH, HEIGHT, image::Luma([90]))
            .save(dir.path().join(format!("{side}06.png")))
            .unwrap();
    }

    let (cal, report) = calibrate_stereo_dir(dir.path(), COLS, ROWS, 1.0).expect("calibrates");
    let skipped: Vec<_> = report.skipped().iter().map(|v| v.id.clone()).collect();
    assert_eq!(skipped, ["06"]);
    assert_eq!(report.views.len(), 6);
    assert!(
        report.rms_stereo_px < 0.1,
        "stereo RMS {}",
        report.rms_stereo_px
    );
    eprintln!(
        "synthetic rig: RMS {:.3}/{:.3}/{:.3} px, epipolar {:.3} px",
        report.rms_left_px,
        report.rms_right_px,
        report.rms_stereo_px,
        report.epipolar_error_mean_px
    );
    assert!(
        report.epipolar_error_mean_px < 0.1,
        "epipolar {}",
        report.epipolar_error_mean_px
    );
    let (l, r) = (cal.left(), cal.right());
    for (got, want) in [
        (l.fx, left.fx),
        (l.fy, left.fy),
        (r.fx, right.fx),
        (r.fy, right.fy),
    ] {
        assert!((got - want).abs() < 0.01 * want, "focal {got} vs {want}");
    }
    for (got, want) in [
        (l.cx, left.cx),
        (l.cy, left.cy),
        (r.cx, right.cx),
        (r.cy, right.cy),
    ] {
        assert!((got - want).abs() < 3.0, "principal point {got} vs {want}");
    }
    let t = Vector3::from(cal.t_m);
    assert!((t - t_lr).norm() < 0.02 * t_lr.norm(), "T {t} vs {t_lr}");
    let r_got = Matrix3::from_fn(|i, j| cal.r[i][j]);
    let angle_err =
        videt_vision::calib::geometry::matrix_to_rodrigues(&(r_got * r_lr.transpose())).norm();
    eprintln!(
        "synthetic rig: rotation error {angle_err:.5} rad, T {t:?}, fx {:.2} {:.2}",
        l.fx, r.fx
    );
    assert!(angle_err < 5e-3, "R {r_got} vs {r_lr}");
}
