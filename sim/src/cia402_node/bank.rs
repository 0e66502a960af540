//! Where the simulated drives live: a port on the userspace bus ([`SimPort`]), the drives
//! answering inline on a simulated clock ([`SteppedDriveBus`]), or on their own thread
//! ([`SimDriveBank`]).

use super::*;

/// A station of the userspace bus the simulated drives can sit on.
pub trait SimPort: Send {
    /// Send a frame.
    fn send_frame(&mut self, frame: &SimFrame) -> Result<(), BusError>;
    /// Receive with a timeout.
    fn receive_frame(&mut self, timeout: Duration) -> Result<Option<SimFrame>, BusError>;
}

impl SimPort for InProcessEndpoint {
    fn send_frame(&mut self, frame: &SimFrame) -> Result<(), BusError> {
        self.send(frame)
    }
    fn receive_frame(&mut self, timeout: Duration) -> Result<Option<SimFrame>, BusError> {
        self.receive_timeout(timeout)
    }
}

impl SimPort for crate::can_bus::udp::UdpEndpoint {
    fn send_frame(&mut self, frame: &SimFrame) -> Result<(), BusError> {
        self.send(frame)
    }
    fn receive_frame(&mut self, timeout: Duration) -> Result<Option<SimFrame>, BusError> {
        self.receive_timeout(timeout)
    }
}

/// Frames a [`SimDriveBank`] takes off its port before it looks at the time: more than a
/// period's traffic of many drives, so a thread woken late catches up with the bus at once.
const MAX_FRAMES_TAKEN_AT_ONCE: usize = 64;

/// `frame` heard by every node of a [`SimDriveBank`], their answers queued in `outbox`.
fn hear<M: MotorPlant>(
    nodes: &mut [SimDriveNode],
    frame: &SimFrame,
    plant: &mut M,
    outbox: &mut Vec<SimFrame>,
) {
    for n in nodes.iter_mut() {
        n.on_frame(frame, plant, &mut |f| outbox.push(f));
    }
}

/// Put every frame of `outbox` on the bus, in order (a frame the bus refuses is lost, as on a
/// bus that is off).
fn send_all<P: SimPort>(port: &mut P, outbox: &mut Vec<SimFrame>) {
    for f in outbox.drain(..) {
        let _ = port.send_frame(&f);
    }
}

/// Simulated drives answering inline, without a thread: frames sent to the bus reach the nodes
/// at once and their answers wait in a preallocated queue. Deterministic, for tests on the
/// twin's simulated clock (the threaded [`SimDriveBank`] is the real-time variant).
pub struct SteppedDriveBus<M: MotorPlant> {
    nodes: Vec<SimDriveNode>,
    faults: Vec<Arc<NodeFaults>>,
    plant: M,
    rx: std::collections::VecDeque<SimFrame>,
}

impl<M: MotorPlant> core::fmt::Debug for SteppedDriveBus<M> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("SteppedDriveBus")
            .field("nodes", &self.nodes.len())
            .finish()
    }
}

impl<M: MotorPlant> SteppedDriveBus<M> {
    /// The drives `specs`, their motors in `plant`.
    pub fn new(specs: &[SimDriveSpec], plant: M) -> Self {
        Self::described(specs, None, plant)
    }

    /// As [`SteppedDriveBus::new`], every drive with `dictionary` (the part's description)
    /// instead of the generic profile when given.
    pub fn described(
        specs: &[SimDriveSpec],
        dictionary: Option<Arc<DriveDictionary>>,
        plant: M,
    ) -> Self {
        let faults: Vec<Arc<NodeFaults>> = specs
            .iter()
            .map(|_| Arc::new(NodeFaults::default()))
            .collect();
        let nodes = specs
            .iter()
            .zip(&faults)
            .map(|(s, f)| SimDriveNode::with_dictionary(*s, f.clone(), dictionary.clone()))
            .collect();
        SteppedDriveBus {
            nodes,
            faults,
            plant,
            rx: std::collections::VecDeque::with_capacity(256),
        }
    }

    /// Fault injector of node `i`.
    pub fn faults(&self, i: usize) -> &Arc<NodeFaults> {
        &self.faults[i]
    }

    /// The nodes.
    pub fn nodes(&self) -> &[SimDriveNode] {
        &self.nodes
    }

    /// Deliver a frame to every node; their answers are queued.
    pub fn send(&mut self, frame: &SimFrame) {
        let rx = &mut self.rx;
        for n in self.nodes.iter_mut() {
            n.on_frame(frame, &mut self.plant, &mut |f| {
                if rx.len() < rx.capacity() {
                    rx.push_back(f)
                }
            });
        }
    }

    /// The next queued answer, after letting the nodes do their time-driven work (boot-up,
    /// heartbeats). Never waits.
    pub fn receive(&mut self) -> Option<SimFrame> {
        let now = Instant::now();
        let rx = &mut self.rx;
        for n in self.nodes.iter_mut() {
            n.poll(now, &mut self.plant, &mut |f| {
                if rx.len() < rx.capacity() {
                    rx.push_back(f)
                }
            });
        }
        self.rx.pop_front()
    }
}

/// Observable state of a bank's nodes, refreshed by the bank thread.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeView {
    /// CiA 402 power state.
    pub power: DrivePower,
    /// NMT state.
    pub nmt: NmtState,
    /// Torque applied to the motor, N·m.
    pub applied_torque_nm: f64,
    /// When the drive entered its power state, as its own thread saw it (`None` where the
    /// drives step with the twin's clock).
    pub power_since: Option<std::time::Instant>,
}

/// Several simulated drives sharing one bus station and one plant, run on a thread.
pub struct SimDriveBank {
    stop: Arc<AtomicBool>,
    views: Arc<Mutex<Vec<NodeView>>>,
    faults: Vec<Arc<NodeFaults>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl core::fmt::Debug for SimDriveBank {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("SimDriveBank")
            .field("nodes", &self.faults.len())
            .finish()
    }
}

impl SimDriveBank {
    /// Start the drives `specs` on `port`, their motors in `plant`.
    pub fn spawn<P: SimPort + 'static, M: MotorPlant + 'static>(
        port: P,
        specs: &[SimDriveSpec],
        plant: M,
    ) -> SimDriveBank {
        Self::spawn_with(port, specs, plant, || {})
    }

    /// As [`SimDriveBank::spawn`], running `on_start` first on the new thread (e.g. to raise
    /// its scheduling priority).
    pub fn spawn_with<P: SimPort + 'static, M: MotorPlant + 'static>(
        port: P,
        specs: &[SimDriveSpec],
        plant: M,
        on_start: impl FnOnce() + Send + 'static,
    ) -> SimDriveBank {
        Self::spawn_described(port, specs, None, plant, on_start)
    }

    /// As [`SimDriveBank::spawn_with`], every drive with `dictionary` (the part's
    /// description) instead of the generic profile when given.
    pub fn spawn_described<P: SimPort + 'static, M: MotorPlant + 'static>(
        mut port: P,
        specs: &[SimDriveSpec],
        dictionary: Option<Arc<DriveDictionary>>,
        mut plant: M,
        on_start: impl FnOnce() + Send + 'static,
    ) -> SimDriveBank {
        let faults: Vec<Arc<NodeFaults>> = specs
            .iter()
            .map(|_| Arc::new(NodeFaults::default()))
            .collect();
        let mut nodes: Vec<SimDriveNode> = specs
            .iter()
            .zip(&faults)
            .map(|(s, f)| SimDriveNode::with_dictionary(*s, f.clone(), dictionary.clone()))
            .collect();
        let stop = Arc::new(AtomicBool::new(false));
        let views = Arc::new(Mutex::new(
            nodes
                .iter()
                .map(|n| NodeView {
                    power: n.power(),
                    nmt: n.nmt_state(),
                    applied_torque_nm: 0.0,
                    power_since: Some(Instant::now()),
                })
                .collect::<Vec<_>>(),
        ));
        let (stop_t, views_t) = (stop.clone(), views.clone());
        let thread = std::thread::Builder::new()
            .name("sim-drives".into())
            .spawn(move || {
                on_start();
                let mut outbox: Vec<SimFrame> = Vec::with_capacity(64);
                // Each node's power state and since when, kept here: the views are published
                // only when their lock is free (below), and a change is still timed when it
                // happened.
                let mut powers: Vec<(DrivePower, Option<Instant>)> = nodes
                    .iter()
                    .map(|n| (n.power(), Some(Instant::now())))
                    .collect();
                while !stop_t.load(Ordering::Relaxed) {
                    // What arrived while this thread was not running is taken first: a real
                    // drive's controller takes frames off the bus as they come, so its
                    // heartbeat consumer never finds the host silent while the host's
                    // heartbeat waits in a queue.
                    for _ in 0..MAX_FRAMES_TAKEN_AT_ONCE {
                        match port.receive_frame(Duration::ZERO) {
                            Ok(Some(frame)) => hear(&mut nodes, &frame, &mut plant, &mut outbox),
                            _ => break,
                        }
                    }
                    // Answers first (a SYNC's process data: the host waits for them), the
                    // nodes' own timers (heartbeats, event-driven PDOs) after: their upkeep
                    // costs more than an answer, and on a slow CPU it made the answers late.
                    send_all(&mut port, &mut outbox);
                    let now = Instant::now();
                    let mut next = now + Duration::from_millis(5);
                    for n in nodes.iter_mut() {
                        next = next.min(n.poll(now, &mut plant, &mut |f| outbox.push(f)));
                    }
                    send_all(&mut port, &mut outbox);
                    let wait = next.saturating_duration_since(Instant::now());
                    match port.receive_frame(wait) {
                        Ok(Some(frame)) => {
                            hear(&mut nodes, &frame, &mut plant, &mut outbox);
                            send_all(&mut port, &mut outbox);
                        }
                        Ok(None) => {}
                        Err(_) => std::thread::sleep(Duration::from_millis(1)),
                    }
                    for (p, n) in powers.iter_mut().zip(&nodes) {
                        if n.power() != p.0 {
                            *p = (n.power(), Some(Instant::now()));
                        }
                    }
                    // Never waits for the lock: a reader holding it (a thread of ordinary
                    // priority, preempted on a busy CPU) would otherwise stop the drives
                    // answering for as long, as a priority inversion. Contended, the views are
                    // published the next time round.
                    if let Ok(mut v) = views_t.try_lock() {
                        for ((view, n), p) in v.iter_mut().zip(&nodes).zip(&powers) {
                            *view = NodeView {
                                power: p.0,
                                nmt: n.nmt_state(),
                                applied_torque_nm: n.applied_torque_nm(),
                                power_since: p.1,
                            };
                        }
                    }
                }
            })
            .expect("spawning the simulated drive thread");
        SimDriveBank {
            stop,
            views,
            faults,
            thread: Some(thread),
        }
    }

    /// Fault injectors, one per node (same order as the specs).
    pub fn faults(&self, node: usize) -> &Arc<NodeFaults> {
        &self.faults[node]
    }

    /// The latest view of every node.
    pub fn views(&self) -> Vec<NodeView> {
        self.views.lock().map(|v| v.clone()).unwrap_or_default()
    }
}

impl Drop for SimDriveBank {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::can_bus::{BusFaults, InProcessBus};

    #[test]
    fn a_reader_holding_the_views_does_not_stop_the_drives_answering() {
        let faults = Arc::new(BusFaults::new(1));
        let mut eps = InProcessBus::with_endpoints(2, 64, faults);
        let mut host = eps.pop().unwrap();
        let drives = eps.pop().unwrap();
        let spec = |node_id| SimDriveSpec {
            node_id,
            axis: 0,
            rated_torque_mnm: 100,
            boot_delay: Duration::from_millis(5),
        };
        let bank = SimDriveBank::spawn(
            drives,
            &[spec(1), spec(2)],
            FreeMotorPlant::new(1, 1e-5, 1e-5, 2000.0),
        );
        // A reader of ordinary priority, preempted while it holds the views' lock, for the
        // whole exchange: the drives boot and answer an SDO read all the same.
        let held = bank.views.lock().unwrap();
        let mut booted = vec![];
        let mut answered = false;
        let t0 = Instant::now();
        while !(booted.len() == 2 && answered) && t0.elapsed() < Duration::from_secs(2) {
            if let Some(f) = host.receive_timeout(Duration::from_millis(50)).unwrap() {
                if f.data() == [0] {
                    booted.push(f.raw_id());
                    if booted.len() == 2 {
                        // Read node 1's device type (0x1000).
                        let read = SimFrame::standard(0x601, &[0x40, 0x00, 0x10, 0, 0, 0, 0, 0]);
                        host.send(&read.unwrap()).unwrap();
                    }
                } else if f.raw_id() == 0x581 {
                    answered = true;
                }
            }
        }
        booted.sort();
        assert_eq!(
            booted,
            vec![0x701, 0x702],
            "boot-ups while the views were held"
        );
        assert!(answered, "no SDO answer while the views were held");
        drop(held);
        // Published once the lock is free, with the time the power state was entered.
        let t1 = Instant::now();
        while bank.views()[0].nmt != NmtState::PreOperational {
            assert!(
                t1.elapsed() < Duration::from_secs(2),
                "views never published"
            );
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(bank.views()[0].power_since.unwrap() <= t1);
    }
}
