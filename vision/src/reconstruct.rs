//! Back-projection of matched segments into 3D with a first-order uncertainty per endpoint.

use crate::matching::SegmentMatch;
use crate::segments::Segment;
use nalgebra::{Matrix3x4, Vector3};

/// The geometry of a rectified pair needed for back-projection: both cameras share the focal
/// length and principal point (OpenCV's `CALIB_ZERO_DISPARITY` convention), the right camera
/// sits `baseline_m` to the right of the left one. Depth is `Z = focal_px * baseline_m / d`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RectifiedGeometry {
    /// Focal length, pixels.
    pub focal_px: f64,
    /// Principal point column, pixels.
    pub cx_px: f64,
    /// Principal point row, pixels.
    pub cy_px: f64,
    /// Distance between the optical centres, metres (or the calibration's length unit).
    pub baseline_m: f64,
}

impl RectifiedGeometry {
    /// From the rectified projection matrices `P1 = [f 0 cx 0; 0 f cy 0; 0 0 1 0]` and
    /// `P2 = [f 0 cx -f B; ...]` (OpenCV `stereoRectify`). Errors when the matrices are not of
    /// that form (non-positive focal length or baseline).
    pub fn from_projections(p1: &Matrix3x4<f64>, p2: &Matrix3x4<f64>) -> Result<Self, String> {
        let focal = p1[(0, 0)];
        if !(focal.is_finite() && focal > 0.0) {
            return Err(format!("P1[0][0] (focal length) = {focal} must be > 0"));
        }
        let baseline = (-p2[(0, 3)] / p2[(0, 0)]).abs();
        if !(baseline.is_finite() && baseline > 0.0) {
            return Err(format!(
                "baseline -P2[0][3]/P2[0][0] = {baseline} must be > 0 (is the pair horizontal?)"
            ));
        }
        Ok(Self {
            focal_px: focal,
            cx_px: p1[(0, 2)],
            cy_px: p1[(1, 2)],
            baseline_m: baseline,
        })
    }

    /// Checks that focal length and baseline are positive and finite.
    pub fn validate(&self) -> Result<(), crate::VisionError> {
        if !(self.focal_px.is_finite() && self.focal_px > 0.0) {
            return Err(crate::VisionError::Parameter {
                name: "geometry.focal_px",
                value: self.focal_px,
                allowed: "> 0",
            });
        }
        if !(self.baseline_m.is_finite() && self.baseline_m > 0.0) {
            return Err(crate::VisionError::Parameter {
                name: "geometry.baseline_m",
                value: self.baseline_m,
                allowed: "> 0",
            });
        }
        Ok(())
    }

    /// The 3D point (left camera frame, metres) seen at left pixel `(x, y)` with disparity `d`
    /// (pixels, > 0), and its standard deviation per axis for a disparity error `sigma_d_px`:
    /// `sigma_Z = Z^2 / (f B) sigma_d`, `sigma_X = |X| / d sigma_d`, `sigma_Y = |Y| / d sigma_d`.
    pub fn back_project(
        &self,
        x_px: f64,
        y_px: f64,
        disparity_px: f64,
        sigma_d_px: f64,
    ) -> Option<(Vector3<f64>, Vector3<f64>)> {
        if disparity_px.is_nan() || disparity_px <= 0.0 {
            return None;
        }
        let z = self.focal_px * self.baseline_m / disparity_px;
        let x = (x_px - self.cx_px) * z / self.focal_px;
        let y = (y_px - self.cy_px) * z / self.focal_px;
        let sigma_z = z * z / (self.focal_px * self.baseline_m) * sigma_d_px;
        let sigma_x = x.abs() / disparity_px * sigma_d_px;
        let sigma_y = y.abs() / disparity_px * sigma_d_px;
        Some((
            Vector3::new(x, y, z),
            Vector3::new(sigma_x, sigma_y, sigma_z),
        ))
    }
}

/// A matched segment in 3D (left camera frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment3d {
    /// Index of the match it comes from.
    pub match_index: u32,
    /// Endpoint at the left segment's `start`, metres.
    pub start_m: Vector3<f64>,
    /// Endpoint at the left segment's `end`, metres.
    pub end_m: Vector3<f64>,
    /// Standard deviation of `start_m` per axis, metres.
    pub start_sigma_m: Vector3<f64>,
    /// Standard deviation of `end_m` per axis, metres.
    pub end_sigma_m: Vector3<f64>,
}

/// Back-projects every match that is not nearly horizontal and has positive disparity at both
/// endpoints, appending to `out` (cleared first).
pub fn back_project_matches(
    geometry: &RectifiedGeometry,
    left: &[Segment],
    matches: &[SegmentMatch],
    sigma_d_px: f64,
    out: &mut Vec<Segment3d>,
) {
    out.clear();
    for (k, m) in matches.iter().enumerate() {
        if m.nearly_horizontal {
            continue;
        }
        let s = &left[m.left as usize];
        let a = geometry.back_project(
            s.start[0] as f64,
            s.start[1] as f64,
            m.disparity_px[0] as f64,
            sigma_d_px,
        );
        let b = geometry.back_project(
            s.end[0] as f64,
            s.end[1] as f64,
            m.disparity_px[1] as f64,
            sigma_d_px,
        );
        if let (Some((pa, sa)), Some((pb, sb))) = (a, b) {
            out.push(Segment3d {
                match_index: k as u32,
                start_m: pa,
                end_m: pb,
                start_sigma_m: sa,
                end_sigma_m: sb,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn geometry() -> RectifiedGeometry {
        RectifiedGeometry {
            focal_px: 500.0,
            cx_px: 320.0,
            cy_px: 240.0,
            baseline_m: 0.1,
        }
    }

    #[test]
    fn a_known_point_round_trips() {
        let g = geometry();
        // Point (0.2, -0.1, 2.0): x = 320 + 500*0.1 = 370, y = 240 - 25 = 215, d = 25.
        let (p, s) = g.back_project(370.0, 215.0, 25.0, 0.5).unwrap();
        assert!((p - Vector3::new(0.2, -0.1, 2.0)).norm() < 1e-12);
        assert!((s.z - 4.0 / 50.0 * 0.5).abs() < 1e-12);
        // Numerical derivative check of sigma_z.
        let (p2, _) = g.back_project(370.0, 215.0, 25.5, 0.5).unwrap();
        assert!(((p.z - p2.z).abs() - s.z).abs() < 0.05 * s.z);
        assert!(g.back_project(370.0, 215.0, 0.0, 0.5).is_none());
    }

    #[test]
    fn geometry_from_opencv_projection_matrices() {
        let p1 = Matrix3x4::new(
            500.0, 0.0, 310.0, 0.0, 0.0, 500.0, 230.0, 0.0, 0.0, 0.0, 1.0, 0.0,
        );
        let p2 = Matrix3x4::new(
            500.0, 0.0, 310.0, -1680.0, 0.0, 500.0, 230.0, 0.0, 0.0, 0.0, 1.0, 0.0,
        );
        let g = RectifiedGeometry::from_projections(&p1, &p2).unwrap();
        assert_eq!(g.focal_px, 500.0);
        assert!((g.baseline_m - 3.36).abs() < 1e-12);
        assert_eq!((g.cx_px, g.cy_px), (310.0, 230.0));
    }
}
