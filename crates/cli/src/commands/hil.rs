//! The HIL processes: `servo plant`, `servo controller`, `servo record` (`servo ctl`, the
//! control plane of a running run, is in [`super::ctl`]).

use crate::args::{HilArgs, PeerTimeoutArgs, RecordingArgs, RunArgs, DEFAULT_RECORDING};
use crate::interrupt::stop_on_signals;
use crate::output::{print_summary, tick_bar, CliError};
use clap::Args;
use runner::Plan;
use std::process::ExitCode;

/// Exit code of a plant that lost its controller (it drove zero current and ended the run).
pub const EXIT_FAULT: u8 = 3;

/// HIL: serve the simulated stage to a controller process.
///
/// Lockstep or real time. A lost controller (no command for 200 ms lockstep / 0.5 ms real
/// time), or one late more often than the overrun budget allows → zero current, exit 3.
/// Example: servo plant --prefix bench --realtime
#[derive(Args, Debug)]
pub struct PlantCmd {
    #[command(flatten)]
    run: RunArgs,
    #[command(flatten)]
    hil: HilArgs,
    #[command(flatten)]
    timeout: PeerTimeoutArgs,
    /// Start without waiting for `servo record`.
    #[arg(long)]
    no_recorder: bool,
    /// After the peers are there, wait for `servo ctl start`.
    #[arg(long)]
    wait_start: bool,
}

impl PlantCmd {
    /// Serves until the run ends; exit 3 when the controller was lost.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let plan = Plan::new(&self.hil.load(&self.run)?)?;
        let prefix = self.hil.prefix()?;
        let options = runner::hil::PlantOptions {
            pacing: self.hil.pacing(),
            wait_for_recorder: !self.no_recorder,
            wait_for_start: self.wait_start,
            peer_timeout: self.timeout.timeout()?,
        };
        let stop = stop_on_signals();
        let r = runner::hil::plant(&plan, &prefix, &options, &stop)?;
        if r.faults == 0 {
            return Ok(ExitCode::from(stop.reason().exit_code()));
        }
        let why = if r.faults & daq_io::flags::FAULT_OVERRUN_BUDGET != 0 {
            format!(
                "overrun budget exceeded ({} overruns; [realtime] overrun_rate {}, overrun_burst_s {})",
                r.overruns, plan.config.realtime.overrun_rate, plan.config.realtime.overrun_burst_s
            )
        } else {
            format!("controller lost (no command for {:?})", r.peer_timeout)
        };
        eprintln!(
            "servo plant: FAULT — {why} at tick {}; drove zero current for {} ticks and ended the run",
            r.fault_tick.unwrap_or(0),
            r.ticks - r.fault_tick.unwrap_or(0)
        );
        Ok(ExitCode::from(EXIT_FAULT))
    }
}

/// HIL: run the controller against a plant process (simulator or DAQ daemon).
///
/// Example: servo controller --prefix bench --mass heavy
#[derive(Args, Debug)]
pub struct ControllerCmd {
    #[command(flatten)]
    run: RunArgs,
    #[command(flatten)]
    hil: HilArgs,
}

impl ControllerCmd {
    /// Runs until the plant closes the run.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let plan = Plan::new(&self.hil.load(&self.run)?)?;
        let stop = stop_on_signals();
        let end = runner::hil::controller(&plan, &self.hil.prefix()?, &stop)?;
        if let Some((cause, tick)) = end.trip {
            eprintln!(
                "servo controller: TRIPPED — {} at tick {}; held the safe state ({}) and ended the run",
                cause.name(),
                tick,
                plan.config.protection.safe_state.name()
            );
        }
        Ok(crate::interrupt::exit_code(&stop, end.trip.is_some()))
    }
}

/// HIL: record a run's telemetry and truth to MCAP and print its summary.
///
/// Example: servo record --prefix bench --out bench.mcap
#[derive(Args, Debug)]
pub struct RecordCmd {
    #[command(flatten)]
    run: RunArgs,
    #[command(flatten)]
    hil: HilArgs,
    #[command(flatten)]
    recording: RecordingArgs,
}

impl RecordCmd {
    /// Records until the run ends and prints its summary.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let plan = Plan::new(&self.hil.load(&self.run)?)?;
        let prefix = self.hil.prefix()?;
        let rec = &self.recording;
        let out = rec.out(DEFAULT_RECORDING.as_ref());
        // The recorder finishes the file whatever happens: a signal to it asks the plant to
        // end the run (so does one to the plant or the controller); the recorder sees the end
        // (or the silence) and closes the file.
        let stop = stop_on_signals();
        let bar = tick_bar(rec.quiet, "recording");
        let mut progress = |done: u64, total: u64| {
            bar.set_length(total);
            bar.set_position(done);
        };
        let result = runner::hil::record(
            &plan,
            &prefix,
            out.clone(),
            self.hil.realtime,
            &stop,
            &mut progress,
        );
        bar.finish_and_clear();
        let summary = result?;
        print_summary(&summary, rec.json);
        if let (Some(p), false) = (out, rec.json) {
            println!("  wrote {}", p.written());
        }
        // Its own signal is how this process ends (128 + it); the run's end otherwise.
        Ok(crate::interrupt::exit_code(&stop, summary.trip.is_some()))
    }
}
