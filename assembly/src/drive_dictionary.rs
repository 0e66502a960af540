//! The simulated drives' dictionary from the configured part's description
//! (`drives.device_description`, or `videt sim-rig --drive-description FILE`): the twin's CiA
//! 402 nodes then hold the objects, types, access, PDO mappability and defaults the EDS or DCF
//! gives, answer each SDO the way CiA 301 says for that case, and report their values in the
//! units the file gives. Without a description they are the generic CiA 402 profile.

use std::path::Path;
use std::sync::Arc;

use videt_config::drive_units::DeviceDescription;
use videt_config::Config;
use videt_drive_description::eds::{parse_value, Eds};
use videt_drive_description::{DriveResolution, TorqueUnit};
use videt_sim::cia402_node::dictionary::{
    DefaultValue, DescribedObject, DriveDictionary, ObjectAccess,
};

/// The dictionary an EDS or DCF describes, with the units the drive reports its values in.
pub fn from_eds(
    eds: &Eds,
    source: &str,
    torque_unit_nm: f64,
    counts_per_position_unit: f64,
    counts_per_s_per_velocity_unit: f64,
) -> DriveDictionary {
    let objects = eds
        .entries()
        .map(|(&(index, subindex), e)| {
            // A DCF's configured value wins over the sheet's default.
            let text = [e.parameter_value.as_deref(), e.default_value.as_deref()]
                .into_iter()
                .flatten()
                .map(str::trim)
                .find(|v| !v.is_empty());
            // `$NODEID+...`: the value differs between node ids 0 and 1.
            let default = text.and_then(|t| match (parse_value(t, 0), parse_value(t, 1)) {
                (Ok(at0), Ok(at1)) => Some(DefaultValue {
                    value: at0,
                    plus_node_id: at1 != at0,
                }),
                _ => None,
            });
            DescribedObject {
                index,
                subindex,
                data_type: e.data_type,
                access: e
                    .access
                    .as_deref()
                    .map_or(ObjectAccess::ReadWrite, ObjectAccess::from_eds),
                pdo_mappable: e.pdo_mappable,
                default,
                text: (e.data_type == Some(0x09)).then(|| text.unwrap_or("").to_string()),
            }
        })
        .collect();
    DriveDictionary {
        source: source.to_string(),
        objects,
        torque_unit_nm,
        counts_per_position_unit,
        counts_per_s_per_velocity_unit,
    }
}

/// The units the drives of `config` give their values in, from `drives.device_description`
/// (`None` without one): the unit of their rated torque 0x6076, encoder counts per position
/// unit and counts per second per velocity unit (1 where the file gives none), with the
/// configured encoder's counts per revolution.
pub fn description_units(config: &Config) -> Option<(TorqueUnit, f64, f64)> {
    let desc = config.drives.description.as_ref()?;
    Some(units_of(desc, config))
}

fn units_of(desc: &DeviceDescription, config: &Config) -> (TorqueUnit, f64, f64) {
    let counts_per_rev = f64::from(config.transmission.counts_per_motor_rev);
    (
        desc.torque_unit(),
        desc.counts_per_position_unit(counts_per_rev).unwrap_or(1.0),
        desc.counts_per_s_per_velocity_unit(counts_per_rev)
            .unwrap_or(1.0),
    )
}

/// The simulated drives' dictionary for `config`: the file `drives.device_description` names,
/// in the units the configuration resolved from it; `None` (the generic profile) without one.
pub fn for_config(config: &Config) -> Result<Option<Arc<DriveDictionary>>, String> {
    match &config.drives.description {
        Some(desc) => for_file(&desc.path, config).map(|d| Some(Arc::new(d))),
        None => Ok(None),
    }
}

/// The dictionary of the EDS or DCF at `path`, its units resolved as `config`'s drives would
/// resolve them were it their `drives.device_description` (the encoder's counts per revolution
/// from `[transmission]`).
pub fn for_file(path: &Path, config: &Config) -> Result<DriveDictionary, String> {
    let what = |e: &dyn std::fmt::Display| format!("drive description {}: {e}", path.display());
    let bytes = std::fs::read(path).map_err(|e| what(&e))?;
    // Vendors' files are not always UTF-8 (a µ in a comment): the objects are ASCII.
    let eds = Eds::parse(&String::from_utf8_lossy(&bytes)).map_err(|e| what(&e))?;
    let name = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into(),
    );
    let resolution =
        DriveResolution::from_eds(&eds, &name, config.drives.node_ids[0]).map_err(|e| what(&e))?;
    let desc = DeviceDescription {
        path: path.to_path_buf(),
        resolution,
    };
    let (torque_unit, per_position, per_velocity) = units_of(&desc, config);
    Ok(from_eds(
        &eds,
        &name,
        torque_unit.newton_metres(),
        per_position,
        per_velocity,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_generic_profile_written_as_an_eds_reads_back_as_itself() {
        let generic = DriveDictionary::generic(40);
        let text = generic.to_eds("generic");
        let back = from_eds(&Eds::parse(&text).unwrap(), "generic.eds", 1e-3, 1.0, 1.0);
        assert_eq!(back.objects, generic.objects, "{text}");
    }

    #[test]
    fn an_eds_gives_types_access_mappability_and_node_relative_defaults() {
        let eds = Eds::parse(
            "[1000]\nDataType=0x0007\nAccessType=ro\nDefaultValue=0x00020192\n\
             [1800sub1]\nDataType=0x0007\nAccessType=rw\nDefaultValue=$NODEID+0x40000180\n\
             [6071]\nDataType=0x0003\nAccessType=rww\nPDOMapping=1\nDefaultValue=0\n\
             [6076]\nDataType=0x0007\nAccessType=rw\nDefaultValue=0\nParameterValue=512871\n",
        )
        .unwrap();
        let d = from_eds(&eds, "drive.dcf", 1e-6, 1.0, 1.0);
        let o = d.object(0x1800, 1).unwrap();
        assert_eq!(o.default.unwrap().at(3), 0x4000_0183);
        assert_eq!(d.object(0x1000, 0).unwrap().access, ObjectAccess::ReadOnly);
        let t = d.object(0x6071, 0).unwrap();
        assert!(t.pdo_mappable && t.access == ObjectAccess::ReadWrite);
        assert_eq!(d.default_of(0x6076, 0, 1), Some(512_871));
        assert!(d.object(0x6072, 0).is_none());
    }
}
