//! The calibration file written by auto-initialization (`videt init`) and read by `videtd`.
//!
//! TOML, with a last line `checksum = "fnv1a64:<16 hex digits>"` over every byte before it, so a
//! corrupt or truncated file is detected and never half-read. Written atomically: a temporary file
//! in the same directory, `fsync`, the previous file copied to `<name>.bak` (also atomically),
//! `rename`, `fsync` of the directory.
//!
//! The file holds the measured base-triangle sides and their residuals, the guide points in the
//! paper's frame, the encoder count of each wire at free length zero (homing), and the workspace
//! the rig serves. The encoder zeros hold as long as the drives keep counting: after the drives
//! lose power, run `videt init` again.

use std::fs::{self, File};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// Version of the calibration format this code writes and reads.
pub const FORMAT_VERSION: u32 = 1;

/// A calibration error: what is wrong, with which file.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    /// There is no calibration file.
    #[error("no calibration at {path}: run `videt init`")]
    Missing {
        /// The file.
        path: String,
    },
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The I/O error.
        source: io::Error,
    },
    /// The file is corrupt or truncated (checksum missing or wrong, or not valid TOML).
    #[error("{path} is corrupt: {reason}; run `videt init` (the previous calibration may be in the .bak file)")]
    Corrupt {
        /// The file.
        path: String,
        /// What is wrong.
        reason: String,
    },
    /// A value is outside its allowed range.
    #[error("{path}: {field} = {value}: must be {allowed}")]
    Invalid {
        /// The file.
        path: String,
        /// The field.
        field: String,
        /// The value found.
        value: String,
        /// The allowed range.
        allowed: String,
    },
}

/// The workspace the calibrated rig serves (see `videt_control::autoinit::WorkspaceSpec`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorkspaceRecord {
    /// Force the wires render towards the frame everywhere in it, N.
    pub force_n: f64,
    /// Largest condition number of the force map in it.
    pub max_condition: f64,
    /// Volume, m³.
    pub volume_m3: f64,
    /// Lower corner of its bounding box, metres.
    pub min_m: [f64; 3],
    /// Upper corner, metres.
    pub max_m: [f64; 3],
    /// The longest each wire gets in it, metres.
    pub required_length_m: [f64; 3],
}

/// A rig calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Calibration {
    /// Format version ([`FORMAT_VERSION`]).
    pub format: u32,
    /// When it was measured, seconds since the Unix epoch.
    pub created_unix_s: u64,
    /// The same, as `YYYY-MM-DDTHH:MM:SSZ`.
    pub created_utc: String,
    /// Where it was measured: `device` or `twin`.
    pub source: String,
    /// Base-triangle sides `[d01, d02, d12]`, metres.
    pub sides_m: [f64; 3],
    /// Residuals of the six side measurements, metres (order: winding 0 gives d01, d02;
    /// winding 1 gives d01, d12; winding 2 gives d02, d12).
    pub residuals_m: [f64; 6],
    /// Guide points in the paper's frame, metres.
    pub guides_m: [[f64; 3]; 3],
    /// Encoder count of each wire at free length zero (its end at the guide ring).
    pub wire_zero_counts: [i64; 3],
    /// Metres of wire per encoder count when measured.
    pub metres_per_count: f64,
    /// The workspace.
    pub workspace: WorkspaceRecord,
}

/// Wire lengths at encoder count zero, metres, of wires whose free length is zero at
/// `zero_counts` with `metres_per_count` of wire per count.
pub fn length_at_zero_m(zero_counts: &[i64; 3], metres_per_count: f64) -> [f64; 3] {
    core::array::from_fn(|i| zero_counts[i] as f64 * metres_per_count)
}

impl Calibration {
    /// Wire length at encoder count zero, metres (`length = this - counts · m/count`).
    pub fn length_at_zero_m(&self) -> [f64; 3] {
        length_at_zero_m(&self.wire_zero_counts, self.metres_per_count)
    }

    /// Age at `now_unix_s`, seconds (0 when the clock is behind the file).
    pub fn age_s(&self, now_unix_s: u64) -> u64 {
        now_unix_s.saturating_sub(self.created_unix_s)
    }

    /// Check every value; `path` names the file in errors.
    pub fn validate(&self, path: &str) -> Result<(), CalibrationError> {
        let invalid = |field: &str, value: String, allowed: &str| CalibrationError::Invalid {
            path: path.to_string(),
            field: field.to_string(),
            value,
            allowed: allowed.to_string(),
        };
        if self.format != FORMAT_VERSION {
            return Err(invalid(
                "format",
                self.format.to_string(),
                &format!("{FORMAT_VERSION}"),
            ));
        }
        for (k, s) in self.sides_m.iter().enumerate() {
            if !(s.is_finite() && *s > 0.0 && *s < 5.0) {
                return Err(invalid(
                    &format!("sides_m[{k}]"),
                    s.to_string(),
                    "in (0, 5) m",
                ));
            }
        }
        for (k, r) in self.residuals_m.iter().enumerate() {
            if !(r.is_finite() && r.abs() < 0.1) {
                return Err(invalid(
                    &format!("residuals_m[{k}]"),
                    r.to_string(),
                    "in (-0.1, 0.1) m",
                ));
            }
        }
        for (i, g) in self.guides_m.iter().enumerate() {
            for (axis, v) in ["x", "y", "z"].iter().zip(g) {
                if !(v.is_finite() && v.abs() < 5.0) {
                    return Err(invalid(
                        &format!("guides_m[{i}].{axis}"),
                        v.to_string(),
                        "finite, within 5 m",
                    ));
                }
            }
        }
        let dist = |a: usize, b: usize| {
            let d: [f64; 3] = core::array::from_fn(|k| self.guides_m[a][k] - self.guides_m[b][k]);
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
        };
        for (k, (a, b)) in [(0, 1), (0, 2), (1, 2)].into_iter().enumerate() {
            if (dist(a, b) - self.sides_m[k]).abs() > 1e-6 {
                return Err(invalid(
                    "guides_m",
                    format!("{:?}", self.guides_m),
                    &format!("consistent with sides_m[{k}] = {}", self.sides_m[k]),
                ));
            }
        }
        if !(self.metres_per_count.is_finite()
            && self.metres_per_count > 0.0
            && self.metres_per_count < 1e-2)
        {
            return Err(invalid(
                "metres_per_count",
                self.metres_per_count.to_string(),
                "in (0, 0.01)",
            ));
        }
        Ok(())
    }

    /// The file's text: the TOML body and its checksum line.
    pub fn to_text(&self) -> Result<String, CalibrationError> {
        let body = toml::to_string(self).map_err(|e| CalibrationError::Corrupt {
            path: String::new(),
            reason: e.to_string(),
        })?;
        let header = "# VIDET rig calibration, written by `videt init`. Do not edit: the last line is a checksum.\n";
        let body = format!("{header}{body}");
        Ok(format!("{body}{}", checksum_line(body.as_bytes())))
    }

    /// Parse and check a file's text; `path` names the file in errors.
    pub fn from_text(text: &str, path: &str) -> Result<Calibration, CalibrationError> {
        let body = verified_body(text, path)?;
        let c: Calibration = toml::from_str(body).map_err(|e| CalibrationError::Corrupt {
            path: path.to_string(),
            reason: e.to_string(),
        })?;
        c.validate(path)?;
        Ok(c)
    }

    /// Read and check a calibration file.
    pub fn load(path: &Path) -> Result<Calibration, CalibrationError> {
        let shown = path.display().to_string();
        let bytes = match fs::read(path) {
            Ok(b) => b,
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                return Err(CalibrationError::Missing { path: shown })
            }
            Err(source) => {
                return Err(CalibrationError::Io {
                    path: shown,
                    source,
                })
            }
        };
        let text = String::from_utf8(bytes).map_err(|_| CalibrationError::Corrupt {
            path: shown.clone(),
            reason: "not UTF-8 text".into(),
        })?;
        Calibration::from_text(&text, &shown)
    }

    /// Write atomically, keeping the previous file as `<name>.bak`.
    pub fn save(&self, path: &Path) -> Result<(), CalibrationError> {
        self.validate(&path.display().to_string())?;
        let text = self.to_text()?;
        write_atomically(path, text.as_bytes()).map_err(|source| CalibrationError::Io {
            path: path.display().to_string(),
            source,
        })
    }
}

/// The two-point calibration of the wire-tension sensors (`videt tension-calibrate`), in its own
/// file beside the rig calibration (`tension-calibration.toml`), checksummed and written the
/// same way. A corrected tension is `(reading - offset_n) * gain`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TensionCalibration {
    /// Format version ([`FORMAT_VERSION`]).
    pub format: u32,
    /// Reading of each sensor with its wire unloaded, N.
    pub offset_n: [f64; 3],
    /// Gain correction of each sensor (known load / reading change).
    pub gain: [f64; 3],
    /// When each wire was last calibrated, seconds since the Unix epoch (0: never).
    pub calibrated_unix_s: [u64; 3],
}

impl Default for TensionCalibration {
    fn default() -> Self {
        TensionCalibration {
            format: FORMAT_VERSION,
            offset_n: [0.0; 3],
            gain: [1.0; 3],
            calibrated_unix_s: [0; 3],
        }
    }
}

impl TensionCalibration {
    /// The file beside a rig calibration file.
    pub fn path_beside(calibration: &Path) -> PathBuf {
        calibration.with_file_name("tension-calibration.toml")
    }

    /// The corrected tension of wire `i` from a reading, N.
    pub fn correct(&self, i: usize, reading_n: f64) -> f64 {
        (reading_n - self.offset_n[i]) * self.gain[i]
    }

    /// Check every value.
    pub fn validate(&self, path: &str) -> Result<(), CalibrationError> {
        let invalid = |field: String, value: f64, allowed: &str| CalibrationError::Invalid {
            path: path.to_string(),
            field,
            value: value.to_string(),
            allowed: allowed.to_string(),
        };
        for i in 0..3 {
            if !(self.offset_n[i].is_finite() && self.offset_n[i].abs() <= 5.0) {
                return Err(invalid(
                    format!("offset_n[{i}]"),
                    self.offset_n[i],
                    "in [-5, 5] N",
                ));
            }
            if !(self.gain[i].is_finite() && (0.5..=2.0).contains(&self.gain[i])) {
                return Err(invalid(format!("gain[{i}]"), self.gain[i], "in [0.5, 2]"));
            }
        }
        Ok(())
    }

    /// Read and check the file.
    pub fn load(path: &Path) -> Result<TensionCalibration, CalibrationError> {
        let shown = path.display().to_string();
        let text = match fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                return Err(CalibrationError::Missing { path: shown })
            }
            Err(source) => {
                return Err(CalibrationError::Io {
                    path: shown,
                    source,
                })
            }
        };
        TensionCalibration::from_text(&text, &shown)
    }

    /// Parse and check a file's text; `path` names the file in errors.
    pub fn from_text(text: &str, path: &str) -> Result<TensionCalibration, CalibrationError> {
        let body = verified_body(text, path)?;
        let c: TensionCalibration =
            toml::from_str(body).map_err(|e| CalibrationError::Corrupt {
                path: path.to_string(),
                reason: e.to_string(),
            })?;
        c.validate(path)?;
        Ok(c)
    }

    /// Write atomically, keeping the previous file as `<name>.bak`.
    pub fn save(&self, path: &Path) -> Result<(), CalibrationError> {
        let shown = path.display().to_string();
        self.validate(&shown)?;
        let body = toml::to_string(self).map_err(|e| CalibrationError::Corrupt {
            path: shown.clone(),
            reason: e.to_string(),
        })?;
        let body = format!("# VIDET tension-sensor calibration, written by `videt tension-calibrate`. The last line is a checksum.\n{body}");
        let text = format!("{body}{}", checksum_line(body.as_bytes()));
        write_atomically(path, text.as_bytes()).map_err(|source| CalibrationError::Io {
            path: shown,
            source,
        })
    }
}

/// FNV-1a, 64 bits.
fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

const CHECKSUM_PREFIX: &str = "checksum = \"fnv1a64:";

fn checksum_line(body: &[u8]) -> String {
    format!("{CHECKSUM_PREFIX}{:016x}\"\n", fnv1a64(body))
}

/// The body of a checksummed text once its last line's checksum matches it.
pub fn verified_body<'a>(text: &'a str, path: &str) -> Result<&'a str, CalibrationError> {
    let corrupt = |reason: &str| CalibrationError::Corrupt {
        path: path.to_string(),
        reason: reason.to_string(),
    };
    let trimmed = text
        .strip_suffix('\n')
        .ok_or_else(|| corrupt("truncated (no final newline)"))?;
    let start = trimmed.rfind('\n').map_or(0, |i| i + 1);
    let last = &trimmed[start..];
    if !last.starts_with(CHECKSUM_PREFIX) {
        return Err(corrupt("truncated (the checksum line is missing)"));
    }
    let body = &text[..start];
    if checksum_line(body.as_bytes()) != text[start..] {
        return Err(corrupt("checksum mismatch"));
    }
    Ok(body)
}

/// The backup's path: `<path>.bak`.
pub fn backup_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".bak");
    path.with_file_name(name)
}

/// Write `contents` to `path` atomically: a temporary file in the same directory, `fsync`,
/// the previous file (if any) copied to `<path>.bak` the same way, `rename`, `fsync` of the
/// directory. A crash at any point leaves either the old or the new file, never a mix.
///
/// A path that exists and is not a regular file (`/dev/null`, `/dev/stdout`, a FIFO) is written
/// to as it is: renaming over it would replace the device or pipe with a file.
pub fn write_atomically(path: &Path, contents: &[u8]) -> io::Result<()> {
    if fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir()) {
        let mut f = fs::OpenOptions::new().write(true).open(path)?;
        return f.write_all(contents);
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    fs::create_dir_all(&dir)?;
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "not a file path"))?
        .to_string_lossy()
        .into_owned();
    let temp = |tag: &str| dir.join(format!(".{name}.{tag}.{}", std::process::id()));
    if path.exists() {
        let old = fs::read(path)?;
        let bak_temp = temp("bak-tmp");
        // A full disk refuses the backup first: nothing of it stays behind.
        if let Err(e) = write_synced(&bak_temp, &old) {
            let _ = fs::remove_file(&bak_temp);
            return Err(e);
        }
        fs::rename(&bak_temp, backup_path(path))?;
    }
    let new_temp = temp("tmp");
    if let Err(e) = write_synced(&new_temp, contents) {
        let _ = fs::remove_file(&new_temp);
        return Err(e);
    }
    fs::rename(&new_temp, path)?;
    File::open(&dir)?.sync_all()
}

fn write_synced(path: &Path, contents: &[u8]) -> io::Result<()> {
    let mut f = File::create(path)?;
    f.write_all(contents)?;
    f.sync_all()
}

/// `YYYY-MM-DDTHH:MM:SSZ` for seconds since the Unix epoch (proleptic Gregorian, UTC).
pub fn utc_timestamp(unix_s: u64) -> String {
    let days = (unix_s / 86_400) as i64;
    let secs = unix_s % 86_400;
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        secs / 3600,
        secs / 60 % 60,
        secs % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_disk_refuses_the_write_and_leaves_the_previous_file_and_no_temporary_one() {
        let Some(disk) = videt_testkit::SmallDisk::mount_or_skip(1_000_000) else {
            return;
        };
        let path = disk.path().join("calibration.toml");
        write_atomically(&path, b"# the calibration in force\n").unwrap();
        let filler = disk.fill_leaving(4096).unwrap();
        let e = write_atomically(&path, &[b'#'; 200_000]).expect_err("no room");
        assert_eq!(e.kind(), io::ErrorKind::StorageFull, "{e}");
        assert_eq!(
            std::fs::read(&path).unwrap(),
            b"# the calibration in force\n"
        );
        std::fs::remove_file(filler).unwrap();
        // The previous file and its backup (written before the new file was refused), and no
        // temporary file.
        let mut left: Vec<_> = std::fs::read_dir(disk.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, ["calibration.toml", "calibration.toml.bak"]);
        assert_eq!(
            std::fs::read(backup_path(&path)).unwrap(),
            b"# the calibration in force\n"
        );

        // A large previous file: its backup is what the disk refuses.
        let large = vec![b'#'; 300_000];
        write_atomically(&path, &large).unwrap();
        std::fs::remove_file(backup_path(&path)).unwrap();
        let filler = disk.fill_leaving(100_000).unwrap();
        let e = write_atomically(&path, b"# new\n").expect_err("no room for the backup");
        assert_eq!(e.kind(), io::ErrorKind::StorageFull, "{e}");
        assert_eq!(std::fs::read(&path).unwrap(), large);
        std::fs::remove_file(filler).unwrap();
        let left: Vec<_> = std::fs::read_dir(disk.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(left, ["calibration.toml"], "no temporary file left");
    }

    #[test]
    fn a_pipe_or_device_is_written_to_not_replaced() {
        use std::io::Read;
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("out.csv");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            eprintln!("skipping: mkfifo is not available");
            return;
        }
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || {
                let mut text = String::new();
                File::open(&fifo)
                    .unwrap()
                    .read_to_string(&mut text)
                    .unwrap();
                text
            })
        };
        write_atomically(&fifo, b"cycle,time_s\n").unwrap();
        assert_eq!(reader.join().unwrap(), "cycle,time_s\n");
        let kind = fs::symlink_metadata(&fifo).unwrap().file_type();
        assert!(kind.is_fifo(), "the pipe was replaced: {kind:?}");
        assert!(!backup_path(&fifo).exists());
    }

    fn sample() -> Calibration {
        let (a, b, c) = (0.37_f64, 0.35_f64, 0.31_f64);
        let x2 = (a * a + b * b - c * c) / (2.0 * a);
        let y2 = (b * b - x2 * x2).sqrt();
        Calibration {
            format: FORMAT_VERSION,
            created_unix_s: 1_795_000_000,
            created_utc: utc_timestamp(1_795_000_000),
            source: "twin".into(),
            sides_m: [a, b, c],
            residuals_m: [1e-5, -2e-5, -1e-5, 3e-5, 2e-5, -3e-5],
            guides_m: [[0.0; 3], [a, 0.0, 0.0], [x2, y2, 0.0]],
            wire_zero_counts: [123, -4_567_890, 42],
            metres_per_count: 2.5e-6,
            workspace: WorkspaceRecord {
                force_n: 3.0,
                max_condition: 20.0,
                volume_m3: 0.01,
                min_m: [0.0, 0.0, 0.1],
                max_m: [0.3, 0.3, 0.6],
                required_length_m: [0.7, 0.7, 0.7],
            },
        }
    }

    #[test]
    fn round_trips_exactly() {
        let c = sample();
        let text = c.to_text().unwrap();
        assert_eq!(Calibration::from_text(&text, "t").unwrap(), c);
    }

    #[test]
    fn every_truncation_and_every_flipped_byte_is_detected() {
        let text = sample().to_text().unwrap();
        for cut in 0..text.len() {
            assert!(
                Calibration::from_text(&text[..cut], "t").is_err(),
                "a file cut at {cut} bytes was accepted"
            );
        }
        let bytes = text.as_bytes();
        for i in (0..bytes.len()).step_by(7) {
            let mut b = bytes.to_vec();
            b[i] ^= 0x01;
            if let Ok(t) = String::from_utf8(b) {
                assert!(
                    Calibration::from_text(&t, "t").is_err(),
                    "flip at {i} accepted"
                );
            }
        }
    }

    #[test]
    fn timestamps_are_utc_dates() {
        assert_eq!(utc_timestamp(0), "1970-01-01T00:00:00Z");
        assert_eq!(utc_timestamp(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(utc_timestamp(1_795_000_000), "2026-11-18T11:06:40Z");
    }

    #[test]
    fn save_keeps_the_previous_file_as_backup() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub").join("calibration.toml");
        let first = sample();
        first.save(&path).unwrap();
        let first_bytes = fs::read(&path).unwrap();
        let mut second = sample();
        second.sides_m[0] += 0.0;
        second.created_unix_s += 60;
        second.save(&path).unwrap();
        assert_eq!(fs::read(backup_path(&path)).unwrap(), first_bytes);
        assert_eq!(Calibration::load(&path).unwrap(), second);
        let names: Vec<_> = fs::read_dir(path.parent().unwrap())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names.len(), 2, "no temporary file left: {names:?}");
    }

    #[test]
    fn tension_calibration_round_trips_and_rejects_corruption() {
        let dir = tempfile::tempdir().unwrap();
        let path = TensionCalibration::path_beside(&dir.path().join("calibration.toml"));
        let mut t = TensionCalibration::default();
        t.offset_n[1] = -0.03;
        t.gain[1] = 1.0 / 0.985;
        t.save(&path).unwrap();
        assert_eq!(TensionCalibration::load(&path).unwrap(), t);
        let text = fs::read_to_string(&path).unwrap();
        fs::write(&path, &text[..text.len() - 5]).unwrap();
        assert!(matches!(
            TensionCalibration::load(&path),
            Err(CalibrationError::Corrupt { .. })
        ));
    }

    #[test]
    fn missing_and_inconsistent_files_say_why() {
        let dir = tempfile::tempdir().unwrap();
        let e = Calibration::load(&dir.path().join("none.toml")).unwrap_err();
        assert!(matches!(e, CalibrationError::Missing { .. }), "{e}");
        let mut c = sample();
        c.sides_m[2] = 0.2;
        let e = c.validate("t").unwrap_err().to_string();
        assert!(e.contains("guides_m"), "{e}");
        let mut c = sample();
        c.sides_m[1] = f64::NAN;
        let e = c.save(&dir.path().join("c.toml")).unwrap_err().to_string();
        assert!(e.contains("sides_m[1]"), "{e}");
    }
}
