//! What a [`Servo`] does beside the tick on a host with the standard library: it times each
//! tick (start lateness after the sample was taken, execution), keeps what the loop was made
//! for, and — once served — exchanges telemetry, health and control-plane requests with the
//! service thread over lock-free rings.

use crate::servo::Servo;
use daq_io::clock::monotonic_ns;
use daq_io::{Latency, Sensor, TickStats};

/// Tick timing of a loop ([`Servo::timing`]), percentiles in ns.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Timing {
    /// Each tick's start after its sample was taken ([`Sensor::published_ns`]), plus a period
    /// for each sample skipped.
    pub lateness: Latency,
    /// Each tick's own work, sample in to command out (Simulink Real-Time's TET).
    pub execution: Latency,
}

/// The host side of a [`Servo`].
pub(crate) struct Host {
    stats: TickStats,
    period_ns: u64,
    expected_seq: u64,
    overruns: u64,
    /// Telemetry dropped by a service that has ended.
    #[cfg(feature = "serve")]
    pub(crate) dropped: u64,
    pub(crate) made_for: Option<crate::file::MadeFor>,
    /// The controller the loop runs (a loaded state-space file takes its output limit).
    pub(crate) spec: crate::deployment::ControllerSpec,
    #[cfg(feature = "serve")]
    pub(crate) link: Option<crate::serve::Link>,
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
            #[cfg(feature = "serve")]
            link: None,
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
    fn record(&mut self, sample: &Sensor, started_ns: u64) {
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

    /// Telemetry records the service ring dropped.
    pub(crate) fn telemetry_dropped(&self) -> u64 {
        #[cfg(feature = "serve")]
        {
            self.dropped + self.link.as_ref().map_or(0, |l| l.dropped())
        }
        #[cfg(not(feature = "serve"))]
        {
            0
        }
    }

    pub(crate) fn timing(&self) -> Timing {
        Timing {
            lateness: self.stats.lateness.summary(),
            execution: self.stats.execution.summary(),
        }
    }
}

impl Servo {
    /// After the tick of `sample` (started at `started_ns`): its timing and, when served, the
    /// exchange with the service thread.
    #[inline]
    pub(crate) fn after_tick(&mut self, sample: &Sensor, started_ns: u64) {
        self.host.record(sample, started_ns);
        #[cfg(feature = "serve")]
        crate::serve::after_tick(self, sample);
        #[cfg(not(feature = "serve"))]
        let _ = sample;
    }

    /// Percentiles of the tick timing so far (ticks whose sample carried
    /// [`Sensor::published_ns`]; nothing is timed otherwise).
    pub fn timing(&self) -> Timing {
        self.host.timing()
    }
}
