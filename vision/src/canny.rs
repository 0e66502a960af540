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
/// Value of a pixel that survived non-maximum suppression but was not connected to a strong edge
/// (the only edge-map value with bit 0 set, which hysteresis relies on).
const WEAK: u8 = 1;
// Hysteresis turns a weak pixel into an edge pixel by adding one.
const _: () = assert!(EDGE == WEAK + 1);

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

/// A smoothed image moved out of a [`CannyWorkspace`] by [`CannyWorkspace::keep_smoothed`].
#[derive(Debug, Default, Clone)]
pub struct KeptSmoothed {
    data: Vec<u8>,
    width: usize,
    height: usize,
}

impl KeptSmoothed {
    /// Row-major pixels.
    pub fn data(&self) -> &[u8] {
        &self.data[..self.width * self.height]
    }

    /// Width, pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height, pixels.
    pub fn height(&self) -> usize {
        self.height
    }
}

/// Reusable buffers of the Canny detector. Create once, call [`CannyWorkspace::detect`] per
/// frame: no allocation happens once the buffers have grown to the frame size.
#[derive(Debug, Default, Clone)]
pub struct CannyWorkspace {
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
    /// Pixels whose neighbours hysteresis has still to visit: the first `pushed` entries.
    /// Every pixel is pushed at most once per image, so `n + NMS_LANES` entries never
    /// overflow although a push writes its slot before deciding whether to keep it.
    stack: Vec<u32>,
    pushed: usize,
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

    /// Horizontal Sobel gradient of the smoothed last image.
    pub fn gx(&self) -> &[i16] {
        &self.gx[..self.width * self.height]
    }

    /// Vertical Sobel gradient of the smoothed last image.
    pub fn gy(&self) -> &[i16] {
        &self.gy[..self.width * self.height]
    }

    /// Sub-pixel localisation of the edge pixels of the last image: for pixel `i` (valid
    /// where [`Self::edges`] is [`EDGE`]), the step `(sx, sy)` of the quantised gradient
    /// direction and the offset along it (pixels, within +-0.5) of the vertex of the parabola
    /// through the magnitudes before, at and after the pixel.
    pub fn subpixel_offset(&self, i: usize) -> ((i32, i32), f32) {
        decode_subpixel(self.subpixel[i])
    }

    /// The sub-pixel shift `[dx, dy]` of edge pixel `i`: [`Self::subpixel_offset`]'s offset
    /// times its step, from a table (the same values, bit for bit).
    #[inline]
    pub fn subpixel_shift(&self, i: usize) -> [f32; 2] {
        SUBPIXEL_SHIFTS[self.subpixel[i] as usize]
    }

    /// The smoothed last image.
    pub fn smoothed(&self) -> &[u8] {
        &self.smoothed[..self.width * self.height]
    }

    /// Moves the smoothed last image into `kept` by exchanging buffers (no copy, and no
    /// allocation once both buffers have grown to the frame size), so that the workspace can
    /// detect the next image while this one is still read. [`Self::smoothed`] holds stale
    /// pixels until the next [`Self::detect`].
    pub fn keep_smoothed(&mut self, kept: &mut KeptSmoothed) {
        std::mem::swap(&mut self.smoothed, &mut kept.data);
        kept.width = self.width;
        kept.height = self.height;
        grow(&mut self.smoothed, self.width * self.height);
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
        grow(&mut self.magnitude, 3 * width);
        grow(&mut self.edges, n);
        grow(&mut self.subpixel, n);
        grow(&mut self.stack, n + NMS_LANES);
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
        run_stages(self, image, params);
        Ok(())
    }

    /// Smoothing only (Gaussian, replicated borders) into [`Self::smoothed`].
    ///
    /// Both passes accumulate `128 + sum(k_t p_t)` in `u16` (weights sum to 256, so no overflow)
    /// and keep the high byte; blocks of [`SMOOTH_LANES`] outputs are accumulated in registers.
    #[inline(always)]
    fn smooth(&mut self, image: &GrayView<'_>) {
        let (w, h) = (self.width, self.height);
        let radius = self.kernel.len() / 2;
        let kernel = &self.kernel[..];
        // Horizontal pass into `horizontal`.
        for y in 0..h {
            let src = image.row(y);
            let pad = &mut self.padded_row[..w + 2 * radius];
            pad[..radius].fill(src[0]);
            pad[radius..radius + w].copy_from_slice(src);
            pad[radius + w..].fill(src[w - 1]);
            let out = &mut self.horizontal[y * w..(y + 1) * w];
            match kernel.len() {
                5 => convolve_fixed::<5>(kernel, |t| &pad[t..t + w], out),
                7 => convolve_fixed::<7>(kernel, |t| &pad[t..t + w], out),
                _ => convolve_row(kernel, |t| &pad[t..t + w], out),
            }
        }
        // Vertical pass into `smoothed`.
        let horizontal = &self.horizontal[..w * h];
        for y in 0..h {
            let out = &mut self.smoothed[y * w..(y + 1) * w];
            let tap_row = |t: usize| {
                let sy = (y + t).saturating_sub(radius).min(h - 1);
                &horizontal[sy * w..(sy + 1) * w]
            };
            match kernel.len() {
                5 => convolve_fixed::<5>(kernel, tap_row, out),
                7 => convolve_fixed::<7>(kernel, tap_row, out),
                _ => convolve_row(kernel, tap_row, out),
            }
        }
    }

    /// Sobel gradients row by row, and the non-maximum suppression of each row as soon as the
    /// magnitudes of the rows around it exist: only three rows of magnitude are kept, so the
    /// gradients are still in cache when they are suppressed.
    #[inline(always)]
    fn gradients_and_suppression(&mut self, params: &CannyParams) {
        let (w, h) = (self.width, self.height);
        let low = params.low_threshold as i16;
        let high = params.high_threshold as i16;
        self.pushed = 0;
        self.edges[..w].fill(0);
        self.edges[(h - 1) * w..h * w].fill(0);
        if w < 3 {
            self.gx[..w * h].fill(0);
            self.gy[..w * h].fill(0);
            self.edges[..w * h].fill(0);
            return;
        }
        for y in 0..h {
            self.sobel_row(y);
            if y >= 2 {
                self.suppress_row(y - 1, low, high);
            }
        }
    }

    /// 3x3 Sobel gradients of row `y` (replicated borders) into [`Self::gx`] and [`Self::gy`],
    /// and its L1 magnitude into the ring slot `y % 3`; the first and last columns get zero
    /// gradient. Needs `w >= 3`.
    #[inline(always)]
    fn sobel_row(&mut self, y: usize) {
        let (w, h) = (self.width, self.height);
        let n = w - 2;
        let ya = y.saturating_sub(1);
        let yc = (y + 1).min(h - 1);
        let a = &self.smoothed[ya * w..ya * w + w];
        let b = &self.smoothed[y * w..y * w + w];
        let c = &self.smoothed[yc * w..yc * w + w];
        let (a0, a1, a2) = (&a[..n], &a[1..n + 1], &a[2..n + 2]);
        let (b0, b2) = (&b[..n], &b[2..n + 2]);
        let (c0, c1, c2) = (&c[..n], &c[1..n + 1], &c[2..n + 2]);
        let row = y * w;
        let slot = (y % 3) * w;
        let gx = &mut self.gx[row + 1..row + 1 + n];
        let gy = &mut self.gy[row + 1..row + 1 + n];
        let mag = &mut self.magnitude[slot + 1..slot + 1 + n];
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
            self.magnitude[slot + x] = 0;
        }
    }

    /// Non-maximum suppression of row `y` (inside `1..h - 1`) along the quantised gradient
    /// direction, from the magnitude ring; strong maxima are marked [`EDGE`] and pushed on the
    /// hysteresis stack, weak ones marked `WEAK`.
    #[inline(always)]
    fn suppress_row(&mut self, y: usize, low: i16, high: i16) {
        let w = self.width;
        let row = y * w;
        let out = &mut self.edges[row..row + w];
        out.fill(0);
        let slot = |r: usize| (r % 3) * w;
        let m_prev = &self.magnitude[slot(y - 1)..slot(y - 1) + w];
        let m_cur = &self.magnitude[slot(y)..slot(y) + w];
        let m_next = &self.magnitude[slot(y + 1)..slot(y + 1) + w];
        let gxr = &self.gx[row..row + w];
        let gyr = &self.gy[row..row + w];
        let subpixel = &mut self.subpixel[row..row + w];
        let rows = NmsRows {
            prev: m_prev,
            cur: m_cur,
            next: m_next,
            gx: gxr,
            gy: gyr,
        };
        let stack = &mut self.stack[..];
        let mut pushed = self.pushed;
        if w <= 1 + NMS_LANES {
            // Rows narrower than one block: pixel by pixel.
            for x in 1..w - 1 {
                let (value, code) = suppress_pixel(&rows, x, low, high);
                out[x] = value;
                if value != 0 {
                    subpixel[x] = code;
                }
                stack[pushed] = (row + x) as u32;
                pushed += usize::from(value == EDGE);
            }
            self.pushed = pushed;
            return;
        }
        // Blocks of NMS_LANES pixels from x = 1, branch-free inside; the last block is aligned
        // to end at w - 1 (it may overlap the previous one: recomputing a pixel gives the same
        // result). Blocks without a magnitude above `low` hold no maximum and are skipped.
        // Which blocks to visit is decided first for up to 64 blocks at once, as a bit mask,
        // so that skipping costs no branch per block: the pattern of empty blocks differs in
        // every frame, and a branch on it would often be mispredicted.
        let full_blocks = (w - 2) / NMS_LANES;
        let blocks = full_blocks + usize::from(!(w - 2).is_multiple_of(NMS_LANES));
        let block_x = |k: usize| {
            if k < full_blocks {
                1 + k * NMS_LANES
            } else {
                w - 1 - NMS_LANES
            }
        };
        let mut done = 1usize;
        for first in (0..blocks).step_by(64) {
            let mut visit = 0u64;
            for k in first..blocks.min(first + 64) {
                let m = lanes(m_cur, block_x(k));
                let busy = m.iter().fold(i16::MIN, |a, &b| a.max(b)) > low;
                visit |= u64::from(busy) << (k - first);
            }
            while visit != 0 {
                let x = block_x(first + visit.trailing_zeros() as usize);
                visit &= visit - 1;
                let block = suppress_block(&rows, x, low, high);
                out[x..x + NMS_LANES].copy_from_slice(&block.values);
                subpixel[x..x + NMS_LANES].copy_from_slice(&block.codes);
                // Pixels before `done` (an overlapping last block) were pushed already. Every
                // lane is written; only strong ones advance the count (no branch per pixel).
                let strong = block.strong_mask & (u32::MAX << done.saturating_sub(x));
                for lane in 0..NMS_LANES {
                    stack[pushed] = (row + x + lane) as u32;
                    pushed += ((strong >> lane) & 1) as usize;
                }
                done = x + NMS_LANES;
            }
        }
        self.pushed = pushed;
    }

    /// Grows strong edges through 8-connected weak pixels.
    #[inline(always)]
    fn hysteresis(&mut self) {
        let w = self.width;
        let edges = &mut self.edges;
        let stack = &mut self.stack[..];
        let mut pushed = self.pushed;
        while pushed > 0 {
            pushed -= 1;
            let i = stack[pushed] as usize;
            // Edge pixels never touch the border (NMS leaves it at 0), so the neighbours exist;
            // one slice from the top-left to the bottom-right neighbour holds them all.
            let first = i - w - 1;
            let window = &mut edges[first..=i + w + 1];
            // Most strong pixels have no weak neighbour: one test on the three rows' bytes
            // (WEAK is the only value with bit 0 set) skips them.
            let row = |r: &[u8]| u32::from(r[0] | r[1] | r[2]);
            let rows = row(&window[..3]) | row(&window[w..w + 3]) | row(&window[2 * w..2 * w + 3]);
            if rows & u32::from(WEAK) == 0 {
                continue;
            }
            // Without a branch per neighbour: weak ones become edges and are pushed.
            for k in [0, 1, 2, w, w + 2, 2 * w, 2 * w + 1, 2 * w + 2] {
                let weak = window[k] == WEAK;
                window[k] += u8::from(weak);
                stack[pushed] = (first + k) as u32;
                pushed += usize::from(weak);
            }
        }
        self.pushed = 0;
    }
}

/// The four stages of [`CannyWorkspace::detect`] on prepared buffers, compiled once per
/// instruction-set level and chosen at run time from the CPU's features (the stages are written
/// as plain loops over slices that the compiler vectorises; with AVX2 they run on 32-byte
/// registers). The dispatch code is the only `unsafe` in the crate and is generated by
/// `multiversion`.
#[allow(unsafe_code)]
#[multiversion::multiversion(targets("x86_64+avx2+bmi1+bmi2+popcnt+lzcnt", "x86_64+sse4.1"))]
fn run_stages<'a>(workspace: &mut CannyWorkspace, image: &GrayView<'a>, params: &CannyParams) {
    workspace.smooth(image);
    workspace.gradients_and_suppression(params);
    workspace.hysteresis();
}

/// tan(22.5 deg) in Q15.
const TG22: i32 = 13573;
/// Pixels per block of the smoothing passes.
const SMOOTH_LANES: usize = 16;
/// Pixels per block of non-maximum suppression.
const NMS_LANES: usize = 16;

/// One output row of a 1-D convolution with `kernel` (weights summing to 256): pixel `x` is
/// `(128 + sum_t kernel[t] * tap_input(t)[x]) >> 8`, where `tap_input(t)` is the input of tap `t`
/// for the whole output row (`out.len()` samples from the first output's). Computed in blocks of [`SMOOTH_LANES`] outputs kept in registers; the
/// last block is aligned to end at the row end.
#[inline(always)]
fn convolve_row<'a>(kernel: &[u16], tap_input: impl Fn(usize) -> &'a [u8], out: &mut [u8]) {
    let w = out.len();
    if w < SMOOTH_LANES {
        for (x, o) in out.iter_mut().enumerate() {
            let mut acc = 128u16;
            for (t, &k) in kernel.iter().enumerate() {
                acc += k * tap_input(t)[x] as u16;
            }
            *o = (acc >> 8) as u8;
        }
        return;
    }
    let mut x = 0;
    while x < w {
        let x0 = x.min(w - SMOOTH_LANES);
        let mut acc = [128u16; SMOOTH_LANES];
        for (t, &k) in kernel.iter().enumerate() {
            let p: &[u8; SMOOTH_LANES] = tap_input(t)[x0..x0 + SMOOTH_LANES].try_into().unwrap();
            for (a, &v) in acc.iter_mut().zip(p) {
                *a += k * v as u16;
            }
        }
        let o: &mut [u8; SMOOTH_LANES] = (&mut out[x0..x0 + SMOOTH_LANES]).try_into().unwrap();
        for (o, &a) in o.iter_mut().zip(&acc) {
            *o = (a >> 8) as u8;
        }
        x = x0 + SMOOTH_LANES;
    }
}

/// [`convolve_row`] for a kernel of `N` taps: `tap_input(t)` is the input of tap `t` for the
/// whole output row (`out.len()` samples from the first output's).
#[inline(always)]
fn convolve_fixed<'a, const N: usize>(
    kernel: &[u16],
    tap_input: impl Fn(usize) -> &'a [u8],
    out: &mut [u8],
) {
    let w = out.len();
    let kernel: [u16; N] = kernel[..N].try_into().unwrap();
    let inputs: [&[u8]; N] = std::array::from_fn(|t| &tap_input(t)[..w]);
    if w < SMOOTH_LANES {
        for (x, o) in out.iter_mut().enumerate() {
            let mut acc = 128u16;
            for t in 0..N {
                acc += kernel[t] * inputs[t][x] as u16;
            }
            *o = (acc >> 8) as u8;
        }
        return;
    }
    let mut x = 0;
    while x < w {
        let x0 = x.min(w - SMOOTH_LANES);
        let mut acc = [128u16; SMOOTH_LANES];
        for t in 0..N {
            let p: &[u8; SMOOTH_LANES] = inputs[t][x0..x0 + SMOOTH_LANES].try_into().unwrap();
            for (a, &v) in acc.iter_mut().zip(p) {
                *a += kernel[t] * v as u16;
            }
        }
        let o: &mut [u8; SMOOTH_LANES] = (&mut out[x0..x0 + SMOOTH_LANES]).try_into().unwrap();
        for (o, &a) in o.iter_mut().zip(&acc) {
            *o = (a >> 8) as u8;
        }
        x = x0 + SMOOTH_LANES;
    }
}

/// The rows of magnitude and gradient around the row being suppressed.
struct NmsRows<'a> {
    prev: &'a [i16],
    cur: &'a [i16],
    next: &'a [i16],
    gx: &'a [i16],
    gy: &'a [i16],
}

/// Result of non-maximum suppression on [`NMS_LANES`] pixels.
struct NmsBlock {
    /// 0, `WEAK` or [`EDGE`] per pixel.
    values: [u8; NMS_LANES],
    /// Sub-pixel codes (meaningful where `values` is not 0).
    codes: [u8; NMS_LANES],
    /// Bit `l` set when pixel `l` is [`EDGE`].
    strong_mask: u32,
}

/// `NMS_LANES` values of `row` from `x`.
#[inline(always)]
fn lanes(row: &[i16], x: usize) -> [i16; NMS_LANES] {
    row[x..x + NMS_LANES].try_into().unwrap()
}

/// Non-maximum suppression of the pixels `x..x + NMS_LANES` (all inside `1..w - 1`), without
/// branches: the same decisions as [`suppress_pixel`] lane by lane.
#[inline(always)]
fn suppress_block(rows: &NmsRows<'_>, x: usize, low: i16, high: i16) -> NmsBlock {
    let m = lanes(rows.cur, x);
    let gx = lanes(rows.gx, x);
    let gy = lanes(rows.gy, x);
    let (cur_l, cur_r) = (lanes(rows.cur, x - 1), lanes(rows.cur, x + 1));
    let (prev_l, prev_c, prev_r) = (
        lanes(rows.prev, x - 1),
        lanes(rows.prev, x),
        lanes(rows.prev, x + 1),
    );
    let (next_l, next_c, next_r) = (
        lanes(rows.next, x - 1),
        lanes(rows.next, x),
        lanes(rows.next, x + 1),
    );
    let mut values = [0u8; NMS_LANES];
    let mut codes = [0u8; NMS_LANES];
    let mut strong = [false; NMS_LANES];
    for l in 0..NMS_LANES {
        let (horizontal, vertical, anti) = direction_sector(gx[l], gy[l]);
        let code = if horizontal {
            0u8
        } else if vertical {
            1
        } else if anti {
            2
        } else {
            3
        };
        let pick = |h: i16, v: i16, a: i16, d: i16| {
            if horizontal {
                h
            } else if vertical {
                v
            } else if anti {
                a
            } else {
                d
            }
        };
        let before = pick(cur_l[l], prev_c[l], next_l[l], prev_l[l]);
        let after = pick(cur_r[l], next_c[l], prev_r[l], next_r[l]);
        let mm = m[l];
        // Ties with the neighbour after count as maxima on the axes only.
        let tie = (horizontal | vertical) as i16;
        let is_max = (mm > low) & (mm > before) & (mm + tie > after);
        let is_strong = is_max & (mm > high);
        values[l] = (is_max as u8) * (WEAK + is_strong as u8);
        strong[l] = is_strong;
        codes[l] = encode_subpixel_branchless(code, before as i32, mm as i32, after as i32);
    }
    let strong_mask = strong
        .iter()
        .enumerate()
        .fold(0u32, |mask, (l, &s)| mask | (s as u32) << l);
    NmsBlock {
        values,
        codes,
        strong_mask,
    }
}

/// The sector of the gradient `(gx, gy)` (components within +-1020) as flags: horizontal
/// (within 22.5 degrees of the x axis), vertical (within 22.5 degrees of the y axis), or else
/// anti-diagonal (components of opposite signs) or diagonal. The same decisions as the Q15
/// comparisons of [`suppress_pixel`], in 16-bit lanes: with `t = floor(|gx| tan 22.5)` (a
/// high-half product), `|gy| 2^15 < |gx| TG22` is `|gx| > 0 && |gy| <= t` (the product is
/// never a multiple of 2^15 for `0 < |gx| < 2^15`) and `|gy| 2^15 > |gx| (TG22 + 2^16)` is
/// `|gy| > 2 |gx| + t`.
#[inline(always)]
fn direction_sector(gx: i16, gy: i16) -> (bool, bool, bool) {
    let (ax, ay) = (gx.abs(), gy.abs());
    let t = ((i32::from(ax) * (2 * TG22)) >> 16) as i16;
    let horizontal = (ax > 0) & (ay <= t);
    let vertical = !horizontal & (ay > 2 * ax + t);
    let anti = !horizontal & !vertical & ((gx ^ gy) < 0);
    (horizontal, vertical, anti)
}

/// Non-maximum suppression of pixel `x` (inside `1..w - 1`): its edge value (0, `WEAK` or
/// [`EDGE`]) and sub-pixel code (meaningful where the value is not 0).
fn suppress_pixel(rows: &NmsRows<'_>, x: usize, low: i16, high: i16) -> (u8, u8) {
    let m = rows.cur[x];
    if m <= low {
        return (0, 0);
    }
    let dx = rows.gx[x] as i32;
    let dy = rows.gy[x] as i32;
    let ax = dx.abs();
    let ay = dy.abs() << 15;
    let tg22x = ax * TG22;
    // Neighbours before/after along the quantised gradient direction.
    let (code, before, after, is_max) = if ay < tg22x {
        let (b, a) = (rows.cur[x - 1], rows.cur[x + 1]);
        (0u8, b, a, m > b && m >= a)
    } else {
        let tg67x = tg22x + (ax << 16);
        if ay > tg67x {
            let (b, a) = (rows.prev[x], rows.next[x]);
            (1, b, a, m > b && m >= a)
        } else if (dx ^ dy) < 0 {
            let (b, a) = (rows.next[x - 1], rows.prev[x + 1]);
            (2, b, a, m > a && m > b)
        } else {
            let (b, a) = (rows.prev[x - 1], rows.next[x + 1]);
            (3, b, a, m > b && m > a)
        }
    };
    if !is_max {
        return (0, 0);
    }
    let code = encode_subpixel(code, before as i32, m as i32, after as i32);
    (if m > high { EDGE } else { WEAK }, code)
}

/// [`encode_subpixel`] without branches (so that a block of them vectorises); equal to it
/// wherever `2 at - before - after > 0`, i.e. at every maximum. Magnitudes are within 0..=2040.
#[inline(always)]
fn encode_subpixel_branchless(code: u8, before: i32, at: i32, after: i32) -> u8 {
    let den = 2 * at - before - after;
    let positive = den > 0;
    let den_safe = if positive { den } else { 1 };
    let n = 31 * (after - before);
    let num = n.abs() + den_safe / 2;
    // floor(num / den) clamped to 31, converted through the float's bits (exact below 2^23)
    // rather than a saturating cast, so that the whole block stays in vector registers.
    let quotient = (num as f32 / den_safe as f32).min(31.0).floor();
    let magnitude = ((quotient + F32_INTEGER_MAGIC).to_bits() - F32_INTEGER_MAGIC.to_bits()) as i32;
    let signed = if n >= 0 { magnitude } else { -magnitude };
    let q = if positive { signed } else { 0 };
    code | ((q as i8 as u8) << 2)
}

/// 2^23: adding it to a float in `0..2^23` that holds an integer leaves that integer in the
/// low mantissa bits.
const F32_INTEGER_MAGIC: f32 = 8_388_608.0;

/// Packs the direction code (2 bits) and the parabola-vertex offset (6 bits, 1/62 px).
fn encode_subpixel(code: u8, before: i32, at: i32, after: i32) -> u8 {
    // offset = 0.5 (before - after) / (before - 2 at + after), within +-0.5 at a maximum;
    // q = round(62 offset), halves away from zero: floor((|n| + floor(den / 2)) / den) with
    // the sign of n.
    let den = 2 * at - before - after;
    let q = if den > 0 {
        let n = 31 * (after - before);
        let magnitude = floor_quotient(n.abs() + den / 2, den).min(31) as i8;
        if n >= 0 {
            magnitude
        } else {
            -magnitude
        }
    } else {
        0
    };
    code | ((q as u8) << 2)
}

/// `floor(num / den)` for `0 <= num < 2^24`, `0 < den < 2^24` (magnitudes of 8-bit images stay
/// far below), through one single-precision division, which is exact here: both operands are
/// exact in `f32`; an integer quotient is representable, so the correctly rounded division
/// returns it; otherwise the quotient is at least `1 / den` away from the integers while the
/// rounding error is at most `num / den * 2^-24 < 1 / den`, so truncation gives the floor.
#[inline]
fn floor_quotient(num: i32, den: i32) -> i32 {
    debug_assert!((0..1 << 24).contains(&num) && (1..1 << 24).contains(&den));
    (num as f32 / den as f32) as i32
}

/// [`decode_subpixel`]'s offset times its step for every code byte.
const SUBPIXEL_SHIFTS: [[f32; 2]; 256] = {
    let mut table = [[0.0f32; 2]; 256];
    let mut byte = 0usize;
    while byte < 256 {
        let ((sx, sy), offset) = decode_subpixel(byte as u8);
        table[byte] = [offset * sx as f32, offset * sy as f32];
        byte += 1;
    }
    table
};

const fn decode_subpixel(byte: u8) -> ((i32, i32), f32) {
    let step = match byte & 3 {
        0 => (1, 0),
        1 => (0, 1),
        2 => (1, -1),
        _ => (1, 1),
    };
    (step, ((byte as i8) >> 2) as f32 / 62.0)
}

fn grow<T: Default + Clone>(buffer: &mut Vec<T>, len: usize) {
    if buffer.len() < len {
        buffer.resize(len, T::default());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn step_image(w: usize, h: usize, edge_x: usize) -> Vec<u8> {
        let mut data = vec![40u8; w * h];
        for y in 0..h {
            for x in edge_x..w {
                data[y * w + x] = 200;
            }
        }
        data
    }

    /// The sub-pixel code with integer divisions.
    fn encode_subpixel_integer(code: u8, before: i32, at: i32, after: i32) -> u8 {
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

    /// Every (denominator, magnitude difference) an 8-bit image can produce at a maximum gives
    /// the code of integer division.
    #[test]
    fn single_precision_subpixel_code_equals_integer_division_everywhere() {
        for diff in -2040i32..=2040 {
            let before = (-diff).max(0);
            let after = before + diff;
            // den = 2 at - before - after has the parity of diff.
            for den in (2 - (diff & 1)..=4080).step_by(2) {
                let at = (den + before + after) / 2;
                let exact = encode_subpixel_integer(3, before, at, after);
                assert_eq!(
                    encode_subpixel(3, before, at, after),
                    exact,
                    "before {before} at {at} after {after}"
                );
                assert_eq!(
                    encode_subpixel_branchless(3, before, at, after),
                    exact,
                    "branch-free: before {before} at {at} after {after}"
                );
            }
        }
        for (before, at, after) in [(5, 1, 3), (0, 0, 0), (2040, 1020, 0)] {
            assert_eq!(
                encode_subpixel(1, before, at, after),
                encode_subpixel_integer(1, before, at, after)
            );
        }
    }

    /// The branch-free block suppression takes the decisions of the pixel-by-pixel one, with
    /// the same sub-pixel code at every maximum, on random gradients including ties.
    #[test]
    fn block_suppression_equals_pixel_suppression() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let w = 2 + NMS_LANES;
        for _ in 0..20_000 {
            let mut row =
                |range: i16| -> Vec<i16> { (0..w).map(|_| rng.random_range(0..=range)).collect() };
            let (prev, cur, next) = (row(60), row(60), row(60));
            let mut signed = |_: usize| -> i16 { rng.random_range(-1020..=1020) };
            let gx: Vec<i16> = (0..w).map(&mut signed).collect();
            let gy: Vec<i16> = (0..w).map(&mut signed).collect();
            let rows = NmsRows {
                prev: &prev,
                cur: &cur,
                next: &next,
                gx: &gx,
                gy: &gy,
            };
            let block = suppress_block(&rows, 1, 20, 40);
            for l in 0..NMS_LANES {
                let (value, code) = suppress_pixel(&rows, 1 + l, 20, 40);
                assert_eq!(block.values[l], value, "lane {l}");
                assert_eq!((block.strong_mask >> l) & 1 == 1, value == EDGE);
                if value != 0 {
                    assert_eq!(block.codes[l], code, "lane {l}");
                }
            }
        }
    }

    /// The 16-bit sector test decides as the Q15 one of `suppress_pixel` for every gradient a
    /// 3x3 Sobel of an 8-bit image can give.
    #[test]
    fn sixteen_bit_sectors_equal_q15_sectors() {
        for gx in -1020i16..=1020 {
            for gy in -1020i16..=1020 {
                let (dx, dy) = (gx as i32, gy as i32);
                let ax = dx.abs();
                let ay = dy.abs() << 15;
                let tg22x = ax * TG22;
                let horizontal = ay < tg22x;
                let vertical = !horizontal && ay > tg22x + (ax << 16);
                let anti = !horizontal && !vertical && (dx ^ dy) < 0;
                assert_eq!(
                    direction_sector(gx, gy),
                    (horizontal, vertical, anti),
                    "gx {gx} gy {gy}"
                );
            }
        }
    }

    /// A kept smoothed image survives the next detection, which smooths into the other buffer.
    #[test]
    fn a_kept_smoothed_image_survives_the_next_detection() {
        let (a, b) = (step_image(30, 20, 10), step_image(30, 20, 17));
        let params = CannyParams::default();
        let mut ws = CannyWorkspace::new();
        ws.detect(&GrayView::new(&a, 30, 20).unwrap(), &params)
            .unwrap();
        let smoothed_a = ws.smoothed().to_vec();
        let mut kept = KeptSmoothed::default();
        ws.keep_smoothed(&mut kept);
        ws.detect(&GrayView::new(&b, 30, 20).unwrap(), &params)
            .unwrap();
        assert_eq!(kept.data(), &smoothed_a[..]);
        assert_eq!((kept.width(), kept.height()), (30, 20));
        let mut alone = CannyWorkspace::new();
        alone
            .detect(&GrayView::new(&b, 30, 20).unwrap(), &params)
            .unwrap();
        assert_eq!(ws.smoothed(), alone.smoothed());
        assert_ne!(ws.smoothed(), kept.data());
    }

    /// The fixed-tap convolutions equal the generic one (kernels of sigma 1.0 and 1.4).
    #[test]
    fn fixed_tap_convolution_equals_generic() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for sigma in [1.0f32, 1.4] {
            let kernel = gaussian_kernel(sigma, (2.0 * sigma).ceil() as usize);
            for w in [1usize, 7, 15, 16, 17, 37, 64] {
                let input: Vec<u8> = (0..w + kernel.len()).map(|_| rng.random()).collect();
                let mut generic = vec![0u8; w];
                convolve_row(&kernel, |t| &input[t..t + w], &mut generic);
                let mut fixed = vec![0u8; w];
                match kernel.len() {
                    5 => convolve_fixed::<5>(&kernel, |t| &input[t..t + w], &mut fixed),
                    7 => convolve_fixed::<7>(&kernel, |t| &input[t..t + w], &mut fixed),
                    n => panic!("kernel of {n} taps"),
                }
                assert_eq!(fixed, generic, "sigma {sigma} width {w}");
            }
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
            assert!(ws.gx()[y * w + cols[0]] > 0);
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
