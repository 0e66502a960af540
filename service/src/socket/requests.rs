//! Answering one request line: what the socket server shares with the supervisor, and the
//! answer to each request a client may send outside a procedure's stream.

use std::sync::Mutex;

use videt_runtime::control_loop::ControlCommand;

use super::protocol::{Request, Response, StatusReport};

/// What the socket server shares with the supervisor.
pub struct ServerShared {
    /// The latest status, refreshed by the supervisor.
    pub status: Mutex<StatusReport>,
    /// Commands to the control thread (the server side is the only producer).
    pub commands: Mutex<rtrb::Producer<ControlCommand>>,
    /// Procedures on the service's hardware (`None`: this service runs none).
    pub procedures: Option<crate::init::remote::ProcedurePort>,
    /// Fault injection into the running twin (`None`: on the device).
    pub sim_faults: Option<videt_assembly::sim_faults::SimFaultPort>,
    /// Wires of the service's device (wire numbers run from 0 to `wires - 1`).
    pub wires: usize,
}

/// Answer one request line.
pub fn handle(line: &[u8], shared: &ServerShared) -> Response {
    answer(Request::parse(line), shared)
}

/// Answer one parsed request line (or say why it could not be parsed).
pub fn answer(request: Result<Request, String>, shared: &ServerShared) -> Response {
    let request = match request {
        Ok(r) => r,
        Err(e) => return Response::error(format!("malformed request: {e}")),
    };
    let command = match request {
        Request::Status => {
            let status = shared.status.lock().map(|s| s.clone()).ok();
            return Response {
                ok: status.is_some(),
                error: None,
                status,
                done: None,
            };
        }
        Request::Stop => ControlCommand::Stop,
        Request::Release { wire } if usize::from(wire) < shared.wires => {
            ControlCommand::ReleaseWire(wire)
        }
        Request::Release { wire } => {
            let names: Vec<String> = (0..shared.wires).map(|w| w.to_string()).collect();
            return Response::error(format!(
                "no wire {wire}: the device's wires are {}",
                names.join(", ")
            ));
        }
        Request::Resume => ControlCommand::Resume,
        Request::ResetFaults => ControlCommand::ResetFaults,
        Request::SimFault { fault } => {
            return match &shared.sim_faults {
                None => Response::error(
                    "sim-fault: faults are injected into the digital twin only (videtd --sim)",
                ),
                Some(port) => match port.apply(&fault) {
                    Ok(done) => Response::ok_with(done),
                    Err(e) => Response::error(e),
                },
            }
        }
    };
    let pushed = shared
        .commands
        .lock()
        .map(|mut p| p.push(command).is_ok())
        .unwrap_or(false);
    if pushed {
        Response::ok()
    } else {
        Response::error("busy: the control thread has not taken the previous commands yet")
    }
}
