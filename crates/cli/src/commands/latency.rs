//! `servo latency`: qualify a host before a real-time run — the periodic loop alone at a rate,
//! its start-lateness histogram, what the kernel settings allow, and whether the run's loop
//! survives the stalls measured.

use crate::args::RtPolicy;
use crate::output::{print_json, tick_bar, CliError};
use clap::Args;
use daq_io::qualify::{measure, readiness, Check, WallClock};
use runner::config::{Loaded, Origin, RealtimeConfig, Role, WaitKind};
use runner::stall::{advice, check_host, survivable, HostStalls, Survivable};
use runner::{Plan, RunError};
use std::path::PathBuf;
use std::process::ExitCode;

/// Qualify this host for real time: tick lateness, overruns and kernel settings
///
/// Runs the servo loop's pacing alone at the loop's rate for
/// --duration and prints its start lateness (p50, p99, p99.9, p99.99, max), the overruns (a
/// tick started a whole period late), the longest stall the loop of --config survives (the
/// default: the thesis PID holding position) beside the longest this host made, a peer timeout
/// between the two, and a readiness report of the kernel settings with what to change. With
/// --json, a file `servo run --hil --realtime --qualification` takes.
///
/// Example: servo latency --config run.toml --wait sleep-spin --duration 10
#[derive(Args, Debug)]
pub struct LatencyCmd {
    /// The run whose loop is judged (its controller, scenario, limits and
    /// [realtime] peer timeout; default: the thesis PID holding position).
    #[arg(long, short)]
    config: Option<PathBuf>,
    /// Loop rate in Hz (100 – 2e6; default: the loop's, plant.timing.servo_rate_hz).
    #[arg(value_parser = crate::args::finite, long)]
    rate_hz: Option<f64>,
    /// How long to measure, in s (0, 600].
    #[arg(value_parser = crate::args::finite, long, default_value_t = 5.0)]
    duration: f64,
    /// How each tick waits for its deadline.
    #[arg(long, value_enum, default_value_t = WaitKind::Spin)]
    wait: WaitKind,
    /// With --wait sleep-spin: spin this long before each deadline, in µs (0 – 10 000).
    #[arg(value_parser = crate::args::finite, long, default_value_t = 50.0)]
    spin_margin_us: f64,
    /// Pin the loop to this CPU (default: wherever the scheduler puts it).
    #[arg(long)]
    cpu: Option<usize>,
    /// Scheduling policy of the loop (fifo/rr need CAP_SYS_NICE or RLIMIT_RTPRIO; with spin
    /// the loop keeps one CPU busy at real-time priority: never on every CPU of a host).
    #[arg(long, value_enum, default_value = "other")]
    rt_policy: RtPolicy,
    /// Real-time priority for fifo/rr, 1..=98.
    #[arg(long, default_value_t = 10)]
    rt_priority: i32,
    /// Lock memory (mlockall) and pre-fault the stack, as the servo processes can.
    #[arg(long)]
    lock_memory: bool,
    /// JSON instead of text.
    #[arg(long)]
    json: bool,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
}

/// What `servo latency` found.
#[derive(Debug, serde::Serialize)]
struct Report {
    /// This host's name (a qualification holds for the host it was measured on).
    host: String,
    /// When it was measured (RFC 3339).
    measured_at: String,
    rate_hz: f64,
    period_ns: u64,
    ticks: u64,
    wait: String,
    /// The policy, priority and CPUs as the kernel reports them after applying the settings.
    policy: String,
    priority: Option<i32>,
    cpus: Vec<usize>,
    lock_memory: bool,
    lateness_ns: Percentiles,
    overruns: u64,
    overrun_rate: f64,
    /// A controller-loss timeout no stall of this run reached (4 × the worst lateness, at
    /// least 1 ms) and within what the stage survives (then at least twice the worst stall),
    /// in ms; None when no timeout is both.
    recommended_peer_timeout_ms: Option<f64>,
    /// An overrun budget this host keeps: burst 2 × the worst stall (at least 2 ms), in ms …
    recommended_overrun_burst_ms: u64,
    /// … and sustained rate 2 × the measured overrun rate (at least 1 %).
    recommended_overrun_rate: f64,
    /// The longest stall this host made (its worst start lateness), as a run checks it.
    host_stalls: HostStalls,
    /// The loop judged.
    #[serde(rename = "loop")]
    judged: String,
    /// The longest stall that loop survives (None: not predicted, see `survivable_note`).
    survivable: Option<Survivable>,
    /// The longest stall the loop survives, s.
    survivable_stall_s: Option<f64>,
    /// Why the survivable stall was not predicted, or what limits it.
    survivable_note: String,
    /// The host's worst stall is within what the loop survives.
    holds: Option<bool>,
    readiness: Vec<Check>,
}

#[derive(Debug, serde::Serialize)]
struct Percentiles {
    min: u64,
    p50: u64,
    p99: u64,
    p999: u64,
    p9999: u64,
    max: u64,
}

impl LatencyCmd {
    /// Measures and reports.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let at = Origin::default();
        let mut judged = match &self.config {
            Some(p) => Loaded::from_file(p)?,
            None => Loaded::default(),
        };
        let rate_hz = self
            .rate_hz
            .unwrap_or(judged.config.plant.timing.servo_rate_hz);
        if !(1e2..=2e6).contains(&rate_hz) {
            let e = match self.rate_hz {
                Some(_) => at.invalid("--rate-hz", rate_hz, "[100, 2e6] Hz"),
                None => judged.origin.invalid(
                    "plant.timing.servo_rate_hz",
                    rate_hz,
                    "[100, 2e6] Hz for servo latency",
                ),
            };
            return Err(e.into());
        }
        judged.config.plant.timing.servo_rate_hz = rate_hz;
        if !(self.duration > 0.0 && self.duration <= 600.0) {
            return Err(at.invalid("--duration", self.duration, "(0, 600] s").into());
        }
        if !(0.0..=1e4).contains(&self.spin_margin_us) {
            return Err(at
                .invalid("--spin-margin-us", self.spin_margin_us, "[0, 10000] µs")
                .into());
        }
        let policy = self.rt_policy.policy();
        if policy.is_realtime()
            && self.wait == WaitKind::Spin
            && daq_io::realtime::online_cpus() < 2
        {
            return Err(at
                .invalid(
                    "--rt-policy",
                    policy.name(),
                    "other with --wait spin on a 1-CPU host (a spinning real-time loop on every CPU starves it)",
                )
                .into());
        }
        // The loop measured is the plant's: its settings as a run would apply them.
        let rt = RealtimeConfig {
            policy,
            priority: self.rt_priority,
            plant_cpu: self.cpu,
            lock_memory: self.lock_memory,
            wait: self.wait,
            spin_margin_s: self.spin_margin_us * 1e-6,
            ..RealtimeConfig::default()
        };
        daq_io::realtime::apply(&rt.settings(Role::Plant))
            .map_err(|e| CliError::Processes(e.to_string()))?;
        let applied = daq_io::realtime::current();
        let wait = rt.wait();
        let period_ns = (1e9 / rate_hz).round() as u64;
        let ticks = (self.duration * rate_hz).round() as u64;
        let bar = tick_bar(self.quiet || self.json, "measuring");
        bar.set_length(ticks);
        // In slices of 0.1 s on one clock, so the bar moves between them.
        let slice = ((0.1 * rate_hz) as u64).max(1);
        let mut clock = WallClock::new(wait);
        let mut lateness = daq_io::LatencyHistogram::new();
        let mut overruns = 0;
        let mut done = 0;
        while done < ticks {
            let n = slice.min(ticks - done);
            let run = measure(&mut clock, period_ns, done..done + n);
            lateness.merge(&run.lateness);
            overruns += run.overruns;
            done += n;
            bar.set_position(done);
        }
        bar.finish_and_clear();
        let l = lateness.summary();
        let cpus = daq_io::realtime::current_cpus();
        let host_stalls = HostStalls {
            worst_s: l.max_ns as f64 * 1e-9,
            measured_s: self.duration,
            rate_hz,
            source: format!(
                "servo latency, {} s at {:.1} kHz on {}, CPUs {}, SCHED_{}",
                self.duration,
                rate_hz / 1e3,
                runner::recording::host_name(),
                daq_io::realtime::list(&cpus),
                applied.0.name().to_uppercase()
            ),
        };
        let (description, survivable, note) = judge(&judged);
        let physics_s = survivable.and_then(|s| s.physics_s());
        let recommended_peer_timeout_ms = recommended_timeout_ms(l.max_ns, physics_s);
        let report = Report {
            host: runner::recording::host_name(),
            measured_at: humantime::format_rfc3339_seconds(std::time::SystemTime::now())
                .to_string(),
            rate_hz,
            period_ns,
            ticks,
            wait: wait.describe(),
            policy: applied.0.name().into(),
            priority: applied.0.is_realtime().then_some(applied.1),
            cpus,
            lock_memory: self.lock_memory,
            lateness_ns: Percentiles {
                min: l.min_ns,
                p50: l.p50_ns,
                p99: l.p99_ns,
                p999: l.p999_ns,
                p9999: lateness.quantile(0.9999),
                max: l.max_ns,
            },
            overruns,
            overrun_rate: overruns as f64 / ticks as f64,
            recommended_peer_timeout_ms,
            recommended_overrun_burst_ms: (2 * l.max_ns).div_ceil(1_000_000).max(2),
            recommended_overrun_rate: (2.0 * overruns as f64 / ticks as f64).max(0.01),
            holds: survivable.map(|s| check_host(&s, &host_stalls).is_ok()),
            survivable_stall_s: survivable.map(|s| s.stall_s()),
            host_stalls,
            judged: description,
            survivable,
            survivable_note: note,
            readiness: readiness(),
        };
        if self.json {
            print_json(&report);
        } else {
            print_report(&report);
        }
        Ok(ExitCode::SUCCESS)
    }
}

fn print_report(r: &Report) {
    let us = |ns: u64| ns as f64 * 1e-3;
    let l = &r.lateness_ns;
    println!(
        "servo latency: {} ticks at {:.1} kHz (period {:.3} µs), {}, CPUs {}, SCHED_{}{}{}",
        r.ticks,
        r.rate_hz / 1e3,
        us(r.period_ns),
        r.wait,
        daq_io::realtime::list(&r.cpus),
        r.policy.to_uppercase(),
        r.priority.map_or(String::new(), |p| format!(" {p}")),
        if r.lock_memory { ", memory locked" } else { "" }
    );
    println!(
        "  start lateness   min {:.2} / p50 {:.2} / p99 {:.2} / p99.9 {:.2} / p99.99 {:.2} / max {:.1} µs",
        us(l.min),
        us(l.p50),
        us(l.p99),
        us(l.p999),
        us(l.p9999),
        us(l.max)
    );
    println!(
        "  overruns         {} ({:.4} %): ticks that started a whole period late",
        r.overruns,
        100.0 * r.overrun_rate
    );
    print_survivable(r);
    match r.recommended_peer_timeout_ms {
        Some(ms) => println!(
            "  peer timeout     {ms} ms recommended (4 × the worst stall seen, within what the stage survives): --peer-timeout-ms or realtime.peer_timeout_s"
        ),
        None => println!(
            "  peer timeout     none keeps this loop within its limits through this host's stalls"
        ),
    }
    println!(
        "  overrun budget   --overrun-burst-ms {} --overrun-rate {:.3} recommended (2 × the worst stall, 2 × the overrun rate)",
        r.recommended_overrun_burst_ms, r.recommended_overrun_rate
    );
    println!("  readiness:");
    for c in &r.readiness {
        println!(
            "    {} {:<24} {}",
            if c.ok { "ok  " } else { "WARN" },
            c.name,
            c.value
        );
        if !c.advice.is_empty() {
            println!("         → {}", c.advice);
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
///
/// [`STALL_MARGIN`]: runner::stall::STALL_MARGIN
fn recommended_timeout_ms(worst_ns: u64, physics_s: Option<f64>) -> Option<f64> {
    let wanted = (4 * worst_ns).div_ceil(1_000_000).max(1) as f64;
    match physics_s {
        Some(p) if wanted * 1e-3 > p => {
            // The longest the stage survives, to 0.1 ms below.
            let ms = (p * 1e4).floor() / 10.0;
            (ms * 1e6 >= runner::stall::STALL_MARGIN * worst_ns as f64).then_some(ms)
        }
        _ => Some(wanted),
    }
}

/// The survivable stall beside the host's, and what to change when the host's is longer.
fn print_survivable(r: &Report) {
    let worst_us = r.host_stalls.worst_s * 1e6;
    let Some(s) = &r.survivable else {
        println!(
            "  survivable stall for this loop ({}): {}",
            r.judged, r.survivable_note
        );
        return;
    };
    let physics = match s.physics_s() {
        Some(p) => format!("the stage alone survives {:.1} µs", p * 1e6),
        None => format!(
            "the stage alone survives more than {:.0} ms",
            runner::stall::MAX_STALL_S * 1e3
        ),
    };
    println!(
        "  survivable stall {:.1} µs for this loop ({}): beyond it {}; {physics}",
        s.stall_s() * 1e6,
        r.judged,
        r.survivable_note
    );
    let margin = runner::stall::STALL_MARGIN;
    if r.holds == Some(true) {
        println!(
            "  verdict          holds: this host stalled {worst_us:.1} µs; this loop survives {margin} × that or more"
        );
    } else {
        println!(
            "  verdict          FAILS: this host stalled {worst_us:.1} µs; this loop survives less than {margin} × that"
        );
        println!("         → {}", advice(s, r.host_stalls.worst_s));
    }
}
