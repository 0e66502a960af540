//! Cost of one control cycle of the CiA 402 drive set (`read_drives` + `write_torques`: SYNC,
//! three TPDO pairs, three RPDOs) against simulated drive nodes:
//! - `inline_nodes`: the nodes answer inside the bus call (driver + node CPU cost only);
//! - `threaded_in_process`: the nodes run on their own thread behind the in-process bus
//!   (adds the queue hand-over and thread wake-up: the SYNC-to-TPDO round trip);
//!   and the PDO codecs alone.

use std::hint::black_box;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use videt_drivers::can::CanPort;
use videt_drivers::cia402::pdo::{Command, Motion, Status};
use videt_drivers::cia402::{Cia402DriveSet, DriveSetConfig};
use videt_hal::{DriveSample, Lifecycle, WireDrives};
use videt_sim::can_bus::{BusError, BusFaults, InProcessBus, InProcessEndpoint, SimFrame};
use videt_sim::cia402_node::{FreeMotorPlant, SimDriveBank, SimDriveSpec, SteppedDriveBus};

/// The WireMan's wire count (three drives, nodes 1, 2, 3).
const WIRES: usize = 3;

struct Inline(SteppedDriveBus<Arc<Mutex<FreeMotorPlant>>>);

impl embedded_can::blocking::Can for Inline {
    type Frame = SimFrame;
    type Error = BusError;
    fn transmit(&mut self, f: &SimFrame) -> Result<(), BusError> {
        self.0.send(f);
        Ok(())
    }
    fn receive(&mut self) -> Result<SimFrame, BusError> {
        loop {
            if let Some(f) = self.0.receive() {
                return Ok(f);
            }
            std::thread::sleep(Duration::from_micros(100));
        }
    }
}

impl CanPort for Inline {
    fn receive_timeout(&mut self, t: Duration) -> Result<Option<SimFrame>, BusError> {
        if let Some(f) = self.0.receive() {
            return Ok(Some(f));
        }
        if !t.is_zero() {
            std::thread::sleep(t.min(Duration::from_micros(200)));
        }
        Ok(self.0.receive())
    }
}

struct Threaded(InProcessEndpoint);

impl embedded_can::blocking::Can for Threaded {
    type Frame = SimFrame;
    type Error = BusError;
    fn transmit(&mut self, f: &SimFrame) -> Result<(), BusError> {
        self.0.send(f)
    }
    fn receive(&mut self) -> Result<SimFrame, BusError> {
        embedded_can::blocking::Can::receive(&mut self.0)
    }
}

impl CanPort for Threaded {
    fn receive_timeout(&mut self, t: Duration) -> Result<Option<SimFrame>, BusError> {
        self.0.receive_timeout(t)
    }
}

fn specs() -> Vec<SimDriveSpec> {
    (0..WIRES)
        .map(|i| SimDriveSpec {
            node_id: i as u8 + 1,
            axis: i,
            rated_torque_mnm: 25,
            boot_delay: Duration::from_millis(2),
        })
        .collect()
}

fn config() -> DriveSetConfig<WIRES> {
    let mut c = DriveSetConfig::new([1, 2, 3], Duration::from_millis(1), 0.025, 15.0);
    // A benchmark iteration is back to back, not paced: allow for the harness's pauses.
    // A loaded machine may stall the process for tens of ms: keep the drives' host-silence
    // reaction and the host's heartbeat check out of the measurement.
    c.drive_heartbeat_timeout = Duration::from_secs(10);
    c.host_silence_timeout_ms = 10_000;
    c.max_missed_cycles = u32::MAX;
    c
}

fn plant() -> Arc<Mutex<FreeMotorPlant>> {
    Arc::new(Mutex::new(FreeMotorPlant::new(WIRES, 1e-5, 1e-3, 2000.0)))
}

fn bench_cycle(c: &mut Criterion) {
    let mut g = c.benchmark_group("cia402_cycle");
    let mut out = [DriveSample::default(); WIRES];

    let mut inline =
        Cia402DriveSet::new(Inline(SteppedDriveBus::new(&specs(), plant())), config()).unwrap();
    inline.configure().unwrap();
    inline.activate().unwrap();
    g.bench_function("inline_nodes", |b| {
        b.iter(|| {
            inline.read_drives(&mut out).unwrap();
            inline.write_torques(black_box(&[0.001; WIRES])).unwrap();
        })
    });

    let mut eps = InProcessBus::with_endpoints(2, 256, Arc::new(BusFaults::default()));
    let node_side = eps.pop().unwrap();
    let host_side = eps.pop().unwrap();
    let _bank = SimDriveBank::spawn(node_side, &specs(), plant());
    let mut threaded = Cia402DriveSet::new(Threaded(host_side), config()).unwrap();
    threaded.configure().unwrap();
    threaded.activate().unwrap();
    g.bench_function("threaded_in_process", |b| {
        b.iter(|| {
            threaded.read_drives(&mut out).unwrap();
            threaded.write_torques(black_box(&[0.001; WIRES])).unwrap();
        })
    });
    g.finish();
}

fn bench_codec(c: &mut Criterion) {
    c.bench_function("pdo_codec/encode_decode_all_three", |b| {
        b.iter(|| {
            let cmd = Command {
                controlword: 0x0F,
                target_torque_permille: black_box(123),
            };
            let m = Motion::decode(black_box(&[1, 2, 3, 4, 5, 6, 7, 8])).unwrap();
            let s = Status::decode(black_box(&[0x37, 0x02, 0, 0])).unwrap();
            black_box((cmd.encode(), m.position, s.statusword))
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(Duration::from_secs(3));
    targets = bench_cycle, bench_codec
}
criterion_main!(benches);
