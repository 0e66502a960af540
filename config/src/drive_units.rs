//! The drives' units: the rated torque that target torque is per mille of, the encoder
//! resolution and the gear, from `drives.device_description` (the drive's EDS or DCF) when the
//! configuration names one, else from `drives.rated_torque_nm` and `[transmission]`; and what
//! they mean for the wires: one step of target torque in newtons of wire tension, and the
//! share of the drive's torque range that `control.t_max_n` needs.
//!
//! Precedence: a value the file gives is used; the same value set in the configuration too
//! must agree with it within 1 % ([`AGREEMENT`]) or the configuration is refused, naming both.
//! A value the file does not give comes from the configuration (or its default).

use std::path::{Path, PathBuf};

use videt_drive_description::units::{
    DriveResolution, Sourced, TorqueUnit, MAX_TARGET_TORQUE_PERMILLE,
};
use videt_drive_description::Eds;

use crate::{Config, ConfigError};

/// The largest relative difference between a value the device description gives and the same
/// value set in the configuration.
pub const AGREEMENT: f64 = 0.01;

/// `drives.device_description` as read on load.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceDescription {
    /// The file read (a relative `drives.device_description` joined to the configuration
    /// file's directory).
    pub path: PathBuf,
    /// What it gives.
    pub resolution: DriveResolution,
}

impl DeviceDescription {
    /// The unit the drives give their rated torque (0x6076) in.
    pub fn torque_unit(&self) -> TorqueUnit {
        self.resolution.torque_unit
    }

    /// Encoder counts per drive position unit (0x6064) with `counts_per_rev` counts per motor
    /// revolution; `None` when the file gives no position unit.
    pub fn counts_per_position_unit(&self, counts_per_rev: f64) -> Option<f64> {
        let unit = self.resolution.position_unit.as_ref()?;
        unit.value.counts_per_unit(Some(counts_per_rev))
    }

    /// Counts per second per drive velocity unit (0x606C) with `counts_per_rev` counts per
    /// motor revolution (rev/min: `counts_per_rev / 60`); `None` when the file gives no
    /// velocity unit.
    pub fn counts_per_s_per_velocity_unit(&self, counts_per_rev: f64) -> Option<f64> {
        let unit = self.resolution.velocity_unit.as_ref()?;
        unit.value.counts_per_s_per_unit(Some(counts_per_rev))
    }
}

/// Which of the values a device description also gives are set in the configuration file.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct ExplicitUnits {
    /// `drives.rated_torque_nm`.
    pub rated_torque: bool,
    /// `transmission.counts_per_motor_rev`.
    pub counts_per_motor_rev: bool,
    /// `transmission.gear_ratio`.
    pub gear_ratio: bool,
}

impl ExplicitUnits {
    /// The keys set in a configuration's TOML text.
    pub(crate) fn of(text: &str) -> ExplicitUnits {
        let table: toml::Table = toml::from_str(text).unwrap_or_default();
        let set = |section: &str, key: &str| {
            table
                .get(section)
                .and_then(|s| s.as_table())
                .is_some_and(|s| s.contains_key(key))
        };
        ExplicitUnits {
            rated_torque: set("drives", "rated_torque_nm"),
            counts_per_motor_rev: set("transmission", "counts_per_motor_rev"),
            gear_ratio: set("transmission", "gear_ratio"),
        }
    }
}

/// A number with three significant digits, without trailing zeros.
pub fn significant(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return x.to_string();
    }
    let decimals = 2 - x.abs().log10().floor() as i32;
    if decimals <= 0 {
        return format!("{x:.0}");
    }
    let text = format!("{x:.prec$}", prec = decimals as usize);
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

fn device_error(path: &Path, message: String) -> ConfigError {
    ConfigError::DeviceDescription {
        path: path.display().to_string(),
        message,
    }
}

/// Read `drives.device_description` (relative to `base_dir` when given, else to the working
/// directory) and put the units it gives into `config`, refusing a value set in the
/// configuration too that differs by more than [`AGREEMENT`].
pub(crate) fn apply(
    config: &mut Config,
    base_dir: Option<&Path>,
    explicit: ExplicitUnits,
) -> Result<(), ConfigError> {
    let Some(named) = config.drives.device_description.clone() else {
        config.drives.description = None;
        return Ok(());
    };
    if named.trim().is_empty() {
        return Err(ConfigError::Invalid {
            field: "drives.device_description".into(),
            value: "\"\"".into(),
            allowed: "the path of the drives' EDS or DCF file (or left out)".into(),
        });
    }
    let path = match base_dir {
        Some(dir) => dir.join(&named),
        None => PathBuf::from(&named),
    };
    let bytes =
        std::fs::read(&path).map_err(|e| device_error(&path, format!("cannot read it: {e}")))?;
    // Vendors' files are not always UTF-8 (a µ in a comment): the objects are ASCII.
    let text = String::from_utf8_lossy(&bytes);
    let eds = Eds::parse(&text)
        .map_err(|e| device_error(&path, format!("not a readable EDS or DCF: {e}")))?;
    let file = path
        .file_name()
        .map_or_else(|| named.clone(), |n| n.to_string_lossy().into_owned());
    let resolution = DriveResolution::from_eds(&eds, &file, config.drives.node_ids[0])
        .map_err(|e| device_error(&path, e.to_string()))?;

    if let Some(rated) = &resolution.rated_torque_nm {
        adopt(
            "drives.rated_torque_nm",
            "N·m",
            &mut config.drives.rated_torque_nm,
            explicit.rated_torque,
            rated,
            (1e-4, 10.0),
            &named,
        )?;
    }
    if let Some(counts) = &resolution.counts_per_motor_rev {
        if (counts.value - counts.value.round()).abs() > 1e-9 {
            return Err(ConfigError::Invalid {
                field: "transmission.counts_per_motor_rev".into(),
                value: format!("{} ({})", counts.value, counts.origin),
                allowed: "a whole number of counts per motor revolution".into(),
            });
        }
        let mut value = f64::from(config.transmission.counts_per_motor_rev);
        adopt(
            "transmission.counts_per_motor_rev",
            "counts/rev",
            &mut value,
            explicit.counts_per_motor_rev,
            counts,
            (1.0, 1_000_000.0),
            &named,
        )?;
        config.transmission.counts_per_motor_rev = value.round() as u32;
    }
    if let Some(gear) = &resolution.gear_ratio {
        adopt(
            "transmission.gear_ratio",
            "",
            &mut config.transmission.gear_ratio,
            explicit.gear_ratio,
            gear,
            (1.0, 1000.0),
            &named,
        )?;
    }
    for (unit, object, what) in [
        (
            resolution.position_unit.as_ref(),
            "0x60A8",
            "a position unit of increments or revolutions",
        ),
        (
            resolution.velocity_unit.as_ref(),
            "0x60A9",
            "a velocity unit of increments or revolutions per second or per minute",
        ),
    ] {
        let Some(unit) = unit else { continue };
        let counts = Some(f64::from(config.transmission.counts_per_motor_rev));
        let understood = if object == "0x60A8" {
            unit.value.counts_per_unit(counts)
        } else {
            unit.value.counts_per_s_per_unit(counts)
        };
        if understood.is_none() {
            return Err(device_error(
                &path,
                format!(
                    "{object} = 0x{:08X} ({}): must be {what} (CiA 402 SI unit codes)",
                    unit.value.0, unit.origin
                ),
            ));
        }
    }
    config.drives.description = Some(DeviceDescription { path, resolution });
    Ok(())
}

/// Use the file's `from` for `field`, checking its range and, when the configuration sets the
/// field too, that both agree.
fn adopt(
    field: &str,
    unit: &str,
    value: &mut f64,
    explicit: bool,
    from: &Sourced<f64>,
    (lo, hi): (f64, f64),
    named: &str,
) -> Result<(), ConfigError> {
    let given = from.value;
    if !(given >= lo && given <= hi) {
        return Err(ConfigError::Invalid {
            field: field.into(),
            value: format!("{given} ({})", from.origin),
            allowed: format!("in [{lo}, {hi}]"),
        });
    }
    // NaN set in the configuration disagrees too.
    let agrees = (*value - given).abs() <= AGREEMENT * given;
    if explicit && !agrees {
        let unit = if unit.is_empty() {
            String::new()
        } else {
            format!(" {unit}")
        };
        return Err(ConfigError::Invalid {
            field: field.into(),
            value: value.to_string(),
            allowed: format!(
                "within {}% of {given}{unit}, the value {} gives in drives.device_description = \
                 {named:?} (or left out, to take the file's)",
                AGREEMENT * 100.0,
                from.origin
            ),
        });
    }
    *value = given;
    Ok(())
}

/// Where the configuration's rated torque, encoder resolution or gear came from: the file's
/// objects, or the configuration field.
fn origin_of(sourced: Option<&Sourced<f64>>, field: &str, file_named: &mut bool) -> String {
    match sourced {
        Some(s) if !*file_named => {
            *file_named = true;
            s.origin.to_string()
        }
        Some(s) => s.origin.expression.clone(),
        None => field.to_string(),
    }
}

impl Config {
    /// The tension of one step of target torque (one per mille of the rated torque) through
    /// the transmission, N.
    pub fn torque_step_tension_n(&self) -> f64 {
        let t = &self.transmission;
        self.drives.rated_torque_nm / 1000.0 * t.gear_ratio * t.efficiency / t.pulley_radius_m
    }

    /// The most per mille of rated torque the drives can be commanded: their 0x6072 when the
    /// device description gives it, else what the INTEGER16 target torque carries.
    pub fn max_torque_permille(&self) -> (u16, String) {
        match self
            .drives
            .description
            .as_ref()
            .and_then(|d| d.resolution.max_torque_permille.as_ref())
        {
            Some(m) => (
                m.value,
                format!("0x6072 = {} per mille of {}", m.value, m.origin.file),
            ),
            None => (
                MAX_TARGET_TORQUE_PERMILLE,
                format!(
                    "the {MAX_TARGET_TORQUE_PERMILLE} per mille an INTEGER16 target torque \
                     (0x6071) carries"
                ),
            ),
        }
    }

    /// The target torque that holds `control.t_max_n`, per mille of the rated torque.
    pub fn t_max_permille(&self) -> f64 {
        let t = &self.transmission;
        let torque_nm = self.control.t_max_n * t.pulley_radius_m / (t.gear_ratio * t.efficiency);
        torque_nm / self.drives.rated_torque_nm * 1000.0
    }

    /// Refuse drives too coarse for `control.t_min_n` (one torque step is more tension) or too
    /// weak for `control.t_max_n`, naming the fields and the numbers.
    pub(crate) fn validate_drive_units(&self) -> Result<(), ConfigError> {
        let t = &self.transmission;
        let rated = self.drives.rated_torque_nm;
        let rated_from = self
            .drives
            .description
            .as_ref()
            .and_then(|d| d.resolution.rated_torque_nm.as_ref())
            .map_or(String::new(), |r| format!(" ({})", r.origin));
        let step_n = self.torque_step_tension_n();
        let c = &self.control;
        if step_n > c.t_min_n {
            return Err(ConfigError::Invalid {
                field: "control.t_min_n".into(),
                value: c.t_min_n.to_string(),
                allowed: format!(
                    "at least one step of target torque, {} N of wire tension: 1 per mille of \
                     drives.rated_torque_nm = {rated} N·m{rated_from} is {} mN·m, through \
                     transmission.gear_ratio = {} and transmission.efficiency = {} onto \
                     transmission.pulley_radius_m = {} m (the drives could not hold a smaller \
                     tension)",
                    significant(step_n),
                    significant(rated),
                    t.gear_ratio,
                    t.efficiency,
                    t.pulley_radius_m
                ),
            });
        }
        let needed = self.t_max_permille();
        let (limit, limit_from) = self.max_torque_permille();
        if needed > f64::from(limit) {
            let highest = c.t_max_n * f64::from(limit) / needed;
            return Err(ConfigError::Invalid {
                field: "control.t_max_n".into(),
                value: c.t_max_n.to_string(),
                allowed: format!(
                    "at most {} N: holding {} N takes {} per mille of drives.rated_torque_nm = \
                     {rated} N·m{rated_from} through transmission.gear_ratio = {} onto \
                     transmission.pulley_radius_m = {} m, beyond {limit_from}",
                    significant(highest),
                    c.t_max_n,
                    significant(needed),
                    t.gear_ratio,
                    t.pulley_radius_m
                ),
            });
        }
        Ok(())
    }

    /// A one-line account of the drives' units and what one torque step is on a wire, for
    /// `videt config check` and the service's start-up log, e.g.
    /// `drives: rated torque 0.513 N·m (0x6076 of x.dcf), 1 step = 0.513 mN·m = 0.667 N of
    /// wire tension; encoder 3200 counts/rev (0x3000 sub5); gear 26 (0x3003 sub1/sub2); ...`.
    pub fn describe_drive_units(&self) -> String {
        let res = self.drives.description.as_ref().map(|d| &d.resolution);
        let mut file_named = false;
        let rated_from = origin_of(
            res.and_then(|r| r.rated_torque_nm.as_ref()),
            "drives.rated_torque_nm",
            &mut file_named,
        );
        let counts_from = origin_of(
            res.and_then(|r| r.counts_per_motor_rev.as_ref()),
            "transmission.counts_per_motor_rev",
            &mut file_named,
        );
        let gear_from = origin_of(
            res.and_then(|r| r.gear_ratio.as_ref()),
            "transmission.gear_ratio",
            &mut file_named,
        );
        let rated = self.drives.rated_torque_nm;
        let (limit, _) = self.max_torque_permille();
        let mut line = format!(
            "drives: rated torque {} N·m ({rated_from}), 1 step = {} mN·m = {} N of wire \
             tension; encoder {} counts/rev ({counts_from}); gear {} ({gear_from}); \
             control.t_max_n = {} N takes {} per mille (limit {limit})",
            significant(rated),
            significant(rated),
            significant(self.torque_step_tension_n()),
            self.transmission.counts_per_motor_rev,
            significant(self.transmission.gear_ratio),
            self.control.t_max_n,
            significant(self.t_max_permille()),
        );
        if let Some(d) = &self.drives.description {
            let r = &d.resolution;
            if let Some(v) = &r.velocity_unit {
                line.push_str(&format!(
                    "; velocity in {} ({})",
                    v.value, v.origin.expression
                ));
            }
            if r.torque_unit != TorqueUnit::default() {
                line.push_str(&format!("; 0x6076 in {}", r.torque_unit.symbol()));
            }
        }
        line
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir() -> tempfile::TempDir {
        tempfile::tempdir().unwrap()
    }

    /// A configuration file in `dir` naming `description` (written there as `drive.eds`).
    fn load(dir: &Path, description: &str, body: &str) -> Result<Config, ConfigError> {
        std::fs::write(dir.join("drive.eds"), description).unwrap();
        let path = dir.join("videt.toml");
        std::fs::write(
            &path,
            format!("[drives]\ndevice_description = \"drive.eds\"\n{body}"),
        )
        .unwrap();
        Config::load(&path)
    }

    const CIA402: &str = "[6076]\nDefaultValue=60\n[608Fsub1]\nDefaultValue=4096\n\
                          [608Fsub2]\nDefaultValue=1\n[60A9]\nDefaultValue=0x00B44700\n";

    #[test]
    fn significant_digits() {
        assert_eq!(significant(0.512871), "0.513");
        assert_eq!(significant(0.05), "0.05");
        assert_eq!(significant(0.0625), "0.0625");
        assert_eq!(significant(22.5), "22.5");
        assert_eq!(significant(3200.0), "3200");
        assert_eq!(significant(26.0), "26");
    }

    #[test]
    fn the_file_gives_the_units_relative_to_the_configuration() {
        let d = dir();
        let c = load(d.path(), CIA402, "").unwrap();
        assert_eq!(c.drives.rated_torque_nm, 0.06);
        assert_eq!(c.transmission.counts_per_motor_rev, 4096);
        assert_eq!(
            c.transmission.gear_ratio, 25.0,
            "not in the file: the default"
        );
        let desc = c.drives.description.as_ref().unwrap();
        assert_eq!(desc.path, d.path().join("drive.eds"));
        assert_eq!(desc.torque_unit(), TorqueUnit::MilliNewtonMetre);
        assert_eq!(
            desc.counts_per_s_per_velocity_unit(4096.0),
            Some(4096.0 / 60.0)
        );
        let line = c.describe_drive_units();
        assert!(
            line.starts_with(
                "drives: rated torque 0.06 N·m (0x6076 of drive.eds), 1 step = 0.06 mN·m = \
                 0.075 N of wire tension; encoder 4096 counts/rev (0x608F sub1/sub2); gear 25 \
                 (transmission.gear_ratio)"
            ),
            "{line}"
        );
        assert!(line.contains("velocity in rev/min (0x60A9)"), "{line}");
        // The same values set in the configuration too, within 1 %: accepted.
        load(
            d.path(),
            CIA402,
            "rated_torque_nm = 0.0603\n[transmission]\ncounts_per_motor_rev = 4096\n",
        )
        .unwrap();
        // The resolved settings written back are a valid configuration.
        let text = toml::to_string_pretty(&c).unwrap();
        let again = Config::from_toml_str_at(&text, "resolved", Some(d.path())).unwrap();
        assert_eq!(again.drives.rated_torque_nm, 0.06);
    }

    #[test]
    fn a_disagreeing_configuration_is_refused_naming_both() {
        let d = dir();
        let e = load(d.path(), CIA402, "rated_torque_nm = 0.05\n")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "drives.rated_torque_nm = 0.05: must be within 1% of 0.06 N·m, the value 0x6076 of \
             drive.eds gives in drives.device_description = \"drive.eds\" (or left out, to take \
             the file's)"
        );
        let e = load(
            d.path(),
            CIA402,
            "[transmission]\ncounts_per_motor_rev = 2000\n",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("transmission.counts_per_motor_rev = 2000: must be within 1% of 4096 counts/rev, the value 0x608F sub1/sub2 of drive.eds"),
            "{e}"
        );
        let geared = format!("{CIA402}[6091sub1]\nDefaultValue=33\n[6091sub2]\nDefaultValue=1\n");
        let e = load(d.path(), &geared, "[transmission]\ngear_ratio = 25.0\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("transmission.gear_ratio = 25: must be within 1% of 33, the value 0x6091 sub1/sub2 of drive.eds"),
            "{e}"
        );
        // Not set: the file's gear.
        let c = load(d.path(), &geared, "").unwrap();
        assert_eq!(c.transmission.gear_ratio, 33.0);
    }

    #[test]
    fn a_missing_or_unreadable_file_names_the_field_and_path() {
        let d = dir();
        let path = d.path().join("videt.toml");
        std::fs::write(&path, "[drives]\ndevice_description = \"nope.dcf\"\n").unwrap();
        let e = Config::load(&path).unwrap_err().to_string();
        let missing = d.path().join("nope.dcf");
        assert!(
            e.starts_with(&format!(
                "drives.device_description = {:?}: cannot read it: ",
                missing.display().to_string()
            )),
            "{e}"
        );
        let e = load(d.path(), "[6076\nDefaultValue=1\n", "")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("drives.device_description")
                && e.contains("not a readable EDS or DCF: line 1"),
            "{e}"
        );
        let e = load(d.path(), "[6076]\nDefaultValue=a lot\n", "")
            .unwrap_err()
            .to_string();
        assert!(e.contains("drive.eds: object 0x6076: "), "{e}");
        let e = load(d.path(), "[60A9]\nDefaultValue=0x00104700\n", "")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("0x60A9 = 0x00104700 (0x60A9 of drive.eds): must be a velocity unit"),
            "{e}"
        );
        let e = Config::from_toml_str("[drives]\ndevice_description = \"\"\n", "t")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("drives.device_description = \"\": must be"),
            "{e}"
        );
    }

    #[test]
    fn a_torque_step_coarser_than_the_minimum_tension_is_refused() {
        // A 0.5 N·m motor through 1:26 onto 20 mm: one step is 0.65 N on the wire.
        let d = dir();
        let big =
            "[6076]\nDefaultValue=500\n[6091sub1]\nDefaultValue=26\n[6091sub2]\nDefaultValue=1\n";
        let e = load(d.path(), big, "").unwrap_err().to_string();
        assert!(
            e.starts_with(
                "control.t_min_n = 0.3: must be at least one step of target torque, 0.65 N of \
                 wire tension: 1 per mille of drives.rated_torque_nm = 0.5 N·m (0x6076 of \
                 drive.eds) is 0.5 mN·m, through transmission.gear_ratio = 26"
            ),
            "{e}"
        );
        // With a minimum tension of a step or more, it runs.
        let c = load(
            d.path(),
            big,
            "[control]\nt_min_n = 0.7\n[autoinit]\npay_out_tension_n = 0.8\n",
        )
        .unwrap();
        assert!((c.torque_step_tension_n() - 0.65).abs() < 1e-12);
        // Without a file, the configured rated torque is checked the same way.
        let e = Config::from_toml_str("[drives]\nrated_torque_nm = 0.5\n", "t")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(
                "control.t_min_n = 0.3: must be at least one step of target torque, 0.625 N"
            ),
            "{e}"
        );
    }

    #[test]
    fn a_maximum_tension_beyond_the_drives_torque_range_is_refused() {
        let d = dir();
        // 15 N on 20 mm through 1:25 is 0.012 N·m: 240 per mille of 0.05 N·m.
        let limited = "[6076]\nDefaultValue=50\n[6072]\nDefaultValue=200\n";
        let e = load(d.path(), limited, "").unwrap_err().to_string();
        assert_eq!(
            e,
            "control.t_max_n = 15: must be at most 12.5 N: holding 15 N takes 240 per mille of \
             drives.rated_torque_nm = 0.05 N·m (0x6076 of drive.eds) through \
             transmission.gear_ratio = 25 onto transmission.pulley_radius_m = 0.02 m, beyond \
             0x6072 = 200 per mille of drive.eds"
        );
        load(d.path(), limited, "[control]\nt_max_n = 12.0\n").unwrap();
        // Without 0x6072: the INTEGER16 range (a 0.1 mN·m motor would need 120000).
        let e = Config::from_toml_str("[drives]\nrated_torque_nm = 0.0001\n", "t")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(
                "control.t_max_n = 15: must be at most 4.1 N: holding 15 N takes 120000 per mille"
            ) && e.ends_with(
                "beyond the 32767 per mille an INTEGER16 target torque (0x6071) carries"
            ),
            "{e}"
        );
    }

    #[test]
    fn the_epos4_dcf_of_a_real_rig_sets_the_units_and_is_checked_against_the_wires() {
        let Some(dir) = videt_testdata::data_dir("canopen/eds") else {
            return;
        };
        let name = "epos4_50_15_can_ec90flat_gp52c_mile800_node1.dcf";
        let with = |body: &str| {
            Config::from_toml_str_at(
                &format!("[drives]\ndevice_description = \"{name}\"\n{body}"),
                "t",
                Some(&dir),
            )
        };
        // A 0.51 N·m motor through its 1:26 gearhead onto a 20 mm pulley: one per mille of
        // torque is 0.667 N on the wire, more than the default minimum tension.
        let e = with("").unwrap_err().to_string();
        assert!(
            e.starts_with(&format!(
                "control.t_min_n = 0.3: must be at least one step of target torque, 0.667 N of \
                 wire tension: 1 per mille of drives.rated_torque_nm = 0.512871 N·m (0x6076 of \
                 {name}) is 0.513 mN·m, through transmission.gear_ratio = 26"
            )),
            "{e}"
        );
        let c = with("[control]\nt_min_n = 0.7\n[autoinit]\npay_out_tension_n = 0.8\n").unwrap();
        assert_eq!(c.drives.rated_torque_nm, 0.512871);
        assert_eq!(c.transmission.counts_per_motor_rev, 3200);
        assert_eq!(c.transmission.gear_ratio, 26.0);
        let desc = c.drives.description.as_ref().unwrap();
        assert_eq!(desc.torque_unit(), TorqueUnit::MicroNewtonMetre);
        let v = desc.counts_per_s_per_velocity_unit(3200.0).unwrap();
        assert!((v - 3200.0 / 60.0).abs() < 1e-9);
        assert_eq!(desc.counts_per_position_unit(3200.0), Some(1.0));
        let line = c.describe_drive_units();
        assert_eq!(
            line,
            format!(
                "drives: rated torque 0.513 N·m (0x6076 of {name}), 1 step = 0.513 mN·m = 0.667 N \
                 of wire tension; encoder 3200 counts/rev (0x3000 sub5); gear 26 (0x3003 \
                 sub1/sub2); control.t_max_n = 15 N takes 22.5 per mille (limit 32767); \
                 velocity in rev/min (0x60A9); 0x6076 in µN·m"
            )
        );
        // The example's mN·m-sized motor and 2000-count encoder disagree with the file.
        let e = with("rated_torque_nm = 0.05\n").unwrap_err().to_string();
        assert!(
            e.starts_with(&format!(
                "drives.rated_torque_nm = 0.05: must be within 1% of 0.512871 N·m, the value \
                 0x6076 of {name} gives"
            )),
            "{e}"
        );
        let e = with("[transmission]\ncounts_per_motor_rev = 2000\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("transmission.counts_per_motor_rev = 2000: must be within 1% of 3200 counts/rev, the value 0x3000 sub5"),
            "{e}"
        );
        let e = with("[transmission]\ngear_ratio = 25.0\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(
                "transmission.gear_ratio = 25: must be within 1% of 26, the value 0x3003 sub1/sub2"
            ),
            "{e}"
        );
    }

    #[test]
    fn a_sheet_without_units_leaves_the_configured_values() {
        let Some(dir) = videt_testdata::data_dir("canopen/eds") else {
            return;
        };
        let c = Config::from_toml_str_at(
            "[drives]\ndevice_description = \"402.eds\"\nrated_torque_nm = 0.04\n",
            "t",
            Some(&dir),
        )
        .unwrap();
        assert_eq!(c.drives.rated_torque_nm, 0.04);
        assert_eq!(c.transmission.counts_per_motor_rev, 2000);
        let line = c.describe_drive_units();
        assert!(
            line.starts_with("drives: rated torque 0.04 N·m (drives.rated_torque_nm), 1 step = 0.04 mN·m = 0.05 N of wire tension; encoder 2000 counts/rev (transmission.counts_per_motor_rev)"),
            "{line}"
        );
        // The Faulhaber sheet gives the encoder only.
        let c = Config::from_toml_str_at(
            "[drives]\ndevice_description = \"605.3150.67-A-EK-2-60.eds\"\n",
            "t",
            Some(&dir),
        )
        .unwrap();
        assert_eq!(c.transmission.counts_per_motor_rev, 3000);
        assert_eq!(c.drives.rated_torque_nm, 0.05);
    }

    #[test]
    fn only_keys_in_the_file_count_as_set() {
        let e = ExplicitUnits::of(
            "[drives]\nrated_torque_nm = 0.05\n[transmission]\ngear_ratio = 2.0\n",
        );
        assert_eq!(
            e,
            ExplicitUnits {
                rated_torque: true,
                counts_per_motor_rev: false,
                gear_ratio: true
            }
        );
        assert_eq!(ExplicitUnits::of(""), ExplicitUnits::default());
    }
}
