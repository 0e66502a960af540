//! Quantization of an RGB sample to a Low/Mid/High triple, in plain RGB or in a
//! brightness-normalised chromaticity space, with hysteresis so that a finger resting on a level
//! boundary does not make the vibration flicker.
//!
//! Both spaces produce three *feature* values on the 0..=255 scale that are compared with the same
//! two thresholds:
//! - [`ColourSpace::Rgb`]: the features are the channel values themselves.
//! - [`ColourSpace::Chromaticity`]: each channel's share of the brightest channel (`c_i = ch_i /
//!   max`, independent of illumination intensity) times a brightness `max` stretched from
//!   `[black_level, white_level]` onto `[0, 255]`. Shading and an under-exposed camera then change
//!   the hue's levels far less than in plain RGB, while black, grey and white stay apart.
//!
//! Default: chromaticity, because it classified the hand-labelled real-image patches better
//! (see `tests/real_patches.rs` and the crate documentation for the measured figures).

use thiserror::Error;

use crate::level::{Level, LevelTriple};

/// A rejected quantizer configuration: the field, its value and what is allowed.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("colour quantizer: {field} = {value} is invalid; allowed: {allowed}")]
pub struct QuantizerConfigError {
    /// The offending field.
    pub field: &'static str,
    /// Its value.
    pub value: f32,
    /// What is allowed.
    pub allowed: &'static str,
}

/// The space the thresholds apply in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ColourSpace {
    /// The camera's RGB values as they are.
    Rgb,
    /// Chromaticity (channel / brightest channel) times the brightness stretched from
    /// `[black_level, white_level]` (8-bit values of the brightest channel) onto `[0, 255]`.
    Chromaticity {
        /// Brightest-channel value at and below which everything is black.
        black_level: f32,
        /// Brightest-channel value at and above which the brightness is full.
        white_level: f32,
    },
}

impl ColourSpace {
    /// The chromaticity space with its default stretch: black at 32, full brightness at 192.
    /// These values were fixed before measuring on the labelled patches (a camera that exposes a
    /// white sheet at about 200 and leaves shadows under 32), not fitted to them.
    pub const CHROMATICITY_DEFAULT: ColourSpace = ColourSpace::Chromaticity {
        black_level: 32.0,
        white_level: 192.0,
    };

    /// The three feature values (0..=255 scale) of an RGB sample in this space.
    pub fn features(self, rgb: [u8; 3]) -> [f32; 3] {
        let values = rgb.map(f32::from);
        match self {
            ColourSpace::Rgb => values,
            ColourSpace::Chromaticity {
                black_level,
                white_level,
            } => {
                let brightest = values[0].max(values[1]).max(values[2]);
                if brightest <= black_level || brightest <= 0.0 {
                    return [0.0; 3];
                }
                let brightness =
                    ((brightest - black_level) / (white_level - black_level)).clamp(0.0, 1.0);
                values.map(|v| v / brightest * brightness * 255.0)
            }
        }
    }
}

/// Thresholds, hysteresis and space of the quantizer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuantizerConfig {
    /// The space the thresholds apply in.
    pub space: ColourSpace,
    /// Feature value (0..=255) from which a channel is Mid rather than Low.
    pub low_mid: f32,
    /// Feature value (0..=255) from which a channel is High rather than Mid.
    pub mid_high: f32,
    /// Half-width of the dead band around each threshold (feature units): the level changes only
    /// when the value lies beyond the threshold by more than this.
    pub hysteresis: f32,
}

impl Default for QuantizerConfig {
    /// Chromaticity space, thresholds at thirds of the range (85, 170), hysteresis 8.
    fn default() -> Self {
        QuantizerConfig {
            space: ColourSpace::CHROMATICITY_DEFAULT,
            low_mid: 85.0,
            mid_high: 170.0,
            hysteresis: 8.0,
        }
    }
}

impl QuantizerConfig {
    /// The same thresholds applied to plain RGB.
    pub fn plain_rgb() -> Self {
        QuantizerConfig {
            space: ColourSpace::Rgb,
            ..QuantizerConfig::default()
        }
    }

    /// Check every field; the error names the field, its value and the allowed range.
    pub fn validate(&self) -> Result<(), QuantizerConfigError> {
        let err = |field, value, allowed| {
            Err(QuantizerConfigError {
                field,
                value,
                allowed,
            })
        };
        if !(self.low_mid > 0.0 && self.low_mid < 255.0) {
            return err("low_mid", self.low_mid, "0 < low_mid < 255");
        }
        if !(self.mid_high > self.low_mid && self.mid_high <= 255.0) {
            return err("mid_high", self.mid_high, "low_mid < mid_high <= 255");
        }
        let max_band = (self.mid_high - self.low_mid) / 2.0;
        if !(self.hysteresis >= 0.0 && self.hysteresis < max_band) {
            return err(
                "hysteresis",
                self.hysteresis,
                "0 <= hysteresis < (mid_high - low_mid) / 2",
            );
        }
        if let ColourSpace::Chromaticity {
            black_level,
            white_level,
        } = self.space
        {
            if !(0.0..255.0).contains(&black_level) {
                return err("black_level", black_level, "0 <= black_level < 255");
            }
            if !(white_level > black_level && white_level <= 255.0) {
                return err(
                    "white_level",
                    white_level,
                    "black_level < white_level <= 255",
                );
            }
        }
        Ok(())
    }

    /// The level of one feature value without hysteresis.
    pub fn level_of(&self, feature: f32) -> Level {
        if feature >= self.mid_high {
            Level::High
        } else if feature >= self.low_mid {
            Level::Mid
        } else {
            Level::Low
        }
    }

    /// The level triple of an RGB sample without hysteresis (memoryless).
    pub fn classify(&self, rgb: [u8; 3]) -> LevelTriple {
        self.space.features(rgb).map(|f| self.level_of(f))
    }

    /// The level a channel holds next, given its current level: it stays while the feature lies
    /// within the current level's interval widened by `hysteresis` on both sides.
    fn next_level(&self, current: Level, feature: f32) -> Level {
        let h = self.hysteresis;
        let stays = match current {
            Level::Low => feature < self.low_mid + h,
            Level::Mid => feature >= self.low_mid - h && feature < self.mid_high + h,
            Level::High => feature >= self.mid_high - h,
        };
        if stays {
            current
        } else {
            self.level_of(feature)
        }
    }
}

/// A stateful quantizer: memoryless for the first sample, with hysteresis afterwards.
/// Allocation-free; `update` is safe to call every cycle.
#[derive(Debug, Clone)]
pub struct Quantizer {
    config: QuantizerConfig,
    current: Option<LevelTriple>,
}

impl Quantizer {
    /// A quantizer with a validated configuration.
    pub fn new(config: QuantizerConfig) -> Result<Quantizer, QuantizerConfigError> {
        config.validate()?;
        Ok(Quantizer {
            config,
            current: None,
        })
    }

    /// Its configuration.
    pub fn config(&self) -> &QuantizerConfig {
        &self.config
    }

    /// The current triple (`None` before the first sample or after [`Quantizer::reset`]).
    pub fn levels(&self) -> Option<LevelTriple> {
        self.current
    }

    /// Forget the state (e.g. the finger left the image): the next sample is classified afresh.
    pub fn reset(&mut self) {
        self.current = None;
    }

    /// Feed one sample; returns the triple to render.
    pub fn update(&mut self, rgb: [u8; 3]) -> LevelTriple {
        let features = self.config.space.features(rgb);
        let next = match self.current {
            None => features.map(|f| self.config.level_of(f)),
            Some(current) => {
                let mut next = current;
                for ((slot, &level), &feature) in next.iter_mut().zip(&current).zip(&features) {
                    *slot = self.config.next_level(level, feature);
                }
                next
            }
        };
        self.current = Some(next);
        next
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use Level::{High as H, Low as L, Mid as M};

    #[test]
    fn saturated_dark_and_grey_colours_in_both_spaces() {
        for cfg in [QuantizerConfig::plain_rgb(), QuantizerConfig::default()] {
            assert_eq!(cfg.classify([255, 0, 0]), [H, L, L], "{cfg:?}");
            assert_eq!(cfg.classify([0, 255, 0]), [L, H, L]);
            assert_eq!(cfg.classify([0, 0, 255]), [L, L, H]);
            assert_eq!(cfg.classify([255, 255, 0]), [H, H, L]);
            assert_eq!(cfg.classify([255, 255, 255]), [H, H, H]);
            assert_eq!(cfg.classify([0, 0, 0]), [L, L, L]);
            assert_eq!(cfg.classify([10, 20, 15]), [L, L, L], "dark is black");
            assert_eq!(cfg.classify([128, 128, 128]), [M, M, M], "mid grey");
        }
    }

    #[test]
    fn chromaticity_keeps_the_hue_of_a_shaded_surface() {
        let cfg = QuantizerConfig::default();
        let plain = QuantizerConfig::plain_rgb();
        // A red surface lit and in half shade: plain RGB drops to dark red, chromaticity keeps red
        // while brightness stays above the white level.
        assert_eq!(cfg.classify([230, 40, 50]), [H, L, L]);
        assert_eq!(cfg.classify([200, 35, 44]), [H, L, L]);
        assert_eq!(plain.classify([160, 28, 35]), [M, L, L]);
        // Grey stays grey, not white: the brightness carries into every channel.
        assert_eq!(cfg.classify([100, 100, 100]), [M, M, M]);
    }

    #[test]
    fn invalid_configurations_name_the_field() {
        for (bad, field) in [
            (
                QuantizerConfig {
                    mid_high: 80.0,
                    ..QuantizerConfig::default()
                },
                "mid_high",
            ),
            (
                QuantizerConfig {
                    hysteresis: 50.0,
                    ..QuantizerConfig::default()
                },
                "hysteresis",
            ),
            (
                QuantizerConfig {
                    low_mid: f32::NAN,
                    ..QuantizerConfig::default()
                },
                "low_mid",
            ),
        ] {
            assert_eq!(bad.validate().unwrap_err().field, field);
        }
        let c = QuantizerConfig {
            space: ColourSpace::Chromaticity {
                black_level: 100.0,
                white_level: 90.0,
            },
            ..QuantizerConfig::default()
        };
        let e = c.validate().unwrap_err();
        assert_eq!(e.field, "white_level");
        assert!(e.to_string().contains("white_level = 90"), "{e}");
        assert!(Quantizer::new(c).is_err());
    }

    #[test]
    fn a_value_wobbling_within_the_band_does_not_flicker() {
        let mut q = Quantizer::new(QuantizerConfig::plain_rgb()).unwrap();
        assert_eq!(q.update([80, 0, 0])[0], L);
        // 85 is the threshold, hysteresis 8: 80..=92 never leaves Low once in Low.
        for i in 0..200u32 {
            let wobble = 80 + (i * 7 % 13) as u8; // 80..=92
            assert_eq!(q.update([wobble, 0, 0])[0], L, "sample {i} = {wobble}");
        }
        // Clearly beyond the band: changes.
        assert_eq!(q.update([94, 0, 0])[0], M);
        // Back within the band on the other side: stays Mid down to 77.
        for v in [90, 84, 80, 77] {
            assert_eq!(q.update([v, 0, 0])[0], M, "{v}");
        }
        assert_eq!(q.update([76, 0, 0])[0], L);
        // Without hysteresis the same wobble flickers (the test above can fail).
        let mut raw = Quantizer::new(QuantizerConfig {
            hysteresis: 0.0,
            ..QuantizerConfig::plain_rgb()
        })
        .unwrap();
        let changes = (0..200u32)
            .map(|i| raw.update([80 + (i * 7 % 13) as u8, 0, 0])[0])
            .collect::<Vec<_>>()
            .windows(2)
            .filter(|w| w[0] != w[1])
            .count();
        assert!(changes > 20, "{changes}");
    }

    #[test]
    fn a_large_jump_skips_the_middle_level() {
        let mut q = Quantizer::new(QuantizerConfig::plain_rgb()).unwrap();
        assert_eq!(q.update([0, 255, 128]), [L, H, M]);
        assert_eq!(q.update([255, 0, 128]), [H, L, M]);
        q.reset();
        assert_eq!(q.levels(), None);
        assert_eq!(q.update([100, 100, 100]), [M, M, M]);
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            rng_seed: proptest::test_runner::RngSeed::Fixed(0x0C01_0A12),
            ..ProptestConfig::with_cases(256)
        })]

        /// Hysteresis only ever keeps a level that the raw classification would leave when the
        /// value lies inside a dead band; outside every band the result equals the memoryless one.
        #[test]
        fn hysteresis_differs_from_memoryless_only_inside_a_band(
            samples in proptest::collection::vec(any::<[u8; 3]>(), 1..40),
            chroma in any::<bool>(),
        ) {
            let cfg = if chroma { QuantizerConfig::default() } else { QuantizerConfig::plain_rgb() };
            let mut q = Quantizer::new(cfg).unwrap();
            for rgb in samples {
                let got = q.update(rgb);
                let raw = cfg.classify(rgb);
                let features = cfg.space.features(rgb);
                for c in 0..3 {
                    if got[c] != raw[c] {
                        let f = features[c];
                        let near = (f - cfg.low_mid).abs() <= cfg.hysteresis
                            || (f - cfg.mid_high).abs() <= cfg.hysteresis;
                        prop_assert!(near, "channel {c}: {got:?} vs {raw:?} at {f}");
                        prop_assert!((got[c] as i8 - raw[c] as i8).abs() == 1);
                    }
                }
            }
        }
    }
}
