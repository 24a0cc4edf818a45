//! The multi-process (HIL) subcommands: `servo plant`, `servo controller`, `servo record`,
//! `servo ctl`, and `servo run --hil`, which starts the three processes and prints the summary.

use crate::{done, fail, print_summary, progress_bar, stop_flag, Recording};
use daq_io::contract::role;
use daq_io::ipc::{leaf, take, ControlSender, Endpoint};
use daq_io::{Control, Health};
use runner::config::Loaded;
use runner::run::RunError;
use runner::summary::Summary;
use std::path::{Path, PathBuf};
use std::process::{Child, ExitCode, Stdio};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// Exit code of a plant that lost its controller (it drove zero current and ended the run).
pub const EXIT_FAULT: u8 = 3;

/// `servo plant`.
pub fn plant(cfg: &Loaded, prefix: &str, options: &runner::hil::PlantOptions) -> ExitCode {
    let stop = stop_flag();
    match runner::hil::plant(cfg, prefix, options, &stop) {
        Ok(r) if r.faults != 0 => {
            eprintln!(
                "servo plant: FAULT — controller lost at tick {} (no command for {:?}); drove zero current for {} ticks and ended the run",
                r.fault_tick.unwrap_or(0),
                r.peer_timeout,
                r.ticks - r.fault_tick.unwrap_or(0)
            );
            ExitCode::from(EXIT_FAULT)
        }
        Ok(_) => ExitCode::SUCCESS,
        Err(e) => done(Err(e)),
    }
}

/// `servo controller`.
pub fn controller(cfg: &Loaded, prefix: &str) -> ExitCode {
    let stop = stop_flag();
    match runner::hil::controller(cfg, prefix, &stop) {
        Ok(_) => ExitCode::SUCCESS,
        Err(e) => done(Err(e)),
    }
}

/// `servo record`.
pub fn record(cfg: &Loaded, prefix: &str, rec: &Recording, realtime: bool) -> ExitCode {
    let out = rec.out();
    // The recorder finishes the file whatever happens: Ctrl-C reaches the plant, which ends
    // the run; the recorder sees the end (or the silence) and closes the file.
    let _stop = stop_flag();
    let bar = progress_bar(rec.quiet, "recording");
    let mut progress = |done: u64, total: u64| {
        bar.set_length(total);
        bar.set_position(done);
    };
    let result = runner::hil::record(cfg, prefix, out.clone(), realtime, &mut progress);
    bar.finish_and_clear();
    match result {
        Ok(s) => {
            print_summary(&s, rec.json);
            if let (Some(p), false) = (out, rec.json) {
                println!("  wrote {}", p.display());
            }
            ExitCode::SUCCESS
        }
        Err(e) => done(Err(e)),
    }
}

/// `servo ctl`: one control-plane message to a running run.
pub fn ctl(prefix: &str, message: Control) -> ExitCode {
    let sent = Endpoint::open(prefix, &format!("ctl-{}", std::process::id())).and_then(|ep| {
        let sender = ControlSender::new(&ep)?;
        sender.send(message)?;
        // Samples of a publisher that is gone cannot be received: stay until the plant and
        // controller have polled (every 2048 ticks: ≈ 10 ms in real time, longer in a lockstep
        // run on a loaded machine).
        std::thread::sleep(Duration::from_secs(1));
        Ok(())
    });
    match sent {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => fail(e, 1),
    }
}

/// Writes `cfg` resolved (controller file made absolute) for the child processes.
fn write_resolved(cfg: &Loaded, dir: &Path) -> Result<PathBuf, RunError> {
    let mut c = cfg.config.clone();
    if let Some(p) = &c.controller.ss_file {
        c.controller.ss_file = Some(std::fs::canonicalize(p).unwrap_or(p.clone()));
    }
    let path = dir.join("config.toml");
    std::fs::create_dir_all(dir)
        .and_then(|_| std::fs::write(&path, c.to_toml()))
        .map_err(|e| RunError::Transport(format!("cannot write {}: {e}", path.display())))?;
    Ok(path)
}

fn spawn(args: &[&str], stdout: Stdio) -> Result<Child, RunError> {
    let exe = std::env::current_exe()
        .map_err(|e| RunError::Transport(format!("cannot find the servo binary: {e}")))?;
    std::process::Command::new(exe)
        .args(args)
        .stdout(stdout)
        .stdin(Stdio::null())
        .spawn()
        .map_err(|e| RunError::Transport(format!("cannot start `servo {}`: {e}", args[0])))
}

/// `servo run --hil`: checks the loop, starts recorder, controller and plant as processes,
/// shows the plant's progress, and returns the recorder's summary with the children's exits.
pub fn run(
    cfg: &Loaded,
    prefix: Option<String>,
    realtime: bool,
    peer_timeout_ms: Option<f64>,
    out: Option<PathBuf>,
    quiet: bool,
) -> Result<(Summary, Vec<(String, i32)>), RunError> {
    runner::run::check_stable(cfg)?;
    let prefix = prefix.unwrap_or_else(|| format!("run-{}", std::process::id()));
    daq_io::ipc::check_prefix(&prefix).map_err(RunError::Transport)?;
    let dir = std::env::temp_dir().join(format!("fts-servo-{prefix}"));
    let config = write_resolved(cfg, &dir)?;
    let config = config.to_str().expect("temp paths are UTF-8");
    let mode = if realtime { "--realtime" } else { "--lockstep" };
    let out_arg = out.as_ref().map(|p| p.display().to_string());
    let mut record_args = vec![
        "record", "--config", config, "--prefix", &prefix, "--json", "--quiet", mode,
    ];
    match &out_arg {
        Some(o) => record_args.extend(["--out", o]),
        None => record_args.push("--no-record"),
    }
    // Subscribe before the children start: a subscriber joining mid-run makes the publishers
    // set up a connection inside a send, a sub-millisecond stall a real-time loop would feel.
    let ep = Endpoint::open(&prefix, "run").map_err(|e| RunError::Transport(e.to_string()))?;
    let health = ep
        .subscriber::<Health>(leaf::HEALTH)
        .map_err(|e| RunError::Transport(e.to_string()))?;
    let stop = stop_flag();
    let recorder = spawn(&record_args, Stdio::piped())?;
    let controller = spawn(
        &["controller", "--config", config, "--prefix", &prefix],
        Stdio::inherit(),
    )?;
    let timeout = peer_timeout_ms.map(|t| t.to_string());
    let mut plant_args = vec!["plant", "--config", config, "--prefix", &prefix, mode];
    if let Some(t) = &timeout {
        plant_args.extend(["--peer-timeout-ms", t]);
    }
    let plant = spawn(&plant_args, Stdio::inherit())?;
    let mut children = [
        ("plant", plant),
        ("controller", controller),
        ("record", recorder),
    ];

    let bar = progress_bar(quiet, if realtime { "real time" } else { "lockstep" });
    let total = cfg.config.ticks();
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
        // Ctrl-C reaches every child; if one hangs afterwards, end it.
        if stop.load(Ordering::Relaxed) && stopped_at.is_none() {
            stopped_at = Some(Instant::now());
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
    let _ = std::fs::remove_dir_all(&dir);
    let summary: Summary = serde_json::from_str(&text).map_err(|_| {
        RunError::Transport(format!(
            "the recorder gave no summary (exit codes: {})",
            codes
                .iter()
                .map(|(n, c)| format!("{n} {c}"))
                .collect::<Vec<_>>()
                .join(", ")
        ))
    })?;
    Ok((summary, codes))
}
