//! # videt-rt-config — the daemon's configuration
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
    /// Where the calibration and the motors' lock live.
    pub files: FilesConfig,
    /// The colour under the finger, rendered on the three vibrotactors.
    pub colour: ColourConfig,
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
    /// CANopen node ids of the drives of wires 0, 1, 2 (1..=127).
    pub node_ids: [u8; 3],
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
    /// Consecutive periods a drive's process data may be missing before it is a fault (0: the
    /// first missing period is). With 1 the drives power off within two periods of a drive
    /// going silent; a bus or computer that delays answers now and then needs more.
    pub max_missed_cycles: u32,
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
    /// GPIO line of the (active-low) e-stop input.
    pub estop_line: u32,
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
    /// Time between two reliefs built from fresh camera frames, seconds.
    pub rebuild_period_s: f64,
    /// Largest disparity searched in the rectified pair, pixels (sets the nearest depth seen:
    /// focal x baseline / disparity).
    pub max_disparity_px: f64,
    /// Largest capture-time difference of a left and a right frame paired, milliseconds. Two
    /// free-running cameras keep whatever phase they started with: this must exceed half their
    /// frame period (16.7 ms at 30 fps) or they may never pair; hardware-synchronised cameras
    /// can be held to 1-2 ms.
    pub pair_tolerance_ms: f64,
    /// Frame rate asked of the cameras, frames per second (a camera without that rate keeps
    /// its nearest; the relief is rebuilt every `rebuild_period_s` from the newest pair).
    pub frame_rate_hz: u32,
}

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
            rated_torque_nm: 0.05,
            device_description: None,
            description: None,
            heartbeat_ms: 10,
            heartbeat_timeout_ms: 50,
            max_missed_cycles: 1,
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
            max_disparity_px: 64.0,
            pair_tolerance_ms: 20.0,
            frame_rate_hz: 30,
        }
    }
}

impl Default for TelemetryConfig {
    fn default() -> Self {
        TelemetryConfig {
            enabled: true,
            directory: "/var/log/videt".into(),
            ring_records: 16384,
        }
    }
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
    /// Guide points in the frame plane `z = 0`, metres, as `[x, y]` pairs.
    pub guides_m: [[f64; 2]; 3],
}

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
    /// Tension loop integral gain, N·m per N·s.
    pub tension_ki_nm_per_n_s: f64,
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
            guides_m: [[0.0, 0.0], [0.37, 0.0], [0.185, 0.30]],
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
        }
    }
}

impl Default for ControlConfig {
    fn default() -> Self {
        ControlConfig {
            rate_hz: 1000,
            stiffness_n_per_m: 800.0,
            damping_n_s_per_m: 5.0,
            algorithm: "P2".to_string(),
            field_n: 0.0,
            free_space_field_n: 0.5,
            t_min_n: 0.3,
            t_max_n: 15.0,
            max_wire_speed_m_s: 0.8,
            tension_kp_nm_per_n: 0.0004,
            tension_ki_nm_per_n_s: 0.04,
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

/// Check that `value` lies in `[lo, hi]` (and is finite), naming `field` otherwise.
fn in_range(field: &str, value: f64, lo: f64, hi: f64) -> Result<(), ConfigError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(ConfigError::Invalid {
            field: field.to_string(),
            value: value.to_string(),
            allowed: format!("in [{lo}, {hi}]"),
        })
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

    /// Check every value against its allowed range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        for (i, g) in self.rig.guides_m.iter().enumerate() {
            for (axis, v) in ["x", "y"].iter().zip(g) {
                in_range(&format!("rig.guides_m[{i}].{axis}"), *v, -2.0, 2.0)?;
            }
        }
        let t = &self.transmission;
        if !(1..=1_000_000).contains(&t.counts_per_motor_rev) {
            return Err(ConfigError::Invalid {
                field: "transmission.counts_per_motor_rev".into(),
                value: t.counts_per_motor_rev.to_string(),
                allowed: "in [1, 1000000]".into(),
            });
        }
        in_range("transmission.gear_ratio", t.gear_ratio, 1.0, 1000.0)?;
        in_range(
            "transmission.pulley_radius_m",
            t.pulley_radius_m,
            0.001,
            0.2,
        )?;
        in_range("transmission.efficiency", t.efficiency, 0.05, 1.0)?;
        let c = &self.control;
        in_range("control.rate_hz", c.rate_hz as f64, 1000.0, 10000.0)?;
        in_range(
            "control.stiffness_n_per_m",
            c.stiffness_n_per_m,
            0.0,
            20000.0,
        )?;
        in_range("control.damping_n_s_per_m", c.damping_n_s_per_m, 0.0, 100.0)?;
        if !["P1", "P2", "F1", "F2", "QP"].contains(&c.algorithm.as_str()) {
            return Err(ConfigError::Invalid {
                field: "control.algorithm".into(),
                value: c.algorithm.clone(),
                allowed: "one of P1, P2, F1, F2, QP".into(),
            });
        }
        in_range("control.t_max_n", c.t_max_n, 0.5, 15.0)?;
        in_range("control.t_min_n", c.t_min_n, 0.05, c.t_max_n)?;
        in_range("control.field_n", c.field_n, 0.0, c.t_max_n)?;
        in_range(
            "control.free_space_field_n",
            c.free_space_field_n,
            0.0,
            c.t_max_n,
        )?;
        in_range(
            "control.max_wire_speed_m_s",
            c.max_wire_speed_m_s,
            0.01,
            0.8,
        )?;
        in_range(
            "control.tension_kp_nm_per_n",
            c.tension_kp_nm_per_n,
            0.0,
            0.1,
        )?;
        in_range(
            "control.tension_ki_nm_per_n_s",
            c.tension_ki_nm_per_n_s,
            0.0,
            10.0,
        )?;
        in_range("control.ramp_down_s", c.ramp_down_s, 0.0, 10.0)?;
        in_range(
            "control.slack_takeup_speed_m_s",
            c.slack_takeup_speed_m_s,
            0.01,
            0.5 * c.max_wire_speed_m_s,
        )?;
        in_range(
            "control.speed_gain_nm_s_per_m",
            c.speed_gain_nm_s_per_m,
            0.0,
            1.0,
        )?;
        in_range(
            "realtime.control_priority",
            self.realtime.control_priority as f64,
            1.0,
            99.0,
        )?;
        self.validate_autoinit()?;
        self.validate_colour()?;
        for (field, path) in [
            ("files.calibration", &self.files.calibration),
            ("files.motors_lock", &self.files.motors_lock),
        ] {
            if path.is_empty() || path.ends_with('/') {
                return Err(ConfigError::Invalid {
                    field: field.into(),
                    value: format!("{path:?}"),
                    allowed: "a file path".into(),
                });
            }
        }
        in_range(
            "realtime.control_cpu",
            self.realtime.control_cpu as f64,
            -1.0,
            1023.0,
        )?;
        let rt = &self.realtime;
        let vision_max = (f64::from(rt.control_priority) - 1.0).max(0.0);
        in_range(
            "realtime.vision_priority",
            f64::from(rt.vision_priority),
            0.0,
            vision_max,
        )?;
        in_range(
            "realtime.cpu_wakeup_latency_us",
            f64::from(rt.cpu_wakeup_latency_us),
            -1.0,
            10000.0,
        )?;
        in_range(
            "realtime.max_consecutive_overruns",
            f64::from(rt.max_consecutive_overruns),
            1.0,
            10000.0,
        )?;
        let d = &self.drives;
        if d.can_interface.is_empty() || d.can_interface.len() > 15 {
            return Err(ConfigError::Invalid {
                field: "drives.can_interface".into(),
                value: d.can_interface.clone(),
                allowed: "an interface name of 1 to 15 characters".into(),
            });
        }
        for (i, id) in d.node_ids.iter().enumerate() {
            in_range(&format!("drives.node_ids[{i}]"), f64::from(*id), 1.0, 127.0)?;
        }
        if d.node_ids[0] == d.node_ids[1]
            || d.node_ids[0] == d.node_ids[2]
            || d.node_ids[1] == d.node_ids[2]
        {
            return Err(ConfigError::Invalid {
                field: "drives.node_ids".into(),
                value: format!("{:?}", d.node_ids),
                allowed: "three different node ids".into(),
            });
        }
        in_range("drives.rated_torque_nm", d.rated_torque_nm, 1e-4, 10.0)?;
        in_range(
            "drives.heartbeat_ms",
            f64::from(d.heartbeat_ms),
            1.0,
            1000.0,
        )?;
        let hb_min = 2.0 * f64::from(d.heartbeat_ms);
        in_range(
            "drives.heartbeat_timeout_ms",
            f64::from(d.heartbeat_timeout_ms),
            hb_min,
            10000.0,
        )?;
        in_range(
            "drives.max_missed_cycles",
            f64::from(d.max_missed_cycles),
            0.0,
            100.0,
        )?;
        if !CAN_BITRATES.contains(&d.bitrate) {
            return Err(ConfigError::Invalid {
                field: "drives.bitrate".into(),
                value: d.bitrate.to_string(),
                allowed: format!("one of {CAN_BITRATES:?} (bit/s)"),
            });
        }
        in_range("drives.max_bus_load", d.max_bus_load, 0.1, 0.95)?;
        self.validate_drive_units()?;
        in_range(
            "sensors.stale_after_ms",
            f64::from(self.sensors.stale_after_ms),
            1.0,
            1000.0,
        )?;
        self.validate_sensors()?;
        in_range(
            "vision.surface_max_age_s",
            self.vision.surface_max_age_s,
            0.05,
            60.0,
        )?;
        in_range(
            "vision.surface_fade_s",
            self.vision.surface_fade_s,
            0.0,
            10.0,
        )?;
        if self.vision.stereo_calibration.is_empty() {
            return Err(ConfigError::Invalid {
                field: "vision.stereo_calibration".into(),
                value: String::new(),
                allowed: "a file path".into(),
            });
        }
        in_range(
            "vision.rebuild_period_s",
            self.vision.rebuild_period_s,
            0.02,
            10.0,
        )?;
        in_range(
            "vision.max_disparity_px",
            self.vision.max_disparity_px,
            1.0,
            1000.0,
        )?;
        in_range(
            "vision.pair_tolerance_ms",
            self.vision.pair_tolerance_ms,
            0.1,
            100.0,
        )?;
        in_range(
            "vision.frame_rate_hz",
            f64::from(self.vision.frame_rate_hz),
            1.0,
            240.0,
        )?;
        in_range(
            "telemetry.ring_records",
            f64::from(self.telemetry.ring_records),
            64.0,
            4_194_304.0,
        )?;
        if self.socket.path.is_empty() {
            return Err(ConfigError::Invalid {
                field: "socket.path".into(),
                value: String::new(),
                allowed: "a file path".into(),
            });
        }
        in_range(
            "socket.max_request_bytes",
            f64::from(self.socket.max_request_bytes),
            64.0,
            1_048_576.0,
        )?;
        in_range(
            "socket.client_timeout_ms",
            f64::from(self.socket.client_timeout_ms),
            10.0,
            600_000.0,
        )?;
        Ok(())
    }
}

impl Config {
    /// The GPIO lines and converter settings of `[sensors]`: every line in use is distinct, and
    /// each converter has a usable device and a plausible nominal scale.
    fn validate_sensors(&self) -> Result<(), ConfigError> {
        let s = &self.sensors;
        if s.gpio_chip.is_empty() {
            return Err(ConfigError::Invalid {
                field: "sensors.gpio_chip".into(),
                value: String::new(),
                allowed: "a GPIO character device path".into(),
            });
        }
        let mut lines: Vec<(String, u32)> = vec![("sensors.estop_line".into(), s.estop_line)];
        let mut named = |field: &str, values: &[u32; 3]| {
            for (i, v) in values.iter().enumerate() {
                lines.push((format!("{field}[{i}]"), *v));
            }
        };
        named("sensors.vibrotactor_lines", &s.vibrotactor_lines);
        let rates: &[u32] = match (s.adc, s.ads1220_mode) {
            (TensionAdc::Hx711, _) => &HX711_SPS,
            (TensionAdc::Ads1220, Ads1220Mode::Normal) => &ADS1220_NORMAL_SPS,
            (TensionAdc::Ads1220, Ads1220Mode::Turbo) => &ADS1220_TURBO_SPS,
            (TensionAdc::Drive, _) => &[],
        };
        if !rates.is_empty() && !rates.contains(&s.sample_rate_sps) {
            return Err(ConfigError::Invalid {
                field: "sensors.sample_rate_sps".into(),
                value: s.sample_rate_sps.to_string(),
                allowed: format!(
                    "one of {rates:?} for this converter (sensors.adc, sensors.ads1220_mode)"
                ),
            });
        }
        match s.adc {
            TensionAdc::Ads1220 => named("sensors.drdy_lines", &s.drdy_lines),
            TensionAdc::Hx711 => {
                named("sensors.hx711_clock_lines", &s.hx711_clock_lines);
                named("sensors.hx711_data_lines", &s.hx711_data_lines);
            }
            TensionAdc::Drive => {}
        }
        for (k, (field, line)) in lines.iter().enumerate() {
            if let Some((other, _)) = lines[..k].iter().find(|(_, l)| l == line) {
                return Err(ConfigError::Invalid {
                    field: field.clone(),
                    value: line.to_string(),
                    allowed: format!("a GPIO line not used already (it is {other})"),
                });
            }
        }
        if s.adc == TensionAdc::Drive {
            if !(0x2000..=0x9FFF).contains(&s.drive_analog_index) {
                return Err(ConfigError::Invalid {
                    field: "sensors.drive_analog_index".into(),
                    value: format!("{:#06x}", s.drive_analog_index),
                    allowed: "in [0x2000, 0x9fff] (a manufacturer or device-profile object)".into(),
                });
            }
            let sub = s.drive_analog_subindex;
            if sub == 0xFF || (s.drive_analog_index == 0x6401 && sub == 0) {
                return Err(ConfigError::Invalid {
                    field: "sensors.drive_analog_subindex".into(),
                    value: sub.to_string(),
                    allowed: "in [0, 254], and in [1, 254] for 0x6401 (its subindex 0 is the \
                              number of inputs)"
                        .into(),
                });
            }
        }
        if s.adc == TensionAdc::Ads1220 {
            for (i, path) in s.spi_devices.iter().enumerate() {
                if path.is_empty() || s.spi_devices[..i].contains(path) {
                    return Err(ConfigError::Invalid {
                        field: format!("sensors.spi_devices[{i}]"),
                        value: format!("{path:?}"),
                        allowed: "a spidev device path, one per wire".into(),
                    });
                }
            }
        }
        // A drive's analog input is a 16-bit value in the drive's own unit (often mV): its
        // counts are coarser than a 24-bit converter's.
        let (counts, scales, allowed) = if s.adc == TensionAdc::Drive {
            (
                (-32_768.0, 32_767.0),
                1e-6..=1.0,
                "between 1e-6 and 1 in magnitude for adc = \"drive\" (negative for an inverted \
                 amplifier)",
            )
        } else {
            (
                (-8_388_608.0, 8_388_607.0),
                1e-9..=1e-2,
                "between 1e-9 and 1e-2 in magnitude (negative for an inverted bridge)",
            )
        };
        for i in 0..3 {
            in_range(
                &format!("sensors.zero_counts[{i}]"),
                f64::from(s.zero_counts[i]),
                counts.0,
                counts.1,
            )?;
            let scale = s.newtons_per_count[i];
            if !(scale.is_finite() && scales.contains(&scale.abs())) {
                return Err(ConfigError::Invalid {
                    field: format!("sensors.newtons_per_count[{i}]"),
                    value: scale.to_string(),
                    allowed: allowed.into(),
                });
            }
        }
        Ok(())
    }

    fn validate_colour(&self) -> Result<(), ConfigError> {
        let c = &self.colour;
        if !(1..=31).contains(&c.window_px) || c.window_px % 2 == 0 {
            return Err(ConfigError::Invalid {
                field: "colour.window_px".into(),
                value: c.window_px.to_string(),
                allowed: "odd, in [1, 31]".into(),
            });
        }
        if c.space == ColourSpaceName::Chromaticity {
            in_range("colour.black_level", c.black_level, 0.0, 254.0)?;
            in_range(
                "colour.white_level",
                c.white_level,
                c.black_level + 1.0,
                255.0,
            )?;
        }
        in_range("colour.low_mid", c.low_mid, 1.0, 254.0)?;
        in_range("colour.mid_high", c.mid_high, c.low_mid + 1.0, 255.0)?;
        let band = (c.mid_high - c.low_mid) / 2.0;
        if !(c.hysteresis >= 0.0 && c.hysteresis < band) {
            return Err(ConfigError::Invalid {
                field: "colour.hysteresis".into(),
                value: c.hysteresis.to_string(),
                allowed: format!(
                    "at least 0 and below half the gap between colour.low_mid and colour.mid_high ({band})"
                ),
            });
        }
        in_range("colour.frequency_hz", c.frequency_hz, 1.0, 1000.0)?;
        let mut lowest = 0.0;
        for (i, &duty) in c.duty.iter().enumerate() {
            in_range(&format!("colour.duty[{i}]"), duty, lowest, 1.0)?;
            lowest = duty;
        }
        Ok(())
    }

    fn validate_autoinit(&self) -> Result<(), ConfigError> {
        let a = &self.autoinit;
        let c = &self.control;
        in_range(
            "autoinit.wind_speed_m_s",
            a.wind_speed_m_s,
            0.005,
            c.max_wire_speed_m_s.min(0.3),
        )?;
        in_range(
            "autoinit.pay_out_tension_n",
            a.pay_out_tension_n,
            c.t_min_n,
            c.t_max_n.min(2.0),
        )?;
        in_range(
            "autoinit.wind_tension_max_n",
            a.wind_tension_max_n,
            a.pay_out_tension_n + 0.5,
            c.t_max_n,
        )?;
        in_range("autoinit.side_tolerance_m", a.side_tolerance_m, 1e-4, 0.02)?;
        in_range("autoinit.min_side_m", a.min_side_m, 0.01, 1.0)?;
        in_range("autoinit.max_length_m", a.max_length_m, 0.1, 5.0)?;
        in_range("autoinit.min_travel_m", a.min_travel_m, 0.001, 0.2)?;
        in_range("autoinit.max_wind_travel_m", a.max_wind_travel_m, 0.01, 5.0)?;
        in_range("autoinit.stage_timeout_s", a.stage_timeout_s, 1.0, 600.0)?;
        in_range(
            "autoinit.workspace_force_n",
            a.workspace_force_n,
            0.0,
            c.t_max_n,
        )?;
        in_range(
            "autoinit.workspace_max_condition",
            a.workspace_max_condition,
            1.0,
            1000.0,
        )?;
        in_range("autoinit.workspace_z_min_m", a.workspace_z_min_m, 0.01, 2.0)?;
        in_range(
            "autoinit.workspace_z_max_m",
            a.workspace_z_max_m,
            a.workspace_z_min_m,
            2.0,
        )?;
        in_range(
            "autoinit.wire_length_margin_m",
            a.wire_length_margin_m,
            0.0,
            1.0,
        )?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_the_example_file_parses() {
        Config::default().validate().unwrap();
        let example = include_str!("../../config/videt.example.toml");
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
    }

    #[test]
    fn errors_name_the_field_value_and_range() {
        let e = Config::from_toml_str("[control]\nrate_hz = 50\n", "t")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("control.rate_hz") && e.contains("50") && e.contains("1000"),
            "{e}"
        );
        let e = Config::from_toml_str("[control]\nt_max_n = 40.0\n", "t")
            .unwrap_err()
            .to_string();
        assert!(e.contains("control.t_max_n") && e.contains("40"), "{e}");
        let e = Config::from_toml_str("[control]\nalgorithm = \"X9\"\n", "t")
            .unwrap_err()
            .to_string();
        assert!(e.contains("control.algorithm") && e.contains("X9"), "{e}");
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
            ("[vision]\nmax_disparity_px = 0.5\n", "vision.max_disparity_px"),
            ("[vision]\npair_tolerance_ms = 0\n", "vision.pair_tolerance_ms"),
            ("[vision]\nframe_rate_hz = 0\n", "vision.frame_rate_hz"),
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
}
