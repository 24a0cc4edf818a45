//! `servo ctl`: the control plane of a running HIL run. Every command is acknowledged by the
//! process that acts on it (the plant for start/stop, the controller for gain changes and
//! controller loads, which it checks against the running loop's stability first); `ctl`
//! prints what the run did, or fails.

use crate::output::CliError;
use clap::{Args, Subcommand};
use daq_io::control_client::{
    gain_outcome, load_outcome, plant_outcome, request as request_ack, Request,
};
use daq_io::ipc::Endpoint;
use daq_io::MAX_LOAD_BYTES;
use runner::RunError;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

/// HIL control plane: start, stop, scale gains or load a controller in a running loop
///
/// Starts a waiting plant, stops a run, scales the controller's gains, or loads another
/// controller into the running loop; prints the run's acknowledgement.
///
/// Exit 0 when the run applied the command; 1 when it refused it (a gain outside the loop's
/// stable range less a 6 dB margin, or not a number; a controller made for another plant or
/// rate, unstable on the run's model, or not a controller), when no run holds the prefix (at
/// once), or when no acknowledgement came within --timeout-s.
/// Example: servo ctl --prefix bench gain 1.2; servo ctl --prefix bench load pid.toml
#[derive(Args, Debug)]
pub struct CtlCmd {
    /// Run prefix.
    #[arg(long)]
    prefix: String,
    /// How long to wait for the acknowledgement, in s (0, 60] (the plant and controller read
    /// the control plane every 2048 ticks: 10 ms in real time).
    #[arg(value_parser = crate::args::finite, long, default_value_t = 5.0)]
    timeout_s: f64,
    /// What to send.
    #[command(subcommand)]
    action: CtlAction,
}

/// `servo ctl` messages.
#[derive(Subcommand, Debug, Clone)]
enum CtlAction {
    /// Start a plant waiting for it (`servo plant --wait-start`).
    Start,
    /// End the run at the next tick boundary (the recording is finished normally).
    Stop,
    /// Multiply the controller output (all gains) by SCALE, keeping a 6 dB gain margin
    ///
    /// Refused unless the loop keeps a 6 dB gain margin at SCALE (the reply names the allowed
    /// range).
    Gain {
        /// Scale factor (dimensionless).
        scale: f64,
    },
    /// Swap the controller at a tick boundary, bumplessly
    ///
    /// The file is a state-space file (`servo synth`)
    /// or a config fragment with a [controller] table (`servo tune`'s pid.toml), at most
    /// 64 KiB; refused when made for another plant or rate, or unstable on the run's model.
    Load {
        /// The controller file.
        file: PathBuf,
    },
}

impl CtlCmd {
    /// Sends one control-plane message to the running run and reports its acknowledgement.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        if !(self.timeout_s > 0.0 && self.timeout_s <= 60.0) {
            return Err(run_config::Origin::default()
                .invalid("--timeout-s", self.timeout_s, "(0, 60] s")
                .into());
        }
        // A file to load is read (and checked: a regular file of bounded size) before the run
        // is looked for, so bad input fails at once whatever the run does.
        let request = match &self.action {
            CtlAction::Start => Request::Start,
            CtlAction::Stop => Request::Stop,
            CtlAction::Gain { scale } => Request::Gain(*scale),
            CtlAction::Load { file } => Request::Load(read_load(file)?),
        };
        let prefix = &self.prefix;
        let ep = Endpoint::open(prefix, &format!("ctl-{}", std::process::id()))
            .map_err(RunError::from)?;
        let timeout = Duration::from_secs_f64(self.timeout_s);
        let ack = request_ack(&ep, prefix, &request, timeout)
            .map_err(|e| CliError::Processes(e.to_string()))?;
        let outcome = match (&self.action, &request) {
            (CtlAction::Gain { scale }, _) => gain_outcome(*scale, &ack),
            (CtlAction::Load { file }, _) => load_outcome(
                &file.display().to_string(),
                &ack,
                &run_config::describe_made_for(file).unwrap_or_else(|| "its made_for".into()),
            ),
            (_, r) => Ok(plant_outcome(r, &ack)),
        };
        match outcome {
            Ok(line) => {
                println!("{line}");
                Ok(ExitCode::SUCCESS)
            }
            Err(why) => Err(CliError::Processes(why)),
        }
    }
}

/// The controller file at `path`: a regular file of at most [`MAX_LOAD_BYTES`].
fn read_load(path: &std::path::Path) -> Result<Vec<u8>, CliError> {
    Ok(run_config::input_file::read_input(
        path,
        MAX_LOAD_BYTES as u64,
    )?)
}
