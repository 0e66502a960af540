//! Rotation parametrisation (Rodrigues vectors) and planar homographies.

use nalgebra::{DMatrix, Matrix3, Vector3};

/// Rotation matrix of the rotation vector `omega` (axis times angle in radians).
pub fn rodrigues_to_matrix(omega: &Vector3<f64>) -> Matrix3<f64> {
    let theta = omega.norm();
    if theta < 1e-12 {
        // First-order expansion keeps the map smooth around zero.
        return Matrix3::identity() + skew(omega);
    }
    let k = omega / theta;
    let kx = skew(&k);
    Matrix3::identity() + kx * theta.sin() + kx * kx * (1.0 - theta.cos())
}

/// Rotation vector (axis times angle, angle in [0, pi]) of the rotation matrix `r`.
pub fn matrix_to_rodrigues(r: &Matrix3<f64>) -> Vector3<f64> {
    let r = nearest_rotation(r);
    let cos_theta = ((r.trace() - 1.0) * 0.5).clamp(-1.0, 1.0);
    let theta = cos_theta.acos();
    let v = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    );
    if theta < 1e-10 {
        return v * 0.5;
    }
    if std::f64::consts::PI - theta > 1e-6 {
        return v * (theta / (2.0 * theta.sin()));
    }
    // Near pi: the axis is the dominant column of (R + I) / 2.
    let b = (r + Matrix3::identity()) * 0.5;
    let mut best = 0;
    for i in 1..3 {
        if b[(i, i)] > b[(best, best)] {
            best = i;
        }
    }
    let mut axis: Vector3<f64> = b.column(best).into_owned();
    axis /= axis.norm().max(1e-300);
    // Fix the sign with the (small) antisymmetric part when available.
    if axis.dot(&v) < 0.0 {
        axis = -axis;
    }
    axis * theta
}

/// The skew-symmetric cross-product matrix of `v`.
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// The rotation matrix nearest (Frobenius norm) to `m`.
pub fn nearest_rotation(m: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = m.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Matrix3::identity();
    };
    let mut r = u * v_t;
    if r.determinant() < 0.0 {
        let mut u = u;
        u.column_mut(2).neg_mut();
        r = u * v_t;
    }
    r
}

/// Homography `H` with `image ~ H * [x, y, 1]` from planar points (normalised DLT, then none of
/// the points at infinity). `None` when the points are degenerate (fewer than 4, collinear).
pub fn fit_homography(plane: &[[f64; 2]], image: &[[f64; 2]]) -> Option<Matrix3<f64>> {
    let n = plane.len();
    if n < 4 || image.len() != n {
        return None;
    }
    let (t_plane, plane_n) = normalise(plane)?;
    let (t_image, image_n) = normalise(image)?;
    let mut a = DMatrix::<f64>::zeros(2 * n, 9);
    for i in 0..n {
        let [x, y] = plane_n[i];
        let [u, v] = image_n[i];
        let r0 = [-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u];
        let r1 = [0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v];
        for c in 0..9 {
            a[(2 * i, c)] = r0[c];
            a[(2 * i + 1, c)] = r1[c];
        }
    }
    let ata = a.transpose() * &a;
    let eig = ata.symmetric_eigen();
    let mut min_index = 0;
    for i in 1..9 {
        if eig.eigenvalues[i] < eig.eigenvalues[min_index] {
            min_index = i;
        }
    }
    let h = eig.eigenvectors.column(min_index);
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let h = t_image.try_inverse()? * hn * t_plane;
    let scale = h[(2, 2)];
    if !scale.is_finite() || scale.abs() < 1e-300 {
        return None;
    }
    let h = h / scale;
    h.iter().all(|v| v.is_finite()).then_some(h)
}

/// Similarity that moves the centroid to the origin and the mean distance to sqrt(2).
fn normalise(points: &[[f64; 2]]) -> Option<(Matrix3<f64>, Vec<[f64; 2]>)> {
    let n = points.len() as f64;
    let cx = points.iter().map(|p| p[0]).sum::<f64>() / n;
    let cy = points.iter().map(|p| p[1]).sum::<f64>() / n;
    let mean_dist = points
        .iter()
        .map(|p| ((p[0] - cx).powi(2) + (p[1] - cy).powi(2)).sqrt())
        .sum::<f64>()
        / n;
    if mean_dist <= 1e-12 || !mean_dist.is_finite() {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / mean_dist;
    let t = Matrix3::new(s, 0.0, -s * cx, 0.0, s, -s * cy, 0.0, 0.0, 1.0);
    let out = points
        .iter()
        .map(|p| [s * (p[0] - cx), s * (p[1] - cy)])
        .collect();
    Some((t, out))
}

/// Apply the homography `h` to the point `p`.
pub fn apply_homography(h: &Matrix3<f64>, p: [f64; 2]) -> [f64; 2] {
    let v = h * Vector3::new(p[0], p[1], 1.0);
    [v.x / v.z, v.y / v.z]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rodrigues_round_trip() {
        for omega in [
            Vector3::new(0.1, -0.2, 0.3),
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1e-9, 0.0, 0.0),
            Vector3::new(0.0, 3.0, 0.1),
            Vector3::new(std::f64::consts::PI - 1e-8, 0.0, 0.0),
        ] {
            let r = rodrigues_to_matrix(&omega);
            assert!((r.transpose() * r - Matrix3::identity()).norm() < 1e-12);
            let back = matrix_to_rodrigues(&r);
            assert!(
                (rodrigues_to_matrix(&back) - r).norm() < 1e-7,
                "{omega:?} -> {back:?}"
            );
        }
    }

    #[test]
    fn homography_recovers_projective_map() {
        let h = Matrix3::new(1.2, 0.1, 30.0, -0.05, 0.9, 50.0, 1e-4, 2e-4, 1.0);
        let plane: Vec<[f64; 2]> = (0..20)
            .map(|i| [(i % 5) as f64 * 10.0, (i / 5) as f64 * 10.0])
            .collect();
        let image: Vec<[f64; 2]> = plane.iter().map(|p| apply_homography(&h, *p)).collect();
        let fit = fit_homography(&plane, &image).expect("fit");
        assert!((fit - h).norm() < 1e-8);
        assert!(fit_homography(&plane[..3], &image[..3]).is_none());
    }
}
