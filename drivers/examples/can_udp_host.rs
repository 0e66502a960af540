//! Drive simulated CiA 402 drives in another process over the cross-process userspace CAN bus:
//!
//! ```text
//! videt-can-hub &                 # the bus
//! videt-sim-drives &              # nodes 1, 2, 3
//! cargo run -p videt-drivers --example can_udp_host -- 127.0.0.1:47800 [PERIOD_MS]
//! ```
//!
//! Configures and enables the three drives, commands 5 mN·m for 1000 cycles (default period
//! 2 ms: each exchange crosses the hub four times), prints the encoder positions and the
//! exchange times, then disables the drives.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};

use videt_drivers::can::CanPort;
use videt_drivers::cia402::{Cia402DriveSet, DriveSetConfig};
use videt_hal::{DriveSample, Lifecycle, WireDrives};
use videt_sim::can_bus::udp::UdpEndpoint;
use videt_sim::can_bus::{BusError, BusFaults, SimFrame};

/// The WireMan's wire count (three drives, nodes 1, 2, 3).
const WIRES: usize = 3;

struct Port(UdpEndpoint);

impl embedded_can::blocking::Can for Port {
    type Frame = SimFrame;
    type Error = BusError;
    fn transmit(&mut self, f: &SimFrame) -> Result<(), BusError> {
        self.0.send(f)
    }
    fn receive(&mut self) -> Result<SimFrame, BusError> {
        embedded_can::blocking::Can::receive(&mut self.0)
    }
}

impl CanPort for Port {
    fn receive_timeout(&mut self, t: Duration) -> Result<Option<SimFrame>, BusError> {
        self.0.receive_timeout(t)
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let hub: SocketAddr = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "127.0.0.1:47800".into())
        .parse()?;
    let port = Port(UdpEndpoint::connect(hub, Arc::new(BusFaults::default()))?);
    let period_ms: f64 = match std::env::args().nth(2) {
        Some(p) => p.parse()?,
        None => 2.0,
    };
    let period = Duration::from_secs_f64(period_ms / 1000.0);
    let mut cfg = DriveSetConfig::new([1, 2, 3], period, 0.025, 15.0);
    cfg.boot_timeout = Duration::from_secs(2);
    let mut set = Cia402DriveSet::new(port, cfg)?;
    let t0 = Instant::now();
    set.configure()?;
    let t1 = Instant::now();
    set.activate()?;
    println!("configured in {:?}, enabled in {:?}", t1 - t0, t1.elapsed());
    let mut out = [DriveSample::default(); WIRES];
    let mut exchange = Vec::with_capacity(1000);
    let start = Instant::now();
    let mut next = start;
    for _ in 0..1000 {
        let c = Instant::now();
        set.read_drives(&mut out)?;
        set.write_torques(&[0.005; WIRES])?;
        exchange.push(c.elapsed());
        next += period;
        if let Some(d) = next.checked_duration_since(Instant::now()) {
            std::thread::sleep(d);
        }
    }
    exchange.sort();
    println!(
        "1000 cycles in {:?}; exchange median {:?}, 99th percentile {:?}, worst {:?}; positions {:?} counts",
        start.elapsed(),
        exchange[500],
        exchange[990],
        exchange[999],
        out.map(|s| s.position_counts)
    );
    set.deactivate()?;
    Ok(())
}
