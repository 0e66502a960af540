//! Whole-stack test of the colour thread on the twin: thimble positions published as the control
//! loop publishes them, the demo image under the explored area, the vibration loop on simulated
//! time writing to recording vibrotactors.

use std::time::{Duration, Instant};

use videt_colour::level::Level::{High, Low};
use videt_colour::{RecordingVibrotactors, SimulatedClock};
use videt_config::Config;
use videt_control::safety::{SafetyReason, SafetyState};
use videt_hal::{Clock, MonoTime};
use videt_runtime::control_loop::{CycleObserver, WindowStats};
use videt_runtime::cycle::CycleRecord;
use videt_runtime::snapshot::snapshot_channel;
use videt_runtime::thimble::thimble_channel;
use videt_service::colour_thread::{demo_colour, spawn_colour_thread, ColourHandles};

/// Wait (bounded) until the colour thread shows `want` in its status.
fn wait_for(handles: &ColourHandles, want: impl Fn(&ColourHandles) -> bool) {
    let start = Instant::now();
    while !want(handles) {
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "colour thread never reached the expected state: {}",
            handles.status_text()
        );
        std::thread::sleep(Duration::from_millis(1));
    }
}

#[test]
fn colour_under_the_thimble_drives_the_vibrotactors_and_safe_state_silences_them() {
    let config = Config::default();
    let wall_z_m = 0.33;
    let source = demo_colour(&config.rig.guides_m, wall_z_m, &config.colour).unwrap();
    let (settings, map) = (source.settings, source.settings.map);
    let (mut thimble_pub, thimble_reader) = thimble_channel();
    let (_frames, frame_reader) = snapshot_channel(source.frame.clone());
    let clock = SimulatedClock::new(MonoTime(1_000_000_000));
    let vibro = RecordingVibrotactors::new(clock.clone(), 100_000);
    let (handles, join) = spawn_colour_thread(
        vibro,
        clock.clone(),
        settings,
        thimble_reader,
        frame_reader,
        None,
    )
    .unwrap();

    // The control loop publishes the thimble state; the supervisor allows rendering only in the
    // normal state (as `ColourRuntime::supervise` does in the service).
    let mut publish = |u: f64, v: f64, safety: SafetyState| {
        let [x, y] = map.image_to_workspace(u, v);
        let record = CycleRecord {
            cycle: 1,
            position_m: [x, y, wall_z_m],
            safety,
            ..CycleRecord::default()
        };
        thimble_pub.observe(&record, &WindowStats::default());
        handles.inputs.set_active(safety == SafetyState::Normal);
    };

    // Before the control loop publishes anything: quiet.
    std::thread::sleep(Duration::from_millis(5));
    assert!(!handles.inputs.is_active());
    assert_eq!(handles.inputs.levels(), None);

    // Red cone of the demo crop (pixel 185, 75): red High, green and blue Low.
    publish(185.5, 75.5, SafetyState::Normal);
    wait_for(&handles, |h| {
        h.inputs.is_active() && h.inputs.levels() == Some([High, Low, Low])
    });
    assert!(
        handles.status_text().starts_with("colour HLL"),
        "{}",
        handles.status_text()
    );
    let red_from = clock.now();
    // Let 0.5 s of simulated time pass on red.
    while clock.now().nanos_since(red_from) < 500_000_000 {
        std::thread::yield_now();
    }
    let red_to = clock.now();

    // Off the image: quiet.
    publish(-30.0, 75.5, SafetyState::Normal);
    wait_for(&handles, |h| h.inputs.levels().is_none());
    assert_eq!(handles.status_text(), "colour quiet (off-image)");

    // Green cone (pixel 120, 75) while the control loop is in a safe state: quiet.
    publish(
        120.5,
        75.5,
        SafetyState::MinimumTension(SafetyReason::EmergencyStop),
    );
    wait_for(&handles, |h| !h.inputs.is_active());
    assert_eq!(handles.status_text(), "colour quiet (not rendering)");
    let safe_from = clock.now();
    while clock.now().nanos_since(safe_from) < 200_000_000 {
        std::thread::yield_now();
    }
    let safe_to = clock.now();

    handles.inputs.request_shutdown();
    let (jitter, vibro) = join.join().unwrap().unwrap();
    assert_eq!(vibro.state(), [false; 3], "off after shutdown");
    assert!(jitter.count() > 700);

    // On red: the red vibrotactor at 75 Hz with High's 50 % duty, green and blue silent.
    let from = red_from.add_nanos(50_000_000);
    let red = vibro.channel_summary(0, from, red_to);
    let f = red.frequency_hz.unwrap();
    assert!((f - 75.0).abs() < 0.75, "{f} Hz");
    assert!((red.duty - 0.5).abs() < 0.03, "{red:?}");
    for c in [1, 2] {
        assert_eq!(vibro.channel_summary(c, from, red_to).rising_edges, 0);
    }
    // In the safe state (after the switch-over tick): every output off.
    for c in 0..3 {
        let s = vibro.channel_summary(c, safe_from.add_nanos(10_000_000), safe_to);
        assert_eq!((s.rising_edges, s.duty), (0, 0.0), "channel {c}");
    }
}

/// `videtd --sim` for 2.5 s with `colour_section` as the configuration's `[colour]` (none:
/// the defaults); its status lines and its log.
fn videtd_sim_with_colour(colour_section: Option<&str>) -> (Vec<String>, String) {
    let dir = tempfile::tempdir().unwrap();
    let mut cmd = std::process::Command::new(videt_testkit::videtd_bin());
    cmd.args([
        "--sim",
        "--duration",
        "2.5",
        "--no-socket",
        "--no-telemetry",
    ]);
    if let Some(section) = colour_section {
        let config = dir.path().join("videt.toml");
        std::fs::write(&config, format!("[colour]\n{section}\n")).unwrap();
        cmd.arg("--config").arg(config).env("RUST_LOG", "info");
    }
    let out = cmd.output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    let stdout = String::from_utf8(out.stdout).unwrap();
    let lines = stdout
        .lines()
        .filter(|l| l.starts_with("t="))
        .map(str::to_owned)
        .collect();
    (lines, stderr)
}

/// `videtd --sim` shows the colour under the finger in its status line and stops cleanly.
#[test]
fn videtd_sim_status_line_shows_the_colour() {
    let (lines, stderr) = videtd_sim_with_colour(None);
    let stdout = lines.join("\n");
    assert!(lines.len() >= 2, "{stdout}");
    // While the operator touches the wall the levels are shown as three letters.
    assert!(
        lines.iter().any(|l| {
            l.split("colour ")
                .nth(1)
                .is_some_and(|c| c.len() >= 3 && c[..3].chars().all(|ch| "LMH".contains(ch)))
        }),
        "{stdout}"
    );
    assert!(
        stderr.contains("colour thread stopped: vibrotactors off"),
        "{stderr}"
    );
}

/// The `[colour]` section of the configuration sets the thresholds `videtd` renders with, and
/// turns the colour off.
#[test]
fn videtd_sim_renders_the_colour_as_the_configuration_says() {
    // Plain RGB, Mid from 1 and High from 2, no dead band: every level follows from the
    // colour shown beside it.
    let (lines, _) = videtd_sim_with_colour(Some(
        "space = \"rgb\"\nlow_mid = 1.0\nmid_high = 2.0\nhysteresis = 0.0",
    ));
    let mut checked = 0;
    for line in &lines {
        // `colour HLL rgb(230, 20, 20)`
        let Some((letters, rgb)) = line
            .split_once("colour ")
            .and_then(|(_, c)| c.split_once(" rgb("))
        else {
            continue;
        };
        let values: Vec<u32> = rgb
            .trim_end_matches(')')
            .split(',')
            .map(|v| v.trim().parse().unwrap())
            .collect();
        let expected: String = values
            .iter()
            .map(|&v| match v {
                0 => 'L',
                1 => 'M',
                _ => 'H',
            })
            .collect();
        assert_eq!(letters, expected, "{line}");
        checked += 1;
    }
    assert!(checked > 0, "no colour rendered: {lines:?}");

    let (lines, stderr) = videtd_sim_with_colour(Some("enabled = false"));
    assert!(
        stderr.contains("colour rendering off (colour.enabled = false)"),
        "{stderr}"
    );
    assert!(!stderr.contains("colour thread"), "{stderr}");
    assert!(lines.iter().all(|l| !l.contains("colour ")), "{lines:?}");
}

/// On the device the colour thread drives the GPIO vibrotactors named by the configuration; a
/// chip that is not there is refused with a message naming the configuration fields (the
/// service then runs without colour), and the colour frames a camera publishes reach the thread.
#[test]
fn device_vibrotactors_are_named_when_missing_and_camera_frames_reach_the_thread() {
    use videt_service::colour_thread::{camera_colour, ColourOutputs, ColourRuntime};
    let config = Config::default();
    let layout = videt_runtime::setup::relief_layout(&config);
    let gpio = ColourOutputs::Gpio {
        chip: "/nonexistent/gpiochip-absent".into(),
        lines: config.sensors.vibrotactor_lines,
    };
    let (source, _writer) = camera_colour(&layout, [640, 480], &Default::default(), gpio).unwrap();
    let (_, thimble) = thimble_channel();
    let Err(e) = ColourRuntime::start(&source, thimble, None) else {
        panic!("opened vibrotactors on a missing chip");
    };
    let text = e.to_string();
    assert!(
        text.contains("/nonexistent/gpiochip-absent")
            && text.contains("(sensors.gpio_chip, sensors.vibrotactor_lines)"),
        "{text}"
    );

    // The camera's frames, over the relief's area: a red frame under the thimble is rendered.
    let (source, mut writer) = camera_colour(
        &layout,
        [64, 48],
        &Default::default(),
        ColourOutputs::Recording,
    )
    .unwrap();
    let map = source.settings.map;
    let (mut thimble_pub, thimble) = thimble_channel();
    let runtime = ColourRuntime::start(&source, thimble, None).unwrap();
    assert!(runtime.frames.is_none(), "the camera publishes the frames");
    let [x, y] = map.image_to_workspace(32.0, 24.0);
    let record = CycleRecord {
        cycle: 1,
        position_m: [x, y, 0.33],
        safety: SafetyState::Normal,
        ..CycleRecord::default()
    };
    thimble_pub.observe(&record, &WindowStats::default());
    runtime.supervise(&record, false);
    writer.publish_with(|f| {
        *f = videt_hal::RgbFrame {
            width: 64,
            height: 48,
            data: [230u8, 20, 20].repeat(64 * 48),
        }
    });
    wait_for(runtime.handles(), |h| h.status_text().contains("rgb(230,"));
    assert!(
        runtime.status_text().starts_with("colour HLL"),
        "{}",
        runtime.status_text()
    );
    runtime.finish();
}
