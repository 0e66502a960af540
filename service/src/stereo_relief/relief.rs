//! The relief of a stereo pair ([`StereoRelief`]): the settings of its updates
//! ([`LiveSettings`]), the whole-image pipeline run on the pair, the first build with the scene
//! depth range it fixes, and the whole-image rebuilds. The updates around the finger are the
//! live module's.

use std::time::{Duration, Instant};

use image::GrayImage;
use videt_relief::{
    build_from_scene, BuildReport, PinholeCamera, ReliefLayout, ReliefModel, ReliefParams,
    SceneSegment3,
};
use videt_vision::matching::MatchChecks;
use videt_vision::patch_stereo::{PatchDepth, PatchParams};
use videt_vision::{
    GrayView, PipelineOutput, PixelRect, RectifiedGeometry, StereoPipeline, VisionParams,
};

use super::mapping::{pinhole, scene_depth_range, scene_segments};
use super::pair::StereoPair;

/// The whole-image pipeline on `pair`: its 3D segments as scene segments, and the run's output.
/// With `patches`, the far sides of its occluding edges are among the segments, and
/// `patch_depth.points` holds the support points (`videt_vision::patch_stereo`).
fn run_whole<'p>(
    pipeline: &'p mut StereoPipeline,
    pair: &StereoPair,
    geometry: &RectifiedGeometry,
    vision: &VisionParams,
    patches: Option<&PatchParams>,
    patch_depth: &mut PatchDepth,
) -> Result<(Vec<SceneSegment3>, &'p PipelineOutput), String> {
    let lv = GrayView::from_image(&pair.left).map_err(|e| e.to_string())?;
    let rv = GrayView::from_image(&pair.right).map_err(|e| e.to_string())?;
    let out = pipeline
        .run(&lv, &rv, Some(geometry), vision)
        .map_err(|e| format!("stereo pipeline: {e}"))?;
    let mut segments = Vec::with_capacity(out.segments_3d.len());
    scene_segments(&out.segments_3d, &mut segments);
    measure_patches(
        patches,
        patch_depth,
        (&lv, &rv),
        geometry,
        out,
        vision,
        None,
    );
    scene_segments(&patch_depth.far_sides, &mut segments);
    Ok((segments, out))
}

/// The patches' depth on a run (`patches` given), or none (cleared).
pub(super) fn measure_patches(
    patches: Option<&PatchParams>,
    patch_depth: &mut PatchDepth,
    (left, right): (&GrayView<'_>, &GrayView<'_>),
    geometry: &RectifiedGeometry,
    out: &PipelineOutput,
    vision: &VisionParams,
    region: Option<PixelRect>,
) {
    match patches {
        Some(params) => patch_depth.measure(
            left,
            right,
            geometry,
            out,
            vision.matching.disparity_max_px,
            vision.disparity_sigma_px,
            region,
            params,
        ),
        None => {
            patch_depth.far_sides.clear();
            patch_depth.points.clear();
        }
    }
}

/// Settings of the live updates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveSettings {
    /// Size of the region of interest around the finger when it is still, pixels (>= 8).
    pub roi_size_px: [f32; 2],
    /// Time between two updates, seconds (the pipeline's "frame"; scales the velocity
    /// look-ahead).
    pub update_period_s: f64,
    /// Time between two whole-image runs, seconds: they replace the pieces that the local
    /// merges split segments into at the regions' borders, so the segment list stays the size
    /// of one image's.
    pub full_refresh_s: f64,
    /// The checks against wrong matches of every run, whole-image and local.
    pub checks: MatchChecks,
    /// Depth from image patches besides the segments (`vision.patch_spacing_px`): the far
    /// sides of occluding edges and support points on a grid this many pixels apart; 0: the
    /// segments alone.
    pub patch_spacing_px: u32,
}

impl Default for LiveSettings {
    /// A 72 x 72 px region, 15 updates per second, a whole-image run every 10 s.
    fn default() -> Self {
        LiveSettings {
            roi_size_px: [72.0, 72.0],
            update_period_s: 1.0 / 15.0,
            full_refresh_s: 10.0,
            checks: MatchChecks::default(),
            patch_spacing_px: DEFAULT_PATCH_SPACING_PX,
        }
    }
}

/// The default of [`LiveSettings::patch_spacing_px`] and `vision.patch_spacing_px`.
pub const DEFAULT_PATCH_SPACING_PX: u32 = videt_config::DEFAULT_PATCH_SPACING_PX;

/// The patch settings of `live`: `None` when the patches are off (spacing 0).
pub(super) fn patch_params(live: &LiveSettings) -> Result<Option<PatchParams>, String> {
    match live.patch_spacing_px {
        0 => Ok(None),
        spacing if videt_config::PATCH_SPACING_RANGE_PX.contains(&spacing) => {
            Ok(Some(PatchParams {
                spacing_px: spacing as usize,
                ..PatchParams::default()
            }))
        }
        other => Err(format!(
            "patch spacing {other} px: {}",
            videt_config::PATCH_SPACING_ALLOWED
        )),
    }
}

/// The checks against wrong matches `config` switches on.
pub fn match_checks(config: &videt_config::VisionConfig) -> MatchChecks {
    MatchChecks {
        left_right: config.left_right_check,
        min_confidence: config.min_match_confidence as f32,
        surface: config.surface_check,
    }
}

/// What the first (whole-image) build did.
#[derive(Debug, Clone)]
pub struct InitialBuild {
    /// 3D segments the pipeline gave.
    pub segments_3d: usize,
    /// Accepted matches.
    pub matches: usize,
    /// Left image segments.
    pub left_segments: usize,
    /// Scene depth range mapped onto the relief, metres.
    pub depth_range_m: [f64; 2],
    /// Time of the pipeline run.
    pub pipeline_time: Duration,
    /// Time of the surface build.
    pub build_time: Duration,
    /// The builder's report.
    pub report: BuildReport,
}

/// The relief of a stereo pair and its live updates (the vision thread's state).
pub struct StereoRelief {
    pub(super) pair: StereoPair,
    pub(super) geometry: RectifiedGeometry,
    pub(super) camera: PinholeCamera,
    pub(super) vision: VisionParams,
    pub(super) relief: ReliefParams,
    pub(super) live: LiveSettings,
    pub(super) pipeline: StereoPipeline,
    pub(super) segments: Vec<SceneSegment3>,
    pub(super) fresh: Vec<SceneSegment3>,
    /// The patch settings of `live` (`None`: off).
    pub(super) patches: Option<PatchParams>,
    /// The support points the relief is built with (left camera frame, metres).
    pub(super) points: Vec<[f64; 3]>,
    pub(super) patch_depth: PatchDepth,
}

impl StereoRelief {
    /// Runs the whole-image pipeline on `pair` and builds the relief laid out by `layout`.
    pub fn build(
        pair: StereoPair,
        layout: &ReliefLayout,
        live: LiveSettings,
    ) -> Result<(StereoRelief, ReliefModel, InitialBuild), String> {
        if !(live.roi_size_px.iter().all(|s| (8.0..=4096.0).contains(s))) {
            return Err(format!(
                "live region of interest {:?} px: each side must be in [8, 4096]",
                live.roi_size_px
            ));
        }
        if !(live.update_period_s.is_finite() && live.update_period_s > 0.0) {
            return Err(format!(
                "live update period {} s must be finite and > 0",
                live.update_period_s
            ));
        }
        if !(live.full_refresh_s.is_finite() && live.full_refresh_s > 0.0) {
            return Err(format!(
                "whole-image refresh period {} s must be finite and > 0",
                live.full_refresh_s
            ));
        }
        let geometry = pair.geometry();
        let mut vision = VisionParams::default();
        vision.matching.disparity_max_px = pair.camera.max_disparity_px;
        live.checks.apply(&mut vision.matching);
        // Live updates by the paper's criterion (no match of the whole-image run missed, no
        // new error in the region), with the context chosen from the data: about three times
        // faster than growing the windows until the region's matches are identical.
        vision.local.exact = false;
        let mut pipeline = StereoPipeline::new();
        let patches = patch_params(&live)?;
        let mut patch_depth = PatchDepth::default();
        let start = Instant::now();
        let (segments, matches, left_segments) = {
            let (segments, out) = run_whole(
                &mut pipeline,
                &pair,
                &geometry,
                &vision,
                patches.as_ref(),
                &mut patch_depth,
            )
            .map_err(|e| format!("{}: {e}", pair.name))?;
            (segments, out.matches.len(), out.left_segments.len())
        };
        let points = patch_depth.points.clone();
        let pipeline_time = start.elapsed();
        let depth_range_m =
            scene_depth_range(&segments).map_err(|e| format!("{}: {e}", pair.name))?;
        let relief = layout.params(pair.size_px(), depth_range_m)?;
        let camera = pinhole(&geometry);
        let start = Instant::now();
        let (model, report) = build_from_scene(&segments, &points, &camera, &relief)
            .map_err(|e| format!("{}: {e}", pair.name))?;
        let build_time = start.elapsed();
        let initial = InitialBuild {
            segments_3d: segments.len(),
            matches,
            left_segments,
            depth_range_m,
            pipeline_time,
            build_time,
            report,
        };
        Ok((
            StereoRelief {
                pair,
                geometry,
                camera,
                vision,
                relief,
                live,
                pipeline,
                segments,
                fresh: Vec::new(),
                patches,
                points,
                patch_depth,
            },
            model,
            initial,
        ))
    }

    /// The build settings (workspace and depth mapping).
    pub fn relief_params(&self) -> &ReliefParams {
        &self.relief
    }

    /// The pair.
    pub fn pair(&self) -> &StereoPair {
        &self.pair
    }

    /// Takes the next rectified frame of the same camera in place of the pair's images (the
    /// buffers are swapped, not copied: `left` and `right` get the old images' pixels). The
    /// segments and the relief stay as they are until the next update.
    pub fn swap_images(&mut self, left: &mut Vec<u8>, right: &mut Vec<u8>) -> Result<(), String> {
        let [w, h] = self.pair.size_px();
        let n = w as usize * h as usize;
        if left.len() != n || right.len() != n {
            return Err(format!(
                "{}: a frame of {} and {} pixels for a {w}x{h} pair",
                self.pair.name,
                left.len(),
                right.len()
            ));
        }
        for (image, pixels) in [(&mut self.pair.left, left), (&mut self.pair.right, right)] {
            let old = std::mem::replace(image, GrayImage::new(0, 0)).into_raw();
            let new = std::mem::replace(pixels, old);
            *image = GrayImage::from_raw(w, h, new).ok_or("frame of inconsistent size")?;
        }
        Ok(())
    }

    /// The segments the relief is built from now (with the far sides of occluding edges when
    /// [`LiveSettings::patch_spacing_px`] is on).
    pub fn segments(&self) -> &[SceneSegment3] {
        &self.segments
    }

    /// The support points the relief is built with now (left camera frame, metres; none when
    /// [`LiveSettings::patch_spacing_px`] is 0).
    pub fn points(&self) -> &[[f64; 3]] {
        &self.points
    }

    /// Re-runs the whole-image pipeline and rebuilds the relief from its segments (the scene
    /// depth range of the first build is kept). Returns the relief and the builder's report.
    pub fn refresh_full(&mut self) -> Result<(ReliefModel, BuildReport), String> {
        let (segments, _) = run_whole(
            &mut self.pipeline,
            &self.pair,
            &self.geometry,
            &self.vision,
            self.patches.as_ref(),
            &mut self.patch_depth,
        )?;
        let (model, report) = build_from_scene(
            &segments,
            &self.patch_depth.points,
            &self.camera,
            &self.relief,
        )
        .map_err(|e| e.to_string())?;
        self.segments = segments;
        self.points.clone_from(&self.patch_depth.points);
        Ok((model, report))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stereo_relief::PairCamera;

    #[test]
    fn the_configured_checks_default_to_the_matchers() {
        let config = videt_config::Config::default();
        assert_eq!(match_checks(&config.vision), MatchChecks::default());
        assert_eq!(LiveSettings::default().checks, MatchChecks::default());
    }

    #[test]
    fn the_configured_relief_shape_builds_the_cameras_relief_but_not_the_demo_box() {
        use videt_relief::ReliefShape;
        let mut config = videt_config::Config::default();
        let layout = videt_runtime::setup::relief_layout(&config);
        assert_eq!(layout.shape, ReliefShape::Stepped, "the default");
        config.vision.relief_shape = videt_config::ReliefShapeName::Interpolated;
        let interpolated = videt_runtime::setup::relief_layout(&config);
        assert_eq!(interpolated.shape, ReliefShape::Interpolated);
        let (relief, _, initial) = StereoRelief::build(
            StereoPair::demo().unwrap(),
            &layout,
            LiveSettings::default(),
        )
        .unwrap();
        assert_eq!(relief.relief_params().shape, ReliefShape::Stepped);
        assert!(initial.report.depth_steps > 0, "{:?}", initial.report);
        let (_, _, plain) = StereoRelief::build(
            StereoPair::demo().unwrap(),
            &interpolated,
            LiveSettings::default(),
        )
        .unwrap();
        assert_eq!(plain.report.depth_steps, 0, "{:?}", plain.report);
        // The demo box's sides are slopes by design: interpolated whatever the setting.
        let (_, report) = crate::relief_scene::box_relief(&layout, 0.0).unwrap();
        assert_eq!(report.depth_steps, 0, "{report:?}");
    }

    #[test]
    fn patches_bring_a_real_pairs_stepped_relief_closer_to_the_true_surface() {
        use videt_evaluation::{load_truth_pair, relief_deviation};
        use videt_relief::ReliefShape;
        use videt_vision::disparity_range::choose_max_disparity;
        // Venus and teddy: two of the four pairs the spacing was chosen on.
        for (name, scale) in [("venus", 8.0), ("teddy", 4.0)] {
            let Some(dir) = videt_testdata::data_dir(&format!("stereo/{name}")) else {
                return;
            };
            let p = load_truth_pair(&dir, name, scale, true).unwrap();
            let mut pipeline = StereoPipeline::new();
            let lv = GrayView::from_image(&p.left).unwrap();
            let rv = GrayView::from_image(&p.right).unwrap();
            let bound =
                choose_max_disparity(&mut pipeline, &lv, &rv, &VisionParams::default()).unwrap();
            let mut camera = PairCamera::nominal(p.left.width());
            camera.max_disparity_px = bound.max_px;
            let pair = StereoPair::new(p.name, p.left, p.right, camera).unwrap();
            let geometry = pair.geometry();
            let mut layout = videt_runtime::setup::relief_layout(&videt_config::Config::default());
            layout.shape = ReliefShape::Stepped;
            let off = |spacing: u32| {
                let live = LiveSettings {
                    patch_spacing_px: spacing,
                    ..LiveSettings::default()
                };
                let (relief, model, _) = StereoRelief::build(pair.clone(), &layout, live).unwrap();
                relief_deviation(&model, relief.relief_params(), &geometry, &p.truth)
                    .unwrap()
                    .phantom(0.005)
                    .deviating_fraction()
            };
            let (without, with) = (off(0), off(12));
            assert!(
                with < 0.7 * without && with < 0.10,
                "{name}: {:.1} % of the area more than 5 mm off with patches, {:.1} % without",
                100.0 * with,
                100.0 * without
            );
        }
    }
}
