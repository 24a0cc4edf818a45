//! What a [`crate::Servo`] keeps beside the tick on a host with the standard library: each
//! tick's timing (start lateness after the sample was taken, execution), what the loop was made
//! for, the controller it runs.

use daq_io::clock::monotonic_ns;
use daq_io::{Latency, Sensor, TickStats};

/// Tick timing of a loop ([`crate::Servo::timing`]), percentiles in ns.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Timing {
    /// Each tick's start after its sample was taken ([`Sensor::published_ns`]), plus a period
    /// for each sample skipped.
    pub lateness: Latency,
    /// Each tick's own work, sample in to command out (Simulink Real-Time's TET).
    pub execution: Latency,
}

/// The host side of a [`crate::Servo`].
pub(crate) struct Host {
    stats: TickStats,
    period_ns: u64,
    expected_seq: u64,
    overruns: u64,
    /// Telemetry dropped by services that have ended.
    #[cfg(feature = "serve")]
    pub(crate) dropped: u64,
    pub(crate) made_for: Option<servo_config::MadeFor>,
    /// The controller the loop runs (a loaded state-space file takes its output limit).
    pub(crate) spec: servo_config::ControllerSpec,
    /// The deployment's servo rate in Hz, as written (what stability records are sealed to).
    pub(crate) servo_rate_hz: f64,
}

impl Host {
    pub(crate) fn new(d: &crate::Deployment) -> Self {
        Host {
            stats: TickStats::default(),
            period_ns: (d.period_s() * 1e9).round() as u64,
            expected_seq: 0,
            overruns: 0,
            #[cfg(feature = "serve")]
            dropped: 0,
            made_for: None,
            spec: d.controller.clone(),
            servo_rate_hz: d.servo_rate_hz,
        }
    }

    /// The tick's start in ns of `CLOCK_MONOTONIC`, when `sample` says when it was taken (0:
    /// the tick is not timed).
    #[inline]
    pub(crate) fn start(&self, sample: &Sensor) -> u64 {
        if sample.published_ns != 0 {
            monotonic_ns()
        } else {
            0
        }
    }

    /// Records the timing of the tick of `sample` that started at `started_ns`.
    #[inline]
    pub(crate) fn record(&mut self, sample: &Sensor, started_ns: u64) {
        let expected = core::mem::replace(&mut self.expected_seq, sample.seq.saturating_add(1));
        // Tick 0 sets things up (connections, caches): it is not timed.
        if started_ns == 0 || sample.seq == 0 {
            return;
        }
        self.stats
            .execution
            .record(monotonic_ns().saturating_sub(started_ns));
        // A loop that fell behind takes the newest sample and skips the rest, a period each.
        // A peer's sequence is not taken on trust: a jump of any size saturates, never wraps.
        let skipped = sample
            .seq
            .saturating_sub(expected)
            .saturating_mul(self.period_ns);
        let late = started_ns
            .saturating_sub(sample.published_ns)
            .saturating_add(skipped);
        self.stats.lateness.record(late);
        self.overruns += u64::from(late >= self.period_ns);
    }

    /// Ticks that started a period or more late.
    pub(crate) fn overruns(&self) -> u64 {
        self.overruns
    }

    /// Percentiles of the tick timing so far.
    pub(crate) fn timing(&self) -> Timing {
        Timing {
            lateness: self.stats.lateness.summary(),
            execution: self.stats.execution.summary(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Ticks `seqs` in order, each sample taken and started at one instant; the overruns.
    fn overruns_of(seqs: &[u64]) -> u64 {
        let mut host = Host::new(&crate::Deployment::thesis_prototype());
        let now = monotonic_ns();
        for &seq in seqs {
            let sample = Sensor {
                seq,
                published_ns: now,
                ..Sensor::default()
            };
            host.record(&sample, now);
        }
        host.overruns()
    }

    /// Tick 1 follows tick 0 (untimed, but a tick): it was counted a period late.
    #[test]
    fn ticks_on_time_are_no_overruns() {
        assert_eq!(overruns_of(&[0, 1, 2, 3]), 0);
        assert_eq!(overruns_of(&[0, 1, 3]), 1, "one sample skipped");
    }

    /// A sequence that jumps so far that the skipped periods overflow is one overrun, not a
    /// wrapped lateness of a few ns (found by fuzzing the PIL link: the product overflowed);
    /// the last sequence number is no overflow either.
    #[test]
    fn a_jump_of_any_size_is_an_overrun() {
        let period_ns = Host::new(&crate::Deployment::thesis_prototype()).period_ns;
        // The jump whose skipped periods are 2⁶⁴ plus less than a period.
        let wraps = u64::MAX / period_ns + 1;
        assert!(wraps.wrapping_mul(period_ns) < period_ns);
        assert_eq!(overruns_of(&[0, 1, 2 + wraps]), 1);
        assert_eq!(overruns_of(&[0, 1, u64::MAX - 1, u64::MAX]), 1);
    }
}
