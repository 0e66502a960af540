//! Bouguet's stereo rectification (the algorithm of OpenCV's `stereoRectify` with
//! `CALIB_ZERO_DISPARITY`): each camera is turned by half the relative rotation, then both by the
//! rotation that aligns the baseline with the image x (or y) axis; a common focal length and
//! principal point are chosen so that, with the free-scaling parameter `alpha`, either only valid
//! pixels (`alpha = 0`) or all source pixels (`alpha = 1`) remain in view.

use nalgebra::{Matrix3, Matrix3x4, Matrix4, Vector3};

use super::camera_model::CameraIntrinsics;
use super::geometry::{matrix_to_rodrigues, rodrigues_to_matrix};

/// Rectifying rotations and projections of a stereo pair.
#[derive(Debug, Clone, PartialEq)]
pub struct Rectification {
    /// Rotation of the left camera frame into the rectified left frame.
    pub r1: Matrix3<f64>,
    /// Rotation of the right camera frame into the rectified right frame.
    pub r2: Matrix3<f64>,
    /// Projection of the rectified left frame to rectified left pixels.
    pub p1: Matrix3x4<f64>,
    /// Projection of the rectified left frame to rectified right pixels (`P2[0][3] = f * Tx`).
    pub p2: Matrix3x4<f64>,
    /// Disparity-to-depth matrix: `[X Y Z W]^T = Q [x y d 1]^T`.
    pub q: Matrix4<f64>,
}

/// Rectify the pair of `width` x `height` images with `X_right = r * X_left + t`.
/// `alpha` in [0, 1]: 0 crops to valid pixels, 1 keeps every source pixel.
pub fn stereo_rectify(
    left: &CameraIntrinsics,
    right: &CameraIntrinsics,
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
    width: u32,
    height: u32,
    alpha: f64,
) -> Rectification {
    let (w, h) = (f64::from(width), f64::from(height));
    // Half rotations: the right camera turns by -om/2, the left by +om/2 (as r_r^T).
    let om = matrix_to_rodrigues(r) * -0.5;
    let r_r = rodrigues_to_matrix(&om);
    let t_half = r_r * t;
    let idx = if t_half.x.abs() > t_half.y.abs() {
        0
    } else {
        1
    };
    let c = t_half[idx];
    let nt = t_half.norm();
    let mut uu = Vector3::zeros();
    uu[idx] = if c > 0.0 { 1.0 } else { -1.0 };
    let mut ww = t_half.cross(&uu);
    let nw = ww.norm();
    if nw > 0.0 {
        ww *= (c.abs() / nt).clamp(-1.0, 1.0).acos() / nw;
    }
    let w_r = rodrigues_to_matrix(&ww);
    let r1 = w_r * r_r.transpose();
    let r2 = w_r * r_r;
    let t_new = r2 * t;

    // Initial common focal length (scaled away again by the alpha step below).
    let mut fc_new = f64::INFINITY;
    for cam in [left, right] {
        let mut fc = if idx == 0 { cam.fy } else { cam.fx };
        let k1 = cam.dist[0];
        if k1 < 0.0 {
            fc *= 1.0 + k1 * (w * w + h * h) / (4.0 * fc * fc);
        }
        fc_new = fc_new.min(fc);
    }
    // Principal points that centre the image corners.
    let mut cc_new = [[0.0; 2]; 2];
    for (k, (cam, rot)) in [(left, &r1), (right, &r2)].into_iter().enumerate() {
        let mut avg = [0.0, 0.0];
        for (px, py) in [
            (0.0, 0.0),
            (w - 1.0, 0.0),
            (0.0, h - 1.0),
            (w - 1.0, h - 1.0),
        ] {
            let (x, y) = cam.pixel_to_normalised([px, py]);
            let p = rot * Vector3::new(x, y, 1.0);
            avg[0] += fc_new * p.x / p.z / 4.0;
            avg[1] += fc_new * p.y / p.z / 4.0;
        }
        cc_new[k] = [(w - 1.0) / 2.0 - avg[0], (h - 1.0) / 2.0 - avg[1]];
    }
    // Zero disparity: the same principal point in both images.
    let cc = [
        (cc_new[0][0] + cc_new[1][0]) * 0.5,
        (cc_new[0][1] + cc_new[1][1]) * 0.5,
    ];

    // Scale so that the inner (alpha = 0) or outer (alpha = 1) rectangle fills the image.
    let alpha = alpha.clamp(0.0, 1.0);
    let mut s0: f64 = 0.0;
    let mut s1: f64 = f64::INFINITY;
    for (cam, rot) in [(left, &r1), (right, &r2)] {
        let (inner, outer) = rectangles(cam, rot, fc_new, cc, width, height);
        let [cx, cy] = cc;
        s0 = s0
            .max(cx / (cx - inner[0]))
            .max(cy / (cy - inner[1]))
            .max((w - 1.0 - cx) / (inner[2] - cx))
            .max((h - 1.0 - cy) / (inner[3] - cy));
        s1 = s1
            .min(cx / (cx - outer[0]))
            .min(cy / (cy - outer[1]))
            .min((w - 1.0 - cx) / (outer[2] - cx))
            .min((h - 1.0 - cy) / (outer[3] - cy));
    }
    let s = s0 * (1.0 - alpha) + s1 * alpha;
    let s = if s.is_finite() && s > 0.0 { s } else { 1.0 };
    let f = fc_new * s;

    let mut p1 = Matrix3x4::zeros();
    p1[(0, 0)] = f;
    p1[(1, 1)] = f;
    p1[(0, 2)] = cc[0];
    p1[(1, 2)] = cc[1];
    p1[(2, 2)] = 1.0;
    let mut p2 = p1;
    p2[(idx, 3)] = t_new[idx] * f;

    let tx = t_new[idx];
    let mut q = Matrix4::zeros();
    q[(0, 0)] = 1.0;
    q[(0, 3)] = -cc[0];
    q[(1, 1)] = 1.0;
    q[(1, 3)] = -cc[1];
    q[(2, 3)] = f;
    q[(3, 2)] = -1.0 / tx;
    q[(3, 3)] = 0.0; // Equal principal points: (cx1 - cx2) / Tx = 0.
    Rectification { r1, r2, p1, p2, q }
}

/// Inner (largest inscribed) and outer (bounding) rectangles `[x0, y0, x1, y1]` of the image
/// border mapped into the rectified image with focal `f` and principal point `cc`.
fn rectangles(
    cam: &CameraIntrinsics,
    rot: &Matrix3<f64>,
    f: f64,
    cc: [f64; 2],
    width: u32,
    height: u32,
) -> ([f64; 4], [f64; 4]) {
    const N: usize = 9;
    let (w, h) = (f64::from(width), f64::from(height));
    let mut inner = [
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::INFINITY,
    ];
    let mut outer = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for yi in 0..N {
        for xi in 0..N {
            let px = [
                xi as f64 * w / (N - 1) as f64,
                yi as f64 * h / (N - 1) as f64,
            ];
            let [u, v] = rectify_pixel(cam, rot, f, cc, px);
            outer[0] = outer[0].min(u);
            outer[1] = outer[1].min(v);
            outer[2] = outer[2].max(u);
            outer[3] = outer[3].max(v);
            if xi == 0 {
                inner[0] = inner[0].max(u);
            }
            if xi == N - 1 {
                inner[2] = inner[2].min(u);
            }
            if yi == 0 {
                inner[1] = inner[1].max(v);
            }
            if yi == N - 1 {
                inner[3] = inner[3].min(v);
            }
        }
    }
    (inner, outer)
}

fn rectify_pixel(
    cam: &CameraIntrinsics,
    rot: &Matrix3<f64>,
    f: f64,
    cc: [f64; 2],
    pixel: [f64; 2],
) -> [f64; 2] {
    let (x, y) = cam.pixel_to_normalised(pixel);
    let p = rot * Vector3::new(x, y, 1.0);
    [f * p.x / p.z + cc[0], f * p.y / p.z + cc[1]]
}

/// Rectified pixel of a source pixel: undistort, rotate by `rot`, project with `p`.
pub fn rectify_point(
    cam: &CameraIntrinsics,
    rot: &Matrix3<f64>,
    p: &Matrix3x4<f64>,
    pixel: [f64; 2],
) -> [f64; 2] {
    let (x, y) = cam.pixel_to_normalised(pixel);
    let v = rot * Vector3::new(x, y, 1.0);
    [
        p[(0, 0)] * v.x / v.z + p[(0, 2)],
        p[(1, 1)] * v.y / v.z + p[(1, 2)],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two cameras and their extrinsics shaped like the real 640x480 rig's.
    fn rig() -> (
        CameraIntrinsics,
        CameraIntrinsics,
        nalgebra::Matrix3<f64>,
        Vector3<f64>,
    ) {
        let left = CameraIntrinsics {
            fx: 536.0,
            fy: 536.0,
            cx: 342.0,
            cy: 235.0,
            dist: [-0.26, -0.05, 0.002, 0.0, 0.25],
        };
        let right = CameraIntrinsics {
            fx: 542.0,
            fy: 541.0,
            cx: 328.0,
            cy: 247.0,
            dist: [-0.28, 0.1, 0.0, 0.001, -0.02],
        };
        let r = rodrigues_to_matrix(&Vector3::new(0.0003, 0.0035, -0.0041));
        let t = Vector3::new(-3.34, 0.04, 0.05);
        (left, right, r, t)
    }

    #[test]
    fn rectified_projections_share_rows() {
        let (left, right, r, t) = rig();
        let rect = stereo_rectify(&left, &right, &r, &t, 640, 480, 1.0);
        // Points in front of the rig must land on the same rectified row in both images.
        for p in [
            Vector3::new(0.5, -1.0, 15.0),
            Vector3::new(-3.0, 2.0, 12.0),
            Vector3::new(2.0, 1.5, 20.0),
        ] {
            let pl = left.project(&p);
            let pr = right.project(&(r * p + t));
            let ql = rectify_point(&left, &rect.r1, &rect.p1, pl);
            let qr = rectify_point(&right, &rect.r2, &rect.p2, pr);
            assert!((ql[1] - qr[1]).abs() < 1e-6, "{ql:?} {qr:?}");
            // Q maps (x, y, disparity) back to the point in the rectified left frame.
            let d = ql[0] - qr[0];
            let h = rect.q * nalgebra::Vector4::new(ql[0], ql[1], d, 1.0);
            let back = Vector3::new(h.x / h.w, h.y / h.w, h.z / h.w);
            assert!(
                (back - rect.r1 * p).norm() < 1e-6,
                "{back} vs {}",
                rect.r1 * p
            );
        }
        assert!((rect.r1.determinant() - 1.0).abs() < 1e-12);
        assert!(rect.p2[(0, 3)] < 0.0);
    }

    #[test]
    fn alpha_zero_keeps_only_valid_pixels_and_alpha_one_keeps_all_source_pixels() {
        use crate::rectify::RectifyMap;
        let (left, right, r, t) = rig();
        let (w, h) = (160u32, 120u32);
        let scale = |c: &CameraIntrinsics| CameraIntrinsics {
            fx: c.fx / 4.0,
            fy: c.fy / 4.0,
            cx: c.cx / 4.0,
            cy: c.cy / 4.0,
            dist: c.dist,
        };
        let (left, right) = (scale(&left), scale(&right));
        let crop = stereo_rectify(&left, &right, &r, &t, w, h, 0.0);
        let full = stereo_rectify(&left, &right, &r, &t, w, h, 1.0);
        assert!(crop.p1[(0, 0)] > full.p1[(0, 0)], "cropping zooms in");
        let cases = [
            (&left, &crop.r1, &crop.p1, &full.r1, &full.p1),
            (&right, &crop.r2, &crop.p2, &full.r2, &full.p2),
        ];
        for (cam, rot, p_crop, rot_full, p_full) in cases {
            let valid = RectifyMap::new(cam, rot, p_crop, w, h).valid_fraction();
            assert!(
                valid > 0.995,
                "alpha 0: {valid} of the rectified pixels valid"
            );
            let valid_full = RectifyMap::new(cam, rot_full, p_full, w, h).valid_fraction();
            assert!(valid_full < 0.97, "alpha 1 shows a border: {valid_full}");
            // Every source pixel stays in view with alpha 1 (half a pixel of slack).
            for px in [
                [0.0, 0.0],
                [159.0, 0.0],
                [0.0, 119.0],
                [159.0, 119.0],
                [80.0, 0.0],
                [0.0, 60.0],
            ] {
                let q = rectify_point(cam, rot_full, p_full, px);
                assert!(
                    q[0] > -0.5 && q[1] > -0.5 && q[0] < 159.5 && q[1] < 119.5,
                    "{px:?} -> {q:?}"
                );
            }
        }
    }
}
