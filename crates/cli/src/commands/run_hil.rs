//! `servo run --hil`: the plant, controller and recorder as three processes over iceoryx2
//! ([`runner::hil::supervise`]), with a progress bar, after the real-time preflight.

use crate::args::{HilArgs, PeerTimeoutArgs, RecordingArgs};
use crate::interrupt::stop_on_signals;
use crate::output::{tick_bar, CliError};
use run_config::Origin;
use runner::hil::{supervise, Supervision};
use runner::stall::{preflight, HostCheck};
use runner::summary::Summary;
use runner::{Plan, RunError};
use std::process::ExitCode;

/// `servo run --hil`: checks the host (real time), runs the three processes, and returns the
/// recorder's summary and the run's exit code ([`runner::hil::Supervised::exit_code`]).
pub fn run(
    plan: &Plan,
    hil: &HilArgs,
    timeout: &PeerTimeoutArgs,
    rec: &RecordingArgs,
    out: Option<runner::recording::Target>,
    host: &HostCheck,
) -> Result<(Summary, ExitCode), CliError> {
    let peer_timeout = timeout.timeout()?;
    if hil.realtime {
        let timeout_s =
            peer_timeout.map_or(plan.config.realtime.peer_timeout_s, |t| t.as_secs_f64());
        preflight(plan, timeout_s, host, &mut |line| eprintln!("{line}"))?;
    }
    if let Some(prefix) = &hil.prefix {
        daq_io::ipc::check_prefix(prefix)
            .map_err(|e| Origin::default().invalid("--prefix", prefix, &e))?;
    }
    let servo = std::env::current_exe()
        .map_err(|e| CliError::Processes(format!("cannot find the servo binary: {e}")))?;
    let supervision = Supervision {
        servo,
        prefix: hil.prefix.clone(),
        realtime: hil.realtime,
        peer_timeout_ms: timeout.peer_timeout_ms,
        out,
    };
    let stop = stop_on_signals();
    let bar = tick_bar(
        rec.quiet,
        if hil.realtime {
            "real time"
        } else {
            "lockstep"
        },
    );
    let run = supervise(plan, &supervision, &stop, &mut |ticks, total| {
        bar.set_length(total);
        bar.set_position(ticks);
    });
    bar.finish_and_clear();
    let run = run.map_err(|e| match e {
        RunError::ChildFailed(f) => CliError::Child {
            name: f.process,
            code: f.code,
        },
        e => e.into(),
    })?;
    if let Some(f) = &run.failed {
        eprintln!("servo {} exited with {}", f.process, f.code);
    }
    let code = u8::try_from(run.exit_code()).unwrap_or(crate::output::FAILED);
    Ok((run.summary, ExitCode::from(code)))
}
