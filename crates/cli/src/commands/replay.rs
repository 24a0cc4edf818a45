//! `servo replay`: re-run a recording from what it holds — as it was (the data channels
//! compared bit for bit) or with a replaced controller, feedforward or plant ("what would this
//! run have been with …"), the metrics side by side.

use super::run::with_progress;
use crate::args::{ControllerArgs, FeedforwardArgs, RecordingArgs};
use crate::interrupt::stop_on_signals;
use crate::output::{print_json, CliError};
use clap::Args;
use runner::config::read_plant_file;
use runner::replay::{FrameDigest, Recorded};
use runner::run::run_with;
use runner::summary::Summary;
use runner::RunError;
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
#[derive(serde::Serialize)]
struct Report<'a> {
    /// Whether the configuration was changed from the recorded one.
    changed: bool,
    /// Frames compared bit for bit (0 when not compared).
    frames_compared: u64,
    /// Identical data channels (`None`: not compared — decimated recording).
    identical: Option<bool>,
    /// The first recorded frame that may differ.
    first_difference_frame: Option<u64>,
    /// The tick an operator first changed the recorded run (`servo ctl load`, `servo ctl
    /// gain`): the replay runs the recorded configuration throughout, so frames from it on are
    /// not compared.
    compared_until_operator_tick: Option<u64>,
    recorded: &'a Summary,
    replayed: &'a Summary,
}

impl ReplayCmd {
    /// Reads, re-runs, compares and prints; the exit code says how the replay ended.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        // A replay runs the configuration alone: an operator's first change (a controller
        // swap, a gain change) ends the part it can reproduce.
        let steered_at = runner::operator_log::OperatorLog::read(&self.file)?.first_tick();
        let mut rec = Recorded::new(steered_at.unwrap_or(u64::MAX));
        let inspected = runner::recording::inspect_with(&self.file, &mut rec)?
            .intact(&self.file, self.salvage)?;
        let (Some(header), Some(recorded_digest)) = (rec.header, rec.digest) else {
            return Err(RunError::NotARun(self.file.clone()).into());
        };
        let mut loaded = header.loaded.clone();
        if let Some(p) = &self.controller_from {
            loaded.config.controller = crate::args::controller_from(p)?;
        }
        self.controller.apply(&mut loaded);
        self.feedforward.apply(&mut loaded);
        if let Some(p) = &self.plant {
            loaded.config.plant = read_plant_file(p)?;
        } else if !rec.has_truth {
            return Err(RunError::NoTruth(self.file.clone()).into());
        }
        let changed = loaded.config != header.loaded.config;
        // As long as the recording: a run stopped early (`servo ctl stop`, a signal) replays
        // to where it stopped, not to its configured duration.
        let recorded_s = inspected.read.last_time_ns.map_or(0.0, |t| t as f64 * 1e-9);
        if recorded_s > 0.0 && recorded_s < loaded.config.run.duration_s {
            loaded.config.run.duration_s = recorded_s;
        }
        let plan = header.replan(loaded.config)?;
        let every = header.every.get();
        let mut digest = FrameDigest::new(recorded_digest.frames());
        let stop = stop_on_signals();
        let out = self.recording.out(DEFAULT_REPLAY.as_ref());
        let replayed = with_progress(&self.recording, out.clone(), &stop, "replaying", |opts| {
            run_with(&plan, opts, |f| digest.add(f))
        })?;
        let compared = (every == 1).then(|| {
            let frames = recorded_digest.frames();
            (frames, recorded_digest.first_difference(digest))
        });
        let report = Report {
            changed,
            frames_compared: compared.map_or(0, |(n, _)| n),
            identical: compared.map(|(_, d)| d.is_none()),
            first_difference_frame: compared.and_then(|(_, d)| d),
            compared_until_operator_tick: steered_at,
            recorded: &inspected.summary,
            replayed: &replayed,
        };
        if self.recording.json {
            print_json(&report);
        } else {
            print_report(&report, every, plan.config.plant.timing.servo_rate_hz);
            if let Some(o) = &out {
                println!("  wrote {}", o.path.display());
            }
        }
        Ok(crate::interrupt::exit_code(&stop, replayed.trip.is_some()))
    }
}

fn print_report(r: &Report, every: u32, rate_hz: f64) {
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
    let (a, b) = (r.recorded, r.replayed);
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
