//! `servo export`: a recording to CSV or NumPy `.npz` (streamed: constant memory), with topic
//! selection, a time window and decimation.

use crate::output::{print_json, CliError};
use clap::{Args, ValueEnum};
use recorder::export::{export, Format, Selection};
use recorder::Overwrite;
use std::path::PathBuf;
use std::process::ExitCode;

/// Export a recording to CSV or NumPy .npz
///
/// Example: servo export run.mcap --topics telemetry --every 20
///
/// `.npz` holds one array per column (`numpy.load("run.npz")["telemetry.following_error_m"]`);
/// names carry their SI unit. Exit 1 if the recording is damaged or unfinished (what is intact
/// is exported all the same), unless --salvage (a killed run's `.partial`).
#[derive(Args, Debug)]
pub struct ExportCmd {
    /// The MCAP recording.
    file: PathBuf,
    /// Output file (default: the recording's name with the format's extension, beside it).
    #[arg(short, long)]
    out: Option<PathBuf>,
    /// Output format (default: from --out's extension, else npz).
    #[arg(long, value_enum)]
    format: Option<FormatArg>,
    /// Topics to export, comma-separated: telemetry, truth, overview (the 1 kHz min/max/mean;
    /// in a CSV only on its own).
    #[arg(long, value_delimiter = ',', default_value = "telemetry,truth")]
    topics: Vec<Topic>,
    /// Start of the time window in s from the run's start.
    #[arg(value_parser = crate::args::finite, long, default_value_t = 0.0)]
    from: f64,
    /// End of the time window in s from the run's start (default: the end).
    #[arg(value_parser = crate::args::finite, long)]
    to: Option<f64>,
    /// Keep every n-th tick of the window (1: all; 200 ≈ 1 kHz at 199.6 kHz).
    #[arg(long, default_value_t = 1)]
    every: u64,
    /// Replace an existing output file.
    #[arg(long)]
    overwrite: bool,
    /// Print what was written as JSON.
    #[arg(long)]
    json: bool,
    /// Read a damaged or unfinished recording (a killed run's `.partial`) as far as it is
    /// intact, say what was skipped, and exit 0 (without it such a file exits 1).
    #[arg(long)]
    salvage: bool,
}

/// `--format`.
#[derive(Debug, Clone, Copy, ValueEnum)]
enum FormatArg {
    Csv,
    Npz,
}

/// One of `--topics`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Topic {
    Telemetry,
    Truth,
    Overview,
}

impl ExportCmd {
    /// Exports and reports.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let format = match (self.format, &self.out) {
            (Some(FormatArg::Csv), _) => Format::Csv,
            (Some(FormatArg::Npz), _) => Format::Npz,
            (None, Some(o)) if o.extension().is_some_and(|e| e == "csv") => Format::Csv,
            (None, _) => Format::Npz,
        };
        let out = self.out.clone().unwrap_or_else(|| {
            self.file.with_extension(match format {
                Format::Csv => "csv",
                Format::Npz => "npz",
            })
        });
        let selection = Selection {
            telemetry: self.topics.contains(&Topic::Telemetry),
            truth: self.topics.contains(&Topic::Truth),
            overview: self.topics.contains(&Topic::Overview),
            from_s: self.from,
            to_s: self.to.unwrap_or(f64::INFINITY),
            every: self.every,
        };
        runner::recording::check_embedded_config(&self.file)?;
        let overwrite = Overwrite::from_flag(self.overwrite);
        let done = export(&self.file, &out, format, &selection, overwrite)?;
        if self.json {
            print_json(&serde_json::json!({
                "path": done.path,
                "rows": done.rows,
                "overview_rows": done.overview_rows,
                "file": done.read.to_string(),
            }));
        } else {
            println!(
                "wrote {}: {} ticks, {} overview rows (recording: {})",
                done.path.display(),
                done.rows,
                done.overview_rows,
                done.read
            );
        }
        Ok(if self.salvage || done.read.is_intact() {
            ExitCode::SUCCESS
        } else {
            eprintln!(
                "error: {}: {}; not trusted as a whole run (--salvage reads what is intact)",
                self.file.display(),
                done.read
            );
            ExitCode::FAILURE
        })
    }
}
