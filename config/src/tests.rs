//! Tests of the configuration: defaults, the example file, and the errors that name fields.

use super::*;

#[test]
fn defaults_are_valid_and_the_example_file_parses() {
    Config::default().validate().unwrap();
    let example = include_str!("../videt.example.toml");
    let c = Config::from_toml_str(example, "videt.example.toml").unwrap();
    assert_eq!(c.control.rate_hz, 1000);
    assert_eq!(
        c.colour,
        ColourConfig::default(),
        "the example shows the defaults"
    );
    assert_eq!(
        c.sensors,
        SensorsConfig::default(),
        "the example shows the defaults"
    );
    assert_eq!(
        c.telemetry,
        TelemetryConfig::default(),
        "the example shows the defaults"
    );
}

#[test]
fn session_log_retention_is_read_and_checked_against_its_ranges() {
    let t = TelemetryConfig::default();
    assert_eq!(
        (t.max_total_mb, t.max_age_days, t.min_free_mb),
        (4096, 30, 1024)
    );
    let c = Config::from_toml_str(
        "[telemetry]\nmax_total_mb = 16\nmax_age_days = 3650\nmin_free_mb = 0\n",
        "t",
    )
    .unwrap();
    assert_eq!(
        (
            c.telemetry.max_total_mb,
            c.telemetry.max_age_days,
            c.telemetry.min_free_mb
        ),
        (16, 3650, 0)
    );
    let c = Config::from_toml_str(
        "[telemetry]\nmax_total_mb = 10000000\nmax_age_days = 1\nmin_free_mb = 10000000\n",
        "t",
    )
    .unwrap();
    assert_eq!(c.telemetry.min_free_mb, 10_000_000);
    for (body, field, allowed) in [
        (
            "max_total_mb = 15",
            "telemetry.max_total_mb = 15",
            "[16, 10000000]",
        ),
        (
            "max_total_mb = 10000001",
            "telemetry.max_total_mb = 10000001",
            "[16, 10000000]",
        ),
        (
            "max_age_days = 0",
            "telemetry.max_age_days = 0",
            "[1, 3650]",
        ),
        (
            "max_age_days = 3651",
            "telemetry.max_age_days = 3651",
            "[1, 3650]",
        ),
        (
            "min_free_mb = 10000001",
            "telemetry.min_free_mb = 10000001",
            "[0, 10000000]",
        ),
    ] {
        let e = Config::from_toml_str(&format!("[telemetry]\n{body}\n"), "t")
            .unwrap_err()
            .to_string();
        assert!(e.contains(field) && e.contains(allowed), "{body}: {e}");
    }
    // Negative and fractional values are not of the keys' type; an unknown key is refused.
    for body in ["min_free_mb = -1", "max_age_days = 1.5", "max_total_gb = 4"] {
        let e = Config::from_toml_str(&format!("[telemetry]\n{body}\n"), "t").unwrap_err();
        assert!(matches!(e, ConfigError::Parse { .. }), "{body}: {e}");
    }
}

/// The error a configuration text is refused with.
fn refusal(text: &str) -> String {
    Config::from_toml_str(text, "t").unwrap_err().to_string()
}

#[test]
fn errors_name_the_field_value_and_range() {
    let e = refusal("[control]\nrate_hz = 50\n");
    assert!(
        e.contains("control.rate_hz") && e.contains("50") && e.contains("1000"),
        "{e}"
    );
    let e = refusal("[control]\nt_max_n = 40.0\n");
    assert!(e.contains("control.t_max_n") && e.contains("40"), "{e}");
    let e = refusal("[control]\nalgorithm = \"X9\"\n");
    assert!(e.contains("control.algorithm") && e.contains("X9"), "{e}");
    let e = refusal("[vision]\nrelief_shape = \"smooth\"\n");
    assert!(
        e.contains("relief_shape") && e.contains("smooth") && e.contains("stepped"),
        "{e}"
    );
}

#[test]
fn colour_settings_are_checked_field_by_field() {
    let cases = [
        ("window_px = 8", "colour.window_px", "odd"),
        ("window_px = 33", "colour.window_px", "31"),
        (
            "low_mid = 150.0\nmid_high = 140.0",
            "colour.mid_high",
            "151",
        ),
        ("hysteresis = 50.0", "colour.hysteresis", "42.5"),
        ("black_level = 200.0", "colour.white_level", "201"),
        ("frequency_hz = 0.0", "colour.frequency_hz", "1000"),
        ("duty = [0.0, 0.5, 0.2]", "colour.duty[2]", "[0.5, 1]"),
    ];
    for (body, field, allowed) in cases {
        let e = Config::from_toml_str(&format!("[colour]\n{body}\n"), "t")
            .unwrap_err()
            .to_string();
        assert!(e.contains(field) && e.contains(allowed), "{body}: {e}");
    }
    // The levels of plain RGB ignore the chromaticity stretch.
    let c = Config::from_toml_str(
        "[colour]\nspace = \"rgb\"\nblack_level = 250.0\nwhite_level = 10.0\n",
        "t",
    )
    .unwrap();
    assert_eq!(c.colour.space, ColourSpaceName::Rgb);
    let e = Config::from_toml_str("[colour]\nspace = \"hsv\"\n", "t")
        .unwrap_err()
        .to_string();
    assert!(e.contains("hsv") && e.contains("chromaticity"), "{e}");
    let e = Config::from_toml_str("[colour]\nstatistic = \"mode\"\n", "t")
        .unwrap_err()
        .to_string();
    assert!(e.contains("mode") && e.contains("median"), "{e}");
}

#[test]
fn autoinit_limits_are_checked_against_the_device_limits() {
    let e = Config::from_toml_str("[autoinit]\nwind_speed_m_s = 0.9\n", "t")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("autoinit.wind_speed_m_s") && e.contains("0.9") && e.contains("0.3"),
        "{e}"
    );
    let e = Config::from_toml_str("[autoinit]\nwind_tension_max_n = 20.0\n", "t")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("autoinit.wind_tension_max_n") && e.contains("15"),
        "{e}"
    );
    let e = Config::from_toml_str("[files]\nmotors_lock = \"\"\n", "t")
        .unwrap_err()
        .to_string();
    assert!(e.contains("files.motors_lock"), "{e}");
}

#[test]
fn every_section_is_validated() {
    for (text, field) in [
        (
            "[realtime]\nvision_priority = 95\n",
            "realtime.vision_priority",
        ),
        (
            "[realtime]\nmax_consecutive_overruns = 0\n",
            "realtime.max_consecutive_overruns",
        ),
        (
            "[realtime]\nmax_consecutive_overruns = 1000001\n",
            "realtime.max_consecutive_overruns",
        ),
        (
            "[realtime]\ncpu_wakeup_latency_us = -5\n",
            "realtime.cpu_wakeup_latency_us",
        ),
        ("[drives]\nnode_ids = [1, 1, 2]\n", "drives.node_ids"),
        ("[drives]\nnode_ids = [1, 2, 200]\n", "drives.node_ids[2]"),
        (
            "[drives]\nheartbeat_ms = 10\nheartbeat_timeout_ms = 15\n",
            "drives.heartbeat_timeout_ms",
        ),
        (
            "[drives]\nmax_missed_cycles = 101\n",
            "drives.max_missed_cycles",
        ),
        (
            "[drives]\npdo_wait_fraction = 1.0\n",
            "drives.pdo_wait_fraction",
        ),
        (
            "[drives]\npower_timeout_ms = 0\n",
            "drives.power_timeout_ms",
        ),
        ("[drives]\nbitrate = 2000000\n", "drives.bitrate"),
        (
            "[sensors]\nadc = \"hx711\"\nhx711_clock_lines = [5, 6, 13]\nhx711_data_lines = [16, 20, 21]\n",
            "sensors.sample_rate_sps",
        ),
        (
            "[sensors]\nads1220_mode = \"normal\"\n",
            "sensors.sample_rate_sps",
        ),
        ("[drives]\nbitrate = 1000\n", "drives.bitrate"),
        (
            "[drives]\nmax_bus_load = 1.0\n",
            "drives.max_bus_load",
        ),
        ("[sensors]\nstale_after_ms = 0\n", "sensors.stale_after_ms"),
        (
            "[sensors]\ndrdy_lines = [5, 17, 13]\n",
            "sensors.drdy_lines[1]",
        ),
        (
            "[sensors]\nadc = \"hx711\"\nsample_rate_sps = 80\nhx711_data_lines = [16, 20, 12]\n",
            "sensors.hx711_data_lines[1]",
        ),
        (
            "[sensors]\nspi_devices = [\"/dev/spidev0.0\", \"/dev/spidev0.0\", \"/dev/spidev1.0\"]\n",
            "sensors.spi_devices[1]",
        ),
        (
            "[sensors]\nnewtons_per_count = [2e-5, 0.0, 2e-5]\n",
            "sensors.newtons_per_count[1]",
        ),
        (
            "[sensors]\nzero_counts = [0, 0, 9000000]\n",
            "sensors.zero_counts[2]",
        ),
        (
            "[vision]\nsurface_max_age_s = 0.0\n",
            "vision.surface_max_age_s",
        ),
        ("[telemetry]\nring_records = 3\n", "telemetry.ring_records"),
        ("[vision]\nrebuild_period_s = 0.0\n", "vision.rebuild_period_s"),
        ("[vision]\nfull_refresh_s = 0.01\n", "vision.full_refresh_s"),
        ("[vision]\nmax_disparity_px = 0.5\n", "vision.max_disparity_px"),
        ("[vision]\npair_tolerance_ms = 0\n", "vision.pair_tolerance_ms"),
        ("[vision]\nframe_rate_hz = 0\n", "vision.frame_rate_hz"),
        ("[vision]\npatch_spacing_px = 3\n", "vision.patch_spacing_px"),
        ("[vision]\npatch_spacing_px = 65\n", "vision.patch_spacing_px"),
        (
            "[vision]\nmin_match_confidence = 1.5\n",
            "vision.min_match_confidence",
        ),
        ("[socket]\npath = \"\"\n", "socket.path"),
        (
            "[control]\nslack_takeup_speed_m_s = 0.6\n",
            "control.slack_takeup_speed_m_s",
        ),
        (
            "[control]\nalgorithm = \"QP\"\nfield_n = 20.0\n",
            "control.field_n",
        ),
    ] {
        let e = Config::from_toml_str(text, "t").unwrap_err().to_string();
        assert!(e.contains(field), "{text:?}: {e}");
    }
}

#[test]
fn a_gpio_line_used_twice_names_both_fields() {
    let e = Config::from_toml_str("[sensors]\nvibrotactor_lines = [22, 23, 17]\n", "t")
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "sensors.vibrotactor_lines[2] = 17: must be a GPIO line not used already (it is sensors.estop_line)"
    );
    // The HX711's lines are only checked when the HX711 is the converter in use.
    Config::from_toml_str("[sensors]\nhx711_clock_lines = [17, 17, 17]\n", "t").unwrap();
    let inverted =
        Config::from_toml_str("[sensors]\nnewtons_per_count = [-2e-5, 2e-5, 2e-5]\n", "t");
    assert!(inverted.is_ok(), "an inverted bridge is allowed");
}

#[test]
fn the_drive_analog_input_is_checked_when_it_is_the_converter() {
    let drive = "[sensors]\nadc = \"drive\"\nnewtons_per_count = [0.005, 0.005, -0.005]\n";
    let c = Config::from_toml_str(drive, "t").unwrap();
    assert_eq!(c.sensors.adc, TensionAdc::Drive);
    assert_eq!(
        (
            c.sensors.drive_analog_index,
            c.sensors.drive_analog_subindex
        ),
        (0x6401, 1)
    );
    // The GPIO lines and SPI devices of the other converters are not in use.
    Config::from_toml_str(
        &format!("{drive}drdy_lines = [17, 17, 17]\nspi_devices = [\"\", \"\", \"\"]\n"),
        "t",
    )
    .unwrap();
    let c = Config::from_toml_str(
        &format!("{drive}drive_analog_index = 0x3160\ndrive_analog_subindex = 0\n"),
        "t",
    )
    .unwrap();
    assert_eq!(c.sensors.drive_analog_index, 0x3160);
    for (extra, message) in [
        (
            "drive_analog_index = 0x1A01\n",
            "sensors.drive_analog_index = 0x1a01: must be in [0x2000, 0x9fff]",
        ),
        (
            "drive_analog_subindex = 0\n",
            "sensors.drive_analog_subindex = 0: must be in [0, 254], and in [1, 254] for 0x6401",
        ),
        (
            "drive_analog_index = 0x3160\ndrive_analog_subindex = 255\n",
            "sensors.drive_analog_subindex = 255: must be in [0, 254]",
        ),
        (
            "zero_counts = [0, 40000, 0]\n",
            "sensors.zero_counts[1] = 40000: must be in [-32768, 32767]",
        ),
        (
            "newtons_per_count = [0.005, 2.0, 0.005]\n",
            "sensors.newtons_per_count[1] = 2: must be between 1e-6 and 1 in magnitude for adc = \"drive\"",
        ),
    ] {
        // A later key would repeat one of `drive`: start from the converter alone.
        let text = if extra.starts_with("newtons") {
            format!("[sensors]\nadc = \"drive\"\n{extra}")
        } else {
            format!("{drive}{extra}")
        };
        let e = Config::from_toml_str(&text, "t").unwrap_err().to_string();
        assert!(e.starts_with(message), "{extra:?}: {e}");
    }
    // Off "drive", the drive fields are not checked.
    Config::from_toml_str("[sensors]\ndrive_analog_index = 0\n", "t").unwrap();
    let e = Config::from_toml_str("[sensors]\nadc = \"spi\"\n", "t")
        .unwrap_err()
        .to_string();
    assert!(e.contains("drive"), "the choices are listed: {e}");
}

#[test]
fn unknown_keys_are_rejected() {
    let e = Config::from_toml_str("[control]\nrate_hzz = 1000\n", "t")
        .unwrap_err()
        .to_string();
    assert!(e.contains("rate_hzz"), "{e}");
}

#[test]
fn rig_device_is_named_and_checked() {
    let mut c = Config::default();
    assert_eq!(c.rig.device, "wireman3");
    for d in RIG_DEVICES {
        c.rig.device = d.into();
        c.validate().unwrap();
    }
    c.rig.device = "wireman".into();
    let e = c.validate().unwrap_err().to_string();
    assert!(e.contains("rig.device") && e.contains("planar2"), "{e}");
    let mut c = Config::default();
    c.rig.planar_guides_x_m = [0.3, 0.305];
    let e = c.validate().unwrap_err().to_string();
    assert!(e.contains("rig.planar_guides_x_m"), "{e}");
    let mut c = Config::default();
    c.rig.spidar_guides_m[2][2] = f64::NAN;
    assert!(c
        .validate()
        .unwrap_err()
        .to_string()
        .contains("rig.spidar_guides_m[2].z"));
}

#[test]
fn the_live_view_is_off_on_loopback_by_default_and_its_settings_are_checked() {
    let c = Config::default();
    assert!(!c.live.enabled);
    assert_eq!(c.live.host_port().unwrap(), ("127.0.0.1".to_string(), 8765));
    for (address, expected) in [
        ("0.0.0.0:9000", Some(("0.0.0.0", 9000))),
        ("[::1]:8765", Some(("::1", 8765))),
        ("backpack.local:0", Some(("backpack.local", 0))),
        ("127.0.0.1", None),
        ("::1:8765", None),
        ("127.0.0.1:70000", None),
        (":8765", None),
    ] {
        let mut c = Config::default();
        c.live.address = address.into();
        match expected {
            Some((host, port)) => {
                assert_eq!(c.live.host_port().unwrap(), (host.to_string(), port));
                c.validate().unwrap();
            }
            None => {
                let e = c.validate().unwrap_err().to_string();
                assert!(e.contains("live.address") && e.contains("HOST:PORT"), "{e}");
            }
        }
    }
    let e = Config::from_toml_str("[live]\nrate_hz = 500\n", "t")
        .unwrap_err()
        .to_string();
    assert!(e.contains("live.rate_hz") && e.contains("[1, 120]"), "{e}");
    let e = Config::from_toml_str("[live]\nclient_backlog = 1\n", "t")
        .unwrap_err()
        .to_string();
    assert!(e.contains("live.client_backlog"), "{e}");
}

#[test]
fn the_relief_is_stepped_with_patches_unless_the_papers_is_asked() {
    let d = Config::default().vision;
    assert_eq!(
        (d.relief_shape, d.patch_spacing_px),
        (ReliefShapeName::Stepped, 12)
    );
    let c = Config::from_toml_str(
        "[vision]\nrelief_shape = \"interpolated\"\npatch_spacing_px = 0\n",
        "t",
    )
    .unwrap();
    assert_eq!(
        (c.vision.relief_shape, c.vision.patch_spacing_px),
        (ReliefShapeName::Interpolated, 0)
    );
}

#[test]
fn the_patch_spacing_is_off_or_between_4_and_64_pixels() {
    for ok in [0u32, 4, 12, 64] {
        let c =
            Config::from_toml_str(&format!("[vision]\npatch_spacing_px = {ok}\n"), "t").unwrap();
        assert_eq!(c.vision.patch_spacing_px, ok);
    }
    let e = Config::from_toml_str("[vision]\npatch_spacing_px = 2\n", "t")
        .unwrap_err()
        .to_string();
    assert!(e.contains("0 (off) or in [4, 64]"), "{e}");
}
