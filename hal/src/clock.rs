//! The monotonic clock the control loop is paced by. Injected, so a recorded or simulated
//! session runs the same loop code on simulated time.

use core::time::Duration;

/// A point on the monotonic clock, in nanoseconds since an arbitrary origin.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct MonoTime(pub u64);

impl MonoTime {
    /// Nanoseconds since the clock's origin.
    pub const fn as_nanos(self) -> u64 {
        self.0
    }
    /// Seconds since the clock's origin.
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 * 1e-9
    }
    /// This time plus a duration (saturating).
    pub fn plus(self, d: Duration) -> MonoTime {
        MonoTime(self.0.saturating_add(d.as_nanos() as u64))
    }
    /// This time plus some nanoseconds (saturating).
    pub const fn add_nanos(self, ns: u64) -> MonoTime {
        MonoTime(self.0.saturating_add(ns))
    }
    /// Nanoseconds from `earlier` to `self`, zero when `earlier` is later.
    pub const fn nanos_since(self, earlier: MonoTime) -> u64 {
        self.0.saturating_sub(earlier.0)
    }
}

/// A monotonic clock with absolute-time sleeps.
pub trait Clock {
    /// Now. **RT**.
    fn now(&self) -> MonoTime;
    /// Sleep until `deadline` (absolute); returns at once when it has passed. **RT** (this is the
    /// loop's one allowed blocking call besides bus I/O). A simulated clock advances the plant.
    fn sleep_until(&mut self, deadline: MonoTime);
}
