//! The stereo calibration file: a JSON document written atomically (temporary file in the same
//! directory, fsync, rename; the previous file kept as `<name>.bak`) and validated on load.

use std::io::Write;
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Matrix3x4, Matrix4, Vector3};
use serde::{Deserialize, Serialize};

use super::camera_model::CameraIntrinsics;
use super::error::CalibError;
use super::rectification::Rectification;
use crate::io::{MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE_PX};

/// Version of the file layout written by this crate.
pub const FORMAT_VERSION: u32 = 1;

/// A complete stereo calibration: both cameras, their relative pose, the rectification and the
/// quality figures. Matrices are row-major; OpenCV's names and conventions
/// (`X_right = R * X_left + T`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StereoCalibration {
    /// File layout version ([`FORMAT_VERSION`]).
    pub format_version: u32,
    /// Image width, pixels (both cameras).
    pub image_width: u32,
    /// Image height, pixels (both cameras).
    pub image_height: u32,
    /// Left camera matrix.
    pub m1: [[f64; 3]; 3],
    /// Left distortion `[k1, k2, p1, p2, k3]`.
    pub d1: [f64; 5],
    /// Right camera matrix.
    pub m2: [[f64; 3]; 3],
    /// Right distortion `[k1, k2, p1, p2, k3]`.
    pub d2: [f64; 5],
    /// Rotation from the left to the right camera frame.
    pub r: [[f64; 3]; 3],
    /// Translation from the left to the right camera frame, metres.
    pub t_m: [f64; 3],
    /// Left rectifying rotation.
    pub r1: [[f64; 3]; 3],
    /// Right rectifying rotation.
    pub r2: [[f64; 3]; 3],
    /// Left rectified projection.
    pub p1: [[f64; 4]; 3],
    /// Right rectified projection.
    pub p2: [[f64; 4]; 3],
    /// Disparity-to-depth matrix.
    pub q: [[f64; 4]; 4],
    /// RMS reprojection error of the left camera calibration, pixels.
    pub rms_left_px: f64,
    /// RMS reprojection error of the right camera calibration, pixels.
    pub rms_right_px: f64,
    /// RMS reprojection error of the stereo calibration, pixels.
    pub rms_stereo_px: f64,
    /// Mean |y_left - y_right| of the calibration corners after rectification, pixels.
    pub epipolar_error_px: f64,
    /// Creation time, seconds since the Unix epoch.
    pub created_unix_s: u64,
}

fn rows3(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))
}

fn rows34(m: &Matrix3x4<f64>) -> [[f64; 4]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))
}

fn rows44(m: &Matrix4<f64>) -> [[f64; 4]; 4] {
    std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))
}

fn intrinsics_matrix(c: &CameraIntrinsics) -> [[f64; 3]; 3] {
    [[c.fx, 0.0, c.cx], [0.0, c.fy, c.cy], [0.0, 0.0, 1.0]]
}

/// Quality figures stored with a calibration, pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QualityFigures {
    /// Left camera RMS reprojection error.
    pub rms_left_px: f64,
    /// Right camera RMS reprojection error.
    pub rms_right_px: f64,
    /// Stereo RMS reprojection error.
    pub rms_stereo_px: f64,
    /// Mean rectified epipolar error.
    pub epipolar_error_px: f64,
}

impl StereoCalibration {
    /// Assemble a calibration (time-stamped now).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        image_width: u32,
        image_height: u32,
        left: &CameraIntrinsics,
        right: &CameraIntrinsics,
        r: &Matrix3<f64>,
        t_m: &Vector3<f64>,
        rect: &Rectification,
        quality: QualityFigures,
    ) -> Self {
        let created_unix_s = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs())
            .unwrap_or(0);
        StereoCalibration {
            format_version: FORMAT_VERSION,
            image_width,
            image_height,
            m1: intrinsics_matrix(left),
            d1: left.dist,
            m2: intrinsics_matrix(right),
            d2: right.dist,
            r: rows3(r),
            t_m: [t_m.x, t_m.y, t_m.z],
            r1: rows3(&rect.r1),
            r2: rows3(&rect.r2),
            p1: rows34(&rect.p1),
            p2: rows34(&rect.p2),
            q: rows44(&rect.q),
            rms_left_px: quality.rms_left_px,
            rms_right_px: quality.rms_right_px,
            rms_stereo_px: quality.rms_stereo_px,
            epipolar_error_px: quality.epipolar_error_px,
            created_unix_s,
        }
    }

    /// Left camera intrinsics.
    pub fn left(&self) -> CameraIntrinsics {
        CameraIntrinsics {
            fx: self.m1[0][0],
            fy: self.m1[1][1],
            cx: self.m1[0][2],
            cy: self.m1[1][2],
            dist: self.d1,
        }
    }

    /// Right camera intrinsics.
    pub fn right(&self) -> CameraIntrinsics {
        CameraIntrinsics {
            fx: self.m2[0][0],
            fy: self.m2[1][1],
            cx: self.m2[0][2],
            cy: self.m2[1][2],
            dist: self.d2,
        }
    }

    /// Left rectifying rotation.
    pub fn r1(&self) -> Matrix3<f64> {
        Matrix3::from_fn(|i, j| self.r1[i][j])
    }

    /// Right rectifying rotation.
    pub fn r2(&self) -> Matrix3<f64> {
        Matrix3::from_fn(|i, j| self.r2[i][j])
    }

    /// Left rectified projection.
    pub fn p1(&self) -> Matrix3x4<f64> {
        Matrix3x4::from_fn(|i, j| self.p1[i][j])
    }

    /// Right rectified projection.
    pub fn p2(&self) -> Matrix3x4<f64> {
        Matrix3x4::from_fn(|i, j| self.p2[i][j])
    }

    /// Check every field: finite numbers, positive sizes and focal lengths, principal points
    /// inside the image, proper rotations, consistent rectified projections.
    pub fn validate(&self) -> Result<(), CalibError> {
        let bad = |field: &str, value: String, allowed: &'static str| {
            Err(CalibError::InvalidCalibration {
                field: field.to_string(),
                value,
                allowed,
            })
        };
        if self.format_version != FORMAT_VERSION {
            return bad(
                "format_version",
                self.format_version.to_string(),
                "must be 1",
            );
        }
        for (field, v) in [
            ("image_width", self.image_width),
            ("image_height", self.image_height),
        ] {
            if !(1..=MAX_IMAGE_SIDE_PX).contains(&v) {
                return bad(field, v.to_string(), "1..=16384 pixels");
            }
        }
        // The remap tables hold one entry per pixel and camera: bounded as images are.
        if u64::from(self.image_width) * u64::from(self.image_height) > MAX_IMAGE_PIXELS {
            return bad(
                "image_width x image_height",
                format!("{}x{}", self.image_width, self.image_height),
                "at most 4096 x 4096 pixels in all",
            );
        }
        let mut numbers: Vec<(String, f64)> = Vec::new();
        let mut push_rows = |name: &str, rows: &[&[f64]]| {
            for (i, row) in rows.iter().enumerate() {
                for (j, v) in row.iter().enumerate() {
                    numbers.push((format!("{name}[{i}][{j}]"), *v));
                }
            }
        };
        push_rows("m1", &[&self.m1[0], &self.m1[1], &self.m1[2]]);
        push_rows("d1", &[&self.d1]);
        push_rows("m2", &[&self.m2[0], &self.m2[1], &self.m2[2]]);
        push_rows("d2", &[&self.d2]);
        push_rows("r", &[&self.r[0], &self.r[1], &self.r[2]]);
        push_rows("t_m", &[&self.t_m]);
        push_rows("r1", &[&self.r1[0], &self.r1[1], &self.r1[2]]);
        push_rows("r2", &[&self.r2[0], &self.r2[1], &self.r2[2]]);
        push_rows("p1", &[&self.p1[0], &self.p1[1], &self.p1[2]]);
        push_rows("p2", &[&self.p2[0], &self.p2[1], &self.p2[2]]);
        push_rows("q", &[&self.q[0], &self.q[1], &self.q[2], &self.q[3]]);
        for (field, v) in numbers {
            if !v.is_finite() {
                return bad(&field, v.to_string(), "must be a finite number");
            }
        }
        let (w, h) = (f64::from(self.image_width), f64::from(self.image_height));
        for (name, m) in [("m1", &self.m1), ("m2", &self.m2)] {
            if m[0][0] <= 0.0 {
                return bad(
                    &format!("{name}[0][0] (fx)"),
                    m[0][0].to_string(),
                    "focal length must be > 0 pixels",
                );
            }
            if m[1][1] <= 0.0 {
                return bad(
                    &format!("{name}[1][1] (fy)"),
                    m[1][1].to_string(),
                    "focal length must be > 0 pixels",
                );
            }
            if !(0.0..w).contains(&m[0][2]) {
                return bad(
                    &format!("{name}[0][2] (cx)"),
                    m[0][2].to_string(),
                    "principal point must lie in 0..image_width",
                );
            }
            if !(0.0..h).contains(&m[1][2]) {
                return bad(
                    &format!("{name}[1][2] (cy)"),
                    m[1][2].to_string(),
                    "principal point must lie in 0..image_height",
                );
            }
            if m[1][0] != 0.0 || m[2] != [0.0, 0.0, 1.0] {
                return bad(
                    name,
                    format!("{m:?}"),
                    "camera matrix must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]]",
                );
            }
        }
        for (name, m) in [("r", &self.r), ("r1", &self.r1), ("r2", &self.r2)] {
            let rm = Matrix3::from_fn(|i, j| m[i][j]);
            let err = (rm.transpose() * rm - Matrix3::identity()).norm();
            if err > 1e-6 || (rm.determinant() - 1.0).abs() > 1e-6 {
                return bad(
                    name,
                    format!("{m:?}"),
                    "must be a rotation matrix (orthonormal, determinant +1)",
                );
            }
        }
        for (name, p) in [("p1", &self.p1), ("p2", &self.p2)] {
            if p[0][0] <= 0.0 || p[1][1] <= 0.0 {
                return bad(
                    &format!("{name} focal"),
                    format!("{}, {}", p[0][0], p[1][1]),
                    "focal length must be > 0 pixels",
                );
            }
        }
        if self.t_m.iter().all(|v| *v == 0.0) {
            return bad(
                "t_m",
                format!("{:?}", self.t_m),
                "baseline must be non-zero",
            );
        }
        for (field, v) in [
            ("rms_left_px", self.rms_left_px),
            ("rms_right_px", self.rms_right_px),
            ("rms_stereo_px", self.rms_stereo_px),
            ("epipolar_error_px", self.epipolar_error_px),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(field, v.to_string(), "must be a finite number >= 0");
            }
        }
        Ok(())
    }

    /// Write the calibration to `path` atomically; the previous file, if any, is kept as
    /// `<path>.bak`.
    pub fn save(&self, path: &Path) -> Result<(), CalibError> {
        self.validate()?;
        let json = serde_json::to_string_pretty(self)
            .map_err(|e| CalibError::Numerical(format!("cannot serialise calibration: {e}")))?;
        write_atomically(path, json.as_bytes())
    }

    /// Read and validate a calibration file. A truncated or corrupt file is an error.
    pub fn load(path: &Path) -> Result<Self, CalibError> {
        let text = std::fs::read_to_string(path).map_err(|e| CalibError::io("read", path, e))?;
        StereoCalibration::from_json(&text, path)
    }

    /// Parse and validate a calibration file's text; `path` names the file in errors.
    pub fn from_json(text: &str, path: &Path) -> Result<Self, CalibError> {
        let cal: StereoCalibration =
            serde_json::from_str(text).map_err(|e| CalibError::CorruptFile {
                path: path.to_path_buf(),
                message: e.to_string(),
            })?;
        cal.validate()?;
        Ok(cal)
    }
}

/// `<path>.bak`.
pub fn backup_path(path: &Path) -> PathBuf {
    let mut name = path
        .file_name()
        .map(|n| n.to_os_string())
        .unwrap_or_default();
    name.push(".bak");
    path.with_file_name(name)
}

/// Write `bytes` to `path` via a synced temporary file in the same directory and a rename; an
/// existing file is first preserved as `<path>.bak`.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), CalibError> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut tmp_name = path
        .file_name()
        .map(|n| n.to_os_string())
        .unwrap_or_default();
    tmp_name.push(format!(".tmp{}", std::process::id()));
    let tmp = dir.join(tmp_name);
    let result = (|| {
        let mut file =
            std::fs::File::create(&tmp).map_err(|e| CalibError::io("create", &tmp, e))?;
        file.write_all(bytes)
            .map_err(|e| CalibError::io("write", &tmp, e))?;
        file.sync_all()
            .map_err(|e| CalibError::io("sync", &tmp, e))?;
        drop(file);
        if path.exists() {
            let bak = backup_path(path);
            // A hard link keeps the live file in place until the rename replaces it.
            let _ = std::fs::remove_file(&bak);
            if std::fs::hard_link(path, &bak).is_err() {
                std::fs::copy(path, &bak).map_err(|e| CalibError::io("back up", &bak, e))?;
            }
        }
        std::fs::rename(&tmp, path).map_err(|e| CalibError::io("rename", path, e))?;
        if let Ok(d) = std::fs::File::open(&dir) {
            let _ = d.sync_all();
        }
        Ok(())
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::calib::geometry::rodrigues_to_matrix;
    use crate::calib::rectification::stereo_rectify;

    #[test]
    fn a_full_disk_refuses_the_calibration_and_leaves_the_previous_one_and_nothing_else() {
        let Some(disk) = videt_testkit::SmallDisk::mount_or_skip(1_000_000) else {
            return;
        };
        let path = disk.path().join("stereo.json");
        write_atomically(&path, b"{}").unwrap();
        let filler = disk.fill_leaving(4096).unwrap();
        let e = write_atomically(&path, &vec![b' '; 200_000]).expect_err("no room");
        assert!(e.to_string().contains("No space left"), "{e}");
        assert_eq!(std::fs::read(&path).unwrap(), b"{}");
        std::fs::remove_file(filler).unwrap();
        let left: Vec<_> = std::fs::read_dir(disk.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(
            left,
            vec!["stereo.json".to_string()],
            "no temporary file left"
        );
    }

    /// A calibration shaped like the real rig's.
    pub(crate) fn sample() -> StereoCalibration {
        let left = CameraIntrinsics {
            fx: 536.0,
            fy: 536.0,
            cx: 342.4,
            cy: 235.5,
            dist: [-0.265, -0.047, 0.0018, -0.0003, 0.252],
        };
        let right = CameraIntrinsics {
            fx: 542.3,
            fy: 541.6,
            cx: 328.3,
            cy: 247.0,
            dist: [-0.281, 0.104, -0.0006, 0.0013, -0.024],
        };
        let r = rodrigues_to_matrix(&Vector3::new(0.0003, 0.0035, -0.0041));
        let t = Vector3::new(-3.344, 0.0417, 0.0528);
        let rect = stereo_rectify(&left, &right, &r, &t, 640, 480, 1.0);
        let q = QualityFigures {
            rms_left_px: 0.2,
            rms_right_px: 0.21,
            rms_stereo_px: 0.22,
            epipolar_error_px: 0.08,
        };
        StereoCalibration::new(640, 480, &left, &right, &r, &t, &rect, q)
    }

    #[test]
    fn save_then_load_round_trips_and_keeps_a_backup() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("stereo.json");
        let first = sample();
        first.save(&path).unwrap();
        assert_eq!(StereoCalibration::load(&path).unwrap(), first);
        assert!(!backup_path(&path).exists());

        let mut second = sample();
        second.rms_stereo_px = 0.3;
        second.save(&path).unwrap();
        assert_eq!(StereoCalibration::load(&path).unwrap(), second);
        assert_eq!(StereoCalibration::load(&backup_path(&path)).unwrap(), first);
        // No temporary files left behind.
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 2, "{names:?}");
    }

    #[test]
    fn truncated_or_corrupt_file_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("stereo.json");
        sample().save(&path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        for cut in [0, 1, text.len() / 3, text.len() - 2] {
            std::fs::write(&path, &text[..cut]).unwrap();
            let err = StereoCalibration::load(&path).unwrap_err();
            assert!(
                matches!(err, CalibError::CorruptFile { .. }),
                "cut {cut}: {err}"
            );
        }
        std::fs::write(&path, text.replace("\"m1\"", "\"m_one\"")).unwrap();
        assert!(matches!(
            StereoCalibration::load(&path).unwrap_err(),
            CalibError::CorruptFile { .. }
        ));
        let err = StereoCalibration::load(&dir.path().join("missing.json")).unwrap_err();
        assert!(matches!(err, CalibError::Io { .. }), "{err}");
    }

    #[test]
    fn invalid_values_are_rejected_naming_the_field() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("stereo.json");
        type Corruption = Box<dyn Fn(&mut StereoCalibration)>;
        let cases: Vec<(&str, Corruption)> = vec![
            ("m1[0][0] (fx)", Box::new(|c| c.m1[0][0] = -5.0)),
            ("m2[1][1] (fy)", Box::new(|c| c.m2[1][1] = 0.0)),
            ("m1[0][2] (cx)", Box::new(|c| c.m1[0][2] = 900.0)),
            ("image_width", Box::new(|c| c.image_width = 0)),
            ("r1", Box::new(|c| c.r1[0][0] = 2.0)),
            ("rms_stereo_px", Box::new(|c| c.rms_stereo_px = -1.0)),
            ("t_m", Box::new(|c| c.t_m = [0.0; 3])),
        ];
        for (field, corrupt) in cases {
            let mut cal = sample();
            corrupt(&mut cal);
            match cal.validate().unwrap_err() {
                CalibError::InvalidCalibration { field: f, .. } => assert_eq!(f, field),
                other => panic!("{field}: unexpected {other}"),
            }
            // A file holding the bad value is refused on load, too.
            let json = serde_json::to_string(&cal).unwrap();
            std::fs::write(&path, json).unwrap();
            assert!(matches!(
                StereoCalibration::load(&path).unwrap_err(),
                CalibError::InvalidCalibration { .. }
            ));
            // And the writer refuses to write it.
            assert!(cal.save(&dir.path().join("other.json")).is_err());
        }
        // Found with the stereo_calibration fuzz target: a file of a 20000 x 20000 camera made the remap
        // tables allocate gigabytes; sizes are bounded as the images the pipeline loads.
        let mut json: serde_json::Value = serde_json::to_value(sample()).unwrap();
        json["image_width"] = 20_000.into();
        json["image_height"] = 20_000.into();
        let err = StereoCalibration::from_json(&json.to_string(), &path).unwrap_err();
        match err {
            CalibError::InvalidCalibration { field, value, .. } => {
                assert_eq!((field.as_str(), value.as_str()), ("image_width", "20000"))
            }
            other => panic!("unexpected {other}"),
        }
        json["image_width"] = 8_000.into();
        json["image_height"] = 6_000.into();
        let err = StereoCalibration::from_json(&json.to_string(), &path).unwrap_err();
        assert!(
            matches!(&err, CalibError::InvalidCalibration { field, .. } if field == "image_width x image_height"),
            "{err}"
        );
        // Non-finite numbers cannot even be written as JSON numbers; `null` is refused on load.
        let json = serde_json::to_string(&sample())
            .unwrap()
            .replacen("536.0", "null", 1);
        std::fs::write(&path, json).unwrap();
        assert!(StereoCalibration::load(&path).is_err());
    }
}
