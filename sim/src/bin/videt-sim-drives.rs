//! `videt-sim-drives [HUB_ADDR] [NODE_IDS]` — three (or more) simulated CiA 402 drives with free
//! motors on the cross-process userspace CAN bus (see `videt-can-hub`), so a host process can
//! drive them over the bus. Node ids default to `1,2,3`; hub to `127.0.0.1:47800`.
//!
//! `videt-sim-drives --can IFACE [NODE_IDS]` puts the same drives on a kernel CAN interface
//! (SocketCAN: `vcan0`, `can0`) instead, so the host's driver goes through the kernel's CAN
//! stack. (`videt sim-rig` serves the whole twin, wires and operator, the same way.)

use std::sync::Arc;
use std::time::Duration;

use videt_sim::can_bus::udp::UdpEndpoint;
use videt_sim::can_bus::BusFaults;
use videt_sim::cia402_node::{FreeMotorPlant, SimDriveBank, SimDriveSpec, SimPort};

/// Where the drives sit.
enum Bus {
    /// The userspace hub at this address.
    Hub(String),
    /// A kernel CAN interface.
    Kernel(String),
}

fn usage(why: &str) -> std::process::ExitCode {
    eprintln!("videt-sim-drives: {why}");
    eprintln!(
        "usage: videt-sim-drives [HUB_ADDR] [NODE_IDS] | videt-sim-drives --can IFACE [NODE_IDS]"
    );
    std::process::ExitCode::from(2)
}

fn main() -> std::process::ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (bus, rest) = match args.first().map(String::as_str) {
        Some("--can") => match args.get(1) {
            Some(iface) => (Bus::Kernel(iface.clone()), &args[2..]),
            None => return usage("--can needs an interface name"),
        },
        Some("-h" | "--help") => return usage("simulated CiA 402 drives"),
        Some(hub) => (Bus::Hub(hub.to_string()), &args[1..]),
        None => (Bus::Hub("127.0.0.1:47800".into()), &args[..]),
    };
    let ids = rest.first().cloned().unwrap_or_else(|| "1,2,3".to_string());
    let mut specs = Vec::new();
    for (axis, id) in ids.split(',').enumerate() {
        match id.trim().parse::<u8>() {
            Ok(n @ 1..=127) => specs.push(SimDriveSpec {
                node_id: n,
                axis,
                rated_torque_mnm: 25,
                boot_delay: Duration::from_millis(20),
            }),
            _ => return usage(&format!("node id {id:?} is not in 1..=127")),
        }
    }
    let plant = FreeMotorPlant::new(specs.len(), 1e-5, 1e-4, 2000.0);
    let (_bank, place) = match bus {
        Bus::Hub(hub) => {
            let addr = match hub.parse() {
                Ok(a) => a,
                Err(e) => return usage(&format!("hub address {hub:?}: {e}")),
            };
            match UdpEndpoint::connect(addr, Arc::new(BusFaults::default())) {
                Ok(p) => (spawn(p, &specs, plant), format!("udp://{hub}")),
                Err(e) => {
                    eprintln!("videt-sim-drives: cannot reach the hub at {hub}: {e}");
                    return std::process::ExitCode::from(2);
                }
            }
        }
        Bus::Kernel(iface) => {
            match videt_sim::can_bus::socketcan::SocketCanEndpoint::open(&iface) {
                Ok(p) => (spawn(p, &specs, plant), format!("CAN interface {iface}")),
                Err(e) => {
                    eprintln!("videt-sim-drives: CAN interface {iface}: {e}");
                    return std::process::ExitCode::from(2);
                }
            }
        }
    };
    eprintln!("videt-sim-drives: nodes {ids} on {place} (rated torque 25 mN·m); Ctrl-C to stop");
    loop {
        std::thread::sleep(Duration::from_secs(3600));
    }
}

fn spawn<P: SimPort + 'static>(
    port: P,
    specs: &[SimDriveSpec],
    plant: FreeMotorPlant,
) -> SimDriveBank {
    SimDriveBank::spawn(port, specs, plant)
}
