//! The whole stereo calibration from a directory of chessboard image pairs: pairing, corner
//! detection, per-camera and stereo calibration, rectification, quality figures.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;

use super::chessboard::{find_chessboard_in_frame, BoardSize, Corners};
use super::error::CalibError;
use super::file::{QualityFigures, StereoCalibration};
use super::image_io::load_gray;
use super::intrinsic::{calibrate_camera, MIN_VIEWS};
use super::rectification::{rectify_point, stereo_rectify, Rectification};
use super::stereo::calibrate_stereo;
use super::CameraIntrinsics;

/// Image file extensions accepted (lower case).
pub const IMAGE_EXTENSIONS: [&str; 4] = ["png", "jpg", "jpeg", "pgm"];

/// Free-scaling parameter of the rectification: 1 keeps every source pixel in the rectified
/// image (OpenCV's `alpha = 1`).
pub const RECTIFY_ALPHA: f64 = 1.0;

/// One left/right image pair and what was found in it.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewReport {
    /// The pair's identifier (the file name after `left` / `right`, e.g. `01`).
    pub id: String,
    /// Left image file.
    pub left_file: PathBuf,
    /// Right image file.
    pub right_file: PathBuf,
    /// Whether the board was found in the left image.
    pub left_found: bool,
    /// Whether the board was found in the right image.
    pub right_found: bool,
    /// RMS reprojection error of this view in the left calibration, pixels.
    pub left_rms_px: Option<f64>,
    /// RMS reprojection error of this view in the right calibration, pixels.
    pub right_rms_px: Option<f64>,
    /// RMS reprojection error of this pair in the stereo calibration, pixels.
    pub stereo_rms_px: Option<f64>,
}

/// What the calibration did and how well it fits.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationReport {
    /// Every pair found in the directory, in identifier order.
    pub views: Vec<ViewReport>,
    /// Left camera RMS reprojection error, pixels.
    pub rms_left_px: f64,
    /// Right camera RMS reprojection error, pixels.
    pub rms_right_px: f64,
    /// Stereo RMS reprojection error, pixels.
    pub rms_stereo_px: f64,
    /// Mean |y_left - y_right| of the corners after rectification, pixels.
    pub epipolar_error_mean_px: f64,
    /// Largest |y_left - y_right| after rectification, pixels.
    pub epipolar_error_max_px: f64,
}

impl CalibrationReport {
    /// Identifiers of the pairs in which the board was missed in at least one image.
    pub fn skipped(&self) -> Vec<&ViewReport> {
        self.views
            .iter()
            .filter(|v| !(v.left_found && v.right_found))
            .collect()
    }
}

/// Check the board description.
pub fn validate_board(
    board_cols: usize,
    board_rows: usize,
    square_m: f64,
) -> Result<(), CalibError> {
    for (field, v) in [("cols", board_cols), ("rows", board_rows)] {
        if !(3..=64).contains(&v) {
            return Err(CalibError::InvalidBoard {
                field,
                value: v.to_string(),
                allowed: "3..=64 inner corners",
            });
        }
    }
    if !(square_m.is_finite() && square_m > 0.0) {
        return Err(CalibError::InvalidBoard {
            field: "square_m",
            value: square_m.to_string(),
            allowed: "a finite square size > 0 metres",
        });
    }
    Ok(())
}

/// The board's corner positions on its plane (z = 0), row-major like the detected corners.
pub fn board_points(board_cols: usize, board_rows: usize, square_m: f64) -> Vec<Vector3<f64>> {
    (0..board_rows)
        .flat_map(|r| {
            (0..board_cols)
                .map(move |c| Vector3::new(c as f64 * square_m, r as f64 * square_m, 0.0))
        })
        .collect()
}

/// Left/right image pairs of `dir`, matched by name (`left<ID>.<ext>` with `right<ID>.<ext>`),
/// sorted by identifier.
pub fn find_image_pairs(dir: &Path) -> Result<Vec<(String, PathBuf, PathBuf)>, CalibError> {
    let entries = std::fs::read_dir(dir).map_err(|e| CalibError::io("read directory", dir, e))?;
    let mut lefts = Vec::new();
    let mut rights = std::collections::BTreeMap::new();
    for entry in entries {
        let entry = entry.map_err(|e| CalibError::io("read directory", dir, e))?;
        let path = entry.path();
        let (Some(stem), Some(ext)) = (
            path.file_stem().and_then(|s| s.to_str()),
            path.extension().and_then(|s| s.to_str()),
        ) else {
            continue;
        };
        if !IMAGE_EXTENSIONS.contains(&ext.to_ascii_lowercase().as_str()) {
            continue;
        }
        let lower = stem.to_ascii_lowercase();
        if let Some(id) = lower.strip_prefix("left") {
            lefts.push((id.to_string(), path.clone()));
        } else if let Some(id) = lower.strip_prefix("right") {
            rights.insert(id.to_string(), path.clone());
        }
    }
    lefts.sort();
    let pairs: Vec<_> = lefts
        .into_iter()
        .filter_map(|(id, left)| {
            rights
                .get(&id)
                .map(|right| (id.clone(), left, right.clone()))
        })
        .collect();
    if pairs.is_empty() {
        return Err(CalibError::NoImagePairs {
            dir: dir.to_path_buf(),
        });
    }
    Ok(pairs)
}

/// Calibrate a stereo pair from the chessboard image pairs in `dir` (board of
/// `board_cols` x `board_rows` inner corners, squares `square_m` metres). Pairs where the board is
/// not found in one image are reported and left out of the calibrations that need them.
pub fn calibrate_stereo_dir(
    dir: &Path,
    board_cols: usize,
    board_rows: usize,
    square_m: f64,
) -> Result<(StereoCalibration, CalibrationReport), CalibError> {
    calibrate_stereo_dir_with_alpha(dir, board_cols, board_rows, square_m, RECTIFY_ALPHA)
}

/// [`calibrate_stereo_dir`] with the rectification's free-scaling parameter `rectify_alpha` in
/// [0, 1]: 0 keeps only valid pixels (no black border), 1 keeps every source pixel.
pub fn calibrate_stereo_dir_with_alpha(
    dir: &Path,
    board_cols: usize,
    board_rows: usize,
    square_m: f64,
    rectify_alpha: f64,
) -> Result<(StereoCalibration, CalibrationReport), CalibError> {
    validate_board(board_cols, board_rows, square_m)?;
    if !(0.0..=1.0).contains(&rectify_alpha) {
        return Err(CalibError::InvalidOption {
            field: "rectify_alpha",
            value: rectify_alpha.to_string(),
            allowed: "0..=1 (0: valid pixels only, 1: all source pixels)",
        });
    }
    let pairs = find_image_pairs(dir)?;
    let size = BoardSize {
        cols: board_cols,
        rows: board_rows,
    };
    let mut image_size: Option<(u32, u32, PathBuf)> = None;
    let mut detections: Vec<(Option<Corners>, Option<Corners>)> = Vec::with_capacity(pairs.len());
    for (_, left, right) in &pairs {
        let mut found = [None, None];
        for (k, path) in [left, right].into_iter().enumerate() {
            let frame = load_gray(path)?;
            match &image_size {
                None => image_size = Some((frame.width, frame.height, path.clone())),
                Some((w, h, _)) if (*w, *h) != (frame.width, frame.height) => {
                    return Err(CalibError::ImageSizeMismatch {
                        path: path.clone(),
                        width: frame.width,
                        height: frame.height,
                        expected_width: *w,
                        expected_height: *h,
                    })
                }
                Some(_) => {}
            }
            found[k] = find_chessboard_in_frame(&frame, size);
        }
        let [l, r] = found;
        detections.push((l, r));
    }
    let (width, height, _) = image_size.ok_or_else(|| CalibError::NoImagePairs {
        dir: dir.to_path_buf(),
    })?;
    let object = board_points(board_cols, board_rows, square_m);

    let left_idx: Vec<usize> = (0..pairs.len())
        .filter(|&i| detections[i].0.is_some())
        .collect();
    let right_idx: Vec<usize> = (0..pairs.len())
        .filter(|&i| detections[i].1.is_some())
        .collect();
    let both_idx: Vec<usize> = (0..pairs.len())
        .filter(|&i| detections[i].0.is_some() && detections[i].1.is_some())
        .collect();
    if left_idx.len() < MIN_VIEWS {
        return Err(CalibError::TooFewViews {
            what: "left camera",
            found: left_idx.len(),
            needed: MIN_VIEWS,
        });
    }
    if right_idx.len() < MIN_VIEWS {
        return Err(CalibError::TooFewViews {
            what: "right camera",
            found: right_idx.len(),
            needed: MIN_VIEWS,
        });
    }
    if both_idx.is_empty() {
        return Err(CalibError::TooFewViews {
            what: "stereo pairs",
            found: 0,
            needed: 1,
        });
    }
    let corners_of = |idx: &[usize], right: bool| -> Vec<Corners> {
        idx.iter()
            .filter_map(|&i| {
                if right {
                    detections[i].1.clone()
                } else {
                    detections[i].0.clone()
                }
            })
            .collect()
    };
    let left_views = corners_of(&left_idx, false);
    let right_views = corners_of(&right_idx, true);
    let left_cal = calibrate_camera(&object, &left_views, width, height)?;
    let right_cal = calibrate_camera(&object, &right_views, width, height)?;

    let stereo_left = corners_of(&both_idx, false);
    let stereo_right = corners_of(&both_idx, true);
    let pose_of = |idx: &[usize], poses: &[super::Pose], i: usize| {
        poses[idx.iter().position(|&k| k == i).unwrap_or(0)]
    };
    let left_poses: Vec<_> = both_idx
        .iter()
        .map(|&i| pose_of(&left_idx, &left_cal.poses, i))
        .collect();
    let right_poses: Vec<_> = both_idx
        .iter()
        .map(|&i| pose_of(&right_idx, &right_cal.poses, i))
        .collect();
    let stereo = calibrate_stereo(
        &object,
        &left_cal.intrinsics,
        &right_cal.intrinsics,
        &stereo_left,
        &stereo_right,
        &left_poses,
        &right_poses,
    )?;
    let rect = stereo_rectify(
        &left_cal.intrinsics,
        &right_cal.intrinsics,
        &stereo.r,
        &stereo.t,
        width,
        height,
        rectify_alpha,
    );
    let (epi_mean, epi_max) = epipolar_error(
        &left_cal.intrinsics,
        &right_cal.intrinsics,
        &rect,
        &stereo_left,
        &stereo_right,
    );

    let views = pairs
        .iter()
        .enumerate()
        .map(|(i, (id, left, right))| ViewReport {
            id: id.clone(),
            left_file: left.clone(),
            right_file: right.clone(),
            left_found: detections[i].0.is_some(),
            right_found: detections[i].1.is_some(),
            left_rms_px: left_idx
                .iter()
                .position(|&k| k == i)
                .map(|p| left_cal.view_rms_px[p]),
            right_rms_px: right_idx
                .iter()
                .position(|&k| k == i)
                .map(|p| right_cal.view_rms_px[p]),
            stereo_rms_px: both_idx
                .iter()
                .position(|&k| k == i)
                .map(|p| stereo.view_rms_px[p]),
        })
        .collect();
    let report = CalibrationReport {
        views,
        rms_left_px: left_cal.rms_px,
        rms_right_px: right_cal.rms_px,
        rms_stereo_px: stereo.rms_px,
        epipolar_error_mean_px: epi_mean,
        epipolar_error_max_px: epi_max,
    };
    let quality = QualityFigures {
        rms_left_px: left_cal.rms_px,
        rms_right_px: right_cal.rms_px,
        rms_stereo_px: stereo.rms_px,
        epipolar_error_px: epi_mean,
    };
    let calibration = StereoCalibration::new(
        width,
        height,
        &left_cal.intrinsics,
        &right_cal.intrinsics,
        &stereo.r,
        &stereo.t,
        &rect,
        quality,
    );
    calibration.validate()?;
    Ok((calibration, report))
}

/// Mean and largest |y_left - y_right| of corresponding points after rectification, pixels.
pub fn epipolar_error(
    left: &CameraIntrinsics,
    right: &CameraIntrinsics,
    rect: &Rectification,
    left_views: &[Corners],
    right_views: &[Corners],
) -> (f64, f64) {
    let (mut sum, mut max, mut n) = (0.0, 0.0f64, 0usize);
    for (lv, rv) in left_views.iter().zip(right_views) {
        for (pl, pr) in lv.iter().zip(rv) {
            let ql = rectify_point(left, &rect.r1, &rect.p1, *pl);
            let qr = rectify_point(right, &rect.r2, &rect.p2, *pr);
            let e = (ql[1] - qr[1]).abs();
            sum += e;
            max = max.max(e);
            n += 1;
        }
    }
    if n == 0 {
        (0.0, 0.0)
    } else {
        (sum / n as f64, max)
    }
}
