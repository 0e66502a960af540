//! Sampling the colour under the thimble: the thimble's workspace `(x, y)` goes through the
//! [`SceneMap`] (the same mapping the bas-relief uses) to a left-image pixel, and the colour is the
//! mean or median of a small square window around it, clipped at the image borders.
//!
//! Allocation-free after construction: the median works in a scratch buffer sized for the largest
//! window when the sampler is built.

use thiserror::Error;
use videt_control::SceneMap;
use videt_hal::RgbFrame;

/// Largest allowed window side, pixels.
pub const MAX_WINDOW_PX: u32 = 31;

/// How the window's pixels are combined into one colour (per channel).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WindowStatistic {
    /// Rounded mean: smooth, but a thin edge in the window mixes two colours.
    Mean,
    /// Median: keeps the majority colour at an edge and ignores speckle.
    Median,
}

/// Window size and statistic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SamplerConfig {
    /// Side of the square window, pixels: odd, `1..=MAX_WINDOW_PX`.
    pub window_px: u32,
    /// How the window is combined.
    pub statistic: WindowStatistic,
}

impl Default for SamplerConfig {
    /// A 7x7 median (about 1.5 % of a 450-pixel-wide image: a fingertip's share of the relief).
    fn default() -> Self {
        SamplerConfig {
            window_px: 7,
            statistic: WindowStatistic::Median,
        }
    }
}

/// Why a sample could not be taken.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SampleError {
    /// The window size is not allowed.
    #[error("colour sampler: window_px = {window_px} is invalid; allowed: odd, 1..={max}", max = MAX_WINDOW_PX)]
    BadWindow {
        /// The rejected size.
        window_px: u32,
    },
    /// The frame's buffer does not match its size.
    #[error("colour frame: {width}x{height} needs {expected} bytes of RGB, has {actual}")]
    BadFrame {
        /// Frame width.
        width: u32,
        /// Frame height.
        height: u32,
        /// `3 * width * height`.
        expected: u64,
        /// `data.len()`.
        actual: u64,
    },
    /// The point lies outside the image (or is not finite).
    #[error("point ({u_px}, {v_px}) px is outside the {width}x{height} image (allowed: 0 <= u < {width}, 0 <= v < {height})")]
    OutsideImage {
        /// Column, pixels.
        u_px: f64,
        /// Row, pixels.
        v_px: f64,
        /// Image width.
        width: u32,
        /// Image height.
        height: u32,
    },
}

/// Samples the colour of a window; holds its scratch buffer.
#[derive(Debug, Clone)]
pub struct WindowSampler {
    config: SamplerConfig,
    scratch: Vec<u8>,
}

/// Check that a frame's buffer matches its size (`3 * width * height` bytes, non-empty).
pub fn check_frame(frame: &RgbFrame) -> Result<(), SampleError> {
    let expected = 3 * u64::from(frame.width) * u64::from(frame.height);
    if expected == 0 || frame.data.len() as u64 != expected {
        return Err(SampleError::BadFrame {
            width: frame.width,
            height: frame.height,
            expected,
            actual: frame.data.len() as u64,
        });
    }
    Ok(())
}

impl WindowSampler {
    /// A sampler; allocates its scratch buffer once, here.
    pub fn new(config: SamplerConfig) -> Result<WindowSampler, SampleError> {
        if config.window_px.is_multiple_of(2)
            || config.window_px == 0
            || config.window_px > MAX_WINDOW_PX
        {
            return Err(SampleError::BadWindow {
                window_px: config.window_px,
            });
        }
        let side = config.window_px as usize;
        Ok(WindowSampler {
            config,
            scratch: vec![0; side * side],
        })
    }

    /// Its configuration.
    pub fn config(&self) -> SamplerConfig {
        self.config
    }

    /// The colour of the window centred on image pixel `(u_px, v_px)` (continuous coordinates:
    /// pixel `(i, j)` covers `[i, i+1) x [j, j+1)`). The window is clipped at the borders.
    /// Allocation-free.
    pub fn sample_pixel(
        &mut self,
        frame: &RgbFrame,
        u_px: f64,
        v_px: f64,
    ) -> Result<[u8; 3], SampleError> {
        check_frame(frame)?;
        let (w, h) = (frame.width, frame.height);
        let inside = u_px.is_finite()
            && v_px.is_finite()
            && u_px >= 0.0
            && v_px >= 0.0
            && u_px < f64::from(w)
            && v_px < f64::from(h);
        if !inside {
            return Err(SampleError::OutsideImage {
                u_px,
                v_px,
                width: w,
                height: h,
            });
        }
        let (cu, cv) = (u_px as u32, v_px as u32);
        let half = self.config.window_px / 2;
        let (u0, u1) = (cu.saturating_sub(half), (cu + half).min(w - 1));
        let (v0, v1) = (cv.saturating_sub(half), (cv + half).min(h - 1));
        let row_stride = 3 * w as usize;
        let pixel_offset = |u: u32, v: u32| v as usize * row_stride + 3 * u as usize;
        let count = ((u1 - u0 + 1) * (v1 - v0 + 1)) as usize;
        let mut out = [0u8; 3];
        match self.config.statistic {
            WindowStatistic::Mean => {
                let mut sums = [0u32; 3];
                for v in v0..=v1 {
                    let row = &frame.data[pixel_offset(u0, v)..pixel_offset(u1, v) + 3];
                    for px in row.chunks_exact(3) {
                        for c in 0..3 {
                            sums[c] += u32::from(px[c]);
                        }
                    }
                }
                let n = count as u32;
                for c in 0..3 {
                    out[c] = ((sums[c] + n / 2) / n) as u8;
                }
            }
            WindowStatistic::Median => {
                for (c, slot) in out.iter_mut().enumerate() {
                    let mut k = 0;
                    for v in v0..=v1 {
                        let row = &frame.data[pixel_offset(u0, v)..pixel_offset(u1, v) + 3];
                        for px in row.chunks_exact(3) {
                            self.scratch[k] = px[c];
                            k += 1;
                        }
                    }
                    let values = &mut self.scratch[..count];
                    let (_, median, _) = values.select_nth_unstable(count / 2);
                    *slot = *median;
                }
            }
        }
        Ok(out)
    }

    /// The colour under the thimble at device `(x_m, y_m)`, through `map` (whose image size must
    /// be the frame's). Allocation-free.
    pub fn sample_workspace(
        &mut self,
        frame: &RgbFrame,
        map: &SceneMap,
        x_m: f64,
        y_m: f64,
    ) -> Result<[u8; 3], SampleError> {
        let [u, v] = map.workspace_to_image(x_m, y_m);
        // The map may have been built for another resolution: scale to this frame.
        let [map_w, map_h] = map.image_size_px();
        let u = u * f64::from(frame.width) / map_w;
        let v = v * f64::from(frame.height) / map_h;
        self.sample_pixel(frame, u, v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig {
            rng_seed: proptest::test_runner::RngSeed::Fixed(0x5A3E),
            ..ProptestConfig::with_cases(200)
        })]

        /// Any point inside any frame, any odd window: no panic, and each channel of the result
        /// lies between the smallest and largest value of the clipped window.
        #[test]
        fn window_statistics_stay_within_the_window(
            w in 1u32..12, h in 1u32..12, seed in any::<u64>(),
            fu in 0.0f64..1.0, fv in 0.0f64..1.0,
            half in 0u32..6, median in any::<bool>(),
        ) {
            let mut x = seed | 1;
            let data: Vec<u8> = (0..3 * w * h).map(|_| {
                x ^= x << 13; x ^= x >> 7; x ^= x << 17;
                (x >> 24) as u8
            }).collect();
            let frame = RgbFrame { width: w, height: h, data };
            let statistic = if median { WindowStatistic::Median } else { WindowStatistic::Mean };
            let mut s = WindowSampler::new(SamplerConfig { window_px: 2 * half + 1, statistic }).unwrap();
            let (u, v) = (fu * f64::from(w), fv * f64::from(h));
            let got = s.sample_pixel(&frame, u, v).unwrap();
            let (cu, cv) = (u as u32, v as u32);
            for c in 0..3 {
                let mut lo = 255u8;
                let mut hi = 0u8;
                for j in cv.saturating_sub(half)..=(cv + half).min(h - 1) {
                    for i in cu.saturating_sub(half)..=(cu + half).min(w - 1) {
                        let p = frame.data[(3 * (j * w + i)) as usize + c];
                        lo = lo.min(p);
                        hi = hi.max(p);
                    }
                }
                prop_assert!(lo <= got[c] && got[c] <= hi, "channel {c}: {} not in {lo}..={hi}", got[c]);
            }
        }
    }

    /// A 5x4 frame whose pixel (u, v) is (10u, 10v, 7).
    fn ramp() -> RgbFrame {
        let (w, h) = (5u32, 4u32);
        let mut data = Vec::new();
        for v in 0..h {
            for u in 0..w {
                data.extend_from_slice(&[10 * u as u8, 10 * v as u8, 7]);
            }
        }
        RgbFrame {
            width: w,
            height: h,
            data,
        }
    }

    #[test]
    fn single_pixel_and_clipped_windows() {
        let f = ramp();
        let mut one = WindowSampler::new(SamplerConfig {
            window_px: 1,
            statistic: WindowStatistic::Mean,
        })
        .unwrap();
        assert_eq!(one.sample_pixel(&f, 3.7, 2.2).unwrap(), [30, 20, 7]);
        let mut mean = WindowSampler::new(SamplerConfig {
            window_px: 3,
            statistic: WindowStatistic::Mean,
        })
        .unwrap();
        // Centre: mean of u 1..=3, v 0..=2.
        assert_eq!(mean.sample_pixel(&f, 2.5, 1.5).unwrap(), [20, 10, 7]);
        // Corner: clipped to u 0..=1, v 0..=1 -> mean 5 (rounded half up).
        assert_eq!(mean.sample_pixel(&f, 0.0, 0.0).unwrap(), [5, 5, 7]);
        // Opposite corner: u 3..=4, v 2..=3 -> 35, 25.
        assert_eq!(mean.sample_pixel(&f, 4.9, 3.9).unwrap(), [35, 25, 7]);
    }

    #[test]
    fn median_ignores_speckle_that_moves_the_mean() {
        let mut f = RgbFrame {
            width: 3,
            height: 3,
            data: [200u8, 10, 10].repeat(9),
        };
        f.data[12..15].copy_from_slice(&[0, 255, 255]); // centre pixel
        let mut med = WindowSampler::new(SamplerConfig {
            window_px: 3,
            statistic: WindowStatistic::Median,
        })
        .unwrap();
        let mut mean = WindowSampler::new(SamplerConfig {
            window_px: 3,
            statistic: WindowStatistic::Mean,
        })
        .unwrap();
        assert_eq!(med.sample_pixel(&f, 1.5, 1.5).unwrap(), [200, 10, 10]);
        assert_eq!(mean.sample_pixel(&f, 1.5, 1.5).unwrap(), [178, 37, 37]);
    }

    #[test]
    fn bad_windows_frames_and_points_are_errors() {
        for window_px in [0, 2, 33] {
            let e = WindowSampler::new(SamplerConfig {
                window_px,
                statistic: WindowStatistic::Mean,
            })
            .unwrap_err();
            assert!(e.to_string().contains("window_px"), "{e}");
        }
        let mut s = WindowSampler::new(SamplerConfig::default()).unwrap();
        let f = ramp();
        for (u, v) in [(-0.1, 1.0), (5.0, 1.0), (1.0, 4.0), (f64::NAN, 1.0)] {
            assert!(matches!(
                s.sample_pixel(&f, u, v),
                Err(SampleError::OutsideImage { .. })
            ));
        }
        let mut short = f.clone();
        short.data.pop();
        let e = s.sample_pixel(&short, 1.0, 1.0).unwrap_err();
        assert!(e.to_string().contains("needs 60 bytes"), "{e}");
        assert!(s.sample_pixel(&RgbFrame::default(), 0.0, 0.0).is_err());
    }

    #[test]
    fn workspace_point_goes_through_the_scene_map() {
        let f = ramp();
        // 0.5 m x 0.4 m area over a 5x4 image: 0.1 m per pixel, origin bottom-left.
        let map = SceneMap::new([0.0, 0.0], [0.5, 0.4], [5, 4], 0.45, 0.08, [0.5, 5.0]).unwrap();
        let mut s = WindowSampler::new(SamplerConfig {
            window_px: 1,
            statistic: WindowStatistic::Median,
        })
        .unwrap();
        // x = 0.35 -> u = 3.5; y = 0.05 (near the bottom) -> v = 3.5.
        assert_eq!(
            s.sample_workspace(&f, &map, 0.35, 0.05).unwrap(),
            [30, 30, 7]
        );
        // Beyond the explored area: outside the image.
        assert!(s.sample_workspace(&f, &map, 0.6, 0.05).is_err());
    }
}
