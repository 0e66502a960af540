//! Fault injection shared by the bus transports: drop rate, delivery delay, bus-off.

use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};

/// Run-time adjustable faults of a bus. Shared (`Arc`) between the endpoints and the test or
/// tool that injects the faults; every field is an atomic, so injecting never blocks the bus.
#[derive(Debug)]
pub struct BusFaults {
    drop_ppm: AtomicU32,
    delay_us: AtomicU32,
    bus_off: AtomicBool,
    rng_state: AtomicU64,
    dropped: AtomicU64,
}

impl Default for BusFaults {
    fn default() -> Self {
        BusFaults::new(0x5EED_CAFE_F00D_1234)
    }
}

impl BusFaults {
    /// No faults; `seed` fixes the sequence of random drops (reproducible runs).
    pub fn new(seed: u64) -> BusFaults {
        BusFaults {
            drop_ppm: AtomicU32::new(0),
            delay_us: AtomicU32::new(0),
            bus_off: AtomicBool::new(false),
            rng_state: AtomicU64::new(seed | 1),
            dropped: AtomicU64::new(0),
        }
    }

    /// Drop each transmitted frame with probability `rate` (clamped to [0, 1]).
    pub fn set_drop_rate(&self, rate: f64) {
        let ppm = (rate.clamp(0.0, 1.0) * 1e6).round() as u32;
        self.drop_ppm.store(ppm, Ordering::Relaxed);
    }

    /// Deliver every frame `delay` after it was sent (0 = at once).
    pub fn set_delay(&self, delay: std::time::Duration) {
        let us = u32::try_from(delay.as_micros()).unwrap_or(u32::MAX);
        self.delay_us.store(us, Ordering::Relaxed);
    }

    /// The configured delivery delay.
    pub fn delay(&self) -> std::time::Duration {
        std::time::Duration::from_micros(u64::from(self.delay_us.load(Ordering::Relaxed)))
    }

    /// Put the bus off (`true`) or back on.
    pub fn set_bus_off(&self, off: bool) {
        self.bus_off.store(off, Ordering::Relaxed);
    }

    /// Whether the bus is off.
    pub fn is_bus_off(&self) -> bool {
        self.bus_off.load(Ordering::Relaxed)
    }

    /// Frames dropped by injection so far.
    pub fn dropped_frames(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Decide whether the next transmitted frame is dropped (consumes one random draw).
    pub(crate) fn should_drop(&self) -> bool {
        let ppm = self.drop_ppm.load(Ordering::Relaxed);
        if ppm == 0 {
            return false;
        }
        // xorshift64*, advanced atomically so concurrent senders never share a draw.
        let mut x = self.rng_state.load(Ordering::Relaxed);
        loop {
            let mut y = x;
            y ^= y >> 12;
            y ^= y << 25;
            y ^= y >> 27;
            match self
                .rng_state
                .compare_exchange_weak(x, y, Ordering::Relaxed, Ordering::Relaxed)
            {
                Ok(_) => {
                    let draw = (y.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 32) % 1_000_000;
                    let drop = (draw as u32) < ppm;
                    if drop {
                        self.dropped.fetch_add(1, Ordering::Relaxed);
                    }
                    return drop;
                }
                Err(current) => x = current,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drop_rate_is_close_to_the_configured_probability() {
        let f = BusFaults::new(42);
        f.set_drop_rate(0.25);
        let n = 100_000;
        let dropped = (0..n).filter(|_| f.should_drop()).count();
        let rate = dropped as f64 / n as f64;
        assert!((rate - 0.25).abs() < 0.01, "rate {rate}");
        assert_eq!(f.dropped_frames(), dropped as u64);
    }

    #[test]
    fn zero_and_full_drop_rates_are_exact() {
        let f = BusFaults::new(1);
        assert!(!(0..1000).any(|_| f.should_drop()));
        f.set_drop_rate(1.0);
        assert!((0..1000).all(|_| f.should_drop()));
    }
}
