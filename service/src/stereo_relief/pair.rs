//! Stereo pairs: the compiled-in demo pair, a pair directory with its optional `camera.toml`,
//! and the rectified camera of a pair ([`PairCamera`]).

use std::path::Path;

use image::GrayImage;
use videt_vision::RectifiedGeometry;

/// The demo pair's left image (PNG, Middlebury "tsukuba", 384 x 288).
pub const DEMO_LEFT_PNG: &[u8] = include_bytes!("../../assets/demo-stereo/left.png");
/// The demo pair's right image (PNG).
pub const DEMO_RIGHT_PNG: &[u8] = include_bytes!("../../assets/demo-stereo/right.png");
/// The demo pair's camera (`camera.toml`, nominal values: see the README there).
pub const DEMO_CAMERA_TOML: &str = include_str!("../../assets/demo-stereo/camera.toml");

/// The rectified camera of a pair, as `camera.toml` in a pair directory gives it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PairCamera {
    /// Rectified focal length, pixels (> 0).
    pub focal_px: f64,
    /// Baseline, metres (> 0).
    pub baseline_m: f64,
    /// Largest disparity searched, pixels (> 0).
    pub max_disparity_px: f32,
    /// Rectified principal point `[cx, cy]`, pixels (default: the image centre).
    #[serde(default)]
    pub principal_px: Option<[f64; 2]>,
}

impl PairCamera {
    /// Nominal values for a pair without `camera.toml`: focal length = image width (about 53°
    /// of horizontal field), 10 cm baseline, disparities up to 64 px. The relief does not depend
    /// on the focal length and baseline (they scale every depth alike and the depth range is
    /// mapped onto the relief depth); the disparity bound does.
    pub fn nominal(image_width_px: u32) -> PairCamera {
        PairCamera {
            focal_px: f64::from(image_width_px.max(1)),
            baseline_m: 0.1,
            max_disparity_px: 64.0,
            principal_px: None,
        }
    }

    /// Parses `camera.toml` text; `source` names it in errors.
    pub fn parse(text: &str, source: &str) -> Result<PairCamera, String> {
        let camera: PairCamera = toml::from_str(text).map_err(|e| format!("{source}: {e}"))?;
        camera.validate().map_err(|e| format!("{source}: {e}"))?;
        Ok(camera)
    }

    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.focal_px.is_finite() && self.focal_px > 0.0) {
            return Err(format!(
                "focal_px = {} must be finite and > 0",
                self.focal_px
            ));
        }
        if !(self.baseline_m.is_finite() && self.baseline_m > 0.0) {
            return Err(format!(
                "baseline_m = {} must be finite and > 0",
                self.baseline_m
            ));
        }
        if let Some(p) = self.principal_px {
            if !p.iter().all(|v| v.is_finite()) {
                return Err(format!("principal_px = {p:?} must be finite"));
            }
        }
        if !(self.max_disparity_px.is_finite() && (1.0..=1000.0).contains(&self.max_disparity_px)) {
            return Err(format!(
                "max_disparity_px = {} must be in [1, 1000]",
                self.max_disparity_px
            ));
        }
        Ok(())
    }
}

/// A rectified stereo pair with its camera.
#[derive(Debug, Clone)]
pub struct StereoPair {
    /// What it is (shown in logs).
    pub name: String,
    /// Left image (8-bit grey).
    pub left: GrayImage,
    /// Right image, the same size.
    pub right: GrayImage,
    /// The rectified camera.
    pub camera: PairCamera,
}

impl StereoPair {
    /// A pair from two images; errors when their sizes differ or are too small.
    pub fn new(
        name: String,
        left: GrayImage,
        right: GrayImage,
        camera: PairCamera,
    ) -> Result<StereoPair, String> {
        camera
            .validate()
            .map_err(|e| format!("{name}: camera: {e}"))?;
        if left.dimensions() != right.dimensions() {
            return Err(format!(
                "{name}: the left image is {}x{} but the right one {}x{}: a rectified pair must have equal sizes",
                left.width(),
                left.height(),
                right.width(),
                right.height()
            ));
        }
        if left.width() < 16 || left.height() < 16 {
            return Err(format!(
                "{name}: the images are {}x{}; at least 16x16 pixels are needed",
                left.width(),
                left.height()
            ));
        }
        Ok(StereoPair {
            name,
            left,
            right,
            camera,
        })
    }

    /// The compiled-in demo pair (Middlebury "tsukuba", nominal camera).
    pub fn demo() -> Result<StereoPair, String> {
        let decode = |bytes: &[u8], which: &str| {
            image::load_from_memory(bytes)
                .map(|i| i.to_luma8())
                .map_err(|e| format!("demo pair: the {which} image does not decode: {e}"))
        };
        let camera = PairCamera::parse(DEMO_CAMERA_TOML, "demo pair camera.toml")?;
        StereoPair::new(
            "demo pair (Middlebury tsukuba)".into(),
            decode(DEMO_LEFT_PNG, "left")?,
            decode(DEMO_RIGHT_PNG, "right")?,
            camera,
        )
    }

    /// A pair directory: `left.png` and `right.png` (or `.ppm`), and optionally `camera.toml`
    /// ([`PairCamera`]; without it the [`PairCamera::nominal`] values are used). Returns the pair
    /// and whether the camera is nominal.
    pub fn load_dir(dir: &Path) -> Result<(StereoPair, bool), String> {
        if !dir.is_dir() {
            return Err(format!(
                "stereo pair directory {} does not exist or is not a directory",
                dir.display()
            ));
        }
        let find = |stem: &str| {
            ["png", "ppm", "pgm"]
                .iter()
                .map(|ext| dir.join(format!("{stem}.{ext}")))
                .find(|p| p.is_file())
                .ok_or_else(|| {
                    format!(
                        "{}: no {stem}.png, {stem}.ppm or {stem}.pgm in it",
                        dir.display()
                    )
                })
        };
        let load = |path: &Path| videt_vision::io::load_gray_image(path).map_err(|e| e.to_string());
        let left = load(&find("left")?)?;
        let right = load(&find("right")?)?;
        let camera_path = dir.join("camera.toml");
        let (camera, nominal) = if camera_path.is_file() {
            let text = std::fs::read_to_string(&camera_path)
                .map_err(|e| format!("cannot read {}: {e}", camera_path.display()))?;
            (
                PairCamera::parse(&text, &camera_path.display().to_string())?,
                false,
            )
        } else {
            (PairCamera::nominal(left.width()), true)
        };
        let pair = StereoPair::new(dir.display().to_string(), left, right, camera)?;
        Ok((pair, nominal))
    }

    /// The rectified geometry (principal point at the image centre unless the camera gives
    /// one).
    pub fn geometry(&self) -> RectifiedGeometry {
        let [cx_px, cy_px] = self.camera.principal_px.unwrap_or([
            (f64::from(self.left.width()) - 1.0) / 2.0,
            (f64::from(self.left.height()) - 1.0) / 2.0,
        ]);
        RectifiedGeometry {
            focal_px: self.camera.focal_px,
            cx_px,
            cy_px,
            baseline_m: self.camera.baseline_m,
        }
    }

    /// Image width and height, pixels.
    pub fn size_px(&self) -> [u32; 2] {
        [self.left.width(), self.left.height()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_toml_is_checked() {
        let c = PairCamera::parse(
            "focal_px = 400.0\nbaseline_m = 0.05\nmax_disparity_px = 20.0\n",
            "x",
        )
        .unwrap();
        assert_eq!(c.max_disparity_px, 20.0);
        let e = PairCamera::parse(
            "focal_px = -1.0\nbaseline_m = 0.05\nmax_disparity_px = 20.0\n",
            "cam.toml",
        )
        .unwrap_err();
        assert!(e.contains("cam.toml") && e.contains("focal_px"), "{e}");
        let e = PairCamera::parse("focal_px = 400.0\n", "cam.toml").unwrap_err();
        assert!(e.contains("baseline_m"), "{e}");
        PairCamera::parse(DEMO_CAMERA_TOML, "demo").unwrap();
    }

    #[test]
    fn bad_pairs_are_rejected_with_a_reason() {
        let cam = PairCamera::nominal(64);
        let e = StereoPair::new(
            "p".into(),
            GrayImage::new(64, 48),
            GrayImage::new(60, 48),
            cam,
        )
        .unwrap_err();
        assert!(e.contains("equal sizes"), "{e}");
        let e = StereoPair::new("p".into(), GrayImage::new(8, 8), GrayImage::new(8, 8), cam)
            .unwrap_err();
        assert!(e.contains("16x16"), "{e}");
        let dir = std::env::temp_dir().join("videt-no-such-pair-dir");
        let e = StereoPair::load_dir(&dir).unwrap_err();
        assert!(e.contains("does not exist"), "{e}");
    }
}
