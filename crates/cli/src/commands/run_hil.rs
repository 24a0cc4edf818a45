//! `servo run --hil`: the plant, controller and recorder as three processes over iceoryx2,
//! supervised from here, with the recorder's summary printed at the end.

use crate::args::{HilArgs, PeerTimeoutArgs, RecordingArgs};
use crate::interrupt::{stop_on_signals, PARENT_ENV};
use crate::output::{tick_bar, CliError};
use daq_io::contract::role;
use daq_io::ipc::{leaf, take, Endpoint};
use daq_io::Health;
use runner::config::{ConfigError, Origin, Role, Scenario};
use runner::stall::{check_host, survivable, HostStalls};
use runner::summary::Summary;
use runner::{Plan, RunError};
use std::path::{Path, PathBuf};
use std::process::{Child, ExitCode, Stdio};
use std::time::{Duration, Instant};

/// Writes the plan's configuration (files made absolute) for the child processes into `dir`
/// (a private folder of this run).
fn write_resolved(plan: &Plan, dir: &Path) -> Result<PathBuf, CliError> {
    let mut c = plan.config.clone();
    if let Some(p) = &c.controller.ss_file {
        c.controller.ss_file = Some(std::fs::canonicalize(p).unwrap_or(p.clone()));
    }
    if let Scenario::Machine(m) = &mut c.scenario {
        if let Some(path) = m.surface.path_mut() {
            *path = std::fs::canonicalize(&*path).unwrap_or(path.clone());
        }
    }
    let path = dir.join("config.toml");
    // Created new (never through a planted link) and private: mode 0600 in a 0700 folder.
    let write = || {
        use std::io::Write;
        recorder::create_private(&path)?.write_all(c.to_toml().as_bytes())
    };
    write().map_err(|source| CliError::Write {
        path: path.clone(),
        source,
    })?;
    Ok(path)
}

fn spawn(args: &[&str], stdout: Stdio) -> Result<Child, CliError> {
    let exe = std::env::current_exe()
        .map_err(|e| CliError::Processes(format!("cannot find the servo binary: {e}")))?;
    std::process::Command::new(exe)
        .args(args)
        .stdout(stdout)
        .stdin(Stdio::null())
        .env(PARENT_ENV, std::process::id().to_string())
        .spawn()
        .map_err(|e| CliError::Processes(format!("cannot start `servo {}`: {e}", args[0])))
}

/// `servo run --hil`: checks the loop, starts recorder, controller and plant as processes,
/// shows the plant's progress, and returns the recorder's summary and the exit code (the
/// first failing child's).
pub fn run(
    plan: &Plan,
    hil: &HilArgs,
    timeout: &PeerTimeoutArgs,
    rec: &RecordingArgs,
    out: Option<runner::recording::Target>,
    host: &HostCheck,
) -> Result<(Summary, ExitCode), CliError> {
    plan.check_stable()?;
    let peer_timeout = timeout.timeout()?;
    let (realtime, quiet) = (hil.realtime, rec.quiet);
    if realtime {
        let timeout_s =
            peer_timeout.map_or(plan.config.realtime.peer_timeout_s, |t| t.as_secs_f64());
        preflight(plan, timeout_s, host)?;
    }
    if let Some(o) = &out {
        // Checked before any process starts (the recorder process checks it again).
        o.check()?;
    }
    let prefix = hil
        .prefix
        .clone()
        .unwrap_or_else(|| format!("run-{}", std::process::id()));
    daq_io::ipc::check_prefix(&prefix)
        .map_err(|e| Origin::default().invalid("--prefix", &prefix, &e))?;
    // Joining first refuses a prefix a live run holds (naming it) before anything is made.
    // Subscribe before the children start: a subscriber joining mid-run makes the publishers
    // set up a connection inside a send, a sub-millisecond stall a real-time loop would feel.
    let ep = Endpoint::open(&prefix, "run").map_err(RunError::from)?;
    let health = ep
        .subscriber::<Health>(leaf::HEALTH)
        .map_err(RunError::from)?;
    // A folder of our own, created exclusively (mode 0700, unpredictable name): nobody else
    // can place or replace the configuration the children run; removed when this returns.
    let dir = tempfile::Builder::new()
        .prefix("fts-servo-")
        .permissions(std::os::unix::fs::PermissionsExt::from_mode(0o700))
        .tempdir()
        .map_err(|source| CliError::Write {
            path: std::env::temp_dir(),
            source,
        })?;
    let config = write_resolved(plan, dir.path())?;
    let config = config.to_str().expect("temp paths are UTF-8");
    let mode = if realtime { "--realtime" } else { "--lockstep" };
    let out_arg = out.as_ref().map(|t| {
        let epoch = std::time::UNIX_EPOCH + std::time::Duration::from_nanos(t.epoch_ns);
        (
            t.path.display().to_string(),
            humantime::format_rfc3339_nanos(epoch).to_string(),
            t.every.to_string(),
        )
    });
    let mut record_args = vec![
        "record", "--config", config, "--prefix", &prefix, "--json", "--quiet", mode,
    ];
    match &out_arg {
        Some((o, epoch, every)) => {
            record_args.extend(["--out", o, "--log-epoch", epoch, "--record-every", every])
        }
        None => record_args.push("--no-record"),
    }
    if rec.overwrite {
        record_args.push("--overwrite");
    }
    let stop = stop_on_signals();
    let recorder = spawn(&record_args, Stdio::piped())?;
    let controller = spawn(
        &["controller", "--config", config, "--prefix", &prefix],
        Stdio::inherit(),
    )?;
    let timeout = timeout.peer_timeout_ms.map(|t| t.to_string());
    let mut plant_args = vec!["plant", "--config", config, "--prefix", &prefix, mode];
    if let Some(t) = &timeout {
        plant_args.extend(["--peer-timeout-ms", t]);
    }
    let plant = spawn(&plant_args, Stdio::inherit())?;
    // This process supervises: low priority, off the servo CPUs (as the recorder). Only now:
    // children inherit niceness and affinity, and an unprivileged user cannot undo them.
    daq_io::realtime::apply(&plan.config.realtime.settings(runner::config::Role::Other))
        .map_err(RunError::from)?;
    let mut children = [
        ("plant", plant),
        ("controller", controller),
        ("record", recorder),
    ];

    let bar = tick_bar(quiet, if realtime { "real time" } else { "lockstep" });
    let total = plan.ticks();
    bar.set_length(total);
    let mut codes: Vec<(String, i32)> = Vec::new();
    let mut stopped_at: Option<Instant> = None;
    while codes.len() < children.len() {
        while let Some(h) = take(&health) {
            if h.role == role::PLANT {
                bar.set_position(h.ticks);
            }
        }
        for (name, child) in children.iter_mut() {
            if codes.iter().any(|(n, _)| n == name) {
                continue;
            }
            if let Ok(Some(status)) = child.try_wait() {
                codes.push((name.to_string(), status.code().unwrap_or(-1)));
            }
        }
        // A stop (a terminal's Ctrl-C reaches the whole group; a supervisor signals only this
        // process) is forwarded, as the same signal, to every child still running: each ends
        // at a tick boundary, the recorder finishes the file naming that signal, and the exit
        // code is 128 + it. One that hangs is killed after 10 s.
        if stop.is_set() && stopped_at.is_none() {
            stopped_at = Some(Instant::now());
            let signal = match stop.reason() {
                runner::stop::EndReason::Signal(s) => {
                    nix::sys::signal::Signal::try_from(s).unwrap_or(nix::sys::signal::SIGTERM)
                }
                _ => nix::sys::signal::SIGTERM,
            };
            for (name, child) in children.iter() {
                if !codes.iter().any(|(n, _)| n == name) {
                    let pid = nix::unistd::Pid::from_raw(child.id() as i32);
                    let _ = nix::sys::signal::kill(pid, signal);
                }
            }
        }
        if stopped_at.is_some_and(|t| t.elapsed() > Duration::from_secs(10)) {
            children.iter_mut().for_each(|(_, c)| drop(c.kill()));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    bar.finish_and_clear();
    let (_, recorder) = children.into_iter().last().expect("three children");
    let mut text = String::new();
    use std::io::Read;
    if let Some(mut o) = recorder.stdout {
        let _ = o.read_to_string(&mut text);
    }
    let failed = codes.iter().find(|(_, c)| *c != 0).cloned();
    let summary: Summary = serde_json::from_str(&text).map_err(|_| match &failed {
        // The child said why on stderr (e.g. the recorder: a full disk, and where the partial
        // file is); its exit code is the run's.
        Some((name, code)) => CliError::Child {
            name: name.to_string(),
            code: *code,
        },
        None => CliError::Processes(format!(
            "the recorder gave no summary (exit codes: {})",
            codes
                .iter()
                .map(|(n, c)| format!("{n} {c}"))
                .collect::<Vec<_>>()
                .join(", ")
        )),
    })?;
    let code = match failed {
        Some((name, c)) => {
            eprintln!("servo {name} exited with {c}");
            ExitCode::from(c as u8)
        }
        None => ExitCode::SUCCESS,
    };
    Ok((summary, code))
}

/// How long a real-time run qualifies its host before it starts, in s.
pub const QUALIFY_S: f64 = 1.0;

/// How old a `servo latency` result may be to stand for this host, in s (a day).
const QUALIFICATION_MAX_AGE_S: u64 = 86_400;

/// What a real-time run checks its host with before it starts.
#[derive(Debug, Default)]
pub struct HostCheck {
    /// A `servo latency --json` result of this host at the run's rate (None: measure for
    /// [`QUALIFY_S`] here).
    pub qualification: Option<PathBuf>,
    /// Start even when the host stalls longer than the loop survives.
    pub force: bool,
}

/// Before a real-time run: the longest stall its loop survives (with peer timeout
/// `timeout_s`, s) against the host's, from a `servo latency` result or a short qualification;
/// refused when the host's is longer, unless forced.
fn preflight(plan: &Plan, timeout_s: f64, check: &HostCheck) -> Result<(), CliError> {
    let survivable = match survivable(plan, timeout_s) {
        Ok(s) => s,
        Err(RunError::StallAnalysis(why)) => {
            eprintln!("note: the survivable stall is not checked: {why}");
            return Ok(());
        }
        Err(e) => return Err(e.into()),
    };
    let host = match &check.qualification {
        Some(path) => read_qualification(path, plan)?,
        None => qualify(plan)?,
    };
    eprintln!(
        "stall check: this loop survives stalls up to {:.1} µs; this host stalled {:.1} µs ({})",
        survivable.stall_s() * 1e6,
        host.worst_s * 1e6,
        host.source
    );
    match check_host(&survivable, &host) {
        Err(e) if check.force => {
            eprintln!("warning: {e} Running anyway (--force).");
            Ok(())
        }
        r => Ok(r?),
    }
}

/// The host's worst stall: the loop's pacing alone at the run's rate with the controller's
/// real-time settings (a stall is the controller's: a plant stall only pauses the simulated
/// stage), for [`QUALIFY_S`], on a thread of its own (its scheduling ends with it).
fn qualify(plan: &Plan) -> Result<HostStalls, CliError> {
    use daq_io::qualify::{measure, WallClock};
    let rt = &plan.config.realtime;
    let rate = plan.config.plant.timing.servo_rate_hz;
    let period_ns = (1e9 / rate).round() as u64;
    let ticks = (QUALIFY_S * rate).round() as u64;
    eprintln!(
        "qualifying this host: {QUALIFY_S} s of the loop's pacing at {:.1} kHz",
        rate / 1e3
    );
    let settings = rt.settings(Role::Controller);
    let wait = rt.wait();
    let measured = std::thread::scope(|s| {
        s.spawn(|| -> Result<(u64, String), RunError> {
            daq_io::realtime::apply(&settings)?;
            let applied = daq_io::realtime::current();
            let cpus = daq_io::realtime::list(&daq_io::realtime::current_cpus());
            let run = measure(&mut WallClock::new(wait), period_ns, 0..ticks);
            let how = format!("CPUs {cpus}, SCHED_{}", applied.0.name().to_uppercase());
            Ok((run.lateness.summary().max_ns, how))
        })
        .join()
        .expect("the qualification does not panic")
    })?;
    Ok(HostStalls {
        worst_s: measured.0 as f64 * 1e-9,
        measured_s: QUALIFY_S,
        rate_hz: rate,
        source: format!(
            "a {QUALIFY_S} s qualification at the run's start, {}; a longer `servo latency` sees rarer stalls",
            measured.1
        ),
    })
}

/// A `servo latency --json` result: its `host_stalls`, when it was measured on this host
/// (`host`), at the run's rate (`rate_hz`) with the controller's settings (`wait`, `policy`,
/// `priority`, `cpus` when the run pins the controller, `lock_memory`), within the last day
/// (`measured_at`).
fn read_qualification(path: &Path, plan: &Plan) -> Result<HostStalls, CliError> {
    use runner::config::input_file::read_text;
    #[derive(serde::Deserialize)]
    struct Latency {
        host: String,
        measured_at: String,
        rate_hz: f64,
        wait: String,
        policy: String,
        priority: Option<i32>,
        cpus: Vec<usize>,
        lock_memory: bool,
        host_stalls: HostStalls,
    }
    let text = read_text(path)?;
    let l: Latency = serde_json::from_str(&text).map_err(|e| ConfigError::Parse {
        path: path.to_owned(),
        message: format!("{e} (a `servo latency --json` result)"),
    })?;
    let at = Origin {
        path: Some(path.to_owned()),
        text: Some(text),
    };
    let here = runner::recording::host_name();
    if l.host != here {
        return Err(at
            .invalid(
                "host",
                &l.host,
                &format!("this host ({here}): qualify it with servo latency here"),
            )
            .into());
    }
    let rate = plan.config.plant.timing.servo_rate_hz;
    if (l.rate_hz - rate).abs() > 1e-9 * rate || l.host_stalls.rate_hz != l.rate_hz {
        return Err(at
            .invalid("rate_hz", l.rate_hz, &format!("the run's {rate} Hz"))
            .into());
    }
    if !(l.host_stalls.worst_s.is_finite() && l.host_stalls.worst_s >= 0.0) {
        return Err(at
            .invalid(
                "host_stalls.worst_s",
                l.host_stalls.worst_s,
                "a stall ≥ 0 s",
            )
            .into());
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
    same("wait", l.wait, rt.wait().describe(), "realtime.wait")?;
    same(
        "policy",
        l.policy,
        settings.policy.name().into(),
        "realtime.policy",
    )?;
    if settings.policy.is_realtime() {
        same(
            "priority",
            format!("{:?}", l.priority),
            format!("{:?}", Some(settings.priority)),
            "realtime.priority",
        )?;
    }
    if !settings.cpus.is_empty() {
        same(
            "cpus",
            format!("{:?}", l.cpus),
            format!("{:?}", settings.cpus),
            "realtime.controller_cpu",
        )?;
    }
    same(
        "lock_memory",
        l.lock_memory.to_string(),
        settings.lock_memory.to_string(),
        "realtime.lock_memory",
    )?;
    let age = humantime::parse_rfc3339(&l.measured_at)
        .ok()
        .and_then(|t| std::time::SystemTime::now().duration_since(t).ok());
    match age {
        Some(a) if a.as_secs() <= QUALIFICATION_MAX_AGE_S => {}
        _ => {
            return Err(at
                .invalid(
                    "measured_at",
                    &l.measured_at,
                    "within the last day (RFC 3339): qualify the host again",
                )
                .into())
        }
    }
    Ok(HostStalls {
        source: format!("{}, {}", l.host_stalls.source, path.display()),
        ..l.host_stalls
    })
}
