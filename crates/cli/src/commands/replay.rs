//! `servo replay`: re-run a recording from what it holds — as it was (the data channels
//! compared bit for bit) or with a replaced controller, feedforward or plant ("what would this
//! run have been with …"), the metrics side by side.

use super::run::with_progress;
use crate::args::{ControllerArgs, FeedforwardArgs, RecordingArgs};
use crate::interrupt::stop_on_signals;
use crate::output::{print_json, CliError};
use clap::Args;
use run_config::read_plant_file;
use runner::replay::{RecordedDesign, Replay, ReplayReport};
use runner::summary::Summary;
use std::path::PathBuf;
use std::process::ExitCode;

/// Default recording of the replay.
const DEFAULT_REPLAY: &str = "replay.mcap";

/// Re-run a recording from its embedded configuration, seed and input files.
///
/// Unchanged, the replay must reproduce the recorded data channels bit for bit (reported).
/// With a replaced controller (--controller-from pid.toml, --controller/--ss-file/--ka),
/// feedforward (--feedforward) or plant (--plant model.toml), it shows what the run would have
/// been: each metric recorded and replayed. A recording of a plant without simulator truth (a
/// DAQ daemon) replays only on an identified model (--plant).
/// Example: servo replay run.mcap --controller-from pid.toml --no-record
#[derive(Args, Debug)]
pub struct ReplayCmd {
    /// The MCAP file written by `servo run`, `servo machine` or `servo record`.
    file: PathBuf,
    /// Replace the controller with the [controller] table of this config file (e.g. the
    /// pid.toml `servo tune` writes; checked against what it was made for).
    #[arg(long)]
    controller_from: Option<PathBuf>,
    #[command(flatten)]
    controller: ControllerArgs,
    #[command(flatten)]
    feedforward: FeedforwardArgs,
    /// Replace the plant with this plant file (a `[plant]` table, e.g. `servo identify`'s
    /// model.toml).
    #[arg(long)]
    plant: Option<PathBuf>,
    #[command(flatten)]
    recording: RecordingArgs,
    /// Read a damaged or unfinished recording (a killed run's `.partial`) as far as it is
    /// intact, say what was skipped, and exit 0 (without it such a file exits 1).
    #[arg(long)]
    salvage: bool,
}

/// A replay's result.
impl ReplayCmd {
    /// Reads, re-runs, compares and prints; the exit code says how the replay ended.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let mut replay = Replay::open(&self.file, self.salvage)?;
        if let Some(p) = &self.controller_from {
            replay.config_mut().controller = crate::args::controller_from(p)?;
        }
        self.controller.apply(&mut replay.config_mut().controller);
        self.feedforward
            .apply(&mut replay.config_mut().controller, None);
        if let Some(p) = &self.plant {
            replay.replace_plant(read_plant_file(p)?);
        }
        let stop = stop_on_signals();
        let out = self.recording.out(DEFAULT_REPLAY.as_ref());
        let report = with_progress(&self.recording, out.clone(), &stop, "replaying", |opts| {
            replay.run(opts)
        })?;
        if self.recording.json {
            print_json(&report);
        } else {
            print_report(&report);
            if let Some(o) = &out {
                println!("  wrote {}", o.written());
            }
        }
        Ok(crate::interrupt::exit_code(
            &stop,
            report.replayed.trip.is_some(),
        ))
    }
}

fn print_report(r: &ReplayReport) {
    let (every, rate_hz) = (r.every, r.rate_hz);
    println!(
        "Replay ({}): {}",
        if r.changed { "changed" } else { "as recorded" },
        r.replayed.meta.controller
    );
    match (r.identical, r.first_difference_frame) {
        (None, _) => println!(
            "  data channels        not compared: recorded every {every} ticks (metrics below are \
             over the recorded ticks against every replayed tick)"
        ),
        (Some(true), _) => println!(
            "  data channels        identical, bit for bit ({} frames)",
            r.frames_compared
        ),
        (Some(false), Some(f)) => println!(
            "  data channels        differ, first within frames {f} … {} (from t = {:.4} s)",
            f + runner::replay::DIGEST_BLOCK - 1,
            f as f64 / rate_hz
        ),
        (Some(false), None) => {}
    }
    match r.design {
        Some(RecordedDesign::Same) => {
            println!("  design               recorded (designed here: the same bits)")
        }
        Some(RecordedDesign::Apart(d)) => println!(
            "  design               recorded (designed here: up to {d:.1e} apart, relative; \
             another processor rounds otherwise)"
        ),
        Some(RecordedDesign::OtherForm) => {
            println!("  design               recorded (this version designs another form)")
        }
        Some(RecordedDesign::NotRecorded) => {
            println!("  design               designed again (the recording carries no deployment)")
        }
        None => {}
    }
    let (was, is) = (&r.recorded.meta.arithmetic, &r.replayed.meta.arithmetic);
    if was != is {
        println!(
            "  arithmetic           recorded with {was}, replayed with {is}: the data channels \
             agree only to rounding (a build with the other `fma` feature reproduces them)"
        );
    }
    if let Some(t) = r.compared_until_operator_tick {
        println!(
            "  steered              at tick {t} (servo ctl load / gain): the replay runs the \
             recorded configuration throughout; frames from there on are not compared"
        );
    }
    println!(
        "  {:<26} {:>12} {:>12} {:>9}",
        "metric", "recorded", "replayed", "change"
    );
    let row = |name: &str, a: f64, b: f64, unit: &str, k: f64| {
        let change = if a != 0.0 {
            format!("{:+.1} %", 100.0 * (b / a - 1.0))
        } else {
            "–".into()
        };
        println!(
            "  {:<26} {:>12.4} {:>12.4} {change:>9}",
            if unit.is_empty() {
                name.to_owned()
            } else {
                format!("{name} ({unit})")
            },
            a * k,
            b * k
        );
    };
    let (a, b) = (&r.recorded, &r.replayed);
    row(
        "following error RMS",
        a.following_error_m.rms,
        b.following_error_m.rms,
        "nm",
        1e9,
    );
    row(
        "following error PV",
        a.following_error_m.pv,
        b.following_error_m.pv,
        "nm",
        1e9,
    );
    row(
        "true error RMS",
        a.true_error_m.rms,
        b.true_error_m.rms,
        "nm",
        1e9,
    );
    row(
        "true error PV",
        a.true_error_m.pv,
        b.true_error_m.pv,
        "nm",
        1e9,
    );
    row("control RMS", a.control_v.rms, b.control_v.rms, "mV", 1e3);
    row(
        "saturated ticks",
        a.saturated_ticks as f64,
        b.saturated_ticks as f64,
        "",
        1.0,
    );
    let trip = |s: &Summary| {
        s.trip
            .as_ref()
            .map_or("none".to_string(), |t| t.cause.clone())
    };
    println!("  {:<26} {:>12} {:>12}", "trip", trip(a), trip(b));
}
