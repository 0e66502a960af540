//! The colour under the thimble: sampling plus stateful quantization, the part the colour thread
//! runs for every new thimble position.

use videt_control::SceneMap;
use videt_hal::RgbFrame;

use crate::level::LevelTriple;
use crate::quantize::{Quantizer, QuantizerConfig, QuantizerConfigError};
use crate::sample::{SampleError, SamplerConfig, WindowSampler};

/// One reading: the sampled colour and the levels to render.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ColourReading {
    /// The window's colour, 8-bit RGB.
    pub rgb: [u8; 3],
    /// The level triple (after hysteresis).
    pub levels: LevelTriple,
}

/// Why a colour reader could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReaderConfigError {
    /// The sampler configuration.
    #[error(transparent)]
    Sampler(#[from] SampleError),
    /// The quantizer configuration.
    #[error(transparent)]
    Quantizer(#[from] QuantizerConfigError),
}

/// Sampler and quantizer together. Allocation-free per reading.
#[derive(Debug, Clone)]
pub struct ColourReader {
    sampler: WindowSampler,
    quantizer: Quantizer,
}

impl ColourReader {
    /// A reader with validated configurations.
    pub fn new(
        sampler: SamplerConfig,
        quantizer: QuantizerConfig,
    ) -> Result<ColourReader, ReaderConfigError> {
        Ok(ColourReader {
            sampler: WindowSampler::new(sampler)?,
            quantizer: Quantizer::new(quantizer)?,
        })
    }

    /// The reading at image pixel `(u_px, v_px)`. Outside the image the quantizer forgets its
    /// state (the next reading inside starts afresh) and the error is returned.
    pub fn read_pixel(
        &mut self,
        frame: &RgbFrame,
        u_px: f64,
        v_px: f64,
    ) -> Result<ColourReading, SampleError> {
        match self.sampler.sample_pixel(frame, u_px, v_px) {
            Ok(rgb) => Ok(ColourReading {
                rgb,
                levels: self.quantizer.update(rgb),
            }),
            Err(e) => {
                self.quantizer.reset();
                Err(e)
            }
        }
    }

    /// The reading under the thimble at device `(x_m, y_m)`.
    pub fn read_workspace(
        &mut self,
        frame: &RgbFrame,
        map: &SceneMap,
        x_m: f64,
        y_m: f64,
    ) -> Result<ColourReading, SampleError> {
        match self.sampler.sample_workspace(frame, map, x_m, y_m) {
            Ok(rgb) => Ok(ColourReading {
                rgb,
                levels: self.quantizer.update(rgb),
            }),
            Err(e) => {
                self.quantizer.reset();
                Err(e)
            }
        }
    }
}
