//! `servo run --hil`: the plant, controller and recorder as three processes over iceoryx2,
//! supervised from here, with the recorder's summary printed at the end.

use crate::args::{HilArgs, PeerTimeoutArgs, RecordingArgs};
use crate::interrupt::{stop_on_signals, PARENT_ENV};
use crate::output::{tick_bar, CliError};
use daq_io::contract::role;
use daq_io::ipc::{leaf, take, Endpoint};
use daq_io::Health;
use runner::config::{Origin, Scenario, SurfaceConfig};
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
        if let SurfaceConfig::Image { path, .. } = &mut m.surface {
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
) -> Result<(Summary, ExitCode), CliError> {
    plan.check_stable()?;
    timeout.timeout()?;
    let (realtime, quiet) = (hil.realtime, rec.quiet);
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
