//! `servo run --hil`'s supervisor: the recorder, controller and plant started as three `servo`
//! processes over iceoryx2, watched until each ends, a stop forwarded to each, and the
//! recorder's summary returned.

use super::PARENT_ENV;
use crate::error::{ChildFailure, RunError};
use crate::plan::Plan;
use crate::recording::Target;
use crate::stop::{EndReason, StopRequest};
use crate::summary::Summary;
use daq_io::contract::role;
use daq_io::ipc::{leaf, take, Endpoint};
use daq_io::Health;
use run_config::{Role, Scenario};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// How long a process that was asked to stop has before it is killed.
const STOP_GRACE: Duration = Duration::from_secs(10);

/// How a HIL run is started.
#[derive(Debug, Clone)]
pub struct Supervision {
    /// The `servo` executable the three processes run.
    pub servo: PathBuf,
    /// The shared-memory prefix of the run (None: `run-<pid>`).
    pub prefix: Option<String>,
    /// Paced by the wall clock (`--realtime`) instead of in lockstep.
    pub realtime: bool,
    /// The plant's controller-loss timeout, ms (None: `realtime.peer_timeout_s`).
    pub peer_timeout_ms: Option<f64>,
    /// Where the recorder writes (None: no recording, the summary only).
    pub out: Option<Target>,
}

/// How a HIL run ended: the recorder's summary, and the first process that failed.
#[derive(Debug, Clone)]
pub struct Supervised {
    /// The recorder's summary of the run.
    pub summary: Summary,
    /// The first process that exited with a code other than 0, if any.
    pub failed: Option<ChildFailure>,
}

impl Supervised {
    /// The run's exit code: its end reason's when that is not 0 (a lost peer, a trip, a failed
    /// write), else the first failed process's (128 + the signal that killed it), else 0. (An
    /// interrupted run's code is its signal's, which its processes exit with.)
    pub fn exit_code(&self) -> i32 {
        let reason = EndReason::EACH
            .iter()
            .filter(|r| !matches!(r, EndReason::Signal(_)))
            .find(|r| self.summary.meta.end_reason.as_deref() == Some(r.name()))
            .map_or(0, |r| r.exit_code());
        match (reason, &self.failed) {
            (0, Some(f)) => f.code,
            (reason, _) => i32::from(reason),
        }
    }
}

/// Runs `plan` as three processes of `s.servo`: checks the loop's stability, starts recorder,
/// controller and plant (this process then takes the supervisor's real-time settings: low
/// priority, off the servo CPUs), reports the plant's tick count to `progress(ticks, total)`,
/// forwards a `stop` (its signal, or SIGTERM) to every process still running — one that hangs is
/// killed after 10 s — and returns the recorder's summary. A process that fails without the
/// recorder giving a summary is [`RunError::ChildFailed`].
pub fn supervise(
    plan: &Plan,
    s: &Supervision,
    stop: &StopRequest,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Supervised, RunError> {
    plan.check_stable()?;
    if let Some(o) = &s.out {
        // Checked before any process starts (the recorder process checks it again).
        o.check()?;
    }
    let prefix = s
        .prefix
        .clone()
        .unwrap_or_else(|| format!("run-{}", std::process::id()));
    daq_io::ipc::check_prefix(&prefix)
        .map_err(|e| run_config::Origin::default().invalid("prefix", &prefix, &e))?;
    // Joining first refuses a prefix a live run holds (naming it) before anything is made.
    // Subscribe before the children start: a subscriber joining mid-run makes the publishers
    // set up a connection inside a send, a sub-millisecond stall a real-time loop would feel.
    let ep = Endpoint::open(&prefix, "run")?;
    let health = ep.subscriber::<Health>(leaf::HEALTH)?;
    // A folder of our own, created exclusively (mode 0700, unpredictable name): nobody else
    // can place or replace the configuration the children run; removed when this returns.
    let dir = tempfile::Builder::new()
        .prefix("fts-servo-")
        .permissions(std::os::unix::fs::PermissionsExt::from_mode(0o700))
        .tempdir()
        .map_err(|e| RunError::Processes(format!("cannot make a private folder: {e}")))?;
    let config = write_resolved(plan, dir.path())?;
    let config = config
        .to_str()
        .ok_or_else(|| RunError::Processes("the temporary folder's path is not UTF-8".into()))?;
    let mode = if s.realtime {
        "--realtime"
    } else {
        "--lockstep"
    };
    let out_arg = s.out.as_ref().map(|t| {
        let epoch = std::time::UNIX_EPOCH + Duration::from_nanos(t.epoch_ns);
        (
            t.path.display().to_string(),
            humantime::format_rfc3339_nanos(epoch).to_string(),
            t.every.to_string(),
            t.split_ns.map(|s| format!("{}", s.get() as f64 * 1e-9)),
        )
    });
    let mut record_args = vec![
        "record", "--config", config, "--prefix", &prefix, "--json", "--quiet", mode,
    ];
    match &out_arg {
        Some((o, epoch, every, split)) => {
            record_args.extend(["--out", o, "--log-epoch", epoch, "--record-every", every]);
            if let Some(s) = split {
                record_args.extend(["--split-s", s]);
            }
        }
        None => record_args.push("--no-record"),
    }
    if s.out.as_ref().is_some_and(|t| t.overwrite) {
        record_args.push("--overwrite");
    }
    let recorder = spawn(&s.servo, &record_args, Stdio::piped())?;
    let controller = spawn(
        &s.servo,
        &["controller", "--config", config, "--prefix", &prefix],
        Stdio::inherit(),
    )?;
    let timeout = s.peer_timeout_ms.map(|t| t.to_string());
    let mut plant_args = vec!["plant", "--config", config, "--prefix", &prefix, mode];
    if let Some(t) = &timeout {
        plant_args.extend(["--peer-timeout-ms", t]);
    }
    let plant = spawn(&s.servo, &plant_args, Stdio::inherit())?;
    // This process supervises: low priority, off the servo CPUs (as the recorder). Only now:
    // children inherit niceness and affinity, and an unprivileged user cannot undo them.
    daq_io::realtime::apply(&plan.config.realtime.settings(Role::Other))?;
    let mut children = [
        ("plant", plant),
        ("controller", controller),
        ("record", recorder),
    ];
    let total = plan.ticks();
    let mut codes: Vec<(&str, i32)> = Vec::new();
    let mut stopped_at: Option<Instant> = None;
    let mut looping = false;
    while codes.len() < children.len() {
        while let Some(h) = take(&health) {
            if h.role == role::PLANT {
                looping |= h.ticks > 0;
                progress(h.ticks, total);
            }
        }
        for (name, child) in children.iter_mut() {
            if codes.iter().any(|(n, _)| n == name) {
                continue;
            }
            if let Ok(Some(status)) = child.try_wait() {
                // Killed by a signal (one it could not handle: SIGKILL): 128 + its number,
                // as a shell reports it.
                use std::os::unix::process::ExitStatusExt;
                let code = status.code().or(status.signal().map(|s| 128 + s));
                codes.push((name, code.unwrap_or(1)));
            }
        }
        // A stop (a terminal's Ctrl-C reaches the whole group; a supervisor signals only this
        // process) is forwarded, as the same signal, to every child still running: each ends
        // at a tick boundary, the recorder finishes the file naming that signal, and the exit
        // code is 128 + it. A recorder that failed (killed, or its file unwritable) stops the
        // loop the same way, with SIGTERM: no loop runs on unrecorded. So does any process
        // that failed before the loop's first tick: the others would wait for it in vain.
        // (A plant or controller lost mid-run is the loop's own to end: a lost peer.)
        let recorder_failed = codes.iter().any(|&(n, c)| n == "record" && c != 0);
        let any_failed = codes.iter().any(|&(_, c)| c != 0);
        if (stop.is_set() || recorder_failed || (any_failed && !looping)) && stopped_at.is_none() {
            stopped_at = Some(Instant::now());
            let signal = match stop.reason() {
                EndReason::Signal(n) if stop.is_set() => {
                    nix::sys::signal::Signal::try_from(n).unwrap_or(nix::sys::signal::SIGTERM)
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
        if stopped_at.is_some_and(|t| t.elapsed() > STOP_GRACE) {
            children.iter_mut().for_each(|(_, c)| drop(c.kill()));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let [_, _, (_, recorder)] = children;
    let mut text = String::new();
    if let Some(mut o) = recorder.stdout {
        use std::io::Read;
        let _ = o.read_to_string(&mut text);
    }
    let failed = codes
        .iter()
        .find(|(_, c)| *c != 0)
        .map(|(name, code)| ChildFailure {
            process: name.to_string(),
            code: *code,
        });
    let summary: Summary = serde_json::from_str(&text).map_err(|_| match &failed {
        // The child said why on stderr (e.g. the recorder: a full disk, and where the partial
        // file is); its exit code is the run's.
        Some(f) => RunError::ChildFailed(f.clone()),
        None => RunError::Processes(format!(
            "the recorder gave no summary (exit codes: {})",
            codes
                .iter()
                .map(|(n, c)| format!("{n} {c}"))
                .collect::<Vec<_>>()
                .join(", ")
        )),
    })?;
    Ok(Supervised { summary, failed })
}

/// Writes the plan's configuration (files made absolute) for the child processes into `dir`
/// (a private folder of this run).
fn write_resolved(plan: &Plan, dir: &Path) -> Result<PathBuf, RunError> {
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
    write().map_err(|e| RunError::Processes(format!("cannot write {}: {e}", path.display())))?;
    Ok(path)
}

/// Starts `servo ARGS` as a child that knows its parent ([`PARENT_ENV`]).
fn spawn(servo: &Path, args: &[&str], stdout: Stdio) -> Result<Child, RunError> {
    Command::new(servo)
        .args(args)
        .stdout(stdout)
        .stdin(Stdio::null())
        .env(PARENT_ENV, std::process::id().to_string())
        .spawn()
        .map_err(|e| {
            RunError::Processes(format!(
                "cannot start `{} {}`: {e}",
                servo.display(),
                args[0]
            ))
        })
}
