//! Period-jitter statistics of a periodic loop, in preallocated storage (a fixed histogram), so
//! recording a period allocates nothing.

/// Histogram bin width, nanoseconds (1 µs).
pub const JITTER_BIN_NS: u64 = 1_000;
/// Number of regular bins (deviations up to 2 ms); larger ones go to an overflow bin.
pub const JITTER_BINS: usize = 2_000;

/// Statistics of the measured periods of a loop against its nominal period.
#[derive(Debug, Clone)]
pub struct PeriodJitter {
    nominal_ns: u64,
    bins: [u32; JITTER_BINS],
    overflow: u32,
    count: u64,
    min_period_ns: u64,
    max_period_ns: u64,
    sum_period_ns: u128,
    max_lateness_ns: u64,
    missed_ticks: u64,
}

impl PeriodJitter {
    /// Empty statistics for a loop of nominal period `nominal_ns`.
    pub fn new(nominal_ns: u64) -> PeriodJitter {
        PeriodJitter {
            nominal_ns,
            bins: [0; JITTER_BINS],
            overflow: 0,
            count: 0,
            min_period_ns: u64::MAX,
            max_period_ns: 0,
            sum_period_ns: 0,
            max_lateness_ns: 0,
            missed_ticks: 0,
        }
    }

    /// Record one measured period (wake to wake). Allocation-free.
    pub fn record_period(&mut self, period_ns: u64) {
        self.count += 1;
        self.min_period_ns = self.min_period_ns.min(period_ns);
        self.max_period_ns = self.max_period_ns.max(period_ns);
        self.sum_period_ns += u128::from(period_ns);
        let bin = (period_ns.abs_diff(self.nominal_ns) / JITTER_BIN_NS) as usize;
        match self.bins.get_mut(bin) {
            Some(b) => *b = b.saturating_add(1),
            None => self.overflow = self.overflow.saturating_add(1),
        }
    }

    /// Record how late a wake-up was after its deadline.
    pub fn record_lateness(&mut self, lateness_ns: u64) {
        self.max_lateness_ns = self.max_lateness_ns.max(lateness_ns);
    }

    /// Record ticks skipped because the loop woke after their deadlines.
    pub fn record_missed(&mut self, ticks: u64) {
        self.missed_ticks += ticks;
    }

    /// Nominal period, nanoseconds.
    pub fn nominal_ns(&self) -> u64 {
        self.nominal_ns
    }
    /// Periods recorded.
    pub fn count(&self) -> u64 {
        self.count
    }
    /// Shortest period, nanoseconds (`None` before any).
    pub fn min_period_ns(&self) -> Option<u64> {
        (self.count > 0).then_some(self.min_period_ns)
    }
    /// Longest period, nanoseconds (`None` before any).
    pub fn max_period_ns(&self) -> Option<u64> {
        (self.count > 0).then_some(self.max_period_ns)
    }
    /// Mean period, nanoseconds (`None` before any).
    pub fn mean_period_ns(&self) -> Option<f64> {
        (self.count > 0).then(|| self.sum_period_ns as f64 / self.count as f64)
    }
    /// Latest wake-up after a deadline, nanoseconds.
    pub fn max_lateness_ns(&self) -> u64 {
        self.max_lateness_ns
    }
    /// Ticks skipped.
    pub fn missed_ticks(&self) -> u64 {
        self.missed_ticks
    }

    /// Upper bound of the `q`-quantile (`0 < q <= 1`) of `|period - nominal|`, nanoseconds, at the
    /// histogram's 1 µs resolution; `None` before any period or when the quantile lies in the
    /// overflow bin (beyond 2 ms).
    pub fn deviation_quantile_ns(&self, q: f64) -> Option<u64> {
        if self.count == 0 {
            return None;
        }
        let target = (q.clamp(0.0, 1.0) * self.count as f64).ceil().max(1.0) as u64;
        let mut seen = 0u64;
        for (i, &n) in self.bins.iter().enumerate() {
            seen += u64::from(n);
            if seen >= target {
                return Some((i as u64 + 1) * JITTER_BIN_NS);
            }
        }
        None
    }

    /// `deviation_quantile_ns(0.99)`.
    pub fn p99_deviation_ns(&self) -> Option<u64> {
        self.deviation_quantile_ns(0.99)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_min_max_and_overflow() {
        let mut j = PeriodJitter::new(1_000_000);
        assert_eq!(j.p99_deviation_ns(), None);
        for _ in 0..98 {
            j.record_period(1_000_000);
        }
        j.record_period(1_004_500); // 4.5 µs late
        j.record_period(990_000); // 10 µs early
        assert_eq!(j.count(), 100);
        assert_eq!(j.min_period_ns(), Some(990_000));
        assert_eq!(j.max_period_ns(), Some(1_004_500));
        assert_eq!(j.deviation_quantile_ns(0.98), Some(1_000));
        assert_eq!(j.p99_deviation_ns(), Some(5_000));
        assert_eq!(j.deviation_quantile_ns(1.0), Some(11_000));
        j.record_period(5_000_000);
        assert_eq!(j.deviation_quantile_ns(1.0), None, "beyond the histogram");
        assert!((j.mean_period_ns().unwrap() - 104_994_500.0 / 101.0).abs() < 1e-6);
    }
}
