//! The in-process bus: endpoints linked by bounded, preallocated queues.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use super::{BusError, BusFaults, SimFrame};

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
                peers: senders
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| *i != me)
                    .map(|(_, s)| s.clone())
                    .collect(),
                faults: faults.clone(),
                pending: None,
                overruns: Arc::new(AtomicU64::new(0)),
            })
            .collect()
    }
}

/// One station on an [`InProcessBus`]. Frames it transmits reach every other endpoint.
#[derive(Debug)]
pub struct InProcessEndpoint {
    index: usize,
    rx: Receiver<Envelope>,
    peers: Vec<SyncSender<Envelope>>,
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
        let envelope = Envelope {
            frame: *frame,
            deliver_at: Instant::now() + self.faults.delay(),
        };
        let mut alive = 0usize;
        for peer in &self.peers {
            match peer.try_send(envelope) {
                Ok(()) => alive += 1,
                Err(TrySendError::Full(_)) => {
                    alive += 1;
                    self.overruns.fetch_add(1, Ordering::Relaxed);
                }
                Err(TrySendError::Disconnected(_)) => {}
            }
        }
        if alive == 0 && !self.peers.is_empty() {
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
                    Err(RecvTimeoutError::Timeout) => return Ok(None),
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
}
