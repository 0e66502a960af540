//! The local control socket: a Unix domain stream socket (mode 0660) through which the `videt`
//! tool talks to the running service. Protocol (documented in `docs/control-socket.md`): one JSON
//! object per line in each direction.
//!
//! Requests: `{"cmd":"status"}`, `{"cmd":"stop"}`, `{"cmd":"release","wire":N}`,
//! `{"cmd":"resume"}`, `{"cmd":"reset-faults"}`. Replies: `{"ok":true,...}` or
//! `{"ok":false,"error":"..."}`. `{"cmd":"init"}` and `{"cmd":"wire-replace","wire":N}` run a
//! procedure on the service's hardware and stream its progress on the connection
//! ([`crate::procedure_stream`]). A malformed, oversized or unauthorised request gets an error
//! reply; a slow client is disconnected after a timeout. Nothing a client does reaches the control
//! thread except through a wait-free command queue, so no client can disturb the loop.

use std::io::{self, BufRead, BufReader, Read, Write};
use std::os::unix::fs::PermissionsExt;
use std::os::unix::io::AsRawFd;
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::control_loop::ControlCommand;
use crate::status::StatusSnapshot;

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
    /// `init` or `wire-replace`.
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
            if command == ProcedureCommand::Init {
                if raw.wire.is_some() {
                    return Err("`init` takes no `wire`".to_string());
                }
                if raw.sim_new_wire_length_m.is_some() {
                    return Err("`init` takes no `sim_new_wire_length_m`".to_string());
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
            other => Err(format!(
                "unknown command `{other}` (status, stop, release, resume, reset-faults, init, wire-replace, continue, cancel, sim-fault)"
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
    /// Telemetry records dropped so far.
    pub telemetry_dropped: u64,
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
    fn ok() -> Response {
        Response {
            ok: true,
            error: None,
            status: None,
            done: None,
        }
    }
    fn ok_with(done: String) -> Response {
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
            procedure: None,
            tension_loop_gain_scale: s.tension_loop_degraded,
            fault: None,
            drives: Vec::new(),
        }
    }
}

/// What the socket server shares with the supervisor.
pub struct ServerShared {
    /// The latest status, refreshed by the supervisor.
    pub status: Mutex<StatusReport>,
    /// Commands to the control thread (the server side is the only producer).
    pub commands: Mutex<rtrb::Producer<ControlCommand>>,
    /// Procedures on the service's hardware (`None`: this service runs none).
    pub procedures: Option<crate::init::remote::ProcedurePort>,
    /// Fault injection into the running twin (`None`: on the device).
    pub sim_faults: Option<crate::sim_faults::SimFaultPort>,
    /// Wires of the service's device (wire numbers run from 0 to `wires - 1`).
    pub wires: usize,
}

/// Settings of the server.
#[derive(Debug, Clone)]
pub struct ServerSettings {
    /// Socket path.
    pub path: PathBuf,
    /// Largest request line, bytes.
    pub max_request_bytes: usize,
    /// Idle clients are dropped after this long.
    pub client_timeout: Duration,
    /// Most clients served at once; more get a "busy" reply.
    pub max_clients: usize,
}

/// The running server.
pub struct Server {
    handle: JoinHandle<()>,
    shutdown: Arc<AtomicBool>,
    path: PathBuf,
}

impl Server {
    /// Stop accepting, remove the socket file, wait for the accept thread.
    pub fn stop(self) {
        self.shutdown.store(true, Ordering::Release);
        let _ = self.handle.join();
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Why the server could not start.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    /// Another service answers on the socket.
    #[error("another videtd is already running on {0}")]
    InUse(PathBuf),
    /// I/O failure.
    #[error("control socket {path}: {source}")]
    Io {
        /// The socket path.
        path: PathBuf,
        /// The error.
        source: io::Error,
    },
}

/// Bind the socket (mode 0660; a stale socket file is replaced) and serve clients on a thread.
pub fn serve(settings: ServerSettings, shared: Arc<ServerShared>) -> Result<Server, ServerError> {
    let path = settings.path.clone();
    let io_err = |source| ServerError::Io {
        path: path.clone(),
        source,
    };
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(io_err)?;
    }
    if path.exists() {
        if UnixStream::connect(&path).is_ok() {
            return Err(ServerError::InUse(path));
        }
        std::fs::remove_file(&path).map_err(io_err)?;
    }
    let listener = UnixListener::bind(&path).map_err(io_err)?;
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o660)).map_err(io_err)?;
    listener.set_nonblocking(true).map_err(io_err)?;
    let socket_gid = std::fs::metadata(&path)
        .map(|m| std::os::unix::fs::MetadataExt::gid(&m))
        .map_err(io_err)?;
    let shutdown = Arc::new(AtomicBool::new(false));
    let stop = Arc::clone(&shutdown);
    let handle = std::thread::Builder::new()
        .name("videt-socket".into())
        .spawn(move || accept_loop(listener, settings, shared, stop, socket_gid))
        .map_err(io_err)?;
    Ok(Server {
        handle,
        shutdown,
        path,
    })
}

fn accept_loop(
    listener: UnixListener,
    settings: ServerSettings,
    shared: Arc<ServerShared>,
    shutdown: Arc<AtomicBool>,
    socket_gid: u32,
) {
    let active = Arc::new(AtomicUsize::new(0));
    while !shutdown.load(Ordering::Acquire) {
        match listener.accept() {
            Ok((mut stream, _)) => {
                let _ = stream.set_nonblocking(false);
                let _ = stream.set_write_timeout(Some(settings.client_timeout));
                if active.load(Ordering::Acquire) >= settings.max_clients {
                    let _ = reply(&mut stream, &Response::error("busy: too many clients"));
                    continue;
                }
                if !authorised(&stream, socket_gid) {
                    let _ = reply(
                        &mut stream,
                        &Response::error("unauthorised: not root, the service's user or its group"),
                    );
                    continue;
                }
                active.fetch_add(1, Ordering::AcqRel);
                let (shared, settings, slot) =
                    (Arc::clone(&shared), settings.clone(), Arc::clone(&active));
                let spawned = std::thread::Builder::new()
                    .name("videt-client".into())
                    .spawn(move || {
                        let _ = serve_client(stream, &settings, &shared);
                        slot.fetch_sub(1, Ordering::AcqRel);
                    });
                if spawned.is_err() {
                    // The thread never ran: give its slot back.
                    active.fetch_sub(1, Ordering::AcqRel);
                }
            }
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(10))
            }
            Err(_) => std::thread::sleep(Duration::from_millis(10)),
        }
    }
}

/// Peer credentials: root, the service's own user, or the socket's group may talk to it.
fn authorised(stream: &UnixStream, socket_gid: u32) -> bool {
    let mut cred = libc::ucred {
        pid: 0,
        uid: u32::MAX,
        gid: u32::MAX,
    };
    let mut len = std::mem::size_of::<libc::ucred>() as libc::socklen_t;
    // SAFETY: `cred` and `len` are valid for writes of the sizes given; the fd is a live socket.
    let rc = unsafe {
        libc::getsockopt(
            stream.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_PEERCRED,
            (&mut cred as *mut libc::ucred).cast(),
            &mut len,
        )
    };
    // SAFETY: geteuid has no preconditions.
    let me = unsafe { libc::geteuid() };
    rc == 0 && (cred.uid == 0 || cred.uid == me || cred.gid == socket_gid)
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

fn serve_client(
    stream: UnixStream,
    settings: &ServerSettings,
    shared: &ServerShared,
) -> io::Result<()> {
    stream.set_read_timeout(Some(settings.client_timeout))?;
    let mut writer = stream.try_clone()?;
    let mut reader = BufReader::new(stream).take(0);
    loop {
        // Read one line of at most max_request_bytes (+1 to detect an oversized one).
        reader.set_limit(settings.max_request_bytes as u64 + 1);
        let mut line = Vec::new();
        match reader.read_until(b'\n', &mut line) {
            Ok(0) => return Ok(()),
            Ok(_) => {}
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                ) =>
            {
                let _ = reply(
                    &mut writer,
                    &Response::error("timeout: no complete request in time"),
                );
                return Ok(());
            }
            Err(e) => return Err(e),
        }
        if line.len() > settings.max_request_bytes {
            reply(
                &mut writer,
                &Response::error(format!(
                    "request too large (limit {} bytes)",
                    settings.max_request_bytes
                )),
            )?;
            return Ok(());
        }
        let last = !line.ends_with(b"\n");
        let parsed = ClientRequest::parse(&line);
        if let Ok(ClientRequest::Procedure(procedure)) = &parsed {
            // The connection carries the procedure's stream until it ends.
            crate::procedure_stream::serve(&mut reader, &mut writer, procedure, shared)?;
            reader
                .get_ref()
                .get_ref()
                .set_read_timeout(Some(settings.client_timeout))?;
            if last {
                return Ok(());
            }
            continue;
        }
        let response = answer(parsed.and_then(Request::one_reply), shared);
        reply(&mut writer, &response)?;
        if last {
            // End of stream without a newline: answered, now close.
            return Ok(());
        }
    }
}

/// Answer one request line.
pub fn handle(line: &[u8], shared: &ServerShared) -> Response {
    answer(Request::parse(line), shared)
}

/// Answer one parsed request line (or say why it could not be parsed).
fn answer(request: Result<Request, String>, shared: &ServerShared) -> Response {
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

/// Send one request to a running service and wait for the reply (client side, for the tool).
pub fn request(path: &Path, request: &Request, timeout: Duration) -> io::Result<Response> {
    let mut stream = UnixStream::connect(path)?;
    stream.set_read_timeout(Some(timeout))?;
    stream.set_write_timeout(Some(timeout))?;
    let mut line = serde_json::to_vec(request).map_err(io::Error::other)?;
    line.push(b'\n');
    stream.write_all(&line)?;
    let mut reply = String::new();
    BufReader::new(stream).read_line(&mut reply)?;
    serde_json::from_str(&reply).map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shared() -> (Arc<ServerShared>, rtrb::Consumer<ControlCommand>) {
        let (producer, consumer) = rtrb::RingBuffer::new(4);
        let status = StatusReport::from_snapshot(&StatusSnapshot::default(), 0);
        (
            Arc::new(ServerShared {
                wires: 3,
                status: Mutex::new(status),
                commands: Mutex::new(producer),
                procedures: None,
                sim_faults: None,
            }),
            consumer,
        )
    }

    #[test]
    fn sim_faults_parse_and_are_refused_off_the_twin() {
        let r = Request::parse(br#"{"cmd":"sim-fault","fault":"sensor:1"}"#).unwrap();
        assert_eq!(
            r,
            Request::SimFault {
                fault: "sensor:1".into()
            }
        );
        assert_eq!(Request::parse(&serde_json::to_vec(&r).unwrap()), Ok(r));
        let e = Request::parse(br#"{"cmd":"sim-fault"}"#).unwrap_err();
        assert!(e.contains("needs `fault`"), "{e}");
        let e = Request::parse(br#"{"cmd":"status","fault":"x"}"#).unwrap_err();
        assert!(e.contains("takes no `fault`"), "{e}");
        let (s, _commands) = shared();
        let reply = handle(br#"{"cmd":"sim-fault","fault":"estop"}"#, &s);
        assert!(!reply.ok);
        assert!(reply.error.unwrap().contains("digital twin only"));
    }

    #[test]
    fn requests_map_to_commands_and_bad_ones_to_errors() {
        let (s, mut commands) = shared();
        assert!(handle(br#"{"cmd":"release","wire":2}"#, &s).ok);
        assert_eq!(commands.pop(), Ok(ControlCommand::ReleaseWire(2)));
        assert!(!handle(br#"{"cmd":"release","wire":7}"#, &s).ok);
        let r = handle(b"{nonsense", &s);
        assert!(!r.ok && r.error.unwrap().contains("malformed"));
        assert!(!handle(br#"{"cmd":"launch-rockets"}"#, &s).ok);
        assert!(!handle(br#"{"cmd":"status","extra":1}"#, &s).ok);
        assert!(!handle(br#"{"cmd":"stop","wire":1}"#, &s).ok);
        assert!(!handle(br#"{"cmd":"release"}"#, &s).ok);
        assert!(handle(br#"{"cmd":"status"}"#, &s).status.is_some());
        for r in [
            Request::Status,
            Request::Stop,
            Request::Release { wire: 1 },
            Request::Resume,
            Request::ResetFaults,
        ] {
            assert_eq!(
                Request::parse(&serde_json::to_vec(&r).unwrap()),
                Ok(r),
                "the client's encoding parses"
            );
        }
        for _ in 0..4 {
            assert!(handle(br#"{"cmd":"resume"}"#, &s).ok);
        }
        let full = handle(br#"{"cmd":"resume"}"#, &s);
        assert!(
            !full.ok && full.error.unwrap().contains("busy"),
            "a full queue is an error, not a wait"
        );
    }

    #[test]
    fn server_answers_and_survives_bad_clients() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.sock");
        let (s, mut commands) = shared();
        let settings = ServerSettings {
            path: path.clone(),
            max_request_bytes: 256,
            client_timeout: Duration::from_millis(300),
            max_clients: 4,
        };
        let server = serve(settings, Arc::clone(&s)).unwrap();
        let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o660);
        assert!(matches!(
            serve(
                ServerSettings {
                    path: path.clone(),
                    max_request_bytes: 256,
                    client_timeout: Duration::from_millis(300),
                    max_clients: 4
                },
                Arc::clone(&s)
            ),
            Err(ServerError::InUse(_))
        ));

        // Oversized request: an error reply, then the connection closes.
        let mut big = UnixStream::connect(&path).unwrap();
        big.write_all(&vec![b'x'; 1000]).unwrap();
        let mut reply_line = String::new();
        BufReader::new(big).read_line(&mut reply_line).unwrap();
        assert!(reply_line.contains("too large"), "{reply_line}");

        // A silent client is dropped after the timeout; meanwhile others are served.
        let _silent = UnixStream::connect(&path).unwrap();
        let r = request(&path, &Request::Status, Duration::from_secs(2)).unwrap();
        assert!(r.ok && r.status.is_some());
        let r = request(&path, &Request::Stop, Duration::from_secs(2)).unwrap();
        assert!(r.ok);
        assert_eq!(commands.pop(), Ok(ControlCommand::Stop));
        server.stop();
        assert!(!path.exists());
    }
}
