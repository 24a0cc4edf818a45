//! SIGINT, SIGTERM and SIGHUP as a stop request the loop polls, so a run ends at a tick
//! boundary with its recording finished and the signal named as its end reason. A second
//! SIGINT (Ctrl-C pressed again) ends the process at once, leaving the recording unfinished
//! (`<name>.<pid>.partial`, recoverable by `servo inspect`).

use nix::sys::signal::Signal;
use runner::hil::PARENT_ENV;
use runner::stop::StopRequest;
use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
use signal_hook::flag;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// The stop request raised by SIGINT, SIGTERM or SIGHUP (it holds the signal's number).
pub fn stop_on_signals() -> StopRequest {
    let stop = StopRequest::new();
    let cell = stop.shared();
    // A second SIGINT ends the process at once — except in a HIL child of `servo run --hil`,
    // which can get two from one Ctrl-C (the terminal's and the one its parent forwards): its
    // parent handles the second, and the child follows its parent (`follow_parent`).
    if std::env::var_os(PARENT_ENV).is_none() {
        // In this order: the shutdown checks whether an earlier SIGINT armed it, then arms it.
        let armed = Arc::new(AtomicBool::new(false));
        let _ = flag::register_conditional_shutdown(SIGINT, 128 + SIGINT, armed.clone());
        let _ = flag::register(SIGINT, armed);
    }
    for signal in [SIGINT, SIGTERM, SIGHUP] {
        let _ = flag::register_usize(signal, cell.clone(), signal as usize);
    }
    stop
}

/// The exit code of a run that ended under `stop`: the stop's (0, 128 + signal), or 5 when
/// machine protection `tripped` the loop (see [`runner::stop::EndReason::exit_code`]).
pub fn exit_code(stop: &StopRequest, tripped: bool) -> std::process::ExitCode {
    std::process::ExitCode::from(stop.reason().after_trip(tripped).exit_code())
}

/// A file size limit (`ulimit -f`, RLIMIT_FSIZE) reached makes the write fail with EFBIG like
/// any other write error — a run then ends as for a full disk (its recording finished with the
/// part that fit, exit 4) — instead of SIGXFSZ killing the process (exit 153, the recording
/// left unfinished, nothing said): the signal is caught and does nothing.
pub fn write_limits_as_errors() {
    let _ = flag::register(
        signal_hook::consts::SIGXFSZ,
        Arc::new(AtomicBool::new(false)),
    );
}

/// A HIL child started by `servo run --hil` asks the kernel for SIGTERM when its parent dies
/// (so it never outlives it), and exits now if the parent is already gone.
pub fn follow_parent() {
    let Some(parent) = std::env::var(PARENT_ENV)
        .ok()
        .and_then(|p| p.parse::<i32>().ok())
    else {
        return;
    };
    let _ = nix::sys::prctl::set_pdeathsig(Signal::SIGTERM);
    if nix::unistd::getppid().as_raw() != parent {
        eprintln!("servo: the `servo run --hil` that started this process is gone; exiting");
        std::process::exit(1);
    }
}
