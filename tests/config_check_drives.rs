//! `videt config check` on configurations that name the drives' device description: the
//! drives' units and torque resolution it prints, and the configurations it refuses.

use std::path::Path;
use std::process::{Command, Output};

fn check(config: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_videt"))
        .args(["config", "check"])
        .arg(config)
        .output()
        .expect("videt runs")
}

/// A configuration file `videt.toml` in `dir` beside `drive.eds`.
fn write(dir: &Path, description: &str, body: &str) -> std::path::PathBuf {
    std::fs::write(dir.join("drive.eds"), description).unwrap();
    let path = dir.join("videt.toml");
    std::fs::write(
        &path,
        format!("[drives]\ndevice_description = \"drive.eds\"\n{body}"),
    )
    .unwrap();
    path
}

const DRIVE_EDS: &str = "[DeviceInfo]\nVendorName=Example\n[6076]\nDefaultValue=40\n\
                         [608Fsub1]\nDefaultValue=4096\n[608Fsub2]\nDefaultValue=1\n\
                         [60A9]\nDefaultValue=0x00B44700\n";

#[test]
fn the_check_prints_the_drives_units_and_what_a_torque_step_is_on_a_wire() {
    let dir = tempfile::tempdir().unwrap();
    let out = check(&write(dir.path(), DRIVE_EDS, ""));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains(
            "\n# drives: rated torque 0.04 N·m (0x6076 of drive.eds), 1 step = 0.04 mN·m = 0.05 N \
             of wire tension; encoder 4096 counts/rev (0x608F sub1/sub2); gear 25 \
             (transmission.gear_ratio); control.t_max_n = 15 N takes 300 per mille (limit 32767); \
             velocity in rev/min (0x60A9)\n"
        ),
        "{stdout}"
    );
    // What the session logs keep, at the default limits and rate.
    assert!(
        stdout.contains(
            "\n# session logs: kept up to 4096 MB, 30 days, 1024 MB left free: about 5.4 hours \
             of sessions at 1000 Hz (0.8 GB per hour)\n"
        ),
        "{stdout}"
    );
    // The resolved settings carry the file's values.
    assert!(stdout.contains("counts_per_motor_rev = 4096"), "{stdout}");
    assert!(stdout.contains("rated_torque_nm = 0.04"), "{stdout}");
}

#[test]
fn the_check_refuses_a_configuration_that_disagrees_with_the_drive() {
    let dir = tempfile::tempdir().unwrap();
    for (body, needles) in [
        (
            "rated_torque_nm = 0.05\n",
            &[
                "drives.rated_torque_nm = 0.05",
                "0.04 N·m",
                "0x6076 of drive.eds",
                "drives.device_description",
            ][..],
        ),
        (
            "[transmission]\ncounts_per_motor_rev = 2000\n",
            &[
                "transmission.counts_per_motor_rev = 2000",
                "4096 counts/rev",
                "0x608F sub1/sub2 of drive.eds",
            ][..],
        ),
    ] {
        let out = check(&write(dir.path(), DRIVE_EDS, body));
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{body:?} accepted");
        for needle in needles {
            assert!(
                stderr.contains(needle),
                "{body:?}: {needle:?} missing: {stderr}"
            );
        }
    }
    // One step of a 0.4 N·m motor is 0.5 N on the wire: more than the minimum tension.
    let coarse = "[6076]\nDefaultValue=400\n";
    let out = check(&write(dir.path(), coarse, ""));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("control.t_min_n = 0.3: must be at least one step of target torque, 0.5 N")
            && stderr.contains("drives.rated_torque_nm = 0.4 N·m (0x6076 of drive.eds)"),
        "{stderr}"
    );
    std::fs::remove_file(dir.path().join("drive.eds")).unwrap();
    let out = check(&dir.path().join("videt.toml"));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(&format!(
            "drives.device_description = {:?}: cannot read it",
            dir.path().join("drive.eds").display().to_string()
        )),
        "{stderr}"
    );
}

#[test]
fn the_check_reads_a_real_epos4_dcf() {
    let Some(data) = videt_testdata::data_dir("canopen/eds") else {
        return;
    };
    let name = "epos4_50_15_can_ec90flat_gp52c_mile800_node1.dcf";
    let dir = tempfile::tempdir().unwrap();
    let description = std::fs::read_to_string(data.join(name)).unwrap();
    let out = check(&write(
        dir.path(),
        &description,
        "[control]\nt_min_n = 0.7\n[autoinit]\npay_out_tension_n = 0.8\n",
    ));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains(
            "# drives: rated torque 0.513 N·m (0x6076 of drive.eds), 1 step = 0.513 mN·m = 0.667 \
             N of wire tension; encoder 3200 counts/rev (0x3000 sub5); gear 26 (0x3003 \
             sub1/sub2)"
        ),
        "{stdout}"
    );
}
