//! The cross-process bus: endpoints in separate processes exchange frames as UDP datagrams
//! on the loopback interface through a tiny hub that forwards every frame to every other
//! registered endpoint.
//!
//! Datagrams: a frame is 16 bytes ([`SimFrame::to_wire`]); a 1-byte `0xFF` is an endpoint's
//! registration ("hello"). The hub learns endpoints by their source address.
//!
//! A hub with a bit rate ([`UdpHub::spawn_timed`]) is the bus's wire: it queues the frames it
//! receives, lets the lowest identifier win each arbitration and forwards a frame when its last
//! bit has been sent ([`super::wire`]).

use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::wire::{Arbiter, BusStats, QueuedFrame, Transmission};
use super::{BusError, BusFaults, SimFrame, TIMED_BUS_QUEUE};

/// The registration datagram an endpoint sends to the hub.
const HELLO: [u8; 1] = [0xFF];
/// Most endpoints a hub forwards to.
pub const MAX_HUB_ENDPOINTS: usize = 64;

/// The hub: forwards every frame to every other endpoint. Runs on its own thread.
#[derive(Debug)]
pub struct UdpHub {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    stats: Option<Arc<BusStats>>,
}

impl UdpHub {
    /// Bind the hub (e.g. `"127.0.0.1:0"` for any free port) and start forwarding at once
    /// (an ideal bus).
    pub fn spawn(bind: &str) -> std::io::Result<UdpHub> {
        UdpHub::spawn_with(bind, None)
    }

    /// Bind the hub and run it as a bus of `bitrate` bit/s: frames take their bit time, queue
    /// while the bus is busy and win it by identifier.
    pub fn spawn_timed(bind: &str, bitrate: u32) -> std::io::Result<UdpHub> {
        UdpHub::spawn_with(bind, Some(bitrate))
    }

    fn spawn_with(bind: &str, bitrate: Option<u32>) -> std::io::Result<UdpHub> {
        let socket = UdpSocket::bind(bind)?;
        let addr = socket.local_addr()?;
        let stop = Arc::new(AtomicBool::new(false));
        let stop_flag = stop.clone();
        let stats = bitrate.map(|b| Arc::new(BusStats::new(b, Instant::now())));
        let hub_stats = stats.clone();
        let thread = std::thread::Builder::new()
            .name("can-hub".into())
            .spawn(move || run_hub(&socket, &stop_flag, hub_stats.as_deref(), |_| {}))?;
        Ok(UdpHub {
            addr,
            stop,
            thread: Some(thread),
            stats,
        })
    }

    /// The address endpoints connect to.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// What a timed hub's bus measured; `None` for an ideal hub.
    pub fn stats(&self) -> Option<&Arc<BusStats>> {
        self.stats.as_ref()
    }

    /// Serve on the calling thread until the process ends (for the hub binary), as an ideal
    /// bus (`bitrate` `None`) or a timed one; `report` is handed the bus's figures every
    /// `report_every`.
    pub fn serve_forever(
        bind: &str,
        bitrate: Option<u32>,
        report_every: Duration,
        mut report: impl FnMut(&BusStats),
    ) -> std::io::Result<()> {
        let socket = UdpSocket::bind(bind)?;
        let stats = bitrate.map(|b| BusStats::new(b, Instant::now()));
        let mut next_report = Instant::now() + report_every;
        run_hub(&socket, &AtomicBool::new(false), stats.as_ref(), |s| {
            if Instant::now() >= next_report {
                report(s);
                next_report += report_every;
            }
        });
        Ok(())
    }
}

impl Drop for UdpHub {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Longest the hub blocks in a receive (how soon it notices `stop`).
const HUB_POLL: Duration = Duration::from_millis(50);

/// The hub's loop: register endpoints, forward frames (at once, or through the arbiter when
/// `stats` gives the bus a bit rate); `tick` is called with the statistics on every pass.
fn run_hub(
    socket: &UdpSocket,
    stop: &AtomicBool,
    stats: Option<&BusStats>,
    mut tick: impl FnMut(&BusStats),
) {
    let mut clients: Vec<SocketAddr> = Vec::with_capacity(MAX_HUB_ENDPOINTS);
    let mut arbiter = stats.map(|s| Arbiter::new(s.bitrate(), TIMED_BUS_QUEUE));
    let mut in_flight: Option<Transmission> = None;
    let mut buf = [0u8; 64];
    let forward = |clients: &[SocketAddr], from: usize, frame: &SimFrame| {
        let wire = frame.to_wire();
        for (i, c) in clients.iter().enumerate() {
            if i != from {
                let _ = socket.send_to(&wire, c);
            }
        }
    };
    while !stop.load(Ordering::Relaxed) {
        let mut wait = HUB_POLL;
        if let (Some(a), Some(st)) = (arbiter.as_mut(), stats) {
            tick(st);
            let now = st.now_ns();
            match in_flight {
                Some(t) if now >= t.end_ns => {
                    forward(&clients, t.queued.from, &t.queued.frame);
                    in_flight = None;
                    continue;
                }
                Some(t) => wait = Duration::from_nanos(t.end_ns - now),
                None => {
                    if let Some(t) = a.next(now) {
                        st.record(&t);
                        in_flight = Some(t);
                        continue;
                    }
                    if let Some(at) = a.next_decision_ns() {
                        wait = Duration::from_nanos(at.saturating_sub(now));
                    }
                }
            }
        }
        let _ = socket.set_read_timeout(Some(wait.clamp(Duration::from_micros(1), HUB_POLL)));
        let (n, from) = match socket.recv_from(&mut buf) {
            Ok(x) => x,
            Err(_) => continue,
        };
        if !clients.contains(&from) && clients.len() < MAX_HUB_ENDPOINTS {
            clients.push(from);
        }
        let Some(sender) = clients.iter().position(|c| *c == from) else {
            continue;
        };
        let Some(frame) = (n == 16).then(|| SimFrame::from_wire(&buf[..16])).flatten() else {
            continue;
        };
        match (arbiter.as_mut(), stats) {
            (Some(a), Some(st)) => {
                let queued = QueuedFrame {
                    frame,
                    from: sender,
                    queued_ns: st.now_ns(),
                };
                if a.offer(queued).is_err() {
                    st.record_overflow();
                }
            }
            _ => forward(&clients, sender, &frame),
        }
    }
}

/// One station on a hub-linked bus, usable from any process on the host.
#[derive(Debug)]
pub struct UdpEndpoint {
    socket: UdpSocket,
    faults: Arc<BusFaults>,
    read_timeout: Option<Duration>,
    pending: Option<(SimFrame, Instant)>,
}

impl UdpEndpoint {
    /// Connect to the hub at `hub` and register.
    pub fn connect(hub: SocketAddr, faults: Arc<BusFaults>) -> std::io::Result<UdpEndpoint> {
        let socket = UdpSocket::bind((hub.ip(), 0))?;
        socket.connect(hub)?;
        socket.send(&HELLO)?;
        Ok(UdpEndpoint {
            socket,
            faults,
            read_timeout: None,
            pending: None,
        })
    }

    /// The fault injector of this endpoint.
    pub fn faults(&self) -> &Arc<BusFaults> {
        &self.faults
    }

    /// Whether the bus is off.
    pub fn is_bus_off(&self) -> bool {
        self.faults.is_bus_off()
    }

    /// Send a frame to every other endpoint.
    pub fn send(&mut self, frame: &SimFrame) -> Result<(), BusError> {
        if self.faults.is_bus_off() {
            return Err(BusError::BusOff);
        }
        if self.faults.should_drop() {
            return Ok(());
        }
        self.socket
            .send(&frame.to_wire())
            .map(|_| ())
            .map_err(|e| BusError::Io(e.kind()))
    }

    /// Receive the next frame, waiting at most `timeout`; `Ok(None)` when none arrived in time.
    pub fn receive_timeout(&mut self, timeout: Duration) -> Result<Option<SimFrame>, BusError> {
        let deadline = Instant::now() + timeout;
        loop {
            if self.faults.is_bus_off() {
                return Err(BusError::BusOff);
            }
            let now = Instant::now();
            if let Some((frame, at)) = self.pending {
                if at <= now {
                    self.pending = None;
                    return Ok(Some(frame));
                }
                std::thread::sleep(at.min(deadline) - now);
                if at <= deadline {
                    self.pending = None;
                    return Ok(Some(frame));
                }
                return Ok(None);
            }
            let left = deadline.saturating_duration_since(now);
            // A zero read timeout means "block forever" to the OS: poll non-blockingly instead.
            let wanted = if left.is_zero() { None } else { Some(left) };
            if wanted != self.read_timeout || wanted.is_none() {
                self.socket
                    .set_nonblocking(wanted.is_none())
                    .map_err(|e| BusError::Io(e.kind()))?;
                if wanted.is_some() {
                    self.socket
                        .set_read_timeout(wanted)
                        .map_err(|e| BusError::Io(e.kind()))?;
                }
                self.read_timeout = wanted;
            }
            let mut buf = [0u8; 32];
            match self.socket.recv(&mut buf) {
                Ok(n) => {
                    let Some(frame) = SimFrame::from_wire(&buf[..n]) else {
                        continue; // not a frame: ignore it
                    };
                    let at = Instant::now() + self.faults.delay();
                    self.pending = Some((frame, at));
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    return Ok(None)
                }
                Err(e) => return Err(BusError::Io(e.kind())),
            }
        }
    }
}

impl_embedded_can!(UdpEndpoint);

#[cfg(test)]
mod tests {
    use super::*;

    fn wait_registered(eps: &mut [&mut UdpEndpoint]) {
        // Registration is a datagram: give the hub a moment to learn every endpoint.
        for e in eps.iter_mut() {
            e.socket.send(&HELLO).unwrap();
        }
        std::thread::sleep(Duration::from_millis(100));
    }

    #[test]
    fn two_endpoints_exchange_frames_through_the_hub_over_loopback() {
        let hub = UdpHub::spawn("127.0.0.1:0").unwrap();
        let faults = Arc::new(BusFaults::new(3));
        let mut a = UdpEndpoint::connect(hub.addr(), faults.clone()).unwrap();
        let mut b = UdpEndpoint::connect(hub.addr(), faults.clone()).unwrap();
        wait_registered(&mut [&mut a, &mut b]);
        let f = SimFrame::standard(0x601, &[0x40, 0x00, 0x10, 0, 0, 0, 0, 0]).unwrap();
        a.send(&f).unwrap();
        assert_eq!(b.receive_timeout(Duration::from_secs(2)).unwrap(), Some(f));
        let g = SimFrame::standard(0x581, &[0x43, 0x00, 0x10, 0, 0x92, 1, 2, 0]).unwrap();
        b.send(&g).unwrap();
        assert_eq!(a.receive_timeout(Duration::from_secs(2)).unwrap(), Some(g));
        // The sender does not hear itself.
        assert_eq!(a.receive_timeout(Duration::from_millis(30)).unwrap(), None);
        // Many frames in a row keep their order.
        for i in 0..100u8 {
            a.send(&SimFrame::standard(0x180, &[i]).unwrap()).unwrap();
        }
        for i in 0..100u8 {
            let f = b.receive_timeout(Duration::from_secs(2)).unwrap().unwrap();
            assert_eq!(embedded_can::Frame::data(&f), &[i]);
        }
    }

    #[test]
    fn bus_off_and_drops_apply_to_the_cross_process_bus() {
        let hub = UdpHub::spawn("127.0.0.1:0").unwrap();
        let faults = Arc::new(BusFaults::new(3));
        let mut a = UdpEndpoint::connect(hub.addr(), faults.clone()).unwrap();
        let mut b = UdpEndpoint::connect(hub.addr(), Arc::new(BusFaults::new(4))).unwrap();
        wait_registered(&mut [&mut a, &mut b]);
        faults.set_drop_rate(1.0);
        a.send(&SimFrame::standard(0x1, &[]).unwrap()).unwrap();
        assert_eq!(b.receive_timeout(Duration::from_millis(50)).unwrap(), None);
        faults.set_bus_off(true);
        assert_eq!(
            a.send(&SimFrame::standard(0x1, &[]).unwrap()),
            Err(BusError::BusOff)
        );
        assert_eq!(a.receive_timeout(Duration::ZERO), Err(BusError::BusOff));
    }
}
