//! Time on the servo path: the host's `CLOCK_MONOTONIC` in ns (the same clock in every process
//! of a run, so a controller can tell how long ago the plant published a sample), and the
//! wait for a tick's deadline ([`TickClock`]), injectable so pacing statistics are testable.

/// `CLOCK_MONOTONIC` in ns (a vDSO read, no system call).
#[inline]
pub fn monotonic_ns() -> u64 {
    use nix::time::{clock_gettime, ClockId};
    clock_gettime(ClockId::CLOCK_MONOTONIC).map_or(0, |t| {
        t.tv_sec() as u64 * 1_000_000_000 + t.tv_nsec() as u64
    })
}

/// Sleeps until `CLOCK_MONOTONIC` reaches `ns` (absolute, so no drift accumulates; an
/// interrupted sleep returns early and the caller spins the rest).
pub fn sleep_until_ns(ns: u64) {
    use nix::sys::time::TimeSpec;
    use nix::time::{clock_nanosleep, ClockId, ClockNanosleepFlags};
    let t = TimeSpec::new((ns / 1_000_000_000) as _, (ns % 1_000_000_000) as _);
    let _ = clock_nanosleep(
        ClockId::CLOCK_MONOTONIC,
        ClockNanosleepFlags::TIMER_ABSTIME,
        &t,
    );
}

/// Waits for tick deadlines; returns when it woke. Time in ns from the start of the run.
pub trait TickClock {
    /// Waits until `deadline_ns`; returns the time it woke (≥ the deadline for a real clock).
    fn wait_until(&mut self, deadline_ns: u64) -> u64;
}

/// How a tick waits for its deadline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum Wait {
    /// Busy-poll the clock (lowest lateness; burns the core).
    Spin,
    /// Sleep until `margin_ns` before the deadline, then spin (frees the core between ticks;
    /// the margin absorbs the sleep's wake-up latency).
    SleepThenSpin {
        /// Spin margin before the deadline, ns.
        margin_ns: u64,
    },
}

impl Wait {
    /// Waits until the absolute monotonic time `deadline_ns` with this strategy; returns the
    /// monotonic time it woke.
    #[inline]
    pub fn until(self, deadline_ns: u64) -> u64 {
        self.sleep_before(deadline_ns);
        loop {
            let now = monotonic_ns();
            if now >= deadline_ns {
                return now;
            }
            std::hint::spin_loop();
        }
    }

    /// The sleeping part alone: with [`Wait::SleepThenSpin`], sleeps until the margin before
    /// `deadline_ns` (absolute monotonic ns); with [`Wait::Spin`], returns at once. For a
    /// process whose spin is a poll for a message (the controller waiting for a sample).
    #[inline]
    pub fn sleep_before(self, deadline_ns: u64) {
        if let Wait::SleepThenSpin { margin_ns } = self {
            let wake = deadline_ns.saturating_sub(margin_ns);
            if wake > monotonic_ns() {
                sleep_until_ns(wake);
            }
        }
    }

    /// A short description (`spin`, `sleep-then-spin (50 µs margin)`).
    pub fn describe(self) -> String {
        match self {
            Wait::Spin => "spin".into(),
            Wait::SleepThenSpin { margin_ns } => {
                format!("sleep-then-spin ({} µs margin)", margin_ns / 1000)
            }
        }
    }
}

/// The wall clock (`CLOCK_MONOTONIC`) from its creation, with a [`Wait`] strategy.
pub struct WallClock {
    start_ns: u64,
    wait: Wait,
}

impl WallClock {
    /// Starts now.
    pub fn new(wait: Wait) -> Self {
        WallClock {
            start_ns: monotonic_ns(),
            wait,
        }
    }
}

impl TickClock for WallClock {
    #[inline]
    fn wait_until(&mut self, deadline_ns: u64) -> u64 {
        self.wait.until(self.start_ns + deadline_ns) - self.start_ns
    }
}
