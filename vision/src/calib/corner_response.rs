//! X-junction (chessboard corner) candidates: the ChESS response of Bennett & Lasenby
//! ("ChESS – Quick and robust detection of chess-board features", CVIU 2014) on a lightly smoothed
//! image, then non-maximum suppression.

/// A grey image as floating point, row-major.
#[derive(Debug, Clone)]
pub struct FloatImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Pixel values, row-major.
    pub data: Vec<f32>,
}

impl FloatImage {
    /// Convert 8-bit grey pixels.
    pub fn from_gray(width: usize, height: usize, pixels: &[u8]) -> Self {
        FloatImage {
            width,
            height,
            data: pixels.iter().map(|&p| f32::from(p)).collect(),
        }
    }

    /// Pixel at integer coordinates (must be inside).
    #[inline]
    pub fn at(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }

    /// Bilinear sample at (x, y), clamped to the border.
    pub fn sample(&self, x: f64, y: f64) -> f64 {
        let max_x = (self.width - 1) as f64;
        let max_y = (self.height - 1) as f64;
        let x = x.clamp(0.0, max_x);
        let y = y.clamp(0.0, max_y);
        let x0 = (x.floor() as usize).min(self.width.saturating_sub(2));
        let y0 = (y.floor() as usize).min(self.height.saturating_sub(2));
        let fx = x - x0 as f64;
        let fy = y - y0 as f64;
        let x1 = (x0 + 1).min(self.width - 1);
        let y1 = (y0 + 1).min(self.height - 1);
        let top = f64::from(self.at(x0, y0)) * (1.0 - fx) + f64::from(self.at(x1, y0)) * fx;
        let bottom = f64::from(self.at(x0, y1)) * (1.0 - fx) + f64::from(self.at(x1, y1)) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// Separable [1 2 1]/4 smoothing (borders replicated).
    pub fn smoothed(&self) -> Self {
        let (w, h) = (self.width, self.height);
        let mut tmp = vec![0.0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let l = self.at(x.saturating_sub(1), y);
                let r = self.at((x + 1).min(w - 1), y);
                tmp[y * w + x] = 0.25 * (l + r) + 0.5 * self.at(x, y);
            }
        }
        let mut out = vec![0.0f32; w * h];
        for y in 0..h {
            let up = y.saturating_sub(1);
            let down = (y + 1).min(h - 1);
            for x in 0..w {
                out[y * w + x] =
                    0.25 * (tmp[up * w + x] + tmp[down * w + x]) + 0.5 * tmp[y * w + x];
            }
        }
        FloatImage {
            width: w,
            height: h,
            data: out,
        }
    }
}

/// A corner candidate: pixel position (refined to the response centroid) and response strength.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Column, pixels.
    pub x: f64,
    /// Row, pixels.
    pub y: f64,
    /// ChESS response (larger: more X-junction-like).
    pub response: f32,
}

/// The 16 ring offsets of radius `radius` pixels, in angular order.
fn ring(radius: f64) -> [(isize, isize); 16] {
    let mut out = [(0isize, 0isize); 16];
    for (k, o) in out.iter_mut().enumerate() {
        let a = k as f64 * std::f64::consts::PI / 8.0;
        *o = (
            (radius * a.cos()).round() as isize,
            (radius * a.sin()).round() as isize,
        );
    }
    out
}

/// Below this "sum response" (grey levels) a pixel cannot be a usable corner: the remaining terms
/// are skipped and its response stays 0.
const MIN_SUM_RESPONSE: f32 = 40.0;

/// ChESS response map at ring radius `radius` pixels (0 within `radius` of the border).
pub fn chess_response(img: &FloatImage, radius: usize) -> Vec<f32> {
    let (w, h) = (img.width, img.height);
    let offsets = ring(radius as f64);
    let mut out = vec![0.0f32; w * h];
    if w <= 2 * radius + 1 || h <= 2 * radius + 1 {
        return out;
    }
    let flat: [isize; 16] = std::array::from_fn(|k| offsets[k].1 * w as isize + offsets[k].0);
    let data = &img.data;
    let mut s = [0.0f32; 16];
    for y in radius..h - radius {
        let row = y * w;
        for x in radius..w - radius {
            let centre = row + x;
            for (sk, off) in s.iter_mut().zip(flat) {
                *sk = data[(centre as isize + off) as usize];
            }
            let sum_resp = (s[0] + s[8] - s[4] - s[12]).abs()
                + (s[1] + s[9] - s[5] - s[13]).abs()
                + (s[2] + s[10] - s[6] - s[14]).abs()
                + (s[3] + s[11] - s[7] - s[15]).abs();
            if sum_resp < MIN_SUM_RESPONSE {
                // Flat or low-contrast neighbourhood: not a corner (response left at 0).
                continue;
            }
            let diff_resp = (s[0] - s[8]).abs()
                + (s[1] - s[9]).abs()
                + (s[2] - s[10]).abs()
                + (s[3] - s[11]).abs()
                + (s[4] - s[12]).abs()
                + (s[5] - s[13]).abs()
                + (s[6] - s[14]).abs()
                + (s[7] - s[15]).abs();
            let ring_mean = s.iter().sum::<f32>() * (1.0 / 16.0);
            let local_mean = (data[centre]
                + data[centre - 1]
                + data[centre + 1]
                + data[centre - w]
                + data[centre + w])
                * 0.2;
            out[centre] = sum_resp - diff_resp - 16.0 * (ring_mean - local_mean).abs();
        }
    }
    out
}

/// Local maxima of `response` (strictly greater than or equal to every value within
/// `nms_radius`) above `threshold`, strongest first.
pub fn local_maxima(
    response: &[f32],
    width: usize,
    height: usize,
    nms_radius: usize,
    threshold: f32,
) -> Vec<Candidate> {
    let mut out = Vec::new();
    let r = nms_radius as isize;
    for y in 1..height.saturating_sub(1) {
        for x in 1..width.saturating_sub(1) {
            let v = response[y * width + x];
            if v <= threshold {
                continue;
            }
            let mut is_max = true;
            'scan: for dy in -r..=r {
                for dx in -r..=r {
                    if dx == 0 && dy == 0 {
                        continue;
                    }
                    let (nx, ny) = (x as isize + dx, y as isize + dy);
                    if nx < 0 || ny < 0 || nx >= width as isize || ny >= height as isize {
                        continue;
                    }
                    let nv = response[ny as usize * width + nx as usize];
                    // Ties broken by raster order so that a plateau yields one maximum.
                    if nv > v || (nv == v && (dy < 0 || (dy == 0 && dx < 0))) {
                        is_max = false;
                        break 'scan;
                    }
                }
            }
            if !is_max {
                continue;
            }
            // Centroid of the positive response in the 3x3 neighbourhood.
            let (mut sx, mut sy, mut sw) = (0.0f64, 0.0f64, 0.0f64);
            for dy in -1isize..=1 {
                for dx in -1isize..=1 {
                    let nv = f64::from(
                        response[(y as isize + dy) as usize * width + (x as isize + dx) as usize],
                    )
                    .max(0.0);
                    sx += nv * dx as f64;
                    sy += nv * dy as f64;
                    sw += nv;
                }
            }
            let (cx, cy) = if sw > 0.0 {
                (sx / sw, sy / sw)
            } else {
                (0.0, 0.0)
            };
            out.push(Candidate {
                x: x as f64 + cx,
                y: y as f64 + cy,
                response: v,
            });
        }
    }
    out.sort_by(|a, b| b.response.total_cmp(&a.response));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn responds_at_x_junction_not_at_edge() {
        // Four quadrants around (20, 20): dark / bright alternating; an edge at x = 40.
        let (w, h) = (60usize, 40usize);
        let mut px = vec![0u8; w * h];
        for y in 0..h {
            for x in 0..w {
                let junction = (x < 20) == (y < 20);
                let v = if x >= 40 {
                    200
                } else if junction {
                    30
                } else {
                    220
                };
                px[y * w + x] = v;
            }
        }
        let img = FloatImage::from_gray(w, h, &px).smoothed();
        let resp = chess_response(&img, 5);
        let peaks = local_maxima(&resp, w, h, 3, 100.0);
        assert!(!peaks.is_empty());
        let best = peaks[0];
        assert!(
            (best.x - 19.5).abs() < 1.0 && (best.y - 19.5).abs() < 1.0,
            "{best:?}"
        );
        assert!(peaks
            .iter()
            .all(|p| (p.x - 40.0).abs() > 3.0 || p.response < best.response * 0.2));
    }
}
