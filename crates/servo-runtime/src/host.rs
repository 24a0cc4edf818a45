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
        // Tick 0 sets things up (connections, caches): it is not timed.
        if started_ns == 0 || sample.seq == 0 {
            return;
        }
        self.stats
            .execution
            .record(monotonic_ns().saturating_sub(started_ns));
        // A loop that fell behind takes the newest sample and skips the rest, a period each.
        let skipped = sample.seq.saturating_sub(self.expected_seq) * self.period_ns;
        let late = started_ns.saturating_sub(sample.published_ns) + skipped;
        self.stats.lateness.record(late);
        self.overruns += u64::from(late >= self.period_ns);
        self.expected_seq = sample.seq + 1;
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
