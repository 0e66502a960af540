//! # videt-config — the configuration: its schema, validation, files and fixes
//!
//! One TOML file (`/etc/videt/videt.toml` on the device; `config/videt.example.toml` in the
//! repository) with sections for the rig geometry, the transmission, control gains and limits, and
//! real-time settings. Unknown keys are rejected; every value is validated on load with an error
//! that names the field, its value and the allowed range. The drives' device description
//! (`drives.device_description`, an EDS or DCF) is read on load and gives the drives' units
//! ([`drive_units`]).
#![forbid(unsafe_code)]
#![warn(missing_docs)]

use std::path::Path;

use serde::{Deserialize, Serialize};

pub mod calibration;
pub mod drive_units;
pub mod edit;
mod validate;

pub use drive_units::DeviceDescription;

/// A configuration error: what is wrong, in which field.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file is not valid TOML for the schema (syntax, unknown key, wrong type).
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// The parser's message (names the key and line).
        message: String,
    },
    /// `drives.device_description` cannot be read, is not an EDS or DCF, or holds a value
    /// that cannot be a drive's.
    #[error("drives.device_description = {path:?}: {message}")]
    DeviceDescription {
        /// The file, as opened.
        path: String,
        /// What is wrong with it.
        message: String,
    },
    /// A value is outside its allowed range.
    #[error("{field} = {value}: must be {allowed}")]
    Invalid {
        /// Dotted field name, e.g. `control.rate_hz`.
        field: String,
        /// The value found.
        value: String,
        /// The allowed range.
        allowed: String,
    },
}

/// The whole configuration.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    /// Rig geometry.
    pub rig: RigConfig,
    /// Motor-to-wire transmission.
    pub transmission: TransmissionConfig,
    /// Control loop.
    pub control: ControlConfig,
    /// Real-time settings.
    pub realtime: RealtimeConfig,
    /// Wire drives on the CAN bus.
    pub drives: DrivesConfig,
    /// Strain-gauge tension sensors.
    pub sensors: SensorsConfig,
    /// Vision thread and the surface it feeds to the control loop.
    pub vision: VisionConfig,
    /// Per-cycle telemetry log.
    pub telemetry: TelemetryConfig,
    /// Local control socket for the `videt` tool.
    pub socket: SocketConfig,
    /// Wire homing and auto-initialization.
    pub autoinit: AutoInitConfig,
    /// The commissioning check of a newly assembled rig (`videt commission`).
    pub commission: CommissionConfig,
    /// Where the calibration and the motors' lock live.
    pub files: FilesConfig,
    /// The colour under the finger, rendered on the three vibrotactors.
    pub colour: ColourConfig,
    /// The live view for Foxglove (off unless enabled here or by `videtd --live`).
    pub live: LiveConfig,
}

/// How the colour window under the finger is combined into one colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ColourStatistic {
    /// The per-channel median: keeps the majority colour at an edge and ignores speckle.
    Median,
    /// The per-channel mean.
    Mean,
}

/// How the relief spans the gaps between the matched 3-D segments (`vision.relief_shape`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ReliefShapeName {
    /// The paper's surface: the height interpolated linearly between the segments, across
    /// depth steps too (a ramp where the scene has a cliff), and down to the back plane at the
    /// border of the area.
    Interpolated,
    /// Depth steps kept as steps (a wall the finger can follow, at the nearer side of an
    /// occluding edge) and the border of the area at the height of what is near it.
    Stepped,
}

/// The space the colour thresholds apply in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ColourSpaceName {
    /// Chromaticity times the brightness stretched from `black_level` to `white_level`: the
    /// levels follow the hue and the lighting matters less.
    Chromaticity,
    /// The camera's RGB values as they are.
    Rgb,
}

/// The colour under the finger: sampling, Low/Mid/High thresholds and the vibration pattern.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ColourConfig {
    /// Render the colour on the vibrotactors at all.
    pub enabled: bool,
    /// Side of the square window sampled under the finger, pixels: odd, 1 to 31.
    pub window_px: u32,
    /// How the window is combined.
    pub statistic: ColourStatistic,
    /// The space the thresholds apply in.
    pub space: ColourSpaceName,
    /// Chromaticity space: brightest-channel value (0-255) at and below which all is black.
    pub black_level: f64,
    /// Chromaticity space: brightest-channel value (0-255) from which the brightness is full.
    pub white_level: f64,
    /// Channel value (0-255) from which a channel is Mid rather than Low.
    pub low_mid: f64,
    /// Channel value (0-255) from which a channel is High rather than Mid.
    pub mid_high: f64,
    /// Half-width of the dead band around each threshold, channel units.
    pub hysteresis: f64,
    /// Vibration carrier frequency, Hz (the paper's 75).
    pub frequency_hz: f64,
    /// Fraction of each carrier period a vibrotactor is on, for Low, Mid and High.
    pub duty: [f64; 3],
}

impl Default for ColourConfig {
    fn default() -> Self {
        ColourConfig {
            enabled: true,
            window_px: 7,
            statistic: ColourStatistic::Median,
            space: ColourSpaceName::Chromaticity,
            black_level: 32.0,
            white_level: 192.0,
            low_mid: 85.0,
            mid_high: 170.0,
            hysteresis: 8.0,
            frequency_hz: 75.0,
            duty: [0.0, 0.2, 0.5],
        }
    }
}

/// The commissioning check of a newly assembled rig, thimble detached (`videt commission`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CommissionConfig {
    /// The tension each drive's test torque holds a wire at against its stop, N (the torque
    /// is the most any motor gets during the check; 0.5..=5, at most `control.t_max_n`).
    pub test_tension_n: f64,
    /// How far the technician pulls each wire out to the mark when its encoder is checked,
    /// metres (0.03..=0.5).
    pub pull_out_m: f64,
    /// A wire moving faster than this during a test has its torque cut, m/s (0.01..=0.2).
    pub max_speed_m_s: f64,
}

impl Default for CommissionConfig {
    fn default() -> Self {
        CommissionConfig {
            test_tension_n: 2.0,
            pull_out_m: 0.1,
            max_speed_m_s: 0.05,
        }
    }
}

/// Wire homing and auto-initialization (`videt init`, `videt wire replace`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AutoInitConfig {
    /// Target winding speed, m/s (at most `control.max_wire_speed_m_s`).
    pub wind_speed_m_s: f64,
    /// Largest tension a winding wire is pulled with, N (at most `control.t_max_n`).
    pub wind_tension_max_n: f64,
    /// Tension of the wires that pay out, N (at least `control.t_min_n`).
    pub pay_out_tension_n: f64,
    /// Largest disagreement of the two measurements of one side, metres.
    pub side_tolerance_m: f64,
    /// Shortest base-triangle side accepted, metres.
    pub min_side_m: f64,
    /// Longest a wire may be during the procedure (before its winding homed it: pay out), metres.
    pub max_length_m: f64,
    /// Shortest winding that counts as movement (a connected wire), metres.
    pub min_travel_m: f64,
    /// Longest travel of one homing or winding before the wire counts as broken or slipping, metres.
    pub max_wind_travel_m: f64,
    /// Longest a homing or one winding may take, seconds.
    pub stage_timeout_s: f64,
    /// Workspace: force the wires must render towards the frame, N.
    pub workspace_force_n: f64,
    /// Workspace: largest condition number of the force map.
    pub workspace_max_condition: f64,
    /// Workspace: nearest plane in front of the frame, metres.
    pub workspace_z_min_m: f64,
    /// Workspace: farthest plane in front of the frame, metres.
    pub workspace_z_max_m: f64,
    /// Length every wire must be usable beyond the workspace's longest, metres.
    pub wire_length_margin_m: f64,
}

impl Default for AutoInitConfig {
    fn default() -> Self {
        AutoInitConfig {
            wind_speed_m_s: 0.08,
            wind_tension_max_n: 3.0,
            pay_out_tension_n: 0.4,
            side_tolerance_m: 0.002,
            min_side_m: 0.05,
            max_length_m: 1.2,
            min_travel_m: 0.02,
            max_wind_travel_m: 2.0,
            stage_timeout_s: 30.0,
            workspace_force_n: 3.0,
            workspace_max_condition: 20.0,
            workspace_z_min_m: 0.10,
            workspace_z_max_m: 0.60,
            wire_length_margin_m: 0.10,
        }
    }
}

/// Files of the service and the tool.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FilesConfig {
    /// The calibration written by `videt init` and read by `videtd`.
    pub calibration: String,
    /// The lock file that gives one process at a time the motors (`flock`).
    pub motors_lock: String,
}

impl Default for FilesConfig {
    fn default() -> Self {
        FilesConfig {
            calibration: "/var/lib/videt/calibration.toml".to_string(),
            motors_lock: "/run/videt/motors.lock".to_string(),
        }
    }
}

/// The CiA 402 wire drives.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DrivesConfig {
    /// SocketCAN interface name.
    pub can_interface: String,
    /// CANopen node ids of the drives of wires 0, 1, 2 (1..=127): which drive moves which
    /// wire. Drives whose ids are on the wrong wires are fixed by reordering this list.
    pub node_ids: [u8; 3],
    /// Per wire (in wire order): the motor turns the other way, so a positive torque unwinds
    /// the wire instead of winding it (a motor mounted mirrored, or the yarn wound the other
    /// way round the pulley). The driver negates the wire's torque (CiA 402 defines no torque
    /// polarity). A yarn wound the other way reverses the encoder too (`encoder_reversed`).
    pub motor_reversed: [bool; 3],
    /// Per wire: the encoder counts down as the wire winds in (its channels swapped, or the
    /// yarn wound the other way). Written to the drive's polarity (0x607E, position and
    /// velocity) where it has that object; negated by the driver where it does not.
    pub encoder_reversed: [bool; 3],
    /// Motor rated torque (CiA 402 object 0x6076), N·m: target torque is in per-mille of it.
    /// With `device_description` giving it, the file's value is used and this, when set, must
    /// agree with it within 1 %.
    pub rated_torque_nm: f64,
    /// The drives' CANopen device description: the EDS, or better the DCF their commissioning
    /// tool exported (it holds the configured values). When given, the rated torque (0x6076),
    /// the encoder resolution, the gear and the drives' position and velocity units come from
    /// it (`drives.rated_torque_nm`, `transmission.counts_per_motor_rev` and
    /// `transmission.gear_ratio` set here too must agree within 1 %). A relative path is
    /// relative to the configuration file's directory (to the working directory for a
    /// configuration not read from a file).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub device_description: Option<String>,
    /// What `device_description` gave, read on load (not a key of the file).
    #[serde(skip)]
    pub description: Option<DeviceDescription>,
    /// Heartbeat period the drives produce, milliseconds.
    pub heartbeat_ms: u16,
    /// A drive silent for this long is a fault, milliseconds.
    pub heartbeat_timeout_ms: u16,
    /// How long each drive tolerates the service's silence before it disables itself (its
    /// heartbeat consumer, 0x1016), milliseconds (20..=10000; the service's heartbeat is sent
    /// every 10 ms).
    pub host_silence_timeout_ms: u16,
    /// Time each drive is given to answer an SDO request while it is configured,
    /// milliseconds (10..=5000). Drives that store parameters in flash as they are written
    /// answer slower.
    pub sdo_timeout_ms: u32,
    /// Consecutive periods a drive's process data may be missing before it is a fault (0: the
    /// first missing period is). With 1 the drives power off within two periods of a drive
    /// going silent; a bus or computer that delays answers now and then needs more.
    pub max_missed_cycles: u32,
    /// Part of the control period the host waits after SYNC for the drives' process data
    /// (0.1..=0.95); the rest of the period is the control step's and the set-points'. Data
    /// that comes later counts as missing that period (`max_missed_cycles`). Drives slow to
    /// answer, or a bus whose answers take long (`videtd` logs how long one period's process
    /// data takes on the bus), need more.
    pub pdo_wait_fraction: f64,
    /// Time each drive's power state machine is given to reach its goal (enabled when the
    /// service starts, disabled when it stops), milliseconds (10..=10000). Drives that charge
    /// a large DC link or release a brake first need more.
    pub power_timeout_ms: u32,
    /// Bit rate of the CAN bus, bit/s: one of CiA 301's 10000, 20000, 50000, 125000, 250000,
    /// 500000, 800000, 1000000.
    pub bitrate: u32,
    /// The largest share of the bus the drives' traffic may take, counted with every possible
    /// stuff bit (0.1..=0.95): a configuration whose control rate needs more is refused.
    pub max_bus_load: f64,
}

/// CiA 301's CAN bit rates, bit/s.
pub const CAN_BITRATES: [u32; 8] = [
    10_000, 20_000, 50_000, 125_000, 250_000, 500_000, 800_000, 1_000_000,
];

/// Which ADC reads the strain gauges.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TensionAdc {
    /// HX711 on GPIO clock/data lines.
    Hx711,
    /// ADS1220 on SPI.
    Ads1220,
    /// The load-cell amplifier wired into each wire drive's analog input, read in TPDO1 at
    /// every SYNC (object `drive_analog_index`/`drive_analog_subindex`).
    Drive,
}

/// The level of a digital input line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LineLevel {
    /// Low (0).
    Low,
    /// High (1).
    High,
}

impl LineLevel {
    /// Its name in the configuration file: `low` or `high`.
    pub fn name(self) -> &'static str {
        match self {
            LineLevel::Low => "low",
            LineLevel::High => "high",
        }
    }

    /// The other level.
    pub fn other(self) -> LineLevel {
        match self {
            LineLevel::Low => LineLevel::High,
            LineLevel::High => LineLevel::Low,
        }
    }
}

/// The ADS1220's operating mode (its data rates depend on it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Ads1220Mode {
    /// Normal mode: 20, 45, 90, 175, 330, 600, 1000 samples/s.
    Normal,
    /// Turbo mode (modulator clock doubled): 40, 90, 180, 350, 660, 1200, 2000 samples/s.
    Turbo,
}

/// The ADS1220's data rates in normal mode, samples/s (register 1 DR code = index).
pub const ADS1220_NORMAL_SPS: [u32; 7] = [20, 45, 90, 175, 330, 600, 1000];
/// The ADS1220's data rates in turbo mode, samples/s (register 1 DR code = index).
pub const ADS1220_TURBO_SPS: [u32; 7] = [40, 90, 180, 350, 660, 1200, 2000];
/// The HX711's data rates, samples/s (its RATE pin).
pub const HX711_SPS: [u32; 2] = [10, 80];

/// Strain-gauge tension sensors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorsConfig {
    /// ADC type.
    pub adc: TensionAdc,
    /// Conversions per second of each converter: the HX711's 10 or 80 as its RATE pin is
    /// wired; the ADS1220's data rate in `ads1220_mode`. Unused with `adc = "drive"` (the
    /// drives sample their input at every SYNC).
    pub sample_rate_sps: u32,
    /// ADS1220: normal or turbo mode.
    pub ads1220_mode: Ads1220Mode,
    /// A tension sample older than this is stale, milliseconds.
    pub stale_after_ms: u16,
    /// GPIO chip device of the e-stop and vibrotactor lines.
    pub gpio_chip: String,
    /// GPIO line of the e-stop input.
    pub estop_line: u32,
    /// The e-stop line's level while the button is pressed: "low" (a normally-closed button
    /// to a pulled-up input, the default: a broken wire reads as pressed) or "high".
    pub estop_pressed_level: LineLevel,
    /// GPIO lines of the three vibrotactors (red, green, blue channels).
    pub vibrotactor_lines: [u32; 3],
    /// ADS1220: the spidev device of each wire's converter.
    pub spi_devices: [String; 3],
    /// ADS1220: the GPIO line (on `gpio_chip`) of each converter's data-ready output.
    pub drdy_lines: [u32; 3],
    /// HX711: the GPIO line of each converter's clock (`PD_SCK`).
    pub hx711_clock_lines: [u32; 3],
    /// HX711: the GPIO line of each converter's data output (`DOUT`).
    pub hx711_data_lines: [u32; 3],
    /// Drive: the object index of each drive's 16-bit signed analog input (the same on every
    /// drive), mapped into TPDO1 after the position and the statusword (the velocity is then
    /// derived from the positions). Default: CiA 401 "read analog input 16-bit"
    /// 0x6401.
    pub drive_analog_index: u16,
    /// Drive: the subindex of the analog input object (default 1: the first input).
    pub drive_analog_subindex: u8,
    /// Raw reading of each wire's converter at zero tension, counts (nominal: the tension
    /// calibration written by `videt tension-calibrate` corrects what remains). A drive's
    /// analog input is 16-bit: -32768..=32767.
    pub zero_counts: [i32; 3],
    /// Newtons per raw count of each wire's converter (nominal, from the load cell's rated
    /// output; negative for a bridge wired inverted). A 50 N, 2 mV/V cell gives 2.33e-5 on the
    /// ADS1220 at gain 128 and 1.16e-5 on the HX711 at gain 128 with a 5 V supply; through a
    /// drive, the amplifier's newtons per volt times the volts per count of the drive's input
    /// (e.g. 0.005 for 50 N over 10 V read in millivolts).
    pub newtons_per_count: [f64; 3],
}

/// Vision thread.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VisionConfig {
    /// Left and right V4L2 devices.
    pub devices: [String; 2],
    /// A live surface not renewed for this long is stale, seconds: forces fade out.
    pub surface_max_age_s: f64,
    /// Time over which forces fade on a stale surface, seconds.
    pub surface_fade_s: f64,
    /// The rig's stereo calibration (`videt calibrate-stereo --out FILE`): without it the
    /// device renders the check wall instead of the scene.
    pub stereo_calibration: String,
    /// Time between two whole-image reliefs built from fresh camera frames while the finger is
    /// not over the scene, seconds.
    pub rebuild_period_s: f64,
    /// Time between two whole-image reliefs while the finger is over the scene, seconds: every
    /// frame in between re-matches the region under the finger only (fast), and the whole-image
    /// run renews the rest of the relief.
    pub full_refresh_s: f64,
    /// Largest disparity searched in the rectified pair, pixels (sets the nearest depth seen:
    /// focal x baseline / disparity).
    pub max_disparity_px: f64,
    /// Largest capture-time difference of a left and a right frame paired, milliseconds. Two
    /// free-running cameras keep whatever phase they started with: this must exceed half their
    /// frame period (16.7 ms at 30 fps) or they may never pair; hardware-synchronised cameras
    /// can be held to 1-2 ms.
    pub pair_tolerance_ms: f64,
    /// Frame rate asked of the cameras, frames per second (a camera without that rate keeps
    /// its nearest). Every frame is captured; while the finger is over the scene, every frame
    /// updates the relief around it.
    pub frame_rate_hz: u32,
    /// Checks against wrong stereo matches (a wrong match becomes a ridge or a hole in the
    /// relief): match the right image to the left one as well and keep a match only when
    /// both directions agree.
    pub left_right_check: bool,
    /// ... drop a match whose confidence (agreement of its matched neighbours, margin over
    /// other candidates, photometric agreement; 0..1) is below this (0: no threshold).
    pub min_match_confidence: f64,
    /// ... drop a match its matched neighbours contradict (an isolated 3-D segment off the
    /// surface around it).
    pub surface_check: bool,
    /// How the relief built from the cameras spans the gaps between the matched segments:
    /// `stepped` (the default) or `interpolated` (the paper's; docs/stereo-accuracy.md, "Relief
    /// shape").
    pub relief_shape: ReliefShapeName,
    /// Depth from image patches besides the matched segments, pixels: the far side of each
    /// occluding edge, and textured patches matched on a grid this many pixels apart, given to
    /// the relief as points (docs/stereo-accuracy.md, "Depth from patches"); 0: the segments
    /// alone. 12 by default.
    pub patch_spacing_px: u32,
}

/// The default of `vision.patch_spacing_px`: chosen on the shared stereo pairs by the floor of
/// the relief (docs/stereo-accuracy.md, "Depth from patches").
pub const DEFAULT_PATCH_SPACING_PX: u32 = 12;

/// The grid spacings `vision.patch_spacing_px` allows besides 0 (off), pixels.
pub const PATCH_SPACING_RANGE_PX: core::ops::RangeInclusive<u32> = 4..=64;

/// What `vision.patch_spacing_px` allows, as its errors say it.
pub const PATCH_SPACING_ALLOWED: &str = "0 (off) or in [4, 64]";

/// Per-cycle telemetry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TelemetryConfig {
    /// Record every cycle to a session log.
    pub enabled: bool,
    /// Directory of the session logs.
    pub directory: String,
    /// Capacity of the ring from the control thread to the writer, records (a full ring drops).
    pub ring_records: u32,
    /// The directory's session logs together take at most this much, MB (1 MB = 10^6 bytes):
    /// beyond it the oldest finished ones are removed.
    pub max_total_mb: u64,
    /// Finished session logs last modified longer ago than this are removed, days.
    pub max_age_days: u32,
    /// Keep at least this much free on the directory's filesystem, MB: below it the oldest
    /// finished session logs are removed.
    pub min_free_mb: u64,
}

/// The local control socket.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SocketConfig {
    /// Path of the Unix domain socket (mode 0660).
    pub path: String,
    /// Largest request accepted, bytes.
    pub max_request_bytes: u32,
    /// A client that sends nothing for this long is disconnected, milliseconds.
    pub client_timeout_ms: u32,
}

impl Default for DrivesConfig {
    fn default() -> Self {
        DrivesConfig {
            can_interface: "can0".into(),
            node_ids: [1, 2, 3],
            motor_reversed: [false; 3],
            encoder_reversed: [false; 3],
            rated_torque_nm: 0.05,
            device_description: None,
            description: None,
            heartbeat_ms: 10,
            heartbeat_timeout_ms: 50,
            host_silence_timeout_ms: 50,
            sdo_timeout_ms: 100,
            max_missed_cycles: 1,
            pdo_wait_fraction: 0.6,
            power_timeout_ms: 500,
            bitrate: 1_000_000,
            max_bus_load: 0.8,
        }
    }
}

impl Default for SensorsConfig {
    fn default() -> Self {
        SensorsConfig {
            adc: TensionAdc::Ads1220,
            sample_rate_sps: 2000,
            ads1220_mode: Ads1220Mode::Turbo,
            stale_after_ms: 20,
            gpio_chip: "/dev/gpiochip0".into(),
            estop_line: 17,
            estop_pressed_level: LineLevel::Low,
            vibrotactor_lines: [22, 23, 24],
            spi_devices: [
                "/dev/spidev0.0".into(),
                "/dev/spidev0.1".into(),
                "/dev/spidev1.0".into(),
            ],
            drdy_lines: [5, 6, 13],
            hx711_clock_lines: [20, 21, 26],
            hx711_data_lines: [16, 19, 12],
            drive_analog_index: 0x6401,
            drive_analog_subindex: 1,
            zero_counts: [0; 3],
            newtons_per_count: [2.33e-5; 3],
        }
    }
}

impl Default for VisionConfig {
    fn default() -> Self {
        VisionConfig {
            devices: ["/dev/video0".into(), "/dev/video2".into()],
            surface_max_age_s: 2.0,
            surface_fade_s: 0.5,
            stereo_calibration: "/etc/videt/stereo.json".into(),
            rebuild_period_s: 0.2,
            full_refresh_s: 10.0,
            max_disparity_px: 64.0,
            pair_tolerance_ms: 20.0,
            frame_rate_hz: 30,
            left_right_check: false,
            min_match_confidence: 0.0,
            surface_check: false,
            relief_shape: ReliefShapeName::Stepped,
            patch_spacing_px: DEFAULT_PATCH_SPACING_PX,
        }
    }
}

impl Default for TelemetryConfig {
    fn default() -> Self {
        TelemetryConfig {
            enabled: true,
            directory: "/var/log/videt".into(),
            ring_records: 16384,
            max_total_mb: 4096,
            max_age_days: 30,
            min_free_mb: 1024,
        }
    }
}

/// The live view: the device's topics served over the Foxglove WebSocket protocol, read-only.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LiveConfig {
    /// Serve the live view.
    pub enabled: bool,
    /// Address and port to listen on. Loopback by default: another machine reaches it only
    /// when an address of the machine's network is given (or through an SSH tunnel).
    pub address: String,
    /// How often the live view samples the control loop and sends, hertz.
    pub rate_hz: f64,
    /// Messages queued per client before the oldest are dropped (a slow client loses
    /// messages; nothing waits for it).
    pub client_backlog: u32,
}

impl Default for LiveConfig {
    fn default() -> Self {
        LiveConfig {
            enabled: false,
            address: "127.0.0.1:8765".into(),
            rate_hz: 30.0,
            client_backlog: 256,
        }
    }
}

impl LiveConfig {
    /// The listening address as host and port, or why `address` is not one.
    pub fn host_port(&self) -> Result<(String, u16), ConfigError> {
        parse_host_port(&self.address).ok_or_else(|| ConfigError::Invalid {
            field: "live.address".into(),
            value: self.address.clone(),
            allowed: "HOST:PORT (an IPv4 address, [IPv6] or a host name, and a port 0-65535)"
                .into(),
        })
    }
}

/// `HOST:PORT`, `[IPv6]:PORT`: the host (brackets removed) and the port.
fn parse_host_port(text: &str) -> Option<(String, u16)> {
    let (host, port) = text.rsplit_once(':')?;
    let port = port.parse().ok()?;
    let host = match host.strip_prefix('[') {
        Some(inner) => inner.strip_suffix(']')?,
        None if host.contains(':') => return None,
        None => host,
    };
    (!host.is_empty() && !host.contains(char::is_whitespace)).then(|| (host.to_string(), port))
}

impl Default for SocketConfig {
    fn default() -> Self {
        SocketConfig {
            path: "/run/videt/videtd.sock".into(),
            max_request_bytes: 4096,
            client_timeout_ms: 2000,
        }
    }
}

/// Rig geometry (used until an auto-initialization calibration is available).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RigConfig {
    /// The device: `"wireman3"` (the wearable three-wire WireMan), `"planar2"` (the planar
    /// two-wire prototype), `"polar1"` (one wire and two passive angle sensors) or `"spidar4"`
    /// (four wires around the workspace).
    pub device: String,
    /// `wireman3`: guide points in the frame plane `z = 0`, metres, as `[x, y]` pairs.
    pub guides_m: [[f64; 2]; 3],
    /// `planar2`: the two guides' positions on the x axis, metres (the paper's prototype:
    /// 0 and 0.52).
    pub planar_guides_x_m: [f64; 2],
    /// `polar1`: the wire's guide point, metres, `[x, y, z]`.
    pub polar_guide_m: [f64; 3],
    /// `spidar4`: the four guide points, metres, `[x, y, z]` each, not in one plane.
    pub spidar_guides_m: [[f64; 3]; 4],
}

/// The device names `rig.device` accepts.
pub const RIG_DEVICES: [&str; 4] = ["wireman3", "planar2", "polar1", "spidar4"];

/// Motor-to-wire transmission of every wire module.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TransmissionConfig {
    /// Encoder counts per motor revolution (500 lines x4 = 2000).
    pub counts_per_motor_rev: u32,
    /// Gear reduction (motor turns per pulley turn).
    pub gear_ratio: f64,
    /// Pulley radius, metres.
    pub pulley_radius_m: f64,
    /// Gear efficiency in (0, 1].
    pub efficiency: f64,
    /// Axial stiffness `EA` of the wire, newtons (Kevlar yarn: about 3 % strain at 250 N, so
    /// 8000 N). The control corrects the encoders' lengths for the wires' stretch with it, and
    /// the twin's wires stretch by it.
    pub wire_ea_n: f64,
    /// Wire inside each module, from the pulley to the guide ring, metres: it stretches in series
    /// with the wire outside.
    pub inside_wire_m: f64,
}

/// Control loop settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControlConfig {
    /// Loop rate, Hz (1000..=10000).
    pub rate_hz: u32,
    /// Contact stiffness, N/m.
    pub stiffness_n_per_m: f64,
    /// Contact damping, N·s/m.
    pub damping_n_s_per_m: f64,
    /// Control algorithm: `P1`, `P2` (the paper's projections), `F1`, `F2` (with a force field
    /// `field_n`), `QP` (bisector field, then the closest reachable force).
    pub algorithm: String,
    /// Magnitude of the force field `f_c` of F1, F2 and QP, N (0 for P1 and P2).
    pub field_n: f64,
    /// Gravity-like pull in free space when the algorithm has no field, N (keeps every wire
    /// taut while the finger moves freely; 0 = wires simply held at `t_min`).
    pub free_space_field_n: f64,
    /// Minimum wire tension, N.
    pub t_min_n: f64,
    /// Maximum wire tension, N (the device's limit is 15 N).
    pub t_max_n: f64,
    /// Largest wire speed before the safety supervisor stops rendering, m/s (device: 0.8).
    pub max_wire_speed_m_s: f64,
    /// Tension loop proportional gain, N·m per N.
    pub tension_kp_nm_per_n: f64,
    /// Correct the encoders' wire lengths for the wires' stretch under the tensions commanded
    /// (`transmission.wire_ea_n`, `transmission.inside_wire_m`). Off, a wall renders softer
    /// than programmed by the wires' stiffness in series (6 % at 2000 N/m).
    pub stretch_compensation: bool,
    /// Tension loop integral gain, N·m per N·s.
    pub tension_ki_nm_per_n_s: f64,
    /// The tension loop's integral learns the static error while the wire is nearly still: its
    /// rate falls linearly with the wire's speed and stops at this speed, m/s. Learning at any
    /// speed, the integral also cancels the transmission's friction and inertia while the finger
    /// moves, the damping a stiff wall's stability rests on (`docs/haptic-bench.md`, Z-width).
    /// 0: the integral learns at any speed.
    pub tension_integral_speed_gate_m_s: f64,
    /// Run the tension loop with reduced gains when the tension sensor is too slow for the
    /// configured ones (`videt config check` says by how much, and the service logs it and
    /// shows it in its status). `false`: such a configuration is refused.
    pub allow_degraded_tension_loop: bool,
    /// Time over which tensions ramp down to `t_min` on shutdown, seconds.
    pub ramp_down_s: f64,
    /// Winding speed at which a slack wire is taken up, m/s (slow enough that it does not snap
    /// taut with a tension spike).
    pub slack_takeup_speed_m_s: f64,
    /// Gain of the wire-speed loop (slack take-up and the winding-speed limit), N·m per m/s.
    pub speed_gain_nm_s_per_m: f64,
}

/// Real-time process settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RealtimeConfig {
    /// SCHED_FIFO priority of the control thread (1..=99).
    pub control_priority: u8,
    /// CPU the control thread is pinned to (`-1` = no pinning).
    pub control_cpu: i32,
    /// Lock all memory (`mlockall`).
    pub lock_memory: bool,
    /// SCHED_FIFO priority of the vision thread (0 = SCHED_OTHER).
    pub vision_priority: u8,
    /// CPU wake-up latency limit held while the service runs (PM QoS `/dev/cpu_dma_latency`),
    /// microseconds: 0 keeps the CPUs out of idle states that are slow to leave; -1 = no limit.
    pub cpu_wakeup_latency_us: i32,
    /// This many control-loop overruns in a row force the minimum-tension safe state.
    pub max_consecutive_overruns: u32,
}

impl Default for RigConfig {
    fn default() -> Self {
        // A frame of the paper's size (370 mm x 300 mm).
        RigConfig {
            device: "wireman3".into(),
            guides_m: [[0.0, 0.0], [0.37, 0.0], [0.185, 0.30]],
            planar_guides_x_m: [0.0, 0.52],
            polar_guide_m: [0.0, 0.0, 0.0],
            // Four alternating corners of a 0.6 m cube around the WireMan's workspace.
            spidar_guides_m: [
                [-0.1, -0.15, 0.0],
                [0.5, 0.45, 0.0],
                [0.5, -0.15, 0.6],
                [-0.1, 0.45, 0.6],
            ],
        }
    }
}

impl Default for TransmissionConfig {
    fn default() -> Self {
        TransmissionConfig {
            counts_per_motor_rev: 2000,
            gear_ratio: 25.0,
            pulley_radius_m: 0.020,
            efficiency: 1.0,
            wire_ea_n: 8000.0,
            inside_wire_m: 0.12,
        }
    }
}

impl Default for ControlConfig {
    fn default() -> Self {
        ControlConfig {
            rate_hz: 1000,
            stiffness_n_per_m: 2000.0,
            damping_n_s_per_m: 5.0,
            algorithm: "P2".to_string(),
            field_n: 0.0,
            free_space_field_n: 0.5,
            t_min_n: 0.3,
            t_max_n: 15.0,
            max_wire_speed_m_s: 0.8,
            tension_kp_nm_per_n: 0.0004,
            stretch_compensation: true,
            tension_ki_nm_per_n_s: 0.04,
            tension_integral_speed_gate_m_s: 0.003,
            allow_degraded_tension_loop: false,
            ramp_down_s: 0.5,
            slack_takeup_speed_m_s: 0.15,
            speed_gain_nm_s_per_m: 0.002,
        }
    }
}

impl Default for RealtimeConfig {
    fn default() -> Self {
        RealtimeConfig {
            control_priority: 80,
            control_cpu: 1,
            lock_memory: true,
            vision_priority: 0,
            cpu_wakeup_latency_us: 0,
            max_consecutive_overruns: 10,
        }
    }
}

impl Config {
    /// Parse and validate TOML text; `origin` names the source in errors. A relative
    /// `drives.device_description` is read from the working directory.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Config, ConfigError> {
        Config::from_toml_str_at(text, origin, None)
    }

    /// Parse and validate TOML text; `origin` names the source in errors. A relative
    /// `drives.device_description` is read from `base_dir` when given (the configuration
    /// file's directory), else from the working directory.
    pub fn from_toml_str_at(
        text: &str,
        origin: &str,
        base_dir: Option<&Path>,
    ) -> Result<Config, ConfigError> {
        let mut config: Config = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: origin.to_string(),
            message: e.to_string(),
        })?;
        let explicit = drive_units::ExplicitUnits::of(text);
        drive_units::apply(&mut config, base_dir, explicit)?;
        config.validate()?;
        Ok(config)
    }

    /// Read, parse and validate a file (and the device description it names, relative to its
    /// directory).
    pub fn load(path: &Path) -> Result<Config, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let dir = path
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        Config::from_toml_str_at(&text, &path.display().to_string(), Some(dir))
    }
}

#[cfg(test)]
mod tests;
