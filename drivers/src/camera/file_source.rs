//! A stereo "camera" reading image pairs from a folder (PNG, PGM/PPM, JPEG): the twin's and the
//! demo's camera. Pairs are files whose names contain `left` and the same name with `right`
//! (`left03.jpg`/`right03.jpg`, `left.ppm`/`right.ppm`), in name order, played in a loop.

use std::path::{Path, PathBuf};

use videt_hal::{MonoTime, StereoCamera, StereoFrame};

use super::CameraError;

const EXTENSIONS: [&str; 6] = ["png", "pgm", "ppm", "pnm", "jpg", "jpeg"];

/// Stereo pairs from image files.
#[derive(Debug, Clone)]
pub struct FileStereoSource {
    pairs: Vec<(PathBuf, PathBuf)>,
    next: usize,
    frame_period_ns: u64,
    frames_delivered: u64,
    with_colour: bool,
}

impl FileStereoSource {
    /// The pairs of `dir`, delivered with stamps `frame_period` apart.
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
            pairs,
            next: 0,
            frame_period_ns: frame_period.as_nanos() as u64,
            frames_delivered: 0,
            with_colour: true,
        }
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

impl videt_hal::ErrorType for FileStereoSource {
    type Error = CameraError;
}

impl StereoCamera for FileStereoSource {
    fn capture(&mut self, out: &mut StereoFrame) -> Result<(), CameraError> {
        let (lp, rp) = &self.pairs[self.next];
        let left = load(lp)?;
        let right = load(rp)?;
        if (left.width(), left.height()) != (right.width(), right.height()) {
            return Err(CameraError::SizeMismatch {
                left_w: left.width(),
                left_h: left.height(),
                right_w: right.width(),
                right_h: right.height(),
            });
        }
        for (img, frame) in [(&left, &mut out.left), (&right, &mut out.right)] {
            let grey = img.to_luma8();
            frame.width = grey.width();
            frame.height = grey.height();
            frame.data.clear();
            frame.data.extend_from_slice(grey.as_raw());
        }
        if self.with_colour && left.color().has_color() {
            let rgb = left.to_rgb8();
            let f = out.left_rgb.get_or_insert_with(Default::default);
            f.width = rgb.width();
            f.height = rgb.height();
            f.data.clear();
            f.data.extend_from_slice(rgb.as_raw());
        } else {
            out.left_rgb = None;
        }
        let stamp = MonoTime(self.frames_delivered * self.frame_period_ns);
        out.left_stamp = stamp;
        out.right_stamp = stamp;
        self.frames_delivered += 1;
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
        let mut cam = FileStereoSource::from_folder(dir.path(), Duration::from_millis(40)).unwrap();
        assert_eq!(cam.pairs().len(), 2);
        let mut f = StereoFrame::default();
        cam.capture(&mut f).unwrap();
        assert_eq!((f.left.width, f.left.height), (4, 3));
        assert_eq!(f.left.data[5], 11);
        assert!(f.left_rgb.is_none(), "a grey file has no colour");
        cam.capture(&mut f).unwrap();
        assert_eq!(f.left_rgb.as_ref().unwrap().data[..3], [200, 10, 20]);
        assert_eq!(f.left_stamp, MonoTime(40_000_000));
        cam.capture(&mut f).unwrap();
        assert_eq!(f.left_stamp, MonoTime(80_000_000));
        assert_eq!(f.left.data[5], 11, "looped back to the first pair");
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
