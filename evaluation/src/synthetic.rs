//! Synthetic rectified pairs with known disparity, for tests and benchmarks.
//!
//! Two renderers:
//! - [`render`]: textured planar layers (each `d = a + b x + c y` in left-image pixels), the
//!   nearer layer hiding the farther, rendered into a clean left and right image (the left
//!   pixel at x is the right pixel at x - d).
//! - [`render_rig`]: textured rectangles in 3D ([`Panel`], e.g. photographs printed on planes)
//!   seen by a rectified pinhole pair ([`Rig`]), each camera with its own imperfections
//!   ([`Imaging`]: optical blur, vignetting, gain and offset, sensor noise); the true disparity
//!   of both views comes out exact, occlusions included.

/// A textured plane of the scene, seen in the left image.
#[derive(Debug, Clone)]
pub struct Layer {
    /// Disparity plane `[a, b, c]`: `d(x, y) = a + b x + c y`, pixels.
    pub disparity: [f32; 3],
    /// Where the layer is, in left-image pixels `[x0, y0, x1, y1]` (exclusive ends).
    pub extent: [f32; 4],
    /// Its texture in left-image coordinates, row-major, the image's size.
    pub texture: Vec<u8>,
}

impl Layer {
    fn disparity_at(&self, x: f32, y: f32) -> f32 {
        self.disparity[0] + self.disparity[1] * x + self.disparity[2] * y
    }

    fn covers(&self, x: f32, y: f32) -> bool {
        let [x0, y0, x1, y1] = self.extent;
        x >= x0 && x < x1 && y >= y0 && y < y1
    }
}

/// A small deterministic generator (64-bit LCG), so that every run sees the same scene.
#[derive(Debug, Clone)]
pub struct Lcg(u64);

impl Lcg {
    /// Seeded.
    pub fn new(seed: u64) -> Self {
        Lcg(seed ^ 0x9E37_79B9_7F4A_7C15)
    }
    /// Uniform in `0..n` (`n > 0`).
    pub fn below(&mut self, n: usize) -> usize {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 33) % n.max(1) as u64) as usize
    }

    /// Uniform in `[0, 1)`.
    pub fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Standard normal (Box-Muller).
    pub fn gaussian(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform(); // in (0, 1]: the logarithm stays finite
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// A texture of `count` random grey rectangles `min..max` px on a mid-grey ground.
pub fn rectangles(
    width: usize,
    height: usize,
    count: usize,
    size_px: [usize; 2],
    rng: &mut Lcg,
) -> Vec<u8> {
    let mut t = vec![128u8; width * height];
    let span = size_px[1].saturating_sub(size_px[0]).max(1);
    for _ in 0..count {
        let (x0, y0) = (rng.below(width), rng.below(height));
        let (rw, rh) = (size_px[0] + rng.below(span), size_px[0] + rng.below(span));
        let v = (15 + rng.below(225)) as u8;
        for y in y0..(y0 + rh).min(height) {
            t[y * width + x0..(x0 + rw).min(width) + y * width].fill(v);
        }
    }
    t
}

/// A map-like texture: blocks of many sizes and greys crossed by dark roads of random
/// direction (dense, many short edges at every orientation, much of it alike).
pub fn printed_map(width: usize, height: usize, rng: &mut Lcg) -> Vec<u8> {
    let blocks = width * height / 120;
    let mut t = rectangles(width, height, blocks, [3, 22], rng);
    for _ in 0..(width + height) / 12 {
        let (x0, y0) = (rng.below(width) as f32, rng.below(height) as f32);
        let angle = rng.below(360) as f32 * std::f32::consts::PI / 180.0;
        let (dx, dy) = (angle.cos(), angle.sin());
        let length = 20 + rng.below(120);
        let grey = (10 + rng.below(40)) as u8;
        for s in 0..length {
            let (x, y) = (x0 + dx * s as f32, y0 + dy * s as f32);
            for o in [-1.0f32, 0.0, 1.0] {
                let (px, py) = ((x - dy * o).round(), (y + dx * o).round());
                if px >= 0.0 && py >= 0.0 && (px as usize) < width && (py as usize) < height {
                    t[py as usize * width + px as usize] = grey;
                }
            }
        }
    }
    t
}

/// The class of scene "a printed map before a background plane": a richly textured map
/// ([`printed_map`]) on a plane 3 px of disparity in front of a plane of coarser blocks
/// (disparities 11 and 8 px), the map covering the middle three quarters of the image.
/// Returns the left and right images and the left image's true disparity.
pub fn printed_map_scene(width: usize, height: usize, seed: u64) -> (Vec<u8>, Vec<u8>, Vec<f32>) {
    let mut rng = Lcg::new(seed);
    let (w, h) = (width as f32, height as f32);
    let back = Layer {
        disparity: [8.0, 0.0, 0.0],
        extent: [0.0, 0.0, w, h],
        texture: rectangles(width, height, width * height / 600, [8, 60], &mut rng),
    };
    let map = Layer {
        disparity: [11.0, 0.0, 0.0],
        extent: [w / 8.0, h / 8.0, w * 7.0 / 8.0, h * 7.0 / 8.0],
        texture: printed_map(width, height, &mut rng),
    };
    render(width, height, &[back, map])
}

/// Renders `layers` (nearest last wins where several cover a pixel: give them far to near)
/// into a left and a right image of `width` x `height`, and the left image's true disparity
/// (`NaN` where no layer is).
pub fn render(width: usize, height: usize, layers: &[Layer]) -> (Vec<u8>, Vec<u8>, Vec<f32>) {
    let mut left = vec![0u8; width * height];
    let mut truth = vec![f32::NAN; width * height];
    for y in 0..height {
        for x in 0..width {
            let (fx, fy) = (x as f32, y as f32);
            if let Some(l) = layers.iter().rev().find(|l| l.covers(fx, fy)) {
                left[y * width + x] = l.texture[y * width + x];
                truth[y * width + x] = l.disparity_at(fx, fy);
            }
        }
    }
    // The right pixel xr sees, of every layer, the left point x with x - d(x, y) = xr; the
    // nearest (largest disparity) visible one wins.
    let mut right = vec![0u8; width * height];
    for y in 0..height {
        let fy = y as f32;
        for xr in 0..width {
            let mut best: Option<(f32, u8)> = None;
            for l in layers {
                let [a, b, c] = l.disparity;
                // x - (a + b x + c y) = xr  =>  x = (xr + a + c y) / (1 - b)
                let x = (xr as f32 + a + c * fy) / (1.0 - b);
                if !l.covers(x, fy) || x < 0.0 || x > (width - 1) as f32 {
                    continue;
                }
                let d = l.disparity_at(x, fy);
                if best.is_some_and(|(bd, _)| bd >= d) {
                    continue;
                }
                best = Some((d, sample(&l.texture, width, x, y)));
            }
            right[y * width + xr] = best.map_or(0, |(_, v)| v);
        }
    }
    (left, right, truth)
}

/// Linear interpolation along the row.
fn sample(texture: &[u8], width: usize, x: f32, y: usize) -> u8 {
    let x0 = x.floor() as usize;
    let x1 = (x0 + 1).min(width - 1);
    let t = x - x0 as f32;
    let row = &texture[y * width..(y + 1) * width];
    (row[x0] as f32 * (1.0 - t) + row[x1] as f32 * t).round() as u8
}

/// A rectified pinhole stereo pair: both cameras share the intrinsics, the right camera sits
/// `baseline_m` to the right of the left one. Coordinates are the left camera's, in metres:
/// x right, y down, z forward. A point at depth `z` has the disparity
/// `focal_px * baseline_m / z`; the left pixel at x sees what the right pixel at x - d sees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rig {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Focal length, pixels.
    pub focal_px: f64,
    /// Principal point `[x, y]`, pixels (pixel centres are at integer coordinates).
    pub principal_px: [f64; 2],
    /// Distance between the two optical centres, metres.
    pub baseline_m: f64,
    /// Each pixel integrates `supersampling` x `supersampling` rays spread over its area.
    pub supersampling: usize,
}

impl Rig {
    /// A `width` x `height` rig with the principal point at the image centre and 4 x 4 rays
    /// per pixel.
    pub fn new(width: usize, height: usize, focal_px: f64, baseline_m: f64) -> Self {
        Rig {
            width,
            height,
            focal_px,
            principal_px: [(width as f64 - 1.0) / 2.0, (height as f64 - 1.0) / 2.0],
            baseline_m,
            supersampling: 4,
        }
    }

    /// The disparity of a point at depth `z_m`, pixels.
    pub fn disparity_at_depth(&self, z_m: f64) -> f64 {
        self.focal_px * self.baseline_m / z_m
    }
}

/// A grey image used as a surface's texture, sampled bilinearly and repeated mirrored beyond
/// its edges (so that tiling shows no seams).
#[derive(Debug, Clone, PartialEq)]
pub struct Texture {
    /// Width, texels.
    pub width: usize,
    /// Height, texels.
    pub height: usize,
    /// Row-major grey levels (0..255).
    pub texels: Vec<f32>,
}

impl Texture {
    /// From row-major 8-bit grey levels (`width * height` of them).
    pub fn from_gray(width: usize, height: usize, pixels: &[u8]) -> Self {
        assert_eq!(pixels.len(), width * height, "texture size");
        Texture {
            width,
            height,
            texels: pixels.iter().map(|&v| f32::from(v)).collect(),
        }
    }

    /// The `width` x `height` part of it whose top-left texel is `(x, y)` (clipped to it).
    pub fn crop(&self, x: usize, y: usize, width: usize, height: usize) -> Self {
        let (x, y) = (x.min(self.width - 1), y.min(self.height - 1));
        let (width, height) = (width.min(self.width - x), height.min(self.height - y));
        Texture {
            width,
            height,
            texels: (y..y + height)
                .flat_map(|r| self.texels[r * self.width + x..r * self.width + x + width].to_vec())
                .collect(),
        }
    }

    /// Bilinear value at `(u, v)` in texels (texel centres at half-integers), mirrored beyond
    /// the edges.
    pub fn sample(&self, u: f64, v: f64) -> f32 {
        let mirror = |i: i64, n: usize| -> usize {
            let n = n as i64;
            let m = i.rem_euclid(2 * n);
            (if m < n { m } else { 2 * n - 1 - m }) as usize
        };
        let (x, y) = (u - 0.5, v - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (tx, ty) = ((x - x0) as f32, (y - y0) as f32);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let (xa, xb) = (mirror(x0, self.width), mirror(x0 + 1, self.width));
        let (ya, yb) = (mirror(y0, self.height), mirror(y0 + 1, self.height));
        let at = |x: usize, y: usize| self.texels[y * self.width + x];
        let top = at(xa, ya) * (1.0 - tx) + at(xb, ya) * tx;
        let bottom = at(xa, yb) * (1.0 - tx) + at(xb, yb) * tx;
        top * (1.0 - ty) + bottom * ty
    }
}

/// The orientation of a plane: the rotation taking a fronto-parallel rectangle (its width
/// along x, its height along y, facing the camera) to the plane's axes. `yaw_deg` turns it
/// about the vertical (positive: its right side recedes), `pitch_deg` about the horizontal
/// (positive: its top recedes), `roll_deg` within its own plane (positive: clockwise as
/// seen). Returns the plane's width axis, height axis and normal (pointing away from the
/// camera), unit vectors.
pub fn plane_axes(yaw_deg: f64, pitch_deg: f64, roll_deg: f64) -> [[f64; 3]; 3] {
    let (sy, cy) = yaw_deg.to_radians().sin_cos();
    let (sp, cp) = pitch_deg.to_radians().sin_cos();
    let (sr, cr) = roll_deg.to_radians().sin_cos();
    // R = R_yaw * R_pitch * R_roll, applied to the unit axes.
    let rotate = |v: [f64; 3]| -> [f64; 3] {
        // Roll about z.
        let v = [cr * v[0] - sr * v[1], sr * v[0] + cr * v[1], v[2]];
        // Pitch about x: the top (y < 0) goes to larger z.
        let v = [v[0], cp * v[1] + sp * v[2], -sp * v[1] + cp * v[2]];
        // Yaw about y: the right side (x > 0) goes to larger z.
        [cy * v[0] - sy * v[2], v[1], sy * v[0] + cy * v[2]]
    };
    [
        rotate([1.0, 0.0, 0.0]),
        rotate([0.0, 1.0, 0.0]),
        rotate([0.0, 0.0, 1.0]),
    ]
}

/// A textured rectangle in 3D: the points `origin + s * width_axis + t * height_axis` for
/// `s, t` in `[0, 1)`, showing its texture `repeat` times across (mirrored tiles), the
/// texture's top-left corner at `origin`. Lambertian: it looks alike from both cameras.
#[derive(Debug, Clone)]
pub struct Panel {
    /// One corner (the texture's top-left), metres.
    pub origin: [f64; 3],
    /// The edge from `origin` along the texture's rows, metres.
    pub width_axis: [f64; 3],
    /// The edge from `origin` along the texture's columns, metres.
    pub height_axis: [f64; 3],
    /// What is printed on it.
    pub texture: std::sync::Arc<Texture>,
    /// How many times the texture repeats across the width and the height.
    pub repeat: [f64; 2],
    /// Its illumination: the radiance is `texture * shade`.
    pub shade: f32,
}

impl Panel {
    /// A `size_m = [width, height]` rectangle centred on `centre`, oriented by `axes` (from
    /// [`plane_axes`]), its texture shown once, fully lit.
    pub fn new(
        centre: [f64; 3],
        size_m: [f64; 2],
        axes: [[f64; 3]; 3],
        texture: std::sync::Arc<Texture>,
    ) -> Self {
        let width_axis = axes[0].map(|a| a * size_m[0]);
        let height_axis = axes[1].map(|a| a * size_m[1]);
        let origin = std::array::from_fn(|i| centre[i] - 0.5 * (width_axis[i] + height_axis[i]));
        Panel {
            origin,
            width_axis,
            height_axis,
            texture,
            repeat: [1.0, 1.0],
            shade: 1.0,
        }
    }

    /// The same, with its texture repeated `repeat` times across each axis.
    pub fn repeated(mut self, repeat: [f64; 2]) -> Self {
        self.repeat = repeat;
        self
    }

    /// The same, lit by `shade` (multiplies the texture).
    pub fn shaded(mut self, shade: f32) -> Self {
        self.shade = shade;
        self
    }

    /// The map from a camera's normalised ray `((x - cx) / f, (y - cy) / f, 1)` to
    /// `(s, t, 1) / z` for the camera whose centre is at `(camera_x_m, 0, 0)`: the inverse
    /// of the matrix whose columns are the two axes and the origin relative to the camera.
    fn ray_to_plane(&self, camera_x_m: f64) -> Option<[[f64; 3]; 3]> {
        let o = [self.origin[0] - camera_x_m, self.origin[1], self.origin[2]];
        let (u, v) = (self.width_axis, self.height_axis);
        // Columns u, v, o.
        let m = [[u[0], v[0], o[0]], [u[1], v[1], o[1]], [u[2], v[2], o[2]]];
        let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        if det.abs() < 1e-12 {
            return None; // seen edge-on (the plane contains the camera centre)
        }
        let c = |r0: usize, c0: usize, r1: usize, c1: usize| {
            m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0]
        };
        Some([
            [
                c(1, 1, 2, 2) / det,
                -c(0, 1, 2, 2) / det,
                c(0, 1, 1, 2) / det,
            ],
            [
                -c(1, 0, 2, 2) / det,
                c(0, 0, 2, 2) / det,
                -c(0, 0, 1, 2) / det,
            ],
            [
                c(1, 0, 2, 1) / det,
                -c(0, 0, 2, 1) / det,
                c(0, 0, 1, 1) / det,
            ],
        ])
    }
}

/// One camera's imperfections, applied in this order to the scene's radiance: optical blur,
/// vignetting, gain and offset, sensor noise, rounding to 8 bits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Imaging {
    /// Gaussian blur of the optics, standard deviation in pixels (0: none).
    pub blur_sigma_px: f64,
    /// Brightness fall-off towards the corners: the image is multiplied by
    /// `1 - vignetting * r^2`, `r` the distance from the principal point over the half
    /// diagonal.
    pub vignetting: f32,
    /// Multiplies the grey level.
    pub gain: f32,
    /// Added to the grey level after the gain.
    pub offset: f32,
    /// Standard deviation of the additive Gaussian sensor noise, grey levels.
    pub noise_sigma: f32,
    /// Seed of the noise.
    pub seed: u64,
}

impl Imaging {
    /// A perfect camera: no blur, vignetting, gain, offset or noise.
    pub fn ideal() -> Self {
        Imaging {
            blur_sigma_px: 0.0,
            vignetting: 0.0,
            gain: 1.0,
            offset: 0.0,
            noise_sigma: 0.0,
            seed: 0,
        }
    }
}

/// A rendered pair with its ground truth.
#[derive(Debug, Clone)]
pub struct RenderedPair {
    /// Left image, row-major grey levels.
    pub left: Vec<u8>,
    /// Right image, row-major grey levels.
    pub right: Vec<u8>,
    /// The left view's true disparity at each pixel centre (`NaN` where no panel is seen):
    /// the left pixel at x sees the point the right pixel at x - d sees, unless it is
    /// occluded there.
    pub disparity_left: Vec<f32>,
    /// The right view's true disparity (`NaN` where no panel is seen): the right pixel at x
    /// sees the point the left pixel at x + d sees, unless it is occluded there.
    pub disparity_right: Vec<f32>,
}

/// Renders `panels` seen by `rig`: each camera's image through its `imaging` (`[left,
/// right]`) and each view's exact disparity (the nearest panel at each pixel centre). Pixels
/// seeing no panel are black.
pub fn render_rig(rig: &Rig, panels: &[Panel], imaging: [&Imaging; 2]) -> RenderedPair {
    let (left, disparity_left) = render_view(rig, panels, 0.0, imaging[0]);
    let (right, disparity_right) = render_view(rig, panels, rig.baseline_m, imaging[1]);
    RenderedPair {
        left,
        right,
        disparity_left,
        disparity_right,
    }
}

/// One camera at `(camera_x_m, 0, 0)`: its image and its disparity map.
fn render_view(
    rig: &Rig,
    panels: &[Panel],
    camera_x_m: f64,
    imaging: &Imaging,
) -> (Vec<u8>, Vec<f32>) {
    let (w, h) = (rig.width, rig.height);
    let maps: Vec<Option<[[f64; 3]; 3]>> =
        panels.iter().map(|p| p.ray_to_plane(camera_x_m)).collect();
    // The nearest panel along the ray through (x, y): its radiance and 1 / depth.
    let trace = |x: f64, y: f64| -> Option<(f32, f64)> {
        let q = [
            (x - rig.principal_px[0]) / rig.focal_px,
            (y - rig.principal_px[1]) / rig.focal_px,
            1.0,
        ];
        let mut best: Option<(usize, f64, f64, f64)> = None;
        for (i, m) in maps.iter().enumerate() {
            let Some(m) = m else { continue };
            let r = |k: usize| m[k][0] * q[0] + m[k][1] * q[1] + m[k][2] * q[2];
            let inv_z = r(2);
            if inv_z <= 0.0 || best.is_some_and(|b| b.3 >= inv_z) {
                continue; // behind the camera, or farther than the nearest so far
            }
            let (s, t) = (r(0) / inv_z, r(1) / inv_z);
            if (0.0..1.0).contains(&s) && (0.0..1.0).contains(&t) {
                best = Some((i, s, t, inv_z));
            }
        }
        best.map(|(i, s, t, inv_z)| {
            let p = &panels[i];
            let tex = &p.texture;
            let u = s * p.repeat[0] * tex.width as f64;
            let v = t * p.repeat[1] * tex.height as f64;
            (tex.sample(u, v) * p.shade, inv_z)
        })
    };
    let n = rig.supersampling.max(1);
    let offsets: Vec<f64> = (0..n).map(|k| (k as f64 + 0.5) / n as f64 - 0.5).collect();
    let mut radiance = vec![0f32; w * h];
    let mut disparity = vec![f32::NAN; w * h];
    let fb = rig.focal_px * rig.baseline_m;
    for y in 0..h {
        for x in 0..w {
            let (fx, fy) = (x as f64, y as f64);
            if let Some((_, inv_z)) = trace(fx, fy) {
                disparity[y * w + x] = (fb * inv_z) as f32;
            }
            let mut sum = 0f32;
            for &oy in &offsets {
                for &ox in &offsets {
                    sum += trace(fx + ox, fy + oy).map_or(0.0, |(v, _)| v);
                }
            }
            radiance[y * w + x] = sum / (n * n) as f32;
        }
    }
    let blurred = gaussian_blur(&radiance, w, h, imaging.blur_sigma_px);
    let mut rng = Lcg::new(imaging.seed);
    let half_diagonal_sq = rig.principal_px[0].powi(2) + rig.principal_px[1].powi(2);
    let image = blurred
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let (dx, dy) = (
                (i % w) as f64 - rig.principal_px[0],
                (i / w) as f64 - rig.principal_px[1],
            );
            let r2 = ((dx * dx + dy * dy) / half_diagonal_sq) as f32;
            let v = v * (1.0 - imaging.vignetting * r2) * imaging.gain + imaging.offset;
            let noise = if imaging.noise_sigma > 0.0 {
                imaging.noise_sigma * rng.gaussian() as f32
            } else {
                0.0
            };
            (v + noise).round().clamp(0.0, 255.0) as u8
        })
        .collect();
    (image, disparity)
}

/// Separable Gaussian blur of standard deviation `sigma` pixels, edges clamped; `sigma <= 0`
/// returns the image unchanged.
pub fn gaussian_blur(image: &[f32], width: usize, height: usize, sigma: f64) -> Vec<f32> {
    if sigma <= 0.0 {
        return image.to_vec();
    }
    let radius = (3.0 * sigma).ceil() as i64;
    let mut kernel: Vec<f32> = (-radius..=radius)
        .map(|k| (-(k * k) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let total: f32 = kernel.iter().sum();
    kernel.iter_mut().for_each(|k| *k /= total);
    let pass = |src: &[f32], along_x: bool| -> Vec<f32> {
        let mut out = vec![0f32; src.len()];
        for y in 0..height as i64 {
            for x in 0..width as i64 {
                let mut acc = 0f32;
                for (j, k) in kernel.iter().enumerate() {
                    let o = j as i64 - radius;
                    let (sx, sy) = if along_x {
                        ((x + o).clamp(0, width as i64 - 1), y)
                    } else {
                        (x, (y + o).clamp(0, height as i64 - 1))
                    };
                    acc += k * src[sy as usize * width + sx as usize];
                }
                out[y as usize * width + x as usize] = acc;
            }
        }
        out
    };
    pass(&pass(image, true), false)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_right_image_is_the_left_shifted_by_the_disparity() {
        let (w, h) = (120, 40);
        let mut rng = Lcg::new(3);
        let back = Layer {
            disparity: [5.0, 0.0, 0.0],
            extent: [0.0, 0.0, w as f32, h as f32],
            texture: rectangles(w, h, 60, [3, 12], &mut rng),
        };
        let front = Layer {
            disparity: [12.0, 0.0, 0.0],
            extent: [40.0, 10.0, 80.0, 30.0],
            texture: rectangles(w, h, 60, [3, 12], &mut rng),
        };
        let (left, right, truth) = render(w, h, &[back, front]);
        let mut checked = 0;
        for y in 0..h {
            for x in 20..w {
                let d = truth[y * w + x];
                let xr = x as f32 - d;
                // Visible in the right image unless hidden by the front layer.
                let hidden =
                    d < 12.0 && (40.0..80.0).contains(&(xr + 12.0)) && (10..30).contains(&y);
                if !hidden {
                    assert_eq!(left[y * w + x], right[y * w + xr as usize], "({x}, {y})");
                    checked += 1;
                }
            }
        }
        assert!(checked > 3000, "{checked}");
    }

    fn fronto_parallel_scene(depth_m: f64) -> Vec<Panel> {
        let (w, h) = (64, 48);
        let mut rng = Lcg::new(9);
        let texture = std::sync::Arc::new(Texture::from_gray(
            w,
            h,
            &rectangles(w, h, 40, [2, 9], &mut rng),
        ));
        vec![Panel::new(
            [0.0, 0.0, depth_m],
            [3.0, 2.0],
            plane_axes(0.0, 0.0, 0.0),
            texture,
        )
        .repeated([4.0, 3.0])]
    }

    #[test]
    fn a_fronto_parallel_panel_is_shifted_by_its_disparity() {
        // f B = 10 px m: at 1 m the disparity is exactly 10 px.
        let rig = Rig::new(160, 90, 200.0, 0.05);
        let panels = fronto_parallel_scene(1.0);
        let ideal = Imaging::ideal();
        let pair = render_rig(&rig, &panels, [&ideal, &ideal]);
        let w = rig.width;
        for y in 0..rig.height {
            for x in 10..w {
                let i = y * w + x;
                assert!((pair.disparity_left[i] - 10.0).abs() < 1e-4, "({x}, {y})");
                assert!((pair.disparity_right[i - 10] - 10.0).abs() < 1e-4);
                assert_eq!(pair.left[i], pair.right[i - 10], "({x}, {y})");
            }
        }
    }

    #[test]
    fn the_two_views_agree_on_slanted_panels_and_occlusions() {
        let rig = Rig::new(200, 120, 220.0, 0.06);
        let mut panels = fronto_parallel_scene(2.0);
        let front = Panel::new(
            [0.05, 0.0, 0.8],
            [0.3, 0.25],
            plane_axes(30.0, -15.0, 5.0),
            panels[0].texture.clone(),
        );
        panels.push(front);
        let ideal = Imaging::ideal();
        let pair = render_rig(&rig, &panels, [&ideal, &ideal]);
        let w = rig.width;
        let (mut consistent, mut occluded, mut photometric) = (0, 0, 0f64);
        for y in 0..rig.height {
            for x in 0..w {
                let d = pair.disparity_left[y * w + x];
                let xr = (x as f32 - d).round();
                let at_edge = x == 0
                    || x + 1 == w
                    || (pair.disparity_left[y * w + x - 1] - d).abs() > 1.0
                    || (pair.disparity_left[y * w + x + 1] - d).abs() > 1.0;
                if xr < 1.0 || at_edge {
                    continue; // rounding xr may step off a panel at its edges
                }
                let dr = pair.disparity_right[y * w + xr as usize];
                if (dr - d).abs() <= 0.6 {
                    consistent += 1;
                    photometric += (f64::from(pair.left[y * w + x])
                        - f64::from(pair.right[y * w + xr as usize]))
                    .abs();
                } else {
                    // Occluded: the right camera sees something nearer there.
                    assert!(dr > d, "({x}, {y}): {d} vs {dr}");
                    occluded += 1;
                }
            }
        }
        assert!(occluded > 50, "{occluded}");
        // Rounding xr moves up to half a pixel: the texture differs a little.
        let mean = photometric / consistent as f64;
        assert!(mean < 12.0, "{mean}");
        // The panel's depth range: 30 degrees of yaw over 0.3 m.
        let front_d: Vec<f32> = pair
            .disparity_left
            .iter()
            .copied()
            .filter(|&d| d > 10.0)
            .collect();
        let (lo, hi) = front_d
            .iter()
            .fold((f32::MAX, f32::MIN), |(a, b), &d| (a.min(d), b.max(d)));
        assert!(lo > 13.0 && hi < 20.0 && hi - lo > 2.0, "{lo}..{hi}");
    }

    #[test]
    fn imaging_adds_noise_of_the_asked_sigma() {
        let rig = Rig::new(120, 80, 200.0, 0.05);
        let panels = fronto_parallel_scene(1.0);
        let noisy = Imaging {
            noise_sigma: 2.0,
            seed: 4,
            ..Imaging::ideal()
        };
        let clean = render_rig(&rig, &panels, [&Imaging::ideal(), &Imaging::ideal()]);
        let with_noise = render_rig(&rig, &panels, [&noisy, &noisy]);
        let n = clean.left.len() as f64;
        let var = clean
            .left
            .iter()
            .zip(&with_noise.left)
            .map(|(&a, &b)| (f64::from(a) - f64::from(b)).powi(2))
            .sum::<f64>()
            / n;
        assert!((var.sqrt() - 2.0).abs() < 0.2, "{}", var.sqrt());
        assert_ne!(with_noise.left, with_noise.right);
    }
}
