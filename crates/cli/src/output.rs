//! What the commands print: errors with their causes and the exit code that says how a
//! command ended, JSON, progress bars, the files a study wrote, margins.

use indicatif::{ProgressBar, ProgressStyle};
use run_config::ConfigError;
use runner::RunError;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::StudyError;

/// Writes a result file (a controller, tuned gains, an identified model) that another command
/// takes: created new, never replacing an existing file unless `overwrite`.
pub fn write_result(path: &std::path::Path, text: &str, overwrite: bool) -> Result<(), CliError> {
    use std::io::Write;
    let io = |source| CliError::Write {
        path: path.to_owned(),
        source,
    };
    let mut options = std::fs::OpenOptions::new();
    options.write(true);
    if overwrite {
        options.create(true).truncate(true);
    } else {
        options.create_new(true);
    }
    let mut file = options.open(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::AlreadyExists => io(std::io::Error::other(
            "it exists: not overwritten (pass --overwrite to replace it)",
        )),
        _ => io(e),
    })?;
    file.write_all(text.as_bytes()).map_err(io)
}

/// Why a command failed.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// Configuration or a flag out of range.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// Building or running the loop.
    #[error(transparent)]
    Run(#[from] RunError),
    /// A study.
    #[error(transparent)]
    Study(#[from] StudyError),
    /// Writing an output file.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// Exporting a recording.
    #[error(transparent)]
    Export(#[from] recorder::export::ExportError),
    /// Starting or supervising the HIL processes.
    #[error("{0}")]
    Processes(String),
    /// The library an FMI unit carries cannot be read.
    #[error("cannot read the FMU library {}: {source} (build it with `cargo build --release -p fmu-ffi`, or name it with FTS_FMU_LIBRARY)", path.display())]
    FmuLibrary {
        /// The library's path.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// A HIL child process failed (it printed why); the command exits with its code.
    #[error("servo {name} exited with {code}")]
    Child {
        /// Which process (`plant`, `controller`, `recorder`).
        name: String,
        /// Its exit code.
        code: i32,
    },
}

impl CliError {
    /// 2 for what the user can fix before running (bad input, a controller that would make
    /// the loop unstable), 4 when the recording could not be written mid-run (the run was
    /// ended safely), 1 for other failures while running.
    pub fn exit_code(&self) -> u8 {
        let input = |r: &RunError| {
            matches!(
                r,
                RunError::Config(_)
                    | RunError::Unstable { .. }
                    | RunError::NoTruth(_)
                    | RunError::HostTooSlow(_)
                    | RunError::Pil(runner::pil::PilError::Refused(_))
                    | RunError::Pil(runner::pil::PilError::Firmware { .. })
            )
        };
        let write_failed = |r: &RunError| {
            matches!(
                r,
                RunError::Record(recorder::RecordError::WriteFailed { .. })
            )
        };
        match self {
            CliError::Run(r) | CliError::Study(StudyError::Run(r)) if write_failed(r) => {
                runner::stop::EndReason::WriteFailed.exit_code()
            }
            CliError::Run(RunError::Stopped(reason)) => reason.exit_code(),
            CliError::Config(_) => BAD_INPUT,
            CliError::Run(r) | CliError::Study(StudyError::Run(r)) if input(r) => BAD_INPUT,
            CliError::Study(StudyError::Config(_)) => BAD_INPUT,
            CliError::Study(StudyError::Map(_) | StudyError::Registration { .. }) => BAD_INPUT,
            CliError::Export(recorder::export::ExportError::Selection(_)) => BAD_INPUT,
            CliError::Child { code, .. } => u8::try_from(*code).unwrap_or(1),
            _ => FAILED,
        }
    }
}

/// Exit code of a failure while running: an unwritable path, a damaged or unfinished
/// recording refused (without `--salvage`), a `servo ctl` refused or unanswered, an
/// identification below 70 % fit.
pub const FAILED: u8 = 1;

/// Exit code of bad input: a configuration problem (located by file, line, key and allowed
/// range), a controller that would make the loop unstable, a host that stalls longer than the
/// loop survives, a selection that matches nothing, a tool path beyond the stage.
pub const BAD_INPUT: u8 = 2;

/// Every exit code: (code, a run's end reason or empty for a command's own, meaning), in
/// code order (`servo --help` and the book's exit-code reference list them).
pub fn exit_codes() -> Vec<(String, String, String)> {
    let mut rows: Vec<(u8, String, String)> = runner::stop::EndReason::EACH
        .iter()
        .map(|r| (r.exit_code(), r.name().to_owned(), r.meaning().to_owned()))
        .chain(
            COMMAND_CODES
                .iter()
                .map(|(code, meaning)| (*code, String::new(), (*meaning).to_owned())),
        )
        .collect();
    rows.sort_by_key(|r| r.0);
    rows.into_iter()
        .map(|(code, reason, meaning)| {
            let code = match reason.as_str() {
                "interrupted" => "128 + signal".to_owned(),
                _ => code.to_string(),
            };
            (code, reason, meaning)
        })
        .collect()
}

/// The exit codes as `servo --help` lists them.
pub fn exit_codes_help() -> String {
    let mut text = String::from("Exit codes:\n");
    for (code, reason, meaning) in exit_codes() {
        let reason = if reason.is_empty() {
            String::new()
        } else {
            format!("{reason}: ")
        };
        text += &format!("  {code:<13} {reason}{meaning}\n");
    }
    text
}

/// The codes a command itself exits with, beside a run's end reasons.
const COMMAND_CODES: [(u8, &str); 3] = [
    (
        FAILED,
        "another failure: an unwritable path, a damaged or unfinished recording refused by \
         `inspect`, `replay`, `spectrum` or `export` (without `--salvage`), `servo ctl` refused \
         or unanswered, `servo identify` with a fit below 70 %",
    ),
    (
        BAD_INPUT,
        "bad input: a configuration problem, located by file, line, key and allowed range; a \
         controller that would make the loop unstable; a host that stalls longer than the loop \
         survives (servo run --hil --realtime); an export selection that matches nothing",
    ),
    (
        KILLED,
        "`servo run --hil`: one of its processes was killed by a signal it cannot handle \
         (SIGKILL: 128 + 9) — the recorder (the loop is stopped; its `.partial` file holds \
         every complete chunk, read it with `--salvage`), or the plant or controller before \
         the loop's first tick (the others are stopped, nothing is recorded) or after its \
         last; killed mid-run, they are a lost peer (3)",
    ),
];

/// Exit code of `servo run --hil` when one of its processes was killed by SIGKILL and the
/// recorder gave no other reason (128 + 9, as a shell reports it).
pub const KILLED: u8 = 137;

impl CliError {
    /// The flag a library error's key stands for: the libraries name their options as keys
    /// (`order`, `bandwidth_hz`), the command line as flags (`--order`, `--bandwidth-hz`).
    pub fn flag_hint(&self) -> Option<String> {
        let config = match self {
            CliError::Config(c)
            | CliError::Study(StudyError::Config(c))
            | CliError::Run(RunError::Config(c))
            | CliError::Study(StudyError::Run(RunError::Config(c))) => c,
            CliError::Run(RunError::RateMismatch { served_hz, .. })
            | CliError::Study(StudyError::Run(RunError::RateMismatch { served_hz, .. })) => {
                return Some(format!("--rate {served_hz:.0}"))
            }
            CliError::Run(RunError::NoTruth(_)) => return Some("--plant model.toml".into()),
            CliError::Run(RunError::HostTooSlow(r))
                if r.survivable.limit() == runner::stall::Limit::PeerTimeout =>
            {
                return Some("--peer-timeout-ms".into())
            }
            CliError::Run(RunError::Damaged { .. }) => return Some("--salvage".into()),
            CliError::Study(StudyError::NoTuningStart { .. }) => return Some("--ms, --mt".into()),
            CliError::Study(StudyError::FrfAborted { .. }) => return Some("--amplitude".into()),
            CliError::Study(StudyError::Map(m)) if m.reason.contains("map.height_unit") => {
                return Some("--height-unit".into())
            }
            CliError::Study(StudyError::Map(m)) if m.reason.contains("map.pitch_m") => {
                return Some("--pitch-mm".into())
            }
            CliError::Run(RunError::Record(recorder::RecordError::Exists { .. }))
            | CliError::Export(recorder::export::ExportError::Write(
                recorder::RecordError::Exists { .. },
            )) => return Some("--overwrite".into()),
            CliError::Export(recorder::export::ExportError::Selection(_)) => {
                return Some("--topics, --from, --to, --every".into())
            }
            _ => return None,
        };
        match config {
            ConfigError::Invalid {
                path: None, key, ..
            } if !key.contains('.') && !key.starts_with('-') => Some(match key.as_str() {
                // The one field whose flag is shorter than its name.
                "probe_noise_rms_m" => "--probe-noise-m".into(),
                "lowpass_m" => "--lowpass-mm".into(),
                key => format!("--{}", key.replace('_', "-")),
            }),
            _ => None,
        }
    }
}

/// Prints `e` with its chain of causes (`error: writing x: I/O error: No space left…`) and its
/// flag (a library names the option's key) and returns exit code `code`.
pub fn fail_cli(e: &CliError) -> ExitCode {
    let code = e.exit_code();
    match e.flag_hint() {
        Some(flag) => fail(&Hinted(e, flag), code),
        None => fail(e, code),
    }
}

/// An error with the command-line flag it concerns.
#[derive(Debug)]
struct Hinted<'a>(&'a CliError, String);

impl std::fmt::Display for Hinted<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} (flag {})", self.0, self.1)
    }
}

impl std::error::Error for Hinted<'_> {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        std::error::Error::source(self.0)
    }
}

/// Prints `e` with its chain of causes (`error: writing x: I/O error: No space left…`) and
/// returns exit code `code`.
pub fn fail(e: &dyn std::error::Error, code: u8) -> ExitCode {
    let mut msg = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        let text = c.to_string();
        if !msg.contains(&text) {
            msg = format!("{msg}: {text}");
        }
        cause = c.source();
    }
    eprintln!("error: {msg}");
    ExitCode::from(code)
}

/// Prints any result as pretty JSON (everything printed serialises).
pub fn print_json(value: &impl serde::Serialize) {
    println!(
        "{}",
        serde_json::to_string_pretty(value).expect("results serialise")
    );
}

/// A progress bar with `template` (indicatif; hidden with `quiet`).
pub fn bar(quiet: bool, len: u64, template: &str) -> ProgressBar {
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(len)
    };
    bar.set_style(
        ProgressStyle::with_template(template)
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar
}

/// A progress bar over ticks labelled `what`.
pub fn tick_bar(quiet: bool, what: &str) -> ProgressBar {
    bar(
        quiet,
        0,
        &format!("{{spinner}} {what} [{{bar:40}}] {{percent:>3}}% {{elapsed_precise}} ETA {{eta}}"),
    )
}

/// A progress bar over `len` study points labelled `what` (`unit`: what a point is).
pub fn points_bar(len: usize, what: &str, unit: &str) -> ProgressBar {
    bar(
        false,
        len as u64,
        &format!("{{spinner}} {what} [{{bar:40}}] {{pos}}/{{len}} {unit} {{elapsed_precise}}"),
    )
}

/// The files a study wrote, and why its plots were skipped if they were.
pub fn print_written(w: &studies::report::Written) {
    let names: Vec<String> = w.files.iter().map(|p| p.display().to_string()).collect();
    println!("  wrote {}", names.join(", "));
    if let Some(n) = &w.note {
        println!("  note: {n}");
    }
}

/// The loop's margins in one line, and on the measured FRF when the run names one.
pub fn print_margins(plan: &runner::Plan) {
    match studies::margins::loop_margins(plan) {
        Ok(m) => println!("  margins (loop broken at the DAC): {}", margins_text(&m)),
        Err(e) => println!("  margins: {e}"),
    }
    if let Some(measured) = &plan.measured {
        let s = &measured.stability;
        let v = s.verdict;
        println!(
            "  on the measured FRF {}: {}; sensitivity peak {:.1} dB at {:.0} Hz",
            measured.source,
            margins_text(&s.margins),
            v.sensitivity_peak.0,
            v.sensitivity_peak.1
        );
        println!(
            "    {} over every bin's uncertainty disk: |1 + L| − r ≥ {:.3} (at {:.0} Hz); beyond {:.0} Hz the model within ±{:.0} %",
            if v.robustly_stable() { "stable" } else { "NOT stable" },
            v.disk_distance.0,
            v.disk_distance.1,
            s.top_hz,
            100.0 * s.beyond
        );
    }
}

/// Phase and gain margins with their frequencies.
fn margins_text(m: &design::loops::Margins) -> String {
    let f = |v: Option<f64>, unit: &str| v.map_or("–".to_string(), |x| format!("{x:.1} {unit}"));
    format!(
        "phase {} at {}, gain {} at {}, lower gain {}",
        f(m.phase_margin_deg, "°"),
        f(m.gain_crossover_hz, "Hz"),
        f(m.gain_margin_db, "dB"),
        f(m.phase_crossover_hz, "Hz"),
        f(m.lower_gain_margin_db, "dB")
    )
}

/// A run's summary, as text or JSON.
pub fn print_summary(s: &runner::summary::Summary, json: bool) {
    if json {
        print_json(s);
    } else {
        print!("{s}");
    }
}
