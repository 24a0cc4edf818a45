//! The HIL processes: `servo plant`, `servo controller`, `servo record`, and `servo ctl`, the
//! control plane of a running run.

use crate::args::{HilArgs, PeerTimeoutArgs, RecordingArgs, RunArgs, DEFAULT_RECORDING};
use crate::interrupt::stop_on_signals;
use crate::output::{print_summary, tick_bar, CliError};
use clap::{Args, Subcommand};
use daq_io::contract::command;
use daq_io::ipc::{ControlSender, Endpoint};
use daq_io::Control;
use runner::{Plan, RunError};
use std::process::ExitCode;
use std::time::Duration;

/// Exit code of a plant that lost its controller (it drove zero current and ended the run).
pub const EXIT_FAULT: u8 = 3;

/// HIL: serve the simulated stage to a controller process.
///
/// Lockstep or real time. A lost controller (no command for 200 ms lockstep / 0.5 ms real
/// time) → zero current, exit 3.
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
        let plan = Plan::new(&self.run.load()?)?;
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
        eprintln!(
            "servo plant: FAULT — controller lost at tick {} (no command for {:?}); drove zero current for {} ticks and ended the run",
            r.fault_tick.unwrap_or(0),
            r.peer_timeout,
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
        let plan = Plan::new(&self.run.load()?)?;
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
        Ok(ExitCode::from(
            stop.reason().after_trip(end.trip.is_some()).exit_code(),
        ))
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
        let plan = Plan::new(&self.run.load()?)?;
        let prefix = self.hil.prefix()?;
        let rec = &self.recording;
        let out = rec.out(DEFAULT_RECORDING.as_ref());
        // The recorder finishes the file whatever happens: a signal reaches the plant, which
        // ends the run; the recorder sees the end (or the silence) and closes the file.
        let _stop = stop_on_signals();
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
            &mut progress,
        );
        bar.finish_and_clear();
        let summary = result?;
        print_summary(&summary, rec.json);
        if let (Some(p), false) = (out, rec.json) {
            println!("  wrote {}", p.path.display());
        }
        let reason = runner::stop::EndReason::Completed.after_trip(summary.trip.is_some());
        Ok(ExitCode::from(reason.exit_code()))
    }
}

/// HIL control plane: start a waiting plant, stop a run, or scale the controller's gains.
///
/// Example: servo ctl --prefix bench gain 1.2
#[derive(Args, Debug)]
pub struct CtlCmd {
    /// Run prefix.
    #[arg(long)]
    prefix: String,
    /// What to send.
    #[command(subcommand)]
    action: CtlAction,
}

/// `servo ctl` messages.
#[derive(Subcommand, Debug, Clone, Copy)]
enum CtlAction {
    /// Start a plant waiting for it (`servo plant --wait-start`).
    Start,
    /// End the run at the next tick boundary (the recording is finished normally).
    Stop,
    /// Multiply the controller output (all gains) by SCALE (0.1..=10).
    Gain {
        /// Scale factor.
        scale: f64,
    },
}

impl CtlAction {
    /// The control-plane message.
    fn message(self) -> Control {
        let (command, value) = match self {
            CtlAction::Start => (command::START, 0.0),
            CtlAction::Stop => (command::STOP, 0.0),
            CtlAction::Gain { scale } => (command::SET_GAIN_SCALE, scale),
        };
        Control {
            command,
            value,
            ..Default::default()
        }
    }
}

impl CtlCmd {
    /// Sends one control-plane message to the running run.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let ep = Endpoint::open(&self.prefix, &format!("ctl-{}", std::process::id()))
            .map_err(RunError::from)?;
        let sender = ControlSender::new(&ep).map_err(RunError::from)?;
        sender.send(self.action.message()).map_err(RunError::from)?;
        // Samples of a publisher that is gone cannot be received: stay until the plant and
        // controller have polled (every 2048 ticks: ≈ 10 ms in real time, longer in a
        // lockstep run on a loaded machine).
        std::thread::sleep(Duration::from_secs(1));
        Ok(ExitCode::SUCCESS)
    }
}
