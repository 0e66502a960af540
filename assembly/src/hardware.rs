//! The device itself: its three CiA 402 drives on SocketCAN, its three strain-gauge converters
//! (ADS1220 or HX711 of their own, or the load-cell amplifiers wired into the drives' analog
//! inputs) and its e-stop, put together as the one hardware object the service runs on, on the
//! system's monotonic clock.
//!
//! [`DeviceHardware`] only delegates each capability to the part that has it; the parts are the
//! `drivers` crate's, and [`open_device`] opens them from the configuration, e-stop first.

use core::fmt;
use std::time::Duration;
use videt_runtime::WIREMAN_WIRES;

use videt_config::{Config, TensionAdc};
use videt_drivers::adc::calibration::TensionCalibration;
use videt_drivers::cia402::{AnalogInputObject, DriveSetConfig};
use videt_hal::{
    Clock, DriveSample, EStop, ErrorKind, ErrorType, Lifecycle, LifecycleState, MonoTime,
    TensionSensors, WireDrives,
};

use videt_runtime::rt::SystemClock;

/// Consecutive e-stop readings (one per control period) that make a press: 3 ms at 1 kHz.
pub const ESTOP_DEBOUNCE_SAMPLES: u8 = 3;

/// The device's drives `D`, tension sensors `T` and e-stop `E` as one hardware object.
pub struct DeviceHardware<D, T, E> {
    drives: D,
    tensions: T,
    estop: E,
    clock: SystemClock,
}

impl<D, T, E> fmt::Debug for DeviceHardware<D, T, E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("DeviceHardware").finish_non_exhaustive()
    }
}

impl<D, T, E> DeviceHardware<D, T, E> {
    /// Put the parts together.
    pub fn new(drives: D, tensions: T, estop: E) -> Self {
        DeviceHardware {
            drives,
            tensions,
            estop,
            clock: SystemClock,
        }
    }

    /// The drives, mutably (to ask them for their fault reports before the service starts).
    pub fn drives_mut(&mut self) -> &mut D {
        &mut self.drives
    }
}

/// Hardware whose CiA 402 drives say what they do beside the HAL's readings: each error that
/// puts them into their safe state, and how they started.
pub trait DriveReports {
    /// The queue of each error that puts the drives into their safe state, as it happens.
    fn fault_reports(&mut self) -> rtrb::Consumer<videt_drivers::cia402::DriveError>;
    /// The drives' identities and missing optional objects as of their last configuration.
    fn startup_report(&self) -> videt_drivers::cia402::SharedStartupReport;
}

impl<P: videt_drivers::can::CanPort, const N: usize, T, E> DriveReports
    for DeviceHardware<videt_drivers::cia402::Cia402DriveSet<P, N>, T, E>
{
    fn fault_reports(&mut self) -> rtrb::Consumer<videt_drivers::cia402::DriveError> {
        self.drives.fault_reports()
    }
    fn startup_report(&self) -> videt_drivers::cia402::SharedStartupReport {
        self.drives.startup_report()
    }
}

/// Tells, once per call, one cause of a drive fault not yet told (`None`: nothing new): the
/// supervisor logs it when the loop reports a fault.
pub type FaultCauses = Box<dyn FnMut() -> Option<String> + Send>;

/// The supervisor's reader of a CiA 402 drive set's fault reports
/// ([`videt_drivers::cia402::Cia402DriveSet::fault_reports`]): each call formats one latched
/// error not yet told, for the service's supervisor.
pub fn drive_fault_causes(
    mut reports: rtrb::Consumer<videt_drivers::cia402::DriveError>,
) -> FaultCauses {
    Box::new(move || reports.pop().ok().map(|e| format!("drives: {e}")))
}

/// A failure of one part of [`DeviceHardware`], carrying that part's own error.
#[derive(Debug)]
pub enum DeviceError<DE, TE, EE> {
    /// The drives.
    Drives(DE),
    /// The tension sensors.
    Tensions(TE),
    /// The e-stop.
    EStop(EE),
    /// The device has no passive angle sensors (the WireMan's hardware).
    NoAngleSensors,
}

impl<DE, TE, EE> videt_hal::Error for DeviceError<DE, TE, EE>
where
    DE: videt_hal::Error,
    TE: videt_hal::Error,
    EE: videt_hal::Error,
{
    fn kind(&self) -> ErrorKind {
        match self {
            DeviceError::Drives(e) => e.kind(),
            DeviceError::Tensions(e) => e.kind(),
            DeviceError::EStop(e) => e.kind(),
            DeviceError::NoAngleSensors => ErrorKind::Other,
        }
    }
}

impl<DE: fmt::Display, TE: fmt::Display, EE: fmt::Display> fmt::Display
    for DeviceError<DE, TE, EE>
{
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DeviceError::Drives(e) => write!(f, "drives: {e}"),
            DeviceError::Tensions(e) => write!(f, "{e}"),
            DeviceError::EStop(e) => write!(f, "e-stop: {e}"),
            DeviceError::NoAngleSensors => f.write_str("the device has no passive angle sensors"),
        }
    }
}

impl<DE, TE, EE> std::error::Error for DeviceError<DE, TE, EE>
where
    DE: fmt::Debug + fmt::Display,
    TE: fmt::Debug + fmt::Display,
    EE: fmt::Debug + fmt::Display,
{
}

impl<D: ErrorType, T: ErrorType, E: ErrorType> ErrorType for DeviceHardware<D, T, E> {
    type Error = DeviceError<D::Error, T::Error, E::Error>;
}

impl<D: Lifecycle, T: ErrorType, E: ErrorType> Lifecycle for DeviceHardware<D, T, E> {
    fn configure(&mut self) -> Result<(), Self::Error> {
        self.drives.configure().map_err(DeviceError::Drives)
    }
    fn activate(&mut self) -> Result<(), Self::Error> {
        self.drives.activate().map_err(DeviceError::Drives)
    }
    fn deactivate(&mut self) -> Result<(), Self::Error> {
        self.drives.deactivate().map_err(DeviceError::Drives)
    }
    fn lifecycle_state(&self) -> LifecycleState {
        self.drives.lifecycle_state()
    }
}

impl<D: WireDrives<WIREMAN_WIRES>, T: ErrorType, E: ErrorType> WireDrives<WIREMAN_WIRES>
    for DeviceHardware<D, T, E>
{
    fn enable(&mut self) -> Result<(), Self::Error> {
        self.drives.enable().map_err(DeviceError::Drives)
    }
    fn disable(&mut self) -> Result<(), Self::Error> {
        self.drives.disable().map_err(DeviceError::Drives)
    }
    fn read_drives(&mut self, out: &mut [DriveSample; WIREMAN_WIRES]) -> Result<(), Self::Error> {
        self.drives.read_drives(out).map_err(DeviceError::Drives)
    }
    fn write_torques(&mut self, torque_nm: &[f64; WIREMAN_WIRES]) -> Result<(), Self::Error> {
        self.drives
            .write_torques(torque_nm)
            .map_err(DeviceError::Drives)
    }
}

impl<D: ErrorType, T: TensionSensors<WIREMAN_WIRES>, E: ErrorType> TensionSensors<WIREMAN_WIRES>
    for DeviceHardware<D, T, E>
{
    fn read_tensions(&mut self, out_n: &mut [f64; WIREMAN_WIRES]) -> Result<(), Self::Error> {
        self.tensions
            .read_tensions(out_n)
            .map_err(DeviceError::Tensions)
    }
    fn read_fresh_tensions(
        &mut self,
        out_n: &mut [f64; WIREMAN_WIRES],
    ) -> Result<[bool; WIREMAN_WIRES], Self::Error> {
        self.tensions
            .read_fresh_tensions(out_n)
            .map_err(DeviceError::Tensions)
    }
}

impl<D: ErrorType, T: ErrorType, E: EStop> EStop for DeviceHardware<D, T, E> {
    fn is_pressed(&mut self) -> Result<bool, Self::Error> {
        self.estop.is_pressed().map_err(DeviceError::EStop)
    }
    fn reset(&mut self) -> Result<(), Self::Error> {
        self.estop.reset().map_err(DeviceError::EStop)
    }
}

/// The WireMan's hardware has no passive angle sensors (the cycle reads them only on a device
/// that has them).
impl<D: ErrorType, T: ErrorType, E: ErrorType> videt_hal::AngleSensors for DeviceHardware<D, T, E> {
    fn read_angles(&mut self, _out_rad: &mut [f64; 2]) -> Result<(), Self::Error> {
        Err(DeviceError::NoAngleSensors)
    }
}

impl<D, T, E> Clock for DeviceHardware<D, T, E> {
    fn now(&self) -> MonoTime {
        self.clock.now()
    }
    fn sleep_until(&mut self, deadline: MonoTime) {
        self.clock.sleep_until(deadline);
    }
}

/// The drive-set settings of the device: node ids, rated torque and heartbeats from
/// `[drives]`, the transmission and limits from `[transmission]` and `[control]`, one SYNC per
/// control period, and with `sensors.adc = "drive"` the analog input object
/// (`sensors.drive_analog_index`/`drive_analog_subindex`) mapped into every drive's TPDO1.
/// With `drives.device_description`, the unit the drives give their rated torque in (µN·m on
/// maxon drives) and their position and velocity units come from the file.
pub fn drive_set_config(config: &Config) -> DriveSetConfig<WIREMAN_WIRES> {
    let d = &config.drives;
    let period = Duration::from_nanos(1_000_000_000 / u64::from(config.control.rate_hz.max(1)));
    let mut c = DriveSetConfig::new(
        d.node_ids,
        period,
        d.rated_torque_nm,
        config.control.t_max_n,
    );
    c.transmission = videt_runtime::setup::transmission(config);
    c.motor_reversed = d.motor_reversed;
    c.encoder_reversed = d.encoder_reversed;
    c.max_wire_speed_m_per_s = config.control.max_wire_speed_m_s;
    c.drive_heartbeat_ms = d.heartbeat_ms;
    c.drive_heartbeat_timeout = Duration::from_millis(u64::from(d.heartbeat_timeout_ms));
    c.host_silence_timeout_ms = d.host_silence_timeout_ms;
    c.sdo_timeout = Duration::from_millis(u64::from(d.sdo_timeout_ms));
    c.max_missed_cycles = d.max_missed_cycles;
    c.pdo_timeout = period.mul_f64(d.pdo_wait_fraction);
    c.power_timeout = Duration::from_millis(u64::from(d.power_timeout_ms));
    if let Some((torque_unit, per_position, per_velocity)) =
        crate::drive_dictionary::description_units(config)
    {
        c.rated_torque_unit = torque_unit;
        c.counts_per_position_unit = per_position;
        c.counts_per_s_per_velocity_unit = per_velocity;
    }
    let s = &config.sensors;
    c.analog_input = (s.adc == TensionAdc::Drive).then_some(AnalogInputObject {
        index: s.drive_analog_index,
        subindex: s.drive_analog_subindex,
    });
    c
}

/// The ADS1220 registers for `[sensors]`: PGA gain 128, the configured mode and data rate.
pub fn ads1220_config(s: &videt_config::SensorsConfig) -> videt_drivers::adc::ads1220::Config {
    use videt_config::{Ads1220Mode, ADS1220_NORMAL_SPS, ADS1220_TURBO_SPS};
    use videt_drivers::adc::ads1220::{Config as Regs, PgaGain};
    let (turbo, rates) = match s.ads1220_mode {
        Ads1220Mode::Normal => (false, ADS1220_NORMAL_SPS),
        Ads1220Mode::Turbo => (true, ADS1220_TURBO_SPS),
    };
    // The configuration was validated: the rate is one of the mode's.
    let code = rates
        .iter()
        .position(|&r| r == s.sample_rate_sps)
        .unwrap_or(6) as u8;
    Regs::bridge_at(PgaGain::X128, turbo, code).unwrap_or(Regs::bridge_for_control(PgaGain::X128))
}

/// The nominal raw-count-to-newton scale of each wire's converter, from `[sensors]`.
pub fn nominal_tension_scales(config: &Config) -> [TensionCalibration; WIREMAN_WIRES] {
    let s = &config.sensors;
    core::array::from_fn(|i| TensionCalibration {
        offset_counts: f64::from(s.zero_counts[i]),
        newtons_per_count: s.newtons_per_count[i],
    })
}

#[cfg(target_os = "linux")]
pub use linux::{open_device, LinuxDevice};

#[cfg(target_os = "linux")]
mod linux {
    use std::time::Duration;

    use videt_config::{Config, TensionAdc};
    use videt_drivers::adc::drive_input::DriveInputAdc;
    use videt_drivers::adc::linux::{open_ads1220, open_hx711, LinuxAdc};
    use videt_drivers::adc::tension_set::{MonotonicClock, StrainGaugeSet};
    use videt_drivers::can::socketcan_port::SocketCanPort;
    use videt_drivers::cia402::Cia402DriveSet;
    use videt_drivers::gpio::estop::EStopInput;
    use videt_drivers::gpio::linux::CdevPin;

    use super::{
        ads1220_config, drive_set_config, nominal_tension_scales, DeviceHardware,
        ESTOP_DEBOUNCE_SAMPLES,
    };

    /// The device on Linux: SocketCAN drives, spidev, GPIO or drive-input converters, a GPIO
    /// e-stop.
    pub type LinuxDevice = DeviceHardware<
        Cia402DriveSet<SocketCanPort, { videt_runtime::WIREMAN_WIRES }>,
        StrainGaugeSet<LinuxAdc, MonotonicClock, { videt_runtime::WIREMAN_WIRES }>,
        EStopInput<CdevPin>,
    >;

    /// Open the device's parts named by `config`: the e-stop first (so no drive is reached
    /// without it), then the three converters, then the CAN interface; with
    /// `sensors.adc = "drive"` the CAN interface right after the e-stop, the three tension
    /// channels being the drives' analog inputs. Nothing is powered: the service configures
    /// and enables the drives. An error names the part, its device and the configuration field
    /// to look at.
    pub fn open_device(config: &Config) -> Result<LinuxDevice, String> {
        let s = &config.sensors;
        let estop = videt_drivers::gpio::linux::estop(
            &s.gpio_chip,
            s.estop_line,
            ESTOP_DEBOUNCE_SAMPLES,
            s.estop_pressed_level == videt_config::LineLevel::High,
        )
        .map_err(|e| format!("{e} (sensors.gpio_chip, sensors.estop_line)"))?;
        let open_drives = || {
            let interface = &config.drives.can_interface;
            let port = SocketCanPort::open(interface)
                .map_err(|e| format!("CAN interface {interface}: {e} (drives.can_interface)"))?;
            Cia402DriveSet::new(port, drive_set_config(config)).map_err(|e| {
                if e.field.starts_with("analog_input") {
                    format!("{e} (sensors.drive_analog_index, sensors.drive_analog_subindex)")
                } else {
                    e.to_string()
                }
            })
        };
        if s.adc == TensionAdc::Drive {
            let drives = open_drives()?;
            let inputs = drives.analog_inputs().ok_or_else(|| {
                "sensors.adc = \"drive\": the drives have no analog input mapped".to_string()
            })?;
            let tensions = StrainGaugeSet::new(
                DriveInputAdc::for_each_wire(&inputs).map(LinuxAdc::DriveInput),
                nominal_tension_scales(config),
                MonotonicClock::default(),
                Duration::from_millis(u64::from(s.stale_after_ms)),
            );
            return Ok(DeviceHardware::new(drives, tensions, estop));
        }
        let open_adc = |wire: usize| match s.adc {
            TensionAdc::Ads1220 => open_ads1220(
                wire,
                &s.spi_devices[wire],
                &s.gpio_chip,
                s.drdy_lines[wire],
                ads1220_config(s),
            )
            .map_err(|e| format!("{e} (sensors.spi_devices, sensors.drdy_lines)")),
            TensionAdc::Hx711 => open_hx711(
                wire,
                &s.gpio_chip,
                s.hx711_clock_lines[wire],
                s.hx711_data_lines[wire],
            )
            .map_err(|e| format!("{e} (sensors.hx711_clock_lines, sensors.hx711_data_lines)")),
            // Opened with the drives above.
            TensionAdc::Drive => Err("sensors.adc = \"drive\" has no converter of its own".into()),
        };
        let adcs = [open_adc(0)?, open_adc(1)?, open_adc(2)?];
        let tensions = StrainGaugeSet::new(
            adcs,
            nominal_tension_scales(config),
            MonotonicClock::default(),
            Duration::from_millis(u64::from(s.stale_after_ms)),
        );
        let drives = open_drives()?;
        Ok(DeviceHardware::new(drives, tensions, estop))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use videt_hal::ErrorKind;

    /// One capability of a device, scripted: its error kind when failing.
    #[derive(Debug, Default)]
    struct Part {
        fail: Option<ErrorKind>,
        calls: Vec<&'static str>,
        pressed: bool,
        state: Option<LifecycleState>,
    }

    impl Part {
        fn step(&mut self, name: &'static str) -> Result<(), ErrorKind> {
            self.calls.push(name);
            self.fail.map_or(Ok(()), Err)
        }
    }

    impl ErrorType for Part {
        type Error = ErrorKind;
    }

    impl Lifecycle for Part {
        fn configure(&mut self) -> Result<(), ErrorKind> {
            self.state = Some(LifecycleState::Inactive);
            self.step("configure")
        }
        fn activate(&mut self) -> Result<(), ErrorKind> {
            self.state = Some(LifecycleState::Active);
            self.step("activate")
        }
        fn deactivate(&mut self) -> Result<(), ErrorKind> {
            self.state = Some(LifecycleState::Inactive);
            self.step("deactivate")
        }
        fn lifecycle_state(&self) -> LifecycleState {
            self.state.unwrap_or(LifecycleState::Unconfigured)
        }
    }

    impl WireDrives<WIREMAN_WIRES> for Part {
        fn enable(&mut self) -> Result<(), ErrorKind> {
            self.step("enable")
        }
        fn disable(&mut self) -> Result<(), ErrorKind> {
            self.step("disable")
        }
        fn read_drives(&mut self, out: &mut [DriveSample; WIREMAN_WIRES]) -> Result<(), ErrorKind> {
            out[1].position_counts = 1234;
            self.step("read_drives")
        }
        fn write_torques(&mut self, _: &[f64; WIREMAN_WIRES]) -> Result<(), ErrorKind> {
            self.step("write_torques")
        }
    }

    impl TensionSensors<WIREMAN_WIRES> for Part {
        fn read_tensions(&mut self, out_n: &mut [f64; WIREMAN_WIRES]) -> Result<(), ErrorKind> {
            *out_n = [1.0, 2.0, 3.0];
            self.step("read_tensions")
        }
    }

    impl EStop for Part {
        fn is_pressed(&mut self) -> Result<bool, ErrorKind> {
            self.step("is_pressed").map(|()| self.pressed)
        }
        fn reset(&mut self) -> Result<(), ErrorKind> {
            self.step("reset")
        }
    }

    fn failing(kind: ErrorKind) -> Part {
        Part {
            fail: Some(kind),
            ..Part::default()
        }
    }

    #[test]
    fn each_capability_goes_to_its_part() {
        let estop = Part {
            pressed: true,
            ..Part::default()
        };
        let mut hw = DeviceHardware::new(Part::default(), Part::default(), estop);
        hw.configure().unwrap();
        hw.activate().unwrap();
        assert_eq!(hw.lifecycle_state(), LifecycleState::Active);
        hw.enable().unwrap();
        let mut samples = [DriveSample::default(); WIREMAN_WIRES];
        hw.read_drives(&mut samples).unwrap();
        assert_eq!(samples[1].position_counts, 1234);
        hw.write_torques(&[0.0; WIREMAN_WIRES]).unwrap();
        let mut t = [0.0; WIREMAN_WIRES];
        hw.read_tensions(&mut t).unwrap();
        assert_eq!(t, [1.0, 2.0, 3.0]);
        assert!(hw.is_pressed().unwrap());
        hw.reset().unwrap();
        hw.disable().unwrap();
        hw.deactivate().unwrap();
        assert_eq!(
            hw.drives.calls,
            [
                "configure",
                "activate",
                "enable",
                "read_drives",
                "write_torques",
                "disable",
                "deactivate"
            ]
        );
        assert_eq!(hw.tensions.calls, ["read_tensions"]);
        assert_eq!(hw.estop.calls, ["is_pressed", "reset"]);
        let before = hw.now();
        hw.sleep_until(before.add_nanos(200_000));
        assert!(hw.now().nanos_since(before) >= 200_000);
    }

    #[test]
    fn a_part_failure_keeps_its_kind_and_names_the_part() {
        let mut hw = DeviceHardware::new(
            failing(ErrorKind::Disconnected),
            failing(ErrorKind::Timeout),
            failing(ErrorKind::Fault),
        );
        let e = hw
            .read_drives(&mut [DriveSample::default(); WIREMAN_WIRES])
            .unwrap_err();
        assert!(matches!(e, DeviceError::Drives(ErrorKind::Disconnected)));
        let e = hw.read_tensions(&mut [0.0; WIREMAN_WIRES]).unwrap_err();
        assert_eq!(videt_hal::Error::kind(&e), ErrorKind::Timeout);
        let e = hw.is_pressed().unwrap_err();
        assert_eq!(videt_hal::Error::kind(&e), ErrorKind::Fault);
        let text = DeviceError::<&str, &str, &str>::EStop("line unreadable").to_string();
        assert_eq!(text, "e-stop: line unreadable");
    }

    #[test]
    fn the_drive_set_follows_the_configuration() {
        let mut config = Config::default();
        config.drives.node_ids = [4, 5, 6];
        config.drives.rated_torque_nm = 0.08;
        config.drives.heartbeat_ms = 20;
        config.drives.heartbeat_timeout_ms = 70;
        config.control.rate_hz = 2000;
        config.drives.pdo_wait_fraction = 0.9;
        config.drives.motor_reversed = [false, true, false];
        config.drives.encoder_reversed = [true, true, false];
        let c = drive_set_config(&config);
        assert_eq!(c.node_ids, [4, 5, 6]);
        assert_eq!(c.motor_reversed, [false, true, false]);
        assert_eq!(c.encoder_reversed, [true, true, false]);
        assert_eq!(c.pdo_timeout, Duration::from_micros(450));
        assert_eq!(c.power_timeout, Duration::from_millis(500));
        assert_eq!(c.rated_torque_nm, 0.08);
        assert_eq!(c.drive_heartbeat_ms, 20);
        assert_eq!(c.drive_heartbeat_timeout, Duration::from_millis(70));
        assert_eq!(c.control_period, Duration::from_micros(500));
        assert_eq!(c.t_max_n, config.control.t_max_n);
        c.validate().unwrap();
        assert_eq!(
            c.analog_input, None,
            "no analog input without adc = \"drive\""
        );
        let scales = nominal_tension_scales(&config);
        assert_eq!(
            scales[2].newtons_per_count,
            config.sensors.newtons_per_count[2]
        );
    }

    #[test]
    fn a_maxon_device_description_sets_the_drives_units() {
        let Some(dir) = videt_testdata::data_dir("canopen/eds") else {
            return;
        };
        let config = Config::from_toml_str_at(
            "[drives]\ndevice_description = \"epos4_50_15_can_ec90flat_gp52c_mile800_node1.dcf\"\n\
             [control]\nt_min_n = 0.7\n[autoinit]\npay_out_tension_n = 0.8\n",
            "t",
            Some(&dir),
        )
        .unwrap();
        let c = drive_set_config(&config);
        assert_eq!(c.rated_torque_nm, 0.512871);
        assert_eq!(
            c.rated_torque_unit,
            videt_drivers::cia402::TorqueUnit::MicroNewtonMetre
        );
        assert_eq!(c.rated_torque_unit.raw(c.rated_torque_nm), 512_871);
        assert_eq!(c.transmission.counts_per_motor_rev, 3200);
        assert_eq!(c.transmission.gear_ratio, 26.0);
        assert_eq!(c.counts_per_position_unit, 1.0);
        assert!((c.counts_per_s_per_velocity_unit - 3200.0 / 60.0).abs() < 1e-9);
        c.validate().unwrap();
        // Without a device description: CiA 402's units, counts and counts/s.
        let c = drive_set_config(&Config::default());
        assert_eq!(
            c.rated_torque_unit,
            videt_drivers::cia402::TorqueUnit::MilliNewtonMetre
        );
        assert_eq!(c.counts_per_s_per_velocity_unit, 1.0);
    }

    #[test]
    fn the_ads1220_runs_at_the_configured_mode_and_rate() {
        use videt_drivers::adc::ads1220::{Config as Regs, PgaGain};
        let mut config = Config::default();
        assert_eq!(
            ads1220_config(&config.sensors),
            Regs::bridge_for_control(PgaGain::X128)
        );
        config.sensors.ads1220_mode = videt_config::Ads1220Mode::Normal;
        config.sensors.sample_rate_sps = 330;
        config.validate().unwrap();
        let r = ads1220_config(&config.sensors);
        assert_eq!((r.reg1 >> 5, (r.reg1 >> 3) & 0b11), (4, 0));
    }

    #[test]
    fn with_drive_inputs_the_drives_map_the_configured_analog_input() {
        let mut config = Config::default();
        config.sensors.adc = TensionAdc::Drive;
        let c = drive_set_config(&config);
        assert_eq!(c.analog_input, Some(AnalogInputObject::CIA401_FIRST));
        config.sensors.drive_analog_index = 0x3160;
        config.sensors.drive_analog_subindex = 2;
        let c = drive_set_config(&config);
        assert_eq!(
            c.analog_input,
            Some(AnalogInputObject {
                index: 0x3160,
                subindex: 2
            })
        );
        c.validate().unwrap();
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_device_that_is_absent_is_named_with_its_configuration_field() {
        let mut config = Config::default();
        config.sensors.gpio_chip = "/dev/no-such-gpiochip".into();
        for adc in [TensionAdc::Ads1220, TensionAdc::Drive] {
            // The e-stop comes first, whatever the tension sensors are.
            config.sensors.adc = adc;
            let e = open_device(&config).unwrap_err();
            assert!(
                e.contains("/dev/no-such-gpiochip line 17 (e-stop)")
                    && e.contains("(sensors.gpio_chip, sensors.estop_line)"),
                "{adc:?}: {e}"
            );
        }
    }
}
