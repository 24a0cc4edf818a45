//! When a real-time run is faulted, as three separate settings ([`FaultPolicy`]): the peer-loss
//! timeout (a safety limit on controller silence), the overrun budget (a controller that
//! answers, but too late too often) and the startup grace window (the first moments of a run,
//! while caches, page tables and the scheduler settle). Pure: time is passed in, so every
//! decision is testable with an injected clock.

/// The three limits, in ns and ticks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaultPolicy {
    /// Controller silence after which it is lost (after the grace window), ns. Silence is
    /// counted from the later of the last command heard (even a late one) and the first
    /// sample published after it: a plant that was itself descheduled does not blame the
    /// controller for its own stall.
    pub peer_timeout_ns: u64,
    /// From the first tick, this long overruns are counted but not charged to the budget, and
    /// silence is a loss only when it lasts the whole window (or `peer_timeout_ns`, if longer),
    /// ns.
    pub grace_ns: u64,
    /// The sustained fraction of late ticks the budget absorbs (0..1): each overrun of a
    /// controller that is heard from (a late answer arrived in the tick) adds 1 to the budget's
    /// level, each tick drains `overrun_rate`. Overruns of a silent controller are the peer
    /// timeout's to judge.
    pub overrun_rate: f64,
    /// The level at which the budget faults the run: a burst this many overruns beyond the
    /// sustained rate (ticks).
    pub overrun_burst: f64,
}

/// Why the watchdog faulted a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Keep going.
    Ok,
    /// The controller was silent longer than the timeout.
    PeerLost,
    /// Overruns beyond the budget.
    OverrunBudget,
}

/// Applies a [`FaultPolicy`] tick by tick.
#[derive(Debug, Clone)]
pub struct Watchdog {
    policy: FaultPolicy,
    level: f64,
    silent_since_ns: Option<u64>,
    grace_overruns: u64,
    peak_level: f64,
}

impl Watchdog {
    /// A watchdog for `policy`.
    pub fn new(policy: FaultPolicy) -> Self {
        Watchdog {
            policy,
            level: 0.0,
            silent_since_ns: None,
            grace_overruns: 0,
            peak_level: 0.0,
        }
    }

    /// Judges one tick. Times in ns since the run's first tick: `now_ns` (after the wait for
    /// the command), `published_ns` (this tick's sample went out). `late`: the command was not
    /// in by its deadline (an overrun); `heard`: a command of any tick arrived during the wait.
    #[inline]
    pub fn tick(&mut self, now_ns: u64, published_ns: u64, late: bool, heard: bool) -> Verdict {
        let in_grace = now_ns < self.policy.grace_ns;
        if heard {
            self.silent_since_ns = None;
        } else if late {
            // Silence starts with the first sample published after the last command heard.
            let since = *self.silent_since_ns.get_or_insert(published_ns);
            let timeout = if in_grace {
                self.policy.peer_timeout_ns.max(self.policy.grace_ns)
            } else {
                self.policy.peer_timeout_ns
            };
            if now_ns.saturating_sub(since) >= timeout {
                return Verdict::PeerLost;
            }
        }
        if in_grace {
            self.grace_overruns += late as u64;
            return Verdict::Ok;
        }
        // Silence is the timeout's to judge: only a late tick of a controller that was heard
        // is charged.
        let charged = late && heard;
        self.level = (self.level + charged as u8 as f64 - self.policy.overrun_rate).max(0.0);
        self.peak_level = self.peak_level.max(self.level);
        if self.level > self.policy.overrun_burst {
            return Verdict::OverrunBudget;
        }
        Verdict::Ok
    }

    /// Overruns inside the grace window (not charged to the budget).
    pub fn grace_overruns(&self) -> u64 {
        self.grace_overruns
    }

    /// The highest level the budget reached (faults above `overrun_burst`).
    pub fn peak_level(&self) -> f64 {
        self.peak_level
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: u64 = 5_010; // ns, 199.6 kHz

    fn policy() -> FaultPolicy {
        FaultPolicy {
            peer_timeout_ns: 500_000,
            grace_ns: 100 * T,
            overrun_rate: 0.05,
            overrun_burst: 40.0,
        }
    }

    /// Runs ticks 0.. with `late(k)` deciding overruns (a late command is still heard);
    /// returns the tick and verdict of the first fault.
    fn run(w: &mut Watchdog, ticks: u64, late: impl Fn(u64) -> bool) -> Option<(u64, Verdict)> {
        (0..ticks).find_map(|k| {
            let v = w.tick(k * T + 2_000, k * T, late(k), true);
            (v != Verdict::Ok).then_some((k, v))
        })
    }

    #[test]
    fn the_budget_faults_at_exactly_the_configured_burst_after_the_grace_window() {
        // Every tick late from the start: 100 grace ticks are free; then the level rises by
        // 0.95 a tick and passes 40 on the 43rd charged tick (42·0.95 = 39.9, 43·0.95 = 40.85).
        let mut w = Watchdog::new(policy());
        assert_eq!(
            run(&mut w, 1_000, |_| true),
            Some((142, Verdict::OverrunBudget))
        );
        assert_eq!(w.grace_overruns(), 100);
    }

    #[test]
    fn a_sustained_rate_below_the_budget_never_faults_and_above_it_does() {
        // One tick in 25 late (4 %) against a 5 % rate: the level never passes one overrun.
        let mut w = Watchdog::new(policy());
        assert_eq!(run(&mut w, 200_000, |k| k % 25 == 0), None);
        assert!(w.peak_level() <= 1.0, "{}", w.peak_level());
        // One in 10 (10 %): the level grows 0.05 a tick on average and passes 40 after about
        // 40 / 0.05 = 800 ticks past the grace window.
        let mut w = Watchdog::new(policy());
        let (k, v) = run(&mut w, 200_000, |k| k % 10 == 0).unwrap();
        assert_eq!(v, Verdict::OverrunBudget);
        assert!((880..=920).contains(&k), "{k}");
    }

    #[test]
    fn silence_is_lost_after_the_timeout_but_only_after_the_whole_grace_window() {
        let mut w = Watchdog::new(FaultPolicy {
            grace_ns: 2_000_000,
            ..policy()
        });
        // Silent from tick 0 (published at 0): in the 2 ms grace window the timeout is the
        // window, not 0.5 ms; the first check at or past 2 ms is the loss.
        let first = (0..10_000u64)
            .find(|&k| w.tick(k * T + 1_000, k * T, true, false) != Verdict::Ok)
            .unwrap();
        assert_eq!(first, (2_000_000u64 - 1_000).div_ceil(T));
        // After the window: silent from a sample published at 1 ms, lost at 1.5 ms.
        let mut w = Watchdog::new(FaultPolicy {
            grace_ns: 0,
            ..policy()
        });
        assert_eq!(w.tick(1_499_999, 1_000_000, true, false), Verdict::Ok);
        assert_eq!(w.tick(1_500_000, 1_000_010, true, false), Verdict::PeerLost);
    }

    #[test]
    fn a_silent_controller_is_judged_by_the_timeout_not_the_budget() {
        // 2 ms of silence at 199.6 kHz is 400 late ticks, far past the 40-tick burst, but the
        // loss comes from the 0.5 ms timeout.
        let mut w = Watchdog::new(FaultPolicy {
            grace_ns: 0,
            ..policy()
        });
        let (k, v) = (1..1_000u64)
            .map(|k| (k, w.tick(k * T + 1_000, k * T, true, false)))
            .find(|(_, v)| *v != Verdict::Ok)
            .unwrap();
        assert_eq!(v, Verdict::PeerLost);
        assert_eq!(k, (500_000u64 + T - 1_000).div_ceil(T));
        assert_eq!(w.peak_level(), 0.0);
    }

    #[test]
    fn a_plant_stall_before_publishing_is_not_controller_silence() {
        let mut w = Watchdog::new(FaultPolicy {
            grace_ns: 0,
            ..policy()
        });
        // Answered at tick 0; the plant then stalls 2 ms before publishing tick 1's sample:
        // the controller had it for 3 µs when the deadline passed.
        assert_eq!(w.tick(4_000, 0, false, true), Verdict::Ok);
        assert_eq!(w.tick(2_003_000, 2_000_000, true, false), Verdict::Ok);
        // A late answer heard counts as alive.
        assert_eq!(w.tick(2_600_000, 2_005_000, true, true), Verdict::Ok);
        assert_eq!(w.tick(3_000_000, 2_610_000, true, false), Verdict::Ok);
        assert_eq!(w.tick(3_110_000, 2_615_000, true, false), Verdict::PeerLost);
    }
}
