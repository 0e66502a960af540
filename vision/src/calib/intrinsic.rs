//! Calibration of one camera from views of a planar target: Zhang's closed-form solution from the
//! view homographies, then Levenberg–Marquardt refinement of the intrinsics, the 5 distortion
//! coefficients and every view's pose (the reprojection error).

use nalgebra::{DMatrix, Matrix3, Vector3};

use super::camera_model::CameraIntrinsics;
use super::error::CalibError;
use super::geometry::{fit_homography, matrix_to_rodrigues, nearest_rotation, rodrigues_to_matrix};
use super::lm::{self, LmSettings, Residuals};

/// Pose of the target in the camera frame: `X_cam = R(rotation) * X_target + translation`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Rotation vector (axis times angle, radians).
    pub rotation: Vector3<f64>,
    /// Translation in target units (metres when the square size is in metres).
    pub translation: Vector3<f64>,
}

impl Pose {
    /// The rotation matrix.
    pub fn rotation_matrix(&self) -> Matrix3<f64> {
        rodrigues_to_matrix(&self.rotation)
    }

    /// Transform a target point into the camera frame.
    pub fn transform(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation_matrix() * p + self.translation
    }

    fn to_params(self, out: &mut [f64]) {
        out[..3].copy_from_slice(self.rotation.as_slice());
        out[3..6].copy_from_slice(self.translation.as_slice());
    }

    fn from_params(p: &[f64]) -> Self {
        Pose {
            rotation: Vector3::new(p[0], p[1], p[2]),
            translation: Vector3::new(p[3], p[4], p[5]),
        }
    }
}

/// Result of calibrating one camera.
#[derive(Debug, Clone)]
pub struct MonoCalibration {
    /// The camera's intrinsics and distortion.
    pub intrinsics: CameraIntrinsics,
    /// The target pose in every view, in the order of the views given.
    pub poses: Vec<Pose>,
    /// Root-mean-square reprojection error over all points, pixels.
    pub rms_px: f64,
    /// Root-mean-square reprojection error of each view, pixels.
    pub view_rms_px: Vec<f64>,
}

/// Minimum number of views for a calibration with distortion.
pub const MIN_VIEWS: usize = 3;

/// Calibrate one camera from `views` (image points, pixels) of the planar target points `object`
/// (z = 0) of an image `width` x `height` pixels.
pub fn calibrate_camera(
    object: &[Vector3<f64>],
    views: &[Vec<[f64; 2]>],
    width: u32,
    height: u32,
) -> Result<MonoCalibration, CalibError> {
    if views.len() < MIN_VIEWS {
        return Err(CalibError::TooFewViews {
            what: "camera calibration",
            found: views.len(),
            needed: MIN_VIEWS,
        });
    }
    let plane: Vec<[f64; 2]> = object.iter().map(|p| [p.x, p.y]).collect();
    let mut homographies = Vec::with_capacity(views.len());
    for (i, v) in views.iter().enumerate() {
        if v.len() != object.len() {
            return Err(CalibError::Numerical(format!(
                "view {i} has {} points, the target has {}",
                v.len(),
                object.len()
            )));
        }
        let h = fit_homography(&plane, v)
            .ok_or_else(|| CalibError::Numerical(format!("view {i}: degenerate target points")))?;
        homographies.push(h);
    }
    let k = zhang_intrinsics(&homographies, width, height)
        .or_else(|| fixed_centre_intrinsics(&homographies, width, height))
        .ok_or_else(|| {
            CalibError::Numerical("no valid initial focal length from the view homographies".into())
        })?;
    let mut intrinsics = CameraIntrinsics {
        fx: k[(0, 0)],
        fy: k[(1, 1)],
        cx: k[(0, 2)],
        cy: k[(1, 2)],
        dist: [0.0; 5],
    };
    let mut poses: Vec<Pose> = homographies
        .iter()
        .map(|h| pose_from_homography(&k, h))
        .collect();

    // Poses first (intrinsics held), then everything jointly.
    for (pose, view) in poses.iter_mut().zip(views) {
        *pose = refine_pose(&intrinsics, object, view, *pose)?;
    }
    let problem = MonoProblem { object, views };
    let mut params = vec![0.0; problem.num_params()];
    params[..9].copy_from_slice(&intrinsics.to_params());
    for (i, pose) in poses.iter().enumerate() {
        pose.to_params(&mut params[9 + 6 * i..15 + 6 * i]);
    }
    lm::solve(&problem, &mut params, LmSettings::default()).map_err(CalibError::Numerical)?;
    intrinsics = CameraIntrinsics::from_params(&params[..9]);
    if !(intrinsics.fx > 0.0 && intrinsics.fy > 0.0) || params.iter().any(|v| !v.is_finite()) {
        return Err(CalibError::Numerical(
            "refinement diverged (non-positive focal length)".into(),
        ));
    }
    let poses: Vec<Pose> = (0..views.len())
        .map(|i| Pose::from_params(&params[9 + 6 * i..15 + 6 * i]))
        .collect();
    let view_sq: Vec<f64> = views
        .iter()
        .zip(&poses)
        .map(|(v, p)| view_squared_error(&intrinsics, p, object, v))
        .collect();
    let total: f64 = view_sq.iter().sum();
    let n_points = (views.len() * object.len()) as f64;
    Ok(MonoCalibration {
        intrinsics,
        poses,
        rms_px: (total / n_points).sqrt(),
        view_rms_px: view_sq
            .iter()
            .map(|s| (s / object.len() as f64).sqrt())
            .collect(),
    })
}

/// Sum of squared reprojection distances of one view, pixels squared.
pub fn view_squared_error(
    cam: &CameraIntrinsics,
    pose: &Pose,
    object: &[Vector3<f64>],
    image: &[[f64; 2]],
) -> f64 {
    let r = pose.rotation_matrix();
    object
        .iter()
        .zip(image)
        .map(|(p, q)| {
            let uv = cam.project(&(r * p + pose.translation));
            (uv[0] - q[0]).powi(2) + (uv[1] - q[1]).powi(2)
        })
        .sum()
}

/// Refine one pose with the intrinsics held (also the per-view pose solver used by stereo
/// initialisation).
pub fn refine_pose(
    cam: &CameraIntrinsics,
    object: &[Vector3<f64>],
    image: &[[f64; 2]],
    initial: Pose,
) -> Result<Pose, CalibError> {
    let problem = PoseProblem { cam, object, image };
    let mut params = [0.0; 6];
    initial.to_params(&mut params);
    lm::solve(
        &problem,
        &mut params,
        LmSettings {
            max_iterations: 50,
            ..LmSettings::default()
        },
    )
    .map_err(CalibError::Numerical)?;
    Ok(Pose::from_params(&params))
}

/// Target pose from a homography and the camera matrix (no distortion).
pub fn pose_from_homography(k: &Matrix3<f64>, h: &Matrix3<f64>) -> Pose {
    let k_inv = k.try_inverse().unwrap_or_else(Matrix3::identity);
    let a = k_inv * h;
    let mut lambda = 1.0 / a.column(0).norm().max(1e-300);
    if (a * lambda)[(2, 2)] < 0.0 {
        lambda = -lambda;
    }
    let r1: Vector3<f64> = a.column(0) * lambda;
    let r2: Vector3<f64> = a.column(1) * lambda;
    let t: Vector3<f64> = a.column(2) * lambda;
    let r3 = r1.cross(&r2);
    let r = nearest_rotation(&Matrix3::from_columns(&[r1, r2, r3]));
    Pose {
        rotation: matrix_to_rodrigues(&r),
        translation: t,
    }
}

/// Zhang's closed form (zero skew imposed) on homographies expressed in image coordinates
/// normalised to the image size. `None` when the solution is not a valid camera.
fn zhang_intrinsics(
    homographies: &[Matrix3<f64>],
    width: u32,
    height: u32,
) -> Option<Matrix3<f64>> {
    let (w, h) = (f64::from(width), f64::from(height));
    let s = 1.0 / w.max(h);
    let norm = Matrix3::new(s, 0.0, -0.5 * w * s, 0.0, s, -0.5 * h * s, 0.0, 0.0, 1.0);
    let mut v = DMatrix::<f64>::zeros(2 * homographies.len() + 1, 6);
    for (i, hm) in homographies.iter().enumerate() {
        let hn = norm * hm;
        let vij = |a: usize, b: usize| -> [f64; 6] {
            let (hi, hj) = (hn.column(a), hn.column(b));
            [
                hi[0] * hj[0],
                hi[0] * hj[1] + hi[1] * hj[0],
                hi[1] * hj[1],
                hi[2] * hj[0] + hi[0] * hj[2],
                hi[2] * hj[1] + hi[1] * hj[2],
                hi[2] * hj[2],
            ]
        };
        let v12 = vij(0, 1);
        let v11 = vij(0, 0);
        let v22 = vij(1, 1);
        for c in 0..6 {
            v[(2 * i, c)] = v12[c];
            v[(2 * i + 1, c)] = v11[c] - v22[c];
        }
    }
    // Zero skew: B12 = 0.
    let last = 2 * homographies.len();
    v[(last, 1)] = 1.0;
    let eig = (v.transpose() * &v).symmetric_eigen();
    let mut idx = 0;
    for i in 1..6 {
        if eig.eigenvalues[i] < eig.eigenvalues[idx] {
            idx = i;
        }
    }
    let b = eig.eigenvectors.column(idx);
    let (b11, b12, b22, b13, b23, b33) = (b[0], b[1], b[2], b[3], b[4], b[5]);
    let den = b11 * b22 - b12 * b12;
    if den.abs() < 1e-300 || b11.abs() < 1e-300 {
        return None;
    }
    let v0 = (b12 * b13 - b11 * b23) / den;
    let lambda = b33 - (b13 * b13 + v0 * (b12 * b13 - b11 * b23)) / b11;
    let alpha_sq = lambda / b11;
    let beta_sq = lambda * b11 / den;
    if !(alpha_sq > 0.0 && beta_sq > 0.0) {
        return None;
    }
    let alpha = alpha_sq.sqrt();
    let beta = beta_sq.sqrt();
    let u0 = -b13 * alpha * alpha / lambda;
    let kn = Matrix3::new(alpha, 0.0, u0, 0.0, beta, v0, 0.0, 0.0, 1.0);
    let k = norm.try_inverse()? * kn;
    let plausible = k[(0, 2)] > 0.0 && k[(0, 2)] < w && k[(1, 2)] > 0.0 && k[(1, 2)] < h;
    let aspect = k[(0, 0)] / k[(1, 1)];
    (plausible && (0.5..2.0).contains(&aspect) && k.iter().all(|x| x.is_finite())).then_some(k)
}

/// OpenCV-style initialisation: principal point at the image centre, focal lengths by linear
/// least squares on the orthogonality constraints.
fn fixed_centre_intrinsics(
    homographies: &[Matrix3<f64>],
    width: u32,
    height: u32,
) -> Option<Matrix3<f64>> {
    let (cx, cy) = (
        (f64::from(width) - 1.0) * 0.5,
        (f64::from(height) - 1.0) * 0.5,
    );
    let shift = Matrix3::new(1.0, 0.0, -cx, 0.0, 1.0, -cy, 0.0, 0.0, 1.0);
    let mut a = DMatrix::<f64>::zeros(2 * homographies.len(), 2);
    let mut rhs = nalgebra::DVector::<f64>::zeros(2 * homographies.len());
    for (i, hm) in homographies.iter().enumerate() {
        let h = shift * hm;
        let (h1, h2) = (h.column(0), h.column(1));
        // h1^T B h2 = 0 and h1^T B h1 = h2^T B h2 with B = diag(u, w, 1).
        a[(2 * i, 0)] = h1[0] * h2[0];
        a[(2 * i, 1)] = h1[1] * h2[1];
        rhs[2 * i] = -h1[2] * h2[2];
        a[(2 * i + 1, 0)] = h1[0] * h1[0] - h2[0] * h2[0];
        a[(2 * i + 1, 1)] = h1[1] * h1[1] - h2[1] * h2[1];
        rhs[2 * i + 1] = -(h1[2] * h1[2] - h2[2] * h2[2]);
    }
    let sol = (a.transpose() * &a).try_inverse()? * a.transpose() * rhs;
    if !(sol[0] > 0.0 && sol[1] > 0.0) {
        return None;
    }
    let fx = 1.0 / sol[0].sqrt();
    let fy = 1.0 / sol[1].sqrt();
    Some(Matrix3::new(fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0))
}

/// Joint refinement: parameters `[fx fy cx cy k1 k2 p1 p2 k3, (rvec, tvec) per view]`.
struct MonoProblem<'a> {
    object: &'a [Vector3<f64>],
    views: &'a [Vec<[f64; 2]>],
}

impl Residuals for MonoProblem<'_> {
    fn num_params(&self) -> usize {
        9 + 6 * self.views.len()
    }
    fn num_residuals(&self) -> usize {
        2 * self.object.len() * self.views.len()
    }
    fn evaluate(&self, params: &[f64], out: &mut [f64]) {
        let cam = CameraIntrinsics::from_params(&params[..9]);
        let n = self.object.len();
        for (v, view) in self.views.iter().enumerate() {
            let pose = Pose::from_params(&params[9 + 6 * v..15 + 6 * v]);
            project_residuals(
                &cam,
                &pose,
                self.object,
                view,
                &mut out[2 * n * v..2 * n * (v + 1)],
            );
        }
    }
    fn affected_rows(&self, index: usize) -> Option<std::ops::Range<usize>> {
        if index < 9 {
            return None;
        }
        let v = (index - 9) / 6;
        let n2 = 2 * self.object.len();
        Some(n2 * v..n2 * (v + 1))
    }
    fn evaluate_rows(&self, params: &[f64], rows: std::ops::Range<usize>, out: &mut [f64]) {
        let n2 = 2 * self.object.len();
        if rows.len() != n2 || !rows.start.is_multiple_of(n2) {
            let mut all = vec![0.0; self.num_residuals()];
            self.evaluate(params, &mut all);
            out.copy_from_slice(&all[rows]);
            return;
        }
        let v = rows.start / n2;
        let cam = CameraIntrinsics::from_params(&params[..9]);
        let pose = Pose::from_params(&params[9 + 6 * v..15 + 6 * v]);
        project_residuals(&cam, &pose, self.object, &self.views[v], out);
    }
}

/// One pose with fixed intrinsics.
struct PoseProblem<'a> {
    cam: &'a CameraIntrinsics,
    object: &'a [Vector3<f64>],
    image: &'a [[f64; 2]],
}

impl Residuals for PoseProblem<'_> {
    fn num_params(&self) -> usize {
        6
    }
    fn num_residuals(&self) -> usize {
        2 * self.object.len()
    }
    fn evaluate(&self, params: &[f64], out: &mut [f64]) {
        project_residuals(
            self.cam,
            &Pose::from_params(params),
            self.object,
            self.image,
            out,
        );
    }
}

/// Reprojection residuals `(u - u_obs, v - v_obs)` of one view into `out`.
pub(crate) fn project_residuals(
    cam: &CameraIntrinsics,
    pose: &Pose,
    object: &[Vector3<f64>],
    image: &[[f64; 2]],
    out: &mut [f64],
) {
    let r = pose.rotation_matrix();
    for (k, (p, q)) in object.iter().zip(image).enumerate() {
        let uv = cam.project(&(r * p + pose.translation));
        out[2 * k] = uv[0] - q[0];
        out[2 * k + 1] = uv[1] - q[1];
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A 9x6 target, unit squares.
    pub(crate) fn board(cols: usize, rows: usize, square: f64) -> Vec<Vector3<f64>> {
        (0..rows)
            .flat_map(|r| {
                (0..cols).map(move |c| Vector3::new(c as f64 * square, r as f64 * square, 0.0))
            })
            .collect()
    }

    pub(crate) fn synthetic_poses() -> Vec<Pose> {
        let rot = [
            [0.1, -0.3, 0.05],
            [-0.35, 0.2, -0.1],
            [0.3, 0.3, 0.2],
            [-0.2, -0.4, 0.0],
            [0.45, -0.1, -0.2],
            [0.0, 0.5, 0.1],
        ];
        let tr = [
            [-4.0, -2.5, 14.0],
            [-3.5, -3.0, 12.0],
            [-5.0, -2.0, 15.0],
            [-3.0, -2.0, 13.0],
            [-4.0, -3.5, 12.5],
            [-4.5, -2.5, 14.5],
        ];
        rot.iter()
            .zip(tr)
            .map(|(r, t)| Pose {
                rotation: Vector3::new(r[0], r[1], r[2]),
                translation: Vector3::new(t[0], t[1], t[2]),
            })
            .collect()
    }

    #[test]
    fn recovers_synthetic_camera() {
        let truth = CameraIntrinsics {
            fx: 530.0,
            fy: 528.0,
            cx: 330.0,
            cy: 242.0,
            dist: [-0.27, 0.08, 0.0015, -0.0008, -0.02],
        };
        let object = board(9, 6, 1.0);
        let poses = synthetic_poses();
        let views: Vec<Vec<[f64; 2]>> = poses
            .iter()
            .map(|p| {
                object
                    .iter()
                    .map(|x| truth.project(&p.transform(x)))
                    .collect()
            })
            .collect();
        for v in &views {
            for q in v {
                assert!(
                    q[0] > 0.0 && q[0] < 640.0 && q[1] > 0.0 && q[1] < 480.0,
                    "point off image {q:?}"
                );
            }
        }
        let cal = calibrate_camera(&object, &views, 640, 480).expect("calibrates");
        let c = cal.intrinsics;
        assert!(cal.rms_px < 1e-6, "rms {}", cal.rms_px);
        assert!(
            (c.fx - truth.fx).abs() < 1e-3 && (c.fy - truth.fy).abs() < 1e-3,
            "{c:?}"
        );
        assert!(
            (c.cx - truth.cx).abs() < 1e-3 && (c.cy - truth.cy).abs() < 1e-3,
            "{c:?}"
        );
        for i in 0..5 {
            assert!(
                (c.dist[i] - truth.dist[i]).abs() < 1e-4,
                "dist {i}: {:?}",
                c.dist
            );
        }
        for (p, t) in cal.poses.iter().zip(&poses) {
            assert!(
                (p.rotation - t.rotation).norm() < 1e-6
                    && (p.translation - t.translation).norm() < 1e-5
            );
        }
    }

    #[test]
    fn too_few_views_is_an_error() {
        let object = board(9, 6, 1.0);
        let view: Vec<[f64; 2]> = object.iter().map(|p| [p.x * 10.0, p.y * 10.0]).collect();
        let err = calibrate_camera(&object, &[view.clone(), view], 640, 480).unwrap_err();
        assert!(
            matches!(
                err,
                CalibError::TooFewViews {
                    found: 2,
                    needed: 3,
                    ..
                }
            ),
            "{err}"
        );
    }
}
