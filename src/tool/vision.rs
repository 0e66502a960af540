//! `videt vision`: run the stereo pipeline on a rectified image pair and write the segments,
//! the matches, the 3D segments and overlay images.
//!
//! `videt vision --left L.png --right R.png (--calib FILE | --rectified --focal PX --baseline M)
//! --out DIR [--roi X,Y,W,H]`

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;
use videt_vision::io::{load_gray_image, write_results};
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
    /// Stereo calibration of the rig (the images are then rectified first).
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
    if let Some(calib) = &args.calib {
        return Err(format!(
            "--calib {}: rectification from a stereo calibration is not available in this build; \
             rectify the images first and use --rectified --focal PX --baseline M",
            calib.display()
        )
        .into());
    }
    let (Some(focal_px), Some(baseline_m)) = (args.focal, args.baseline) else {
        return Err("--rectified needs --focal PX and --baseline M".into());
    };
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
    let geometry = RectifiedGeometry {
        focal_px,
        cx_px: (left.width() as f64 - 1.0) / 2.0,
        cy_px: (left.height() as f64 - 1.0) / 2.0,
        baseline_m,
    };
    geometry.validate()?;
    let params = VisionParams::default();
    let lv = GrayView::from_image(&left)?;
    let rv = GrayView::from_image(&right)?;
    let mut pipeline = StereoPipeline::new();
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
        "segments: {} left, {} right; matches: {}; 3D segments: {}\n\
         edges (Canny, both images)   {:8.3} ms\n\
         chain linking                {:8.3} ms\n\
         segment approximation        {:8.3} ms\n\
         matching                     {:8.3} ms\n\
         back-projection              {:8.3} ms\n\
         total                        {:8.3} ms\n\
         written to {}\n",
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
    // A closed pipe (`| head`) is not an error of the computation.
    let _ = std::io::Write::write_all(&mut std::io::stdout(), report.as_bytes());
    Ok(ExitCode::SUCCESS)
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
}
