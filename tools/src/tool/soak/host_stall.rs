//! Telling the host's stalls from the service's faults. A safe state nobody injected is the
//! host's when the session log and the kernel show that the control thread lost the CPU just
//! before: woken half a period late (the kernel not running a SCHED_FIFO thread on time), or
//! held up for many periods in the middle of a cycle while the hypervisor reports that much
//! time stolen from the virtual machine's CPUs (`steal` in `/proc/stat`).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use videt_runtime::telemetry::Log;

/// A cycle that lasted this long was held up, not slow: its only blocking calls are the bus
/// I/O, each bounded by a period.
const HELD_UP_NS: u64 = 20_000_000;

/// Stolen time that can explain a cycle held up, at least, ms.
const MIN_STOLEN_MS: f64 = 20.0;

/// Why a safe state is the host's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum HostStall {
    /// The control thread was woken this late, microseconds.
    LateWakeUp {
        /// The latest wake-up in the periods before.
        late_us: f64,
    },
    /// A cycle was held up this long while the hypervisor took the CPUs away.
    CpuStolen {
        /// The longest period, wake-up and cycle, milliseconds.
        held_ms: f64,
        /// Time stolen from the control CPU meanwhile, milliseconds.
        stolen_ms: f64,
    },
}

impl HostStall {
    /// In words, for the soak's table.
    pub(super) fn describe(&self) -> String {
        match *self {
            HostStall::LateWakeUp { late_us } => format!(
                "the host woke the control thread {:.1} ms late just before",
                late_us / 1e3
            ),
            HostStall::CpuStolen { held_ms, stolen_ms } => format!(
                "a cycle was held up {held_ms:.0} ms while the hypervisor took {stolen_ms:.0} ms from the control CPU"
            ),
        }
    }
}

/// An entry into a safe state recorded in a session log.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct SafeStateEntry {
    /// Time of the first safe period in the run, seconds.
    pub time_s: f64,
    /// The safe state's name (as the control socket gives it).
    pub state: String,
    /// When the host caused it, how.
    pub host: Option<HostStall>,
}

/// Every entry into a safe state in `log`, each marked as the host's when, over the periods
/// before it and its own (the overrun limit's worth from the recorded configuration, and at
/// least 0.2 s: the drives' silence timeouts):
/// - the control thread woke at least half a period late. The loop keeps its period grid,
///   skipping the periods already gone, so its own slowness never shows as a late wake-up: a
///   late wake-up is the kernel not running a SCHED_FIFO thread on time (a virtual machine
///   whose CPU is taken away, a kernel without PREEMPT_RT under load);
/// - or a period lasted [`HELD_UP_NS`] or more, wake-up and cycle, and `stolen_ms(cpu, from,
///   to)` (the hypervisor's stolen time on the control CPU between two Unix times, ns) says at
///   least half of that (and at least [`MIN_STOLEN_MS`]) was taken from the CPU around it.
pub(super) fn safe_state_entries(
    log: &Log,
    stolen_ms: &dyn Fn(Option<usize>, u64, u64) -> f64,
) -> Vec<SafeStateEntry> {
    let rate = log.header.rate_hz.max(1);
    let period_ns = 1e9 / f64::from(rate);
    let config = log
        .session
        .as_ref()
        .and_then(|s| s.as_ref().ok())
        .map(|s| &s.config);
    let limit = config
        .map_or(10, |c| c.realtime.max_consecutive_overruns)
        .max(rate / 5)
        .max(1) as usize;
    let cpu = config.and_then(|c| usize::try_from(c.realtime.control_cpu).ok());
    let mut entries = Vec::new();
    for k in 1..log.records.len() {
        let Some(reason) = log.records[k].safety.reason() else {
            continue;
        };
        if log.records[k - 1].safety.reason().is_some() {
            continue;
        }
        let before = &log.records[k.saturating_sub(limit)..k];
        let latest = before.iter().map(|r| r.wake_latency_ns).max().unwrap_or(0) as f64;
        let window = &log.records[k.saturating_sub(limit)..=k];
        let held_ns = window
            .iter()
            .map(|r| r.wake_latency_ns + r.compute_ns)
            .max()
            .unwrap_or(0);
        let host = if latest >= 0.5 * period_ns {
            Some(HostStall::LateWakeUp {
                late_us: latest / 1e3,
            })
        } else if held_ns >= HELD_UP_NS {
            let at = |r: &videt_runtime::cycle::CycleRecord| log.header.start_unix_ns + r.time.0;
            // The log's clock starts with the control loop, a moment after its header's wall
            // time; the steal counter is sampled every 20 ms: half a second of slack each side.
            let from = at(&window[0]).saturating_sub(500_000_000);
            let to = at(&log.records[k]) + 500_000_000;
            let stolen = stolen_ms(cpu, from, to);
            let held_ms = held_ns as f64 / 1e6;
            // At least two of the counter's ticks: it gathers slices too short to stall
            // anything (about 10 ms a minute on an idle machine).
            (stolen >= (0.5 * held_ms).max(MIN_STOLEN_MS)).then_some(HostStall::CpuStolen {
                held_ms,
                stolen_ms: stolen,
            })
        } else {
            None
        };
        entries.push(SafeStateEntry {
            time_s: log.records[k].time.0 as f64 / 1e9,
            state: reason.as_str().to_string(),
            host,
        });
    }
    entries
}

/// A reading of the stolen time: (Unix time, ns; stolen time of each CPU so far, ms).
type StealSample = (u64, Vec<f64>);

/// The hypervisor's stolen time of each CPU (`steal` in `/proc/stat`), sampled every 20 ms
/// by a thread of its own for as long as this lives.
pub(super) struct StolenTime {
    /// The readings, kept when they changed.
    samples: Arc<Mutex<Vec<StealSample>>>,
    stop: Arc<AtomicBool>,
}

/// The clock ticks per second `/proc/stat` counts in.
fn clock_ticks_per_s() -> f64 {
    // SAFETY: sysconf has no preconditions.
    match unsafe { libc::sysconf(libc::_SC_CLK_TCK) } {
        t if t > 0 => t as f64,
        _ => 100.0,
    }
}

/// Each CPU's stolen time from the text of `/proc/stat` (its `cpuN` lines, 8th value, in
/// clock ticks), ms.
fn parse_steal_ms(text: &str, ticks_per_s: f64) -> Vec<f64> {
    let mut cpus = Vec::new();
    for line in text.lines() {
        let mut fields = line.split_whitespace();
        let Some(name) = fields.next() else { continue };
        let Some(index) = name.strip_prefix("cpu").filter(|n| !n.is_empty()) else {
            continue;
        };
        let (Ok(index), Some(steal)) = (index.parse::<usize>(), fields.nth(7)) else {
            continue;
        };
        if cpus.len() <= index {
            cpus.resize(index + 1, 0.0);
        }
        cpus[index] = steal.parse::<f64>().unwrap_or(0.0) * 1e3 / ticks_per_s;
    }
    cpus
}

fn unix_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

impl StolenTime {
    /// Start sampling.
    pub(super) fn start() -> StolenTime {
        let samples = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let (kept, stopped) = (Arc::clone(&samples), Arc::clone(&stop));
        std::thread::spawn(move || {
            let ticks_per_s = clock_ticks_per_s();
            while !stopped.load(Ordering::Relaxed) {
                if let Ok(text) = std::fs::read_to_string("/proc/stat") {
                    let now = parse_steal_ms(&text, ticks_per_s);
                    if let Ok(mut k) = kept.lock() {
                        if k.last().map(|(_, v)| v) != Some(&now) {
                            k.push((unix_ns(), now));
                        }
                    }
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        });
        StolenTime { samples, stop }
    }

    /// Time stolen from `cpu` (all CPUs together when `None`) between two Unix times, ns.
    pub(super) fn stolen_ms(&self, cpu: Option<usize>, from_ns: u64, to_ns: u64) -> f64 {
        let Ok(samples) = self.samples.lock() else {
            return 0.0;
        };
        stolen_between(&samples, cpu, from_ns, to_ns)
    }
}

impl Drop for StolenTime {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

/// From samples kept when they changed: the increase of `cpu`'s stolen time between the last
/// samples at or before `from_ns` and `to_ns` (before the first sample, its value: nothing is
/// known earlier).
fn stolen_between(samples: &[StealSample], cpu: Option<usize>, from_ns: u64, to_ns: u64) -> f64 {
    if samples.is_empty() || from_ns > to_ns {
        return 0.0;
    }
    let value = |t: u64| {
        let at = samples.partition_point(|(s, _)| *s <= t).max(1);
        let v = &samples[at - 1].1;
        match cpu {
            Some(c) => v.get(c).copied().unwrap_or(0.0),
            None => v.iter().sum(),
        }
    };
    (value(to_ns) - value(from_ns)).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use videt_runtime::cycle::CycleRecord;
    use videt_runtime::telemetry::LogHeader;

    /// 100 periods at 1 kHz; periods 50..60 woken `late_ns` late, period 60 lasting
    /// `held_ns` of cycle, the safe state from period 60 on.
    fn log_with(late_ns: u64, held_ns: u64) -> Log {
        use videt_control::{SafetyReason, SafetyState};
        let records = (0..100u64)
            .map(|k| CycleRecord {
                cycle: k,
                time: videt_hal::MonoTime(k * 1_000_000),
                wake_latency_ns: if (50..60).contains(&k) {
                    late_ns
                } else {
                    15_000
                },
                compute_ns: if k == 60 { held_ns } else { 400_000 },
                safety: if k >= 60 {
                    SafetyState::MinimumTension(SafetyReason::DeadlineOverrun)
                } else {
                    SafetyState::Normal
                },
                ..CycleRecord::default()
            })
            .collect();
        Log::of_records(
            LogHeader {
                rate_hz: 1000,
                start_unix_ns: 7_000_000_000,
            },
            records,
        )
    }

    #[test]
    fn a_safe_state_is_the_hosts_only_when_the_wake_ups_before_it_were_late() {
        let none = |_: Option<usize>, _: u64, _: u64| 0.0;
        // The kernel woke the control thread 1.5 ms late: the host's doing.
        let e = safe_state_entries(&log_with(1_500_000, 400_000), &none);
        assert_eq!(e.len(), 1);
        assert_eq!(e[0].state, "deadline-overrun");
        assert_eq!(e[0].host, Some(HostStall::LateWakeUp { late_us: 1500.0 }));
        assert!((e[0].time_s - 0.060).abs() < 1e-9, "{}", e[0].time_s);
        // On time every period: the overruns were the cycle's own.
        let e = safe_state_entries(&log_with(40_000, 400_000), &none);
        assert_eq!((e.len(), e[0].host), (1, None));
    }

    #[test]
    fn a_cycle_held_up_is_the_hosts_only_when_the_hypervisor_took_the_cpu() {
        // A cycle held up 100 ms while 100 ms were stolen around it, on the control CPU.
        let asked = std::cell::Cell::new(None);
        let stolen = |cpu: Option<usize>, from: u64, to: u64| {
            asked.set(Some((cpu, from, to)));
            100.0
        };
        let e = safe_state_entries(&log_with(15_000, 100_000_000), &stolen);
        assert_eq!(
            e[0].host,
            Some(HostStall::CpuStolen {
                held_ms: 100.015,
                stolen_ms: 100.0
            })
        );
        // Asked about the window around the period, on the log's wall clock.
        let (_, from, to) = asked.get().unwrap();
        assert!(from <= 7_000_000_000 + 60_000_000 && to >= 7_000_000_000 + 60_000_000);
        // Nothing stolen: the cycle blocked by itself, a failure.
        let e = safe_state_entries(&log_with(15_000, 100_000_000), &|_, _, _| 10.0);
        assert_eq!(e[0].host, None);
        // A cycle 5 ms long is slow, not held up: no excuse whatever was stolen.
        let e = safe_state_entries(&log_with(15_000, 5_000_000), &stolen);
        assert_eq!(e[0].host, None);
    }

    #[test]
    fn stolen_time_is_read_per_cpu_and_between_two_instants() {
        let text = "cpu  1 2 3 4 5 6 7 900 0 0\ncpu0 1 2 3 4 5 6 7 300 0 0\ncpu1 1 2 3 4 5 6 7 600 0 0\nintr 5\n";
        assert_eq!(parse_steal_ms(text, 100.0), vec![3000.0, 6000.0]);
        let samples = vec![
            (100, vec![0.0, 10.0]),
            (200, vec![0.0, 110.0]),
            (300, vec![20.0, 110.0]),
        ];
        assert_eq!(stolen_between(&samples, Some(1), 150, 250), 100.0);
        assert_eq!(stolen_between(&samples, Some(1), 210, 400), 0.0);
        assert_eq!(stolen_between(&samples, None, 50, 400), 120.0);
        assert_eq!(stolen_between(&[], None, 50, 400), 0.0);
    }
}
