//! The straightforward Canny detector the optimised one in the parent module must reproduce
//! exactly: whole-image buffers for every intermediate result, branchy non-maximum suppression
//! and the sub-pixel offsets of every maximum computed eagerly. Tests only.
#![allow(dead_code)]

use super::{gaussian_kernel, grow, CannyParams, EDGE, WEAK};
use crate::error::VisionError;
use crate::gray::GrayView;

/// Reusable buffers of the Canny detector. Create once, call [`ReferenceCanny::detect`] per
/// frame: no allocation happens once the buffers have grown to the frame size.
#[derive(Debug, Default, Clone)]
pub struct ReferenceCanny {
    width: usize,
    height: usize,
    kernel: Vec<u16>,
    kernel_sigma: f32,
    padded_row: Vec<u8>,
    accumulator: Vec<u16>,
    horizontal: Vec<u8>,
    smoothed: Vec<u8>,
    gx: Vec<i16>,
    gy: Vec<i16>,
    magnitude: Vec<i16>,
    edges: Vec<u8>,
    subpixel: Vec<u8>,
    stack: Vec<u32>,
}

impl ReferenceCanny {
    /// An empty workspace; buffers grow on first use.
    pub fn new() -> Self {
        Self::default()
    }

    /// Width of the last processed image, pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height of the last processed image, pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Edge map of the last image, row-major: [`EDGE`] marks an edge pixel.
    pub fn edges(&self) -> &[u8] {
        &self.edges[..self.width * self.height]
    }

    /// Horizontal Sobel gradient of the smoothed last image.
    pub fn gx(&self) -> &[i16] {
        &self.gx[..self.width * self.height]
    }

    /// Vertical Sobel gradient of the smoothed last image.
    pub fn gy(&self) -> &[i16] {
        &self.gy[..self.width * self.height]
    }

    /// L1 gradient magnitude `|gx| + |gy|` of the last image.
    pub fn magnitude(&self) -> &[i16] {
        &self.magnitude[..self.width * self.height]
    }

    /// Sub-pixel localisation of the edge pixels of the last image: for pixel `i` (valid
    /// where [`Self::edges`] is [`EDGE`]), the step `(sx, sy)` of the quantised gradient
    /// direction and the offset along it (pixels, within +-0.5) of the vertex of the parabola
    /// through the magnitudes before, at and after the pixel.
    pub fn subpixel_offset(&self, i: usize) -> ((i32, i32), f32) {
        decode_subpixel(self.subpixel[i])
    }

    /// The smoothed last image.
    pub fn smoothed(&self) -> &[u8] {
        &self.smoothed[..self.width * self.height]
    }

    fn prepare(&mut self, params: &CannyParams, width: usize, height: usize) {
        let n = width * height;
        let radius = params.kernel_radius();
        if self.kernel.is_empty() || self.kernel_sigma != params.sigma_px {
            self.kernel = gaussian_kernel(params.sigma_px, radius);
            self.kernel_sigma = params.sigma_px;
        }
        self.width = width;
        self.height = height;
        grow(&mut self.padded_row, width + 2 * radius);
        grow(&mut self.accumulator, width);
        grow(&mut self.horizontal, n);
        grow(&mut self.smoothed, n);
        grow(&mut self.gx, n);
        grow(&mut self.gy, n);
        grow(&mut self.magnitude, n);
        grow(&mut self.edges, n);
        grow(&mut self.subpixel, n);
        if self.stack.capacity() < n / 4 {
            self.stack.reserve(n / 4);
        }
    }

    /// Runs the detector on `image`; results are read through [`Self::edges`], [`Self::gx`],
    /// [`Self::gy`] and [`Self::smoothed`].
    pub fn detect(
        &mut self,
        image: &GrayView<'_>,
        params: &CannyParams,
    ) -> Result<(), VisionError> {
        params.validate()?;
        self.prepare(params, image.width(), image.height());
        self.smooth(image);
        self.sobel();
        self.suppress_non_maxima(params);
        self.hysteresis();
        Ok(())
    }

    /// Smoothing only (Gaussian, replicated borders) into [`Self::smoothed`].
    fn smooth(&mut self, image: &GrayView<'_>) {
        let (w, h) = (self.width, self.height);
        let radius = self.kernel.len() / 2;
        let taps = self.kernel.len();
        // Horizontal pass into `horizontal`.
        for y in 0..h {
            let src = image.row(y);
            let pad = &mut self.padded_row[..w + 2 * radius];
            pad[..radius].fill(src[0]);
            pad[radius..radius + w].copy_from_slice(src);
            pad[radius + w..].fill(src[w - 1]);
            let acc = &mut self.accumulator[..w];
            acc.fill(128);
            for (t, &k) in self.kernel.iter().enumerate().take(taps) {
                for (a, &p) in acc.iter_mut().zip(&pad[t..t + w]) {
                    *a += k * p as u16;
                }
            }
            let out = &mut self.horizontal[y * w..(y + 1) * w];
            for (o, &a) in out.iter_mut().zip(acc.iter()) {
                *o = (a >> 8) as u8;
            }
        }
        // Vertical pass into `smoothed`.
        for y in 0..h {
            let acc = &mut self.accumulator[..w];
            acc.fill(128);
            for (t, &k) in self.kernel.iter().enumerate() {
                let sy = (y + t).saturating_sub(radius).min(h - 1);
                let src = &self.horizontal[sy * w..(sy + 1) * w];
                for (a, &p) in acc.iter_mut().zip(src) {
                    *a += k * p as u16;
                }
            }
            let out = &mut self.smoothed[y * w..(y + 1) * w];
            for (o, &a) in out.iter_mut().zip(acc.iter()) {
                *o = (a >> 8) as u8;
            }
        }
    }

    /// 3x3 Sobel gradients and L1 magnitude; the first and last columns get zero gradient.
    fn sobel(&mut self) {
        let (w, h) = (self.width, self.height);
        if w < 3 {
            self.gx[..w * h].fill(0);
            self.gy[..w * h].fill(0);
            self.magnitude[..w * h].fill(0);
            return;
        }
        let n = w - 2;
        for y in 0..h {
            let ya = y.saturating_sub(1);
            let yc = (y + 1).min(h - 1);
            let a = &self.smoothed[ya * w..ya * w + w];
            let b = &self.smoothed[y * w..y * w + w];
            let c = &self.smoothed[yc * w..yc * w + w];
            let (a0, a1, a2) = (&a[..n], &a[1..n + 1], &a[2..n + 2]);
            let (b0, b2) = (&b[..n], &b[2..n + 2]);
            let (c0, c1, c2) = (&c[..n], &c[1..n + 1], &c[2..n + 2]);
            let row = y * w;
            let gx = &mut self.gx[row + 1..row + 1 + n];
            let gy = &mut self.gy[row + 1..row + 1 + n];
            let mag = &mut self.magnitude[row + 1..row + 1 + n];
            for i in 0..n {
                let dx = (a2[i] as i16 - a0[i] as i16)
                    + 2 * (b2[i] as i16 - b0[i] as i16)
                    + (c2[i] as i16 - c0[i] as i16);
                let dy = (c0[i] as i16 + 2 * c1[i] as i16 + c2[i] as i16)
                    - (a0[i] as i16 + 2 * a1[i] as i16 + a2[i] as i16);
                gx[i] = dx;
                gy[i] = dy;
                mag[i] = dx.abs() + dy.abs();
            }
            for x in [0, w - 1] {
                self.gx[row + x] = 0;
                self.gy[row + x] = 0;
                self.magnitude[row + x] = 0;
            }
        }
    }

    /// Non-maximum suppression along the quantised gradient direction; strong maxima are
    /// marked [`EDGE`] and pushed on the hysteresis stack, weak ones marked `WEAK`.
    fn suppress_non_maxima(&mut self, params: &CannyParams) {
        let (w, h) = (self.width, self.height);
        let low = params.low_threshold as i16;
        let high = params.high_threshold as i16;
        // tan(22.5 deg) in Q15.
        const TG22: i32 = 13573;
        self.stack.clear();
        self.edges[..w].fill(0);
        self.edges[(h - 1) * w..h * w].fill(0);
        if w < 3 || h < 3 {
            self.edges[..w * h].fill(0);
            return;
        }
        for y in 1..h - 1 {
            let row = y * w;
            let out = &mut self.edges[row..row + w];
            out.fill(0);
            let m_prev = &self.magnitude[row - w..row];
            let m_cur = &self.magnitude[row..row + w];
            let m_next = &self.magnitude[row + w..row + 2 * w];
            let gxr = &self.gx[row..row + w];
            let gyr = &self.gy[row..row + w];
            let subpixel = &mut self.subpixel[row..row + w];
            // Skip runs of 16 pixels below the low threshold with a vectorised maximum.
            let mut x = 1;
            while x < w - 1 {
                let end = (x + 16).min(w - 1);
                let run_max = m_cur[x..end].iter().fold(i16::MIN, |a, &b| a.max(b));
                if run_max <= low {
                    x = end;
                    continue;
                }
                for x in x..end {
                    let m = m_cur[x];
                    if m <= low {
                        continue;
                    }
                    let dx = gxr[x] as i32;
                    let dy = gyr[x] as i32;
                    let ax = dx.abs();
                    let ay = dy.abs() << 15;
                    let tg22x = ax * TG22;
                    // Neighbours before/after along the quantised gradient direction.
                    let (code, before, after, is_max) = if ay < tg22x {
                        let (b, a) = (m_cur[x - 1], m_cur[x + 1]);
                        (0u8, b, a, m > b && m >= a)
                    } else {
                        let tg67x = tg22x + (ax << 16);
                        if ay > tg67x {
                            let (b, a) = (m_prev[x], m_next[x]);
                            (1, b, a, m > b && m >= a)
                        } else if (dx ^ dy) < 0 {
                            let (b, a) = (m_next[x - 1], m_prev[x + 1]);
                            (2, b, a, m > a && m > b)
                        } else {
                            let (b, a) = (m_prev[x - 1], m_next[x + 1]);
                            (3, b, a, m > b && m > a)
                        }
                    };
                    if is_max {
                        subpixel[x] = encode_subpixel(code, before as i32, m as i32, after as i32);
                        if m > high {
                            out[x] = EDGE;
                            self.stack.push((row + x) as u32);
                        } else {
                            out[x] = WEAK;
                        }
                    }
                }
                x = end;
            }
        }
    }

    /// Grows strong edges through 8-connected weak pixels.
    fn hysteresis(&mut self) {
        let w = self.width;
        let edges = &mut self.edges;
        while let Some(i) = self.stack.pop() {
            let i = i as usize;
            // Edge pixels never touch the border (NMS leaves it at 0), so the neighbours exist.
            for j in [
                i - w - 1,
                i - w,
                i - w + 1,
                i - 1,
                i + 1,
                i + w - 1,
                i + w,
                i + w + 1,
            ] {
                if edges[j] == WEAK {
                    edges[j] = EDGE;
                    self.stack.push(j as u32);
                }
            }
        }
    }
}

fn decode_subpixel(byte: u8) -> ((i32, i32), f32) {
    let step = match byte & 3 {
        0 => (1, 0),
        1 => (0, 1),
        2 => (1, -1),
        _ => (1, 1),
    };
    (step, ((byte as i8) >> 2) as f32 / 62.0)
}

/// Packs the direction code (2 bits) and the parabola-vertex offset (6 bits, 1/62 px) with
/// integer divisions.
pub(super) fn encode_subpixel(code: u8, before: i32, at: i32, after: i32) -> u8 {
    let den = 2 * at - before - after;
    let q = if den > 0 {
        let n = 31 * (after - before);
        let q = if n >= 0 {
            (n + den / 2) / den
        } else {
            -((-n + den / 2) / den)
        };
        q.clamp(-31, 31) as i8
    } else {
        0
    };
    code | ((q as u8) << 2)
}
