//! The in-process bus: endpoints linked by bounded, preallocated queues, either ideal (a frame
//! reaches the others at once) or timed (a wire thread arbitrates at the configured bit rate).

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use super::wire::{Arbiter, BusStats, QueuedFrame};
use super::{BusError, BusFaults, SimFrame};

/// Frames a timed bus queues while it is busy (all senders together), as a transmit queue.
pub const TIMED_BUS_QUEUE: usize = 256;

/// A frame in flight, with the instant it may be delivered (injected delay).
#[derive(Debug, Clone, Copy)]
struct Envelope {
    frame: SimFrame,
    deliver_at: Instant,
}

/// Builder of an in-process bus.
#[derive(Debug)]
pub struct InProcessBus;

impl InProcessBus {
    /// Create a bus with `count` endpoints, each with a receive queue of `queue_capacity`
    /// frames (allocated here, never grown), all subject to `faults`.
    pub fn with_endpoints(
        count: usize,
        queue_capacity: usize,
        faults: Arc<BusFaults>,
    ) -> Vec<InProcessEndpoint> {
        let (senders, receivers): (Vec<_>, Vec<_>) = (0..count)
            .map(|_| sync_channel(queue_capacity.max(1)))
            .unzip();
        receivers
            .into_iter()
            .enumerate()
            .map(|(me, rx)| InProcessEndpoint {
                index: me,
                rx,
                route: Route::Ideal(
                    senders
                        .iter()
                        .enumerate()
                        .filter(|(i, _)| *i != me)
                        .map(|(_, s)| s.clone())
                        .collect(),
                ),
                faults: faults.clone(),
                pending: None,
                overruns: Arc::new(AtomicU64::new(0)),
            })
            .collect()
    }

    /// Create a bus of `bitrate` bit/s with `count` endpoints: frames queue for the bus (the
    /// wire's queue and its hand-over queue hold [`TIMED_BUS_QUEUE`] each), the lowest identifier wins each arbitration, and a
    /// frame reaches the others when its last bit is sent. A wire thread runs the bus until
    /// every endpoint is dropped. Returns the endpoints and the bus's measurements.
    pub fn timed(
        count: usize,
        queue_capacity: usize,
        faults: Arc<BusFaults>,
        bitrate: u32,
    ) -> std::io::Result<(Vec<InProcessEndpoint>, Arc<BusStats>)> {
        Self::timed_with(count, queue_capacity, faults, bitrate, || {})
    }

    /// As [`InProcessBus::timed`], running `on_start` first on the wire thread. The wire stands
    /// for hardware that keeps its bit time whatever the host's load: a caller that runs real
    /// time uses `on_start` to raise the thread to the drives' priority, or a loaded host delays
    /// every frame by its scheduler's latency (tens of milliseconds under a busy CFS).
    pub fn timed_with(
        count: usize,
        queue_capacity: usize,
        faults: Arc<BusFaults>,
        bitrate: u32,
        on_start: impl FnOnce() + Send + 'static,
    ) -> std::io::Result<(Vec<InProcessEndpoint>, Arc<BusStats>)> {
        let stats = Arc::new(BusStats::new(bitrate, Instant::now()));
        let (to_wire, from_endpoints) = sync_channel::<QueuedFrame>(TIMED_BUS_QUEUE);
        let live = Arc::new(AtomicUsize::new(count));
        let mut outs = Vec::with_capacity(count);
        let mut endpoints = Vec::with_capacity(count);
        for me in 0..count {
            let (tx, rx) = sync_channel(queue_capacity.max(1));
            outs.push(tx);
            endpoints.push(InProcessEndpoint {
                index: me,
                rx,
                route: Route::Timed {
                    wire: to_wire.clone(),
                    stats: stats.clone(),
                    live: live.clone(),
                    peers: count.saturating_sub(1),
                },
                faults: faults.clone(),
                pending: None,
                overruns: Arc::new(AtomicU64::new(0)),
            });
        }
        drop(to_wire);
        let wire = Wire {
            arbiter: Arbiter::new(bitrate, TIMED_BUS_QUEUE),
            from_endpoints,
            outs,
            faults,
            stats: stats.clone(),
        };
        std::thread::Builder::new()
            .name("can-wire".into())
            .spawn(move || {
                on_start();
                wire.run()
            })?;
        Ok((endpoints, stats))
    }
}

/// How an endpoint's frames reach the others.
#[derive(Debug)]
enum Route {
    /// Straight into every other endpoint's queue.
    Ideal(Vec<SyncSender<Envelope>>),
    /// Through the wire thread.
    Timed {
        wire: SyncSender<QueuedFrame>,
        stats: Arc<BusStats>,
        live: Arc<AtomicUsize>,
        peers: usize,
    },
}

/// The wire thread of a timed bus.
struct Wire {
    arbiter: Arbiter,
    from_endpoints: Receiver<QueuedFrame>,
    outs: Vec<SyncSender<Envelope>>,
    faults: Arc<BusFaults>,
    stats: Arc<BusStats>,
}

impl Wire {
    fn run(mut self) {
        let mut senders_gone = false;
        loop {
            while let Ok(q) = self.from_endpoints.try_recv() {
                self.queue(q);
            }
            let now = self.stats.now_ns();
            if let Some(t) = self.arbiter.next(now) {
                self.stats.record(&t);
                let deliver_at =
                    self.stats.origin() + Duration::from_nanos(t.end_ns) + self.faults.delay();
                let envelope = Envelope {
                    frame: t.queued.frame,
                    deliver_at,
                };
                for (i, out) in self.outs.iter().enumerate() {
                    // A receiver that is gone or full loses the frame (its own overrun).
                    if i != t.queued.from {
                        let _ = out.try_send(envelope);
                    }
                }
                continue;
            }
            if senders_gone {
                return;
            }
            let wait = match self.arbiter.next_decision_ns() {
                Some(at) => Duration::from_nanos(at.saturating_sub(now)),
                None => Duration::from_millis(100),
            };
            match self.from_endpoints.recv_timeout(wait) {
                Ok(q) => self.queue(q),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => senders_gone = true,
            }
        }
    }

    fn queue(&mut self, q: QueuedFrame) {
        if self.arbiter.offer(q).is_err() {
            self.stats.record_overflow();
        }
    }
}

/// One station on an [`InProcessBus`]. Frames it transmits reach every other endpoint.
#[derive(Debug)]
pub struct InProcessEndpoint {
    index: usize,
    rx: Receiver<Envelope>,
    route: Route,
    faults: Arc<BusFaults>,
    pending: Option<Envelope>,
    overruns: Arc<AtomicU64>,
}

impl InProcessEndpoint {
    /// This endpoint's position on the bus (creation order).
    pub fn index(&self) -> usize {
        self.index
    }

    /// The bus's fault injector.
    pub fn faults(&self) -> &Arc<BusFaults> {
        &self.faults
    }

    /// Whether the bus is off.
    pub fn is_bus_off(&self) -> bool {
        self.faults.is_bus_off()
    }

    /// Frames this endpoint sent that a full peer queue had to discard.
    pub fn overruns(&self) -> u64 {
        self.overruns.load(Ordering::Relaxed)
    }

    /// Send a frame to every other endpoint; never blocks (a full queue loses the frame for
    /// that receiver and counts an overrun).
    pub fn send(&mut self, frame: &SimFrame) -> Result<(), BusError> {
        if self.faults.is_bus_off() {
            return Err(BusError::BusOff);
        }
        if self.faults.should_drop() {
            return Ok(());
        }
        let peers = match &self.route {
            Route::Ideal(peers) => peers,
            Route::Timed {
                wire,
                stats,
                live,
                peers,
            } => {
                if *peers > 0 && live.load(Ordering::Relaxed) <= 1 {
                    return Err(BusError::Disconnected);
                }
                let queued = QueuedFrame {
                    frame: *frame,
                    from: self.index,
                    queued_ns: stats.now_ns(),
                };
                return match wire.try_send(queued) {
                    Ok(()) => Ok(()),
                    Err(TrySendError::Full(_)) => {
                        stats.record_overflow();
                        Err(BusError::TransmitQueueFull)
                    }
                    Err(TrySendError::Disconnected(_)) => Err(BusError::Disconnected),
                };
            }
        };
        let envelope = Envelope {
            frame: *frame,
            deliver_at: Instant::now() + self.faults.delay(),
        };
        let mut alive = 0usize;
        for peer in peers {
            match peer.try_send(envelope) {
                Ok(()) => alive += 1,
                Err(TrySendError::Full(_)) => {
                    alive += 1;
                    self.overruns.fetch_add(1, Ordering::Relaxed);
                }
                Err(TrySendError::Disconnected(_)) => {}
            }
        }
        if alive == 0 && !peers.is_empty() {
            return Err(BusError::Disconnected);
        }
        Ok(())
    }

    /// Receive the next frame, waiting at most `timeout`; `Ok(None)` when none arrived in time.
    pub fn receive_timeout(&mut self, timeout: Duration) -> Result<Option<SimFrame>, BusError> {
        let deadline = Instant::now() + timeout;
        if self.faults.is_bus_off() {
            return Err(BusError::BusOff);
        }
        let envelope = match self.pending.take() {
            Some(e) => e,
            None => {
                let now = Instant::now();
                match self
                    .rx
                    .recv_timeout(deadline.saturating_duration_since(now))
                {
                    Ok(e) => e,
                    Err(RecvTimeoutError::Timeout) => {
                        return match &self.route {
                            Route::Timed { live, peers, .. }
                                if *peers > 0 && live.load(Ordering::Relaxed) <= 1 =>
                            {
                                Err(BusError::Disconnected)
                            }
                            _ => Ok(None),
                        }
                    }
                    Err(RecvTimeoutError::Disconnected) => return Err(BusError::Disconnected),
                }
            }
        };
        let now = Instant::now();
        if envelope.deliver_at <= now {
            return Ok(Some(envelope.frame));
        }
        if envelope.deliver_at <= deadline {
            std::thread::sleep(envelope.deliver_at - now);
            if self.faults.is_bus_off() {
                return Err(BusError::BusOff);
            }
            return Ok(Some(envelope.frame));
        }
        // Not deliverable before the deadline: keep it for a later call.
        self.pending = Some(envelope);
        std::thread::sleep(deadline.saturating_duration_since(now));
        Ok(None)
    }
}

impl Drop for InProcessEndpoint {
    fn drop(&mut self) {
        if let Route::Timed { live, .. } = &self.route {
            live.fetch_sub(1, Ordering::Relaxed);
        }
    }
}

impl_embedded_can!(InProcessEndpoint);

#[cfg(test)]
mod tests {
    use super::*;

    fn bus(n: usize, cap: usize) -> (Arc<BusFaults>, Vec<InProcessEndpoint>) {
        let faults = Arc::new(BusFaults::new(7));
        (faults.clone(), InProcessBus::with_endpoints(n, cap, faults))
    }

    #[test]
    fn every_frame_reaches_every_other_endpoint_but_not_the_sender() {
        let (_, mut eps) = bus(3, 8);
        let f = SimFrame::standard(0x123, &[1, 2]).unwrap();
        eps[0].send(&f).unwrap();
        assert_eq!(eps[1].receive_timeout(Duration::ZERO).unwrap(), Some(f));
        assert_eq!(eps[2].receive_timeout(Duration::ZERO).unwrap(), Some(f));
        assert_eq!(eps[0].receive_timeout(Duration::ZERO).unwrap(), None);
    }

    #[test]
    fn receive_times_out_without_traffic() {
        let (_, mut eps) = bus(2, 4);
        let t0 = Instant::now();
        assert_eq!(
            eps[0].receive_timeout(Duration::from_millis(20)).unwrap(),
            None
        );
        assert!(t0.elapsed() >= Duration::from_millis(20));
    }

    #[test]
    fn a_full_queue_drops_and_counts_overruns_without_blocking() {
        let (_, mut eps) = bus(2, 2);
        let f = SimFrame::standard(0x1, &[]).unwrap();
        for _ in 0..5 {
            eps[0].send(&f).unwrap();
        }
        assert_eq!(eps[0].overruns(), 3);
        assert!(eps[1].receive_timeout(Duration::ZERO).unwrap().is_some());
        assert!(eps[1].receive_timeout(Duration::ZERO).unwrap().is_some());
        assert!(eps[1].receive_timeout(Duration::ZERO).unwrap().is_none());
    }

    #[test]
    fn bus_off_fails_transmit_and_receive_and_recovers() {
        let (faults, mut eps) = bus(2, 4);
        faults.set_bus_off(true);
        let f = SimFrame::standard(0x1, &[]).unwrap();
        assert_eq!(eps[0].send(&f), Err(BusError::BusOff));
        assert_eq!(
            eps[1].receive_timeout(Duration::ZERO),
            Err(BusError::BusOff)
        );
        assert!(eps[1].is_bus_off());
        faults.set_bus_off(false);
        eps[0].send(&f).unwrap();
        assert_eq!(eps[1].receive_timeout(Duration::ZERO).unwrap(), Some(f));
    }

    #[test]
    fn delayed_frames_arrive_after_the_delay_and_not_before() {
        let (faults, mut eps) = bus(2, 4);
        faults.set_delay(Duration::from_millis(30));
        let f = SimFrame::standard(0x2, &[5]).unwrap();
        let t0 = Instant::now();
        eps[0].send(&f).unwrap();
        assert_eq!(
            eps[1].receive_timeout(Duration::from_millis(5)).unwrap(),
            None
        );
        assert_eq!(
            eps[1].receive_timeout(Duration::from_millis(100)).unwrap(),
            Some(f)
        );
        assert!(t0.elapsed() >= Duration::from_millis(30));
    }

    #[test]
    fn dropped_frames_never_arrive() {
        let (faults, mut eps) = bus(2, 4);
        faults.set_drop_rate(1.0);
        eps[0].send(&SimFrame::standard(0x3, &[]).unwrap()).unwrap();
        assert_eq!(
            eps[1].receive_timeout(Duration::from_millis(5)).unwrap(),
            None
        );
        assert_eq!(faults.dropped_frames(), 1);
    }

    #[test]
    fn a_bus_whose_peers_are_gone_reports_disconnected() {
        let (_, mut eps) = bus(2, 4);
        let mut a = eps.remove(0);
        drop(eps);
        assert_eq!(
            a.send(&SimFrame::standard(0x3, &[]).unwrap()),
            Err(BusError::Disconnected)
        );
        assert_eq!(
            a.receive_timeout(Duration::ZERO),
            Err(BusError::Disconnected)
        );
    }

    #[test]
    fn frames_cross_threads() {
        let (_, mut eps) = bus(2, 16);
        let mut b = eps.pop().unwrap();
        let mut a = eps.pop().unwrap();
        let t = std::thread::spawn(move || {
            let f = b.receive_timeout(Duration::from_secs(2)).unwrap().unwrap();
            b.send(&f).unwrap();
        });
        let f = SimFrame::standard(0x7FF, &[0xAA; 8]).unwrap();
        a.send(&f).unwrap();
        assert_eq!(a.receive_timeout(Duration::from_secs(2)).unwrap(), Some(f));
        t.join().unwrap();
    }

    fn timed_bus(
        n: usize,
        bitrate: u32,
    ) -> (Arc<BusFaults>, Vec<InProcessEndpoint>, Arc<BusStats>) {
        let faults = Arc::new(BusFaults::new(7));
        let (eps, stats) = InProcessBus::timed(n, 64, faults.clone(), bitrate).unwrap();
        (faults, eps, stats)
    }

    #[test]
    fn a_timed_bus_delivers_after_the_frames_bits_and_in_identifier_order() {
        // 10 kbit/s: a 8-byte frame takes 11-13.5 ms, far above scheduling noise.
        let (_, mut eps, stats) = timed_bus(3, 10_000);
        let f_high = SimFrame::standard(0x300, &[0xA5; 8]).unwrap();
        let f_low = SimFrame::standard(0x100, &[0x5A; 8]).unwrap();
        let t0 = Instant::now();
        // The first frame takes the idle bus; the two queued behind it are arbitrated.
        eps[0]
            .send(&SimFrame::standard(0x700, &[1]).unwrap())
            .unwrap();
        eps[0].send(&f_high).unwrap();
        eps[1].send(&f_low).unwrap();
        let mut got = Vec::new();
        while got.len() < 3 {
            if let Some(f) = eps[2].receive_timeout(Duration::from_secs(2)).unwrap() {
                got.push((f.raw_id(), t0.elapsed()));
            } else {
                panic!("the timed bus lost a frame: {got:?}");
            }
        }
        let ids: Vec<u32> = got.iter().map(|g| g.0).collect();
        assert_eq!(ids, vec![0x700, 0x100, 0x300]);
        let bits: u32 = [SimFrame::standard(0x700, &[1]).unwrap(), f_low, f_high]
            .iter()
            .map(super::super::wire::sim_frame_bits)
            .sum();
        let on_the_wire = Duration::from_micros(u64::from(bits) * 100);
        assert!(got[2].1 >= on_the_wire, "{:?} < {on_the_wire:?}", got[2].1);
        // The sender of the low id frame heard the other two, not its own.
        let mut heard = Vec::new();
        while let Some(f) = eps[1].receive_timeout(Duration::from_millis(100)).unwrap() {
            heard.push(f.raw_id());
        }
        assert_eq!(heard, vec![0x700, 0x300]);
        let s = stats.snapshot();
        assert_eq!(s.frames, 3);
        assert!(s.load > 0.9, "three frames back to back: load {}", s.load);
        assert!(
            s.max_wait_us > 10_000.0,
            "the last frame waited two frames: {s:?}"
        );
    }

    #[test]
    fn a_timed_bus_keeps_its_faults_and_reports_lost_peers() {
        let (faults, mut eps, _) = timed_bus(2, 1_000_000);
        faults.set_bus_off(true);
        let f = SimFrame::standard(0x1, &[]).unwrap();
        assert_eq!(eps[0].send(&f), Err(BusError::BusOff));
        faults.set_bus_off(false);
        eps[0].send(&f).unwrap();
        assert_eq!(
            eps[1].receive_timeout(Duration::from_secs(1)).unwrap(),
            Some(f)
        );
        let mut a = eps.remove(0);
        drop(eps);
        assert_eq!(a.send(&f), Err(BusError::Disconnected));
        assert_eq!(
            a.receive_timeout(Duration::ZERO),
            Err(BusError::Disconnected)
        );
    }

    #[test]
    fn an_overloaded_timed_bus_fills_its_transmit_queue() {
        // 10 kbit/s carries about 90 empty frames a second; offer far more at once.
        let (_, mut eps, stats) = timed_bus(2, 10_000);
        let f = SimFrame::standard(0x080, &[]).unwrap();
        let refused = (0..2 * TIMED_BUS_QUEUE + 8)
            .filter(|_| eps[0].send(&f) == Err(BusError::TransmitQueueFull))
            .count();
        assert!(refused > 0, "nothing refused");
        assert!(stats.snapshot().overflows >= refused as u64);
    }
}
