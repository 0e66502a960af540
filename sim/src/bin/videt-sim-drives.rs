//! `videt-sim-drives [HUB_ADDR] [NODE_IDS]` — three (or more) simulated CiA 402 drives with free
//! motors on the cross-process userspace CAN bus (see `videt-can-hub`), so a host process can
//! drive them over the bus. Node ids default to `1,2,3`; hub to `127.0.0.1:47800`.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use videt_sim::can_bus::udp::UdpEndpoint;
use videt_sim::can_bus::BusFaults;
use videt_sim::cia402_node::{FreeMotorPlant, SimDriveBank, SimDriveSpec};

fn main() -> std::process::ExitCode {
    let mut args = std::env::args().skip(1);
    let hub = args.next().unwrap_or_else(|| "127.0.0.1:47800".to_string());
    let ids = args.next().unwrap_or_else(|| "1,2,3".to_string());
    let hub: SocketAddr = match hub.parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("videt-sim-drives: hub address {hub:?}: {e}");
            return std::process::ExitCode::from(2);
        }
    };
    let mut specs = Vec::new();
    for (axis, id) in ids.split(',').enumerate() {
        match id.trim().parse::<u8>() {
            Ok(n @ 1..=127) => specs.push(SimDriveSpec {
                node_id: n,
                axis,
                rated_torque_mnm: 25,
                boot_delay: Duration::from_millis(20),
            }),
            _ => {
                eprintln!("videt-sim-drives: node id {id:?} is not in 1..=127");
                return std::process::ExitCode::from(2);
            }
        }
    }
    let port = match UdpEndpoint::connect(hub, Arc::new(BusFaults::default())) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("videt-sim-drives: cannot reach the hub at {hub}: {e}");
            return std::process::ExitCode::from(2);
        }
    };
    let plant = FreeMotorPlant::new(specs.len(), 1e-5, 1e-4, 2000.0);
    let _bank = SimDriveBank::spawn(port, &specs, plant);
    eprintln!(
        "videt-sim-drives: nodes {ids} on udp://{hub} (rated torque 25 mN·m); Ctrl-C to stop"
    );
    loop {
        std::thread::sleep(Duration::from_secs(3600));
    }
}
