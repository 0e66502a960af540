//! Phantom relief per stereo pair: what wrong matches make the wearer feel, with the matcher's
//! checks against wrong matches off and as the defaults set them.
//!
//! Each pair's bas-relief is built as the product builds it and compared, pixel by pixel, with
//! the true surface on the device (`videt_evaluation::relief`: every left pixel of
//! known true disparity is mapped onto the explorable area with the relief's scene map, and the
//! relief's height there is compared with the true surface's along the device's `z`). A pixel
//! **deviates** when the two differ by more than the threshold (default 5 mm).
//!
//! Much of that deviation is there even when every match is correct: the relief interpolates
//! between correct segments across depth steps and ramps down to the back plane at the border.
//! That is the **floor**: the deviation of the relief built from only the correct matches. The
//! **phantom area** proper is the excess over it
//! ([`ReliefDeviation::excess_over`](videt_evaluation::ReliefDeviation::excess_over)):
//! the pixels deviating in a relief but not in the floor relief, the deviation the wrong
//! matches add (when the relief keeps every correct match of the floor, see below). It is
//! reported in cm^2 of explorable area with its largest 4-connected region (one phantom ridge
//! or hole under the finger).
//!
//! Pairs: the shared Middlebury pairs (`stereo/NAME` of the test data) and every directory under
//! the extra directory (default `target/extra-stereo`, `scripts/fetch-extra-stereo.sh`) holding a
//! `scale.txt` (`left.ppm|png`, `right.ppm|png`, `disp_left.pgm` divided by the scale, occlusions
//! masked by `disp_right.pgm` when there is one).
//!
//! Each pair is run as the product runs a stereo pair: the nominal camera
//! ([`PairCamera::nominal`]), the disparity bound measured on the pair
//! ([`choose_max_disparity`]), the whole-image pipeline, the 3D segments as scene segments
//! ([`scene_segments`]). Rows per pair, every match judged against the ground truth ([`judge`],
//! as [`evaluate`](videt_evaluation::evaluate) judges them):
//! - `before`: [`VisionParams::default`] with `matching.mutual_check`, `matching.surface_check`
//!   off and `matching.min_confidence` 0 (the matcher without any check);
//! - `after`: [`VisionParams::default`] as it is (the checks it has on are printed);
//! - `correct only`: the floor, from only `before`'s matches judged correct;
//! - `after correct`: from only `after`'s matches judged correct.
//!
//! Every row of a pair is built with the same scene map, `before`'s (its segments' 2nd..98th
//! percentile of depth mapped onto the relief depth), so that the rows differ only by their
//! segments, not by a rescaled relief. The relief is laid out as the service lays it out in
//! front of the default rig ([`ReliefLayout::for_config`]: the image over a 20 x 15 cm area,
//! 4 cm of relief in front of a back plane at 36 cm, the rig's scale); with `--view` as `videt vision --surface` lays out a stereo view without a
//! rig instead (the image over a 40 cm wide area, 8 cm of relief, back plane at 45 cm,
//! [`view_params`]'s layout).
//!
//! Columns per row: the back-projected matches (those that shape the relief), how many are
//! judged wrong and unevaluated (no truth along them), the scene depths mapped onto the relief,
//! the evaluated area (known truth, inside the area's frame), the total deviating area and its
//! fraction of the evaluated area, the phantom area (excess over the floor) and its largest
//! region, and (`own`) the excess over the relief of the row's own correct matches.
//!
//! The excess over the floor is what the wrong matches add only when the row keeps every
//! correct match of the floor, as `before` does. A check also drops correct matches, and the
//! relief then interpolates where they were: `after`'s phantom area is split into its excess
//! over `after correct` (by the wrong matches it keeps) and `after correct`'s excess over the
//! floor (by the correct matches it drops); the two overlap little, but need not add up
//! exactly. The final summary table puts `before` and `after`
//! side by side per pair: wrong and correct matches, phantom area, its largest region, the
//! total deviating fraction (and the floor's), and that split.
//!
//! `cargo run --release -p videt-evaluation --example phantom_relief -- [--view] [--extra DIR]
//! [--threshold-mm MM] [--after-checks LIST] [--figure FILE.png] [--figure-pairs a,b,c]
//! [--pairs a,b,c] [--shape interpolated|stepped] [--step-height-mm MM] [--step-slope S]
//! [--step-width-mm MM] [--step-wall-slope S] [--patch-spacing PX]` (`--pairs`: only these pairs; `--shape` and `--step-*`: the relief
//! builder's [`ReliefShape`] and step settings instead of the defaults'; `--patch-spacing`:
//! depth from image patches as `vision.patch_spacing_px` sets it, 0 off, the default the
//! configuration's: the far sides of occluding edges join the segments of their matches, judged
//! as their matches, and the support points join every row, the floor's too)
//! (`--after-checks`: `after`'s checks instead of the defaults', `none` or a comma-separated
//! list of `left-right`, `surface`, `confidence=T`).
//!
//! With `--figure FILE.png` it writes one PNG: a row per pair of `--figure-pairs` (default:
//! `syn-shelf`, `tsukuba`, `motorcycle`, `cones`, those that exist), the columns `before` and
//! `after`: the left image greyed, darker where not evaluated, the phantom pixels (excess over
//! the floor: wrong matches kept and correct ones dropped alike) red, the other deviating pixels
//! (deviating in the floor too) light blue.

use std::path::{Path, PathBuf};
use std::sync::Once;

use image::imageops::FilterType;
use image::{GrayImage, Rgb, RgbImage};
use plotters::prelude::*;
use plotters::style::FontStyle;
use videt_config::{PATCH_SPACING_ALLOWED, PATCH_SPACING_RANGE_PX};
use videt_evaluation::{
    judge, load_extra_pairs, load_truth_pair, relief_deviation, DisparityMap, MatchVerdict,
    PhantomArea, ReliefDeviation, TruthPair, MIDDLEBURY_PAIRS,
};
use videt_relief::{build_from_scene, ReliefLayout, ReliefParams, ReliefShape, SceneSegment3};
use videt_service::stereo_relief::{
    pinhole, scene_depth_range, scene_segments, view_params, PairCamera, StereoPair,
};
use videt_vision::disparity_range::choose_max_disparity;
use videt_vision::matching::MatchChecks;
use videt_vision::patch_stereo::{PatchDepth, PatchParams};
use videt_vision::{GrayView, RectifiedGeometry, StereoPipeline, VisionParams};

/// The relief depth of a stereo view without a rig: `videt vision --surface`'s default
/// `--relief-depth`, metres.
const VIEW_RELIEF_DEPTH_M: f64 = 0.08;

/// Default deviation threshold, millimetres.
const DEFAULT_THRESHOLD_MM: f64 = 5.0;

/// The pairs of the figure unless `--figure-pairs` names others.
const DEFAULT_FIGURE_PAIRS: [&str; 4] = ["syn-shelf", "tsukuba", "motorcycle", "cones"];

/// Width of one image in the figure, pixels.
const FIGURE_CELL_WIDTH: u32 = 480;

/// The matcher without any check against wrong matches.
fn without_checks() -> VisionParams {
    let mut p = VisionParams::default();
    MatchChecks::NONE.apply(&mut p.matching);
    p
}

/// The checks against wrong matches `params` has on (`none`, or a list of `left-right`,
/// `surface`, `confidence=T`).
fn checks_on(params: &VisionParams) -> String {
    MatchChecks::of(&params.matching).to_string()
}

/// How the relief is laid out on the device.
#[derive(Debug, Clone, Copy)]
enum Layout {
    /// `view_params`: 40 cm wide, 8 cm deep, back plane at 45 cm.
    View,
    /// The service's layout in front of the default rig.
    Rig(ReliefLayout),
}

impl Layout {
    fn params(
        &self,
        segments: &[SceneSegment3],
        size_px: [u32; 2],
    ) -> Result<ReliefParams, String> {
        match self {
            Layout::View => view_params(segments, size_px, VIEW_RELIEF_DEPTH_M),
            Layout::Rig(layout) => layout.params(size_px, scene_depth_range(segments)?),
        }
    }
}

/// A pair with its ground truth.
struct Pair {
    name: String,
    stereo: StereoPair,
    truth: DisparityMap,
}

/// The pair as the service would run it: the nominal camera.
fn as_stereo(p: TruthPair) -> Result<Pair, String> {
    let camera = PairCamera::nominal(p.left.width());
    Ok(Pair {
        stereo: StereoPair::new(p.name.clone(), p.left, p.right, camera)?,
        name: p.name,
        truth: p.truth,
    })
}

/// One run's 3D segments with the verdict on the match each comes from.
struct Run {
    segments: Vec<SceneSegment3>,
    verdicts: Vec<MatchVerdict>,
    points: Vec<[f64; 3]>,
}

impl Run {
    /// The segments of the matches judged correct.
    fn correct_only(&self) -> Run {
        let (segments, verdicts) = self
            .segments
            .iter()
            .zip(&self.verdicts)
            .filter(|(_, v)| **v == MatchVerdict::Correct)
            .map(|(s, v)| (*s, *v))
            .unzip();
        Run {
            segments,
            verdicts,
            points: self.points.clone(),
        }
    }

    fn count(&self, verdict: MatchVerdict) -> usize {
        self.verdicts.iter().filter(|&&v| v == verdict).count()
    }
}

/// The whole-image pipeline on `pair` with `params` and the disparity bound measured on the
/// pair (as `videt vision` does by default); every back-projected match judged against the
/// truth.
fn run(
    pipeline: &mut StereoPipeline,
    pair: &Pair,
    geometry: &RectifiedGeometry,
    params: &VisionParams,
    patches: Option<&PatchParams>,
) -> Result<Run, String> {
    let lv = GrayView::from_image(&pair.stereo.left).map_err(|e| e.to_string())?;
    let rv = GrayView::from_image(&pair.stereo.right).map_err(|e| e.to_string())?;
    let mut params = *params;
    params.matching.disparity_max_px = choose_max_disparity(pipeline, &lv, &rv, &params)
        .map_err(|e| e.to_string())?
        .max_px;
    let out = pipeline
        .run(&lv, &rv, Some(geometry), &params)
        .map_err(|e| format!("stereo pipeline: {e}"))?;
    let mut segments_3d = out.segments_3d.clone();
    let mut patch_depth = PatchDepth::default();
    if let Some(patches) = patches {
        patch_depth.measure(
            &lv,
            &rv,
            geometry,
            out,
            params.matching.disparity_max_px,
            params.disparity_sigma_px,
            None,
            patches,
        );
        segments_3d.extend_from_slice(&patch_depth.far_sides);
    }
    let mut segments = Vec::with_capacity(segments_3d.len());
    scene_segments(&segments_3d, &mut segments);
    // A far side is judged as the match whose edge it is beside.
    let verdicts = segments_3d
        .iter()
        .map(|s| {
            let m = &out.matches[s.match_index as usize];
            judge(
                &out.left_segments[m.left as usize],
                &out.right_segments[m.right as usize],
                m,
                &pair.truth,
            )
        })
        .collect();
    Ok(Run {
        segments,
        verdicts,
        points: patch_depth.points,
    })
}

/// The deviation from the truth of the relief of `segments` built with `params`.
fn deviation_of(
    pair: &Pair,
    params: &ReliefParams,
    segments: &[SceneSegment3],
    points: &[[f64; 3]],
) -> Result<ReliefDeviation, String> {
    let geometry = pair.stereo.geometry();
    let (model, _) = build_from_scene(segments, points, &pinhole(&geometry), params)
        .map_err(|e| e.to_string())?;
    relief_deviation(&model, params, &geometry, &pair.truth).map_err(|e| e.to_string())
}

/// One row of a pair's table.
struct Row {
    matches: usize,
    wrong: usize,
    unevaluated: usize,
    /// Every deviating pixel.
    total: PhantomArea,
    /// The deviating pixels not deviating in the floor.
    excess: PhantomArea,
    /// The deviating pixels not deviating in the relief of this row's own correct matches
    /// (`None` for the reliefs of correct matches only).
    own: Option<PhantomArea>,
    deviation: ReliefDeviation,
}

/// A pair's rows, all on `before`'s scene map: `before`, `after`, the floor (`correct only`,
/// `before`'s correct matches) and `after`'s correct matches only.
struct PairResult {
    name: String,
    depth_range_m: [f64; 2],
    before: Row,
    after: Row,
    floor: Row,
    after_correct: Row,
}

impl PairResult {
    fn rows(&self) -> [(&'static str, &Row); 4] {
        [
            ("before", &self.before),
            ("after", &self.after),
            ("correct only", &self.floor),
            ("after correct", &self.after_correct),
        ]
    }
}

fn measure(
    pipeline: &mut StereoPipeline,
    pair: &Pair,
    layout: Layout,
    threshold_m: f64,
    after_params: &VisionParams,
    shape: &ShapeOptions,
) -> Result<PairResult, String> {
    let geometry = pair.stereo.geometry();
    let patches = shape.patches();
    let before = run(
        pipeline,
        pair,
        &geometry,
        &without_checks(),
        patches.as_ref(),
    )
    .map_err(|e| format!("before: {e}"))?;
    let after = run(pipeline, pair, &geometry, after_params, patches.as_ref())
        .map_err(|e| format!("after: {e}"))?;
    let mut params = layout.params(&before.segments, pair.stereo.size_px())?;
    shape.apply(&mut params);
    let depth_range_m = scene_depth_range(&before.segments)?;
    // A row: `r`'s relief, its excess over the floor (over itself for the floor) and over
    // `own_floor`.
    let row = |r: &Run,
               floor: Option<&ReliefDeviation>,
               own_floor: Option<&ReliefDeviation>|
     -> Result<Row, String> {
        let deviation = deviation_of(pair, &params, &r.segments, &r.points)?;
        let excess_over = |floor: &ReliefDeviation| {
            deviation
                .excess_over(floor, threshold_m)
                .map_err(|e| e.to_string())
        };
        Ok(Row {
            matches: r.segments.len(),
            wrong: r.count(MatchVerdict::Wrong),
            unevaluated: r.count(MatchVerdict::Unevaluated),
            total: deviation.phantom(threshold_m),
            excess: excess_over(floor.unwrap_or(&deviation))?,
            own: own_floor.map(excess_over).transpose()?,
            deviation,
        })
    };
    let floor = row(&before.correct_only(), None, None)?;
    let after_correct = row(&after.correct_only(), Some(&floor.deviation), None)?;
    Ok(PairResult {
        name: pair.name.clone(),
        depth_range_m,
        before: row(&before, Some(&floor.deviation), Some(&floor.deviation))?,
        after: row(
            &after,
            Some(&floor.deviation),
            Some(&after_correct.deviation),
        )?,
        floor,
        after_correct,
    })
}

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

/// Red: phantom (deviating here, not in the floor).
const PHANTOM: Rgb<u8> = Rgb([225, 25, 25]);
/// Light blue: deviating here and in the floor.
const FLOOR: Rgb<u8> = Rgb([140, 195, 245]);

/// The left image greyed, darker where not evaluated, the excess over `floor` red, the other
/// deviating pixels light blue.
fn cell(
    left: &GrayImage,
    deviation: &ReliefDeviation,
    floor: &ReliefDeviation,
    threshold_m: f64,
) -> Result<RgbImage, String> {
    let excess = deviation
        .excess_mask(floor, threshold_m)
        .map_err(|e| e.to_string())?;
    let deviating = deviation.deviating_mask(threshold_m);
    let width = deviation.width;
    Ok(RgbImage::from_fn(left.width(), left.height(), |x, y| {
        let i = y as usize * width + x as usize;
        let g = left.get_pixel(x, y)[0];
        if excess[i] {
            PHANTOM
        } else if deviating[i] {
            FLOOR
        } else if deviation.at(x as usize, y as usize).is_some() {
            let v = 110 + g / 2;
            Rgb([v, v, v])
        } else {
            let v = g / 3;
            Rgb([v, v, v])
        }
    }))
}

/// The figure: a row per pair of `results` (with its left image), the columns `before` and
/// `after`; written to a temporary name next to `path`, then renamed.
fn write_figure(
    path: &Path,
    results: &[(&PairResult, &GrayImage)],
    after_checks: &str,
    layout_label: &str,
    threshold_mm: f64,
) -> Result<(), Box<dyn std::error::Error>> {
    register_font();
    let threshold_m = threshold_mm * 1e-3;
    let margin = 12u32;
    let title_h = 80u32;
    let label_h = 24u32;
    let legend_h = 30u32;
    let cells: Vec<[RgbImage; 2]> = results
        .iter()
        .map(|(r, left)| -> Result<[RgbImage; 2], String> {
            let scale = |im: RgbImage| {
                let h = (f64::from(im.height()) * f64::from(FIGURE_CELL_WIDTH)
                    / f64::from(im.width()))
                .round() as u32;
                image::imageops::resize(&im, FIGURE_CELL_WIDTH, h.max(1), FilterType::Triangle)
            };
            Ok([
                scale(cell(
                    left,
                    &r.before.deviation,
                    &r.floor.deviation,
                    threshold_m,
                )?),
                scale(cell(
                    left,
                    &r.after.deviation,
                    &r.floor.deviation,
                    threshold_m,
                )?),
            ])
        })
        .collect::<Result<_, _>>()?;
    let width = 3 * margin + 2 * FIGURE_CELL_WIDTH;
    let height = title_h
        + cells
            .iter()
            .map(|c| label_h + c[0].height() + margin)
            .sum::<u32>()
        + legend_h;
    let mut buffer = vec![255u8; (width * height * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, (width, height)).into_drawing_area();
        let text = |s: &str, x: u32, y: u32, size: u32| {
            root.draw(&Text::new(
                s.to_string(),
                (x as i32, y as i32),
                ("sans-serif", size).into_font().color(&BLACK),
            ))
        };
        text(
            &format!(
                "Phantom relief: deviating by > {threshold_mm} mm from the true surface, not in \
                 the correct-only relief"
            ),
            margin,
            6,
            17,
        )?;
        text(layout_label, margin, 30, 15)?;
        text("before: no check against wrong matches", margin, 56, 15)?;
        text(
            &format!("after: {after_checks}"),
            2 * margin + FIGURE_CELL_WIDTH,
            56,
            15,
        )?;
        let mut y = title_h;
        for ((r, _), c) in results.iter().zip(&cells) {
            for (k, row) in [&r.before, &r.after].into_iter().enumerate() {
                let x = margin + k as u32 * (FIGURE_CELL_WIDTH + margin);
                text(
                    &format!(
                        "{}: {} wrong, phantom {:.1} cm² (largest {:.1}), deviating {:.0}%",
                        r.name,
                        row.wrong,
                        row.excess.deviating_area_m2 * 1e4,
                        row.excess.largest_region_m2 * 1e4,
                        100.0 * row.total.deviating_fraction()
                    ),
                    x,
                    y + 4,
                    14,
                )?;
            }
            y += label_h + c[0].height() + margin;
        }
        let swatch =
            |colour: Rgb<u8>, x: u32, label: &str| -> Result<(), Box<dyn std::error::Error>> {
                let top = (y + 8) as i32;
                root.draw(&Rectangle::new(
                    [(x as i32, top), (x as i32 + 14, top + 14)],
                    RGBColor(colour[0], colour[1], colour[2]).filled(),
                ))?;
                text(label, x + 20, y + 7, 14)?;
                Ok(())
            };
        swatch(
            PHANTOM,
            margin,
            "phantom: deviating, not in the correct-only relief",
        )?;
        swatch(
            FLOOR,
            margin + 380,
            "deviating in the correct-only relief too",
        )?;
        swatch(Rgb([40, 40, 40]), margin + 680, "not evaluated")?;
        root.present()?;
    }
    let mut figure =
        RgbImage::from_raw(width, height, buffer).ok_or("figure buffer of the wrong size")?;
    let mut y = title_h;
    for c in &cells {
        for (k, im) in c.iter().enumerate() {
            let x = margin + k as u32 * (FIGURE_CELL_WIDTH + margin);
            image::imageops::replace(&mut figure, im, i64::from(x), i64::from(y + label_h));
        }
        y += label_h + c[0].height() + margin;
    }
    let name = path
        .file_name()
        .ok_or_else(|| format!("{}: not a file name", path.display()))?
        .to_string_lossy();
    let tmp = path.with_file_name(format!(".{name}.tmp"));
    figure.save_with_format(&tmp, image::ImageFormat::Png)?;
    std::fs::rename(&tmp, path)?;
    Ok(())
}

/// The relief builder's shape settings given on the command line (`--shape`, `--step-*`);
/// the defaults' where not given.
#[derive(Debug, Clone, Copy, Default)]
struct ShapeOptions {
    shape: Option<ReliefShape>,
    /// `--patch-spacing`: depth from patches on a grid this many pixels apart (0: off).
    patch_spacing_px: usize,
    step_min_height_m: Option<f64>,
    step_min_slope: Option<f64>,
    step_width_m: Option<f64>,
    step_max_wall_slope: Option<f64>,
}

impl ShapeOptions {
    fn parse(value_of: impl Fn(&str) -> Option<String>) -> Result<ShapeOptions, String> {
        let number = |flag: &str, scale: f64| -> Result<Option<f64>, String> {
            value_of(flag)
                .map(|v| {
                    v.parse::<f64>()
                        .map(|x| x * scale)
                        .map_err(|e| format!("{flag} {v}: {e}"))
                })
                .transpose()
        };
        let shape = match value_of("--shape").as_deref() {
            None => None,
            Some("interpolated") => Some(ReliefShape::Interpolated),
            Some("stepped") => Some(ReliefShape::Stepped),
            Some(other) => {
                return Err(format!(
                    "--shape {other}: expected `interpolated` or `stepped`"
                ))
            }
        };
        let patch_spacing_px = match value_of("--patch-spacing") {
            // The segments alone unless asked: the paper's relief (the service's default
            // is `--shape stepped --patch-spacing 12`).
            None => 0,
            Some(v) => match v.parse::<usize>() {
                Ok(n) if n == 0 || PATCH_SPACING_RANGE_PX.contains(&(n as u32)) => n,
                _ => return Err(format!("--patch-spacing {v}: {PATCH_SPACING_ALLOWED}")),
            },
        };
        Ok(ShapeOptions {
            shape,
            patch_spacing_px,
            step_min_height_m: number("--step-height-mm", 1e-3)?,
            step_min_slope: number("--step-slope", 1.0)?,
            step_width_m: number("--step-width-mm", 1e-3)?,
            step_max_wall_slope: number("--step-wall-slope", 1.0)?,
        })
    }

    /// The patch settings (`None`: off).
    fn patches(&self) -> Option<PatchParams> {
        (self.patch_spacing_px > 0).then(|| PatchParams {
            spacing_px: self.patch_spacing_px,
            ..PatchParams::default()
        })
    }

    fn apply(&self, params: &mut ReliefParams) {
        params.shape = self.shape.unwrap_or(params.shape);
        params.step_min_height_m = self.step_min_height_m.unwrap_or(params.step_min_height_m);
        params.step_min_slope = self.step_min_slope.unwrap_or(params.step_min_slope);
        params.step_width_m = self.step_width_m.unwrap_or(params.step_width_m);
        params.step_max_wall_slope = self
            .step_max_wall_slope
            .unwrap_or(params.step_max_wall_slope);
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value_of = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let extra_dir = value_of("--extra").map(PathBuf::from).unwrap_or_else(|| {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("..")
            .join("target/extra-stereo")
    });
    let figure_path = value_of("--figure").map(PathBuf::from);
    let figure_pairs: Vec<String> = match value_of("--figure-pairs") {
        Some(list) => list
            .split(',')
            .map(|s| s.trim().to_string())
            .filter(|s| !s.is_empty())
            .collect(),
        None => DEFAULT_FIGURE_PAIRS.iter().map(|s| s.to_string()).collect(),
    };
    let threshold_mm: f64 = match value_of("--threshold-mm") {
        Some(t) => t.parse()?,
        None => DEFAULT_THRESHOLD_MM,
    };
    if !(threshold_mm.is_finite() && threshold_mm >= 0.0) {
        return Err(format!("--threshold-mm {threshold_mm} must be finite and >= 0").into());
    }
    let threshold_m = threshold_mm * 1e-3;
    let shape = ShapeOptions::parse(value_of)?;
    let only: Option<Vec<String>> =
        value_of("--pairs").map(|list| list.split(',').map(|s| s.trim().to_string()).collect());
    let layout = if args.iter().any(|a| a == "--view") {
        Layout::View
    } else {
        Layout::Rig(videt_runtime::setup::relief_layout(
            &videt_config::Config::default(),
        ))
    };

    let mut pairs = Vec::new();
    for (name, scale) in MIDDLEBURY_PAIRS {
        match videt_testdata::data_dir(&format!("stereo/{name}")) {
            Some(dir) => pairs.push(as_stereo(load_truth_pair(&dir, name, scale, true)?)?),
            None => println!("{name}: not in the shared data, skipped"),
        }
    }
    for p in load_extra_pairs(&extra_dir)? {
        pairs.push(as_stereo(p)?);
    }
    if let Some(only) = &only {
        pairs.retain(|p| only.contains(&p.name));
    }

    let layout_label = match layout {
        Layout::View => format!(
            "stereo view: image over a {:.0} cm wide area, {:.0} cm of relief, back plane at \
             {:.0} cm",
            100.0 * videt_service::stereo_relief::VIEW_AREA_WIDTH_M,
            100.0 * VIEW_RELIEF_DEPTH_M,
            100.0 * videt_service::stereo_relief::VIEW_BACK_PLANE_Z_M
        ),
        Layout::Rig(l) => format!(
            "the rig's scale: {:.0} x {:.0} cm area, {:.0} cm of relief, back plane at {:.0} cm",
            100.0 * l.size_m[0],
            100.0 * l.size_m[1],
            100.0 * l.relief_depth_m,
            100.0 * l.back_plane_z_m
        ),
    };
    // `--after-checks LIST`: the checks of `after` instead of the defaults' (`none`, or a
    // comma-separated list of `left-right`, `surface`, `confidence=T`).
    let mut after_params = VisionParams::default();
    if let Some(list) = args
        .iter()
        .position(|a| a == "--after-checks")
        .and_then(|i| args.get(i + 1))
    {
        let checks: MatchChecks = list.parse().map_err(|e| format!("--after-checks: {e}"))?;
        checks.apply(&mut after_params.matching);
    }
    let after_checks = format!(
        "{} ({})",
        if after_params == VisionParams::default() {
            "the defaults"
        } else {
            "the defaults with other checks"
        },
        checks_on(&after_params)
    );
    println!("relief: {layout_label}");
    println!("before: the defaults without any check; after: {after_checks}");
    println!(
        "deviating: > {threshold_mm} mm from the true surface (device z); phantom: deviating but \
         not in the correct-only relief (before's correct matches), all rows on before's scene \
         map\n"
    );
    println!(
        "{:<11} {:<13} {:>7} {:>6} {:>6} {:>12} {:>8} {:>9} {:>8} {:>9} {:>9} {:>9}",
        "pair",
        "relief",
        "matches",
        "wrong",
        "uneval",
        "depths m",
        "eval cm2",
        "dev cm2",
        "dev %",
        "phantom",
        "largest",
        "own"
    );
    let mut pipeline = StereoPipeline::new();
    let mut results = Vec::new();
    for pair in &pairs {
        let r = measure(
            &mut pipeline,
            pair,
            layout,
            threshold_m,
            &after_params,
            &shape,
        )
        .map_err(|e| format!("{}: {e}", pair.name))?;
        for (label, row) in r.rows() {
            println!(
                "{:<11} {:<13} {:>7} {:>6} {:>6} {:>5.2}..{:<5.2} {:>8.1} {:>9.1} {:>7.1}% {:>9.2} {:>9.2} {:>9}",
                r.name,
                label,
                row.matches,
                row.wrong,
                row.unevaluated,
                r.depth_range_m[0],
                r.depth_range_m[1],
                row.total.evaluated_area_m2 * 1e4,
                row.total.deviating_area_m2 * 1e4,
                100.0 * row.total.deviating_fraction(),
                row.excess.deviating_area_m2 * 1e4,
                row.excess.largest_region_m2 * 1e4,
                row.own.map_or("-".to_string(), |o| format!(
                    "{:.2}",
                    o.deviating_area_m2 * 1e4
                ))
            );
        }
        results.push(r);
    }

    println!(
        "\nsummary ({layout_label})\nphantom and largest region in cm^2, deviating % of the \
         evaluated area; after's phantom split into its excess over the relief of its own correct \
         matches (by the wrong matches it keeps) and that relief's excess over the floor (by the \
         correct matches it drops)"
    );
    println!(
        "{:<11} {:>13} {:>13} {:>15} {:>15} {:>20} {:>15}",
        "", "wrong", "correct", "phantom cm2", "largest cm2", "deviating %", "after's split"
    );
    println!(
        "{:<11} {:>6} {:>6} {:>6} {:>6} {:>7} {:>7} {:>7} {:>7} {:>6} {:>6} {:>6} {:>7} {:>7}",
        "pair",
        "before",
        "after",
        "before",
        "after",
        "before",
        "after",
        "before",
        "after",
        "before",
        "after",
        "floor",
        "wrong",
        "dropped"
    );
    let correct = |row: &Row| row.matches - row.wrong - row.unevaluated;
    let mut sums = [0.0f64; 8];
    for r in &results {
        let own = r.after.own.map_or(0.0, |o| o.deviating_area_m2 * 1e4);
        let dropped = r.after_correct.excess.deviating_area_m2 * 1e4;
        println!(
            "{:<11} {:>6} {:>6} {:>6} {:>6} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>5.1}% {:>5.1}% \
             {:>5.1}% {:>7.2} {:>7.2}",
            r.name,
            r.before.wrong,
            r.after.wrong,
            correct(&r.before),
            correct(&r.after),
            r.before.excess.deviating_area_m2 * 1e4,
            r.after.excess.deviating_area_m2 * 1e4,
            r.before.excess.largest_region_m2 * 1e4,
            r.after.excess.largest_region_m2 * 1e4,
            100.0 * r.before.total.deviating_fraction(),
            100.0 * r.after.total.deviating_fraction(),
            100.0 * r.floor.total.deviating_fraction(),
            own,
            dropped
        );
        let values = [
            r.before.wrong as f64,
            r.after.wrong as f64,
            correct(&r.before) as f64,
            correct(&r.after) as f64,
            r.before.excess.deviating_area_m2 * 1e4,
            r.after.excess.deviating_area_m2 * 1e4,
            own,
            dropped,
        ];
        for (sum, v) in sums.iter_mut().zip(values) {
            *sum += v;
        }
    }
    println!(
        "{:<11} {:>6} {:>6} {:>6} {:>6} {:>7.2} {:>7.2} {:>39} {:>7.2} {:>7.2}",
        "all", sums[0], sums[1], sums[2], sums[3], sums[4], sums[5], "", sums[6], sums[7]
    );

    if let Some(path) = &figure_path {
        let mut shown = Vec::new();
        for name in &figure_pairs {
            match results.iter().zip(&pairs).find(|(r, _)| &r.name == name) {
                Some((r, p)) => shown.push((r, &p.stereo.left)),
                None => println!("figure: no pair {name}, left out"),
            }
        }
        if shown.is_empty() {
            return Err("figure: none of the --figure-pairs exists".into());
        }
        write_figure(
            path,
            &shown,
            &checks_on(&after_params),
            &layout_label,
            threshold_mm,
        )?;
        println!(
            "\nfigure: {} (red: phantom, light blue: deviating in the correct-only relief too)",
            path.display()
        );
    }
    Ok(())
}
