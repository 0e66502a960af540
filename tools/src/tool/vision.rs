//! `videt vision`: run the stereo pipeline on a rectified image pair and write the segments,
//! the matches, the 3D segments and overlay images.
//!
//! `videt vision --left L.png --right R.png (--calib FILE | --rectified --focal PX --baseline M)
//! --out DIR [--roi X,Y,W,H] [--checks LIST] [--surface [--relief-depth M]]`
//!
//! With `--surface` it also builds the bas-relief from the 3D segments (the image stretched over
//! a 40 cm wide area, the scene's depth range mapped onto the relief depth) and writes the mesh
//! (`surface.ply`) and a shaded depth image (`surface_depth.png`).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;
use image::GrayImage;
use videt_hal::GrayFrame;
use videt_relief::build_from_scene;
use videt_relief::export::write_surface_outputs;
use videt_vision::disparity_range::choose_max_disparity;
use videt_vision::io::{load_gray_image, write_results};
use videt_vision::matching::MatchChecks;
use videt_vision::{GrayView, LocalRegion, RectifiedGeometry, StereoPipeline, VisionParams};

use super::ToolResult;

/// Run the stereo pipeline (edges, segments, matching, 3D) on an image pair.
#[derive(Debug, Args)]
pub struct VisionArgs {
    /// Left image.
    #[arg(long, value_name = "L.png")]
    pub left: PathBuf,
    /// Right image.
    #[arg(long, value_name = "R.png")]
    pub right: PathBuf,
    /// Stereo calibration of the rig (`videt calibrate-stereo`): the images are rectified
    /// with it first, and the 3D geometry comes from its rectified projections.
    #[arg(long, value_name = "FILE", required_unless_present = "rectified")]
    pub calib: Option<PathBuf>,
    /// The images are already rectified; give the rectified focal length and the baseline.
    #[arg(long, conflicts_with = "calib", requires_all = ["focal", "baseline"])]
    pub rectified: bool,
    /// Rectified focal length, pixels (with --rectified; principal point = image centre).
    #[arg(long, value_name = "PX", requires = "rectified")]
    pub focal: Option<f64>,
    /// Baseline, metres (with --rectified).
    #[arg(long, value_name = "M", requires = "rectified")]
    pub baseline: Option<f64>,
    /// Output directory.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Process only this region of the left image (local mode): column, row, width, height.
    #[arg(long, value_name = "X,Y,W,H", value_parser = parse_roi)]
    pub roi: Option<[u32; 4]>,
    /// Largest disparity searched, pixels (nearest depth = focal x baseline / this). Default:
    /// measured on the pair (a first pass searching the whole width; the bound is the 98th
    /// percentile of its disparities x1.25 + 8 px), and printed.
    #[arg(long, value_name = "PX")]
    pub max_disparity: Option<f32>,
    /// Also build the bas-relief from the 3D segments and write `surface.ply` (the mesh, device
    /// frame, metres) and `surface_depth.png` (shaded depth) into the output directory.
    #[arg(long)]
    pub surface: bool,
    /// Checks against wrong matches: `none`, or a comma-separated list of `left-right` (match
    /// the right image to the left one too; keep a match both directions agree on),
    /// `surface` (drop a match its matched neighbours contradict) and `confidence=T` (drop a
    /// match whose confidence is below T, in 0..=1). Default: the service's defaults.
    #[arg(long, value_name = "LIST", value_parser = parse_checks)]
    pub checks: Option<MatchChecks>,
    /// With --surface: the relief depth d_max, metres (the nearest scene depth stands out this
    /// much in front of the back plane at 0.45 m).
    #[arg(long, value_name = "M", default_value_t = 0.08, requires = "surface")]
    pub relief_depth: f64,
}

fn parse_checks(text: &str) -> Result<MatchChecks, String> {
    text.parse().map_err(|e| format!("--checks: {e}"))
}

fn parse_roi(text: &str) -> Result<[u32; 4], String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != 4 {
        return Err(format!("--roi wants X,Y,W,H (4 numbers), got {text:?}"));
    }
    let mut roi = [0u32; 4];
    for (value, (part, name)) in roi.iter_mut().zip(parts.iter().zip(["X", "Y", "W", "H"])) {
        *value = part
            .parse()
            .map_err(|_| format!("--roi {name} = {part:?} is not a non-negative integer"))?;
    }
    if roi[2] == 0 || roi[3] == 0 {
        return Err(format!("--roi width and height must be > 0, got {text:?}"));
    }
    Ok(roi)
}

/// Runs the subcommand.
pub fn run(args: &VisionArgs) -> ToolResult {
    if args.surface {
        videt_service::stereo_relief::check_view_relief_depth(args.relief_depth)
            .map_err(|e| format!("--relief-depth: {e}"))?;
    }
    let left = load_gray_image(&args.left)?;
    let right = load_gray_image(&args.right)?;
    if left.dimensions() != right.dimensions() {
        return Err(format!(
            "{} is {}x{} but {} is {}x{}: a rectified pair must have equal sizes",
            args.left.display(),
            left.width(),
            left.height(),
            args.right.display(),
            right.width(),
            right.height()
        )
        .into());
    }
    let (left, right, geometry) = match &args.calib {
        Some(path) => rectify_with_calibration(path, left, right)?,
        None => {
            let (Some(focal_px), Some(baseline_m)) = (args.focal, args.baseline) else {
                return Err("--rectified needs --focal PX and --baseline M".into());
            };
            let geometry = RectifiedGeometry {
                focal_px,
                cx_px: (left.width() as f64 - 1.0) / 2.0,
                cy_px: (left.height() as f64 - 1.0) / 2.0,
                baseline_m,
            };
            (left, right, geometry)
        }
    };
    geometry.validate()?;
    let mut params = VisionParams::default();
    if let Some(checks) = &args.checks {
        checks.apply(&mut params.matching);
    }
    let lv = GrayView::from_image(&left)?;
    let rv = GrayView::from_image(&right)?;
    let mut pipeline = StereoPipeline::new();
    let range_line = match args.max_disparity {
        Some(px) => {
            params.matching.disparity_max_px = px;
            format!("max disparity {px} px (given)")
        }
        None => {
            let range = choose_max_disparity(&mut pipeline, &lv, &rv, &params)?;
            params.matching.disparity_max_px = range.max_px;
            range.describe()
        }
    };
    params
        .validate()
        .map_err(|e| format!("--max-disparity: {e}"))?;
    let output = match args.roi {
        None => pipeline.run(&lv, &rv, Some(&geometry), &params)?,
        Some([x, y, w, h]) => {
            let region = LocalRegion {
                centre_px: [x as f32 + w as f32 / 2.0, y as f32 + h as f32 / 2.0],
                size_px: [w as f32, h as f32],
                velocity_px_per_frame: [0.0, 0.0],
            };
            pipeline.run_local(&lv, &rv, Some(&geometry), &params, &region)?
        }
    };
    write_results(&args.out, output, &left, &right)?;
    let t = &output.timings;
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    let report = format!(
        "{range_line}\n\
         checks against wrong matches: {}\n\
         segments: {} left, {} right; matches: {}; 3D segments: {}\n\
         edges (Canny, both images)   {:8.3} ms\n\
         chain linking                {:8.3} ms\n\
         segment approximation        {:8.3} ms\n\
         matching                     {:8.3} ms\n\
         back-projection              {:8.3} ms\n\
         total                        {:8.3} ms\n\
         written to {}\n",
        MatchChecks::of(&params.matching),
        output.left_segments.len(),
        output.right_segments.len(),
        output.matches.len(),
        output.segments_3d.len(),
        ms(t.edges),
        ms(t.chains),
        ms(t.segments),
        ms(t.matching),
        ms(t.reconstruction),
        ms(t.total),
        args.out.display()
    );
    let report = if args.surface {
        let surface = write_surface(args, output, &geometry, [left.width(), left.height()])?;
        report + &surface
    } else {
        report
    };
    // A closed pipe (`| head`) is not an error of the computation.
    let _ = std::io::Write::write_all(&mut std::io::stdout(), report.as_bytes());
    Ok(ExitCode::SUCCESS)
}

/// Builds the bas-relief from the run's 3D segments and writes its mesh and depth image into
/// the output directory; returns the report text.
fn write_surface(
    args: &VisionArgs,
    output: &videt_vision::PipelineOutput,
    geometry: &RectifiedGeometry,
    image_size_px: [u32; 2],
) -> Result<String, super::ToolError> {
    use videt_service::stereo_relief::{pinhole, report_text, scene_segments, view_params};
    if output.segments_3d.is_empty() {
        return Err(format!(
            "--surface: no 3D segments to build a surface from ({} matches, none back-projected; \
             nearly horizontal matches have no reliable depth)",
            output.matches.len()
        )
        .into());
    }
    let mut segments = Vec::with_capacity(output.segments_3d.len());
    scene_segments(&output.segments_3d, &mut segments);
    let params = view_params(&segments, image_size_px, args.relief_depth)
        .map_err(|e| format!("--surface: {e}"))?;
    let (model, report) = build_from_scene(&segments, &[], &pinhole(geometry), &params)
        .map_err(|e| format!("--surface: {e}"))?;
    let [ply, png] = write_surface_outputs(&model, &args.out)?;
    let [near, far] = videt_service::stereo_relief::scene_depth_range(&segments)?;
    let back = params.scene_map.back_plane_z_m();
    let depth = params.scene_map.relief_depth_m();
    Ok(format!(
        "{}relief: scene depths {:.2}..{:.2} m (2nd..98th percentile) onto z {:.3}..{:.3} m \
         (back plane), area {:.3} x {:.3} m\nwritten {} and {}\n",
        report_text(&report),
        near,
        far,
        back - depth,
        back,
        params.area_m()[2] - params.area_m()[0],
        params.area_m()[3] - params.area_m()[1],
        ply.display(),
        png.display()
    ))
}

/// Rectifies the pair with the calibration's remap tables; the geometry comes from its P1, P2.
fn rectify_with_calibration(
    path: &std::path::Path,
    left: GrayImage,
    right: GrayImage,
) -> Result<(GrayImage, GrayImage, RectifiedGeometry), super::ToolError> {
    let rig = videt_service::camera_relief::CalibratedRig::load(path)
        .map_err(|e| format!("--calib {e}"))?;
    let [width, height] = rig.size_px;
    if left.dimensions() != (width, height) {
        return Err(format!(
            "the images are {}x{} but the calibration {} is for {width}x{height} images",
            left.width(),
            left.height(),
            path.display(),
        )
        .into());
    }
    let (geometry, rectifier) = (rig.geometry, rig.rectifier);
    let to_frame = |image: GrayImage| GrayFrame {
        width: image.width(),
        height: image.height(),
        data: image.into_raw(),
    };
    let (mut rect_left, mut rect_right) = (GrayFrame::default(), GrayFrame::default());
    rectifier.left.apply(&to_frame(left), &mut rect_left)?;
    rectifier.right.apply(&to_frame(right), &mut rect_right)?;
    let to_image = |frame: GrayFrame| {
        GrayImage::from_raw(frame.width, frame.height, frame.data)
            .ok_or("rectified frame has an inconsistent size")
    };
    Ok((to_image(rect_left)?, to_image(rect_right)?, geometry))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roi_parsing() {
        assert_eq!(parse_roi("10, 20,100,80").unwrap(), [10, 20, 100, 80]);
        assert!(parse_roi("10,20,100").unwrap_err().contains("4 numbers"));
        assert!(parse_roi("10,20,-1,5").unwrap_err().contains("W"));
        assert!(parse_roi("1,2,0,5").unwrap_err().contains("> 0"));
    }

    #[test]
    fn checks_parsing() {
        assert_eq!(parse_checks("none").unwrap(), MatchChecks::NONE);
        let c = parse_checks("left-right, confidence=0.25").unwrap();
        assert!(c.left_right && !c.surface && (c.min_confidence - 0.25).abs() < 1e-6);
        assert!(parse_checks("surface").unwrap().surface);
        assert!(parse_checks("confidence=2").unwrap_err().contains("0..=1"));
        assert!(parse_checks("lr").unwrap_err().contains("left-right"));
    }
}
