//! Host qualification: the loop's pacing alone at a rate with the run's real-time settings,
//! measured on a thread of its own (the caller's scheduling is left as it was). One file type,
//! [`Qualification`]: `servo latency --json` (and Python) write it; a real-time run reads it
//! back through [`Qualification::read`] and checks its host before it starts ([`preflight`]).

use super::{check_host, survivable, HostStalls, Survivable, STALL_MARGIN};
use crate::error::RunError;
use crate::plan::Plan;
use crate::recording::host_name;
use daq_io::qualify::{measure, readiness, Check, WallClock};
use daq_io::realtime::RtSettings;
use daq_io::LatencyHistogram;
use run_config::input_file::read_text;
use run_config::{ConfigError, Loaded, Origin, RealtimeConfig, Role};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// How long a real-time run qualifies its host before it starts when no qualification file is
/// given, in s.
pub const QUALIFY_S: f64 = 1.0;

/// How old a qualification may be to stand for its host, in s (a day).
const MAX_AGE_S: u64 = 86_400;

/// Start lateness percentiles, in ns.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Percentiles {
    /// The earliest start.
    pub min: u64,
    /// The median.
    pub p50: u64,
    /// The 99th percentile.
    pub p99: u64,
    /// The 99.9th percentile.
    pub p999: u64,
    /// The 99.99th percentile.
    pub p9999: u64,
    /// The latest start: the host's worst stall.
    pub max: u64,
}

/// A host qualified for real time: what `servo latency --json` writes and
/// `servo run --hil --realtime --qualification` reads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Qualification {
    /// This host's name (a qualification holds for the host it was measured on).
    pub host: String,
    /// When it was measured (RFC 3339).
    pub measured_at: String,
    /// The loop rate measured at, Hz.
    pub rate_hz: f64,
    /// The period, ns.
    pub period_ns: u64,
    /// Ticks measured.
    pub ticks: u64,
    /// How each tick waited for its deadline (`realtime.wait`).
    pub wait: String,
    /// The policy as the kernel reports it after applying the settings.
    pub policy: String,
    /// The real-time priority, for fifo and rr.
    pub priority: Option<i32>,
    /// The CPUs the loop could run on.
    pub cpus: Vec<usize>,
    /// Memory locked (mlockall) and the stack pre-faulted.
    pub lock_memory: bool,
    /// Start lateness, ns.
    pub lateness_ns: Percentiles,
    /// Ticks that started a whole period late.
    pub overruns: u64,
    /// Overruns per tick.
    pub overrun_rate: f64,
    /// A controller-loss timeout no stall of this run reached (4 × the worst lateness, at
    /// least 1 ms) and within what the stage survives (then at least [`STALL_MARGIN`] × the
    /// worst stall), in ms; None when no timeout is both.
    pub recommended_peer_timeout_ms: Option<f64>,
    /// An overrun budget this host keeps: burst 2 × the worst stall (at least 2 ms), in ms …
    pub recommended_overrun_burst_ms: u64,
    /// … and sustained rate 2 × the measured overrun rate (at least 1 %).
    pub recommended_overrun_rate: f64,
    /// The longest stall this host made (its worst start lateness), as a run checks it.
    pub host_stalls: HostStalls,
    /// The loop judged.
    #[serde(rename = "loop")]
    pub judged: String,
    /// The longest stall that loop survives (None: not predicted, see `survivable_note`).
    pub survivable: Option<Survivable>,
    /// The longest stall the loop survives, s.
    pub survivable_stall_s: Option<f64>,
    /// Why the survivable stall was not predicted, or what limits it.
    pub survivable_note: String,
    /// The host's worst stall is within what the loop survives.
    pub holds: Option<bool>,
    /// The kernel settings, each with what to change.
    pub readiness: Vec<Check>,
}

/// What a qualification measures: the pacing of `role`'s loop with `realtime`'s settings at
/// `rate_hz` for `duration_s`.
#[derive(Debug, Clone)]
pub struct Measurement {
    /// The loop rate, Hz.
    pub rate_hz: f64,
    /// How long, s.
    pub duration_s: f64,
    /// The real-time settings (policy, priority, CPUs, memory lock, wait).
    pub realtime: RealtimeConfig,
    /// Whose settings the loop takes (`servo latency`: the plant's; a run's start: the
    /// controller's, whose stall is the one that matters).
    pub role: Role,
}

/// The pacing as measured.
struct Paced {
    lateness: LatencyHistogram,
    overruns: u64,
    policy: daq_io::realtime::Policy,
    priority: i32,
    cpus: Vec<usize>,
}

/// Paces a loop of `ticks` at `period_ns` with `settings` on a thread of its own (its
/// scheduling ends with it), in slices of 0.1 s; `progress(done, total)` after each.
fn pace(
    settings: &RtSettings,
    wait: daq_io::clock::Wait,
    period_ns: u64,
    ticks: u64,
    progress: &mut (dyn FnMut(u64, u64) + Send),
) -> Result<Paced, RunError> {
    let slice = (100_000_000 / period_ns).max(1);
    std::thread::scope(|s| {
        s.spawn(|| -> Result<Paced, RunError> {
            daq_io::realtime::apply(settings)?;
            let (policy, priority) = daq_io::realtime::current();
            let mut clock = WallClock::new(wait);
            let mut lateness = LatencyHistogram::new();
            let (mut overruns, mut done) = (0, 0);
            while done < ticks {
                let n = slice.min(ticks - done);
                let run = measure(&mut clock, period_ns, done..done + n);
                lateness.merge(&run.lateness);
                overruns += run.overruns;
                done += n;
                progress(done, ticks);
            }
            Ok(Paced {
                lateness,
                overruns,
                policy,
                priority,
                cpus: daq_io::realtime::current_cpus(),
            })
        })
        .join()
        .expect("the pacing loop does not panic")
    })
}

impl Qualification {
    /// Measures this host as `m` says and judges `judged`'s loop against it (its controller,
    /// scenario, limits and `realtime.peer_timeout_s`) at `m.rate_hz`. `progress(done, total)`
    /// reports ticks measured.
    pub fn measure(
        judged: &Loaded,
        m: &Measurement,
        progress: &mut (dyn FnMut(u64, u64) + Send),
    ) -> Result<Qualification, RunError> {
        let at = Origin::default();
        if !(1e2..=2e6).contains(&m.rate_hz) {
            return Err(at.invalid("rate_hz", m.rate_hz, "[100, 2e6] Hz").into());
        }
        if !(m.duration_s > 0.0 && m.duration_s <= 600.0) {
            return Err(at.invalid("duration_s", m.duration_s, "(0, 600] s").into());
        }
        let mut judged = judged.clone();
        judged.config.plant.timing.servo_rate_hz = m.rate_hz;
        let period_ns = (1e9 / m.rate_hz).round() as u64;
        let ticks = (m.duration_s * m.rate_hz).round() as u64;
        let wait = m.realtime.wait();
        let settings = m.realtime.settings(m.role);
        let paced = pace(&settings, wait, period_ns, ticks, progress)?;
        let l = paced.lateness.summary();
        let host_stalls = HostStalls {
            worst_s: l.max_ns as f64 * 1e-9,
            measured_s: m.duration_s,
            rate_hz: m.rate_hz,
            source: format!(
                "servo latency, {} s at {:.1} kHz on {}, CPUs {}, SCHED_{}",
                m.duration_s,
                m.rate_hz / 1e3,
                host_name(),
                daq_io::realtime::list(&paced.cpus),
                paced.policy.name().to_uppercase()
            ),
        };
        let (judged_loop, survivable, note) = judge(&judged);
        let physics_s = survivable.and_then(|s| s.physics_s());
        Ok(Qualification {
            host: host_name(),
            measured_at: humantime::format_rfc3339_seconds(std::time::SystemTime::now())
                .to_string(),
            rate_hz: m.rate_hz,
            period_ns,
            ticks,
            wait: wait.describe(),
            policy: paced.policy.name().into(),
            priority: paced.policy.is_realtime().then_some(paced.priority),
            cpus: paced.cpus,
            lock_memory: m.realtime.lock_memory,
            lateness_ns: Percentiles {
                min: l.min_ns,
                p50: l.p50_ns,
                p99: l.p99_ns,
                p999: l.p999_ns,
                p9999: paced.lateness.quantile(0.9999),
                max: l.max_ns,
            },
            overruns: paced.overruns,
            overrun_rate: paced.overruns as f64 / ticks as f64,
            recommended_peer_timeout_ms: recommended_timeout_ms(l.max_ns, physics_s),
            recommended_overrun_burst_ms: (2 * l.max_ns).div_ceil(1_000_000).max(2),
            recommended_overrun_rate: (2.0 * paced.overruns as f64 / ticks as f64).max(0.01),
            holds: survivable.map(|s| check_host(&s, &host_stalls).is_ok()),
            survivable_stall_s: survivable.map(|s| s.stall_s()),
            host_stalls,
            judged: judged_loop,
            survivable,
            survivable_note: note,
            readiness: readiness(),
        })
    }

    /// Reads the qualification at `path` and returns its host stalls, when it was measured on
    /// this host (`host`), at `plan`'s rate (`rate_hz`) with the controller's settings
    /// (`wait`, `policy`, `priority`, `cpus` when the run pins the controller,
    /// `lock_memory`), within the last day (`measured_at`); otherwise an error naming the key.
    pub fn read(path: &Path, plan: &Plan) -> Result<HostStalls, RunError> {
        let text = read_text(path)?;
        let q: Qualification = serde_json::from_str(&text).map_err(|e| ConfigError::Parse {
            path: path.to_owned(),
            message: format!("{e} (a `servo latency --json` result)"),
        })?;
        let at = Origin {
            path: Some(path.to_owned()),
            text: Some(text),
        };
        q.check(plan, &at)?;
        Ok(HostStalls {
            source: format!("{}, {}", q.host_stalls.source, path.display()),
            ..q.host_stalls
        })
    }

    /// Whether this qualification stands for this host and `plan`'s controller loop.
    fn check(&self, plan: &Plan, at: &Origin) -> Result<(), ConfigError> {
        let here = host_name();
        if self.host != here {
            return Err(at.invalid(
                "host",
                &self.host,
                &format!("this host ({here}): qualify it with servo latency here"),
            ));
        }
        let rate = plan.config.plant.timing.servo_rate_hz;
        if (self.rate_hz - rate).abs() > 1e-9 * rate || self.host_stalls.rate_hz != self.rate_hz {
            return Err(at.invalid("rate_hz", self.rate_hz, &format!("the run's {rate} Hz")));
        }
        let worst = self.host_stalls.worst_s;
        if !(worst.is_finite() && worst >= 0.0) {
            return Err(at.invalid("host_stalls.worst_s", worst, "a stall ≥ 0 s"));
        }
        let rt = &plan.config.realtime;
        let settings = rt.settings(Role::Controller);
        let same = |key: &str, got: String, run: String, run_key: &str| {
            if got == run {
                Ok(())
            } else {
                Err(at.invalid(key, got, &format!("{run}, the run's {run_key}")))
            }
        };
        same(
            "wait",
            self.wait.clone(),
            rt.wait().describe(),
            "realtime.wait",
        )?;
        same(
            "policy",
            self.policy.clone(),
            settings.policy.name().into(),
            "realtime.policy",
        )?;
        if settings.policy.is_realtime() {
            same(
                "priority",
                format!("{:?}", self.priority),
                format!("{:?}", Some(settings.priority)),
                "realtime.priority",
            )?;
        }
        if !settings.cpus.is_empty() {
            same(
                "cpus",
                format!("{:?}", self.cpus),
                format!("{:?}", settings.cpus),
                "realtime.controller_cpu",
            )?;
        }
        same(
            "lock_memory",
            self.lock_memory.to_string(),
            settings.lock_memory.to_string(),
            "realtime.lock_memory",
        )?;
        let age = humantime::parse_rfc3339(&self.measured_at)
            .ok()
            .and_then(|t| std::time::SystemTime::now().duration_since(t).ok());
        match age {
            Some(a) if a.as_secs() <= MAX_AGE_S => Ok(()),
            _ => Err(at.invalid(
                "measured_at",
                &self.measured_at,
                "within the last day (RFC 3339): qualify the host again",
            )),
        }
    }
}

/// The loop of `judged`, the stall it survives (with its own `realtime.peer_timeout_s`), and a
/// note: what limits it, or why it was not predicted.
fn judge(judged: &Loaded) -> (String, Option<Survivable>, String) {
    let c = &judged.config;
    let what = |controller: &str| {
        format!(
            "{controller}, {}, {:.1} kHz",
            c.scenario.name(),
            c.plant.timing.servo_rate_hz / 1e3
        )
    };
    let plan = match Plan::new(judged) {
        Ok(p) => p,
        Err(e) => return (what("its controller"), None, format!("not predicted: {e}")),
    };
    let description = what(&plan.controller.description);
    match survivable(&plan, c.realtime.peer_timeout_s) {
        Ok(s) => {
            let note = s.limit().describe().to_owned();
            (description, Some(s), note)
        }
        Err(RunError::StallAnalysis(why)) => (description, None, format!("not predicted: {why}")),
        Err(e) => (description, None, format!("not predicted: {e}")),
    }
}

/// 4 × the worst stall `worst_ns` (at least 1 ms), in ms — unless the stage survives less
/// (`physics_s`): then the longest it survives, if that is still [`STALL_MARGIN`] × the worst
/// stall; None when no timeout is both.
fn recommended_timeout_ms(worst_ns: u64, physics_s: Option<f64>) -> Option<f64> {
    let wanted = (4 * worst_ns).div_ceil(1_000_000).max(1) as f64;
    match physics_s {
        Some(p) if wanted * 1e-3 > p => {
            // The longest the stage survives, to 0.1 ms below.
            let ms = (p * 1e4).floor() / 10.0;
            (ms * 1e6 >= STALL_MARGIN * worst_ns as f64).then_some(ms)
        }
        _ => Some(wanted),
    }
}

/// What a real-time run checks its host with before it starts.
#[derive(Debug, Clone, Default)]
pub struct HostCheck {
    /// A qualification of this host at the run's rate (None: measure for [`QUALIFY_S`]).
    pub qualification: Option<PathBuf>,
    /// Start even when the host stalls longer than the loop survives.
    pub force: bool,
}

/// Before a real-time run: the longest stall its loop survives (with peer timeout
/// `timeout_s`, s) against the host's — from `check.qualification` or a [`QUALIFY_S`]
/// measurement with the controller's settings — refused ([`RunError::HostTooSlow`]) when the
/// host's is longer, unless forced. What it finds is told to `notice`, one line each.
pub fn preflight(
    plan: &Plan,
    timeout_s: f64,
    check: &HostCheck,
    notice: &mut dyn FnMut(&str),
) -> Result<(), RunError> {
    plan.check_stable()?;
    let survivable = match survivable(plan, timeout_s) {
        Ok(s) => s,
        Err(RunError::StallAnalysis(why)) => {
            notice(&format!("note: the survivable stall is not checked: {why}"));
            return Ok(());
        }
        Err(e) => return Err(e),
    };
    let host = match &check.qualification {
        Some(path) => Qualification::read(path, plan)?,
        None => qualify_briefly(plan, notice)?,
    };
    notice(&format!(
        "stall check: this loop survives stalls up to {:.1} µs; this host stalled {:.1} µs ({})",
        survivable.stall_s() * 1e6,
        host.worst_s * 1e6,
        host.source
    ));
    match check_host(&survivable, &host) {
        Err(e) if check.force => {
            notice(&format!("warning: {e} Running anyway (--force)."));
            Ok(())
        }
        r => r,
    }
}

/// The host's worst stall: the loop's pacing alone at the run's rate with the controller's
/// real-time settings (a stall is the controller's: a plant stall only pauses the simulated
/// stage), for [`QUALIFY_S`].
fn qualify_briefly(plan: &Plan, notice: &mut dyn FnMut(&str)) -> Result<HostStalls, RunError> {
    let rt = &plan.config.realtime;
    let rate = plan.config.plant.timing.servo_rate_hz;
    notice(&format!(
        "qualifying this host: {QUALIFY_S} s of the loop's pacing at {:.1} kHz",
        rate / 1e3
    ));
    let period_ns = (1e9 / rate).round() as u64;
    let ticks = (QUALIFY_S * rate).round() as u64;
    let paced = pace(
        &rt.settings(Role::Controller),
        rt.wait(),
        period_ns,
        ticks,
        &mut |_, _| {},
    )?;
    Ok(HostStalls {
        worst_s: paced.lateness.summary().max_ns as f64 * 1e-9,
        measured_s: QUALIFY_S,
        rate_hz: rate,
        source: format!(
            "a {QUALIFY_S} s qualification at the run's start, CPUs {}, SCHED_{}; a longer `servo latency` sees rarer stalls",
            daq_io::realtime::list(&paced.cpus),
            paced.policy.name().to_uppercase()
        ),
    })
}
