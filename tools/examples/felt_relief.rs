//! What the wearer touches on the relief of a stereo pair, against the true surface: the pixel
//! comparison and the felt surface, for the paper's interpolated relief, the stepped one, and
//! the stepped one with depth from image patches (`vision.patch_spacing_px`).
//!
//! Per pair with ground truth (the shared Middlebury pairs and every pair under the extra
//! directory, default `target/extra-stereo`, as `phantom_relief` finds them), the relief is
//! built as the service builds it (`StereoRelief::build`: the default matcher, laid out in front
//! of the default rig, 20 x 15 cm, 4 cm of relief; the disparity bound measured on the pair)
//! in three variants, `interpolated` (the paper's), `stepped` ([`ReliefShape::Stepped`]) and
//! `stepped+patches` (the stepped relief of the segments, the far sides of occluding edges and
//! the support points of `videt_vision::patch_stereo`, on a grid `--patch-spacing` px apart,
//! default 12), and:
//!
//! - **pixels**: the fraction of the evaluated area more than 5 mm off the true surface
//!   (`videt_evaluation::relief_deviation`, as `phantom_relief` reports it);
//! - **felt**: the twin's virtual operator sweeps the area inside the frame in 1 cm rows at
//!   8 cm/s with a 1 N push, the real control cycle rendering the relief through the CiA 402
//!   twin (`videt_tools::felt_surface`); the height the finger was held at is compared with the
//!   true surface: median and 95th percentile of the error, the 95th percentile over the
//!   cells the true surface does not step across by more than 5 mm ("faces") and the share of
//!   cells it does ("steps"), the fraction of the visited 5 mm cells more than 5 mm off, and
//!   the wires' force in contact (99th percentile, largest).
//!
//! `cargo run --release -p videt-tools --example felt_relief -- [--pairs a,b] [--extra DIR]
//! [--rows-mm MM] [--patch-spacing PX] [--figure FILE.png]`
//!
//! With `--figure` it writes one PNG, a row per pair: the true surface, the interpolated relief
//! (before), the stepped relief with patches (after), and the felt surface on it (the median
//! height the finger was held at per 2.5 mm cell), coloured by height.

use std::path::{Path, PathBuf};

use image::{Rgb, RgbImage};
use plotters::prelude::*;
use videt_config::{Config, PATCH_SPACING_RANGE_PX};
use videt_evaluation::{
    load_extra_pairs, load_truth_pair, relief_deviation, DisparityMap, TruthPair, MIDDLEBURY_PAIRS,
};
use videt_relief::{build_from_scene, ReliefLayout, ReliefModel, ReliefParams, ReliefShape};
use videt_service::stereo_relief::{pinhole, LiveSettings, PairCamera, StereoPair, StereoRelief};
use videt_tools::felt_surface::{felt_map, felt_surface, FeltMap, FeltSettings, FeltSurface};
use videt_tools::haptic_bench::rig::{run, start_position, Experiment, Parts};
use videt_vision::disparity_range::choose_max_disparity;
use videt_vision::{GrayView, RectifiedGeometry, StereoPipeline, VisionParams};

const THRESHOLD_M: f64 = 0.005;

/// The true surface's device `z` at `(x, y)`: the left pixel there, its true depth mapped as
/// the relief maps depths.
fn truth_z(
    params: &ReliefParams,
    geometry: &RectifiedGeometry,
    truth: &DisparityMap,
    x: f64,
    y: f64,
) -> Option<f64> {
    let map = &params.scene_map;
    let [u, v] = map.workspace_to_image(x, y);
    let (i, j) = (u.round(), v.round());
    if !(i >= 0.0 && j >= 0.0 && (i as usize) < truth.width && (j as usize) < truth.height) {
        return None;
    }
    let d = truth.values[j as usize * truth.width + i as usize];
    if !(d.is_finite() && d > 0.0) {
        return None;
    }
    let (point, _) = geometry.back_project(i, j, f64::from(d), 0.0)?;
    Some(map.scene_depth_to_relief_z(point.z))
}

/// One relief's figures.
struct Figures {
    pixels_off: f64,
    felt: FeltSurface,
    build_ms: f64,
    /// The relief swept and the felt surface, for the figure.
    model: ReliefModel,
    felt_map: FeltMap,
}

fn measure(
    config: &Config,
    model: &ReliefModel,
    params: &ReliefParams,
    geometry: &RectifiedGeometry,
    truth: &DisparityMap,
    rows_m: f64,
    build_ms: f64,
) -> Result<Figures, String> {
    let pixels_off = relief_deviation(model, params, geometry, truth)
        .map_err(|e| e.to_string())?
        .phantom(THRESHOLD_M)
        .deviating_fraction();
    let area = params.area_m();
    let fw = params.frame_width_m.max(params.merge_distance_m) + 0.002;
    let mut settings = FeltSettings::over([area[0] + fw, area[1] + fw, area[2] - fw, area[3] - fw]);
    settings.row_spacing_m = rows_m;
    let start = start_position(config);
    let trace = run(&Experiment {
        config: config.clone(),
        surface: model.clone(),
        operator: settings.operator(start),
        duration_s: settings.duration_s(start),
        parts: Parts::Faithful,
    })?;
    let felt = felt_surface(
        &trace,
        model,
        |x, y| truth_z(params, geometry, truth, x, y),
        &settings,
    );
    Ok(Figures {
        pixels_off,
        felt,
        build_ms,
        model: model.clone(),
        felt_map: felt_map(&trace, model, &settings, FIGURE_CELL_M),
    })
}

/// The reliefs compared.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Variant {
    /// The paper's, from the segments.
    Interpolated,
    /// [`ReliefShape::Stepped`], from the segments.
    Stepped,
    /// [`ReliefShape::Stepped`], from the segments, the far sides and the support points.
    SteppedPatches,
}

impl Variant {
    const ALL: [Variant; 3] = [
        Variant::Interpolated,
        Variant::Stepped,
        Variant::SteppedPatches,
    ];

    fn label(self) -> &'static str {
        match self {
            Variant::Interpolated => "interpolated",
            Variant::Stepped => "stepped",
            Variant::SteppedPatches => "stepped+patches",
        }
    }
}

/// A pair's reliefs, measured, with what its figure row needs.
struct PairRun {
    name: String,
    params: ReliefParams,
    geometry: RectifiedGeometry,
    truth: DisparityMap,
    shapes: Vec<(Variant, Figures)>,
}

fn pair_figures(
    config: &Config,
    layout: &ReliefLayout,
    p: TruthPair,
    rows_m: f64,
    patch_spacing_px: u32,
) -> Result<PairRun, String> {
    let mut pipeline = StereoPipeline::new();
    let lv = GrayView::from_image(&p.left).map_err(|e| e.to_string())?;
    let rv = GrayView::from_image(&p.right).map_err(|e| e.to_string())?;
    let bound = choose_max_disparity(&mut pipeline, &lv, &rv, &VisionParams::default())
        .map_err(|e| e.to_string())?;
    let mut camera = PairCamera::nominal(p.left.width());
    camera.max_disparity_px = bound.max_px;
    let truth = p.truth;
    let pair = StereoPair::new(p.name, p.left, p.right, camera)?;
    let geometry = pair.geometry();
    let segments_only = LiveSettings {
        patch_spacing_px: 0,
        ..LiveSettings::default()
    };
    let with_patches = LiveSettings {
        patch_spacing_px,
        ..LiveSettings::default()
    };
    let (patched, _, _) = StereoRelief::build(pair.clone(), layout, with_patches)?;
    let (relief, _, _) = StereoRelief::build(pair, layout, segments_only)?;
    let mut out = Vec::new();
    for variant in Variant::ALL {
        let mut params = *relief.relief_params();
        let (source, shape) = match variant {
            Variant::Interpolated => (&relief, ReliefShape::Interpolated),
            Variant::Stepped => (&relief, ReliefShape::Stepped),
            Variant::SteppedPatches => (&patched, ReliefShape::Stepped),
        };
        params.shape = shape;
        let t = std::time::Instant::now();
        let (model, _) = build_from_scene(
            source.segments(),
            source.points(),
            &pinhole(&geometry),
            &params,
        )
        .map_err(|e| e.to_string())?;
        let build_ms = t.elapsed().as_secs_f64() * 1e3;
        let figures = measure(config, &model, &params, &geometry, &truth, rows_m, build_ms)?;
        out.push((variant, figures));
    }
    Ok(PairRun {
        name: relief.pair().name.clone(),
        params: *relief.relief_params(),
        geometry,
        truth,
        shapes: out,
    })
}

/// Cells of the felt surface in the figure, metres.
const FIGURE_CELL_M: f64 = 0.0025;
/// A panel's width, pixels.
const PANEL_W: u32 = 300;

/// The colour of a relief height: warm where raised (the nearest depth), dark blue at the
/// back plane; black where unknown or never touched.
fn height_colour(z: Option<f64>, params: &ReliefParams) -> Rgb<u8> {
    let Some(z) = z else {
        return Rgb([0, 0, 0]);
    };
    let back = params.scene_map.back_plane_z_m();
    let near = back - params.scene_map.relief_depth_m();
    let t = ((back - z) / (back - near)).clamp(0.0, 1.0);
    let stops = [
        [30.0, 35.0, 95.0],
        [200.0, 60.0, 90.0],
        [255.0, 225.0, 110.0],
    ];
    let (a, b, f) = if t < 0.5 {
        (stops[0], stops[1], t * 2.0)
    } else {
        (stops[1], stops[2], t * 2.0 - 1.0)
    };
    Rgb([0, 1, 2].map(|k| (a[k] + (b[k] - a[k]) * f) as u8))
}

/// A panel of the area: `height(x, y)` coloured.
fn panel(params: &ReliefParams, height: impl Fn(f64, f64) -> Option<f64>) -> RgbImage {
    let [x0, y0, x1, y1] = params.area_m();
    let h = (f64::from(PANEL_W) * (y1 - y0) / (x1 - x0)).round() as u32;
    RgbImage::from_fn(PANEL_W, h, |c, r| {
        let x = x0 + (f64::from(c) + 0.5) / f64::from(PANEL_W) * (x1 - x0);
        let y = y1 - (f64::from(r) + 0.5) / f64::from(h) * (y1 - y0);
        height_colour(height(x, y), params)
    })
}

/// One PNG: a row per pair, the true surface, the interpolated and the stepped relief, and the
/// felt surface of the stepped relief.
fn write_figure(path: &Path, runs: &[PairRun]) -> Result<(), Box<dyn std::error::Error>> {
    videt_tools::plotting::register_font();
    let (margin, title_h, label_h) = (10u32, 50u32, 22u32);
    let rows: Vec<[RgbImage; 4]> = runs
        .iter()
        .map(|r| {
            let p = &r.params;
            let shape = |s: Variant| r.shapes.iter().find(|x| x.0 == s).map(|x| &x.1);
            let relief = |s: Variant| {
                panel(p, |x, y| {
                    shape(s).and_then(|f| f.model.height_at(x, y).map(|h| h.z_m))
                })
            };
            [
                panel(p, |x, y| truth_z(p, &r.geometry, &r.truth, x, y)),
                relief(Variant::Interpolated),
                relief(Variant::SteppedPatches),
                panel(p, |x, y| {
                    shape(Variant::SteppedPatches).and_then(|f| f.felt_map.at(x, y))
                }),
            ]
        })
        .collect();
    let width = 5 * margin + 4 * PANEL_W;
    let height = title_h
        + rows
            .iter()
            .map(|r| label_h + r[0].height() + margin)
            .sum::<u32>();
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
            "True surface | relief, interpolated (the paper's) | relief, stepped with patches | \
             felt on the stepped relief with patches",
            margin,
            6,
            15,
        )?;
        text(
            "yellow: raised (nearest), dark blue: the back plane, black: unknown or not touched",
            margin,
            28,
            13,
        )?;
        let mut y = title_h;
        for (r, row) in runs.iter().zip(&rows) {
            let f = |s: Variant| r.shapes.iter().find(|x| x.0 == s).map(|x| &x.1);
            let (Some(a), Some(b)) = (f(Variant::Interpolated), f(Variant::SteppedPatches)) else {
                continue;
            };
            text(
                &format!(
                    "{}: off > 5 mm {:.0}% -> {:.0}%; felt p95 {:.1} -> {:.1} mm",
                    r.name,
                    100.0 * a.pixels_off,
                    100.0 * b.pixels_off,
                    a.felt.p95_m * 1e3,
                    b.felt.p95_m * 1e3
                ),
                margin,
                y + 3,
                13,
            )?;
            y += label_h + row[0].height() + margin;
        }
        root.present()?;
    }
    let mut image = RgbImage::from_raw(width, height, buffer).ok_or("figure buffer")?;
    let mut y = title_h;
    for row in &rows {
        for (k, p) in row.iter().enumerate() {
            let x = margin + k as u32 * (PANEL_W + margin);
            image::imageops::overlay(&mut image, p, i64::from(x), i64::from(y + label_h));
        }
        y += label_h + row[0].height() + margin;
    }
    image.save(path)?;
    Ok(())
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
    let only: Option<Vec<String>> =
        value_of("--pairs").map(|l| l.split(',').map(|s| s.trim().to_string()).collect());
    let rows_m = match value_of("--rows-mm") {
        Some(v) => v.parse::<f64>()? * 1e-3,
        None => 0.01,
    };
    if !(rows_m.is_finite() && rows_m >= 0.001) {
        return Err("--rows-mm must be at least 1".into());
    }
    let patch_spacing_px = match value_of("--patch-spacing") {
        None => 12,
        Some(v) => match v.parse::<u32>() {
            Ok(n) if PATCH_SPACING_RANGE_PX.contains(&n) => n,
            _ => {
                let (lo, hi) = (PATCH_SPACING_RANGE_PX.start(), PATCH_SPACING_RANGE_PX.end());
                return Err(format!("--patch-spacing {v}: in [{lo}, {hi}]").into());
            }
        },
    };
    let config = Config::default();
    let layout = videt_runtime::setup::relief_layout(&config);

    let mut pairs = Vec::new();
    for (name, scale) in MIDDLEBURY_PAIRS {
        match videt_testdata::data_dir(&format!("stereo/{name}")) {
            Some(dir) => pairs.push(load_truth_pair(&dir, name, scale, true)?),
            None => println!("{name}: not in the shared data, skipped"),
        }
    }
    pairs.extend(load_extra_pairs(&extra_dir)?);
    if let Some(only) = &only {
        pairs.retain(|p| only.contains(&p.name));
    }
    println!(
        "relief in front of the default rig (20 x 15 cm, 4 cm of relief), the default matcher; \
         off: > 5 mm from the true surface; felt: a raster of {:.0} mm rows at 8 cm/s, 1 N push",
        rows_m * 1e3
    );
    println!(
        "{:<11} {:<15} {:>8} {:>9} {:>9} {:>9} {:>11} {:>8} {:>8} {:>9} {:>9} {:>9}",
        "pair",
        "relief",
        "build ms",
        "pixels %",
        "felt p50",
        "felt p95",
        "p95 faces",
        "steps %",
        "felt %",
        "samples",
        "F p99 N",
        "F max N"
    );
    let figure = value_of("--figure").map(PathBuf::from);
    let mut runs = Vec::new();
    for p in pairs {
        let name = p.name.clone();
        let run = pair_figures(&config, &layout, p, rows_m, patch_spacing_px)
            .map_err(|e| format!("{name}: {e}"))?;
        for (shape, f) in &run.shapes {
            println!(
                "{:<11} {:<15} {:>8.2} {:>8.1}% {:>6.1} mm {:>6.1} mm {:>8.1} mm {:>7.1}% {:>7.1}% {:>9} {:>9.2} {:>9.2}",
                name,
                shape.label(),
                f.build_ms,
                100.0 * f.pixels_off,
                f.felt.median_m * 1e3,
                f.felt.p95_m * 1e3,
                f.felt.p95_off_steps_m * 1e3,
                100.0 * f.felt.step_cells as f64 / f.felt.cells.max(1) as f64,
                100.0 * f.felt.off_fraction,
                f.felt.samples,
                f.felt.force_p99_n,
                f.felt.force_max_n
            );
        }
        runs.push(run);
    }
    if let Some(path) = figure {
        write_figure(&path, &runs)?;
        println!("figure: {}", path.display());
    }
    Ok(())
}
