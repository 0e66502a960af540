//! Stereo calibration with the intrinsics held: the rigid transform from the left to the right
//! camera (`X_right = R * X_left + T`, OpenCV's convention), refined jointly with the target
//! pose of every view by Levenberg–Marquardt on the reprojection error in both images.

use nalgebra::{Matrix3, Vector3};

use super::camera_model::CameraIntrinsics;
use super::error::CalibError;
use super::geometry::{matrix_to_rodrigues, rodrigues_to_matrix};
use super::intrinsic::{project_residuals, view_squared_error, Pose};
use super::lm::{self, LmSettings, Residuals};

/// Result of the stereo calibration.
#[derive(Debug, Clone)]
pub struct StereoExtrinsics {
    /// Rotation from the left to the right camera frame.
    pub r: Matrix3<f64>,
    /// Translation from the left to the right camera frame (target units).
    pub t: Vector3<f64>,
    /// Target pose in the left camera, per view.
    pub left_poses: Vec<Pose>,
    /// RMS reprojection error over both cameras, pixels.
    pub rms_px: f64,
    /// RMS reprojection error of each view pair over both cameras, pixels.
    pub view_rms_px: Vec<f64>,
}

/// Calibrate the pair from views seen by both cameras. `left_poses` and `right_poses` are the
/// per-camera calibration poses of the same views (used to initialise).
pub fn calibrate_stereo(
    object: &[Vector3<f64>],
    left: &CameraIntrinsics,
    right: &CameraIntrinsics,
    left_views: &[Vec<[f64; 2]>],
    right_views: &[Vec<[f64; 2]>],
    left_poses: &[Pose],
    right_poses: &[Pose],
) -> Result<StereoExtrinsics, CalibError> {
    let n_views = left_views.len();
    if n_views == 0
        || right_views.len() != n_views
        || left_poses.len() != n_views
        || right_poses.len() != n_views
    {
        return Err(CalibError::TooFewViews {
            what: "stereo calibration",
            found: n_views.min(right_views.len()),
            needed: 1,
        });
    }
    // Initial R, T: component-wise median of the per-view relative transforms.
    let mut rvecs = [Vec::new(), Vec::new(), Vec::new()];
    let mut tvecs = [Vec::new(), Vec::new(), Vec::new()];
    for (pl, pr) in left_poses.iter().zip(right_poses) {
        let r = pr.rotation_matrix() * pl.rotation_matrix().transpose();
        let t = pr.translation - r * pl.translation;
        let om = matrix_to_rodrigues(&r);
        for k in 0..3 {
            rvecs[k].push(om[k]);
            tvecs[k].push(t[k]);
        }
    }
    let om0 = Vector3::new(
        median(&mut rvecs[0]),
        median(&mut rvecs[1]),
        median(&mut rvecs[2]),
    );
    let t0 = Vector3::new(
        median(&mut tvecs[0]),
        median(&mut tvecs[1]),
        median(&mut tvecs[2]),
    );

    let problem = StereoProblem {
        object,
        left,
        right,
        left_views,
        right_views,
    };
    let mut params = vec![0.0; problem.num_params()];
    params[..3].copy_from_slice(om0.as_slice());
    params[3..6].copy_from_slice(t0.as_slice());
    for (i, p) in left_poses.iter().enumerate() {
        params[6 + 6 * i..9 + 6 * i].copy_from_slice(p.rotation.as_slice());
        params[9 + 6 * i..12 + 6 * i].copy_from_slice(p.translation.as_slice());
    }
    lm::solve(&problem, &mut params, LmSettings::default()).map_err(CalibError::Numerical)?;
    if params.iter().any(|v| !v.is_finite()) {
        return Err(CalibError::Numerical("stereo refinement diverged".into()));
    }
    let r = rodrigues_to_matrix(&Vector3::new(params[0], params[1], params[2]));
    let t = Vector3::new(params[3], params[4], params[5]);
    let left_poses: Vec<Pose> = (0..n_views).map(|i| pose_at(&params, i)).collect();
    let mut total = 0.0;
    let mut view_rms_px = Vec::with_capacity(n_views);
    for (i, pl) in left_poses.iter().enumerate() {
        let pr = right_pose(&r, &t, pl);
        let sq = view_squared_error(left, pl, object, &left_views[i])
            + view_squared_error(right, &pr, object, &right_views[i]);
        total += sq;
        view_rms_px.push((sq / (2 * object.len()) as f64).sqrt());
    }
    let rms_px = (total / (2 * n_views * object.len()) as f64).sqrt();
    Ok(StereoExtrinsics {
        r,
        t,
        left_poses,
        rms_px,
        view_rms_px,
    })
}

/// The target pose in the right camera given the pose in the left one.
pub fn right_pose(r: &Matrix3<f64>, t: &Vector3<f64>, left: &Pose) -> Pose {
    let rot = r * left.rotation_matrix();
    Pose {
        rotation: matrix_to_rodrigues(&rot),
        translation: r * left.translation + t,
    }
}

fn pose_at(params: &[f64], view: usize) -> Pose {
    let b = 6 + 6 * view;
    Pose {
        rotation: Vector3::new(params[b], params[b + 1], params[b + 2]),
        translation: Vector3::new(params[b + 3], params[b + 4], params[b + 5]),
    }
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

impl StereoProblem<'_> {
    /// Residuals of view `v`: left (u, v) pairs, then right.
    fn evaluate_view(&self, params: &[f64], v: usize, out: &mut [f64]) {
        let r = rodrigues_to_matrix(&Vector3::new(params[0], params[1], params[2]));
        let t = Vector3::new(params[3], params[4], params[5]);
        let n2 = 2 * self.object.len();
        let pl = pose_at(params, v);
        let (lo, ro) = out.split_at_mut(n2);
        project_residuals(self.left, &pl, self.object, &self.left_views[v], lo);
        // Right pose composed directly as a matrix (avoids a Rodrigues round trip).
        let rot = r * pl.rotation_matrix();
        let tr = r * pl.translation + t;
        for (k, (p, q)) in self.object.iter().zip(&self.right_views[v]).enumerate() {
            let uv = self.right.project(&(rot * p + tr));
            ro[2 * k] = uv[0] - q[0];
            ro[2 * k + 1] = uv[1] - q[1];
        }
    }
}

/// Parameters `[rvec_lr, t_lr, (rvec, tvec) of the target in the left camera per view]`.
struct StereoProblem<'a> {
    object: &'a [Vector3<f64>],
    left: &'a CameraIntrinsics,
    right: &'a CameraIntrinsics,
    left_views: &'a [Vec<[f64; 2]>],
    right_views: &'a [Vec<[f64; 2]>],
}

impl Residuals for StereoProblem<'_> {
    fn num_params(&self) -> usize {
        6 + 6 * self.left_views.len()
    }
    fn num_residuals(&self) -> usize {
        4 * self.object.len() * self.left_views.len()
    }
    fn evaluate(&self, params: &[f64], out: &mut [f64]) {
        let n4 = 4 * self.object.len();
        for v in 0..self.left_views.len() {
            self.evaluate_view(params, v, &mut out[n4 * v..n4 * (v + 1)]);
        }
    }
    fn evaluate_rows(&self, params: &[f64], rows: std::ops::Range<usize>, out: &mut [f64]) {
        let n4 = 4 * self.object.len();
        if rows.len() == n4 && rows.start.is_multiple_of(n4) {
            self.evaluate_view(params, rows.start / n4, out);
        } else {
            let mut all = vec![0.0; self.num_residuals()];
            self.evaluate(params, &mut all);
            out.copy_from_slice(&all[rows]);
        }
    }
    fn affected_rows(&self, index: usize) -> Option<std::ops::Range<usize>> {
        if index < 6 {
            return None;
        }
        let v = (index - 6) / 6;
        let n4 = 4 * self.object.len();
        Some(n4 * v..n4 * (v + 1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::intrinsic::calibrate_camera;
    use crate::calib::intrinsic::tests::{board, synthetic_poses};

    #[test]
    fn recovers_synthetic_rig() {
        let left = CameraIntrinsics {
            fx: 536.0,
            fy: 535.0,
            cx: 330.0,
            cy: 240.0,
            dist: [-0.26, 0.05, 0.001, -0.0005, 0.0],
        };
        let right = CameraIntrinsics {
            fx: 540.0,
            fy: 541.0,
            cx: 325.0,
            cy: 245.0,
            dist: [-0.28, 0.1, -0.0005, 0.001, -0.02],
        };
        let r = rodrigues_to_matrix(&Vector3::new(0.004, -0.003, 0.002));
        let t = Vector3::new(-3.3, 0.04, 0.05);
        let object = board(9, 6, 1.0);
        let poses = synthetic_poses();
        let lv: Vec<Vec<[f64; 2]>> = poses
            .iter()
            .map(|p| {
                object
                    .iter()
                    .map(|x| left.project(&p.transform(x)))
                    .collect()
            })
            .collect();
        let rv: Vec<Vec<[f64; 2]>> = poses
            .iter()
            .map(|p| {
                let pr = right_pose(&r, &t, p);
                object
                    .iter()
                    .map(|x| right.project(&pr.transform(x)))
                    .collect()
            })
            .collect();
        let cl = calibrate_camera(&object, &lv, 640, 480).unwrap();
        let cr = calibrate_camera(&object, &rv, 640, 480).unwrap();
        let st = calibrate_stereo(
            &object,
            &cl.intrinsics,
            &cr.intrinsics,
            &lv,
            &rv,
            &cl.poses,
            &cr.poses,
        )
        .unwrap();
        assert!(st.rms_px < 1e-6, "rms {}", st.rms_px);
        assert!((st.r - r).norm() < 1e-7, "{}", st.r);
        assert!((st.t - t).norm() < 1e-6, "{}", st.t);
    }
}
