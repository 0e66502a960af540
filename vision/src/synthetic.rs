//! Synthetic rectified pairs with known disparity, for tests and benchmarks: textured planar
//! layers (each `d = a + b x + c y` in left-image pixels), the nearer layer hiding the farther,
//! rendered into a left and a right image (the left pixel at x is the right pixel at x - d).

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
}
