//! The drives' start-up report in the service: each drive's identity and the optional objects
//! it lacks, logged once per configuration (identities at INFO, what the service does without
//! a missing object at WARN, a drive unlike the configured device description at WARN), and
//! carried in the status reply.

use serde::{Deserialize, Serialize};
use tracing::{info, warn};
use videt_config::Config;
use videt_drivers::cia402::{DriveIdentity, SharedStartupReport, StartupReport};

/// One drive's identity, as the status reply carries it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DriveStatus {
    /// Wire index (0-based).
    pub wire: u8,
    /// CANopen node id.
    pub node: u8,
    /// Device type (0x1000).
    pub device_type: u32,
    /// Vendor id (0x1018 sub 1), when the drive has it.
    pub vendor_id: Option<u32>,
    /// Product code (0x1018 sub 2), when the drive has it.
    pub product_code: Option<u32>,
    /// Revision number (0x1018 sub 3), when the drive has it.
    pub revision: Option<u32>,
    /// Serial number (0x1018 sub 4), when the drive has it.
    pub serial: Option<u32>,
}

impl DriveStatus {
    /// The drive's identity, to print as the service logs it.
    pub fn identity(&self) -> DriveIdentity {
        DriveIdentity {
            device_type: self.device_type,
            vendor_id: self.vendor_id,
            product_code: self.product_code,
            revision: self.revision,
            serial: self.serial,
        }
    }
}

/// The drives of `report`, as the status reply carries them.
pub fn drive_statuses(report: &StartupReport) -> Vec<DriveStatus> {
    report
        .drives
        .iter()
        .map(|&(wire, node, id)| DriveStatus {
            wire,
            node,
            device_type: id.device_type,
            vendor_id: id.vendor_id,
            product_code: id.product_code,
            revision: id.revision,
            serial: id.serial,
        })
        .collect()
}

/// What differs between the drive's identity and the configured device description, if
/// anything: the vendor id or the product code, each only where both give it.
pub fn unlike_description(status: &DriveStatus, config: &Config) -> Option<String> {
    let r = &config.drives.description.as_ref()?.resolution;
    let mut differences = Vec::new();
    if let (Some(drive), Some(file)) = (status.vendor_id, r.vendor_id) {
        if drive != file {
            differences.push(format!(
                "vendor {drive:#010x} where the file says {file:#010x}"
            ));
        }
    }
    if let (Some(drive), Some(file)) = (status.product_code, r.product_code) {
        if drive != file {
            differences.push(format!(
                "product {drive:#010x} where the file says {file:#010x}"
            ));
        }
    }
    (!differences.is_empty()).then(|| {
        format!(
            "drive of wire {} (node {}): {}; drives.device_description = {:?} may describe \
             another drive (its units and objects are then not this drive's)",
            status.wire,
            status.node,
            differences.join(", "),
            r.file
        )
    })
}

/// Follows a drive set's [`SharedStartupReport`]: tells each new one once.
#[derive(Debug)]
pub struct DriveReportWatch {
    shared: SharedStartupReport,
    told: u64,
    drives: Vec<DriveStatus>,
}

impl DriveReportWatch {
    /// Watch `shared`.
    pub fn new(shared: SharedStartupReport) -> DriveReportWatch {
        DriveReportWatch {
            shared,
            told: 0,
            drives: Vec::new(),
        }
    }

    /// Log a report not yet told (identities, missing optional objects, a drive unlike the
    /// configured description); the drives of the latest report.
    pub fn poll(&mut self, config: &Config) -> &[DriveStatus] {
        let report = match self.shared.lock() {
            Ok(r) if r.generation != self.told => r.clone(),
            _ => return &self.drives,
        };
        self.told = report.generation;
        self.drives = drive_statuses(&report);
        for &(wire, node, id) in &report.drives {
            info!("drive of wire {wire} (node {node}): {id}");
        }
        for note in &report.notes {
            warn!("{note}");
        }
        for d in &self.drives {
            if let Some(w) = unlike_description(d, config) {
                warn!("{w}");
            }
        }
        &self.drives
    }
}

/// A configuration in `dir` whose `drives.device_description` (`drive.eds`) describes a maxon
/// drive, product 0x65520000 (for tests).
#[cfg(test)]
pub(crate) fn described_config(dir: &std::path::Path) -> Config {
    std::fs::write(
        dir.join("drive.eds"),
        "[DeviceInfo]\nVendorNumber=0x000000FB\nProductNumber=0x65520000\n[6076]\n\
         DefaultValue=50000\n",
    )
    .unwrap();
    let path = dir.join("videt.toml");
    std::fs::write(&path, "[drives]\ndevice_description = \"drive.eds\"\n").unwrap();
    Config::load(&path).unwrap()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drive_unlike_the_configured_description_is_named_with_both_values() {
        let dir = tempfile::tempdir().unwrap();
        let config = described_config(dir.path());
        let mut drive = DriveStatus {
            wire: 1,
            node: 2,
            device_type: 0x0002_0192,
            vendor_id: Some(0xFB),
            product_code: Some(0x6552_0000),
            revision: None,
            serial: None,
        };
        assert_eq!(unlike_description(&drive, &config), None);
        drive.product_code = Some(0x6551_0000);
        let w = unlike_description(&drive, &config).unwrap();
        assert!(
            w.starts_with(
                "drive of wire 1 (node 2): product 0x65510000 where the file says 0x65520000; \
                 drives.device_description = \"drive.eds\""
            ),
            "{w}"
        );
        // Without a description there is nothing to compare.
        assert_eq!(unlike_description(&drive, &Config::default()), None);
    }

    #[test]
    fn a_new_report_is_told_once_and_its_drives_kept() {
        let shared = SharedStartupReport::default();
        let mut watch = DriveReportWatch::new(shared.clone());
        let config = Config::default();
        assert!(watch.poll(&config).is_empty());
        {
            let mut r = shared.lock().unwrap();
            r.generation = 1;
            r.drives = vec![(
                0,
                1,
                DriveIdentity {
                    device_type: 0x0002_0192,
                    vendor_id: Some(0xFB),
                    ..DriveIdentity::default()
                },
            )];
        }
        let drives = watch.poll(&config).to_vec();
        assert_eq!(drives.len(), 1);
        assert_eq!((drives[0].wire, drives[0].vendor_id), (0, Some(0xFB)));
        assert_eq!(watch.told, 1);
        assert_eq!(watch.poll(&config), drives.as_slice());
    }
}
