//! The vision thread on cameras: capture a stereo pair, rectify it with the rig's stereo
//! calibration (`videt calibrate-stereo`), and turn it into the bas-relief the control thread
//! renders. Every frame the camera delivers is captured (a V4L2 queue never holds stale frames);
//! while the finger is over the scene, each frame re-matches the region under it (the
//! pipeline's local mode), merges it into the relief and rebuilds it, and a whole-image run
//! renews the rest every `vision.full_refresh_s`; while the finger is elsewhere, a whole-image
//! run every `vision.rebuild_period_s` keeps the relief up to date. Each relief is published
//! with its frame's capture time, so the control thread measures the frame-to-force latency.
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
use videt_relief::ReliefModel;
use videt_vision::calib::StereoCalibration;
use videt_vision::rectify::{RgbPlanes, StereoRectifier};
use videt_vision::RectifiedGeometry;

use videt_hal::MonoTime;

use crate::stereo_relief::{
    InitialBuild, LiveSettings, PairCamera, RegionUpdate, StereoPair, StereoRelief,
};
use videt_relief::ReliefLayout;
use videt_runtime::snapshot::{SnapshotReader, SnapshotWriter};
use videt_runtime::thimble::ThimbleState;

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
    local_updates: AtomicU64,
    failures: AtomicU64,
    last_latency_us: AtomicU64,
    max_latency_us: AtomicU64,
    cpu_permille: AtomicU64,
}

impl CameraStats {
    /// Whole-image reliefs built from a fresh pair and published.
    pub fn rebuilds(&self) -> u64 {
        self.rebuilds.load(Ordering::Relaxed)
    }
    /// Reliefs updated around the finger from a fresh pair and published.
    pub fn local_updates(&self) -> u64 {
        self.local_updates.load(Ordering::Relaxed)
    }
    /// Captures or builds that failed (the previous relief stays).
    pub fn failures(&self) -> u64 {
        self.failures.load(Ordering::Relaxed)
    }
    /// Capture to publication of the last relief and the largest so far, microseconds.
    pub fn latency_us(&self) -> [u64; 2] {
        [
            self.last_latency_us.load(Ordering::Relaxed),
            self.max_latency_us.load(Ordering::Relaxed),
        ]
    }
    /// CPU time of the vision thread over the last second, per mille of one core.
    pub fn cpu_permille(&self) -> u64 {
        self.cpu_permille.load(Ordering::Relaxed)
    }

    fn published(&self, captured: MonoTime) {
        let now = videt_hal::Clock::now(&videt_runtime::rt::SystemClock);
        let us = now.nanos_since(captured) / 1000;
        self.last_latency_us.store(us, Ordering::Relaxed);
        self.max_latency_us.fetch_max(us, Ordering::Relaxed);
    }

    /// For the status line: `reliefs N whole + M local (F failed), frame to publish X ms
    /// (max Y), vision CPU Z %`.
    pub fn status_text(&self) -> String {
        let [last, max] = self.latency_us();
        format!(
            " | reliefs {} whole + {} local ({} failed), frame to publish {:.1} ms (max {:.1}), vision CPU {:.1} %",
            self.rebuilds(),
            self.local_updates(),
            self.failures(),
            last as f64 / 1e3,
            max as f64 / 1e3,
            self.cpu_permille() as f64 / 10.0
        )
    }
}

/// A stereo camera and what turns its frames into reliefs.
pub struct CameraRelief<C> {
    camera: C,
    camera_name: String,
    rig: CalibratedRig,
    pair_camera: PairCamera,
    layout: ReliefLayout,
    live_settings: LiveSettings,
    frame: StereoFrame,
    left: GrayFrame,
    right: GrayFrame,
    /// Capture time of the rectified pair in `left`/`right` (`None`: none yet).
    captured: Option<MonoTime>,
    /// The relief of the last whole-image run, updated around the finger since.
    live: Option<StereoRelief>,
    colour: Option<ColourPublisher>,
    /// Where the rectified left grey frames go for the live view.
    live_image: Option<std::sync::Arc<videt_viewers::live::ImageSlot>>,
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
            live_settings: LiveSettings::default(),
            frame: StereoFrame::default(),
            left: GrayFrame::default(),
            right: GrayFrame::default(),
            captured: None,
            live: None,
            colour: None,
            live_image: None,
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

    /// Also offer each rectified left grey frame to the live view through `slot`.
    pub fn with_live_image(mut self, slot: std::sync::Arc<videt_viewers::live::ImageSlot>) -> Self {
        self.live_image = Some(slot);
        self
    }

    /// The region of interest of the updates around the finger (the update period only
    /// scales the velocity look-ahead: set it to the camera's frame period).
    pub fn with_live_settings(mut self, settings: LiveSettings) -> Self {
        self.live_settings = settings;
        self
    }

    /// Capture the next pair and rectify it; returns its capture time (the earlier of the two
    /// cameras' stamps, `CLOCK_MONOTONIC`).
    pub fn capture(&mut self) -> Result<MonoTime, String> {
        let name = &self.camera_name;
        self.captured = None;
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
        let captured = self.frame.left_stamp.min(self.frame.right_stamp);
        if let Some(slot) = &self.live_image {
            let l = &self.left;
            slot.offer(captured.as_nanos(), l.width, l.height, &l.data);
        }
        self.captured = Some(captured);
        Ok(captured)
    }

    /// The last captured pair, rectified.
    fn captured_pair(&self) -> Result<StereoPair, String> {
        let name = &self.camera_name;
        if self.captured.is_none() {
            return Err(format!("{name}: no frame captured"));
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

    /// The whole-image relief of the last captured pair (its depth range mapped anew); the
    /// updates around the finger start from it.
    pub fn build_whole(&mut self) -> Result<(ReliefModel, InitialBuild), String> {
        let pair = self.captured_pair()?;
        let (relief, model, build) = StereoRelief::build(pair, &self.layout, self.live_settings)?;
        self.live = Some(relief);
        Ok((model, build))
    }

    /// Capture, rectify, match and build: the relief of the scene now.
    pub fn rebuild(&mut self) -> Result<(ReliefModel, InitialBuild), String> {
        self.capture()?;
        self.build_whole()
    }

    /// Whether a thimble at `position_m` is over the scene of the last whole-image relief.
    pub fn finger_over(&self, position_m: [f64; 3]) -> bool {
        self.live
            .as_ref()
            .is_some_and(|r| r.region_under(position_m, [0.0; 3]).is_some())
    }

    /// The relief updated around a thimble at `position_m` moving at `velocity_m_s` from the
    /// last captured pair: the region under the finger re-matched, merged into the relief's
    /// segments and the relief rebuilt. `Ok(None)` when there is no whole-image relief yet or
    /// the finger is not over the scene.
    pub fn update_around(
        &mut self,
        position_m: [f64; 3],
        velocity_m_s: [f64; 3],
    ) -> Result<Option<(ReliefModel, RegionUpdate)>, String> {
        let name = &self.camera_name;
        if self.captured.is_none() {
            return Err(format!("{name}: no frame captured"));
        }
        let Some(relief) = self.live.as_mut() else {
            return Ok(None);
        };
        // The new pixels go to the relief's pair; its old ones come back as the next buffers.
        relief.swap_images(&mut self.left.data, &mut self.right.data)?;
        self.captured = None;
        relief.update_around(position_m, velocity_m_s)
    }
}

/// When the camera vision thread rebuilds the relief.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraSchedule {
    /// Whole-image rebuild period while the finger is not over the scene
    /// (`vision.rebuild_period_s`).
    pub rebuild_period: Duration,
    /// Longest time between two whole-image rebuilds while the finger is over it
    /// (`vision.full_refresh_s`); also how often the cheaper of the two ways of following a
    /// frame is measured again.
    pub full_refresh: Duration,
}

/// While whole-image runs follow the frames (they were faster), an update around the finger is
/// timed again this often: a cost measured in one part of the scene may not hold in another. A
/// way timed after a pause this long has its estimate replaced, not averaged.
const LOCAL_PROBE_PERIOD: Duration = Duration::from_secs(1);

/// What the vision thread does with a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameWork {
    /// Nothing (the finger is not over the scene and no whole-image run is due).
    Skip,
    /// A whole-image run.
    Whole,
    /// The region under the finger re-matched, merged and the relief rebuilt.
    Local,
}

/// Chooses the work of each frame. While the finger is over the scene, every frame renews the
/// relief under it by whichever is faster on this scene and machine: the update around the
/// finger or the whole-image run (which renews the region as well, and the rest with it). Each
/// way is timed whenever it runs (a moving average); the whole-image run runs at least every
/// `full_refresh`, the update around the finger at least every second, so that both estimates
/// stay current. While the finger is elsewhere, a whole-image run every `rebuild_period`.
#[derive(Debug, Clone)]
pub struct FramePlanner {
    schedule: CameraSchedule,
    /// When each last ran: whole, local.
    last: [Option<Instant>; 2],
    /// Moving averages of their durations, seconds: whole, local.
    cost_s: [Option<f64>; 2],
}

impl FramePlanner {
    /// A planner; the first relief was built just now (a whole-image run).
    pub fn new(schedule: CameraSchedule) -> Self {
        FramePlanner {
            schedule,
            last: [Some(Instant::now()), None],
            cost_s: [None, None],
        }
    }

    /// The work for a frame at `now`, the finger over the scene or not.
    pub fn plan(&self, now: Instant, finger_over: bool) -> FrameWork {
        let since = |k: usize| self.last[k].map(|t| now.saturating_duration_since(t));
        let due = |k: usize, period: Duration| since(k).is_none_or(|d| d >= period);
        if !finger_over {
            return if due(0, self.schedule.rebuild_period) {
                FrameWork::Whole
            } else {
                FrameWork::Skip
            };
        }
        // Each way is timed (again) when it is due or was never timed, the whole-image run
        // first.
        if due(0, self.schedule.full_refresh) || self.cost_s[0].is_none() {
            return FrameWork::Whole;
        }
        if due(1, LOCAL_PROBE_PERIOD.min(self.schedule.full_refresh)) || self.cost_s[1].is_none() {
            return FrameWork::Local;
        }
        match self.cost_s {
            [Some(whole), Some(local)] if whole < local => FrameWork::Whole,
            _ => FrameWork::Local,
        }
    }

    /// `work` started at `start` and took `took`.
    pub fn ran(&mut self, work: FrameWork, start: Instant, took: Duration) {
        let k = match work {
            FrameWork::Skip => return,
            FrameWork::Whole => 0,
            FrameWork::Local => 1,
        };
        // Runs in a row are averaged; one after a pause of a probe period or more replaces an
        // estimate that may be out of date.
        let fresh =
            self.last[k].is_some_and(|t| start.saturating_duration_since(t) < LOCAL_PROBE_PERIOD);
        self.last[k] = Some(start);
        let t = took.as_secs_f64();
        self.cost_s[k] = Some(match self.cost_s[k] {
            Some(c) if fresh => 0.8 * c + 0.2 * t,
            _ => t,
        });
    }
}

/// Capture every frame of the camera on a thread of its own and turn frames into reliefs
/// published through `writer` (each with its capture time), until `stop` is set: around the
/// finger (`thimble`, the control loop's newest state) while it is over the scene, whole images
/// as [`FramePlanner`] says. The first relief is expected to be published already (it starts
/// the feed). A capture or build that fails leaves the published relief alone, is counted and
/// waits `schedule.rebuild_period` before the next capture. The thread runs SCHED_FIFO at
/// `fifo_priority` when one is given (`realtime.vision_priority`, below the control thread's),
/// else SCHED_OTHER.
pub fn spawn_camera_updates<C: StereoCamera + Send + 'static>(
    mut relief: CameraRelief<C>,
    mut writer: SnapshotWriter<ReliefModel>,
    schedule: CameraSchedule,
    mut thimble: Option<SnapshotReader<ThimbleState>>,
    stats: Arc<CameraStats>,
    stop: Arc<AtomicBool>,
    fifo_priority: Option<u8>,
) -> std::io::Result<std::thread::JoinHandle<()>> {
    std::thread::Builder::new()
        .name("videt-vision".into())
        .spawn(move || {
            videt_runtime::rt::enter_vision_priority(fifo_priority);
            let mut planner = FramePlanner::new(schedule);
            let mut cpu_window = (Instant::now(), videt_runtime::rt::thread_cpu_time());
            let fail = |stats: &CameraStats, what: &str, e: String| {
                if stats.failures.fetch_add(1, Ordering::Relaxed) < 10 {
                    tracing::warn!("{what} (the previous relief stays and fades when stale): {e}");
                }
                std::thread::sleep(schedule.rebuild_period);
            };
            while !stop.load(Ordering::Relaxed) {
                let (wall, cpu) = (cpu_window.0.elapsed(), videt_runtime::rt::thread_cpu_time());
                if wall >= Duration::from_secs(1) {
                    let share = (cpu - cpu_window.1).as_secs_f64() / wall.as_secs_f64();
                    stats
                        .cpu_permille
                        .store((share * 1000.0).round() as u64, Ordering::Relaxed);
                    cpu_window = (Instant::now(), cpu);
                }
                let captured = match relief.capture() {
                    Ok(t) => t,
                    Err(e) => {
                        fail(&stats, "relief not renewed", e);
                        continue;
                    }
                };
                let finger = thimble
                    .as_mut()
                    .and_then(|t| {
                        let s = t.latest();
                        (s.version > 0).then_some((s.value.position_m, s.value.velocity_m_s))
                    })
                    .filter(|&(p, _)| relief.finger_over(p));
                let start = Instant::now();
                let work = planner.plan(start, finger.is_some());
                let result = match (work, finger) {
                    (FrameWork::Whole, _) => relief.build_whole().map(|(m, _)| Some(m)),
                    (FrameWork::Local, Some((p, v))) => {
                        relief.update_around(p, v).map(|u| u.map(|(m, _)| m))
                    }
                    _ => Ok(None),
                };
                let took = start.elapsed();
                match result {
                    Ok(Some(model)) => {
                        writer.publish_captured_with(Some(captured), |slot| *slot = model);
                        stats.published(captured);
                        planner.ran(work, start, took);
                        if work == FrameWork::Whole {
                            stats.rebuilds.fetch_add(1, Ordering::Relaxed);
                        } else {
                            stats.local_updates.fetch_add(1, Ordering::Relaxed);
                        }
                    }
                    Ok(None) => {}
                    Err(e) => fail(&stats, "relief not renewed", e),
                }
            }
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn schedule() -> CameraSchedule {
        CameraSchedule {
            rebuild_period: Duration::from_millis(200),
            full_refresh: Duration::from_secs(10),
        }
    }

    #[test]
    fn away_from_the_scene_a_whole_image_run_every_rebuild_period() {
        let t0 = Instant::now();
        let mut p = FramePlanner::new(schedule());
        p.last[0] = Some(t0);
        assert_eq!(
            p.plan(t0 + Duration::from_millis(100), false),
            FrameWork::Skip
        );
        assert_eq!(
            p.plan(t0 + Duration::from_millis(200), false),
            FrameWork::Whole
        );
    }

    #[test]
    fn over_the_scene_the_faster_way_follows_each_frame_and_both_are_measured_again() {
        let ms = Duration::from_millis;
        let t0 = Instant::now();
        let mut p = FramePlanner::new(schedule());
        p.last[0] = Some(t0);
        // The first relief was not timed: a whole-image run is.
        assert_eq!(p.plan(t0 + ms(1), true), FrameWork::Whole);
        p.ran(FrameWork::Whole, t0, ms(5));
        // Local never measured: it runs (and is measured).
        assert_eq!(p.plan(t0 + ms(66), true), FrameWork::Local);
        p.ran(FrameWork::Local, t0 + ms(66), ms(11));
        // Slower than the whole-image run: the whole image follows the frames...
        assert_eq!(p.plan(t0 + ms(133), true), FrameWork::Whole);
        p.ran(FrameWork::Whole, t0 + ms(133), ms(5));
        // ... until the local update is due to be measured again, a second after it last ran.
        assert_eq!(p.plan(t0 + ms(1_000), true), FrameWork::Whole);
        assert_eq!(p.plan(t0 + ms(1_066), true), FrameWork::Local);
        p.ran(FrameWork::Local, t0 + ms(1_066), ms(11));
        assert_eq!(p.plan(t0 + ms(1_133), true), FrameWork::Whole);
        p.ran(FrameWork::Whole, t0 + ms(1_133), ms(5));
        assert_eq!(p.plan(t0 + ms(10_100), true), FrameWork::Local);
        p.ran(FrameWork::Local, t0 + ms(10_100), ms(2));
        // Now faster: local, with a whole-image run every full refresh.
        assert_eq!(p.plan(t0 + ms(10_120), true), FrameWork::Local);
        p.ran(FrameWork::Local, t0 + ms(10_120), ms(2));
        assert_eq!(p.plan(t0 + ms(11_100), true), FrameWork::Local);
        assert_eq!(p.plan(t0 + ms(11_140), true), FrameWork::Whole);
        p.ran(FrameWork::Whole, t0 + ms(11_140), ms(5));
        assert_eq!(p.plan(t0 + ms(11_160), true), FrameWork::Local);
        // The finger leaves: whole images at the rebuild period only.
        assert_eq!(p.plan(t0 + ms(11_300), false), FrameWork::Skip);
        assert_eq!(p.plan(t0 + ms(11_400), false), FrameWork::Whole);
    }

    #[test]
    fn a_missing_calibration_names_its_path() {
        let e = CalibratedRig::load(Path::new("/nonexistent/stereo.json")).unwrap_err();
        assert!(e.starts_with("/nonexistent/stereo.json: "), "{e}");
    }
}
