//! The physical layer of the twin's bus: a bit rate, arbitration by identifier, frames
//! queued while the bus is busy, and the load measured.
//!
//! [`Arbiter`] is the pure model, on a clock of nanoseconds: every frame offered carries the
//! instant it was queued; whenever the bus falls idle the lowest identifier among the frames
//! queued by then wins (ties in the order they were queued) and holds the bus for its exact
//! length in bits ([`videt_can_timing::frame_bits`]) at the configured bit rate. A frame
//! arrives at every receiver when its last bit has been sent.
//!
//! The arbiter looks back: it decides the transmission that starts at instant `T` only once
//! the clock has reached `T`, from the frames queued up to `T`, so a wire thread woken late
//! still produces the bus's schedule (its receivers just see the frame that much later).

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use embedded_can::Frame;
use videt_can_timing::{bits_to_ns, frame_bits, worst_case_bits};

use super::SimFrame;

/// A frame waiting for the bus.
#[derive(Debug, Clone, Copy)]
pub struct QueuedFrame {
    /// The frame.
    pub frame: SimFrame,
    /// The endpoint that sent it (it does not receive its own frame).
    pub from: usize,
    /// When the sender queued it, ns on the arbiter's clock.
    pub queued_ns: u64,
}

/// A frame that won the bus.
#[derive(Debug, Clone, Copy)]
pub struct Transmission {
    /// The frame and its sender.
    pub queued: QueuedFrame,
    /// First bit on the bus, ns on the arbiter's clock.
    pub start_ns: u64,
    /// Last bit (intermission included) sent: when receivers have it.
    pub end_ns: u64,
}

/// Bus time of `frame` in bits: exact for standard data frames; the worst case of its length
/// for extended and remote frames (20 more bits for the extended identifier).
pub fn sim_frame_bits(frame: &SimFrame) -> u32 {
    let dlc = frame.dlc() as u8;
    if frame.is_extended() {
        worst_case_bits(dlc) + 20 + 5
    } else if frame.is_remote_frame() {
        worst_case_bits(0)
    } else {
        frame_bits(frame.raw_id() as u16, frame.data())
    }
}

/// The arbitration of one bus (pure; no clock of its own). Holds at most `capacity` queued
/// frames, allocated once.
#[derive(Debug)]
pub struct Arbiter {
    bitrate: u32,
    pending: Vec<(u64, QueuedFrame)>,
    capacity: usize,
    sequence: u64,
    idle_at_ns: u64,
}

/// The arbiter's queue is full: the frame is lost (a transmit-queue overflow).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QueueFull;

impl Arbiter {
    /// An idle bus of `bitrate` bit/s with room for `capacity` queued frames.
    pub fn new(bitrate: u32, capacity: usize) -> Arbiter {
        Arbiter {
            bitrate: bitrate.max(1),
            pending: Vec::with_capacity(capacity.max(1)),
            capacity: capacity.max(1),
            sequence: 0,
            idle_at_ns: 0,
        }
    }

    /// The bit rate, bit/s.
    pub fn bitrate(&self) -> u32 {
        self.bitrate
    }

    /// Frames waiting for the bus.
    pub fn queued(&self) -> usize {
        self.pending.len()
    }

    /// Queue a frame for the bus.
    pub fn offer(&mut self, frame: QueuedFrame) -> Result<(), QueueFull> {
        if self.pending.len() >= self.capacity {
            return Err(QueueFull);
        }
        self.sequence += 1;
        self.pending.push((self.sequence, frame));
        Ok(())
    }

    /// When the next arbitration happens (the bus falls idle with a frame waiting, or the
    /// first frame of an idle bus was queued); `None` without queued frames.
    pub fn next_decision_ns(&self) -> Option<u64> {
        let first_queued = self.pending.iter().map(|(_, q)| q.queued_ns).min()?;
        Some(first_queued.max(self.idle_at_ns))
    }

    /// The transmission that starts next, if its arbitration instant is at or before `now_ns`
    /// (every frame queued by then must have been offered).
    pub fn next(&mut self, now_ns: u64) -> Option<Transmission> {
        let at = self.next_decision_ns()?;
        if at > now_ns {
            return None;
        }
        let (winner, _) = self
            .pending
            .iter()
            .enumerate()
            .filter(|(_, (_, q))| q.queued_ns <= at)
            .min_by_key(|(_, (seq, q))| (q.frame.raw_id(), *seq))?;
        let (_, queued) = self.pending.swap_remove(winner);
        let end_ns = at + bits_to_ns(sim_frame_bits(&queued.frame), self.bitrate);
        self.idle_at_ns = end_ns;
        Some(Transmission {
            queued,
            start_ns: at,
            end_ns,
        })
    }
}

/// What a bus measured; shared, atomics only.
#[derive(Debug)]
pub struct BusStats {
    origin: Instant,
    bitrate: u32,
    frames: AtomicU64,
    busy_ns: AtomicU64,
    wait_ns_max: AtomicU64,
    wait_ns_total: AtomicU64,
    overflows: AtomicU64,
    last_end_ns: AtomicU64,
}

/// A reading of [`BusStats`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BusStatsSnapshot {
    /// The bus's bit rate, bit/s.
    pub bitrate: u32,
    /// Frames carried.
    pub frames: u64,
    /// Share of the time the bus carried bits, from the first frame to the last.
    pub load: f64,
    /// Longest time a frame waited for the bus after it was queued, µs.
    pub max_wait_us: f64,
    /// Mean time a frame waited for the bus, µs.
    pub mean_wait_us: f64,
    /// Frames lost to a full transmit queue.
    pub overflows: u64,
    /// Time the bus carried bits, ns.
    pub busy_ns: u64,
    /// When the last frame ended, ns on the bus's clock (the load's time span).
    pub last_end_ns: u64,
}

impl BusStatsSnapshot {
    /// The load between an `earlier` reading and this one.
    pub fn load_since(&self, earlier: &BusStatsSnapshot) -> f64 {
        let span = self.last_end_ns.saturating_sub(earlier.last_end_ns) as f64;
        if span > 0.0 {
            self.busy_ns.saturating_sub(earlier.busy_ns) as f64 / span
        } else {
            0.0
        }
    }
}

impl BusStats {
    /// Empty statistics of a bus at `bitrate`, on a clock starting at `origin`.
    pub fn new(bitrate: u32, origin: Instant) -> BusStats {
        BusStats {
            origin,
            bitrate,
            frames: AtomicU64::new(0),
            busy_ns: AtomicU64::new(0),
            wait_ns_max: AtomicU64::new(0),
            wait_ns_total: AtomicU64::new(0),
            overflows: AtomicU64::new(0),
            last_end_ns: AtomicU64::new(0),
        }
    }

    /// The bus's bit rate, bit/s.
    pub fn bitrate(&self) -> u32 {
        self.bitrate
    }

    /// The clock the statistics (and the arbiter) run on.
    pub fn origin(&self) -> Instant {
        self.origin
    }

    /// Nanoseconds since the origin.
    pub fn now_ns(&self) -> u64 {
        self.origin.elapsed().as_nanos() as u64
    }

    /// Count one transmission.
    pub fn record(&self, t: &Transmission) {
        self.frames.fetch_add(1, Ordering::Relaxed);
        self.busy_ns
            .fetch_add(t.end_ns - t.start_ns, Ordering::Relaxed);
        let wait = t.start_ns.saturating_sub(t.queued.queued_ns);
        self.wait_ns_total.fetch_add(wait, Ordering::Relaxed);
        self.wait_ns_max.fetch_max(wait, Ordering::Relaxed);
        self.last_end_ns.fetch_max(t.end_ns, Ordering::Relaxed);
    }

    /// Count one frame lost to a full queue.
    pub fn record_overflow(&self) {
        self.overflows.fetch_add(1, Ordering::Relaxed);
    }

    /// The figures so far.
    pub fn snapshot(&self) -> BusStatsSnapshot {
        let frames = self.frames.load(Ordering::Relaxed);
        let busy_ns = self.busy_ns.load(Ordering::Relaxed);
        let last_end_ns = self.last_end_ns.load(Ordering::Relaxed);
        let (busy, span) = (busy_ns as f64, last_end_ns as f64);
        BusStatsSnapshot {
            bitrate: self.bitrate,
            frames,
            load: if span > 0.0 { busy / span } else { 0.0 },
            max_wait_us: self.wait_ns_max.load(Ordering::Relaxed) as f64 / 1e3,
            mean_wait_us: if frames > 0 {
                self.wait_ns_total.load(Ordering::Relaxed) as f64 / frames as f64 / 1e3
            } else {
                0.0
            },
            overflows: self.overflows.load(Ordering::Relaxed),
            busy_ns,
            last_end_ns,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q(id: u16, len: usize, from: usize, at: u64) -> QueuedFrame {
        QueuedFrame {
            frame: SimFrame::standard(id, &[0x55; 8][..len]).unwrap(),
            from,
            queued_ns: at,
        }
    }

    #[test]
    fn a_frame_holds_the_bus_for_its_bits() {
        let mut a = Arbiter::new(1_000_000, 8);
        a.offer(q(0x080, 0, 0, 1_000)).unwrap();
        let t = a.next(1_000).unwrap();
        let bits = frame_bits(0x080, &[]);
        assert_eq!(
            (t.start_ns, t.end_ns),
            (1_000, 1_000 + 1_000 * u64::from(bits))
        );
        assert!(a.next(u64::MAX).is_none());
    }

    #[test]
    fn the_lowest_identifier_wins_among_frames_queued_while_the_bus_was_busy() {
        let mut a = Arbiter::new(1_000_000, 8);
        a.offer(q(0x080, 0, 0, 0)).unwrap();
        let sync = a.next(0).unwrap();
        // Three answers queued during the SYNC, highest id first.
        a.offer(q(0x183, 8, 1, 10)).unwrap();
        a.offer(q(0x182, 8, 1, 20)).unwrap();
        a.offer(q(0x181, 8, 1, 30)).unwrap();
        // Nothing decided before the bus is idle.
        assert!(a.next(sync.end_ns - 1).is_none());
        let order: Vec<u32> = std::iter::from_fn(|| a.next(u64::MAX))
            .map(|t| t.queued.frame.raw_id())
            .collect();
        assert_eq!(order, vec![0x181, 0x182, 0x183]);
    }

    #[test]
    fn a_frame_queued_after_the_bus_fell_idle_does_not_take_part_in_that_arbitration() {
        let mut a = Arbiter::new(500_000, 8);
        a.offer(q(0x300, 4, 0, 0)).unwrap();
        let first = a.next(0).unwrap();
        a.offer(q(0x281, 8, 1, first.end_ns - 1)).unwrap();
        a.offer(q(0x080, 0, 0, first.end_ns + 1)).unwrap();
        let second = a.next(u64::MAX).unwrap();
        assert_eq!(second.queued.frame.raw_id(), 0x281);
        assert_eq!(second.start_ns, first.end_ns);
        let third = a.next(u64::MAX).unwrap();
        assert_eq!(third.queued.frame.raw_id(), 0x080);
        assert_eq!(third.start_ns, second.end_ns);
    }

    #[test]
    fn an_idle_bus_starts_a_frame_when_it_is_queued() {
        let mut a = Arbiter::new(1_000_000, 8);
        a.offer(q(0x181, 8, 1, 5_000_000)).unwrap();
        assert_eq!(a.next_decision_ns(), Some(5_000_000));
        assert!(a.next(4_999_999).is_none());
        assert_eq!(a.next(9_000_000).unwrap().start_ns, 5_000_000);
    }

    #[test]
    fn a_full_queue_refuses_frames() {
        let mut a = Arbiter::new(1_000_000, 2);
        a.offer(q(1, 0, 0, 0)).unwrap();
        a.offer(q(2, 0, 0, 0)).unwrap();
        assert_eq!(a.offer(q(3, 0, 0, 0)), Err(QueueFull));
    }

    #[test]
    fn statistics_measure_load_and_waiting() {
        let stats = BusStats::new(1_000_000, Instant::now());
        let mut a = Arbiter::new(1_000_000, 8);
        a.offer(q(0x181, 8, 1, 0)).unwrap();
        a.offer(q(0x182, 8, 1, 0)).unwrap();
        let t1 = a.next(u64::MAX).unwrap();
        let t2 = a.next(u64::MAX).unwrap();
        stats.record(&t1);
        stats.record(&t2);
        let s = stats.snapshot();
        assert_eq!(s.frames, 2);
        assert!((s.load - 1.0).abs() < 1e-12, "back to back: {}", s.load);
        assert!((s.max_wait_us - (t1.end_ns as f64) / 1e3).abs() < 1e-9);
    }
}
