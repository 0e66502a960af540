//! The pinhole camera with the 5-coefficient Brown–Conrady distortion (k1, k2, p1, p2, k3),
//! the model OpenCV calls the standard one.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Intrinsic parameters of one camera, in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraIntrinsics {
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Distortion coefficients `[k1, k2, p1, p2, k3]`.
    pub dist: [f64; 5],
}

impl CameraIntrinsics {
    /// Number of parameters in [`Self::to_params`].
    pub const PARAMS: usize = 9;

    /// The camera matrix `K`.
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0)
    }

    /// Parameters as `[fx, fy, cx, cy, k1, k2, p1, p2, k3]`.
    pub fn to_params(&self) -> [f64; 9] {
        let d = self.dist;
        [
            self.fx, self.fy, self.cx, self.cy, d[0], d[1], d[2], d[3], d[4],
        ]
    }

    /// The inverse of [`Self::to_params`].
    pub fn from_params(p: &[f64]) -> Self {
        CameraIntrinsics {
            fx: p[0],
            fy: p[1],
            cx: p[2],
            cy: p[3],
            dist: [p[4], p[5], p[6], p[7], p[8]],
        }
    }

    /// Distort normalised undistorted coordinates (x, y) = (X/Z, Y/Z).
    pub fn distort_normalised(&self, x: f64, y: f64) -> (f64, f64) {
        let [k1, k2, p1, p2, k3] = self.dist;
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
        (xd, yd)
    }

    /// Pixel of the normalised undistorted coordinates (x, y).
    pub fn normalised_to_pixel(&self, x: f64, y: f64) -> [f64; 2] {
        let (xd, yd) = self.distort_normalised(x, y);
        [self.fx * xd + self.cx, self.fy * yd + self.cy]
    }

    /// Pixel of the camera-frame point `p` (which must lie in front of the camera).
    pub fn project(&self, p: &Vector3<f64>) -> [f64; 2] {
        self.normalised_to_pixel(p.x / p.z, p.y / p.z)
    }

    /// Normalised undistorted coordinates of a pixel (fixed-point iteration, like OpenCV's
    /// `undistortPoints`, run to convergence).
    pub fn pixel_to_normalised(&self, pixel: [f64; 2]) -> (f64, f64) {
        let xd = (pixel[0] - self.cx) / self.fx;
        let yd = (pixel[1] - self.cy) / self.fy;
        let [k1, k2, p1, p2, k3] = self.dist;
        let (mut x, mut y) = (xd, yd);
        for _ in 0..50 {
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
            if radial.abs() < 1e-12 || !radial.is_finite() {
                break;
            }
            let dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
            let dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
            let nx = (xd - dx) / radial;
            let ny = (yd - dy) / radial;
            let step = (nx - x).abs() + (ny - y).abs();
            x = nx;
            y = ny;
            if step < 1e-14 {
                break;
            }
        }
        (x, y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn undistort_inverts_distort() {
        let cam = CameraIntrinsics {
            fx: 536.0,
            fy: 536.0,
            cx: 342.0,
            cy: 235.0,
            dist: [-0.265, -0.0466, 0.0018, -0.0003, 0.252],
        };
        for &(x, y) in &[(0.0, 0.0), (0.3, -0.2), (-0.4, 0.3), (0.5, 0.1)] {
            let px = cam.normalised_to_pixel(x, y);
            let (bx, by) = cam.pixel_to_normalised(px);
            assert!(
                (bx - x).abs() < 1e-9 && (by - y).abs() < 1e-9,
                "({x},{y}) -> ({bx},{by})"
            );
        }
    }
}
