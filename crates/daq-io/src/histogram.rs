//! Allocation-free latency histogram: 10 ns bins to 200 µs, 1 µs bins to 20 ms (the stalls of
//! a VM), exact min and max, and a coarse level (100 bins per group) so percentiles come from
//! a scan of a few hundred bins — cheap enough for a health report between two ticks.

use crate::contract::Latency;

/// Fine bins: 10 ns wide, to 200 µs.
const FINE_BINS: usize = 20_000;
/// Fine bin width in ns.
const FINE_NS: u64 = 10;
/// Where the wide bins start, ns.
const WIDE_FROM_NS: u64 = FINE_BINS as u64 * FINE_NS;
/// Wide bin width in ns.
const WIDE_NS: u64 = 1_000;
/// Bins in all (the last collects everything ≥ 20 ms).
const BINS: usize = FINE_BINS + 19_800;
/// Bins per coarse group.
const FINE_PER_COARSE: usize = 100;
/// Coarse groups.
const COARSE: usize = BINS / FINE_PER_COARSE;

/// The bin of `ns`.
#[inline]
fn bin_of(ns: u64) -> usize {
    if ns < WIDE_FROM_NS {
        (ns / FINE_NS) as usize
    } else {
        (FINE_BINS + ((ns - WIDE_FROM_NS) / WIDE_NS) as usize).min(BINS - 1)
    }
}

/// The centre of bin `b`, ns.
fn centre_of(b: usize) -> u64 {
    if b < FINE_BINS {
        b as u64 * FINE_NS + FINE_NS / 2
    } else {
        WIDE_FROM_NS + (b - FINE_BINS) as u64 * WIDE_NS + WIDE_NS / 2
    }
}

/// Records latencies in ns; percentiles to 10 ns below 200 µs, to 1 µs below 20 ms (beyond:
/// the exact maximum).
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
    coarse: Box<[u64; COARSE]>,
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
            coarse: Box::new([0; COARSE]),
            count: 0,
            min: u64::MAX,
            max: 0,
        }
    }

    /// Adds one latency in ns (allocation-free).
    #[inline]
    pub fn record(&mut self, ns: u64) {
        let bin = bin_of(ns);
        self.bins[bin] = self.bins[bin].saturating_add(1);
        self.coarse[bin / FINE_PER_COARSE] += 1;
        self.count += 1;
        self.min = self.min.min(ns);
        self.max = self.max.max(ns);
    }

    /// Adds every record of `other`.
    pub fn merge(&mut self, other: &LatencyHistogram) {
        for (a, b) in self.bins.iter_mut().zip(other.bins.iter()) {
            *a = a.saturating_add(*b);
        }
        for (a, b) in self.coarse.iter_mut().zip(other.coarse.iter()) {
            *a += b;
        }
        self.count += other.count;
        self.min = self.min.min(other.min);
        self.max = self.max.max(other.max);
    }

    /// The latency below which a fraction `q` (0..=1) of the records lie, in ns (bin centre,
    /// clamped to the exact min and max).
    pub fn quantile(&self, q: f64) -> u64 {
        let mut out = [0];
        self.quantiles(&[q], &mut out);
        out[0]
    }

    /// [`Self::quantile`] of every `q` (ascending) into `out`, in one pass over the bins.
    pub fn quantiles(&self, qs: &[f64], out: &mut [u64]) {
        if self.count == 0 {
            out.iter_mut().for_each(|o| *o = 0);
            return;
        }
        let rank = |q: f64| ((q * self.count as f64).ceil() as u64).clamp(1, self.count);
        let mut next = 0; // the first quantile not yet found
        let mut seen = 0u64;
        for (c, &n) in self.coarse.iter().enumerate() {
            if next == qs.len() {
                return;
            }
            if seen + n < rank(qs[next]) {
                seen += n;
                continue;
            }
            let first = c * FINE_PER_COARSE;
            for (i, &m) in self.bins[first..first + FINE_PER_COARSE].iter().enumerate() {
                seen += m as u64;
                while next < qs.len() && seen >= rank(qs[next]) {
                    let bin = first + i;
                    out[next] = if bin == BINS - 1 {
                        self.max
                    } else {
                        centre_of(bin).clamp(self.min, self.max)
                    };
                    next += 1;
                }
            }
        }
        out[next..].iter_mut().for_each(|o| *o = self.max);
    }

    /// Count, min, median, p99, p99.9, p99.99 and max (one pass over the bins: cheap enough
    /// for a health report between two ticks).
    pub fn summary(&self) -> Latency {
        let mut p = [0; 4];
        self.quantiles(&[0.5, 0.99, 0.999, 0.9999], &mut p);
        Latency {
            count: self.count,
            min_ns: if self.count == 0 { 0 } else { self.min },
            p50_ns: p[0],
            p99_ns: p[1],
            p999_ns: p[2],
            p9999_ns: p[3],
            max_ns: self.max,
        }
    }
}

/// The per-tick times a servo process keeps (allocation-free after creation): round trip,
/// start lateness and execution time, reported in its [`crate::Health`].
#[derive(Clone, Default)]
pub struct TickStats {
    /// Sensor published → command received (the plant's view).
    pub round_trip: LatencyHistogram,
    /// Tick start after its deadline (the controller: after the sample's publication).
    pub lateness: LatencyHistogram,
    /// The tick's own work (Simulink Real-Time's TET).
    pub execution: LatencyHistogram,
}

impl TickStats {
    /// Writes the percentiles into `health` (one pass over each histogram: a few hundred
    /// additions, cheap enough between two ticks).
    pub fn report(&self, health: &mut crate::Health) {
        health.latency = self.round_trip.summary();
        health.lateness = self.lateness.summary();
        health.execution = self.execution.summary();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_equal_the_sorted_reference_across_the_coarse_bins() {
        // Spread over many coarse bins, with tails in the wide bins and past the range.
        let data: Vec<u64> = (0..50_000u64)
            .map(|k| {
                (k * 7919) % 180_000
                    + match k % 997 {
                        0 => 400_000,
                        1 => 30_000_000,
                        _ => 0,
                    }
            })
            .collect();
        let mut h = LatencyHistogram::new();
        data.iter().for_each(|&d| h.record(d));
        let mut sorted = data.clone();
        sorted.sort_unstable();
        let n = sorted.len();
        for q in [
            0.001, 0.25, 0.5, 0.9, 0.99, 0.9975, 0.9985, 0.999, 0.9999, 1.0,
        ] {
            let want = sorted[((q * n as f64).ceil() as usize).clamp(1, n) - 1];
            let got = h.quantile(q);
            if want >= 20_000_000 {
                assert_eq!(got, *sorted.last().unwrap(), "q {q}: beyond the range");
            } else if want >= 200_000 {
                assert!(got.abs_diff(want) <= 500, "q {q}: {got} vs {want}");
            } else {
                assert!(got.abs_diff(want) <= 5, "q {q}: {got} vs {want}");
            }
        }
        let l = h.summary();
        assert_eq!(
            [l.p50_ns, l.p99_ns, l.p999_ns, l.p9999_ns],
            [0.5, 0.99, 0.999, 0.9999].map(|q| h.quantile(q))
        );
    }
}
