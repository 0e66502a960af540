//! The drives of real parts' descriptions: the CAN twin's CiA 402 nodes built from every EDS and
//! DCF of the shared data (and from the generic profile), configured, enabled and run by the
//! real driver through the service's start-up, or refused with a text that names the wire, the
//! node, the object and what would fix it, leaving every drive disabled and pre-operational.

use std::path::Path;
use std::time::Duration;
use videt_assembly::hardware::DriveReports;

use videt_assembly::can_twin::{drive_config, CanTwin};
use videt_assembly::WiremanTwin;
use videt_config::Config;
use videt_hal::{DriveSample, Lifecycle, WireDrives};
use videt_runtime::control_loop::start_hardware;
use videt_sim::cia402_node::DrivePower;

/// What the driver does with a part.
#[derive(Debug)]
enum Outcome {
    /// Configures, enables and runs; the optional objects it lacks are told.
    Runs { notes: &'static [&'static str] },
    /// Refused at start-up with a text holding each of these.
    Refused(&'static [&'static str]),
}

/// Every shipped description and what the driver must do with it.
const PARTS: &[(&str, Outcome)] = &[
    (
        "301.eds",
        Outcome::Refused(&[
            "drive of wire 0 (node 1): 0x1000:00 (device type) is 0x00000000, profile 0: not a \
             CiA 402 drive",
            "drives.node_ids",
        ]),
    ),
    (
        "402.eds",
        Outcome::Refused(&[
            "0x1000:00 (device type) is 0x00000000",
            "not a CiA 402 drive",
        ]),
    ),
    (
        "605.3150.67-A-EK-2-60.eds",
        Outcome::Refused(&[
            "drive of wire 0 (node 1): 0x6502:00 (supported drive modes) is 0x00000025: no \
             cyclic synchronous torque mode",
        ]),
    ),
    (
        "605.3150.67-B-EK-2-60.eds",
        Outcome::Refused(&["0x6502:00 (supported drive modes) is 0x00000025"]),
    ),
    // Their motor data are not set (0x6076 = 0): the drive must be commissioned first (they
    // have no target torque 0x6071 either).
    (
        "MD80_DS402.eds",
        Outcome::Refused(&[
            "drive of wire 0 (node 1): 0x6076:00 (motor rated torque) is 0 mN·m but the \
             configuration says 50 mN·m",
        ]),
    ),
    (
        "MDv1.0.0.eds",
        Outcome::Refused(&["0x6076:00 (motor rated torque) is 0 mN·m"]),
    ),
    (
        "epos4_50_15_can_ec90flat_gp52c_mile800_node1.dcf",
        Outcome::Runs {
            notes: &[
                "0x6072:00 (max torque): object does not exist in the object dictionary \
                 (0x06020000); only the service's own torque clamp limits the tension",
                "0x1801:05 (TPDO2 event timer): sub-index does not exist (0x06090011); the \
                 status PDO is then sent on change only",
            ],
        },
    ),
    (
        "epos4_50_15_can_ec90flat_gp52c_mile800_node1_hm.dcf",
        Outcome::Runs {
            notes: &["0x1801:05 (TPDO2 event timer)"],
        },
    ),
    (
        "epos4_50_15_can_ec90flat_gp52c_mile800_node2.dcf",
        Outcome::Runs {
            notes: &["0x1801:05 (TPDO2 event timer)"],
        },
    ),
];

/// The service's configuration for drives described by `description` (a file written into
/// `dir`): the file's units where the configuration accepts them; otherwise (a file that gives
/// no usable rated torque) the default configuration, the rated torque left unchecked.
fn configured(dir: &Path, name: &str, description: &str) -> (Config, bool) {
    let path = dir.join(name);
    std::fs::write(&path, description).unwrap();
    let toml = dir.join(format!("{name}.toml"));
    std::fs::write(
        &toml,
        format!(
            "[drives]\ndevice_description = {:?}\n",
            path.display().to_string()
        ),
    )
    .unwrap();
    match Config::load(&toml) {
        Ok(c) => (c, true),
        Err(e) => {
            eprintln!("{name}: the configuration refuses it ({e}); default units");
            (Config::default(), false)
        }
    }
}

/// Start the CAN twin with drives of `description`; run 200 periods when it starts.
fn start(dir: &Path, name: &str, description: &str) -> (Result<(), String>, Vec<String>) {
    let (config, units_from_file) = configured(dir, name, description);
    let dictionary = videt_assembly::drive_dictionary::for_file(&dir.join(name), &config).unwrap();
    let mut drives = drive_config::<3>(&config);
    drives.drive_heartbeat_timeout = Duration::from_secs(3600);
    drives.verify_rated_torque = units_from_file;
    let twin: WiremanTwin = videt_assembly::twin_scene::wireman_wall_scene(&config, 42).twin;
    let mut hw = CanTwin::stepped(twin, drives, Some(std::sync::Arc::new(dictionary))).unwrap();
    let started = start_hardware(&mut hw).map_err(|e| e.to_string());
    let notes = {
        let report = hw.startup_report();
        let r = report.lock().unwrap();
        r.notes.iter().map(|n| n.to_string()).collect()
    };
    if started.is_ok() {
        let mut out = [DriveSample::default(); 3];
        for _ in 0..200 {
            hw.write_torques(&[0.001; 3]).unwrap();
            hw.read_drives(&mut out).unwrap();
        }
        assert!(
            hw.drive_nodes()
                .iter()
                .all(|n| n.power == DrivePower::OperationEnabled && n.applied_torque_nm > 0.0),
            "{name}: {:?}",
            hw.drive_nodes()
        );
        hw.deactivate().unwrap();
    } else {
        // Nothing is left enabled, nor exchanging process data.
        for n in hw.drive_nodes() {
            assert_ne!(n.power, DrivePower::OperationEnabled, "{name}");
            assert_ne!(
                n.nmt,
                videt_sim::cia402_node::NmtState::Operational,
                "{name}"
            );
            assert_eq!(n.applied_torque_nm, 0.0, "{name}");
        }
    }
    (started, notes)
}

#[test]
fn every_shipped_part_runs_or_is_refused_with_a_text_a_technician_can_act_on() {
    let Some(data) = videt_testdata::data_dir("canopen/eds") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let mut shipped: Vec<String> = std::fs::read_dir(&data)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".eds") || n.ends_with(".dcf"))
        .collect();
    shipped.sort();
    let mut listed: Vec<String> = PARTS.iter().map(|(n, _)| n.to_string()).collect();
    listed.sort();
    assert_eq!(
        shipped, listed,
        "every shipped description has its expected outcome"
    );
    for (name, outcome) in PARTS {
        let text = String::from_utf8_lossy(&std::fs::read(data.join(name)).unwrap()).into_owned();
        let (started, notes) = start(dir.path(), name, &text);
        eprintln!("{name}: {started:?}");
        match (outcome, started) {
            (Outcome::Runs { notes: expected }, Ok(())) => {
                for e in *expected {
                    assert!(
                        notes.iter().any(|n| n.contains(e)),
                        "{name}: no note with {e:?} in {notes:?}"
                    );
                }
            }
            (Outcome::Refused(expected), Err(text)) => {
                for e in *expected {
                    assert!(text.contains(e), "{name}: {e:?} not in {text:?}");
                }
                assert!(!text.contains('{'), "{name}: a Debug dump: {text}");
            }
            (o, r) => panic!("{name}: expected {o:?}, got {r:?}"),
        }
    }
}

/// The EPOS4 DCF with the object `section` (and its sub-indices) cut out.
fn epos4_without(section: &str) -> Option<String> {
    let data = videt_testdata::data_dir("canopen/eds")?;
    let text = String::from_utf8_lossy(
        &std::fs::read(data.join("epos4_50_15_can_ec90flat_gp52c_mile800_node1.dcf")).unwrap(),
    )
    .into_owned();
    let mut out = String::new();
    let mut skipping = false;
    for line in text.lines() {
        if let Some(header) = line.trim().strip_prefix('[') {
            let name = header.split(']').next().unwrap_or("").to_ascii_lowercase();
            skipping = name == section || name.starts_with(&format!("{section}sub"));
        }
        if !skipping {
            out.push_str(line);
            out.push('\n');
        }
    }
    Some(out)
}

#[test]
fn a_drive_without_a_heartbeat_producer_is_refused_before_anything_is_enabled() {
    let Some(text) = epos4_without("1017") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (started, _) = start(dir.path(), "no-heartbeat.dcf", &text);
    let e = started.unwrap_err();
    assert!(
        e.contains(
            "drive of wire 0 (node 1): 0x1017:00 (producer heartbeat time): object does not exist \
             in the object dictionary (0x06020000); the service needs it"
        ) && e.contains("use a drive with a heartbeat producer"),
        "{e}"
    );
}

#[test]
fn a_drive_without_a_heartbeat_consumer_is_refused_for_safety() {
    let Some(text) = epos4_without("1016") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let e = start(dir.path(), "no-consumer.dcf", &text).0.unwrap_err();
    assert!(
        e.contains("0x1016:01 (consumer heartbeat time)") && e.contains("hold the last torque"),
        "{e}"
    );
}

#[test]
fn a_drive_that_refuses_a_mapping_is_named_with_the_object_it_was_to_carry() {
    // The EPOS4 with its position actual value not mappable.
    let Some(text) = epos4_without("6064") else {
        return;
    };
    let text = format!(
        "{text}\n[6064]\nParameterName=Position actual value\nObjectType=0x7\nDataType=0x0004\n\
         AccessType=ro\nPDOMapping=0\nDefaultValue=0\n"
    );
    let dir = tempfile::tempdir().unwrap();
    let e = start(dir.path(), "no-position-pdo.dcf", &text)
        .0
        .unwrap_err();
    assert!(
        e.contains(
            "0x1a00:01 (TPDO1 mapping) entry 1 refused 0x6064:00 (position actual value) (32 \
             bits): object cannot be mapped to the PDO (0x06040041)"
        ),
        "{e}"
    );
}

#[test]
fn a_drive_without_a_mappable_target_torque_is_refused() {
    let Some(text) = epos4_without("6071") else {
        return;
    };
    let text = format!(
        "{text}\n[6071]\nParameterName=Target torque\nObjectType=0x7\nDataType=0x0003\n\
         AccessType=rw\nPDOMapping=0\nDefaultValue=0\n"
    );
    let dir = tempfile::tempdir().unwrap();
    let e = start(dir.path(), "no-torque-pdo.dcf", &text).0.unwrap_err();
    assert!(
        e.contains(
            "drive of wire 0 (node 1): 0x1600:02 (RPDO1 mapping) entry 2 refused 0x6071:00 \
             (target torque) (16 bits): object cannot be mapped to the PDO (0x06040041); the \
             service needs it: the torque command of every period, in RPDO1; use a drive that \
             maps the target torque"
        ),
        "{e}"
    );
}

#[test]
fn the_generic_profile_runs_and_tells_its_missing_event_timer() {
    let config = Config::default();
    let mut drives = drive_config::<3>(&config);
    drives.drive_heartbeat_timeout = Duration::from_secs(3600);
    let mut hw = CanTwin::stepped(
        videt_assembly::twin_scene::wireman_wall_scene(&config, 42).twin,
        drives,
        None,
    )
    .unwrap();
    start_hardware(&mut hw).unwrap();
    let report = hw.startup_report();
    let r = report.lock().unwrap();
    assert_eq!(r.drives.len(), 3);
    assert!(r.drives.iter().all(|(_, _, id)| id.is_cia402()));
    // The generic drive has no TPDO2 event timer either.
    assert_eq!(r.notes.len(), 3, "{:?}", r.notes);
}
