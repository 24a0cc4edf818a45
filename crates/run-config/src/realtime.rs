//! `[realtime]`: how the HIL processes run when paced in real time — scheduling, cores, memory,
//! the wait for each tick, and the three separate fault settings (peer-loss timeout, overrun
//! budget, startup grace window). Defaults need no privilege and suit a shared machine; see
//! the book's real-time host page (`docs/src/how-to/realtime-host.md`) and `servo latency`
//! for what a host allows.

use super::Origin;
use crate::ConfigError;
use daq_io::clock::Wait;
use daq_io::realtime::{online_cpus, Policy, RtSettings};
use serde::{Deserialize, Serialize};

/// How a servo process waits for its next tick.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, schemars::JsonSchema,
)]
#[serde(rename_all = "kebab-case")]
pub enum WaitKind {
    /// Busy-poll (lowest lateness; the process keeps its core at 100 %).
    #[default]
    Spin,
    /// Sleep until `spin_margin_s` before the tick, then spin: frees the core between ticks
    /// (for rates where the period is well above the host's wake-up latency, e.g. 20 kHz).
    SleepSpin,
}

/// Real-time settings of a HIL run (used with `--realtime`; the scheduling keys apply in
/// lockstep too).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct RealtimeConfig {
    /// Scheduling policy of the plant and controller processes: `other` (default, no
    /// privilege), `fifo` or `rr` (need CAP_SYS_NICE or an RLIMIT_RTPRIO).
    pub policy: Policy,
    /// Real-time priority for `fifo` / `rr`, 1..=98 (default 10: low, so kernel threads and
    /// anything more urgent still preempt).
    pub priority: i32,
    /// CPU of the plant process (unset: any).
    pub plant_cpu: Option<usize>,
    /// CPU of the controller process (unset: any).
    pub controller_cpu: Option<usize>,
    /// Lock the servo processes' memory (`mlockall`) and pre-fault their stacks, so no page
    /// fault lands in a tick (needs a locked-memory limit of a few hundred MB: iceoryx2 maps
    /// its shared memory into every process).
    pub lock_memory: bool,
    /// How the plant waits for each tick, and the controller for each sample.
    pub wait: WaitKind,
    /// With `wait = "sleep-spin"`: spin this long before each tick, in s (default 50 µs, above
    /// a VM's typical timer wake-up latency).
    pub spin_margin_s: f64,
    /// Controller silence after which the plant declares it lost and drives zero current, in s
    /// (default 0.5 ms: the DAC is at 0 V within 1 ms of the last command). Counted from the
    /// first sample published after the last command heard, so the plant's own stalls do not
    /// count. `servo latency` recommends a value for the host.
    pub peer_timeout_s: f64,
    /// Startup grace window, in s (default 50 ms): overruns are counted but not charged to
    /// the budget, and silence is a loss only if it lasts the whole window.
    pub grace_s: f64,
    /// Overrun budget, sustained part: the fraction of late ticks absorbed indefinitely
    /// (default 0.05). A controller late more often than this is faulted. Charged are the
    /// overruns of ticks where the controller was heard from (it always has at least one period
    /// from the sample's publication); a silent controller is the peer timeout's case.
    pub overrun_rate: f64,
    /// Overrun budget, burst part: how many ticks' worth of overruns beyond the sustained rate
    /// are absorbed at once, in s (default 2 ms, above the ~1 ms hypervisor stalls of a cloud
    /// VM; `servo latency` recommends a value for the host).
    pub overrun_burst_s: f64,
    /// Niceness of the processes off the servo path (recorder, `servo run --hil` itself),
    /// 0..=19 (default 10). They are kept off the servo CPUs when CPUs remain.
    pub others_nice: i32,
}

impl Default for RealtimeConfig {
    fn default() -> Self {
        RealtimeConfig {
            policy: Policy::Other,
            priority: 10,
            plant_cpu: None,
            controller_cpu: None,
            lock_memory: false,
            wait: WaitKind::Spin,
            spin_margin_s: 50e-6,
            peer_timeout_s: 5e-4,
            grace_s: 0.05,
            overrun_rate: 0.05,
            overrun_burst_s: 2e-3,
            others_nice: 10,
        }
    }
}

/// Which HIL process asks for its settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// The plant server.
    Plant,
    /// The controller.
    Controller,
    /// The recorder and the orchestrator: low priority, off the servo CPUs.
    Other,
}

impl RealtimeConfig {
    /// The wait strategy.
    pub fn wait(&self) -> Wait {
        match self.wait {
            WaitKind::Spin => Wait::Spin,
            WaitKind::SleepSpin => Wait::SleepThenSpin {
                margin_ns: (self.spin_margin_s * 1e9).round() as u64,
            },
        }
    }

    /// The settings process `role` applies at its start.
    pub fn settings(&self, role: Role) -> RtSettings {
        let servo = |cpu: Option<usize>| RtSettings {
            policy: self.policy,
            priority: self.priority,
            cpus: cpu.into_iter().collect(),
            lock_memory: self.lock_memory,
            prefault_bytes: 256 * 1024,
            nice: 0,
        };
        match role {
            Role::Plant => servo(self.plant_cpu),
            Role::Controller => servo(self.controller_cpu),
            Role::Other => {
                let taken = [self.plant_cpu, self.controller_cpu];
                let free: Vec<usize> = (0..online_cpus())
                    .filter(|c| !taken.contains(&Some(*c)))
                    .collect();
                RtSettings {
                    // Off the servo CPUs when any remain; never nowhere.
                    cpus: if taken.iter().any(Option::is_some) && !free.is_empty() {
                        free
                    } else {
                        Vec::new()
                    },
                    nice: self.others_nice,
                    ..RtSettings::default()
                }
            }
        }
    }

    /// Checks every value against its allowed range (`period_s`: the servo period in s), and
    /// refuses settings that would starve the host: spinning real-time processes on every CPU,
    /// or "sleeping" ones whose spin margin leaves them less than half of each period asleep.
    pub fn validate(&self, at: &Origin, period_s: f64) -> Result<(), ConfigError> {
        let r = self;
        if r.policy.is_realtime() && !(1..=98).contains(&r.priority) {
            return Err(at.invalid("realtime.priority", r.priority, "1..=98"));
        }
        let cpus = online_cpus();
        for (key, cpu) in [
            ("realtime.plant_cpu", r.plant_cpu),
            ("realtime.controller_cpu", r.controller_cpu),
        ] {
            if let Some(c) = cpu.filter(|&c| c >= cpus) {
                return Err(at.invalid(
                    key,
                    c,
                    &format!("0..={} (the CPUs of this host)", cpus - 1),
                ));
            }
        }
        let positive = |key: &str, v: f64, max: f64, unit: &str| {
            if v > 0.0 && v <= max {
                Ok(())
            } else {
                Err(at.invalid(key, v, &format!("(0, {max}] {unit}")))
            }
        };
        positive("realtime.spin_margin_s", r.spin_margin_s, 0.01, "s")?;
        positive("realtime.peer_timeout_s", r.peer_timeout_s, 10.0, "s")?;
        positive("realtime.overrun_burst_s", r.overrun_burst_s, 10.0, "s")?;
        if !(r.grace_s >= 0.0 && r.grace_s <= 10.0) {
            return Err(at.invalid("realtime.grace_s", r.grace_s, "[0, 10] s"));
        }
        if !(r.overrun_rate >= 0.0 && r.overrun_rate < 1.0) {
            return Err(at.invalid("realtime.overrun_rate", r.overrun_rate, "[0, 1)"));
        }
        if !(0..=19).contains(&r.others_nice) {
            return Err(at.invalid("realtime.others_nice", r.others_nice, "0..=19"));
        }
        if r.policy.is_realtime()
            && r.wait == WaitKind::SleepSpin
            && r.spin_margin_s > 0.5 * period_s
        {
            return Err(at.invalid(
                "realtime.spin_margin_s",
                r.spin_margin_s,
                &format!("(0, {:.3e}] s with a real-time policy: at most half the {:.3e} s period, so each servo process sleeps at least half of it (a larger margin spins, and two spinning real-time processes starve a host without a spare CPU)", 0.5 * period_s, period_s),
            ));
        }
        if r.policy.is_realtime() && r.wait == WaitKind::Spin {
            // Plant and controller both spin: with a real-time policy they must each have a
            // CPU of their own and leave one for everything else.
            let leaves_a_cpu = matches!((r.plant_cpu, r.controller_cpu), (Some(p), Some(c)) if p != c && cpus >= 3);
            if !leaves_a_cpu {
                return Err(at.invalid(
                    "realtime.policy",
                    r.policy.name(),
                    &format!("other with wait = \"spin\" on this {cpus}-CPU host: two spinning real-time processes need plant_cpu and controller_cpu on distinct CPUs and a third CPU for everything else (otherwise they starve the host, and RT throttling stops them every second); use wait = \"sleep-spin\" or policy = \"other\""),
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spinning_real_time_processes_that_would_starve_the_host_are_refused() {
        let at = Origin::default();
        let fifo = RealtimeConfig {
            policy: Policy::Fifo,
            ..Default::default()
        };
        let period = 50e-6; // 20 kHz
        let e = fifo.validate(&at, period).unwrap_err().to_string();
        assert!(
            e.contains("realtime.policy") && e.contains("sleep-spin"),
            "{e}"
        );
        let sleeping = RealtimeConfig {
            wait: WaitKind::SleepSpin,
            spin_margin_s: 20e-6,
            ..fifo
        };
        assert!(sleeping.validate(&at, period).is_ok());
        // A 50 µs margin at 20 kHz never sleeps: the same as spinning.
        let e = RealtimeConfig {
            spin_margin_s: 50e-6,
            ..sleeping
        }
        .validate(&at, period)
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("realtime.spin_margin_s") && e.contains("half"),
            "{e}"
        );
        let e = RealtimeConfig {
            priority: 99,
            ..sleeping
        }
        .validate(&at, period)
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("realtime.priority") && e.contains("1..=98"),
            "{e}"
        );
        let e = RealtimeConfig {
            plant_cpu: Some(4096),
            ..Default::default()
        }
        .validate(&at, period)
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("realtime.plant_cpu") && e.contains("the CPUs of this host"),
            "{e}"
        );
    }

    #[test]
    fn the_processes_off_the_servo_path_get_the_remaining_cpus_at_low_priority() {
        let c = RealtimeConfig {
            plant_cpu: Some(0),
            ..Default::default()
        };
        let others = c.settings(Role::Other);
        assert_eq!(others.nice, 10);
        assert!(!others.cpus.contains(&0));
        assert_eq!(others.cpus.len(), online_cpus() - 1);
        let plant = c.settings(Role::Plant);
        assert_eq!((plant.cpus, plant.nice), (vec![0], 0));
    }
}
