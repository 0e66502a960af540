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

/// Refine `corner` (x, y pixels) in `img`: the integer pixels of a `2 * half + 1` square window,
/// gradients by central differences, Gaussian weights of standard deviation `half / 2` centred on
/// the current estimate, iterated until the update is below `epsilon_px`. Returns the start point unchanged when the system is
/// degenerate (flat window) or the estimate leaves the window.
pub fn refine_corner(img: &FloatImage, corner: [f64; 2], settings: &SubPixSettings) -> [f64; 2] {
    let half = settings.half_window.max(1) as isize;
    let hw = half as f64;
    let (w, h) = (img.width as isize, img.height as isize);
    let mut q = corner;
    for _ in 0..settings.max_iterations {
        let (qx, qy) = (q[0].round() as isize, q[1].round() as isize);
        let (mut a, mut b, mut c, mut bx, mut by) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for y in (qy - half).max(1)..=(qy + half).min(h - 2) {
            let dy = y as f64 - q[1];
            for x in (qx - half).max(1)..=(qx + half).min(w - 2) {
                let dx = x as f64 - q[0];
                let (xu, yu) = (x as usize, y as usize);
                let gx = 0.5 * f64::from(img.at(xu + 1, yu) - img.at(xu - 1, yu));
                let gy = 0.5 * f64::from(img.at(xu, yu + 1) - img.at(xu, yu - 1));
                let wgt = (-2.0 * (dx * dx + dy * dy) / (hw * hw)).exp();
                let gxx = wgt * gx * gx;
                let gxy = wgt * gx * gy;
                let gyy = wgt * gy * gy;
                a += gxx;
                b += gxy;
                c += gyy;
                bx += gxx * dx + gxy * dy;
                by += gxy * dx + gyy * dy;
            }
        }
        let det = a * c - b * b;
        if det.abs() <= 1e-9 * (a * c).abs().max(1e-300) {
            return corner;
        }
        // Offsets are relative to the current estimate.
        let sx = (c * bx - b * by) / det;
        let sy = (a * by - b * bx) / det;
        q = [q[0] + sx, q[1] + sy];
        if (sx * sx + sy * sy).sqrt() < settings.epsilon_px {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Anti-aliased X-junction at (cx, cy) rotated by `angle`, rendered by 8x8 supersampling.
    fn render_junction(cx: f64, cy: f64, angle: f64) -> FloatImage {
        let (w, h) = (41usize, 41usize);
        let (s, c) = angle.sin_cos();
        let mut data = vec![0.0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut acc = 0.0;
                for sy in 0..8 {
                    for sx in 0..8 {
                        let px = x as f64 + (sx as f64 + 0.5) / 8.0 - 0.5 - cx;
                        let py = y as f64 + (sy as f64 + 0.5) / 8.0 - 0.5 - cy;
                        let u = c * px + s * py;
                        let v = -s * px + c * py;
                        acc += if (u > 0.0) == (v > 0.0) { 40.0 } else { 210.0 };
                    }
                }
                data[y * w + x] = (acc / 64.0) as f32;
            }
        }
        FloatImage {
            width: w,
            height: h,
            data,
        }
    }

    #[test]
    fn converges_to_junction_from_pixel_start() {
        for &(cx, cy, angle) in &[(20.3, 19.7, 0.2), (20.77, 20.12, -0.5), (19.5, 20.5, 0.0)] {
            let img = render_junction(cx, cy, angle).smoothed();
            let start = [cx.round() + 1.0, cy.round() - 1.0];
            let q = refine_corner(&img, start, &SubPixSettings::default());
            assert!(
                (q[0] - cx).abs() < 0.05 && (q[1] - cy).abs() < 0.05,
                "{q:?} vs ({cx}, {cy})"
            );
        }
    }
}
