//! Host qualification (`servo latency`): the periodic loop alone at a rate, as the plant server
//! paces it, with its start lateness in a histogram; and a readiness report of the kernel
//! settings that decide whether a host holds a rate (LinuxCNC's latency test, rt-tests'
//! cyclictest). The clock is injected ([`TickClock`]) so the statistics are testable.

pub use crate::clock::{TickClock, Wait, WallClock};
use crate::LatencyHistogram;

/// What a latency run measured.
#[derive(Clone)]
pub struct LatencyRun {
    /// Start lateness of every tick (woke − deadline), ns.
    pub lateness: LatencyHistogram,
    /// Ticks that started a whole period or more late (the next deadline had passed).
    pub overruns: u64,
    /// Ticks run.
    pub ticks: u64,
}

/// Runs ticks `ticks` of `period_ns` on `clock` (deadline k·T), recording each tick's
/// lateness (a range, so a long run can be measured in slices on one clock). Allocation-free
/// after the histogram.
pub fn measure(
    clock: &mut impl TickClock,
    period_ns: u64,
    ticks: std::ops::Range<u64>,
) -> LatencyRun {
    let mut lateness = LatencyHistogram::new();
    let mut overruns = 0;
    let n = ticks.end - ticks.start;
    for k in ticks {
        let deadline = k * period_ns;
        let late = clock.wait_until(deadline).saturating_sub(deadline);
        lateness.record(late);
        if late >= period_ns {
            overruns += 1;
        }
    }
    LatencyRun {
        lateness,
        overruns,
        ticks: n,
    }
}

/// One readiness item: what the host has, whether it suits real time, what to change.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Check {
    /// What is checked.
    pub name: String,
    /// What this host has.
    pub value: String,
    /// Suitable for a 199.6 kHz loop.
    pub ok: bool,
    /// What to change (empty when ok).
    pub advice: String,
}

/// The kernel preemption model from `/sys/kernel/realtime` and `/proc/version`.
pub fn preemption(realtime_flag: Option<&str>, version: &str) -> Check {
    let rt = realtime_flag.is_some_and(|f| f.trim() == "1") || version.contains("PREEMPT_RT");
    let value = if rt {
        "PREEMPT_RT"
    } else if version.contains("PREEMPT_DYNAMIC") {
        "PREEMPT_DYNAMIC (not RT)"
    } else if version.contains("PREEMPT") {
        "PREEMPT (not RT)"
    } else {
        "no preemption model named (voluntary)"
    };
    Check {
        name: "kernel preemption".into(),
        value: value.into(),
        ok: rt,
        advice: if rt {
            String::new()
        } else {
            "boot a PREEMPT_RT kernel (Debian: linux-image-rt-amd64) for bounded wake-up latency"
                .into()
        },
    }
}

/// RT throttling from `/proc/sys/kernel/sched_rt_runtime_us`.
pub fn rt_throttling(runtime_us: &str) -> Check {
    let v: i64 = runtime_us.trim().parse().unwrap_or(0);
    Check {
        name: "RT throttling".into(),
        value: if v < 0 {
            "off (sched_rt_runtime_us = -1)".into()
        } else {
            format!(
                "on: real-time tasks stopped for {} ms every second",
                (1_000_000 - v) / 1000
            )
        },
        ok: v < 0,
        advice: if v < 0 {
            String::new()
        } else {
            "a spinning SCHED_FIFO loop is throttled; on a dedicated host with isolated cores set kernel.sched_rt_runtime_us = -1 (never on a shared or 2-core development machine: it starves everything else)".into()
        },
    }
}

/// Isolated cores from `/sys/devices/system/cpu/isolated`.
pub fn isolated_cores(isolated: &str) -> Check {
    let v = isolated.trim();
    Check {
        name: "isolated cores".into(),
        value: if v.is_empty() {
            "none".into()
        } else {
            v.into()
        },
        ok: !v.is_empty(),
        advice: if v.is_empty() {
            "isolate the servo cores: isolcpus=2,3 nohz_full=2,3 rcu_nocbs=2,3 on the kernel command line, then --cpu".into()
        } else {
            String::new()
        },
    }
}

/// The CPU frequency governor of cpu0 (None: not exposed, as in most VMs).
pub fn governor(governor: Option<&str>) -> Check {
    let v = governor.map(str::trim);
    Check {
        name: "CPU frequency governor".into(),
        value: v.unwrap_or("not exposed (a VM: the hypervisor decides)").into(),
        ok: v.is_none_or(|g| g == "performance"),
        advice: match v {
            Some(g) if g != "performance" => {
                "set the governor to performance (cpupower frequency-set -g performance) and disable deep C-states".into()
            }
            _ => String::new(),
        },
    }
}

/// Simultaneous multithreading from `/sys/devices/system/cpu/smt/active`.
pub fn smt(active: Option<&str>) -> Check {
    let on = active.is_some_and(|a| a.trim() == "1");
    Check {
        name: "SMT (hyper-threading)".into(),
        value: if on { "active" } else { "off or not reported" }.into(),
        ok: !on,
        advice: if on {
            "keep the sibling of a servo core idle, or turn SMT off (nosmt)".into()
        } else {
            String::new()
        },
    }
}

/// The locked-memory limit from `/proc/self/limits`.
pub fn memlock(limits: &str) -> Check {
    let soft = limits
        .lines()
        .find(|l| l.starts_with("Max locked memory"))
        .and_then(|l| l.split_whitespace().nth(3));
    let ok =
        soft.is_some_and(|s| s == "unlimited" || s.parse::<u64>().is_ok_and(|b| b >= 64 << 20));
    Check {
        name: "locked-memory limit".into(),
        value: match soft {
            Some("unlimited") => "unlimited".into(),
            Some(b) => format!("{b} bytes"),
            None => "unknown".into(),
        },
        ok,
        advice: if ok {
            String::new()
        } else {
            "raise memlock (ulimit -l unlimited, or LimitMEMLOCK= in the service) so the loop can lock its memory".into()
        },
    }
}

/// Every readiness check of this host.
pub fn readiness() -> Vec<Check> {
    let read = |p: &str| std::fs::read_to_string(p).ok();
    vec![
        preemption(
            read("/sys/kernel/realtime").as_deref(),
            &read("/proc/version").unwrap_or_default(),
        ),
        rt_throttling(&read("/proc/sys/kernel/sched_rt_runtime_us").unwrap_or_default()),
        isolated_cores(&read("/sys/devices/system/cpu/isolated").unwrap_or_default()),
        governor(read("/sys/devices/system/cpu/cpu0/cpufreq/scaling_governor").as_deref()),
        smt(read("/sys/devices/system/cpu/smt/active").as_deref()),
        memlock(&read("/proc/self/limits").unwrap_or_default()),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A clock that wakes each tick at a scripted lateness.
    struct Scripted(Vec<u64>, usize);

    impl TickClock for Scripted {
        fn wait_until(&mut self, deadline_ns: u64) -> u64 {
            let late = self.0[self.1 % self.0.len()];
            self.1 += 1;
            deadline_ns + late
        }
    }

    #[test]
    fn statistics_equal_the_reference_from_the_per_tick_lateness() {
        // 10 000 ticks of 5010 ns with a lateness pattern including three overruns.
        let pattern: Vec<u64> = (0..10_000u64)
            .map(|k| match k {
                17 => 5_010,
                4_000 => 9_000,
                9_999 => 150_000,
                _ => (k * 37) % 900,
            })
            .collect();
        let mut clock = Scripted(pattern.clone(), 0);
        let mut run = measure(&mut clock, 5_010, 0..4_000);
        let rest = measure(&mut clock, 5_010, 4_000..10_000);
        run.lateness.merge(&rest.lateness);
        run.overruns += rest.overruns;
        run.ticks += rest.ticks;
        assert_eq!((run.ticks, run.overruns), (10_000, 3));
        let mut sorted = pattern.clone();
        sorted.sort_unstable();
        let reference = |q: f64| sorted[((q * 10_000.0).ceil() as usize).clamp(1, 10_000) - 1];
        let l = run.lateness.summary();
        assert_eq!((l.min_ns, l.max_ns, l.count), (0, 150_000, 10_000));
        for (q, got) in [(0.5, l.p50_ns), (0.99, l.p99_ns), (0.999, l.p999_ns)] {
            let want = reference(q);
            assert!(got.abs_diff(want) <= 5, "q {q}: {got} vs {want}");
        }
    }

    #[test]
    fn readiness_reads_what_the_kernel_says() {
        assert!(preemption(Some("1\n"), "").ok);
        let p = preemption(None, "Linux version 6.1.0 #1 SMP PREEMPT_DYNAMIC Debian");
        assert!(!p.ok && p.value.contains("PREEMPT_DYNAMIC") && p.advice.contains("PREEMPT_RT"));
        let t = rt_throttling("950000\n");
        assert!(!t.ok && t.value.contains("50 ms") && t.advice.contains("never on a shared"));
        assert!(rt_throttling("-1").ok);
        assert!(!isolated_cores("\n").ok && isolated_cores("2-3\n").ok);
        assert!(governor(None).ok && governor(Some("performance\n")).ok);
        assert!(!governor(Some("powersave")).ok);
        assert!(!smt(Some("1")).ok && smt(Some("0")).ok);
        let limits = "Limit                     Soft Limit           Hard Limit           Units\nMax locked memory         8388608              8388608              bytes\n";
        let m = memlock(limits);
        assert!(!m.ok && m.value == "8388608 bytes", "{m:?}");
        assert!(
            memlock(&limits.replace(
                "8388608              8388608",
                "unlimited            unlimited"
            ))
            .ok
        );
    }
}
