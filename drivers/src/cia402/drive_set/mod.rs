//! The wire drives on one CAN bus, one per wire of an `N`-wire device, driven through CiA 402
//! cyclic synchronous torque mode: `impl WireDrives<N> + Lifecycle` over any [`CanPort`], for
//! every wire count `N` (the count comes from the configuration's node ids).
//!
//! Per control cycle ([`WireDrives::read_drives`] then [`WireDrives::write_torques`]):
//! stale frames are drained, SYNC is sent, the TPDOs of every drive are awaited until
//! `pdo_timeout`, heartbeats and EMCYs are checked, then the RPDOs (controlword + target
//! torque) are sent. Any failure latches an error, sends "disable voltage, zero torque" to every
//! drive (the safe state) and fails every later cycle until the set is deactivated and
//! reconfigured, or re-activated. The cycle methods allocate nothing and block only in the
//! bus receive, never past `pdo_timeout`.
//!
//! With [`DriveSetConfig::analog_input`] set, TPDO1 carries each drive's analog input (and its
//! statusword) in the velocity's place, and the velocity is derived from the positions of
//! successive SYNCs; every cycle the values that arrived with this cycle's TPDO1 are published
//! to the shared [`DriveAnalogInputs`] ([`Cia402DriveSet::analog_inputs`]).
//!
//! Here are the set, its construction and its accessors; the frame I/O is in `frames`, the
//! drives' links in `node`, the exchange of every control period in `cyclic`, the SDO
//! transfers in `sdo`, the drives' identities in `identify`, their configuration and start in
//! `bring_up`, the power sequencing in `power`, and the HAL trait implementations in `hal`.
//!
//! [`WireDrives::read_drives`]: videt_hal::WireDrives::read_drives
//! [`WireDrives::write_torques`]: videt_hal::WireDrives::write_torques

mod bring_up;
mod cyclic;
mod frames;
mod hal;
mod identify;
mod node;
mod power;
mod sdo;

use std::sync::Arc;
use std::time::Instant;

use videt_hal::{LifecycleState, Transmission};

use self::node::NodeLink;
use super::analog::DriveAnalogInputs;
use super::config::{ConfigError, DriveSetConfig};
use super::error::DriveError;
use super::identity::{SharedStartupReport, StartupReport};
use super::state::PowerState;
use crate::can::CanPort;

/// Length of wire (m) for an encoder position: `length_at_zero - counts * metres_per_count`.
pub fn wire_length_m(t: &Transmission, length_at_zero_m: f64, position_counts: i64) -> f64 {
    length_at_zero_m - position_counts as f64 * t.metres_per_count()
}

/// `N` CiA 402 wire drives on one CAN port, wire `i` being the drive of node
/// `config().node_ids[i]`. Build with [`Cia402DriveSet::new`], which takes `N` from the
/// [`DriveSetConfig<N>`]; the per-wire state lives in fixed `[_; N]` arrays.
#[derive(Debug)]
pub struct Cia402DriveSet<P: CanPort, const N: usize> {
    port: P,
    cfg: DriveSetConfig<N>,
    nodes: [NodeLink; N],
    lifecycle: LifecycleState,
    latched: Option<DriveError>,
    host_heartbeat_due: Instant,
    operational_expected: bool,
    /// When the latest SYNC was sent: the one a TPDO1 answers (a late one is absorbed before
    /// the next SYNC goes out).
    sync_sent_at: Instant,
    epoch: Instant,
    analog: Option<Arc<DriveAnalogInputs<N>>>,
    /// Where each latched error is pushed for a non-RT reader to report, once one asked.
    fault_reports: Option<rtrb::Producer<DriveError>>,
    /// The identities and notes the configuration under way gathers.
    gathering: StartupReport,
    /// The identities and notes of the last configuration, for readers off the control thread.
    report: SharedStartupReport,
}

/// Latched errors a [`Cia402DriveSet`] holds for its reader before it drops newer ones.
pub const FAULT_REPORTS_CAPACITY: usize = 8;

impl<P: CanPort, const N: usize> Cia402DriveSet<P, N> {
    /// Take the port and a validated configuration of `N` drives (`N` is the length of
    /// [`DriveSetConfig::node_ids`]). Nothing is sent yet (`Unconfigured`).
    pub fn new(port: P, cfg: DriveSetConfig<N>) -> Result<Self, ConfigError> {
        cfg.validate()?;
        let analog = cfg.analog_input.map(|_| Arc::new(DriveAnalogInputs::new()));
        let now = Instant::now();
        let nodes = core::array::from_fn(|i| NodeLink::new(cfg.node_ids[i], i, now));
        Ok(Cia402DriveSet {
            port,
            cfg,
            nodes,
            lifecycle: LifecycleState::Unconfigured,
            latched: None,
            host_heartbeat_due: now,
            operational_expected: false,
            sync_sent_at: now,
            epoch: now,
            analog,
            fault_reports: None,
            gathering: StartupReport::default(),
            report: SharedStartupReport::default(),
        })
    }

    /// Give the port back.
    pub fn release(self) -> P {
        self.port
    }

    /// The port (for inspection; the set keeps using it).
    pub fn port(&self) -> &P {
        &self.port
    }

    /// The port, mutably (tests script the drives through it).
    #[cfg(test)]
    pub(crate) fn port_mut(&mut self) -> &mut P {
        &mut self.port
    }

    /// The configuration.
    pub fn config(&self) -> &DriveSetConfig<N> {
        &self.cfg
    }

    /// The drives' analog inputs, updated by every cycle, when
    /// [`DriveSetConfig::analog_input`] is set (`None` otherwise). Each wire's sample counter
    /// advances only for a TPDO1 that answered the current cycle's SYNC.
    pub fn analog_inputs(&self) -> Option<Arc<DriveAnalogInputs<N>>> {
        self.analog.clone()
    }

    /// From now on, every error that puts the set into its safe state is also pushed, as it is
    /// latched, to the returned queue: the control thread cannot say why it stopped (it does
    /// not format), a supervisor reading the queue can. The push is wait-free and allocates
    /// nothing; errors beyond [`FAULT_REPORTS_CAPACITY`] unread ones are dropped. A second call
    /// replaces the first queue.
    pub fn fault_reports(&mut self) -> rtrb::Consumer<DriveError> {
        let (producer, consumer) = rtrb::RingBuffer::new(FAULT_REPORTS_CAPACITY);
        self.fault_reports = Some(producer);
        consumer
    }

    /// The drives' identities and the optional objects they lack, as of the last
    /// configuration, shared: a service's supervisor logs them and puts them in its status.
    /// Updated by every configuration (not on the real-time path).
    pub fn startup_report(&self) -> SharedStartupReport {
        SharedStartupReport::clone(&self.report)
    }

    fn publish_startup_report(&mut self) {
        if let Ok(mut r) = self.report.lock() {
            let generation = r.generation + 1;
            *r = StartupReport {
                generation,
                ..core::mem::take(&mut self.gathering)
            };
        }
    }

    /// The error that put the set into its safe state, if any.
    pub fn latched_error(&self) -> Option<DriveError> {
        self.latched
    }

    /// The decoded power state of each drive (from the last statusword).
    pub fn power_states(&self) -> [PowerState; N] {
        core::array::from_fn(|i| self.nodes[i].power_state())
    }

    /// Seconds since the set was created (for logs).
    pub fn uptime_s(&self) -> f64 {
        self.epoch.elapsed().as_secs_f64()
    }
}
