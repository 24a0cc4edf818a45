//! `servo latency`: qualify a host before a real-time run — the periodic loop alone at a rate,
//! its start-lateness histogram, what the kernel settings allow, and whether the run's loop
//! survives the stalls measured.

use crate::args::RtPolicy;
use crate::choice::choice;
use crate::output::{print_json, tick_bar, CliError};
use clap::Args;
use run_config::{Loaded, Origin, RealtimeConfig, Role, WaitKind};
use runner::stall::{advice, Measurement, Qualification};
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
    #[arg(long, value_parser = choice::<WaitKind>(), default_value = "spin")]
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

impl LatencyCmd {
    /// Measures and reports.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let at = Origin::default();
        let judged = match &self.config {
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
        let realtime = RealtimeConfig {
            policy,
            priority: self.rt_priority,
            plant_cpu: self.cpu,
            lock_memory: self.lock_memory,
            wait: self.wait,
            spin_margin_s: self.spin_margin_us * 1e-6,
            ..RealtimeConfig::default()
        };
        let measurement = Measurement {
            rate_hz,
            duration_s: self.duration,
            realtime,
            role: Role::Plant,
        };
        let bar = tick_bar(self.quiet || self.json, "measuring");
        let report = Qualification::measure(&judged, &measurement, &mut |done, total| {
            bar.set_length(total);
            bar.set_position(done);
        })?;
        bar.finish_and_clear();
        if self.json {
            print_json(&report);
        } else {
            print_report(&report);
        }
        Ok(ExitCode::SUCCESS)
    }
}

fn print_report(r: &Qualification) {
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

/// The survivable stall beside the host's, and what to change when the host's is longer.
fn print_survivable(r: &Qualification) {
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
