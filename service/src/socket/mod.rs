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
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

pub mod protocol;
pub mod requests;

pub use protocol::{
    reply, write_line, ClientRequest, ProcedureCommand, ProcedureRequest, Request, Response,
    StatusReport,
};
use requests::answer;
pub use requests::{handle, ServerShared};

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

/// Peer credentials: root, the service's own user, or a member of the socket's group (its
/// primary group or one of its supplementary groups: technicians join the group `videt`) may
/// talk to it.
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
    rc == 0
        && permits(cred.uid, me, socket_gid, || {
            let mut groups = peer_groups(stream);
            groups.push(cred.gid);
            groups
        })
}

/// Whether a peer with user `uid` and groups `groups` (primary and supplementary, asked for
/// only when the user alone does not decide) may talk to a service running as user `me`
/// whose socket belongs to group `socket_gid`.
fn permits(
    uid: libc::uid_t,
    me: libc::uid_t,
    socket_gid: libc::gid_t,
    groups: impl FnOnce() -> Vec<libc::gid_t>,
) -> bool {
    uid == 0 || uid == me || groups().contains(&socket_gid)
}

/// The peer's supplementary groups, as they were when it connected (`SO_PEERGROUPS`); empty
/// when the kernel cannot tell.
fn peer_groups(stream: &UnixStream) -> Vec<libc::gid_t> {
    let mut groups: Vec<libc::gid_t> = vec![0; 64];
    for _ in 0..2 {
        let mut len = (groups.len() * std::mem::size_of::<libc::gid_t>()) as libc::socklen_t;
        // SAFETY: `groups` is valid for writes of `len` bytes; the fd is a live socket.
        let rc = unsafe {
            libc::getsockopt(
                stream.as_raw_fd(),
                libc::SOL_SOCKET,
                libc::SO_PEERGROUPS,
                groups.as_mut_ptr().cast(),
                &mut len,
            )
        };
        let count = len as usize / std::mem::size_of::<libc::gid_t>();
        if rc == 0 {
            groups.truncate(count);
            return groups;
        }
        // ERANGE: `len` says how many there are.
        if io::Error::last_os_error().raw_os_error() != Some(libc::ERANGE) || count <= groups.len()
        {
            break;
        }
        groups.resize(count, 0);
    }
    Vec::new()
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
    use std::sync::Mutex;
    use videt_runtime::control_loop::ControlCommand;
    use videt_runtime::status::StatusSnapshot;

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
    fn the_peer_groups_are_the_connecting_process_groups() {
        let (a, _b) = UnixStream::pair().unwrap();
        let mut own: Vec<libc::gid_t> = vec![0; 256];
        // SAFETY: `own` has room for 256 groups.
        let n = unsafe { libc::getgroups(own.len() as i32, own.as_mut_ptr()) };
        assert!(n >= 0);
        own.truncate(n as usize);
        let mut peer = peer_groups(&a);
        own.sort_unstable();
        peer.sort_unstable();
        assert_eq!(peer, own);
        // The peer (this process) is authorised by its user.
        assert!(authorised(&a, u32::MAX));
    }

    #[test]
    fn a_member_of_the_socket_group_by_a_supplementary_group_is_permitted() {
        let (me, videt, tech) = (999, 990, 1000);
        // Root and the service's own user, whatever their groups.
        assert!(permits(0, me, videt, Vec::new));
        assert!(permits(me, me, videt, Vec::new));
        // A technician whose primary group is their own and who joined videt.
        assert!(permits(tech, me, videt, || vec![1000, 24, videt]));
        // ... or whose primary group is videt.
        assert!(permits(tech, me, videt, || vec![videt]));
        // Anyone else is refused.
        assert!(!permits(tech, me, videt, || vec![1000, 24]));
        assert!(!permits(tech, me, videt, Vec::new));
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
