//! The digital twin behind the real CAN drive driver (`videtd --sim can`): the control loop talks
//! CiA 402 over the userspace CAN bus to three simulated drive nodes, whose motors are the twin's
//! motors. Tensions, e-stop and the clock come from the twin directly.
//!
//! Per cycle: `read_drives` runs the driver's SYNC exchange (the nodes apply the torque latched
//! from the previous RPDO and report the twin's encoders), then hands the nodes' torques to the
//! twin's motors; `sleep_until` advances the twin's physics and publishes its encoders to the
//! nodes. The hand-over is wait-free ([`SharedMotors`]).
//!
//! The simulated drives are the configured part: with `drives.device_description` their
//! dictionary is the file's ([`crate::drive_dictionary`]: its objects, answers, rated torque and
//! units); without one they are generic CiA 402 drives whose rated torque (0x6076, mN·m) is the
//! configured drive's ([`setup::twin_rated_torque_mnm`]). Either way the torque reaches the
//! twin's motors in the configured drive's per-mille steps.

use std::sync::Arc;
use std::time::Duration;

use videt_control::WireDevice;
use videt_drivers::can::CanPort;
use videt_drivers::cia402::{Cia402DriveSet, DriveError, DriveSetConfig};
use videt_hal::{
    AngleSensors, Clock, DriveSample, EStop, ErrorKind, ErrorType, Lifecycle, LifecycleState,
    MonoTime, TensionSensors, WireDrives,
};
use videt_sim::can_bus::{
    BusError, BusFaults, BusStats, InProcessBus, InProcessEndpoint, SimFrame,
};
use videt_sim::cia402_node::{
    DriveDictionary, NodeView, SharedMotors, SimDriveBank, SimDriveSpec, SteppedDriveBus,
};
use videt_sim::{Twin, TwinError};

use crate::twin_rt::RealTimeTwin;
use videt_config::Config;
use videt_runtime::setup;

/// Node ids of the simulated drives (wire 0, 1, 2, 3: a device uses the first ones).
pub const NODE_IDS: [u8; 4] = [1, 2, 3, 4];

/// The driver's CAN port onto the simulated drives.
#[derive(Debug)]
pub enum SimCanPort {
    /// The host's station on the in-process bus; the drives run on their own thread.
    Threaded(InProcessEndpoint),
    /// The drives answer inline (deterministic, for the twin's simulated clock).
    Stepped(Box<SteppedDriveBus<Arc<SharedMotors>>>),
}

impl embedded_can::blocking::Can for SimCanPort {
    type Frame = SimFrame;
    type Error = BusError;
    fn transmit(&mut self, frame: &SimFrame) -> Result<(), BusError> {
        match self {
            SimCanPort::Threaded(ep) => ep.send(frame),
            SimCanPort::Stepped(bus) => {
                bus.send(frame);
                Ok(())
            }
        }
    }
    fn receive(&mut self) -> Result<SimFrame, BusError> {
        loop {
            if let Some(f) = self.receive_timeout(Duration::from_millis(100))? {
                return Ok(f);
            }
        }
    }
}

impl CanPort for SimCanPort {
    fn receive_timeout(&mut self, timeout: Duration) -> Result<Option<SimFrame>, BusError> {
        match self {
            SimCanPort::Threaded(ep) => ep.receive_timeout(timeout),
            SimCanPort::Stepped(bus) => {
                if let Some(f) = bus.receive() {
                    return Ok(Some(f));
                }
                if !timeout.is_zero() {
                    // Time-driven answers (boot-up, heartbeat): look again a little later.
                    std::thread::sleep(timeout.min(Duration::from_micros(200)));
                }
                Ok(bus.receive())
            }
        }
    }
    fn is_bus_off(&self) -> bool {
        match self {
            SimCanPort::Threaded(ep) => ep.is_bus_off(),
            SimCanPort::Stepped(_) => false,
        }
    }
}

/// The twin of an `N`-wire device as the CAN twin needs it: its HAL devices plus access to
/// the model.
pub trait TwinDevice<const N: usize>:
    Lifecycle
    + WireDrives<N>
    + TensionSensors<N>
    + EStop
    + AngleSensors
    + Clock
    + ErrorType<Error = TwinError>
{
    /// The device the twin models.
    type Device: WireDevice<N>;
    /// The twin.
    fn model(&self) -> &Twin<N, Self::Device>;
    /// The twin, mutably.
    fn model_mut(&mut self) -> &mut Twin<N, Self::Device>;
}

impl<const N: usize, D: WireDevice<N>> TwinDevice<N> for Twin<N, D> {
    type Device = D;
    fn model(&self) -> &Twin<N, D> {
        self
    }
    fn model_mut(&mut self) -> &mut Twin<N, D> {
        self
    }
}

impl<const N: usize, D: WireDevice<N>> TwinDevice<N> for RealTimeTwin<N, D> {
    type Device = D;
    fn model(&self) -> &Twin<N, D> {
        self.twin()
    }
    fn model_mut(&mut self) -> &mut Twin<N, D> {
        self.twin_mut()
    }
}

/// An error of the CAN twin: from the drive driver or from the twin's other devices.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CanTwinError {
    /// The CiA 402 drive driver.
    Drives(DriveError),
    /// The twin (tension sensors, e-stop, its lifecycle).
    Twin(ErrorKind),
}

impl videt_hal::Error for CanTwinError {
    fn kind(&self) -> ErrorKind {
        match self {
            CanTwinError::Drives(e) => videt_hal::Error::kind(e),
            CanTwinError::Twin(k) => *k,
        }
    }
}

impl core::fmt::Display for CanTwinError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            CanTwinError::Drives(e) => write!(f, "{e}"),
            CanTwinError::Twin(k) => write!(f, "simulated device: {k}"),
        }
    }
}

impl std::error::Error for CanTwinError {}

fn twin_err(e: videt_sim::TwinError) -> CanTwinError {
    CanTwinError::Twin(videt_hal::Error::kind(&e))
}

/// The drive-set configuration for the simulated drives, from the daemon's configuration.
/// With `drives.device_description`, the drives are that part ([`crate::drive_dictionary`]):
/// the configured rated torque and the file's units, as in device mode. Without one, the
/// configured drive's rated torque to the nearest mN·m ([`setup::twin_rated_torque_mnm`]),
/// which the generic simulated drives report in 0x6076 (mN·m, CiA 402).
pub fn drive_config<const N: usize>(config: &Config) -> DriveSetConfig<N> {
    let period = Duration::from_nanos(1_000_000_000 / u64::from(config.control.rate_hz.max(1)));
    let rated_torque_nm = match &config.drives.description {
        Some(_) => config.drives.rated_torque_nm,
        None => f64::from(setup::twin_rated_torque_mnm(config)) / 1000.0,
    };
    let mut c = DriveSetConfig::new(
        core::array::from_fn(|i| NODE_IDS[i]),
        period,
        rated_torque_nm,
        config.control.t_max_n,
    );
    if let Some((torque_unit, per_position, per_velocity)) =
        crate::drive_dictionary::description_units(config)
    {
        c.rated_torque_unit = torque_unit;
        c.counts_per_position_unit = per_position;
        c.counts_per_s_per_velocity_unit = per_velocity;
    }
    c.transmission = setup::transmission(config);
    c.max_wire_speed_m_per_s = config.control.max_wire_speed_m_s;
    // The directions the configuration corrects, as the device's drive set applies them.
    let d = &config.drives;
    c.motor_reversed = core::array::from_fn(|i| d.motor_reversed.get(i) == Some(&true));
    c.encoder_reversed = core::array::from_fn(|i| d.encoder_reversed.get(i) == Some(&true));
    // The simulated drives share the host's CPUs: on a kernel without PREEMPT_RT their thread
    // can be woken milliseconds late, which real drives never are. Tolerate up to 20 periods
    // without process data and 100 ms of silence either way here (a real drive set keeps the
    // defaults: 1 period, 35 ms, 50 ms).
    c.max_missed_cycles = 20;
    c.drive_heartbeat_timeout = Duration::from_millis(100);
    c.host_silence_timeout_ms = 100;
    c
}

/// The twin of an `N`-wire device with its drives behind CiA 402 nodes on a userspace CAN bus.
pub struct CanTwin<const N: usize, T: TwinDevice<N>> {
    twin: T,
    drives: Cia402DriveSet<SimCanPort, N>,
    motors: Arc<SharedMotors>,
    bank: Option<SimDriveBank>,
    bus_faults: Arc<BusFaults>,
    bus_stats: Option<Arc<BusStats>>,
    encoders: [DriveSample; N],
}

impl<const N: usize, T: TwinDevice<N>> core::fmt::Debug for CanTwin<N, T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("CanTwin").field("bank", &self.bank).finish()
    }
}

/// The simulated drives, their rated torque (0x6076, mN·m) the drive set's.
fn node_specs<const N: usize>(drive_config: &DriveSetConfig<N>) -> Vec<SimDriveSpec> {
    let rated_torque_mnm = setup::whole_mnm(drive_config.rated_torque_nm);
    (0..N)
        .map(|i| SimDriveSpec {
            node_id: NODE_IDS[i],
            axis: i,
            rated_torque_mnm,
            boot_delay: Duration::from_millis(20),
        })
        .collect()
}

impl<const N: usize, D: WireDevice<N>> CanTwin<N, Twin<N, D>> {
    /// The twin on its simulated clock, its drives answering inline: deterministic and faster
    /// than real time (whole-stack tests). The drives' rated torque is `drive_config`'s; they
    /// apply torque in its per-mille steps (the twin's own step model is switched off).
    /// `dictionary` is the drives' part (the generic CiA 402 profile when `None`;
    /// [`crate::drive_dictionary::for_config`]).
    pub fn stepped(
        mut twin: Twin<N, D>,
        drive_config: DriveSetConfig<N>,
        dictionary: Option<Arc<DriveDictionary>>,
    ) -> Result<CanTwin<N, Twin<N, D>>, String> {
        twin.set_clock_mode(videt_sim::ClockMode::Simulated);
        twin.set_torque_step_nm(None);
        let motors = Arc::new(SharedMotors::new(N));
        let bus =
            SteppedDriveBus::described(&node_specs(&drive_config), dictionary, motors.clone());
        let drives = Cia402DriveSet::new(SimCanPort::Stepped(Box::new(bus)), drive_config)
            .map_err(|e| e.to_string())?;
        let mut can_twin = CanTwin {
            twin,
            drives,
            motors,
            bank: None,
            bus_faults: Arc::new(BusFaults::default()),
            bus_stats: None,
            encoders: [DriveSample::default(); N],
        };
        can_twin.publish_encoders();
        Ok(can_twin)
    }
}

impl<const N: usize, D: WireDevice<N>> CanTwin<N, RealTimeTwin<N, D>> {
    /// Put `twin`'s motors behind three simulated CiA 402 nodes and the real driver, on a bus
    /// of `bitrate` bit/s (frames take their bit time, queue while the bus is busy and win it
    /// by identifier). The nodes and the bus's wire run on their own threads, at SCHED_FIFO
    /// `drive_priority` when given and pinned to `drive_cpu` when given (they stand for
    /// hardware that answers SYNC whatever the host's load: use the control thread's priority
    /// and CPU). The drives' rated torque is `drive_config`'s; they apply
    /// torque in its per-mille steps (the twin's own step model is switched off). `dictionary`
    /// is the drives' part (the generic CiA 402 profile when `None`).
    pub fn new(
        mut twin: Twin<N, D>,
        drive_config: DriveSetConfig<N>,
        dictionary: Option<Arc<DriveDictionary>>,
        bitrate: u32,
        drive_priority: Option<u8>,
        drive_cpu: Option<usize>,
    ) -> Result<CanTwin<N, RealTimeTwin<N, D>>, String> {
        let bus_faults = Arc::new(BusFaults::default());
        // The wire and the drives stand for hardware: both run at `drive_priority`, or a loaded
        // host's scheduler latency lands on every frame and the driver sees missed cycles; and
        // on `drive_cpu` (the control thread's), so that what stalls the rest of the machine
        // does not stall them while the control thread runs on, and each period's hand-overs
        // between the control thread, the wire and the drives need no cross-CPU wake-up.
        let drive_cpu = drive_cpu.filter(|&cpu| videt_runtime::rt::cpu_allowed(cpu));
        let raise = move |what: &'static str| {
            if let Some(p) = drive_priority {
                if let Err(e) = videt_runtime::rt::set_fifo(p) {
                    tracing::warn!(
                        "simulated {what} stay SCHED_OTHER ({e}): a loaded host may delay their frames"
                    );
                }
            }
            if let Some(cpu) = drive_cpu {
                if let Err(e) = videt_runtime::rt::pin_to_cpu(cpu) {
                    tracing::warn!("simulated {what} not pinned to CPU {cpu}: {e}");
                }
            }
        };
        let (mut eps, bus_stats) =
            InProcessBus::timed_with(2, 256, bus_faults.clone(), bitrate, move || raise("bus"))
                .map_err(|e| format!("cannot start the simulated bus: {e}"))?;
        twin.set_torque_step_nm(None);
        let node_side = eps.pop().ok_or("bus without endpoints")?;
        let host_side = eps.pop().ok_or("bus without endpoints")?;
        let motors = Arc::new(SharedMotors::new(N));
        let specs = node_specs(&drive_config);
        let bank = SimDriveBank::spawn_described(
            node_side,
            &specs,
            dictionary,
            motors.clone(),
            move || raise("drives"),
        );
        let drives = Cia402DriveSet::new(SimCanPort::Threaded(host_side), drive_config)
            .map_err(|e| e.to_string())?;
        let mut can_twin = CanTwin {
            twin: RealTimeTwin::new(twin),
            drives,
            motors,
            bank: Some(bank),
            bus_faults,
            bus_stats: Some(bus_stats),
            encoders: [DriveSample::default(); N],
        };
        can_twin.publish_encoders();
        Ok(can_twin)
    }
}

impl<const N: usize, T: TwinDevice<N>> CanTwin<N, T> {
    /// The bus's fault injector (drops, delay, bus-off).
    pub fn bus_faults(&self) -> &Arc<BusFaults> {
        &self.bus_faults
    }

    /// What the simulated bus measured (load, waiting, overflows); `None` for the stepped
    /// twin, whose drives answer inline without a bus.
    pub fn bus_stats(&self) -> Option<Arc<BusStats>> {
        self.bus_stats.clone()
    }

    /// The state of every simulated drive.
    pub fn drive_nodes(&self) -> Vec<NodeView> {
        match (&self.bank, self.drives.port()) {
            (Some(bank), _) => bank.views(),
            (None, SimCanPort::Stepped(bus)) => bus
                .nodes()
                .iter()
                .map(|n| NodeView {
                    power: n.power(),
                    nmt: n.nmt_state(),
                    applied_torque_nm: n.applied_torque_nm(),
                    power_since: None,
                })
                .collect(),
            (None, SimCanPort::Threaded(_)) => Vec::new(),
        }
    }

    /// The fault handles of the twin, its bus and its drives.
    pub fn sim_faults(&self) -> crate::sim_faults::SimFaultPort {
        let drives = match (&self.bank, self.drives.port()) {
            (Some(bank), _) => (0..N).map(|i| Arc::clone(bank.faults(i))).collect(),
            (None, SimCanPort::Stepped(bus)) => (0..N).map(|i| Arc::clone(bus.faults(i))).collect(),
            (None, SimCanPort::Threaded(_)) => Vec::new(),
        };
        crate::sim_faults::SimFaultPort {
            twin: self.twin().fault_inbox(),
            bus: Some(Arc::clone(&self.bus_faults)),
            drives,
            vision_stall: None,
            wires: N,
        }
    }

    /// The error that put the drives into their safe state, if any.
    pub fn drive_error(&self) -> Option<DriveError> {
        self.drives.latched_error()
    }

    /// The twin.
    pub fn twin(&self) -> &Twin<N, T::Device> {
        self.twin.model()
    }

    /// The twin, mutably (a procedure's simulated technician acts on it).
    pub fn twin_mut(&mut self) -> &mut Twin<N, T::Device> {
        self.twin.model_mut()
    }

    /// The twin's encoders, as the simulated drives' encoders.
    fn publish_encoders(&mut self) {
        // The twin reads its encoders whatever its drive state.
        if self
            .twin
            .model_mut()
            .read_drives(&mut self.encoders)
            .is_ok()
        {
            for (i, s) in self.encoders.iter().enumerate() {
                self.motors
                    .publish_encoder(i, s.position_counts, s.velocity_counts_per_s);
            }
        }
    }

    /// The simulated drives' torques into the twin's motors.
    fn apply_node_torques(&mut self) {
        if self.twin.model().drives_enabled() {
            let t: [f64; N] = core::array::from_fn(|i| self.motors.torque_nm(i));
            let _ = self.twin.model_mut().write_torques(&t);
        }
    }
}

impl<const N: usize, T: TwinDevice<N>> ErrorType for CanTwin<N, T> {
    type Error = CanTwinError;
}

/// Log a failed (non-RT) lifecycle step with the driver's full explanation.
fn logged(r: Result<(), CanTwinError>, step: &str) -> Result<(), CanTwinError> {
    if let Err(e) = &r {
        tracing::error!("CAN drives: {step} failed: {e}");
    }
    r
}

impl<const N: usize, T: TwinDevice<N>> Lifecycle for CanTwin<N, T> {
    fn configure(&mut self) -> Result<(), CanTwinError> {
        self.twin.configure().map_err(twin_err)?;
        let r = self.drives.configure().map_err(CanTwinError::Drives);
        logged(r, "configure")
    }
    fn activate(&mut self) -> Result<(), CanTwinError> {
        self.twin.activate().map_err(twin_err)?;
        // The twin's motors follow whatever the simulated drives apply.
        self.twin.enable().map_err(twin_err)?;
        let r = self.drives.activate().map_err(CanTwinError::Drives);
        logged(r, "activate")
    }
    fn deactivate(&mut self) -> Result<(), CanTwinError> {
        // Non-RT: say why the drives went to their safe state, if they did.
        if let Some(e) = self.drives.latched_error() {
            tracing::warn!("CAN drives had entered their safe state: {e}");
        }
        let r = self.drives.deactivate().map_err(CanTwinError::Drives);
        self.twin.deactivate().map_err(twin_err)?;
        r
    }
    fn lifecycle_state(&self) -> LifecycleState {
        self.drives.lifecycle_state()
    }
}

impl<const N: usize, T: TwinDevice<N>> WireDrives<N> for CanTwin<N, T> {
    fn enable(&mut self) -> Result<(), CanTwinError> {
        self.drives.enable().map_err(CanTwinError::Drives)
    }
    fn disable(&mut self) -> Result<(), CanTwinError> {
        self.drives.disable().map_err(CanTwinError::Drives)
    }
    fn read_drives(&mut self, out: &mut [DriveSample; N]) -> Result<(), CanTwinError> {
        let r = self.drives.read_drives(out).map_err(CanTwinError::Drives);
        self.apply_node_torques();
        r
    }
    fn write_torques(&mut self, torque_nm: &[f64; N]) -> Result<(), CanTwinError> {
        self.drives
            .write_torques(torque_nm)
            .map_err(CanTwinError::Drives)
    }
}

impl<const N: usize, T: TwinDevice<N>> TensionSensors<N> for CanTwin<N, T> {
    fn read_tensions(&mut self, out_n: &mut [f64; N]) -> Result<(), CanTwinError> {
        self.twin.read_tensions(out_n).map_err(twin_err)
    }
    fn read_fresh_tensions(&mut self, out_n: &mut [f64; N]) -> Result<[bool; N], CanTwinError> {
        self.twin.read_fresh_tensions(out_n).map_err(twin_err)
    }
}

impl<const N: usize, T: TwinDevice<N>> videt_hal::AngleSensors for CanTwin<N, T> {
    fn read_angles(&mut self, out_rad: &mut [f64; 2]) -> Result<(), CanTwinError> {
        self.twin.read_angles(out_rad).map_err(twin_err)
    }
}

impl<const N: usize, T: TwinDevice<N>> EStop for CanTwin<N, T> {
    fn is_pressed(&mut self) -> Result<bool, CanTwinError> {
        self.twin.is_pressed().map_err(twin_err)
    }
    fn reset(&mut self) -> Result<(), CanTwinError> {
        self.twin.reset().map_err(twin_err)
    }
}

impl<const N: usize, T: TwinDevice<N>> Clock for CanTwin<N, T> {
    fn now(&self) -> MonoTime {
        self.twin.now()
    }
    fn sleep_until(&mut self, deadline: MonoTime) {
        self.apply_node_torques();
        self.twin.sleep_until(deadline);
        // Bring the physics up to the clock (a twin on its simulated clock is there already),
        // then let the simulated drives sample their encoders.
        let now = self.twin.now();
        self.twin.model_mut().advance_to(now);
        self.publish_encoders();
    }
}

/// The simulated drives report through the real driver, as the device's do.
impl<const N: usize, T: TwinDevice<N>> crate::hardware::DriveReports for CanTwin<N, T> {
    fn fault_reports(&mut self) -> rtrb::Consumer<DriveError> {
        self.drives.fault_reports()
    }
    fn startup_report(&self) -> videt_drivers::cia402::SharedStartupReport {
        self.drives.startup_report()
    }
}
