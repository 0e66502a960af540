//! With the drives' analog inputs as tension sensors, the control cycle's reads allocate and
//! free nothing: `read_drives` (SYNC, TPDOs with the analog inputs, publishing them) then
//! `read_tensions` (the three drive inputs through the strain-gauge set) then `write_torques`,
//! against three simulated CiA 402 drives on the in-process bus, under a global allocator that
//! counts the allocations made on this thread (the simulated drives run on their own). So does
//! the fault path: an EMCY latched, queued for the supervisor, and the safe commands sent.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use videt_drivers::adc::calibration::TensionCalibration;
use videt_drivers::adc::drive_input::DriveInputAdc;
use videt_drivers::adc::tension_set::{MonotonicClock, StrainGaugeSet};
use videt_drivers::can::CanPort;
use videt_drivers::cia402::{AnalogInputObject, Cia402DriveSet, DriveSetConfig};
use videt_hal::{DriveSample, Lifecycle, TensionSensors, WireDrives};
use videt_sim::can_bus::{BusError, BusFaults, InProcessBus, InProcessEndpoint, SimFrame};
use videt_sim::cia402_node::{FreeMotorPlant, SimDriveBank, SimDriveSpec};

/// The WireMan's wire count (three drives, nodes 1, 2, 3).
const WIRES: usize = 3;

#[global_allocator]
static GLOBAL: videt_testkit::CountingAllocator = videt_testkit::CountingAllocator;

/// The host's station of the in-process bus, as the drive driver's port.
struct Host(InProcessEndpoint);

impl embedded_can::blocking::Can for Host {
    type Frame = SimFrame;
    type Error = BusError;
    fn transmit(&mut self, frame: &SimFrame) -> Result<(), BusError> {
        self.0.send(frame)
    }
    fn receive(&mut self) -> Result<SimFrame, BusError> {
        loop {
            if let Some(f) = self.0.receive_timeout(Duration::from_millis(100))? {
                return Ok(f);
            }
        }
    }
}

impl CanPort for Host {
    fn receive_timeout(&mut self, timeout: Duration) -> Result<Option<SimFrame>, BusError> {
        self.0.receive_timeout(timeout)
    }
    fn is_bus_off(&self) -> bool {
        self.0.is_bus_off()
    }
}

const PERIOD: Duration = Duration::from_millis(5);

#[test]
fn reading_drives_and_drive_input_tensions_allocates_nothing() {
    let mut eps = InProcessBus::with_endpoints(2, 256, Arc::new(BusFaults::new(5)));
    let drives = eps.pop().unwrap();
    let host = eps.pop().unwrap();
    let plant = Arc::new(Mutex::new(FreeMotorPlant::new(WIRES, 1e-5, 1e-4, 2000.0)));
    for (axis, v) in [1000, 2000, 3000].into_iter().enumerate() {
        plant.lock().unwrap().set_analog_input(axis, v);
    }
    let specs: Vec<SimDriveSpec> = (0..WIRES)
        .map(|i| SimDriveSpec {
            node_id: i as u8 + 1,
            axis: i,
            rated_torque_mnm: 100,
            boot_delay: Duration::from_millis(5),
        })
        .collect();
    let bank = SimDriveBank::spawn(drives, &specs, plant.clone());
    let mut cfg = DriveSetConfig::new([1, 2, 3], PERIOD, 0.1, 40.0);
    cfg.analog_input = Some(AnalogInputObject::default());
    // This test is about allocations, not deadlines: ride out a loaded machine.
    cfg.boot_timeout = Duration::from_secs(2);
    cfg.max_missed_cycles = 50;
    cfg.drive_heartbeat_timeout = Duration::from_millis(500);
    cfg.host_silence_timeout_ms = 1000;
    let mut set = Cia402DriveSet::new(Host(host), cfg).unwrap();
    let mut fault_reports = set.fault_reports();
    let inputs = set.analog_inputs().unwrap();
    let mut tensions = StrainGaugeSet::new(
        DriveInputAdc::for_each_wire(&inputs),
        [TensionCalibration {
            offset_counts: 0.0,
            newtons_per_count: 0.01,
        }; WIRES],
        MonotonicClock::default(),
        Duration::from_millis(200),
    );
    set.configure().unwrap();
    set.activate().unwrap();

    let mut samples = [DriveSample::default(); WIRES];
    let mut n = [0.0; WIRES];
    let mut run = |cycles: u32| -> u32 {
        let mut fresh = 0;
        for _ in 0..cycles {
            let start = Instant::now();
            set.read_drives(&mut samples).unwrap();
            if tensions.read_tensions(&mut n).is_ok() {
                fresh += 1;
            }
            set.write_torques(&[0.001; WIRES]).unwrap();
            if let Some(rest) = (start + PERIOD).checked_duration_since(Instant::now()) {
                std::thread::sleep(rest);
            }
        }
        fresh
    };
    // Warm-up: the bus's blocking receive sets up its per-thread state once.
    run(20);
    let before = inputs.latest(2).count;
    let (read, counts) = videt_testkit::count_allocations(|| run(200));
    assert_eq!(
        counts,
        videt_testkit::AllocCounts::default(),
        "allocations and frees in the cycle"
    );
    assert_eq!(read, 200, "every cycle had a tension");
    assert!(
        inputs.latest(2).count - before > 150,
        "the inputs kept arriving"
    );
    assert_eq!(n, [10.0, 20.0, 30.0]);

    // A drive's EMCY: the set latches it, reports it to the supervisor's queue and commands
    // the safe state, all without allocating.
    bank.faults(1).raise_fault(0x2310);
    let (latched, counts) = videt_testkit::count_allocations(|| {
        for _ in 0..50 {
            let start = Instant::now();
            if let Err(e) = set.read_drives(&mut samples) {
                return Some(e);
            }
            let _ = set.write_torques(&[0.001; WIRES]);
            if let Some(rest) = (start + PERIOD).checked_duration_since(Instant::now()) {
                std::thread::sleep(rest);
            }
        }
        None
    });
    assert_eq!(
        counts,
        videt_testkit::AllocCounts::default(),
        "allocations and frees on the fault path"
    );
    let latched = latched.expect("the EMCY put the drives in their safe state");
    assert_eq!(fault_reports.pop().ok(), Some(latched));
}
