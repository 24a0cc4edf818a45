//! `servo ctl`: the control plane of a running HIL run. Every command is acknowledged by the
//! process that acts on it (the plant for start/stop, the controller for gain changes, which
//! it checks against the running loop's stability margins first); `ctl` prints what the run
//! did, or fails.

use crate::output::CliError;
use clap::{Args, Subcommand};
use daq_io::contract::{ack_status, command};
use daq_io::ipc::{leaf, take, ControlSender, Endpoint};
use daq_io::{Ack, Control};
use runner::RunError;
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// HIL control plane: start a waiting plant, stop a run, or scale the controller's gains;
/// prints the run's acknowledgement.
///
/// Exit 0 when the run applied the command; 1 when it refused it (a gain outside the loop's
/// stable range less a 6 dB margin, or not a number), when no run holds the prefix (at once),
/// or when no acknowledgement came within --timeout-s.
/// Example: servo ctl --prefix bench gain 1.2
#[derive(Args, Debug)]
pub struct CtlCmd {
    /// Run prefix.
    #[arg(long)]
    prefix: String,
    /// How long to wait for the acknowledgement, in s (0, 60] (the plant and controller read
    /// the control plane every 2048 ticks: 10 ms in real time).
    #[arg(long, default_value_t = 5.0)]
    timeout_s: f64,
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
    /// Multiply the controller output (all gains) by SCALE; refused unless the loop keeps a
    /// 6 dB gain margin at it (the reply names the allowed range).
    Gain {
        /// Scale factor (dimensionless).
        scale: f64,
    },
}

impl CtlAction {
    /// The control-plane message with request id `id`.
    fn message(self, id: u64) -> Control {
        let (command, value) = match self {
            CtlAction::Start => (command::START, 0.0),
            CtlAction::Stop => (command::STOP, 0.0),
            CtlAction::Gain { scale } => (command::SET_GAIN_SCALE, scale),
        };
        Control {
            command,
            value,
            id,
            ..Default::default()
        }
    }

    /// The process that acts on it.
    fn target(self) -> &'static str {
        match self {
            CtlAction::Start | CtlAction::Stop => "plant",
            CtlAction::Gain { .. } => "controller",
        }
    }

    /// What the run did, as one line.
    fn report(self, a: &Ack) -> Result<String, String> {
        match (self, a.status) {
            (CtlAction::Gain { scale }, ack_status::APPLIED) => Ok(format!(
                "gain ×{scale} applied from tick {} (allowed ×{:.3}–×{:.3}: the loop goes unstable above ×{:.3}, {:.1} dB of gain margin at ×1)",
                a.tick,
                a.low,
                a.high,
                a.unstable_at,
                20.0 * a.unstable_at.log10()
            )),
            (CtlAction::Gain { scale }, ack_status::REFUSED_MARGIN) => Err(format!(
                "gain ×{scale} refused: the loop goes unstable above ×{:.3} (gain margin {:.1} dB at ×1); changes keep a 6 dB margin: allowed ×{:.3}–×{:.3}",
                a.unstable_at,
                20.0 * a.unstable_at.log10(),
                a.low,
                a.high
            )),
            (CtlAction::Gain { scale }, _) => {
                Err(format!("gain ×{scale} refused: not a finite number"))
            }
            (CtlAction::Stop, _) => Ok(format!("stop applied: the run ends at tick {}", a.tick)),
            (CtlAction::Start, _) => Ok("start applied: the plant runs".into()),
        }
    }
}

impl CtlCmd {
    /// Sends one control-plane message to the running run and reports its acknowledgement.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        if !(self.timeout_s > 0.0 && self.timeout_s <= 60.0) {
            return Err(runner::config::Origin::default()
                .invalid("--timeout-s", self.timeout_s, "(0, 60] s")
                .into());
        }
        let prefix = &self.prefix;
        let ep = Endpoint::open(prefix, &format!("ctl-{}", std::process::id()))
            .map_err(RunError::from)?;
        let target = self.action.target();
        if !ep.peers().iter().any(|p| p.role == target) {
            return Err(CliError::Processes(format!(
                "no run on prefix {prefix:?}: no live {target} (start one with `servo run --hil --prefix {prefix}`)"
            )));
        }
        let acks = ep.subscriber::<Ack>(leaf::ACK).map_err(RunError::from)?;
        let sender = ControlSender::new(&ep).map_err(RunError::from)?;
        let id = daq_io::peers::random_id();
        sender
            .send(self.action.message(id))
            .map_err(RunError::from)?;
        let start = Instant::now();
        let timeout = Duration::from_secs_f64(self.timeout_s);
        while start.elapsed() < timeout {
            while let Some(a) = take(&acks) {
                if a.id == id {
                    return match self.action.report(&a) {
                        Ok(line) => {
                            println!("{line}");
                            Ok(ExitCode::SUCCESS)
                        }
                        Err(why) => Err(CliError::Processes(why)),
                    };
                }
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        Err(CliError::Processes(format!(
            "no acknowledgement from the {target} of run {prefix:?} within {} s (is it still running?)",
            self.timeout_s
        )))
    }
}
