//! Canny edge detection written for speed: integer separable Gaussian smoothing, Sobel
//! gradients, non-maximum suppression and hysteresis, all in buffers of a [`CannyWorkspace`]
//! that are allocated once per image size and reused frame after frame.
//!
//! The gradient magnitude is the L1 norm `|gx| + |gy|` of the 3x3 Sobel gradient of the smoothed
//! image (the convention of OpenCV's `Canny` with `L2gradient = false`); thresholds are in those
//! units (0..=2040 for 8-bit images).

use crate::error::VisionError;
use crate::gray::GrayView;

/// Value of an edge pixel in [`CannyWorkspace::edges`].
pub const EDGE: u8 = 2;
/// Value of a pixel that survived non-maximum suppression but was not connected to a strong edge.
const WEAK: u8 = 1;

/// Parameters of the Canny detector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CannyParams {
    /// Standard deviation of the Gaussian smoothing, pixels (0.5..=4). The kernel has
    /// `2 * ceil(2 sigma) + 1` taps.
    pub sigma_px: f32,
    /// Hysteresis low threshold on the L1 Sobel magnitude.
    pub low_threshold: u16,
    /// Hysteresis high threshold on the L1 Sobel magnitude (>= low).
    pub high_threshold: u16,
}

impl Default for CannyParams {
    /// `sigma 1.0 px` (5-tap kernel), thresholds 40 / 100: a good default for indoor scenes at
    /// VGA resolution.
    fn default() -> Self {
        Self {
            sigma_px: 1.0,
            low_threshold: 40,
            high_threshold: 100,
        }
    }
}

impl CannyParams {
    /// Checks the ranges documented on the fields.
    pub fn validate(&self) -> Result<(), VisionError> {
        if !(0.5..=4.0).contains(&self.sigma_px) {
            return Err(VisionError::Parameter {
                name: "canny.sigma_px",
                value: self.sigma_px as f64,
                allowed: "0.5..=4.0",
            });
        }
        if self.high_threshold < self.low_threshold || self.high_threshold > 2040 {
            return Err(VisionError::Parameter {
                name: "canny.high_threshold",
                value: self.high_threshold as f64,
                allowed: "low_threshold..=2040",
            });
        }
        Ok(())
    }

    /// Radius of the smoothing kernel, pixels.
    pub fn kernel_radius(&self) -> usize {
        ((2.0 * self.sigma_px).ceil() as usize).max(1)
    }
}

/// Integer Gaussian kernel with weights summing to 256.
fn gaussian_kernel(sigma_px: f32, radius: usize) -> Vec<u16> {
    let weights: Vec<f64> = (0..=2 * radius)
        .map(|i| {
            let d = i as f64 - radius as f64;
            (-d * d / (2.0 * (sigma_px as f64).powi(2))).exp()
        })
        .collect();
    let sum: f64 = weights.iter().sum();
    let mut kernel: Vec<u16> = weights
        .iter()
        .map(|w| (w / sum * 256.0).round() as u16)
        .collect();
    let total: i32 = kernel.iter().map(|&k| k as i32).sum();
    kernel[radius] = (kernel[radius] as i32 + 256 - total) as u16;
    kernel
}

/// tan(22.5 deg) in Q15: the bound between horizontal/vertical and diagonal gradient directions.
const TG22: i32 = 13573;

/// Reusable buffers of the Canny detector. Create once, call [`CannyWorkspace::detect`] per
/// frame: no allocation happens once the buffers have grown to the frame size.
///
/// One pass over the rows does everything but the hysteresis: row `y` is smoothed
/// horizontally into a ring of `2 r + 1` rows and vertically into [`Self::smoothed`], row
/// `y - 1` gets its Sobel gradient (kept in a two-row ring) and magnitude, and row `y - 2` its
/// non-maximum suppression, so the intermediate rows stay in the first-level cache. Every row
/// loop is branch-free integer arithmetic on slices of equal length, which the compiler turns
/// into SIMD code. After the hysteresis, the sub-pixel offsets of the edge pixels only are
/// computed (raster order); the gradient is computed on demand from the smoothed image
/// ([`Self::gradient`]).
#[derive(Debug, Default, Clone)]
pub struct CannyWorkspace {
    width: usize,
    height: usize,
    kernel: Vec<u16>,
    kernel_sigma: f32,
    padded_row: Vec<u8>,
    accumulator: Vec<u16>,
    /// Ring of `kernel.len()` horizontally smoothed rows.
    horizontal: Vec<u8>,
    smoothed: Vec<u8>,
    /// Ring of two rows of Sobel gradients.
    gx: Vec<i16>,
    gy: Vec<i16>,
    magnitude: Vec<i16>,
    edges: Vec<u8>,
    /// Sub-pixel code of each edge pixel (direction code and parabola-vertex offset).
    subpixel: Vec<u8>,
    stack: Vec<u32>,
}

impl CannyWorkspace {
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

    /// The 3x3 Sobel gradient `(gx, gy)` of the smoothed last image at pixel `(x, y)` (rows
    /// replicated at the top and bottom borders; zero in the first and last columns).
    /// `(x, y)` must lie inside the image.
    #[inline]
    pub fn gradient(&self, x: usize, y: usize) -> (i16, i16) {
        let (w, h) = (self.width, self.height);
        if x == 0 || x + 1 >= w {
            return (0, 0);
        }
        let s = &self.smoothed;
        let (ya, yc) = (y.saturating_sub(1) * w, (y + 1).min(h - 1) * w);
        let y = y * w;
        let p = |i: usize| s[i] as i16;
        let dx = (p(ya + x + 1) - p(ya + x - 1))
            + 2 * (p(y + x + 1) - p(y + x - 1))
            + (p(yc + x + 1) - p(yc + x - 1));
        let dy = (p(yc + x - 1) + 2 * p(yc + x) + p(yc + x + 1))
            - (p(ya + x - 1) + 2 * p(ya + x) + p(ya + x + 1));
        (dx, dy)
    }

    /// L1 gradient magnitude `|gx| + |gy|` of the last image, row-major.
    pub fn magnitude(&self) -> &[i16] {
        &self.magnitude[..self.width * self.height]
    }

    /// Sub-pixel localisation of the edge pixels of the last image: for pixel `i` (valid
    /// where [`Self::edges`] is [`EDGE`]), the step `(sx, sy)` of the quantised gradient
    /// direction and the offset along it (pixels, within +-0.5, in steps of 1/62) of the vertex
    /// of the parabola through the magnitudes before, at and after the pixel.
    pub fn subpixel_offset(&self, i: usize) -> ((i32, i32), f32) {
        decode_subpixel(self.subpixel[i])
    }

    /// [`Self::subpixel_offset`] of pixel `(x, y)`.
    #[inline]
    pub fn subpixel_offset_at(&self, x: usize, y: usize) -> ((i32, i32), f32) {
        self.subpixel_offset(y * self.width + x)
    }

    /// Sub-pixel code of every edge pixel, in raster order (the rows read stay in cache).
    fn locate_edges(&mut self) {
        let (w, h) = (self.width, self.height);
        if w < 3 || h < 3 {
            return;
        }
        for y in 1..h - 1 {
            let row = y * w;
            let m = &self.magnitude[row - w..row + 2 * w];
            let s = &self.smoothed[row - w..row + 2 * w];
            let codes = &mut self.subpixel[row..row + w];
            for_each_equal(&self.edges[row + 1..row + w - 1], EDGE, |x| {
                let c = x + 1;
                // 3x3 neighbourhoods: above at c - 1..c + 2, the row at w + c - 1.., below at
                // 2w + c - 1..
                let (a, b, d) = (c - 1, w + c - 1, 2 * w + c - 1);
                let p = |i: usize| s[i] as i16;
                let dx = (p(a + 2) - p(a)) + 2 * (p(b + 2) - p(b)) + (p(d + 2) - p(d));
                let dy = (p(d) + 2 * p(d + 1) + p(d + 2)) - (p(a) + 2 * p(a + 1) + p(a + 2));
                // Branch-free selection (the directions of successive edge pixels are
                // unpredictable): the direction code and its two neighbours.
                let (dx, dy) = (dx as i32, dy as i32);
                let ax = dx.abs();
                let ay = dy.abs() << 15;
                let tg22x = ax * TG22;
                let horizontal = ay < tg22x;
                let vertical = !horizontal & (ay > tg22x + (ax << 16));
                let anti_diagonal = (dx ^ dy) < 0;
                let (diag_code, diag_before, diag_after) = if anti_diagonal {
                    (2, m[d], m[a + 2])
                } else {
                    (3, m[a], m[d + 2])
                };
                let (axis_code, axis_before, axis_after) = if horizontal {
                    (0, m[b], m[b + 2])
                } else {
                    (1, m[a + 1], m[d + 1])
                };
                let axis = horizontal | vertical;
                let code = if axis { axis_code } else { diag_code };
                let before = if axis { axis_before } else { diag_before };
                let after = if axis { axis_after } else { diag_after };
                codes[c] = encode_subpixel(code, before as i32, m[b + 1] as i32, after as i32);
            });
        }
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
        grow(&mut self.horizontal, (2 * radius + 1) * width);
        grow(&mut self.smoothed, n);
        grow(&mut self.gx, 2 * width);
        grow(&mut self.gy, 2 * width);
        grow(&mut self.magnitude, n);
        grow(&mut self.edges, n);
        grow(&mut self.subpixel, n);
        if self.stack.capacity() < n / 4 {
            self.stack.reserve(n / 4);
        }
    }

    /// Runs the detector on `image`; results are read through [`Self::edges`],
    /// [`Self::smoothed`], [`Self::magnitude`], [`Self::gradient`] and
    /// [`Self::subpixel_offset`].
    pub fn detect(
        &mut self,
        image: &GrayView<'_>,
        params: &CannyParams,
    ) -> Result<(), VisionError> {
        params.validate()?;
        let (w, h) = (image.width(), image.height());
        self.prepare(params, w, h);
        self.stack.clear();
        let low = params.low_threshold as i16;
        let high = params.high_threshold as i16;
        let radius = self.kernel.len() / 2;
        let ring = 2 * radius + 1;
        // Horizontal smoothing of the rows needed before the first vertical pass.
        for sy in 0..radius.min(h) {
            self.smooth_row_horizontal(image.row(sy), sy % ring);
        }
        // Iteration y: smoothing of row y, gradient of row y - 1, suppression of row y - 2.
        for y in 0..=h {
            if y < h {
                if y + radius < h {
                    let sy = y + radius;
                    self.smooth_row_horizontal(image.row(sy), sy % ring);
                }
                self.smooth_row_vertical(y);
            }
            if y >= 1 {
                self.gradient_row(y - 1);
            }
            if y >= 2 {
                self.suppress_row(y - 2, low, high);
            }
        }
        self.edges[..w].fill(0);
        self.edges[(h - 1) * w..h * w].fill(0);
        self.hysteresis();
        self.locate_edges();
        Ok(())
    }

    /// Horizontal Gaussian pass (replicated borders) of `src` into ring slot `slot`.
    fn smooth_row_horizontal(&mut self, src: &[u8], slot: usize) {
        let w = self.width;
        let radius = self.kernel.len() / 2;
        let pad = &mut self.padded_row[..w + 2 * radius];
        pad[..radius].fill(src[0]);
        pad[radius..radius + w].copy_from_slice(src);
        pad[radius + w..].fill(src[w - 1]);
        let acc = &mut self.accumulator[..w];
        // The kernel is symmetric: taps t and 2r - t share one product (exact integers).
        let centre = self.kernel[radius];
        for (a, &p) in acc.iter_mut().zip(&pad[radius..radius + w]) {
            *a = 128 + centre * p as u16;
        }
        for (t, &k) in self.kernel.iter().enumerate().take(radius) {
            let (left, right) = (&pad[t..t + w], &pad[2 * radius - t..2 * radius - t + w]);
            for ((a, &l), &r) in acc.iter_mut().zip(left).zip(right) {
                *a += k * (l as u16 + r as u16);
            }
        }
        let out = &mut self.horizontal[slot * w..(slot + 1) * w];
        for (o, &a) in out.iter_mut().zip(acc.iter()) {
            *o = (a >> 8) as u8;
        }
    }

    /// Vertical Gaussian pass producing row `y` of [`Self::smoothed`] from the ring.
    fn smooth_row_vertical(&mut self, y: usize) {
        let (w, h) = (self.width, self.height);
        let radius = self.kernel.len() / 2;
        let ring = 2 * radius + 1;
        let slot = |t: usize| ((y + t).saturating_sub(radius).min(h - 1)) % ring;
        let rows = &self.horizontal;
        let row = |t: usize| &rows[slot(t) * w..(slot(t) + 1) * w];
        let acc = &mut self.accumulator[..w];
        let centre = self.kernel[radius];
        for (a, &p) in acc.iter_mut().zip(row(radius)) {
            *a = 128 + centre * p as u16;
        }
        for (t, &k) in self.kernel.iter().enumerate().take(radius) {
            for ((a, &u), &d) in acc.iter_mut().zip(row(t)).zip(row(2 * radius - t)) {
                *a += k * (u as u16 + d as u16);
            }
        }
        let out = &mut self.smoothed[y * w..(y + 1) * w];
        for (o, &a) in out.iter_mut().zip(acc.iter()) {
            *o = (a >> 8) as u8;
        }
    }

    /// 3x3 Sobel gradient of row `y` into the gradient ring and L1 magnitude into
    /// [`Self::magnitude`]; the first and last columns get zero.
    fn gradient_row(&mut self, y: usize) {
        let (w, h) = (self.width, self.height);
        let slot = (y % 2) * w;
        let gx = &mut self.gx[slot..slot + w];
        let gy = &mut self.gy[slot..slot + w];
        let mag = &mut self.magnitude[y * w..(y + 1) * w];
        if w < 3 {
            gx.fill(0);
            gy.fill(0);
            mag.fill(0);
            return;
        }
        let n = w - 2;
        let ya = y.saturating_sub(1);
        let yc = (y + 1).min(h - 1);
        let a = &self.smoothed[ya * w..ya * w + w];
        let b = &self.smoothed[y * w..y * w + w];
        let c = &self.smoothed[yc * w..yc * w + w];
        let (a0, a1, a2) = (&a[..n], &a[1..n + 1], &a[2..n + 2]);
        let (b0, b2) = (&b[..n], &b[2..n + 2]);
        let (c0, c1, c2) = (&c[..n], &c[1..n + 1], &c[2..n + 2]);
        let (gxn, gyn, magn) = (&mut gx[1..n + 1], &mut gy[1..n + 1], &mut mag[1..n + 1]);
        for i in 0..n {
            let dx = (a2[i] as i16 - a0[i] as i16)
                + 2 * (b2[i] as i16 - b0[i] as i16)
                + (c2[i] as i16 - c0[i] as i16);
            let dy = (c0[i] as i16 + 2 * c1[i] as i16 + c2[i] as i16)
                - (a0[i] as i16 + 2 * a1[i] as i16 + a2[i] as i16);
            gxn[i] = dx;
            gyn[i] = dy;
            magn[i] = dx.abs() + dy.abs();
        }
        for x in [0, w - 1] {
            gx[x] = 0;
            gy[x] = 0;
            mag[x] = 0;
        }
    }

    /// Non-maximum suppression of row `y` (1 <= y < h - 1) along the quantised gradient
    /// direction: maxima above `high` are marked [`EDGE`] and pushed on the hysteresis stack,
    /// maxima above `low` marked `WEAK`.
    fn suppress_row(&mut self, y: usize, low: i16, high: i16) {
        let (w, h) = (self.width, self.height);
        let row = y * w;
        let out = &mut self.edges[row..row + w];
        out.fill(0);
        if w < 3 || y == 0 || y + 1 >= h {
            return;
        }
        let n = w - 2;
        let slot = (y % 2) * w;
        let gx = &self.gx[slot + 1..slot + 1 + n];
        let gy = &self.gy[slot + 1..slot + 1 + n];
        let m = &self.magnitude;
        let (mp, mc, mn) = (&m[row - w..row], &m[row..row + w], &m[row + w..row + 2 * w]);
        let (mp0, mp1, mp2) = (&mp[..n], &mp[1..n + 1], &mp[2..n + 2]);
        let (mc0, mc1, mc2) = (&mc[..n], &mc[1..n + 1], &mc[2..n + 2]);
        let (mn0, mn1, mn2) = (&mn[..n], &mn[1..n + 1], &mn[2..n + 2]);
        let classes = &mut out[1..n + 1];
        for i in 0..n {
            // Every neighbour is loaded and the right pair selected without branches, so that
            // the loop vectorises.
            let (p0, p1, p2) = (mp0[i], mp1[i], mp2[i]);
            let (c0, mag, c2) = (mc0[i], mc1[i], mc2[i]);
            let (n0, n1, n2) = (mn0[i], mn1[i], mn2[i]);
            let (dx, dy) = (gx[i] as i32, gy[i] as i32);
            let ax = dx.abs();
            let ay = dy.abs() << 15;
            let tg22x = ax * TG22;
            let tg67x = tg22x + (ax << 16);
            let horizontal = ay < tg22x;
            let vertical = !horizontal & (ay > tg67x);
            let anti_diagonal = (dx ^ dy) < 0;
            // Neighbours before/after along the direction (codes 0, 1, 2, 3:
            // horizontal, vertical, anti-diagonal, diagonal).
            let (diag_before, diag_after) = if anti_diagonal { (n0, p2) } else { (p0, n2) };
            let (axis_before, axis_after) = if horizontal { (c0, c2) } else { (p1, n1) };
            let axis = horizontal | vertical;
            let before = if axis { axis_before } else { diag_before };
            let after = if axis { axis_after } else { diag_after };
            // Ties with the pixel after count as maxima along rows and columns only.
            let after_bound = after - i16::from(axis);
            let is_max = (mag > before) & (mag > after_bound) & (mag > low);
            classes[i] = u8::from(is_max) * (WEAK + u8::from(mag > high));
        }
        // Strong maxima seed the hysteresis.
        for_each_equal(classes, EDGE, |x| self.stack.push((row + 1 + x) as u32));
    }

    /// Grows strong edges through 8-connected weak pixels.
    fn hysteresis(&mut self) {
        let w = self.width;
        let edges = &mut self.edges;
        while let Some(i) = self.stack.pop() {
            let i = i as usize;
            // Edge pixels never touch the border (it stays 0), so the neighbours exist.
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

/// Calls `f(i)` for every `i` with `bytes[i] == value`, in increasing order. Eight bytes at a
/// time are compared at once as one 64-bit word (exact zero-byte test of `word ^ value`), and
/// the set bits of the resulting mask visited.
#[inline]
pub(crate) fn for_each_equal(bytes: &[u8], value: u8, mut f: impl FnMut(usize)) {
    const LOW7: u64 = 0x7f7f_7f7f_7f7f_7f7f;
    let pattern = u64::from_le_bytes([value; 8]);
    let mut chunks = bytes.chunks_exact(8);
    let mut base = 0;
    for chunk in &mut chunks {
        let word = u64::from_le_bytes(chunk.try_into().unwrap_or([0; 8])) ^ pattern;
        // High bit of each byte set iff the byte of `word` is non-zero (no carries between
        // bytes: each byte's low 7 bits plus 0x7f stays below 0x100).
        let nonzero = ((word & LOW7) + LOW7) | word;
        let mut equal = !nonzero & !LOW7;
        while equal != 0 {
            f(base + (equal.trailing_zeros() / 8) as usize);
            equal &= equal - 1;
        }
        base += 8;
    }
    for (k, &b) in chunks.remainder().iter().enumerate() {
        if b == value {
            f(base + k);
        }
    }
}

/// Packs the direction code (2 bits) and the parabola-vertex offset (6 bits, 1/62 px).
fn encode_subpixel(code: u8, before: i32, at: i32, after: i32) -> u8 {
    // offset = 0.5 (before - after) / (before - 2 at + after), within +-0.5 at a maximum;
    // q = round(62 offset), halves away from zero: floor((|n| + floor(den / 2)) / den) with
    // the sign of n; 0 when den <= 0. Branch-free.
    let den = 2 * at - before - after;
    let n = 31 * (after - before);
    let magnitude = q_quotient(n.abs() + den.max(1) / 2, den.max(1)).min(31);
    let signed = if n >= 0 { magnitude } else { -magnitude };
    let q = if den > 0 { signed } else { 0 };
    code | (((q as i8) as u8) << 2)
}

/// `floor(num / den)` for `0 <= num < 2^24`, `0 < den < 2^24`, through one single-precision
/// division, which is exact here: both operands are exact in `f32`; an integer quotient is
/// representable, so the correctly rounded division returns it; otherwise the quotient is at
/// least `1 / den` away from the integers while the rounding error is at most
/// `num / den * 2^-24 < 1 / den`, so truncation gives the floor.
#[inline]
fn q_quotient(num: i32, den: i32) -> i32 {
    debug_assert!((0..1 << 24).contains(&num) && (1..1 << 24).contains(&den));
    (num as f32 / den as f32) as i32
}

fn decode_subpixel(byte: u8) -> ((i32, i32), f32) {
    let step = match byte & 3 {
        0 => (1, 0),
        1 => (0, 1),
        2 => (1, -1),
        _ => (1, 1),
    };
    (step, SUBPIXEL_OFFSETS[(byte >> 2) as usize])
}

/// The offsets `q / 62` of the 6-bit two's-complement codes `q` (index = the code's bits).
const SUBPIXEL_OFFSETS: [f32; 64] = {
    let mut table = [0.0f32; 64];
    let mut k = 0;
    while k < 64 {
        table[k] = (((k as u8) << 2) as i8 >> 2) as f32 / 62.0;
        k += 1;
    }
    table
};

fn grow<T: Default + Clone>(buffer: &mut Vec<T>, len: usize) {
    if buffer.len() < len {
        buffer.resize(len, T::default());
    }
}

#[cfg(test)]
mod reference;

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn step_image(w: usize, h: usize, edge_x: usize) -> Vec<u8> {
        let mut data = vec![40u8; w * h];
        for y in 0..h {
            for x in edge_x..w {
                data[y * w + x] = 200;
            }
        }
        data
    }

    /// Checks every output of `ws` (just run on `view`) against the reference detector.
    fn assert_same_as_reference(ws: &CannyWorkspace, view: &GrayView<'_>, params: &CannyParams) {
        let mut r = reference::ReferenceCanny::new();
        r.detect(view, params).unwrap();
        let (w, h) = (view.width(), view.height());
        assert_eq!((ws.width(), ws.height()), (w, h));
        assert_eq!(ws.smoothed(), r.smoothed(), "smoothed");
        assert_eq!(ws.magnitude(), r.magnitude(), "magnitude");
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                assert_eq!(
                    ws.gradient(x, y),
                    (r.gx()[i], r.gy()[i]),
                    "gradient {x},{y}"
                );
            }
        }
        assert_eq!(ws.edges(), r.edges(), "edge map");
        for (i, &e) in ws.edges().iter().enumerate() {
            if e == EDGE {
                assert_eq!(ws.subpixel_offset(i), r.subpixel_offset(i), "subpixel {i}");
            }
        }
    }

    /// A `w x h` image of random rectangles plus noise (edges of every direction and
    /// contrast).
    fn random_image(w: usize, h: usize, seed: u64, noise: u8) -> Vec<u8> {
        let mut state = seed
            .wrapping_mul(2862933555777941757)
            .wrapping_add(3037000493);
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as usize
        };
        let mut data = vec![(next() % 256) as u8; w * h];
        for _ in 0..(w * h / 60).max(2) {
            let (x0, y0) = (next() % w, next() % h);
            let (rw, rh) = (1 + next() % 20, 1 + next() % 20);
            let v = (next() % 256) as u8;
            for y in y0..(y0 + rh).min(h) {
                for x in x0..(x0 + rw).min(w) {
                    data[y * w + x] = v;
                }
            }
        }
        for p in &mut data {
            *p = p.saturating_add((next() % (noise as usize + 1)) as u8);
        }
        data
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 96,
            rng_seed: proptest::test_runner::RngSeed::Fixed(7),
            ..ProptestConfig::default()
        })]

        /// The row-pipelined detector reproduces the reference exactly: every size (including
        /// images narrower or shorter than the kernel), kernel width and threshold, windows of
        /// larger frames, and a workspace reused across sizes.
        #[test]
        fn optimised_detector_equals_reference(
            w in 1usize..90,
            h in 1usize..70,
            seed in any::<u64>(),
            noise in 0u8..40,
            sigma in 0.5f32..4.0,
            low in 0u16..300,
            extra in 0u16..300,
            window in (0usize..5, 0usize..5),
        ) {
            let params = CannyParams { sigma_px: sigma, low_threshold: low, high_threshold: low + extra };
            let data = random_image(w, h, seed, noise);
            let view = GrayView::new(&data, w, h).unwrap();
            let mut ws = CannyWorkspace::new();
            ws.detect(&view, &params).unwrap();
            assert_same_as_reference(&ws, &view, &params);
            let rect = crate::gray::PixelRect { x: window.0, y: window.1, width: w, height: h };
            if let Some(sub) = view.window(rect) {
                ws.detect(&sub, &params).unwrap();
                assert_same_as_reference(&ws, &sub, &params);
            }
        }
    }

    #[test]
    fn default_parameters_on_a_vga_sized_image_equal_the_reference() {
        let (w, h) = (640, 480);
        let data = random_image(w, h, 11, 12);
        let view = GrayView::new(&data, w, h).unwrap();
        let params = CannyParams::default();
        let mut ws = CannyWorkspace::new();
        ws.detect(&view, &params).unwrap();
        assert!(ws.edges().iter().filter(|&&e| e == EDGE).count() > 5000);
        assert_same_as_reference(&ws, &view, &params);
    }

    /// Every (denominator, magnitude difference) an 8-bit image can produce at a maximum gives
    /// the code of the integer-division reference.
    #[test]
    fn single_precision_subpixel_code_equals_integer_division_everywhere() {
        for diff in -2040i32..=2040 {
            let before = (-diff).max(0);
            let after = before + diff;
            // den = 2 at - before - after has the parity of diff.
            for den in (2 - (diff & 1)..=4080).step_by(2) {
                let at = (den + before + after) / 2;
                assert_eq!(
                    encode_subpixel(3, before, at, after),
                    reference::encode_subpixel(3, before, at, after),
                    "before {before} at {at} after {after}"
                );
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 256,
            rng_seed: proptest::test_runner::RngSeed::Fixed(9),
            ..ProptestConfig::default()
        })]

        /// The word-at-a-time search finds exactly the positions of a plain comparison.
        #[test]
        fn for_each_equal_finds_every_match(
            bytes in prop::collection::vec(prop_oneof![Just(0u8), Just(1), Just(2), any::<u8>()], 0..70),
            value in prop_oneof![Just(0u8), Just(2), Just(0x80), any::<u8>()],
        ) {
            let mut found = Vec::new();
            for_each_equal(&bytes, value, |i| found.push(i));
            let expected: Vec<usize> = (0..bytes.len()).filter(|&i| bytes[i] == value).collect();
            prop_assert_eq!(found, expected);
        }
    }

    #[test]
    fn kernel_sums_to_256_and_is_symmetric() {
        for sigma in [0.5f32, 1.0, 1.4, 2.0, 3.3] {
            let p = CannyParams {
                sigma_px: sigma,
                ..CannyParams::default()
            };
            let k = gaussian_kernel(sigma, p.kernel_radius());
            assert_eq!(k.iter().map(|&v| v as u32).sum::<u32>(), 256);
            let r: Vec<u16> = k.iter().rev().copied().collect();
            assert_eq!(k, r);
        }
    }

    #[test]
    fn vertical_step_gives_one_thin_edge_column() {
        let (w, h) = (40, 30);
        let data = step_image(w, h, 20);
        let view = GrayView::new(&data, w, h).unwrap();
        let mut ws = CannyWorkspace::new();
        ws.detect(&view, &CannyParams::default()).unwrap();
        for y in 2..h - 2 {
            let cols: Vec<usize> = (0..w).filter(|&x| ws.edges()[y * w + x] == EDGE).collect();
            assert_eq!(cols.len(), 1, "row {y}: {cols:?}");
            assert!((19..=20).contains(&cols[0]));
            assert!(ws.gradient(cols[0], y).0 > 0);
        }
    }

    #[test]
    fn flat_image_has_no_edges_and_reuse_does_not_leak_state() {
        let (w, h) = (40, 30);
        let mut ws = CannyWorkspace::new();
        let step = step_image(w, h, 10);
        ws.detect(
            &GrayView::new(&step, w, h).unwrap(),
            &CannyParams::default(),
        )
        .unwrap();
        let flat = vec![90u8; 20 * 10];
        ws.detect(
            &GrayView::new(&flat, 20, 10).unwrap(),
            &CannyParams::default(),
        )
        .unwrap();
        assert!(ws.edges().iter().all(|&e| e != EDGE));
        assert_eq!(ws.edges().len(), 200);
    }

    #[test]
    fn weak_edges_survive_only_when_connected() {
        // A faint vertical line connected to a strong one survives; an isolated faint one does not.
        let (w, h) = (60, 40);
        let mut data = vec![60u8; w * h];
        // Column x = 20: a step fading from 160 grey levels (strong) to 20 (weak) down the rows.
        for y in 0..h {
            let step = (160 - 5 * y as i32).max(20) as u8;
            for x in 20..45 {
                data[y * w + x] = 60 + step;
            }
        }
        // Column x = 45: a weak step on every row, connected to nothing strong.
        for y in 0..h {
            for x in 45..w {
                data[y * w + x] = data[y * w + 44] + 20;
            }
        }
        let p = CannyParams {
            sigma_px: 1.0,
            low_threshold: 30,
            high_threshold: 200,
        };
        let mut ws = CannyWorkspace::new();
        ws.detect(&GrayView::new(&data, w, h).unwrap(), &p).unwrap();
        let e = ws.edges();
        let at = |x: usize, y: usize| (x - 1..=x + 1).any(|xx| e[y * w + xx] == EDGE);
        assert!(at(20, 10), "strong part");
        assert!(at(20, 30), "weak part connected to the strong part");
        assert!(!at(45, 30), "isolated weak edge");
    }

    #[test]
    fn bad_parameters_are_rejected() {
        let p = CannyParams {
            sigma_px: 9.0,
            ..CannyParams::default()
        };
        assert!(p.validate().is_err());
        let p = CannyParams {
            low_threshold: 50,
            high_threshold: 10,
            ..CannyParams::default()
        };
        assert!(p.validate().is_err());
    }
}
