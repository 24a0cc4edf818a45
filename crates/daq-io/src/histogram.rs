//! Allocation-free latency histogram: 10 ns bins to 200 µs, exact min and max.

use crate::contract::Latency;

/// Bin width in ns.
const BIN_NS: u64 = 10;
/// Bins (the last collects everything ≥ 200 µs).
const BINS: usize = 20_000;

/// Records latencies in ns; percentiles to 10 ns (beyond 200 µs: the exact maximum).
///
/// ```
/// let mut h = daq_io::LatencyHistogram::new();
/// for ns in [1_000, 2_000, 3_000] { h.record(ns); }
/// let l = h.summary();
/// assert_eq!((l.min_ns, l.max_ns, l.count), (1_000, 3_000, 3));
/// assert!((l.p50_ns as i64 - 2_000).abs() <= 10);
/// ```
#[derive(Clone)]
pub struct LatencyHistogram {
    bins: Box<[u32; BINS]>,
    count: u64,
    min: u64,
    max: u64,
}

impl Default for LatencyHistogram {
    fn default() -> Self {
        Self::new()
    }
}

impl LatencyHistogram {
    /// An empty histogram (allocates its bins once, here).
    pub fn new() -> Self {
        LatencyHistogram {
            bins: Box::new([0; BINS]),
            count: 0,
            min: u64::MAX,
            max: 0,
        }
    }

    /// Adds one latency in ns (allocation-free).
    #[inline]
    pub fn record(&mut self, ns: u64) {
        let bin = ((ns / BIN_NS) as usize).min(BINS - 1);
        self.bins[bin] = self.bins[bin].saturating_add(1);
        self.count += 1;
        self.min = self.min.min(ns);
        self.max = self.max.max(ns);
    }

    /// Adds every record of `other`.
    pub fn merge(&mut self, other: &LatencyHistogram) {
        for (a, b) in self.bins.iter_mut().zip(other.bins.iter()) {
            *a = a.saturating_add(*b);
        }
        self.count += other.count;
        self.min = self.min.min(other.min);
        self.max = self.max.max(other.max);
    }

    /// The latency below which a fraction `q` (0..=1) of the records lie, in ns (bin centre,
    /// clamped to the exact min and max).
    pub fn quantile(&self, q: f64) -> u64 {
        if self.count == 0 {
            return 0;
        }
        let rank = ((q * self.count as f64).ceil() as u64).clamp(1, self.count);
        let mut seen = 0u64;
        for (i, &n) in self.bins.iter().enumerate() {
            seen += n as u64;
            if seen >= rank {
                if i == BINS - 1 {
                    return self.max;
                }
                return (i as u64 * BIN_NS + BIN_NS / 2).clamp(self.min, self.max);
            }
        }
        self.max
    }

    /// Count, min, median, p99, p99.9 and max.
    pub fn summary(&self) -> Latency {
        Latency {
            count: self.count,
            min_ns: if self.count == 0 { 0 } else { self.min },
            p50_ns: self.quantile(0.5),
            p99_ns: self.quantile(0.99),
            p999_ns: self.quantile(0.999),
            max_ns: self.max,
        }
    }
}
