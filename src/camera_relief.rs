//! The vision thread on cameras: capture a stereo pair, rectify it with the rig's stereo
//! calibration (`videt calibrate-stereo`), run the whole-image pipeline and build the
//! bas-relief, again and again; each relief is published to the control thread.
//!
//! A capture or build that fails leaves the previous relief in place and is counted; the
//! control loop fades the forces out on a relief that is not renewed within
//! `vision.surface_max_age_s`, so a camera that stops never leaves a stale scene under the
//! finger.

use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use image::GrayImage;
use videt_hal::{GrayFrame, RgbFrame, StereoCamera, StereoFrame};
use videt_vision::calib::StereoCalibration;
use videt_vision::rectify::{RgbPlanes, StereoRectifier};
use videt_vision::surface::ReliefModel;
use videt_vision::RectifiedGeometry;

use crate::relief_scene::ReliefLayout;
use crate::snapshot::SnapshotWriter;
use crate::stereo_relief::{InitialBuild, LiveSettings, PairCamera, StereoPair, StereoRelief};

/// A calibrated stereo rig: the remap tables of both cameras and the rectified geometry.
#[derive(Debug, Clone)]
pub struct CalibratedRig {
    /// Remap tables.
    pub rectifier: StereoRectifier,
    /// Focal length, principal point and baseline after rectification.
    pub geometry: RectifiedGeometry,
    /// Image width and height the calibration is for, pixels.
    pub size_px: [u32; 2],
}

impl CalibratedRig {
    /// Load a stereo calibration file and build its remap tables. Errors start with the path.
    pub fn load(path: &Path) -> Result<CalibratedRig, String> {
        let at = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
        let calibration = StereoCalibration::load(path).map_err(|e| at(&e))?;
        CalibratedRig::from_calibration(&calibration).map_err(|e| at(&e))
    }

    /// Parse a stereo calibration file's text (`path` names it in errors) and build its remap
    /// tables. Errors start with the path.
    pub fn from_text(text: &str, path: &Path) -> Result<CalibratedRig, String> {
        let at = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
        let calibration = StereoCalibration::from_json(text, path).map_err(|e| at(&e))?;
        CalibratedRig::from_calibration(&calibration).map_err(|e| at(&e))
    }

    /// Build the remap tables and the rectified geometry of a validated calibration.
    pub fn from_calibration(calibration: &StereoCalibration) -> Result<CalibratedRig, String> {
        let (p1, p2) = (calibration.p1(), calibration.p2());
        if (p1[(0, 2)] - p2[(0, 2)]).abs() > 1e-6 {
            return Err(format!(
                "the rectified principal points differ (cx {} vs {}); rectify with zero disparity at infinity",
                p1[(0, 2)],
                p2[(0, 2)]
            ));
        }
        let geometry = RectifiedGeometry::from_projections(&p1, &p2).map_err(|e| e.to_string())?;
        let rectifier =
            StereoRectifier::from_calibration(calibration).map_err(|e| e.to_string())?;
        Ok(CalibratedRig {
            rectifier,
            geometry,
            size_px: [calibration.image_width, calibration.image_height],
        })
    }
}

/// Counters of the camera vision thread, readable from any thread.
#[derive(Debug, Default)]
pub struct CameraStats {
    rebuilds: AtomicU64,
    failures: AtomicU64,
    last_rebuild_us: AtomicU64,
}

impl CameraStats {
    /// Reliefs built from a fresh pair and published.
    pub fn rebuilds(&self) -> u64 {
        self.rebuilds.load(Ordering::Relaxed)
    }
    /// Captures or builds that failed (the previous relief stays).
    pub fn failures(&self) -> u64 {
        self.failures.load(Ordering::Relaxed)
    }
    /// Time of the last capture-to-relief, microseconds.
    pub fn last_rebuild_us(&self) -> u64 {
        self.last_rebuild_us.load(Ordering::Relaxed)
    }
}

/// A stereo camera and what turns its frames into reliefs.
pub struct CameraRelief<C> {
    camera: C,
    camera_name: String,
    rig: CalibratedRig,
    pair_camera: PairCamera,
    layout: ReliefLayout,
    frame: StereoFrame,
    left: GrayFrame,
    right: GrayFrame,
    colour: Option<ColourPublisher>,
}

/// Where the rectified left colour frames go (the colour thread), and the buffers they are
/// rectified through.
struct ColourPublisher {
    writer: SnapshotWriter<RgbFrame>,
    rectified: RgbFrame,
    planes: RgbPlanes,
}

impl<C: StereoCamera> CameraRelief<C> {
    /// `camera` (named `camera_name` in messages) calibrated by `rig`, searched for
    /// disparities up to `max_disparity_px`, its relief laid out by `layout`.
    pub fn new(
        camera: C,
        camera_name: String,
        rig: CalibratedRig,
        max_disparity_px: f32,
        layout: ReliefLayout,
    ) -> Result<Self, String> {
        let g = &rig.geometry;
        let pair_camera = PairCamera {
            focal_px: g.focal_px,
            baseline_m: g.baseline_m,
            max_disparity_px,
            principal_px: Some([g.cx_px, g.cy_px]),
        };
        pair_camera
            .validate()
            .map_err(|e| format!("{camera_name}: {e}"))?;
        Ok(CameraRelief {
            camera,
            camera_name,
            rig,
            pair_camera,
            layout,
            frame: StereoFrame::default(),
            left: GrayFrame::default(),
            right: GrayFrame::default(),
            colour: None,
        })
    }

    /// Also publish each captured left colour frame, rectified like the grey one, through
    /// `writer` (for the colour under the finger). A camera that delivers no colour publishes
    /// nothing.
    pub fn with_colour(mut self, writer: SnapshotWriter<RgbFrame>) -> Self {
        self.colour = Some(ColourPublisher {
            writer,
            rectified: RgbFrame::default(),
            planes: RgbPlanes::default(),
        });
        self
    }

    /// Capture the next pair and rectify it.
    pub fn capture_pair(&mut self) -> Result<StereoPair, String> {
        let name = &self.camera_name;
        self.camera
            .capture(&mut self.frame)
            .map_err(|e| format!("{name}: capture failed: {e:?}"))?;
        let [w, h] = self.rig.size_px;
        for (side, f) in [("left", &self.frame.left), ("right", &self.frame.right)] {
            if (f.width, f.height) != (w, h) {
                return Err(format!(
                    "{name}: the {side} frame is {}x{} but the stereo calibration is for {w}x{h} images",
                    f.width, f.height
                ));
            }
        }
        self.rig
            .rectifier
            .apply(&self.frame, &mut self.left, &mut self.right)
            .map_err(|e| format!("{name}: rectification: {e}"))?;
        if let (Some(colour), Some(rgb)) = (self.colour.as_mut(), self.frame.left_rgb.as_ref()) {
            self.rig
                .rectifier
                .left
                .apply_rgb(rgb, &mut colour.rectified, &mut colour.planes)
                .map_err(|e| format!("{name}: rectification of the colour frame: {e}"))?;
            let rectified = &colour.rectified;
            colour
                .writer
                .publish_with(|slot| slot.clone_from(rectified));
        }
        let image = |f: &GrayFrame| {
            GrayImage::from_raw(f.width, f.height, f.data.clone())
                .ok_or_else(|| format!("{name}: rectified frame of inconsistent size"))
        };
        StereoPair::new(
            name.clone(),
            image(&self.left)?,
            image(&self.right)?,
            self.pair_camera,
        )
    }

    /// Capture, rectify, match and build: the relief of the scene now.
    pub fn rebuild(&mut self) -> Result<(ReliefModel, InitialBuild), String> {
        let pair = self.capture_pair()?;
        let (_, model, build) = StereoRelief::build(pair, &self.layout, LiveSettings::default())?;
        Ok((model, build))
    }
}

/// Rebuild the relief from the camera every `period` on a thread of its own, publishing each
/// through `writer`, until `stop` is set. The first relief is expected to be published
/// already (it starts the feed). The thread runs SCHED_FIFO at `fifo_priority` when one is
/// given (`realtime.vision_priority`, below the control thread's), else SCHED_OTHER.
pub fn spawn_camera_updates<C: StereoCamera + Send + 'static>(
    mut relief: CameraRelief<C>,
    mut writer: SnapshotWriter<ReliefModel>,
    period: Duration,
    stats: Arc<CameraStats>,
    stop: Arc<AtomicBool>,
    fifo_priority: Option<u8>,
) -> std::io::Result<std::thread::JoinHandle<()>> {
    std::thread::Builder::new()
        .name("videt-vision".into())
        .spawn(move || {
            crate::rt::enter_vision_priority(fifo_priority);
            let mut next = Instant::now() + period;
            while !stop.load(Ordering::Relaxed) {
                let now = Instant::now();
                if next > now {
                    std::thread::sleep(next - now);
                }
                next = (next + period).max(Instant::now());
                let start = Instant::now();
                match relief.rebuild() {
                    Ok((model, _)) => {
                        writer.publish_with(|slot| *slot = model);
                        stats.rebuilds.fetch_add(1, Ordering::Relaxed);
                        stats
                            .last_rebuild_us
                            .store(start.elapsed().as_micros() as u64, Ordering::Relaxed);
                    }
                    Err(e) => {
                        if stats.failures.fetch_add(1, Ordering::Relaxed) < 10 {
                            tracing::warn!("relief not renewed (the previous one stays and fades when stale): {e}");
                        }
                    }
                }
            }
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_calibration_names_its_path() {
        let e = CalibratedRig::load(Path::new("/nonexistent/stereo.json")).unwrap_err();
        assert!(e.starts_with("/nonexistent/stereo.json: "), "{e}");
    }
}
