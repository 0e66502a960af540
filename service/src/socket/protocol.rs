//! The control socket's protocol: the requests a client sends and the replies it gets, one JSON
//! object per line in each direction (`docs/control-socket.md`).

use std::io::{self, Write};
use std::os::unix::net::UnixStream;

use serde::{Deserialize, Serialize};

use videt_runtime::status::StatusSnapshot;

/// A request from a client (also the `videt service` subcommands).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, clap::Subcommand)]
#[serde(tag = "cmd", rename_all = "kebab-case")]
pub enum Request {
    /// Loop rate, safety state, thimble, tensions, contact.
    Status,
    /// Ramp the forces out, power the drives off and stop the service.
    Stop,
    /// Release wire N (0, 1 or 2) so it can be pulled out and replaced.
    Release {
        /// Wire index.
        wire: u8,
    },
    /// Leave the released-wire mode.
    Resume,
    /// Clear latched faults that do not need a restart.
    ResetFaults,
    /// On the twin only: inject a fault into the running twin (`sensor:1`, `bus-off`, ...;
    /// see `videt service sim-fault --help`).
    SimFault {
        /// The fault: break:N, detach:N, sensor:N, sensor-restore, estop, estop-release,
        /// drive:N, emcy:N[:CODE], emcy-clear:N, heartbeat:N, heartbeat-restore:N, bus-off,
        /// bus-on.
        fault: String,
    },
}

/// The wire form of a request, parsed strictly (unknown fields rejected).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct WireRequest {
    cmd: String,
    #[serde(default)]
    wire: Option<u8>,
    #[serde(default)]
    yes: Option<bool>,
    #[serde(default)]
    sim_seed: Option<u64>,
    #[serde(default)]
    sim_faults: Option<Vec<String>>,
    #[serde(default)]
    sim_new_wire_length_m: Option<f64>,
    #[serde(default)]
    fault: Option<String>,
}

/// A procedure the service runs on its own hardware, streaming its progress back
/// (`{"cmd":"init"}`, `{"cmd":"wire-replace","wire":N}`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProcedureRequest {
    /// `init`, `wire-replace` or `commission`.
    pub cmd: ProcedureCommand,
    /// The wire to replace (`wire-replace`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wire: Option<u8>,
    /// The manual steps are already done: the service does not wait for `continue`.
    pub yes: bool,
    /// On a twin: where its technician connects the thimble.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sim_seed: Option<u64>,
    /// On a twin: faults to rehearse (`videt init --sim-fault` syntax).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub sim_faults: Vec<String>,
    /// On a twin: usable length of the new yarn, metres (`wire-replace`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sim_new_wire_length_m: Option<f64>,
}

/// Which procedure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ProcedureCommand {
    /// Auto-initialization.
    Init,
    /// Wire replacement, then auto-initialization.
    WireReplace,
    /// The commissioning check of the rig.
    Commission,
}

/// Any line a client may send.
#[derive(Debug, Clone, PartialEq)]
pub enum ClientRequest {
    /// A one-reply request.
    Simple(Request),
    /// Start a procedure (a stream of replies follows).
    Procedure(ProcedureRequest),
    /// During a procedure: the manual step asked for is done.
    Continue,
    /// During a procedure: abort it.
    Cancel,
}

impl ClientRequest {
    /// Parse one request line; the error says what is wrong.
    pub fn parse(line: &[u8]) -> Result<ClientRequest, String> {
        let raw: WireRequest = serde_json::from_slice(line).map_err(|e| e.to_string())?;
        let cmd = raw.cmd.as_str();
        if cmd != "sim-fault" && raw.fault.is_some() {
            return Err(format!("`{cmd}` takes no `fault`"));
        }
        let procedure_field = [
            ("yes", raw.yes.is_some()),
            ("sim_seed", raw.sim_seed.is_some()),
            ("sim_faults", raw.sim_faults.is_some()),
            ("sim_new_wire_length_m", raw.sim_new_wire_length_m.is_some()),
        ]
        .into_iter()
        .find(|(_, given)| *given)
        .map(|(name, _)| name);
        let plain = |r: ClientRequest| match (raw.wire, procedure_field) {
            (None, None) => Ok(r),
            (Some(_), _) => Err(format!("`{cmd}` takes no `wire`")),
            (None, Some(field)) => Err(format!("`{cmd}` takes no `{field}`")),
        };
        let procedure = |command: ProcedureCommand| {
            if command != ProcedureCommand::WireReplace {
                if raw.wire.is_some() {
                    return Err(format!("`{cmd}` takes no `wire`"));
                }
                if raw.sim_new_wire_length_m.is_some() {
                    return Err(format!("`{cmd}` takes no `sim_new_wire_length_m`"));
                }
            } else if raw.wire.is_none() {
                return Err("`wire-replace` needs `wire`".to_string());
            }
            Ok(ClientRequest::Procedure(ProcedureRequest {
                cmd: command,
                wire: raw.wire,
                yes: raw.yes.unwrap_or(false),
                sim_seed: raw.sim_seed,
                sim_faults: raw.sim_faults.clone().unwrap_or_default(),
                sim_new_wire_length_m: raw.sim_new_wire_length_m,
            }))
        };
        match cmd {
            "status" => plain(ClientRequest::Simple(Request::Status)),
            "stop" => plain(ClientRequest::Simple(Request::Stop)),
            "resume" => plain(ClientRequest::Simple(Request::Resume)),
            "reset-faults" => plain(ClientRequest::Simple(Request::ResetFaults)),
            "continue" => plain(ClientRequest::Continue),
            "cancel" => plain(ClientRequest::Cancel),
            "release" => match (raw.wire, procedure_field) {
                (Some(wire), None) => Ok(ClientRequest::Simple(Request::Release { wire })),
                (None, _) => Err("`release` needs `wire`".to_string()),
                (Some(_), Some(field)) => Err(format!("`release` takes no `{field}`")),
            },
            "sim-fault" => match raw.fault.clone() {
                Some(fault) => plain(ClientRequest::Simple(Request::SimFault { fault })),
                None => Err("`sim-fault` needs `fault`".to_string()),
            },
            "init" => procedure(ProcedureCommand::Init),
            "wire-replace" => procedure(ProcedureCommand::WireReplace),
            "commission" => procedure(ProcedureCommand::Commission),
            other => Err(format!(
                "unknown command `{other}` (status, stop, release, resume, reset-faults, init, wire-replace, commission, continue, cancel, sim-fault)"
            )),
        }
    }
}

impl Request {
    /// Parse one one-reply request line; the error says what is wrong.
    pub fn parse(line: &[u8]) -> Result<Request, String> {
        Self::one_reply(ClientRequest::parse(line)?)
    }

    /// The one-reply request `request` is, or why it is not one.
    pub fn one_reply(request: ClientRequest) -> Result<Request, String> {
        match request {
            ClientRequest::Simple(r) => Ok(r),
            ClientRequest::Procedure(p) => Err(format!(
                "`{}` streams its replies: send it on a connection of its own",
                serde_json::to_value(p.cmd)
                    .ok()
                    .and_then(|v| v.as_str().map(str::to_string))
                    .unwrap_or_default()
            )),
            ClientRequest::Continue | ClientRequest::Cancel => {
                Err("no procedure runs on this connection".to_string())
            }
        }
    }
}

/// The status part of a reply.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StatusReport {
    /// Service time, seconds.
    pub time_s: f64,
    /// Achieved loop rate over the last second, Hz.
    pub rate_hz: f64,
    /// Control periods run.
    pub cycles: u64,
    /// Missed deadlines since start.
    pub overruns: u64,
    /// Worst wake-up latency over the last second, microseconds.
    pub worst_wake_latency_us: f64,
    /// Safety state: `normal` or the reason for the safe state.
    pub safety: String,
    /// Whether the drives are powered off by the safety supervisor.
    pub power_off: bool,
    /// Thimble position, metres.
    pub position_m: [f64; 3],
    /// The device (`wireman3`, `planar2`, `polar1`; absent from older services: the WireMan).
    #[serde(default = "wireman")]
    pub device: String,
    /// Measured wire tensions, newtons, one per wire of the device.
    pub tensions_n: Vec<f64>,
    /// Touching the surface.
    pub in_contact: bool,
    /// Rendered force magnitude, newtons.
    pub force_n: f64,
    /// Wire released for replacement, if any.
    pub released_wire: Option<u8>,
    /// The surface is stale (forces faded out).
    pub surface_stale: bool,
    /// Telemetry records dropped so far (a full ring).
    pub telemetry_dropped: u64,
    /// Telemetry records lost so far because the session log's disk refused them.
    #[serde(default)]
    pub telemetry_lost: u64,
    /// While the session log cannot be written: why (a full disk, an I/O error).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub telemetry_error: Option<String>,
    /// A procedure running on the service's hardware (`init`, `wire-replace`), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub procedure: Option<String>,
    /// The fraction of the configured PI gains the tension loop runs with, when degraded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tension_loop_gain_scale: Option<f64>,
    /// In a safe state: the latest cause the hardware told since it left normal operation
    /// (`drives: drive of wire 2 (node 3): emergency 0x8611 ...`), if it told one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fault: Option<String>,
    /// Each drive's identity read at start-up (device type, vendor, product, revision, serial;
    /// empty on hardware without CANopen drives).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub drives: Vec<crate::drive_report::DriveStatus>,
}

fn wireman() -> String {
    "wireman3".into()
}

/// A reply.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Response {
    /// Whether the request was carried out.
    pub ok: bool,
    /// What went wrong, when not ok.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// The status, for `status`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub status: Option<StatusReport>,
    /// What was done, for `sim-fault`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub done: Option<String>,
}

impl Response {
    pub(crate) fn ok() -> Response {
        Response {
            ok: true,
            error: None,
            status: None,
            done: None,
        }
    }
    pub(crate) fn ok_with(done: String) -> Response {
        Response {
            done: Some(done),
            ..Response::ok()
        }
    }
    /// An error reply.
    pub fn error(message: impl Into<String>) -> Response {
        Response {
            ok: false,
            error: Some(message.into()),
            status: None,
            done: None,
        }
    }
}

impl StatusReport {
    /// The report for a snapshot.
    pub fn from_snapshot(s: &StatusSnapshot, telemetry_dropped: u64) -> StatusReport {
        let r = &s.record;
        let f = r.rendered_force_n;
        StatusReport {
            time_s: r.time.as_secs_f64(),
            rate_hz: s.window.rate_hz,
            cycles: r.cycle + u64::from(r.cycle > 0 || s.window.rate_hz > 0.0),
            overruns: s.window.overruns_total,
            worst_wake_latency_us: s.window.worst_latency_ns as f64 * 1e-3,
            safety: r.safety.as_str().to_string(),
            power_off: r.safety.power_off(),
            position_m: r.position_m,
            device: s.device.to_string(),
            tensions_n: s.tensions_n().to_vec(),
            in_contact: r.in_contact,
            force_n: (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt(),
            released_wire: u8::try_from(r.released_wire).ok(),
            surface_stale: r.surface_stale,
            telemetry_dropped,
            telemetry_lost: 0,
            telemetry_error: None,
            procedure: None,
            tension_loop_gain_scale: s.tension_loop_degraded,
            fault: None,
            drives: Vec::new(),
        }
    }
}

/// Write one reply line.
pub fn reply(stream: &mut UnixStream, response: &Response) -> io::Result<()> {
    write_line(stream, response)
}

/// Write `value` as one JSON line (the socket protocol's framing), in one write.
pub fn write_line<T: Serialize + ?Sized>(stream: &mut impl Write, value: &T) -> io::Result<()> {
    let mut line = serde_json::to_vec(value).map_err(io::Error::other)?;
    line.push(b'\n');
    stream.write_all(&line)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_degraded_tension_loop_reaches_the_status_reply() {
        let s = StatusSnapshot {
            tension_loop_degraded: Some(0.656),
            ..StatusSnapshot::default()
        };
        let report = StatusReport::from_snapshot(&s, 0);
        assert_eq!(report.tension_loop_gain_scale, Some(0.656));
    }
}
