//! The vibrotactors on the digital twin: a recording implementation of
//! [`videt_hal::Vibrotactors`] that stores every output edge with its time in a preallocated
//! buffer, a simulated clock to drive the loop on simulated time, and the analysis of a recording
//! (frequency and duty per channel).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use videt_hal::{Clock, ErrorKind, ErrorType, MonoTime, Vibrotactors, VIBROTACTORS};

/// A clock on simulated time. Clones share the same time, so a device holding a clone stamps its
/// events with the loop's time. `sleep_until` jumps to the deadline plus an optional wake-up
/// latency drawn from a fixed-seed generator (to exercise jitter statistics deterministically).
#[derive(Debug, Clone)]
pub struct SimulatedClock {
    now_ns: Arc<AtomicU64>,
    max_latency_ns: u64,
    rng_state: u64,
}

impl SimulatedClock {
    /// A clock at `start` with punctual wake-ups.
    pub fn new(start: MonoTime) -> SimulatedClock {
        SimulatedClock {
            now_ns: Arc::new(AtomicU64::new(start.as_nanos())),
            max_latency_ns: 0,
            rng_state: 0x9E37_79B9_7F4A_7C15,
        }
    }

    /// The same clock whose wake-ups come late by a uniform pseudo-random `0..=max_latency_ns`
    /// (fixed seed `seed`).
    pub fn with_latency(mut self, max_latency_ns: u64, seed: u64) -> SimulatedClock {
        self.max_latency_ns = max_latency_ns;
        self.rng_state = seed | 1;
        self
    }

    /// Move time forward by `ns` (e.g. to simulate work).
    pub fn advance(&self, ns: u64) {
        self.now_ns.fetch_add(ns, Ordering::AcqRel);
    }

    fn next_latency(&mut self) -> u64 {
        if self.max_latency_ns == 0 {
            return 0;
        }
        // xorshift64*: deterministic, allocation-free.
        let mut x = self.rng_state;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.rng_state = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D) % (self.max_latency_ns + 1)
    }
}

impl Clock for SimulatedClock {
    fn now(&self) -> MonoTime {
        MonoTime(self.now_ns.load(Ordering::Acquire))
    }
    fn sleep_until(&mut self, deadline: MonoTime) {
        let latency = self.next_latency();
        let target = deadline.as_nanos().saturating_add(latency);
        self.now_ns.fetch_max(target, Ordering::AcqRel);
    }
}

/// One output change.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Edge {
    /// When it was written.
    pub time: MonoTime,
    /// Which vibrotactor (0 red, 1 green, 2 blue).
    pub channel: u8,
    /// The new state.
    pub on: bool,
}

/// Recording vibrotactors: keep the output states and log each change with the clock's time.
/// The log has a fixed capacity set at construction; when full, further edges are counted as
/// dropped (never grown), so `set_outputs` never allocates.
#[derive(Debug, Clone)]
pub struct RecordingVibrotactors<C> {
    clock: C,
    state: [bool; VIBROTACTORS],
    edges: Vec<Edge>,
    dropped_edges: u64,
    writes: u64,
    fail_from_write: Option<u64>,
}

impl<C: Clock> RecordingVibrotactors<C> {
    /// All outputs off, room for `capacity` edges, stamping with `clock`.
    pub fn new(clock: C, capacity: usize) -> Self {
        RecordingVibrotactors {
            clock,
            state: [false; VIBROTACTORS],
            edges: Vec::with_capacity(capacity),
            dropped_edges: 0,
            writes: 0,
            fail_from_write: None,
        }
    }

    /// Make every write from the `n`-th on (0-based) fail with `Disconnected` (a pulled
    /// connector), to test the loop's reaction.
    pub fn fail_from_write(&mut self, n: u64) {
        self.fail_from_write = Some(n);
    }

    /// The current outputs.
    pub fn state(&self) -> [bool; VIBROTACTORS] {
        self.state
    }
    /// The recorded edges, oldest first.
    pub fn edges(&self) -> &[Edge] {
        &self.edges
    }
    /// Edges that did not fit.
    pub fn dropped_edges(&self) -> u64 {
        self.dropped_edges
    }
    /// Successful `set_outputs` calls.
    pub fn writes(&self) -> u64 {
        self.writes
    }
    /// Forget the recorded edges (keeps the capacity and the states).
    pub fn clear(&mut self) {
        self.edges.clear();
        self.dropped_edges = 0;
    }

    /// Frequency and duty of one channel over `[from, to)`, from the recorded edges. The state
    /// before the first edge in the window is taken from the edges before it (off if none).
    pub fn channel_summary(&self, channel: usize, from: MonoTime, to: MonoTime) -> ChannelSummary {
        summarize(&self.edges, channel, from, to)
    }
}

impl<C> ErrorType for RecordingVibrotactors<C> {
    type Error = ErrorKind;
}

impl<C: Clock> Vibrotactors for RecordingVibrotactors<C> {
    fn set_outputs(&mut self, on: &[bool; VIBROTACTORS]) -> Result<(), ErrorKind> {
        if self.fail_from_write.is_some_and(|n| self.writes >= n) {
            return Err(ErrorKind::Disconnected);
        }
        let time = self.clock.now();
        for (channel, (&new, old)) in on.iter().zip(self.state.iter_mut()).enumerate() {
            if new != *old {
                *old = new;
                if self.edges.len() < self.edges.capacity() {
                    self.edges.push(Edge {
                        time,
                        channel: channel as u8,
                        on: new,
                    });
                } else {
                    self.dropped_edges += 1;
                }
            }
        }
        self.writes += 1;
        Ok(())
    }
}

/// What a channel did over a time window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChannelSummary {
    /// Rising edges in the window.
    pub rising_edges: u64,
    /// `(rising_edges - 1) / (last rising - first rising)`, Hz; `None` with fewer than 2.
    pub frequency_hz: Option<f64>,
    /// Fraction of the window the output was on.
    pub duty: f64,
    /// Shortest and longest time between consecutive rising edges, nanoseconds.
    pub period_range_ns: Option<(u64, u64)>,
}

/// Summarize one channel's edges over `[from, to)`.
pub fn summarize(edges: &[Edge], channel: usize, from: MonoTime, to: MonoTime) -> ChannelSummary {
    let mut state = false;
    let mut since = from;
    let mut on_ns = 0u64;
    let mut rising = 0u64;
    let mut first_rise: Option<MonoTime> = None;
    let mut last_rise: Option<MonoTime> = None;
    let mut range: Option<(u64, u64)> = None;
    for e in edges.iter().filter(|e| usize::from(e.channel) == channel) {
        if e.time < from {
            state = e.on;
            continue;
        }
        if e.time >= to {
            break;
        }
        if state {
            on_ns += e.time.nanos_since(since);
        }
        if e.on && !state {
            rising += 1;
            if let Some(prev) = last_rise {
                let p = e.time.nanos_since(prev);
                range = Some(range.map_or((p, p), |(lo, hi)| (lo.min(p), hi.max(p))));
            }
            first_rise.get_or_insert(e.time);
            last_rise = Some(e.time);
        }
        state = e.on;
        since = e.time;
    }
    if state {
        on_ns += to.nanos_since(since);
    }
    let window_ns = to.nanos_since(from);
    let frequency_hz = match (first_rise, last_rise) {
        (Some(a), Some(b)) if rising >= 2 && b > a => {
            Some((rising - 1) as f64 / (b.nanos_since(a) as f64 * 1e-9))
        }
        _ => None,
    };
    ChannelSummary {
        rising_edges: rising,
        frequency_hz,
        duty: if window_ns == 0 {
            0.0
        } else {
            on_ns as f64 / window_ns as f64
        },
        period_range_ns: range,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_edges_only_and_drops_when_full() {
        let clock = SimulatedClock::new(MonoTime(1_000));
        let mut v = RecordingVibrotactors::new(clock.clone(), 3);
        v.set_outputs(&[true, false, false]).unwrap();
        clock.advance(500);
        v.set_outputs(&[true, false, false]).unwrap(); // no change: no edge
        v.set_outputs(&[false, true, false]).unwrap();
        assert_eq!(v.edges().len(), 3);
        assert_eq!(
            v.edges()[1],
            Edge {
                time: MonoTime(1_500),
                channel: 0,
                on: false
            }
        );
        v.set_outputs(&[false, false, true]).unwrap();
        assert_eq!(v.edges().len(), 3, "capacity is fixed");
        assert_eq!(v.dropped_edges(), 2);
        assert_eq!(v.writes(), 4);
        v.fail_from_write(4);
        assert_eq!(v.set_outputs(&[false; 3]), Err(ErrorKind::Disconnected));
    }

    #[test]
    fn summary_of_a_known_square_wave() {
        // 10 periods of 1000 ns, on for 300 ns each, channel 1.
        let mut edges = Vec::new();
        for k in 0..10u64 {
            edges.push(Edge {
                time: MonoTime(k * 1000),
                channel: 1,
                on: true,
            });
            edges.push(Edge {
                time: MonoTime(k * 1000 + 300),
                channel: 1,
                on: false,
            });
        }
        let s = summarize(&edges, 1, MonoTime(0), MonoTime(10_000));
        assert_eq!(s.rising_edges, 10);
        assert!((s.frequency_hz.unwrap() - 1e6).abs() < 1e-6);
        assert!((s.duty - 0.3).abs() < 1e-12);
        assert_eq!(s.period_range_ns, Some((1000, 1000)));
        // A window starting mid-pulse counts the pulse's remainder.
        let s = summarize(&edges, 1, MonoTime(100), MonoTime(1_100));
        assert!((s.duty - 0.3).abs() < 1e-12, "{s:?}");
        let quiet = summarize(&edges, 0, MonoTime(0), MonoTime(10_000));
        assert_eq!(quiet.duty, 0.0);
        assert_eq!(quiet.frequency_hz, None);
    }

    #[test]
    fn simulated_latency_is_bounded_and_deterministic() {
        let mut a = SimulatedClock::new(MonoTime(0)).with_latency(5_000, 7);
        let mut b = SimulatedClock::new(MonoTime(0)).with_latency(5_000, 7);
        for k in 1..100u64 {
            a.sleep_until(MonoTime(k * 100_000));
            b.sleep_until(MonoTime(k * 100_000));
            assert_eq!(a.now(), b.now());
            assert!(a.now().as_nanos() - k * 100_000 <= 5_000);
        }
    }
}
