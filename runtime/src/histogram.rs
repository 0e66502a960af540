//! A fixed-size latency histogram: recording is O(1), allocation-free and bounded, so the control
//! thread can record every period. 1 µs buckets up to 2 ms, 100 µs buckets up to 100 ms, then one
//! overflow bucket; the exact maximum is kept as well.

/// Buckets of 1 µs from 0 to 2 ms.
const FINE_BUCKETS: usize = 2000;
const FINE_NS: u64 = 1_000;
/// Buckets of 100 µs from 2 ms to 100 ms.
const COARSE_BUCKETS: usize = 980;
const COARSE_NS: u64 = 100_000;
const FINE_LIMIT_NS: u64 = FINE_BUCKETS as u64 * FINE_NS;
const COARSE_LIMIT_NS: u64 = FINE_LIMIT_NS + COARSE_BUCKETS as u64 * COARSE_NS;
const BUCKETS: usize = FINE_BUCKETS + COARSE_BUCKETS + 1;

/// Latency histogram in nanoseconds.
#[derive(Clone)]
pub struct Histogram {
    counts: Box<[u64; BUCKETS]>,
    total: u64,
    max_ns: u64,
    sum_ns: u128,
}

impl core::fmt::Debug for Histogram {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Histogram")
            .field("total", &self.total)
            .field("max_ns", &self.max_ns)
            .finish()
    }
}

impl Default for Histogram {
    fn default() -> Self {
        Histogram::new()
    }
}

impl Histogram {
    /// An empty histogram (allocates its buckets once, here).
    pub fn new() -> Histogram {
        Histogram {
            counts: Box::new([0; BUCKETS]),
            total: 0,
            max_ns: 0,
            sum_ns: 0,
        }
    }

    fn bucket(ns: u64) -> usize {
        if ns < FINE_LIMIT_NS {
            (ns / FINE_NS) as usize
        } else if ns < COARSE_LIMIT_NS {
            FINE_BUCKETS + ((ns - FINE_LIMIT_NS) / COARSE_NS) as usize
        } else {
            BUCKETS - 1
        }
    }

    /// Upper edge of a bucket, nanoseconds.
    fn upper_edge_ns(bucket: usize) -> u64 {
        if bucket < FINE_BUCKETS {
            (bucket as u64 + 1) * FINE_NS
        } else if bucket < BUCKETS - 1 {
            FINE_LIMIT_NS + (bucket - FINE_BUCKETS + 1) as u64 * COARSE_NS
        } else {
            u64::MAX
        }
    }

    /// Record one value. O(1), no allocation.
    #[inline]
    pub fn record(&mut self, ns: u64) {
        self.counts[Self::bucket(ns)] += 1;
        self.total += 1;
        self.sum_ns += u128::from(ns);
        self.max_ns = self.max_ns.max(ns);
    }

    /// Number of values recorded.
    pub fn count(&self) -> u64 {
        self.total
    }

    /// Largest value recorded, nanoseconds.
    pub fn max_ns(&self) -> u64 {
        self.max_ns
    }

    /// Mean, nanoseconds (0 when empty).
    pub fn mean_ns(&self) -> f64 {
        if self.total == 0 {
            0.0
        } else {
            self.sum_ns as f64 / self.total as f64
        }
    }

    /// The value below which a fraction `q` (0..=1) of the records fall: the upper edge of the
    /// bucket holding that quantile, capped at the exact maximum. 0 when empty.
    pub fn quantile_ns(&self, q: f64) -> u64 {
        if self.total == 0 {
            return 0;
        }
        let rank = ((q.clamp(0.0, 1.0) * self.total as f64).ceil() as u64).max(1);
        let mut seen = 0;
        for (i, c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                return Self::upper_edge_ns(i).min(self.max_ns);
            }
        }
        self.max_ns
    }

    /// The buckets holding values, in order: lower edge, upper edge (`u64::MAX` for the
    /// overflow bucket) and count.
    pub fn buckets(&self) -> impl Iterator<Item = (u64, u64, u64)> + '_ {
        self.counts
            .iter()
            .enumerate()
            .filter(|(_, c)| **c > 0)
            .map(|(i, c)| {
                let lower = if i == 0 {
                    0
                } else {
                    Self::upper_edge_ns(i - 1)
                };
                (lower, Self::upper_edge_ns(i), *c)
            })
    }

    /// How many values exceeded `ns` (at bucket resolution).
    pub fn count_above(&self, ns: u64) -> u64 {
        let b = Self::bucket(ns);
        self.counts[b + 1..].iter().sum()
    }

    /// Forget everything.
    pub fn clear(&mut self) {
        self.counts.fill(0);
        self.total = 0;
        self.max_ns = 0;
        self.sum_ns = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_buckets_hold_every_value_between_their_edges() {
        let mut h = Histogram::new();
        let values = [
            0,
            999,
            1_000,
            1_500_000,
            2_050_000,
            99_999_999,
            100_000_000,
            u64::MAX,
        ];
        for v in values {
            h.record(v);
        }
        let buckets: Vec<(u64, u64, u64)> = h.buckets().collect();
        assert_eq!(
            buckets.iter().map(|b| b.2).sum::<u64>(),
            values.len() as u64
        );
        for v in values {
            assert!(
                buckets
                    .iter()
                    .any(|&(lo, hi, _)| lo <= v && (v < hi || hi == u64::MAX)),
                "{v} in no bucket: {buckets:?}"
            );
        }
        assert!(buckets.windows(2).all(|w| w[0].1 <= w[1].0));
    }

    #[test]
    fn quantiles_of_a_known_distribution() {
        let mut h = Histogram::new();
        for us in 1..=1000u64 {
            h.record(us * 1000 - 500);
        }
        assert_eq!(h.count(), 1000);
        assert_eq!(h.quantile_ns(0.5), 500_000);
        assert_eq!(h.quantile_ns(0.99), 990_000);
        assert_eq!(h.max_ns(), 999_500);
        assert_eq!(h.quantile_ns(1.0), 999_500, "capped at the exact maximum");
        assert_eq!(h.count_above(899_999), 100);
    }

    #[test]
    fn coarse_and_overflow_buckets() {
        let mut h = Histogram::new();
        h.record(5_050_000);
        h.record(3_000_000_000);
        assert_eq!(h.quantile_ns(0.5), 5_100_000);
        assert_eq!(h.quantile_ns(1.0), 3_000_000_000);
        assert!(Histogram::new().quantile_ns(0.5) == 0);
    }
}
