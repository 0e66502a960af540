//! Each drive's identity against the configuration: the drive set reads its device type
//! (0x1000, refused unless CiA 402) and identity object (0x1018) when it starts; the check
//! compares the vendor id and product code with the configured device description's.

use videt_config::Config;

use super::StepReport;
use crate::drive_report::{unlike_description, DriveStatus};

/// One step per drive that answered at its node id: PASS when its identity is the configured
/// description's (or no description is configured to compare with), FAIL otherwise. `drives`
/// empty (hardware without CANopen drives): one SKIPPED step saying `why`.
pub fn identity_steps(drives: &[DriveStatus], config: &Config, why: &str) -> Vec<StepReport> {
    if drives.is_empty() {
        return vec![StepReport::skipped("drives.identity", why)];
    }
    drives
        .iter()
        .map(|d| {
            let name = format!("drive{}.identity", d.wire);
            let identity = d.identity();
            match (unlike_description(d, config), &config.drives.description) {
                (Some(unlike), _) => StepReport::fail(name, unlike, Vec::new()).with_wiring(
                    "a drive of another model at this node, or the description of another drive: \
                     name this drive's EDS/DCF in drives.device_description (or fit the drive it describes)",
                ),
                (None, Some(description)) => StepReport::pass(
                    name,
                    format!(
                        "node {} answers: {identity}, as {} describes it",
                        d.node, description.resolution.file
                    ),
                ),
                (None, None) => StepReport::pass(
                    name,
                    format!(
                        "node {} answers: {identity} (no drives.device_description to compare with)",
                        d.node
                    ),
                ),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::init::commission::Verdict;

    fn drive(wire: u8, product: u32) -> DriveStatus {
        DriveStatus {
            wire,
            node: wire + 1,
            device_type: 0x0002_0192,
            vendor_id: Some(0xFB),
            product_code: Some(product),
            revision: None,
            serial: None,
        }
    }

    #[test]
    fn each_drive_is_named_against_the_configured_description() {
        let dir = tempfile::tempdir().unwrap();
        let config = crate::drive_report::described_config(dir.path());
        let steps = identity_steps(
            &[
                drive(0, 0x6552_0000),
                drive(1, 0x6551_0000),
                drive(2, 0x6552_0000),
            ],
            &config,
            "unused",
        );
        let verdicts: Vec<(&str, Verdict)> =
            steps.iter().map(|s| (s.name.as_str(), s.verdict)).collect();
        assert_eq!(
            verdicts,
            [
                ("drive0.identity", Verdict::Pass),
                ("drive1.identity", Verdict::Fail),
                ("drive2.identity", Verdict::Pass)
            ]
        );
        assert!(
            steps[0].measured.contains("node 1 answers"),
            "{:?}",
            steps[0]
        );
        assert!(
            steps[1].measured.contains("product 0x65510000"),
            "{:?}",
            steps[1]
        );
        assert!(steps[1].wiring.is_some());
        // Without a description the identity is told, not judged; without drives, skipped.
        let plain = identity_steps(&[drive(0, 1)], &Config::default(), "unused");
        assert_eq!(plain[0].verdict, Verdict::Pass);
        assert!(plain[0].measured.contains("no drives.device_description"));
        let none = identity_steps(&[], &Config::default(), "the twin has no CANopen drives");
        assert_eq!(none.len(), 1);
        assert_eq!(
            (none[0].name.as_str(), none[0].verdict),
            ("drives.identity", Verdict::Skipped)
        );
    }
}
