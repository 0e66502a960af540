//! `videt calibrate-stereo --images DIR --board COLSxROWS --square M --out FILE [--alpha A]`:
//! calibrate the
//! stereo camera pair from chessboard image pairs (`leftNN.<png|jpg|pgm>` with `rightNN.<ext>`),
//! print the per-view and overall reprojection errors and the rectified epipolar error, and write
//! the calibration atomically (the previous file kept as `FILE.bak`).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;
use videt_vision::calib::{calibrate_stereo_dir_with_alpha, CalibrationReport};

use super::ToolResult;

/// Arguments of `videt calibrate-stereo`.
#[derive(Debug, Args)]
pub struct CalibrateStereoArgs {
    /// Directory of image pairs named leftNN / rightNN (png, jpg, jpeg or pgm).
    #[arg(long, value_name = "DIR")]
    pub images: PathBuf,
    /// Inner corners of the chessboard as COLSxROWS, e.g. 9x6.
    #[arg(long, value_name = "COLSxROWS", value_parser = parse_board)]
    pub board: BoardCorners,
    /// Side of one chessboard square, metres.
    #[arg(long, value_name = "M")]
    pub square: f64,
    /// Calibration file to write (JSON).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Rectification free scaling in [0, 1]: 0 keeps only valid pixels, 1 keeps every source
    /// pixel (black borders).
    #[arg(long, value_name = "A", default_value_t = videt_vision::calib::workflow::RECTIFY_ALPHA)]
    pub alpha: f64,
}

/// Inner-corner counts given on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoardCorners {
    /// Inner corners per row.
    pub cols: usize,
    /// Inner corners per column.
    pub rows: usize,
}

/// Parse `COLSxROWS` (e.g. `9x6`).
pub fn parse_board(text: &str) -> Result<BoardCorners, String> {
    let bad = || format!("board '{text}' must be COLSxROWS inner corners, e.g. 9x6");
    let (cols, rows) = text.split_once(['x', 'X']).ok_or_else(bad)?;
    let cols: usize = cols.trim().parse().map_err(|_| bad())?;
    let rows: usize = rows.trim().parse().map_err(|_| bad())?;
    Ok(BoardCorners { cols, rows })
}

/// Calibrate, print the report, write the file.
pub fn run(args: &CalibrateStereoArgs) -> ToolResult {
    // Refuse an unwritable destination before the (long) calibration runs.
    let out_dir = match args.out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !out_dir.is_dir() {
        return Err(format!(
            "--out {}: directory {} does not exist",
            args.out.display(),
            out_dir.display()
        )
        .into());
    }
    let (calibration, report) = calibrate_stereo_dir_with_alpha(
        &args.images,
        args.board.cols,
        args.board.rows,
        args.square,
        args.alpha,
    )?;
    print_report(&report);
    calibration.save(&args.out)?;
    println!("calibration written to {}", args.out.display());
    Ok(ExitCode::SUCCESS)
}

fn print_report(report: &CalibrationReport) {
    let px = |v: Option<f64>| v.map_or_else(|| "     -".to_string(), |v| format!("{v:6.3}"));
    println!("pair  left  right  rms_left_px rms_right_px rms_stereo_px");
    for v in &report.views {
        let found = |f: bool| if f { "found" } else { "MISS " };
        println!(
            "{:<5} {} {}  {}       {}        {}",
            v.id,
            found(v.left_found),
            found(v.right_found),
            px(v.left_rms_px),
            px(v.right_rms_px),
            px(v.stereo_rms_px)
        );
    }
    for v in report.skipped() {
        println!(
            "skipped pair {}: board not found in {}",
            v.id,
            match (v.left_found, v.right_found) {
                (false, false) =>
                    format!("{} and {}", v.left_file.display(), v.right_file.display()),
                (false, true) => v.left_file.display().to_string(),
                _ => v.right_file.display().to_string(),
            }
        );
    }
    println!(
        "RMS reprojection error: left {:.3} px, right {:.3} px, stereo {:.3} px",
        report.rms_left_px, report.rms_right_px, report.rms_stereo_px
    );
    println!(
        "rectified epipolar error |y_left - y_right|: mean {:.3} px, max {:.3} px",
        report.epipolar_error_mean_px, report.epipolar_error_max_px
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_board_sizes() {
        assert_eq!(parse_board("9x6"), Ok(BoardCorners { cols: 9, rows: 6 }));
        assert_eq!(parse_board("7X5"), Ok(BoardCorners { cols: 7, rows: 5 }));
        for bad in ["9", "9x", "x6", "9x-6", "nine x six", ""] {
            assert!(parse_board(bad).unwrap_err().contains("COLSxROWS"), "{bad}");
        }
    }
}
