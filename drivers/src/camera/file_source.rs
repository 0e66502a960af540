//! A stereo "camera" reading image pairs from a folder (PNG, PGM/PPM, JPEG): the twin's and the
//! demo's camera. Pairs are files whose names contain `left` and the same name with `right`
//! (`left03.jpg`/`right03.jpg`, `left.ppm`/`right.ppm`), in name order, played in a loop.
//!
//! It runs like a free-running camera: a frame is exposed every frame period on
//! `CLOCK_MONOTONIC` (the clock V4L2 stamps buffers with), [`StereoCamera::capture`] blocks
//! until the next one and stamps it with its exposure time, and a reader that comes late gets
//! the newest exposed frame (the older ones are overwritten, as in a camera's single-buffer
//! mode). Each file is decoded once, on its first delivery, and kept: from the second loop on a
//! capture costs what a camera's does (a copy), not a JPEG decode.

use std::path::{Path, PathBuf};
use std::time::Duration;

use videt_hal::{MonoTime, StereoCamera, StereoFrame};

use super::CameraError;

const EXTENSIONS: [&str; 6] = ["png", "pgm", "ppm", "pnm", "jpg", "jpeg"];

/// Decoded pairs kept at most (a larger folder decodes the others on every delivery).
const MAX_CACHED_PAIRS: usize = 64;

/// Stereo pairs from image files.
#[derive(Debug, Clone)]
pub struct FileStereoSource {
    pairs: Vec<(PathBuf, PathBuf)>,
    decoded: Vec<Option<StereoFrame>>,
    next: usize,
    frame_period_ns: u64,
    /// Exposure time of the last frame delivered (`None` before the first).
    last_exposure: Option<MonoTime>,
    with_colour: bool,
    paced: bool,
}

/// `CLOCK_MONOTONIC` now.
pub fn monotonic_now() -> MonoTime {
    let d = nix::time::clock_gettime(nix::time::ClockId::CLOCK_MONOTONIC)
        .map(Duration::from)
        .unwrap_or_default();
    MonoTime(d.as_nanos() as u64)
}

impl FileStereoSource {
    /// The pairs of `dir`, one exposed every `frame_period`.
    pub fn from_folder(
        dir: &Path,
        frame_period: core::time::Duration,
    ) -> Result<Self, CameraError> {
        let io = |source| CameraError::Io {
            path: dir.to_path_buf(),
            source,
        };
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(io)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.extension()
                    .and_then(|e| e.to_str())
                    .is_some_and(|e| EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
            })
            .collect();
        files.sort();
        let mut pairs = Vec::new();
        for left in &files {
            let Some(name) = left.file_name().and_then(|n| n.to_str()) else {
                continue;
            };
            if !name.contains("left") {
                continue;
            }
            let right = left.with_file_name(name.replacen("left", "right", 1));
            if files.contains(&right) {
                pairs.push((left.clone(), right));
            }
        }
        if pairs.is_empty() {
            return Err(CameraError::NoPairs {
                dir: dir.to_path_buf(),
            });
        }
        Ok(Self::from_pairs(pairs, frame_period))
    }

    /// Explicit pairs (left, right).
    pub fn from_pairs(pairs: Vec<(PathBuf, PathBuf)>, frame_period: core::time::Duration) -> Self {
        FileStereoSource {
            decoded: vec![None; pairs.len().min(MAX_CACHED_PAIRS)],
            pairs,
            next: 0,
            frame_period_ns: (frame_period.as_nanos() as u64).max(1),
            last_exposure: None,
            with_colour: true,
            paced: true,
        }
    }

    /// Deliver at once instead of waiting for the next frame period (tools that read a
    /// folder as fast as they can); stamps stay `frame_period` apart.
    pub fn unpaced(mut self) -> Self {
        self.paced = false;
        self
    }

    /// Deliver the left image in colour too (default on).
    pub fn with_colour(mut self, on: bool) -> Self {
        self.with_colour = on;
        self
    }

    /// The pairs, in delivery order.
    pub fn pairs(&self) -> &[(PathBuf, PathBuf)] {
        &self.pairs
    }
}

fn load(path: &Path) -> Result<image::DynamicImage, CameraError> {
    image::ImageReader::open(path)
        .map_err(|source| CameraError::Io {
            path: path.to_path_buf(),
            source,
        })?
        .with_guessed_format()
        .map_err(|source| CameraError::Io {
            path: path.to_path_buf(),
            source,
        })?
        .decode()
        .map_err(|e| CameraError::Decode {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })
}

impl FileStereoSource {
    /// Waits for the next exposure (paced) and returns its time: one frame period after the
    /// last delivered one, or the newest exposure when the reader came late.
    fn next_exposure(&mut self) -> MonoTime {
        let period = self.frame_period_ns;
        let Some(last) = self.last_exposure else {
            return monotonic_now();
        };
        let due = last.add_nanos(period);
        if !self.paced {
            return due;
        }
        let now = monotonic_now();
        if now < due {
            std::thread::sleep(Duration::from_nanos(due.0 - now.0));
            return due;
        }
        // Late: the newest frame exposed by now.
        due.add_nanos((now.0 - due.0) / period * period)
    }
}

/// Decodes a pair of files (the left one in colour too when asked and coloured).
fn decode_pair(
    (left_path, right_path): &(PathBuf, PathBuf),
    with_colour: bool,
) -> Result<StereoFrame, CameraError> {
    let left = load(left_path)?;
    let right = load(right_path)?;
    if (left.width(), left.height()) != (right.width(), right.height()) {
        return Err(CameraError::SizeMismatch {
            left_w: left.width(),
            left_h: left.height(),
            right_w: right.width(),
            right_h: right.height(),
        });
    }
    let mut frame = StereoFrame::default();
    for (img, f) in [(&left, &mut frame.left), (&right, &mut frame.right)] {
        let grey = img.to_luma8();
        f.width = grey.width();
        f.height = grey.height();
        f.data = grey.into_raw();
    }
    if with_colour && left.color().has_color() {
        let rgb = left.to_rgb8();
        frame.left_rgb = Some(videt_hal::RgbFrame {
            width: rgb.width(),
            height: rgb.height(),
            data: rgb.into_raw(),
        });
    }
    Ok(frame)
}

impl videt_hal::ErrorType for FileStereoSource {
    type Error = CameraError;
}

impl StereoCamera for FileStereoSource {
    fn capture(&mut self, out: &mut StereoFrame) -> Result<(), CameraError> {
        let index = self.next;
        let with_colour = self.with_colour;
        if let Some(slot @ None) = self.decoded.get_mut(index) {
            *slot = Some(decode_pair(&self.pairs[index], with_colour)?);
        }
        let exposure = self.next_exposure();
        let uncached;
        let frame = match self.decoded.get(index) {
            Some(Some(f)) => f,
            _ => {
                uncached = decode_pair(&self.pairs[index], with_colour)?;
                &uncached
            }
        };
        for (from, to) in [(&frame.left, &mut out.left), (&frame.right, &mut out.right)] {
            to.width = from.width;
            to.height = from.height;
            to.data.clear();
            to.data.extend_from_slice(&from.data);
        }
        match &frame.left_rgb {
            Some(rgb) => out
                .left_rgb
                .get_or_insert_with(Default::default)
                .clone_from(rgb),
            None => out.left_rgb = None,
        }
        out.left_stamp = exposure;
        out.right_stamp = exposure;
        self.last_exposure = Some(exposure);
        self.next = (self.next + 1) % self.pairs.len();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn reads_png_and_pgm_pairs_from_a_folder_in_order_and_loops() {
        let dir = tempfile::tempdir().unwrap();
        let grey = image::GrayImage::from_fn(4, 3, |x, y| image::Luma([(x + 10 * y) as u8]));
        grey.save(dir.path().join("left_a.pgm")).unwrap();
        grey.save(dir.path().join("right_a.pgm")).unwrap();
        let rgb = image::RgbImage::from_pixel(4, 3, image::Rgb([200, 10, 20]));
        rgb.save(dir.path().join("left_b.png")).unwrap();
        rgb.save(dir.path().join("right_b.png")).unwrap();
        std::fs::write(dir.path().join("left_c.png"), b"no partner").unwrap();
        let mut cam = FileStereoSource::from_folder(dir.path(), Duration::from_millis(40))
            .unwrap()
            .unpaced();
        assert_eq!(cam.pairs().len(), 2);
        let mut f = StereoFrame::default();
        cam.capture(&mut f).unwrap();
        assert_eq!((f.left.width, f.left.height), (4, 3));
        assert_eq!(f.left.data[5], 11);
        assert!(f.left_rgb.is_none(), "a grey file has no colour");
        let first = f.left_stamp;
        cam.capture(&mut f).unwrap();
        assert_eq!(f.left_rgb.as_ref().unwrap().data[..3], [200, 10, 20]);
        assert_eq!(f.left_stamp, first.add_nanos(40_000_000));
        cam.capture(&mut f).unwrap();
        assert_eq!(f.left_stamp, first.add_nanos(80_000_000));
        assert_eq!(f.left.data[5], 11, "looped back to the first pair");
        assert!(f.left_rgb.is_none(), "from the cache: still grey");
    }

    /// Frames come one period apart on CLOCK_MONOTONIC, stamped with their exposure time: a
    /// capture waits for the next one, and a reader that comes late gets the newest.
    #[test]
    fn frames_are_exposed_one_period_apart_and_a_late_reader_gets_the_newest() {
        let dir = tempfile::tempdir().unwrap();
        let grey = image::GrayImage::new(4, 3);
        grey.save(dir.path().join("left.png")).unwrap();
        grey.save(dir.path().join("right.png")).unwrap();
        let period = Duration::from_millis(20);
        let mut cam = FileStereoSource::from_folder(dir.path(), period).unwrap();
        let mut f = StereoFrame::default();
        cam.capture(&mut f).unwrap();
        let first = f.left_stamp;
        assert!(monotonic_now().nanos_since(first) < 1_000_000_000);
        cam.capture(&mut f).unwrap();
        assert_eq!(f.left_stamp, first.add_nanos(20_000_000));
        assert!(
            monotonic_now() >= f.left_stamp,
            "not delivered before its exposure"
        );
        std::thread::sleep(Duration::from_millis(75));
        cam.capture(&mut f).unwrap();
        let late = f.left_stamp.nanos_since(first);
        assert_eq!(late % 20_000_000, 0, "on the exposure grid: {late}");
        assert!(
            late >= 80_000_000,
            "the newest exposure, not the next one: {late}"
        );
        assert!(monotonic_now().nanos_since(f.left_stamp) < 20_000_000 + 50_000_000);
    }

    #[test]
    fn mismatched_sizes_and_bad_files_are_clear_errors() {
        let dir = tempfile::tempdir().unwrap();
        image::GrayImage::new(4, 3)
            .save(dir.path().join("left.png"))
            .unwrap();
        image::GrayImage::new(5, 3)
            .save(dir.path().join("right.png"))
            .unwrap();
        let mut cam = FileStereoSource::from_folder(dir.path(), Duration::from_millis(40)).unwrap();
        let e = cam.capture(&mut StereoFrame::default()).unwrap_err();
        assert_eq!(e.to_string(), "left image is 4x3 but right image is 5x3");
        std::fs::write(dir.path().join("left.png"), b"not a png").unwrap();
        let e = cam.capture(&mut StereoFrame::default()).unwrap_err();
        assert!(matches!(e, CameraError::Decode { .. }), "{e}");
        let empty = tempfile::tempdir().unwrap();
        assert!(matches!(
            FileStereoSource::from_folder(empty.path(), Duration::from_millis(40)),
            Err(CameraError::NoPairs { .. })
        ));
    }

    #[test]
    fn reads_the_real_chessboard_and_middlebury_pairs() {
        if let Some(dir) = videt_testdata::data_dir("calib/chessboard") {
            let mut cam = FileStereoSource::from_folder(&dir, Duration::from_millis(33)).unwrap();
            assert_eq!(cam.pairs().len(), 9);
            let mut f = StereoFrame::default();
            cam.capture(&mut f).unwrap();
            assert_eq!((f.left.width, f.left.height), (640, 480));
            assert_eq!((f.right.width, f.right.height), (640, 480));
        }
        if let Some(dir) = videt_testdata::data_dir("stereo/tsukuba") {
            let mut cam = FileStereoSource::from_folder(&dir, Duration::from_millis(33)).unwrap();
            let mut f = StereoFrame::default();
            cam.capture(&mut f).unwrap();
            assert_eq!((f.left.width, f.left.height), (384, 288));
            assert_eq!(f.left_rgb.as_ref().unwrap().data.len(), 384 * 288 * 3);
        }
    }
}
