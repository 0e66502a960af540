//! The drive's units as its device description (EDS or DCF) gives them: rated torque, torque
//! limit, encoder resolution, gear and the SI units of position and velocity, each with the
//! objects and the file it was read from. Pure: the caller reads and parses the file
//! ([`Eds::parse`]); **non-RT** (allocates).
//!
//! | value | objects read | unit |
//! |---|---|---|
//! | rated torque | 0x6076; maxon: 0x3001 sub1 × sub5 when 0x6076 is not given | mN·m (CiA 402); **µN·m on maxon drives** |
//! | torque limit | 0x6072 | per mille of the rated torque |
//! | encoder | 0x608F sub1 / sub2; maxon: 0x3000 sub5 ("main sensor resolution") | increments per motor revolution |
//! | gear | 0x6091 sub1 / sub2; maxon: 0x3003 sub1 / sub2 | motor revolutions per shaft revolution |
//! | units | 0x60A8 (position), 0x60A9 (velocity) | CiA 402 SI unit codes |
//!
//! A DCF's `ParameterValue` wins over the `DefaultValue` ([`Eds::value`]). A value that is
//! absent or zero is *not given* (generic sheets carry 0 defaults), and so is a 1:1 encoder
//! or gear ratio (the profile's default of 0x608F, 0x6091 and maxon's 0x3003: no encoder has
//! one increment per revolution, and a drive without a configured gear reports 1:1).
//!
//! maxon drives (vendor id 0x000000FB, from `[DeviceInfo] VendorNumber` or 0x1018 sub1) give
//! 0x6076 in µN·m, not in CiA 402's mN·m: an EPOS4 with a 0.51 N·m motor holds 512871 there,
//! and its torque constant (0x3001 sub5, µN·m/A) times its nominal current (0x3001 sub1, mA)
//! gives the same number. Their manufacturer objects (0x3000, 0x3001, 0x3003) are read only
//! for maxon drives. Velocity units are taken as of the motor shaft, whose encoder counts the
//! position.

use core::fmt;

use crate::eds::{Eds, EdsError};

/// The CiA-assigned vendor id of maxon motor ag.
pub const MAXON_VENDOR_ID: u32 = 0x0000_00FB;

/// The largest per-mille value a target torque (0x6071, INTEGER16) can command.
pub const MAX_TARGET_TORQUE_PERMILLE: u16 = i16::MAX as u16;

/// The unit of a drive's motor rated torque (0x6076).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TorqueUnit {
    /// mN·m, as CiA 402 defines it.
    #[default]
    MilliNewtonMetre,
    /// µN·m: maxon drives (EPOS4).
    MicroNewtonMetre,
}

impl TorqueUnit {
    /// The unit of 0x6076 on a drive of this vendor.
    pub fn of_vendor(vendor_id: Option<u32>) -> TorqueUnit {
        if vendor_id == Some(MAXON_VENDOR_ID) {
            TorqueUnit::MicroNewtonMetre
        } else {
            TorqueUnit::MilliNewtonMetre
        }
    }

    /// Newton-metres per unit.
    pub fn newton_metres(self) -> f64 {
        match self {
            TorqueUnit::MilliNewtonMetre => 1e-3,
            TorqueUnit::MicroNewtonMetre => 1e-6,
        }
    }

    /// The unit's symbol.
    pub fn symbol(self) -> &'static str {
        match self {
            TorqueUnit::MilliNewtonMetre => "mN·m",
            TorqueUnit::MicroNewtonMetre => "µN·m",
        }
    }

    /// A torque in N·m as the drive's 0x6076 value (rounded, saturated to UNSIGNED32).
    pub fn raw(self, torque_nm: f64) -> u32 {
        let v = (torque_nm / self.newton_metres()).round();
        if v.is_nan() {
            0
        } else {
            v.clamp(0.0, f64::from(u32::MAX)) as u32
        }
    }
}

/// One object dictionary entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ObjectRef {
    /// Index.
    pub index: u16,
    /// Subindex (0 for a plain variable).
    pub subindex: u8,
}

impl fmt::Display for ObjectRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.subindex == 0 {
            write!(f, "0x{:04X}", self.index)
        } else {
            write!(f, "0x{:04X} sub{}", self.index, self.subindex)
        }
    }
}

/// Where a value came from: the objects read, how they combine, and the file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Origin {
    /// The file, as named to [`DriveResolution::from_eds`].
    pub file: String,
    /// Every object the value was computed from.
    pub objects: Vec<ObjectRef>,
    /// How they combine, e.g. `0x608F sub1/sub2` or `0x3001 sub1 × sub5`.
    pub expression: String,
}

impl Origin {
    fn one(file: &str, index: u16, subindex: u8) -> Origin {
        let o = ObjectRef { index, subindex };
        Origin {
            file: file.to_string(),
            objects: vec![o],
            expression: o.to_string(),
        }
    }

    fn pair(file: &str, index: u16, a: u8, b: u8, operator: &str) -> Origin {
        Origin {
            file: file.to_string(),
            objects: vec![
                ObjectRef { index, subindex: a },
                ObjectRef { index, subindex: b },
            ],
            expression: format!("0x{index:04X} sub{a}{operator}sub{b}"),
        }
    }

    /// `self` used together with `other` (e.g. a velocity unit in revolutions with the
    /// encoder resolution).
    fn with(&self, other: &Origin) -> Origin {
        let mut objects = self.objects.clone();
        objects.extend_from_slice(&other.objects);
        Origin {
            file: self.file.clone(),
            objects,
            expression: format!("{} with {}", self.expression, other.expression),
        }
    }
}

impl fmt::Display for Origin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} of {}", self.expression, self.file)
    }
}

/// A value and where it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct Sourced<T> {
    /// The value.
    pub value: T,
    /// Its objects and file.
    pub origin: Origin,
}

/// A CiA 402 SI unit code (0x60A8, 0x60A9): prefix exponent (byte 3, signed), numerator unit
/// (byte 2) and denominator unit (byte 1), e.g. 0x00B50000 increments, 0x00B44700 rev/min.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SiUnit(pub u32);

/// SI unit code of increments (encoder counts).
pub const SI_INCREMENTS: u8 = 0xB5;
/// SI unit code of revolutions.
pub const SI_REVOLUTIONS: u8 = 0xB4;
/// SI unit code of the second.
pub const SI_SECOND: u8 = 0x03;
/// SI unit code of the minute.
pub const SI_MINUTE: u8 = 0x47;

impl SiUnit {
    /// The power of ten of the prefix (0 for none, -3 for milli).
    pub fn prefix_exponent(self) -> i8 {
        (self.0 >> 24) as u8 as i8
    }

    /// The unit code of the numerator.
    pub fn numerator(self) -> u8 {
        (self.0 >> 16) as u8
    }

    /// The unit code of the denominator (0: none).
    pub fn denominator(self) -> u8 {
        (self.0 >> 8) as u8
    }

    fn scale(self) -> f64 {
        10f64.powi(i32::from(self.prefix_exponent()))
    }

    /// Encoder counts in one unit of the numerator, when it is a count or a revolution (the
    /// latter needs the counts per revolution).
    fn counts(self, counts_per_rev: Option<f64>) -> Option<f64> {
        match self.numerator() {
            SI_INCREMENTS => Some(1.0),
            SI_REVOLUTIONS => counts_per_rev,
            _ => None,
        }
    }

    /// Encoder counts per position unit, for a position unit (no denominator).
    pub fn counts_per_unit(self, counts_per_rev: Option<f64>) -> Option<f64> {
        if self.denominator() != 0 {
            return None;
        }
        self.counts(counts_per_rev).map(|c| c * self.scale())
    }

    /// Counts per second per velocity unit, for a velocity unit (per second or per minute):
    /// rev/min gives `counts_per_rev / 60`.
    pub fn counts_per_s_per_unit(self, counts_per_rev: Option<f64>) -> Option<f64> {
        let seconds = match self.denominator() {
            SI_SECOND => 1.0,
            SI_MINUTE => 60.0,
            _ => return None,
        };
        self.counts(counts_per_rev)
            .map(|c| c * self.scale() / seconds)
    }
}

impl fmt::Display for SiUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let num = match self.numerator() {
            SI_INCREMENTS => "inc",
            SI_REVOLUTIONS => "rev",
            _ => return write!(f, "0x{:08X}", self.0),
        };
        let den = match self.denominator() {
            0 => "",
            SI_SECOND => "/s",
            SI_MINUTE => "/min",
            _ => return write!(f, "0x{:08X}", self.0),
        };
        match self.prefix_exponent() {
            0 => write!(f, "{num}{den}"),
            p => write!(f, "1e{p} {num}{den}"),
        }
    }
}

/// A value of the device description that cannot be a drive's setting.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ResolutionError {
    /// The value is not a number.
    #[error("{file}: object {object}: {source}")]
    NotANumber {
        /// The file.
        file: String,
        /// The object.
        object: ObjectRef,
        /// The reader's error.
        source: EdsError,
    },
    /// The value is negative or too large for its object.
    #[error("{file}: object {object} = {value}: must be in [0, {max}]")]
    OutOfRange {
        /// The file.
        file: String,
        /// The object.
        object: ObjectRef,
        /// The value found.
        value: i128,
        /// The object's largest value.
        max: u64,
    },
}

/// The drive's units as its device description gives them; `None`: not given.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveResolution {
    /// The file, as named to [`DriveResolution::from_eds`].
    pub file: String,
    /// The vendor id (`[DeviceInfo] VendorNumber`, else 0x1018 sub1), when given.
    pub vendor_id: Option<u32>,
    /// `[DeviceInfo] ProductName`, when given.
    pub product_name: Option<String>,
    /// The product code (`[DeviceInfo] ProductNumber`, else 0x1018 sub2), when given.
    pub product_code: Option<u32>,
    /// The unit of 0x6076 on this drive.
    pub torque_unit: TorqueUnit,
    /// Motor rated torque, N·m (target torque 0x6071 is per mille of it).
    pub rated_torque_nm: Option<Sourced<f64>>,
    /// Torque limit (0x6072), per mille of the rated torque.
    pub max_torque_permille: Option<Sourced<u16>>,
    /// Encoder increments per motor revolution.
    pub counts_per_motor_rev: Option<Sourced<f64>>,
    /// Gear reduction, motor revolutions per shaft revolution.
    pub gear_ratio: Option<Sourced<f64>>,
    /// The unit of position values (0x6064).
    pub position_unit: Option<Sourced<SiUnit>>,
    /// The unit of velocity values (0x606C).
    pub velocity_unit: Option<Sourced<SiUnit>>,
    /// Encoder counts per position unit (from the position unit and, for revolutions, the
    /// encoder resolution).
    pub counts_per_position_unit: Option<Sourced<f64>>,
    /// Encoder counts per second per velocity unit (rev/min: counts per revolution / 60).
    pub counts_per_s_per_velocity_unit: Option<Sourced<f64>>,
}

/// Reads unsigned values of one file.
struct Reader<'a> {
    eds: &'a Eds,
    file: &'a str,
    node_id: u8,
}

impl Reader<'_> {
    /// The value of an unsigned object; `None` when absent or zero.
    fn unsigned(&self, index: u16, subindex: u8, max: u64) -> Result<Option<u64>, ResolutionError> {
        let object = ObjectRef { index, subindex };
        let value = self
            .eds
            .value(index, subindex, self.node_id)
            .map_err(|source| ResolutionError::NotANumber {
                file: self.file.to_string(),
                object,
                source,
            })?;
        match value {
            None | Some(0) => Ok(None),
            Some(v) if v > 0 && v <= i128::from(max) => Ok(Some(v as u64)),
            Some(v) => Err(ResolutionError::OutOfRange {
                file: self.file.to_string(),
                object,
                value: v,
                max,
            }),
        }
    }

    /// `sub a / sub b` of `index` when both are given and the ratio is not 1:1.
    fn ratio(&self, index: u16, a: u8, b: u8) -> Result<Option<Sourced<f64>>, ResolutionError> {
        let max = u64::from(u32::MAX);
        match (self.unsigned(index, a, max)?, self.unsigned(index, b, max)?) {
            (Some(n), Some(d)) if n != d => Ok(Some(Sourced {
                value: n as f64 / d as f64,
                origin: Origin::pair(self.file, index, a, b, "/"),
            })),
            _ => Ok(None),
        }
    }
}

impl DriveResolution {
    /// Read the units of the drive `eds` describes. `file` names it in every [`Origin`] and
    /// error; `node_id` resolves `$NODEID` expressions.
    pub fn from_eds(
        eds: &Eds,
        file: &str,
        node_id: u8,
    ) -> Result<DriveResolution, ResolutionError> {
        let r = Reader { eds, file, node_id };
        let u32_max = u64::from(u32::MAX);
        let vendor_id = match eds.vendor_number.filter(|&v| v != 0) {
            Some(v) => Some(v),
            None => r.unsigned(0x1018, 1, u32_max)?.map(|v| v as u32),
        };
        let product_code = match eds.product_number.filter(|&v| v != 0) {
            Some(v) => Some(v),
            None => r.unsigned(0x1018, 2, u32_max)?.map(|v| v as u32),
        };
        let maxon = vendor_id == Some(MAXON_VENDOR_ID);
        let torque_unit = TorqueUnit::of_vendor(vendor_id);

        let rated_torque_nm = match r.unsigned(0x6076, 0, u32_max)? {
            Some(raw) => Some(Sourced {
                value: raw as f64 * torque_unit.newton_metres(),
                origin: Origin::one(file, 0x6076, 0),
            }),
            // maxon: nominal current (mA) times torque constant (µN·m/A).
            None if maxon => match (
                r.unsigned(0x3001, 1, u32_max)?,
                r.unsigned(0x3001, 5, u32_max)?,
            ) {
                (Some(current_ma), Some(kt_un_m_per_a)) => Some(Sourced {
                    value: current_ma as f64 / 1000.0 * kt_un_m_per_a as f64 * 1e-6,
                    origin: Origin::pair(file, 0x3001, 1, 5, " × "),
                }),
                _ => None,
            },
            None => None,
        };

        let max_torque_permille = r
            .unsigned(0x6072, 0, u64::from(u16::MAX))?
            .map(|v| Sourced {
                value: v as u16,
                origin: Origin::one(file, 0x6072, 0),
            });

        let mut counts_per_motor_rev = r.ratio(0x608F, 1, 2)?.filter(|c| c.value > 1.0);
        if counts_per_motor_rev.is_none() && maxon {
            counts_per_motor_rev =
                r.unsigned(0x3000, 5, u32_max)?
                    .filter(|&c| c > 1)
                    .map(|c| Sourced {
                        value: c as f64,
                        origin: Origin::one(file, 0x3000, 5),
                    });
        }

        let mut gear_ratio = r.ratio(0x6091, 1, 2)?;
        if gear_ratio.is_none() && maxon {
            gear_ratio = r.ratio(0x3003, 1, 2)?;
        }

        let unit = |index: u16| -> Result<Option<Sourced<SiUnit>>, ResolutionError> {
            Ok(r.unsigned(index, 0, u32_max)?.map(|v| Sourced {
                value: SiUnit(v as u32),
                origin: Origin::one(file, index, 0),
            }))
        };
        let position_unit = unit(0x60A8)?;
        let velocity_unit = unit(0x60A9)?;

        let counts = counts_per_motor_rev.as_ref();
        let derive = |u: &Sourced<SiUnit>, per: fn(SiUnit, Option<f64>) -> Option<f64>| {
            let value = per(u.value, counts.map(|c| c.value))?;
            let origin = match (u.value.numerator(), counts) {
                (SI_REVOLUTIONS, Some(c)) => u.origin.with(&c.origin),
                _ => u.origin.clone(),
            };
            Some(Sourced { value, origin })
        };
        let counts_per_position_unit = position_unit
            .as_ref()
            .and_then(|u| derive(u, SiUnit::counts_per_unit));
        let counts_per_s_per_velocity_unit = velocity_unit
            .as_ref()
            .and_then(|u| derive(u, SiUnit::counts_per_s_per_unit));

        Ok(DriveResolution {
            file: file.to_string(),
            vendor_id,
            product_name: eds.product_name.clone(),
            product_code,
            torque_unit,
            rated_torque_nm,
            max_torque_permille,
            counts_per_motor_rev,
            gear_ratio,
            position_unit,
            velocity_unit,
            counts_per_position_unit,
            counts_per_s_per_velocity_unit,
        })
    }

    /// One step of target torque (one per mille of the rated torque), N·m.
    pub fn torque_step_nm(&self) -> Option<f64> {
        self.rated_torque_nm.as_ref().map(|r| r.value / 1000.0)
    }

    /// Whether the file gives none of the units.
    pub fn gives_nothing(&self) -> bool {
        self.rated_torque_nm.is_none()
            && self.max_torque_permille.is_none()
            && self.counts_per_motor_rev.is_none()
            && self.gear_ratio.is_none()
            && self.position_unit.is_none()
            && self.velocity_unit.is_none()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn resolve(text: &str) -> DriveResolution {
        DriveResolution::from_eds(&Eds::parse(text).unwrap(), "t.eds", 1).unwrap()
    }

    fn real(name: &str) -> Option<DriveResolution> {
        let path = videt_testdata::data_dir(&format!("canopen/eds/{name}"))?;
        let text = std::fs::read_to_string(path).expect("readable data file");
        let eds = Eds::parse(&text).expect(name);
        Some(DriveResolution::from_eds(&eds, name, 1).expect(name))
    }

    #[test]
    fn a_cia402_drive_gives_every_unit_in_profile_objects() {
        let r = resolve(
            "[6076]\nDefaultValue=100\n[6072]\nDefaultValue=2500\n\
             [608Fsub1]\nDefaultValue=4096\n[608Fsub2]\nDefaultValue=1\n\
             [6091sub1]\nDefaultValue=25\n[6091sub2]\nDefaultValue=1\n\
             [60A8]\nDefaultValue=0x00B50000\n[60A9]\nDefaultValue=0x00B44700\n",
        );
        assert_eq!(r.torque_unit, TorqueUnit::MilliNewtonMetre);
        let rated = r.rated_torque_nm.as_ref().unwrap();
        assert!((rated.value - 0.1).abs() < 1e-12);
        assert_eq!(rated.origin.to_string(), "0x6076 of t.eds");
        assert!((r.torque_step_nm().unwrap() - 1e-4).abs() < 1e-15);
        assert_eq!(r.max_torque_permille.as_ref().unwrap().value, 2500);
        let counts = r.counts_per_motor_rev.as_ref().unwrap();
        assert_eq!(counts.value, 4096.0);
        assert_eq!(counts.origin.expression, "0x608F sub1/sub2");
        assert_eq!(r.gear_ratio.as_ref().unwrap().value, 25.0);
        assert_eq!(r.counts_per_position_unit.as_ref().unwrap().value, 1.0);
        let v = r.counts_per_s_per_velocity_unit.as_ref().unwrap();
        assert!((v.value - 4096.0 / 60.0).abs() < 1e-9);
        assert_eq!(v.origin.expression, "0x60A9 with 0x608F sub1/sub2");
        assert_eq!(v.origin.objects.len(), 3);
        assert!(!r.gives_nothing());
    }

    #[test]
    fn zero_and_one_to_one_defaults_are_not_given() {
        let r = resolve(
            "[DeviceInfo]\nVendorNumber=0x0\n[6076]\nDefaultValue=0x00000000\n\
             [6072]\nDefaultValue=0\n[608Fsub1]\nDefaultValue=1\n[608Fsub2]\nDefaultValue=1\n\
             [6091sub1]\nDefaultValue=1\n[6091sub2]\nDefaultValue=1\n[60A9]\nDefaultValue=0\n",
        );
        assert!(r.gives_nothing(), "{r:?}");
        assert_eq!(r.vendor_id, None);
    }

    #[test]
    fn maxon_drives_give_micro_newton_metres_and_their_own_objects() {
        // 0x6076 not given: the nominal current times the torque constant.
        let r = resolve(
            "[DeviceInfo]\nVendorNumber=0x000000FB\n[6076]\nDefaultValue=0\n\
             [3001sub1]\nParameterValue=2000\n[3001sub5]\nParameterValue=25000\n\
             [3000sub5]\nParameterValue=2048\n\
             [3003sub1]\nParameterValue=33\n[3003sub2]\nParameterValue=2\n\
             [60A9]\nParameterValue=0xFDB44700\n",
        );
        assert_eq!(r.torque_unit, TorqueUnit::MicroNewtonMetre);
        let rated = r.rated_torque_nm.unwrap();
        assert!((rated.value - 0.05).abs() < 1e-12);
        assert_eq!(rated.origin.expression, "0x3001 sub1 × sub5");
        assert_eq!(r.counts_per_motor_rev.unwrap().value, 2048.0);
        assert_eq!(r.gear_ratio.unwrap().value, 16.5);
        // 0.001 rev/min.
        let v = r.counts_per_s_per_velocity_unit.unwrap().value;
        assert!((v - 2048.0 / 60.0 / 1000.0).abs() < 1e-12, "{v}");
        // The same manufacturer objects on another vendor's drive mean something else.
        let other = resolve("[3000sub5]\nDefaultValue=2048\n[3001sub1]\nDefaultValue=2000\n[3001sub5]\nDefaultValue=25000\n");
        assert!(other.gives_nothing(), "{other:?}");
        // The vendor from the identity object when [DeviceInfo] has none.
        let id = resolve("[1018sub1]\nParameterValue=0xFB\n[6076]\nDefaultValue=512871\n");
        assert_eq!(id.vendor_id, Some(MAXON_VENDOR_ID));
        assert!((id.rated_torque_nm.unwrap().value - 0.512871).abs() < 1e-12);
    }

    #[test]
    fn values_that_cannot_be_settings_name_the_object_and_file() {
        let e = DriveResolution::from_eds(
            &Eds::parse("[6076]\nDefaultValue=lots\n").unwrap(),
            "x.dcf",
            1,
        )
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("x.dcf: object 0x6076: "), "{e}");
        let e = DriveResolution::from_eds(
            &Eds::parse("[6072]\nDefaultValue=-5\n").unwrap(),
            "x.dcf",
            1,
        )
        .unwrap_err()
        .to_string();
        assert_eq!(e, "x.dcf: object 0x6072 = -5: must be in [0, 65535]");
    }

    #[test]
    fn si_unit_codes_decode() {
        assert_eq!(SiUnit(0x00B5_0000).to_string(), "inc");
        assert_eq!(SiUnit(0x00B4_4700).to_string(), "rev/min");
        assert_eq!(SiUnit(0xFDB4_4700).to_string(), "1e-3 rev/min");
        assert_eq!(SiUnit(0x00B5_0300).to_string(), "inc/s");
        assert_eq!(SiUnit(0x0001_0000).to_string(), "0x00010000");
        assert_eq!(SiUnit(0x00B5_0300).counts_per_s_per_unit(None), Some(1.0));
        assert_eq!(SiUnit(0x00B4_4700).counts_per_s_per_unit(None), None);
        assert_eq!(
            SiUnit(0x00B4_0300).counts_per_s_per_unit(Some(500.0)),
            Some(500.0)
        );
        assert_eq!(
            SiUnit(0x00B4_0000).counts_per_unit(Some(500.0)),
            Some(500.0)
        );
        assert_eq!(SiUnit(0x00B4_4700).counts_per_unit(Some(500.0)), None);
        assert_eq!(TorqueUnit::MicroNewtonMetre.raw(0.512871), 512_871);
        assert_eq!(TorqueUnit::MilliNewtonMetre.raw(0.05), 50);
    }

    #[test]
    fn the_epos4_dcf_gives_its_motor_in_micro_newton_metres() {
        let Some(r) = real("epos4_50_15_can_ec90flat_gp52c_mile800_node1.dcf") else {
            return;
        };
        assert_eq!(r.vendor_id, Some(MAXON_VENDOR_ID));
        assert_eq!(r.torque_unit, TorqueUnit::MicroNewtonMetre);
        let rated = r.rated_torque_nm.as_ref().unwrap();
        assert!((rated.value - 0.512871).abs() < 1e-12, "{}", rated.value);
        assert_eq!(
            rated.origin.to_string(),
            "0x6076 of epos4_50_15_can_ec90flat_gp52c_mile800_node1.dcf"
        );
        // The unit is µN·m: the torque constant (µN·m/A) times the nominal current (mA).
        let eds = Eds::parse(
            &std::fs::read_to_string(
                videt_testdata::data_dir(
                    "canopen/eds/epos4_50_15_can_ec90flat_gp52c_mile800_node1.dcf",
                )
                .unwrap(),
            )
            .unwrap(),
        )
        .unwrap();
        let kt = eds.value(0x3001, 5, 1).unwrap().unwrap() as f64 * 1e-6;
        let current = eds.value(0x3001, 1, 1).unwrap().unwrap() as f64 * 1e-3;
        assert!((kt * current - rated.value).abs() < 1e-6 * rated.value);
        assert_eq!(r.max_torque_permille, None, "the EPOS4 has no 0x6072");
        let counts = r.counts_per_motor_rev.as_ref().unwrap();
        assert_eq!(counts.value, 3200.0);
        assert_eq!(counts.origin.expression, "0x3000 sub5");
        let gear = r.gear_ratio.as_ref().unwrap();
        assert_eq!(gear.value, 26.0);
        assert_eq!(gear.origin.expression, "0x3003 sub1/sub2");
        assert_eq!(r.position_unit.as_ref().unwrap().value, SiUnit(0x00B5_0000));
        assert_eq!(r.counts_per_position_unit.as_ref().unwrap().value, 1.0);
        assert_eq!(
            r.velocity_unit.as_ref().unwrap().value.to_string(),
            "rev/min"
        );
        let v = r.counts_per_s_per_velocity_unit.as_ref().unwrap();
        assert!((v.value - 3200.0 / 60.0).abs() < 1e-9);
        assert_eq!(v.origin.expression, "0x60A9 with 0x3000 sub5");
        // The second drive of the same rig has its own motor.
        let Some(node2) = real("epos4_50_15_can_ec90flat_gp52c_mile800_node2.dcf") else {
            return;
        };
        assert!((node2.rated_torque_nm.unwrap().value - 0.512347).abs() < 1e-12);
    }

    #[test]
    fn the_faulhaber_eds_gives_its_encoder_and_no_rated_torque() {
        for name in ["605.3150.67-A-EK-2-60.eds", "605.3150.67-B-EK-2-60.eds"] {
            let Some(r) = real(name) else {
                return;
            };
            assert_eq!(r.vendor_id, Some(327), "{name}");
            assert_eq!(r.torque_unit, TorqueUnit::MilliNewtonMetre);
            assert_eq!(r.rated_torque_nm, None, "{name}");
            let counts = r.counts_per_motor_rev.unwrap();
            assert_eq!(counts.value, 3000.0, "{name}");
            assert_eq!(counts.origin.expression, "0x608F sub1/sub2");
            assert_eq!(r.gear_ratio, None, "1:1 is the default: {name}");
            assert_eq!(r.velocity_unit, None, "{name}");
        }
    }

    #[test]
    fn generic_sheets_give_nothing() {
        for name in ["402.eds", "301.eds", "MD80_DS402.eds", "MDv1.0.0.eds"] {
            let Some(r) = real(name) else {
                return;
            };
            assert!(r.gives_nothing(), "{name}: {r:?}");
            assert_eq!(r.torque_unit, TorqueUnit::MilliNewtonMetre, "{name}");
        }
    }
}
