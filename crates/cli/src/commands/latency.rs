//! `servo latency`: qualify a host before a real-time run — the periodic loop alone at a rate,
//! its start-lateness histogram, and what the kernel settings allow.

use crate::args::RtPolicy;
use crate::output::{print_json, tick_bar, CliError};
use clap::Args;
use daq_io::qualify::{measure, readiness, Check, WallClock};
use runner::config::{Origin, RealtimeConfig, Role, WaitKind};
use std::process::ExitCode;

/// Qualify this host for real time: tick lateness, overruns and kernel settings
///
/// Runs the servo loop's pacing alone at --rate-hz for
/// --duration and prints its start lateness (p50, p99, p99.9, p99.99, max), the overruns (a
/// tick started a whole period late), a peer timeout no observed stall reaches, and a readiness
/// report of the kernel settings with what to change.
///
/// Example: servo latency --rate-hz 20000 --wait sleep-spin --duration 10
#[derive(Args, Debug)]
pub struct LatencyCmd {
    /// Loop rate in Hz (100 – 2e6).
    #[arg(value_parser = crate::args::finite, long, default_value_t = 199_600.0)]
    rate_hz: f64,
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
    /// least 1 ms), in ms.
    recommended_peer_timeout_ms: u64,
    /// An overrun budget this host keeps: burst 2 × the worst stall (at least 2 ms), in ms …
    recommended_overrun_burst_ms: u64,
    /// … and sustained rate 2 × the measured overrun rate (at least 1 %).
    recommended_overrun_rate: f64,
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
        if !(1e2..=2e6).contains(&self.rate_hz) {
            return Err(at
                .invalid("--rate-hz", self.rate_hz, "[100, 2e6] Hz")
                .into());
        }
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
        let period_ns = (1e9 / self.rate_hz).round() as u64;
        let ticks = (self.duration * self.rate_hz).round() as u64;
        let bar = tick_bar(self.quiet || self.json, "measuring");
        bar.set_length(ticks);
        // In slices of 0.1 s on one clock, so the bar moves between them.
        let slice = ((0.1 * self.rate_hz) as u64).max(1);
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
        let report = Report {
            rate_hz: self.rate_hz,
            period_ns,
            ticks,
            wait: wait.describe(),
            policy: applied.0.name().into(),
            priority: applied.0.is_realtime().then_some(applied.1),
            cpus: daq_io::realtime::current_cpus(),
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
            recommended_peer_timeout_ms: (4 * l.max_ns).div_ceil(1_000_000).max(1),
            recommended_overrun_burst_ms: (2 * l.max_ns).div_ceil(1_000_000).max(2),
            recommended_overrun_rate: (2.0 * overruns as f64 / ticks as f64).max(0.01),
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
    println!(
        "  peer timeout     ≥ {} ms recommended (4 × the worst stall seen): --peer-timeout-ms",
        r.recommended_peer_timeout_ms
    );
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
