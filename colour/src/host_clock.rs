//! The host's monotonic clock (`std::time::Instant`) as a [`videt_hal::Clock`], for running the
//! vibration loop on a workstation or in measurements. Deadlines are absolute; the sleep itself
//! is `std::thread::sleep` for the remaining time, so the schedule does not drift even though
//! each wake-up may come late.

use std::time::{Duration, Instant};

use videt_hal::{Clock, MonoTime};

/// Nanoseconds since the clock was created, on the host's monotonic clock. Copies share the
/// origin.
#[derive(Debug, Clone, Copy)]
pub struct HostClock {
    origin: Instant,
}

impl Default for HostClock {
    fn default() -> Self {
        HostClock::new()
    }
}

impl HostClock {
    /// A clock whose zero is now.
    pub fn new() -> HostClock {
        HostClock {
            origin: Instant::now(),
        }
    }
}

impl Clock for HostClock {
    fn now(&self) -> MonoTime {
        MonoTime(self.origin.elapsed().as_nanos() as u64)
    }
    fn sleep_until(&mut self, deadline: MonoTime) {
        let now = self.now();
        if deadline > now {
            std::thread::sleep(Duration::from_nanos(deadline.nanos_since(now)));
        }
    }
}
