//! The bas-relief from a real stereo pair, kept up to date around the finger.
//!
//! [`StereoRelief`] runs the stereo pipeline (rectified mode: Canny, segments, Ayache matching,
//! back-projection) on a pair, maps the 3D segments into the device workspace with a
//! [`ReliefLayout`] and builds the relief with the surface builder. Then, given the thimble's
//! position and velocity, it re-matches only the image region of interest under the finger (the
//! pipeline's local mode), replaces the segments inside that region with the fresh ones
//! ([`merge_region`]) and rebuilds the relief: the live update the vision thread publishes.
//!
//! The scene depth range mapped onto the relief depth is fixed at the first build (robust
//! percentiles of the segments' depths, so a few wrong matches do not flatten the relief), so
//! that a live update never rescales the whole relief.
//!
//! The demo pair ([`StereoPair::demo`]) is compiled in: Middlebury's "tsukuba" pair
//! (`assets/demo-stereo/`, attribution there).

use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use image::GrayImage;
use videt_relief::region::merge_region;
use videt_relief::{
    build_from_scene, BuildReport, PinholeCamera, ReliefModel, ReliefParams, SceneSegment3,
};
use videt_vision::matching::MatchChecks;
use videt_vision::patch_stereo::{PatchDepth, PatchParams};
use videt_vision::{
    GrayView, LocalRegion, PipelineOutput, PixelRect, RectifiedGeometry, Segment3d, StereoPipeline,
    VisionParams,
};

use videt_relief::ReliefLayout;
use videt_runtime::snapshot::{SnapshotReader, SnapshotWriter};
use videt_runtime::thimble::ThimbleState;

/// The demo pair's left image (PNG, Middlebury "tsukuba", 384 x 288).
pub const DEMO_LEFT_PNG: &[u8] = include_bytes!("../assets/demo-stereo/left.png");
/// The demo pair's right image (PNG).
pub const DEMO_RIGHT_PNG: &[u8] = include_bytes!("../assets/demo-stereo/right.png");
/// The demo pair's camera (`camera.toml`, nominal values: see the README there).
pub const DEMO_CAMERA_TOML: &str = include_str!("../assets/demo-stereo/camera.toml");

/// Lower and upper percentiles of the segments' endpoint depths mapped onto the relief range.
const DEPTH_PERCENTILES: [f64; 2] = [0.02, 0.98];

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

/// The left camera's pinhole of a rectified geometry.
pub fn pinhole(geometry: &RectifiedGeometry) -> PinholeCamera {
    PinholeCamera {
        focal_px: geometry.focal_px,
        cx_px: geometry.cx_px,
        cy_px: geometry.cy_px,
    }
}

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
fn measure_patches(
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

/// The pipeline's 3D segments as the surface builder's input (appended to `out`).
pub fn scene_segments(segments: &[Segment3d], out: &mut Vec<SceneSegment3>) {
    out.extend(segments.iter().map(|s| SceneSegment3 {
        a_m: [s.start_m.x, s.start_m.y, s.start_m.z],
        b_m: [s.end_m.x, s.end_m.y, s.end_m.z],
    }));
}

/// The scene depth range mapped onto the relief: the 2nd and 98th percentiles of the segments'
/// endpoint depths (in front of the camera), widened to at least 10 % of the far depth.
pub fn scene_depth_range(segments: &[SceneSegment3]) -> Result<[f64; 2], String> {
    let mut depths: Vec<f64> = segments
        .iter()
        .flat_map(|s| [s.a_m[2], s.b_m[2]])
        .filter(|z| z.is_finite() && *z > 0.0)
        .collect();
    if depths.is_empty() {
        return Err("no 3D segment in front of the camera: no scene depth range".into());
    }
    depths.sort_by(f64::total_cmp);
    let at = |q: f64| depths[((depths.len() - 1) as f64 * q).round() as usize];
    let (near, mut far) = (at(DEPTH_PERCENTILES[0]), at(DEPTH_PERCENTILES[1]));
    if far < near * 1.1 {
        far = near * 1.1;
    }
    Ok([near, far])
}

/// Device area a tool builds a relief on when there is no rig: 40 cm wide, at the origin.
pub const VIEW_AREA_WIDTH_M: f64 = 0.4;
/// Back plane of that relief, device `z`, metres.
pub const VIEW_BACK_PLANE_Z_M: f64 = 0.45;

/// Checks a relief depth for [`view_params`]: in `(0, 0.45)` metres.
pub fn check_view_relief_depth(relief_depth_m: f64) -> Result<(), String> {
    if relief_depth_m.is_finite() && relief_depth_m > 0.0 && relief_depth_m < VIEW_BACK_PLANE_Z_M {
        Ok(())
    } else {
        Err(format!(
            "relief depth {relief_depth_m} m must be in (0, {VIEW_BACK_PLANE_Z_M})"
        ))
    }
}

/// Build settings for one camera view without a rig (as `params_for_view` of the surface
/// module, but with the robust [`scene_depth_range`] and a chosen relief depth): the image
/// stretched over a 40 cm wide area at the origin (the image's aspect), `relief_depth_m` of
/// relief in front of a back plane at 45 cm.
pub fn view_params(
    segments: &[SceneSegment3],
    image_size_px: [u32; 2],
    relief_depth_m: f64,
) -> Result<ReliefParams, String> {
    check_view_relief_depth(relief_depth_m)?;
    let [w, h] = image_size_px;
    if w == 0 || h == 0 {
        return Err(format!("image size {w}x{h} has no pixels"));
    }
    let depth_range = scene_depth_range(segments)?;
    let size = [
        VIEW_AREA_WIDTH_M,
        VIEW_AREA_WIDTH_M * f64::from(h) / f64::from(w),
    ];
    let map = videt_control::SceneMap::new(
        [0.0, 0.0],
        size,
        image_size_px,
        VIEW_BACK_PLANE_Z_M,
        relief_depth_m,
        depth_range,
    )
    .map_err(|e| e.to_string())?;
    Ok(ReliefParams::new(map))
}

/// A short name for a rejection reason (for counting them by kind).
pub fn reason_label(reason: &videt_relief::RejectReason) -> &'static str {
    use videt_relief::RejectReason as R;
    match reason {
        R::NotFinite => "coordinate not finite",
        R::BehindCamera => "behind the camera",
        R::OutsideArea => "outside the explorable area",
        R::Degenerate => "shorter than the merge distance",
        R::Duplicate => "duplicate",
        R::CrossesNearerSegment { .. } => "crosses a nearer segment (occluded, kept as points)",
        R::OverlapsSegment { .. } => "overlaps a nearer segment (kept as points)",
        R::TriangulationConflict => "triangulation conflict",
    }
}

/// The build report as text: segments used and rejected (counted by reason), mesh size, time.
pub fn report_text(report: &BuildReport) -> String {
    use std::fmt::Write as _;
    let mut by_reason: Vec<(&'static str, usize)> = Vec::new();
    for r in &report.rejections {
        let label = reason_label(&r.reason);
        match by_reason.iter_mut().find(|(l, _)| *l == label) {
            Some((_, n)) => *n += 1,
            None => by_reason.push((label, 1)),
        }
    }
    let t = &report.timings;
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "surface: {} segments given, {} used as constraint edges ({} edges after {} crossings split), {} rejected",
        report.segments_in,
        report.constraints_kept,
        report.constraint_edges,
        report.crossings_split,
        report.rejections.len()
    );
    for (label, n) in by_reason {
        let _ = writeln!(s, "  rejected: {n:4} {label}");
    }
    let _ = writeln!(
        s,
        "mesh: {} vertices, {} triangles ({} points merged)",
        report.vertices, report.triangles, report.points_merged
    );
    let _ = writeln!(
        s,
        "build: {:.3} ms (cleaning {:.3}, crossings {:.3}, triangulation {:.3}, model {:.3})",
        ms(t.cleaning + t.crossings + t.triangulation + t.model),
        ms(t.cleaning),
        ms(t.crossings),
        ms(t.triangulation),
        ms(t.model)
    );
    s
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

/// Whether the pixel nearest `(u, v)` lies in `rect = [x0, y0, x1, y1]` (`x0 <= x < x1`, the
/// same for `y`).
fn in_pixel_rect(u: f64, v: f64, rect: [f64; 4]) -> bool {
    let (x, y) = (u.round(), v.round());
    x >= rect[0] && x < rect[2] && y >= rect[1] && y < rect[3]
}

/// The default of [`LiveSettings::patch_spacing_px`] and `vision.patch_spacing_px`.
pub const DEFAULT_PATCH_SPACING_PX: u32 = videt_config::DEFAULT_PATCH_SPACING_PX;

/// The patch settings of `live`: `None` when the patches are off (spacing 0).
fn patch_params(live: &LiveSettings) -> Result<Option<PatchParams>, String> {
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

/// Pieces shorter than this in the image are dropped after a merge, pixels.
const MIN_PIECE_PX: f64 = 1.0;

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

/// What a live update did.
#[derive(Debug, Clone)]
pub struct RegionUpdate {
    /// The region re-matched, left image pixels `[u0, v0, u1, v1]`.
    pub roi_px: [f64; 4],
    /// Fresh 3D segments the local run gave.
    pub fresh_segments: usize,
    /// Segments the rebuild was given (old outside the region, fresh inside).
    pub merged_segments: usize,
    /// Time of the local pipeline run.
    pub match_time: Duration,
    /// Time of the merge of the fresh segments into the old ones.
    pub merge_time: Duration,
    /// Time of the rebuild.
    pub build_time: Duration,
    /// The builder's report.
    pub report: BuildReport,
}

impl RegionUpdate {
    /// Whole update time (match + merge + build).
    pub fn total_time(&self) -> Duration {
        self.match_time + self.merge_time + self.build_time
    }
}

/// The relief of a stereo pair and its live updates (the vision thread's state).
pub struct StereoRelief {
    pair: StereoPair,
    geometry: RectifiedGeometry,
    camera: PinholeCamera,
    vision: VisionParams,
    relief: ReliefParams,
    live: LiveSettings,
    pipeline: StereoPipeline,
    segments: Vec<SceneSegment3>,
    fresh: Vec<SceneSegment3>,
    /// The patch settings of `live` (`None`: off).
    patches: Option<PatchParams>,
    /// The support points the relief is built with (left camera frame, metres).
    points: Vec<[f64; 3]>,
    patch_depth: PatchDepth,
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

    /// The left-image region of interest `(centre, velocity)` in pixels under a thimble at
    /// `position_m` moving at `velocity_m_s`, or `None` when the finger is not over the image.
    pub fn region_under(
        &self,
        position_m: [f64; 3],
        velocity_m_s: [f64; 3],
    ) -> Option<LocalRegion> {
        let map = &self.relief.scene_map;
        let [x, y, _] = position_m;
        let [u, v] = map.workspace_to_image(x, y);
        let [w, h] = map.image_size_px();
        if !(u.is_finite() && v.is_finite() && (0.0..w).contains(&u) && (0.0..h).contains(&v)) {
            return None;
        }
        // Pixels per metre along x and y (v grows with -y).
        let [u1, v1] = map.workspace_to_image(x + 1e-3, y + 1e-3);
        let (du, dv) = ((u1 - u) * 1e3, (v1 - v) * 1e3);
        let frame = self.live.update_period_s;
        let vel = [
            (velocity_m_s[0] * du * frame) as f32,
            (velocity_m_s[1] * dv * frame) as f32,
        ];
        Some(LocalRegion {
            centre_px: [u as f32, v as f32],
            size_px: self.live.roi_size_px,
            velocity_px_per_frame: if vel.iter().all(|c| c.is_finite()) {
                vel
            } else {
                [0.0, 0.0]
            },
        })
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

    /// Re-matches the region under the thimble, merges it into the segments and rebuilds the
    /// relief. `Ok(None)` when the finger is not over the image (nothing to update).
    pub fn update_around(
        &mut self,
        position_m: [f64; 3],
        velocity_m_s: [f64; 3],
    ) -> Result<Option<(ReliefModel, RegionUpdate)>, String> {
        let Some(region) = self.region_under(position_m, velocity_m_s) else {
            return Ok(None);
        };
        let start = Instant::now();
        let roi = {
            let lv = GrayView::from_image(&self.pair.left).map_err(|e| e.to_string())?;
            let rv = GrayView::from_image(&self.pair.right).map_err(|e| e.to_string())?;
            let out = self
                .pipeline
                .run_local(&lv, &rv, Some(&self.geometry), &self.vision, &region)
                .map_err(|e| format!("local stereo pipeline: {e}"))?;
            let Some(windows) = out.local else {
                return Err("local stereo pipeline returned no region".into());
            };
            self.fresh.clear();
            scene_segments(&out.segments_3d, &mut self.fresh);
            measure_patches(
                self.patches.as_ref(),
                &mut self.patch_depth,
                (&lv, &rv),
                &self.geometry,
                out,
                &self.vision,
                Some(windows.roi),
            );
            scene_segments(&self.patch_depth.far_sides, &mut self.fresh);
            let r = windows.roi;
            [
                r.x as f64,
                r.y as f64,
                (r.x + r.width) as f64,
                (r.y + r.height) as f64,
            ]
        };
        let match_time = start.elapsed();
        let start = Instant::now();
        let mut merged = merge_region(&self.segments, &self.fresh, &self.camera, roi);
        let camera = self.camera;
        merged.retain(|s| match (camera.project(&s.a_m), camera.project(&s.b_m)) {
            (Some((a, _)), Some((b, _))) => (a[0] - b[0]).hypot(a[1] - b[1]) >= MIN_PIECE_PX,
            // Not projectable: the builder rejects it with its reason.
            _ => true,
        });
        // The support points: the old ones outside the region, the fresh ones inside.
        // (The points are grid nodes, whole pixels: rounded back, a node is in the region when
        // its column and row are.)
        self.points.retain(|p| {
            camera
                .project(p)
                .is_none_or(|([u, v], _)| !in_pixel_rect(u, v, roi))
        });
        self.points.extend_from_slice(&self.patch_depth.points);
        let merge_time = start.elapsed();
        let start = Instant::now();
        let (model, report) = build_from_scene(&merged, &self.points, &self.camera, &self.relief)
            .map_err(|e| e.to_string())?;
        let build_time = start.elapsed();
        let update = RegionUpdate {
            roi_px: roi,
            fresh_segments: self.fresh.len(),
            merged_segments: merged.len(),
            match_time,
            merge_time,
            build_time,
            report,
        };
        self.segments = merged;
        Ok(Some((model, update)))
    }
}

/// Counters of the live updates, shared between the vision thread and the status line.
#[derive(Debug, Default)]
pub struct LiveStats {
    updates: AtomicU64,
    failures: AtomicU64,
    keepalives: AtomicU64,
    full_refreshes: AtomicU64,
    last_update_us: AtomicU64,
    max_update_us: AtomicU64,
}

impl LiveStats {
    /// Live region updates published.
    pub fn updates(&self) -> u64 {
        self.updates.load(Ordering::Relaxed)
    }

    /// Updates that failed (the previous relief stays).
    pub fn failures(&self) -> u64 {
        self.failures.load(Ordering::Relaxed)
    }

    /// The unchanged relief re-published because the finger was away from the image.
    pub fn keepalives(&self) -> u64 {
        self.keepalives.load(Ordering::Relaxed)
    }

    /// Whole-image runs published.
    pub fn full_refreshes(&self) -> u64 {
        self.full_refreshes.load(Ordering::Relaxed)
    }

    /// Time of the last update and of the slowest one (match + rebuild), microseconds.
    pub fn update_time_us(&self) -> [u64; 2] {
        [
            self.last_update_us.load(Ordering::Relaxed),
            self.max_update_us.load(Ordering::Relaxed),
        ]
    }

    /// Records one published update that took `time`.
    pub fn record_update(&self, time: Duration) {
        let us = time.as_micros().min(u128::from(u64::MAX)) as u64;
        self.updates.fetch_add(1, Ordering::Relaxed);
        self.last_update_us.store(us, Ordering::Relaxed);
        self.max_update_us.fetch_max(us, Ordering::Relaxed);
    }

    /// For the status line: `relief: N live updates (last X ms, max Y ms)`.
    pub fn status_text(&self) -> String {
        let [last, max] = self.update_time_us();
        let failures = match self.failures() {
            0 => String::new(),
            n => format!(", {n} failed"),
        };
        format!(
            "  relief: {} live updates (last {:.1} ms, max {:.1} ms{failures}), {} whole-image",
            self.updates(),
            last as f64 * 1e-3,
            max as f64 * 1e-3,
            self.full_refreshes()
        )
    }
}

/// Start the vision thread (`videt-vision`) of a stereo relief: at the live update rate it
/// reads the newest thimble state, re-matches the region under the finger and publishes the
/// rebuilt relief (every `full_refresh_s` a whole-image run instead); when the finger is not
/// over the image it re-publishes the current relief every `keepalive_s` seconds (the relief
/// is not stale: vision is running). The thread runs SCHED_FIFO at `fifo_priority` when one is
/// given (`realtime.vision_priority`), else SCHED_OTHER. Runs until the process ends.
pub fn spawn_live_updates(
    mut relief: StereoRelief,
    initial: ReliefModel,
    mut writer: SnapshotWriter<ReliefModel>,
    mut thimble: SnapshotReader<ThimbleState>,
    stats: Arc<LiveStats>,
    keepalive_s: f64,
    fifo_priority: Option<u8>,
) -> std::io::Result<std::thread::JoinHandle<()>> {
    let period = Duration::from_secs_f64(relief.live.update_period_s);
    let keepalive = Duration::from_secs_f64(keepalive_s.clamp(1e-3, 3600.0));
    let full_refresh = Duration::from_secs_f64(relief.live.full_refresh_s.clamp(1e-3, 1e6));
    std::thread::Builder::new()
        .name("videt-vision".into())
        .spawn(move || {
            videt_runtime::rt::enter_vision_priority(fifo_priority);
            let mut current = initial;
            let mut next_tick = Instant::now() + period;
            let mut last_publish = Instant::now();
            let mut last_full = Instant::now();
            loop {
                let now = Instant::now();
                if next_tick > now {
                    std::thread::sleep(next_tick - now);
                }
                next_tick += period;
                if next_tick + period < Instant::now() {
                    // Fell behind (a slow update): do not try to catch up.
                    next_tick = Instant::now() + period;
                }
                if last_full.elapsed() >= full_refresh {
                    last_full = Instant::now();
                    match relief.refresh_full() {
                        Ok((model, _)) => {
                            current = model;
                            writer.publish_with(|slot| slot.clone_from(&current));
                            stats.full_refreshes.fetch_add(1, Ordering::Relaxed);
                            last_publish = Instant::now();
                        }
                        Err(e) => {
                            if stats.failures.fetch_add(1, Ordering::Relaxed) < 10 {
                                tracing::warn!("whole-image relief refresh failed (the previous relief stays): {e}");
                            }
                        }
                    }
                    continue;
                }
                let state = thimble.latest();
                let (version, position, velocity) = (
                    state.version,
                    state.value.position_m,
                    state.value.velocity_m_s,
                );
                // The stored pair stands for a frame captured as the update starts.
                let captured = videt_hal::Clock::now(&videt_runtime::rt::SystemClock);
                let update = if version == 0 {
                    Ok(None) // the control loop has not published a position yet
                } else {
                    relief.update_around(position, velocity)
                };
                match update {
                    Ok(Some((model, update))) => {
                        current = model;
                        writer.publish_captured_with(Some(captured), |slot| {
                            slot.clone_from(&current)
                        });
                        stats.record_update(update.total_time());
                        last_publish = Instant::now();
                    }
                    Ok(None) => {}
                    Err(e) => {
                        if stats.failures.fetch_add(1, Ordering::Relaxed) < 10 {
                            tracing::warn!(
                                "live relief update failed (the previous relief stays): {e}"
                            );
                        }
                    }
                }
                if last_publish.elapsed() >= keepalive {
                    writer.publish_with(|slot| slot.clone_from(&current));
                    stats.keepalives.fetch_add(1, Ordering::Relaxed);
                    last_publish = Instant::now();
                }
            }
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_configured_checks_default_to_the_matchers() {
        let config = videt_config::Config::default();
        assert_eq!(match_checks(&config.vision), MatchChecks::default());
        assert_eq!(LiveSettings::default().checks, MatchChecks::default());
    }

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
    fn depth_range_ignores_a_few_outliers() {
        let seg = |z: f64| SceneSegment3 {
            a_m: [0.0, 0.0, z],
            b_m: [0.1, 0.0, z],
        };
        let mut segs: Vec<_> = (0..100).map(|k| seg(2.0 + k as f64 * 0.02)).collect();
        segs.push(seg(0.01));
        segs.push(seg(f64::NAN));
        let [near, far] = scene_depth_range(&segs).unwrap();
        assert!(near > 1.9 && far < 4.1 && far > 3.8, "{near} {far}");
        assert!(scene_depth_range(&[seg(-1.0)]).is_err());
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
    fn patches_add_far_sides_and_points_and_an_update_renews_only_those_in_its_region() {
        let layout = videt_runtime::setup::relief_layout(&videt_config::Config::default());
        let (_, _, plain) = StereoRelief::build(
            StereoPair::demo().unwrap(),
            &layout,
            LiveSettings {
                patch_spacing_px: 0,
                ..LiveSettings::default()
            },
        )
        .unwrap();
        let (mut relief, model, initial) = StereoRelief::build(
            StereoPair::demo().unwrap(),
            &layout,
            LiveSettings {
                patch_spacing_px: 12,
                ..LiveSettings::default()
            },
        )
        .unwrap();
        assert!(relief.points().len() > 100, "{}", relief.points().len());
        // The far sides of occluding edges join the segments.
        assert!(
            initial.segments_3d > plain.segments_3d,
            "{} with patches, {} without",
            initial.segments_3d,
            plain.segments_3d
        );
        let before = relief.points().to_vec();
        let [cx, cy] = layout.centre_m;
        let (_, update) = relief
            .update_around([cx, cy, 0.3], [0.0; 3])
            .unwrap()
            .unwrap();
        let r = update.roi_px;
        let camera = relief.camera;
        let inside = |p: &[f64; 3]| {
            let ([u, v], _) = camera.project(p).unwrap();
            in_pixel_rect(u, v, r)
        };
        let split = |points: &[[f64; 3]]| {
            let (mut a, mut b): (Vec<_>, Vec<_>) = points.iter().copied().partition(inside);
            let key = |p: &[f64; 3]| p.map(f64::to_bits);
            a.sort_by_key(key);
            b.sort_by_key(key);
            (a, b)
        };
        let (in_before, out_before) = split(&before);
        let (in_after, out_after) = split(relief.points());
        assert!(
            !in_before.is_empty(),
            "no support point in the region {r:?}"
        );
        // Outside the region the points stay; inside, the same images give them again.
        assert_eq!(out_after, out_before);
        assert_eq!(in_after, in_before);
        // A whole-image run measures them all anew: the same relief.
        let (refreshed, _) = relief.refresh_full().unwrap();
        assert_eq!(refreshed, model);
        assert!(patch_params(&LiveSettings {
            patch_spacing_px: 3,
            ..LiveSettings::default()
        })
        .unwrap_err()
        .contains("[4, 64]"));
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

    #[test]
    fn demo_pair_builds_a_relief_and_updates_it_around_the_finger() {
        let config = videt_config::Config::default();
        let layout = videt_runtime::setup::relief_layout(&config);
        let (mut relief, model, initial) = StereoRelief::build(
            StereoPair::demo().unwrap(),
            &layout,
            LiveSettings::default(),
        )
        .unwrap();
        assert!(initial.segments_3d > 50, "{}", initial.segments_3d);
        assert!(initial.report.constraints_kept > 30, "{:?}", initial.report);
        let back = model.back_plane_z_m();
        let front = back - layout.relief_depth_m;
        for v in model.vertices() {
            assert!(v[2] >= front - 1e-9 && v[2] <= back + 1e-9, "{v:?}");
        }
        let initial_segments = relief.segments().to_vec();
        // Over the centre of the area: an update; off the area: none.
        let [cx, cy] = layout.centre_m;
        let (updated, update) = relief
            .update_around([cx, cy, 0.3], [0.02, 0.0, 0.0])
            .unwrap()
            .unwrap();
        assert!(update.fresh_segments > 0, "{update:?}");
        assert!(update.roi_px[2] > update.roi_px[0] && update.roi_px[3] > update.roi_px[1]);
        // The region re-matched on the same images finds the whole-image run's segments there
        // again (same pixels, same depths), but for the few whose chains the local window cuts.
        let camera = relief.camera;
        let image_of = |s: &SceneSegment3| {
            let (a, za) = camera.project(&s.a_m).unwrap();
            let (b, zb) = camera.project(&s.b_m).unwrap();
            (a, b, za, zb)
        };
        let found_again = relief
            .fresh
            .iter()
            .filter(|f| {
                let (fa, fb, fza, fzb) = image_of(f);
                initial_segments.iter().any(|o| {
                    let (oa, ob, oza, ozb) = image_of(o);
                    let near = |p: [f64; 2], q: [f64; 2]| (p[0] - q[0]).hypot(p[1] - q[1]) < 1.0;
                    near(fa, oa)
                        && near(fb, ob)
                        && (fza / oza - 1.0).abs() < 0.02
                        && (fzb / ozb - 1.0).abs() < 0.02
                })
            })
            .count();
        assert!(
            found_again * 4 >= update.fresh_segments * 3,
            "{found_again} of {} fresh segments found again",
            update.fresh_segments
        );
        assert!(update.merged_segments >= initial_segments.len() - 5);
        assert_eq!(updated.back_plane_z_m(), model.back_plane_z_m());
        // Many updates along a sweep: pieces accumulate a little; a whole-image run resets them.
        for k in 0..40 {
            let x = cx - 0.07 + 0.0035 * k as f64;
            relief
                .update_around([x, cy + 0.03, 0.3], [0.05, 0.0, 0.0])
                .unwrap()
                .unwrap();
        }
        let (refreshed, _) = relief.refresh_full().unwrap();
        assert_eq!(relief.segments().len(), initial.segments_3d);
        assert_eq!(refreshed, model);
        assert!(relief
            .update_around([cx + 1.0, cy, 0.3], [0.0; 3])
            .unwrap()
            .is_none());
    }
}
