//! `servo run`: the closed loop in process, or (`--hil`) as three processes.

use crate::args::{HilArgs, PeerTimeoutArgs, RecordingArgs, RunArgs, DEFAULT_RECORDING};
use crate::interrupt::stop_on_signals;
use crate::output::{print_summary, tick_bar, CliError};
use clap::Args;
use runner::pil::PilOptions;
use runner::run::{run, run_on_target, RunOptions};
use runner::stop::{EndReason, StopRequest};
use runner::{Plan, RunError};
use std::path::PathBuf;
use std::process::ExitCode;

/// Run the closed loop against the simulated stage and record it to MCAP.
///
/// With no options: the thesis stage, the Chapter 7 PID at 199.6 kHz, sensor and current
/// noise and base vibration on, holding position for 1 s, recorded to ./run.mcap.
/// Example: servo run --mass heavy --scenario sine --amplitude 2e-6 --frequency 200
#[derive(Args, Debug)]
pub struct Run {
    #[command(flatten)]
    run: RunArgs,
    #[command(flatten)]
    recording: RecordingArgs,
    /// Run plant, controller and recorder as three processes over iceoryx2 shared memory
    /// (`servo plant`, `servo controller`, `servo record`); same summary.
    #[arg(long)]
    hil: bool,
    #[command(flatten)]
    hil_args: HilArgs,
    #[command(flatten)]
    timeout: PeerTimeoutArgs,
    /// Print the loop's digest (FNV-1a over each tick's seq, gap and accelerometer readings and
    /// command): what a C, C++ or Python loop of the same deployment and stage prints.
    #[arg(long, conflicts_with = "hil")]
    digest: bool,
    /// Processor in the loop: the controller runs in this firmware (the ARM ELF built in
    /// firmware/) on a Cortex-M7 under qemu-system-arm, the stage here, one sample and one
    /// command per tick over the semihosting console. The summary gives its cost on the target.
    #[arg(long, value_name = "FIRMWARE_ELF", conflicts_with = "hil")]
    pil: Option<PathBuf>,
    /// With --pil: the processor clock the target's cost is converted for, in Hz (default
    /// 480e6: an STM32H7).
    #[arg(long, value_name = "HZ", requires = "pil", value_parser = crate::args::positive)]
    target_clock_hz: Option<f64>,
    /// With --hil --realtime: this host's stalls from a `servo latency --json` result (this
    /// host, the run's rate, the last day) instead of a 1 s qualification at the start. A run
    /// whose loop does not survive the host's worst stall is refused (--force runs it).
    #[arg(long, value_name = "LATENCY_JSON", requires = "realtime")]
    qualification: Option<PathBuf>,
}

impl Run {
    /// Runs it; the exit code says how it ended (see [`runner::stop::EndReason::exit_code`];
    /// with `--hil`, the first failing child's).
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let plan = Plan::new(&self.hil_args.load(&self.run)?)?;
        let rec = &self.recording;
        let out = rec.out(DEFAULT_RECORDING.as_ref());
        let (summary, code) = if self.hil {
            let host = runner::stall::HostCheck {
                qualification: self.qualification.clone(),
                force: self.run.closed_loop.controller.force,
            };
            super::run_hil::run(
                &plan,
                &self.hil_args,
                &self.timeout,
                rec,
                out.clone(),
                &host,
            )?
        } else {
            let pil = self.pil.as_ref().map(|firmware| {
                let mut pil = PilOptions::new(firmware);
                pil.force = self.run.closed_loop.controller.force;
                if let Some(hz) = self.target_clock_hz {
                    pil.model.clock_hz = hz;
                }
                pil
            });
            let what = if pil.is_some() {
                "on the target"
            } else {
                "simulating"
            };
            let stop = stop_on_signals();
            let summary = with_progress(rec, out.clone(), &stop, what, |opts| {
                let opts = RunOptions {
                    digest: self.digest,
                    ..opts
                };
                match &pil {
                    Some(pil) => run_on_target(&plan, opts, pil, |_| {}),
                    None => run(&plan, opts),
                }
            })?;
            // A target lost mid-run ended the run as `peer-lost`.
            let code = match summary.meta.target.as_ref().and_then(|t| t.lost.as_ref()) {
                Some(_) => ExitCode::from(EndReason::PeerLost.exit_code()),
                None => crate::interrupt::exit_code(&stop, summary.trip.is_some()),
            };
            (summary, code)
        };
        print_summary(&summary, rec.json);
        if let (Some(o), false) = (out, rec.json) {
            println!(
                "  wrote {} (open it in Foxglove: topics /overview, /telemetry and /truth)",
                o.written()
            );
        }
        Ok(code)
    }
}

/// Runs `f` recording to `out` (as `rec` says), with `stop` and a progress bar labelled `what`.
pub fn with_progress<T, E>(
    rec: &RecordingArgs,
    out: Option<runner::recording::Target>,
    stop: &StopRequest,
    what: &str,
    f: impl FnOnce(RunOptions<'_>) -> Result<T, E>,
) -> Result<T, E>
where
    E: From<RunError>,
{
    let bar = tick_bar(rec.quiet, what);
    let mut progress = |done: u64, total: u64| {
        bar.set_length(total);
        bar.set_position(done);
    };
    let result = f(RunOptions {
        out,
        stop,
        progress: &mut progress,
        digest: false,
    });
    bar.finish_and_clear();
    result
}
