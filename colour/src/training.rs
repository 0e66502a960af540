//! The trainer's aid: read an image file, report the levels at a pixel (text or JSON), and render
//! the whole image in the 27 level colours so a trainer sees what the wearer will feel.

use std::io::Write;
use std::path::{Path, PathBuf};

use thiserror::Error;
use videt_hal::RgbFrame;

use crate::level::{level_colour, Level};
use crate::quantize::QuantizerConfig;
use crate::reader::{ColourReader, ColourReading, ReaderConfigError};
use crate::sample::{SampleError, SamplerConfig};

/// Largest image accepted, pixels per side.
pub const MAX_IMAGE_SIDE_PX: u32 = 16_384;

/// What went wrong with an image file.
#[derive(Debug, Error)]
pub enum ImageFileError {
    /// The file could not be read.
    #[error("cannot read image {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not an image this tool understands (PNG, JPEG, PPM/PGM/PAM).
    #[error("cannot decode image {path}: {reason}")]
    Decode {
        /// The file.
        path: PathBuf,
        /// The decoder's reason.
        reason: String,
    },
    /// The image has a size the tool does not accept.
    #[error("image {path} is {width}x{height}; allowed: 1..={max} pixels per side", max = MAX_IMAGE_SIDE_PX)]
    Size {
        /// The file.
        path: PathBuf,
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
    /// The output could not be written.
    #[error("cannot write {path}: {reason}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
}

/// Load an image file (PNG, JPEG, PPM/PGM/PAM; format from the content) as 8-bit RGB.
pub fn load_rgb(path: &Path) -> Result<RgbFrame, ImageFileError> {
    let bytes = std::fs::read(path).map_err(|source| ImageFileError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    decode_rgb(bytes, path)
}

/// Decode an image held in memory (e.g. one built into the binary); `name` appears in errors.
pub fn decode_rgb(bytes: Vec<u8>, name: &Path) -> Result<RgbFrame, ImageFileError> {
    let path = name;
    let decoded = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| ImageFileError::Decode {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?
        .decode()
        .map_err(|e| ImageFileError::Decode {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
    let (width, height) = (decoded.width(), decoded.height());
    if width == 0 || height == 0 || width > MAX_IMAGE_SIDE_PX || height > MAX_IMAGE_SIDE_PX {
        return Err(ImageFileError::Size {
            path: path.to_path_buf(),
            width,
            height,
        });
    }
    Ok(RgbFrame {
        width,
        height,
        data: decoded.into_rgb8().into_raw(),
    })
}

/// The reading at image pixel `(u_px, v_px)` (memoryless: one sample, no hysteresis history).
pub fn reading_at(
    frame: &RgbFrame,
    u_px: f64,
    v_px: f64,
    sampler: SamplerConfig,
    quantizer: QuantizerConfig,
) -> Result<ColourReading, ReadingError> {
    let mut reader = ColourReader::new(sampler, quantizer)?;
    Ok(reader.read_pixel(frame, u_px, v_px)?)
}

/// Why a reading failed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ReadingError {
    /// Bad window or quantizer settings.
    #[error(transparent)]
    Config(#[from] ReaderConfigError),
    /// Bad frame or point.
    #[error(transparent)]
    Sample(#[from] SampleError),
}

/// `{"rgb": [r, g, b], "levels": ["low"|"mid"|"high", x3]}`, exactly.
pub fn reading_json(reading: &ColourReading) -> String {
    let [r, g, b] = reading.rgb;
    let [lr, lg, lb] = reading.levels.map(Level::as_str);
    format!(r#"{{"rgb": [{r}, {g}, {b}], "levels": ["{lr}", "{lg}", "{lb}"]}}"#)
}

/// `rgb 210 40 52 -> levels high low low (HLL)`.
pub fn reading_text(reading: &ColourReading) -> String {
    let [r, g, b] = reading.rgb;
    let [lr, lg, lb] = reading.levels.map(Level::as_str);
    let letters: String = reading.levels.iter().map(|l| l.letter()).collect();
    format!("rgb {r} {g} {b} -> levels {lr} {lg} {lb} ({letters})")
}

/// The image with every pixel replaced by the colour of its level triple (memoryless
/// classification of each pixel's window).
pub fn quantize_image(
    frame: &RgbFrame,
    sampler: SamplerConfig,
    quantizer: QuantizerConfig,
) -> Result<RgbFrame, ReadingError> {
    crate::sample::check_frame(frame)?;
    quantizer.validate().map_err(ReaderConfigError::Quantizer)?;
    let mut sample =
        crate::sample::WindowSampler::new(sampler).map_err(ReaderConfigError::Sampler)?;
    let mut data = Vec::with_capacity(frame.data.len());
    for v in 0..frame.height {
        for u in 0..frame.width {
            let rgb = sample.sample_pixel(frame, f64::from(u) + 0.5, f64::from(v) + 0.5)?;
            data.extend_from_slice(&level_colour(quantizer.classify(rgb)));
        }
    }
    Ok(RgbFrame {
        width: frame.width,
        height: frame.height,
        data,
    })
}

/// Write a frame as PNG atomically: a temporary file beside the target, fsync, rename.
pub fn write_png(frame: &RgbFrame, path: &Path) -> Result<(), ImageFileError> {
    let fail = |reason: String| ImageFileError::Write {
        path: path.to_path_buf(),
        reason,
    };
    crate::sample::check_frame(frame).map_err(|e| fail(e.to_string()))?;
    let mut encoded = Vec::new();
    image::codecs::png::PngEncoder::new(&mut encoded)
        .write_image_rgb(frame)
        .map_err(|e| fail(e.to_string()))?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .ok_or_else(|| fail("the path has no file name".into()))?;
    let tmp = dir.join(format!(".{}.tmp", name.to_string_lossy()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(&encoded)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(fail(e.to_string()));
    }
    Ok(())
}

trait WriteRgb {
    fn write_image_rgb(self, frame: &RgbFrame) -> image::ImageResult<()>;
}

impl<W: Write> WriteRgb for image::codecs::png::PngEncoder<W> {
    fn write_image_rgb(self, frame: &RgbFrame) -> image::ImageResult<()> {
        use image::ImageEncoder;
        self.write_image(
            &frame.data,
            frame.width,
            frame.height,
            image::ExtendedColorType::Rgb8,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_colour_frame() -> RgbFrame {
        // Left half saturated red, right half mid grey, 8x4.
        let mut data = Vec::new();
        for _v in 0..4 {
            for u in 0..8 {
                data.extend_from_slice(if u < 4 {
                    &[240, 20, 30]
                } else {
                    &[128, 128, 128]
                });
            }
        }
        RgbFrame {
            width: 8,
            height: 4,
            data,
        }
    }

    #[test]
    fn json_has_the_exact_shape() {
        let f = two_colour_frame();
        let r = reading_at(
            &f,
            1.0,
            1.0,
            SamplerConfig::default(),
            QuantizerConfig::default(),
        )
        .unwrap();
        assert_eq!(
            reading_json(&r),
            r#"{"rgb": [240, 20, 30], "levels": ["high", "low", "low"]}"#
        );
        assert_eq!(
            reading_text(&r),
            "rgb 240 20 30 -> levels high low low (HLL)"
        );
        let e = reading_at(
            &f,
            8.0,
            1.0,
            SamplerConfig::default(),
            QuantizerConfig::default(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("outside the 8x4 image"), "{e}");
    }

    #[test]
    fn quantized_image_round_trips_through_png() {
        let dir = tempfile::tempdir().unwrap();
        let f = two_colour_frame();
        let q = quantize_image(
            &f,
            SamplerConfig {
                window_px: 1,
                statistic: crate::WindowStatistic::Median,
            },
            QuantizerConfig::default(),
        )
        .unwrap();
        assert_eq!(&q.data[0..3], &[255, 0, 0]);
        assert_eq!(&q.data[3 * 7..3 * 8], &[128, 128, 128]);
        let path = dir.path().join("levels.png");
        write_png(&q, &path).unwrap();
        assert_eq!(load_rgb(&path).unwrap(), q);
        assert!(!dir.path().join(".levels.png.tmp").exists());
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig {
            rng_seed: proptest::test_runner::RngSeed::Fixed(0xB17E5),
            ..proptest::prelude::ProptestConfig::with_cases(300)
        })]

        /// Arbitrary bytes, and PPM headers with arbitrary sizes and truncated bodies, decode to
        /// an error or a consistent frame; never a panic.
        #[test]
        fn arbitrary_bytes_never_panic(
            body in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..200),
            w in 0u32..70_000, h in 0u32..70_000, ppm in proptest::prelude::any::<bool>(),
        ) {
            let mut bytes = if ppm { format!("P6\n{w} {h}\n255\n").into_bytes() } else { Vec::new() };
            bytes.extend_from_slice(&body);
            if let Ok(f) = decode_rgb(bytes, Path::new("fuzz")) {
                proptest::prop_assert!(crate::sample::check_frame(&f).is_ok());
            }
        }
    }

    #[test]
    fn bad_files_give_clear_errors() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("nope.png");
        let e = load_rgb(&missing).unwrap_err();
        assert!(e.to_string().starts_with("cannot read image"), "{e}");
        let junk = dir.path().join("junk.png");
        std::fs::write(&junk, b"not an image at all").unwrap();
        let e = load_rgb(&junk).unwrap_err();
        assert!(e.to_string().starts_with("cannot decode image"), "{e}");
        let truncated = dir.path().join("short.ppm");
        std::fs::write(&truncated, b"P6\n4 4\n255\n\x01\x02").unwrap();
        assert!(matches!(
            load_rgb(&truncated),
            Err(ImageFileError::Decode { .. })
        ));
        let e = write_png(&two_colour_frame(), &dir.path().join("no/such/dir/x.png")).unwrap_err();
        assert!(e.to_string().starts_with("cannot write"), "{e}");
    }
}
