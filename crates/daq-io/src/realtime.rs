//! Real-time settings of a servo process, applied at its start: scheduling policy and priority,
//! CPU affinity, memory locking with pre-faulting, and niceness for the processes that must
//! stay out of the servo path (recorder, orchestrator). A host that refuses gets a clear error
//! naming the setting, what the kernel said and what to change.

/// Linux scheduling policies a servo process may ask for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "kebab-case")]
pub enum Policy {
    /// `SCHED_OTHER`: the normal time-sharing scheduler (needs no privilege).
    #[default]
    Other,
    /// `SCHED_FIFO` at a real-time priority: runs until it blocks or yields.
    Fifo,
    /// `SCHED_RR`: `SCHED_FIFO` with a time slice among equal priorities.
    Rr,
}

impl Policy {
    /// The name in configs and messages.
    pub fn name(self) -> &'static str {
        match self {
            Policy::Other => "other",
            Policy::Fifo => "fifo",
            Policy::Rr => "rr",
        }
    }

    /// A real-time policy (`fifo`, `rr`).
    pub fn is_realtime(self) -> bool {
        self != Policy::Other
    }
}

/// What to ask of the host for one process.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RtSettings {
    /// Scheduling policy.
    pub policy: Policy,
    /// Real-time priority for `fifo` / `rr` (1..=98; keep it low on a shared host).
    pub priority: i32,
    /// CPUs the process may run on (empty: any).
    pub cpus: Vec<usize>,
    /// Lock all current and future memory (`mlockall`) and pre-fault `prefault_bytes` of stack,
    /// so no page fault lands in a tick.
    pub lock_memory: bool,
    /// Stack pre-faulted when locking memory, bytes.
    pub prefault_bytes: usize,
    /// Niceness for `other` (-20..=19; 0 leaves it; 10 for the processes off the servo path).
    pub nice: i32,
}

/// A setting the host refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{setting}: the host refused ({errno}); {advice}")]
pub struct RtError {
    /// The setting (`scheduling policy fifo priority 10`, `CPU affinity 0,5`, …).
    pub setting: String,
    /// What the kernel said.
    pub errno: String,
    /// What to change.
    pub advice: String,
}

/// The CPUs online on this host.
pub fn online_cpus() -> usize {
    use nix::unistd::{sysconf, SysconfVar};
    sysconf(SysconfVar::_NPROCESSORS_ONLN)
        .ok()
        .flatten()
        .map_or(1, |n| n.max(1) as usize)
}

/// Applies `s` to the calling thread (and so to every thread it starts later; call it first
/// thing in a servo process). Checks the values first (priority range, CPUs that exist), then
/// asks the kernel for each.
pub fn apply(s: &RtSettings) -> Result<(), RtError> {
    use nix::sched::{sched_setaffinity, CpuSet};
    use nix::unistd::Pid;
    let cpus = online_cpus();
    let affinity = || format!("CPU affinity {}", list(&s.cpus));
    if let Some(&bad) = s.cpus.iter().find(|&&c| c >= cpus) {
        return Err(RtError {
            setting: affinity(),
            errno: format!("no CPU {bad}"),
            advice: format!("this host has CPUs 0–{}", cpus - 1),
        });
    }
    if !s.cpus.is_empty() {
        let mut set = CpuSet::new();
        let result = s
            .cpus
            .iter()
            .try_for_each(|&c| set.set(c))
            .and_then(|()| sched_setaffinity(Pid::from_raw(0), &set));
        if let Err(e) = result {
            return Err(RtError {
                setting: affinity(),
                errno: e.desc().into(),
                advice:
                    "the CPUs may be outside this process's cpuset: pick CPUs from `taskset -p $$`"
                        .into(),
            });
        }
    }
    if s.policy.is_realtime() {
        set_realtime(s.policy, s.priority)?;
    } else if s.nice != 0 {
        set_nice(s.nice)?;
    }
    if s.lock_memory {
        use nix::sys::mman::{mlockall, MlockAllFlags};
        if let Err(e) = mlockall(MlockAllFlags::MCL_CURRENT | MlockAllFlags::MCL_FUTURE) {
            return Err(RtError {
                setting: "memory locking (mlockall)".into(),
                errno: e.desc().into(),
                advice: "raise the locked-memory limit (`ulimit -l unlimited`; LimitMEMLOCK=infinity in a systemd service)".into(),
            });
        }
        prefault_stack(s.prefault_bytes);
    }
    Ok(())
}

/// `SCHED_FIFO` / `SCHED_RR` at `priority` for the calling thread.
fn set_realtime(policy: Policy, priority: i32) -> Result<(), RtError> {
    use thread_priority::unix::{
        set_thread_priority_and_policy, thread_native_id, RealtimeThreadSchedulePolicy,
        ThreadSchedulePolicy,
    };
    use thread_priority::ThreadPriority;
    let setting = format!("scheduling policy {} priority {priority}", policy.name());
    let value = u8::try_from(priority)
        .ok()
        .filter(|p| (1..=98).contains(p))
        .ok_or_else(|| RtError {
            setting: setting.clone(),
            errno: "out of range".into(),
            advice: "allowed 1..=98 (keep servo priorities low, e.g. 10–50, below the kernel's own threads at 99)".into(),
        })?;
    let rt = match policy {
        Policy::Fifo => RealtimeThreadSchedulePolicy::Fifo,
        _ => RealtimeThreadSchedulePolicy::RoundRobin,
    };
    let priority = ThreadPriority::Crossplatform(
        value
            .try_into()
            .expect("1..=98 is a cross-platform priority"),
    );
    set_thread_priority_and_policy(
        thread_native_id(),
        priority,
        ThreadSchedulePolicy::Realtime(rt),
    )
    .map_err(|e| RtError {
        setting,
        errno: match e {
            thread_priority::Error::OS(n) => nix::errno::Errno::from_raw(n).desc().into(),
            other => other.to_string(),
        },
        advice: format!("needs CAP_SYS_NICE or an RLIMIT_RTPRIO of at least {value} (`ulimit -r`; LimitRTPRIO= in a systemd service; `@realtime - rtprio 98` in /etc/security/limits.conf)"),
    })
}

/// Niceness `nice` (0..=19) under `SCHED_OTHER` for the calling thread, checked against what
/// the kernel then reports.
fn set_nice(nice: i32) -> Result<(), RtError> {
    use thread_priority::unix::{
        set_thread_priority_and_policy, thread_native_id, NormalThreadSchedulePolicy,
        ThreadSchedulePolicy,
    };
    use thread_priority::{ThreadPriority, ThreadPriorityValue};
    let setting = format!("niceness {nice}");
    if !(0..=19).contains(&nice) {
        return Err(RtError {
            setting,
            errno: "out of range".into(),
            advice: "allowed 0..=19 (a lower priority for processes off the servo path)".into(),
        });
    }
    // thread-priority maps its 0..=99 scale linearly onto niceness 19..=-20.
    let niceness_of = |p: u8| ((39.0f32 * (1.0 - f32::from(p) / 99.0)) as i8 - 20) as i32;
    let p = (0..=99u8).find(|&p| niceness_of(p) == nice).unwrap_or(0);
    let value = ThreadPriorityValue::try_from(p).expect("0..=99 is a cross-platform priority");
    let set = set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::Crossplatform(value),
        ThreadSchedulePolicy::Normal(NormalThreadSchedulePolicy::Other),
    );
    let now = current_nice();
    match set {
        Ok(()) if now == Some(nice) => Ok(()),
        r => Err(RtError {
            setting,
            errno: match r {
                Err(e) => e.to_string(),
                Ok(()) => format!("the kernel reports niceness {now:?}"),
            },
            advice: "check `ulimit -e`".into(),
        }),
    }
}

/// The calling thread's niceness, from `/proc/thread-self/stat` (field 19).
pub fn current_nice() -> Option<i32> {
    let stat = std::fs::read_to_string("/proc/thread-self/stat").ok()?;
    // After the command name in parentheses: state is field 3, niceness field 19.
    let rest = &stat[stat.rfind(')')? + 2..];
    rest.split_whitespace().nth(16)?.parse().ok()
}

/// Touches `bytes` of stack so its pages are mapped (and, after `mlockall`, locked) before
/// the first tick.
#[inline(never)]
fn prefault_stack(bytes: usize) {
    const CHUNK: usize = 16 * 1024;
    fn touch(left: usize) {
        let mut page = [0u8; CHUNK];
        std::hint::black_box(&mut page);
        if left > CHUNK {
            touch(left - CHUNK);
        }
        std::hint::black_box(&page);
    }
    touch(bytes);
}

/// `0,1,3`.
pub fn list(cpus: &[usize]) -> String {
    cpus.iter()
        .map(|c| c.to_string())
        .collect::<Vec<_>>()
        .join(",")
}

/// The calling thread's scheduling policy and real-time priority, as the kernel reports it.
pub fn current() -> (Policy, i32) {
    use thread_priority::unix::{
        thread_native_id, thread_schedule_policy_param, RealtimeThreadSchedulePolicy,
        ThreadSchedulePolicy,
    };
    match thread_schedule_policy_param(thread_native_id()) {
        Ok((ThreadSchedulePolicy::Realtime(p), param)) => (
            if p == RealtimeThreadSchedulePolicy::Fifo {
                Policy::Fifo
            } else {
                Policy::Rr
            },
            param.sched_priority,
        ),
        _ => (Policy::Other, 0),
    }
}

/// The calling thread's allowed CPUs.
pub fn current_cpus() -> Vec<usize> {
    let Ok(set) = nix::sched::sched_getaffinity(nix::unistd::Pid::from_raw(0)) else {
        return Vec::new();
    };
    (0..nix::sched::CpuSet::count())
        .filter(|&c| set.is_set(c).unwrap_or(false))
        .collect()
}
