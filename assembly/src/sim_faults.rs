//! Faults injected into the running twin through the service's control socket
//! (`{"cmd":"sim-fault","fault":"..."}`, `videt service sim-fault ...`): the soak and a
//! technician rehearsing a fault use it. Only a twin offers them; the device refuses.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use videt_sim::can_bus::BusFaults;
use videt_sim::cia402_node::NodeFaults;
use videt_sim::{FaultInbox, InboxFault, TwinFault};

/// Emergency code a drive raises for an injected `emcy` (0x7500: communication, generic).
pub const DEFAULT_EMCY_CODE: u16 = 0x7500;

/// The fault handles of a twin: its physics and, behind a CAN bus, the bus and the drives.
#[derive(Clone)]
pub struct SimFaultPort {
    /// The twin's inbox.
    pub twin: Arc<FaultInbox>,
    /// The simulated CAN bus (`None`: no bus, the HAL twin).
    pub bus: Option<Arc<BusFaults>>,
    /// The simulated drives, one per wire (empty: no drives).
    pub drives: Vec<Arc<NodeFaults>>,
    /// The scene's vision thread publishes nothing while set (`None`: no live scene).
    pub vision_stall: Option<Arc<AtomicBool>>,
    /// Wires of the twin's device (faults name wires 0 to `wires - 1`).
    pub wires: usize,
}

/// The faults `SimFaultPort::apply` knows, for errors and help.
pub const FAULTS: &str =
    "break:N, detach:N, sensor:N, sensor-restore, estop, estop-release, drive:N, \
     emcy:N[:CODE], emcy-clear:N, heartbeat:N, heartbeat-restore:N, bus-off, bus-on, vision-stall, \
     vision-resume";

impl SimFaultPort {
    /// Apply the fault `spec` names; returns what was done, or why not.
    pub fn apply(&self, spec: &str) -> Result<String, String> {
        let parts: Vec<&str> = spec.split(':').collect();
        let wire = |s: &str| {
            s.parse::<usize>()
                .ok()
                .filter(|w| *w < self.wires)
                .ok_or_else(|| {
                    let wires: Vec<String> = (0..self.wires).map(|w| w.to_string()).collect();
                    format!(
                        "fault {spec:?}: wire {s:?} must be one of the device's wires ({})",
                        wires.join(", ")
                    )
                })
        };
        let post = |f: InboxFault, what: String| {
            self.twin
                .post(f)
                .map(|()| what)
                .map_err(|_| "the twin has not taken the previous faults yet".to_string())
        };
        let drive = |s: &str| -> Result<&Arc<NodeFaults>, String> {
            let w = wire(s)?;
            self.drives.get(w).ok_or_else(|| {
                format!("fault {spec:?}: no simulated CAN drives (videtd --sim can)")
            })
        };
        let bus = || {
            self.bus
                .as_ref()
                .ok_or_else(|| format!("fault {spec:?}: no simulated CAN bus (videtd --sim can)"))
        };
        match parts.as_slice() {
            ["break", n] => post(
                InboxFault::Fault(TwinFault::BreakWire(wire(n)?)),
                format!("wire {n} breaks"),
            ),
            ["detach", n] => post(
                InboxFault::Fault(TwinFault::DetachWire(wire(n)?)),
                format!("wire {n} comes off the thimble"),
            ),
            ["sensor", n] => post(
                InboxFault::Fault(TwinFault::FailTensionSensor(wire(n)?)),
                format!("tension sensor {n} fails"),
            ),
            ["sensor-restore"] => post(
                InboxFault::RestoreTensionSensor,
                "the tension sensor works again".into(),
            ),
            ["estop"] => post(
                InboxFault::Fault(TwinFault::PressEStop),
                "the e-stop is pressed".into(),
            ),
            ["estop-release"] => post(InboxFault::ReleaseEStop, "the e-stop is released".into()),
            ["drive", n] => post(
                InboxFault::Fault(TwinFault::FaultDrive(wire(n)?)),
                format!("drive {n} faults"),
            ),
            ["emcy", n] | ["emcy", n, _] => {
                let code = match parts.get(2) {
                    None => DEFAULT_EMCY_CODE,
                    Some(c) => u16::from_str_radix(c.trim_start_matches("0x"), 16)
                        .map_err(|_| format!("fault {spec:?}: code {c:?} must be hexadecimal"))?,
                };
                drive(n)?.raise_fault(code);
                Ok(format!(
                    "drive {n} raises emergency {code:#06x} and latches a fault"
                ))
            }
            ["emcy-clear", n] => {
                drive(n)?.clear_fault();
                Ok(format!("drive {n}: the fault's cause is gone"))
            }
            ["heartbeat", n] => {
                drive(n)?.set_mute_heartbeat(true);
                Ok(format!("drive {n} stops its heartbeat"))
            }
            ["heartbeat-restore", n] => {
                drive(n)?.set_mute_heartbeat(false);
                Ok(format!("drive {n} beats again"))
            }
            ["bus-off"] => {
                bus()?.set_bus_off(true);
                Ok("the CAN bus goes off".into())
            }
            ["bus-on"] => {
                bus()?.set_bus_off(false);
                Ok("the CAN bus is back".into())
            }
            ["vision-stall"] | ["vision-resume"] => {
                let stall = self.vision_stall.as_ref().ok_or_else(|| {
                    format!("fault {spec:?}: no live scene (videtd --sim --scene box)")
                })?;
                let on = parts[0] == "vision-stall";
                stall.store(on, Ordering::Relaxed);
                Ok(if on {
                    "the vision thread stalls: no new relief".into()
                } else {
                    "the vision thread publishes again".into()
                })
            }
            _ => Err(format!("unknown fault {spec:?}: expected one of {FAULTS}")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use videt_runtime::WIREMAN_WIRES;

    #[test]
    fn faults_reach_their_handles_and_bad_ones_are_named() {
        let port = SimFaultPort {
            twin: Arc::new(FaultInbox::default()),
            bus: Some(Arc::new(BusFaults::default())),
            drives: (0..WIREMAN_WIRES)
                .map(|_| Arc::new(NodeFaults::default()))
                .collect(),
            vision_stall: Some(Arc::new(AtomicBool::new(false))),
            wires: WIREMAN_WIRES,
        };
        assert!(port.apply("sensor:1").unwrap().contains("sensor 1"));
        port.apply("bus-off").unwrap();
        assert!(port.bus.as_ref().unwrap().is_bus_off());
        port.apply("bus-on").unwrap();
        assert!(!port.bus.as_ref().unwrap().is_bus_off());
        assert!(port.apply("emcy:2:8611").unwrap().contains("0x8611"));
        port.apply("vision-stall").unwrap();
        assert!(port.vision_stall.as_ref().unwrap().load(Ordering::Relaxed));
        port.apply("vision-resume").unwrap();
        assert!(!port.vision_stall.as_ref().unwrap().load(Ordering::Relaxed));
        for bad in ["sensor:3", "break", "emcy:0:zz", "melt:1", ""] {
            let e = port.apply(bad).unwrap_err();
            assert!(e.contains(bad) || e.contains("unknown fault"), "{bad}: {e}");
        }
        let two_wires = SimFaultPort {
            wires: 2,
            ..port.clone()
        };
        let e = two_wires.apply("break:2").unwrap_err();
        assert!(e.contains("wires (0, 1)"), "{e}");
        let hal_twin = SimFaultPort {
            bus: None,
            drives: Vec::new(),
            vision_stall: None,
            ..port
        };
        assert!(hal_twin
            .apply("vision-stall")
            .unwrap_err()
            .contains("--scene box"));
        assert!(hal_twin.apply("bus-off").unwrap_err().contains("--sim can"));
        assert!(hal_twin
            .apply("heartbeat:0")
            .unwrap_err()
            .contains("--sim can"));
    }
}
