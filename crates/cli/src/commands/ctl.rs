//! `servo ctl`: the control plane of a running HIL run. Every command is acknowledged by the
//! process that acts on it (the plant for start/stop, the controller for gain changes and
//! controller loads, which it checks against the running loop's stability first); `ctl`
//! prints what the run did, or fails.

use crate::output::CliError;
use clap::{Args, Subcommand};
use daq_io::contract::{ack_status, command};
use daq_io::ipc::{leaf, take, ControlSender, Endpoint};
use daq_io::{Ack, Control, ControllerLoad, MAX_LOAD_BYTES};
use runner::RunError;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

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

impl CtlAction {
    /// The control-plane message with request id `id`, or the file of a load (sent on its
    /// own service).
    fn message(&self, id: u64) -> Result<Control, &std::path::Path> {
        let (command, value) = match self {
            CtlAction::Start => (command::START, 0.0),
            CtlAction::Stop => (command::STOP, 0.0),
            CtlAction::Gain { scale } => (command::SET_GAIN_SCALE, *scale),
            CtlAction::Load { file } => return Err(file),
        };
        Ok(Control {
            command,
            value,
            id,
            ..Default::default()
        })
    }

    /// The process that acts on it.
    fn target(&self) -> &'static str {
        match self {
            CtlAction::Start | CtlAction::Stop => "plant",
            CtlAction::Gain { .. } | CtlAction::Load { .. } => "controller",
        }
    }

    /// What the run did, as one line.
    fn report(&self, a: &Ack) -> Result<String, String> {
        match (self, a.status) {
            (CtlAction::Load { file }, status) => load_report(file, a, status),
            (CtlAction::Gain { scale }, ack_status::APPLIED) => Ok(format!(
                "gain ×{scale} applied from tick {} (allowed ×{:.3}–×{:.3}: the loop goes unstable above ×{:.3}, {:.1} dB of gain margin at ×1)",
                a.tick,
                a.low,
                a.high,
                a.unstable_at,
                20.0 * libm::log10(a.unstable_at)
            )),
            (CtlAction::Gain { scale }, ack_status::REFUSED_MARGIN) => Err(format!(
                "gain ×{scale} refused: the loop goes unstable above ×{:.3} (gain margin {:.1} dB at ×1); changes keep a 6 dB margin: allowed ×{:.3}–×{:.3}",
                a.unstable_at,
                20.0 * libm::log10(a.unstable_at),
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
        let id = daq_io::peers::random_id();
        // A file to load is read (and checked: a regular file of bounded size) before the run
        // is looked for, so bad input fails at once whatever the run does.
        let load = match &self.action {
            CtlAction::Load { file } => Some(read_load(file, id)?),
            _ => None,
        };
        let prefix = &self.prefix;
        let ep = Endpoint::open(prefix, &format!("ctl-{}", std::process::id()))
            .map_err(RunError::from)?;
        let target = self.action.target();
        let start = Instant::now();
        let timeout = Duration::from_secs_f64(self.timeout_s);
        // No process on the prefix: no run, say so at once. Others of the run there but not
        // yet the target (a run whose processes are still starting): wait for it as long as
        // for the answer.
        loop {
            let peers = ep.peers();
            if peers.iter().any(|p| p.role == target) {
                break;
            }
            if peers.is_empty() || start.elapsed() >= timeout {
                return Err(CliError::Processes(format!(
                    "no run on prefix {prefix:?}: no live {target} (start one with `servo run --hil --prefix {prefix}`)"
                )));
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let acks = ep.subscriber::<Ack>(leaf::ACK).map_err(RunError::from)?;
        // Sent once the run listens (a process that has just started may not yet: a message
        // before any subscriber is lost), by a publisher that lives until the answer came
        // (iceoryx2 takes a sample back from the subscribers when its publisher goes).
        let listening = |heard: Result<bool, _>, leaf: &str| {
            if heard.map_err(RunError::from)? {
                Ok(())
            } else {
                Err(CliError::Processes(format!(
                    "the {target} of run {prefix:?} does not listen on {leaf} (still starting?)"
                )))
            }
        };
        let (_load, _control) = match (self.action.message(id), load) {
            (Err(_), Some(load)) => {
                listening(
                    ep.await_subscriber::<ControllerLoad>(leaf::CONTROLLER_LOAD, timeout),
                    leaf::CONTROLLER_LOAD,
                )?;
                let publisher = ep
                    .publisher::<ControllerLoad>(leaf::CONTROLLER_LOAD)
                    .map_err(RunError::from)?;
                if !daq_io::ipc::send(&publisher, load) {
                    return Err(CliError::Processes(
                        "the transport refused the controller load".into(),
                    ));
                }
                (Some(publisher), None)
            }
            (Err(_), None) => unreachable!("a load's file is read above"),
            (Ok(message), _) => {
                listening(
                    ep.await_subscriber::<Control>(leaf::CONTROL, timeout),
                    leaf::CONTROL,
                )?;
                let sender = ControlSender::new(&ep).map_err(RunError::from)?;
                sender.send(message).map_err(RunError::from)?;
                (None, Some(sender))
            }
        };
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

/// The load request `id` of controller file `path` (at most [`MAX_LOAD_BYTES`]).
fn read_load(path: &std::path::Path, id: u64) -> Result<ControllerLoad, CliError> {
    let bytes = runner::config::input_file::read_input(path, MAX_LOAD_BYTES as u64)?;
    ControllerLoad::new(id, &bytes).ok_or_else(|| {
        runner::config::Origin::default()
            .invalid(
                "load FILE",
                path.display(),
                &format!("at most {MAX_LOAD_BYTES} bytes"),
            )
            .into()
    })
}

/// What the run did with controller `file` (acknowledged with `status`), as one line.
fn load_report(file: &std::path::Path, a: &Ack, status: u32) -> Result<String, String> {
    let name = file.display();
    match status {
        ack_status::APPLIED => Ok(format!(
            "controller {name} took the loop at tick {}, bumplessly (the old output fades over 5 ms); closed-loop spectral radius {:.6}; gain scale now allowed ×{:.3}–×{:.3}",
            a.tick, a.value, a.low, a.high
        )),
        ack_status::REFUSED_PROVENANCE => Err(format!(
            "controller {name} refused: made for another plant or rate than the run's ({}); the controller process names both",
            runner::config::describe_made_for(file).unwrap_or_else(|| "its made_for".into())
        )),
        ack_status::REFUSED_MARGIN if a.value >= 1.0 => Err(format!(
            "controller {name} refused: the closed loop on the run's model would be unstable (spectral radius {:.6} ≥ 1); the running controller stays",
            a.value
        )),
        ack_status::REFUSED_MARGIN => Err(format!(
            "controller {name} refused: stable at gain ×1 but not at the run's present gain scale; reset it (`servo ctl gain 1`) and load again"
        )),
        _ => Err(format!(
            "controller {name} refused: not a controller this run can build, a change of feedforward (a load swaps the feedback controller only), or another load is in progress (the controller process says which)"
        )),
    }
}
