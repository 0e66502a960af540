//! Sub-pixel corner refinement by gradient orthogonality (the iteration of OpenCV's
//! `cornerSubPix`): at the true corner `q`, every image gradient `g(p)` in the window is orthogonal
//! to `p - q`, so `q` solves `sum w g g^T q = sum w g g^T p`.

use super::corner_response::FloatImage;

/// Settings of the refinement.
#[derive(Debug, Clone, Copy)]
pub struct SubPixSettings {
    /// Half-size of the square window, pixels (the window is `2 * half + 1` wide).
    pub half_window: usize,
    /// Maximum iterations.
    pub max_iterations: usize,
    /// Stop when the update moves the corner less than this, pixels.
    pub epsilon_px: f64,
}

impl Default for SubPixSettings {
    fn default() -> Self {
        SubPixSettings {
            half_window: 5,
            max_iterations: 40,
            epsilon_px: 1e-3,
        }
    }
}

/// Refine `corner` (x, y pixels) in `img`. Returns the start point unchanged when the system is
/// degenerate (flat window) or the estimate leaves the window.
pub fn refine_corner(img: &FloatImage, corner: [f64; 2], settings: &SubPixSettings) -> [f64; 2] {
    let half = settings.half_window as isize;
    let hw = settings.half_window.max(1) as f64;
    let mut q = corner;
    for _ in 0..settings.max_iterations {
        let (mut a, mut b, mut c, mut bx, mut by) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for dy in -half..=half {
            for dx in -half..=half {
                let px = q[0] + dx as f64;
                let py = q[1] + dy as f64;
                let gx = 0.5 * (img.sample(px + 1.0, py) - img.sample(px - 1.0, py));
                let gy = 0.5 * (img.sample(px, py + 1.0) - img.sample(px, py - 1.0));
                let wgt = (-((dx * dx + dy * dy) as f64) / (hw * hw)).exp();
                let gxx = wgt * gx * gx;
                let gxy = wgt * gx * gy;
                let gyy = wgt * gy * gy;
                a += gxx;
                b += gxy;
                c += gyy;
                bx += gxx * px + gxy * py;
                by += gxy * px + gyy * py;
            }
        }
        let det = a * c - b * b;
        if det.abs() <= 1e-9 * (a * c).abs().max(1e-300) {
            return corner;
        }
        let nx = (c * bx - b * by) / det;
        let ny = (a * by - b * bx) / det;
        let step = ((nx - q[0]).powi(2) + (ny - q[1]).powi(2)).sqrt();
        q = [nx, ny];
        if step < settings.epsilon_px {
            break;
        }
    }
    if (q[0] - corner[0]).abs() > hw
        || (q[1] - corner[1]).abs() > hw
        || !q[0].is_finite()
        || !q[1].is_finite()
    {
        return corner;
    }
    q
}
