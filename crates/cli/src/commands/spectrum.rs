//! `servo spectrum`: PSD and CAS of a recording's following error, true error and control
//! output beside the error budget of the recorded configuration (thesis §5.7.4, Fig 5-15).

use crate::output::{print_json, print_written, CliError};
use clap::Args;
use run_config::Origin;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::spectrum::{BandRms, SpectrumOptions, SpectrumSink, RESOLUTION_RANGE_HZ};
use studies::StudyError;

/// Spectrum of a recorded run beside its error budget (thesis §5.7.4, Fig 5-15).
///
/// Welch PSD (Hann, 50 % overlap) and CAS of the following error, the control output and —
/// for a simulated run — the true tool error, from the settle time to the end (or a trip),
/// with the budget's prediction for the recorded configuration and the RMS difference per
/// decade band. After a `servo ctl load`, from the settle time after the last swap, predicted
/// for the loaded controller (the recording keeps it). Streams the file in constant memory.
/// Example: servo run --duration 2 && servo spectrum run.mcap
#[derive(Args, Debug)]
pub struct SpectrumCmd {
    /// The MCAP file written by `servo run` or `servo record`.
    file: PathBuf,
    /// Frequency resolution (bin spacing) in Hz, 0.1 – 1000 (the segment is fs / resolution
    /// samples; finer bins average fewer segments).
    #[arg(value_parser = crate::args::finite, long, default_value_t = 10.0)]
    resolution_hz: f64,
    /// Analysis start in s of run time (default: the run's settle time, counted from the last
    /// controller swap if there was one). The prediction is for the controller in the loop
    /// at this time.
    #[arg(value_parser = crate::args::finite, long)]
    from_s: Option<f64>,
    /// Analysis end in s of run time (default: the end of the run).
    #[arg(value_parser = crate::args::finite, long)]
    to_s: Option<f64>,
    /// Predict with the [controller] table of this config file (e.g. a candidate's pid.toml)
    /// instead of the controller in the loop at the window's start.
    #[arg(long)]
    controller_from: Option<PathBuf>,
    /// Output directory for CSV, JSON, PNG and SVG.
    #[arg(long, default_value = "spectrum")]
    out_dir: PathBuf,
    /// Print the result as JSON.
    #[arg(long)]
    json: bool,
    /// Read a damaged or unfinished recording (a killed run's `.partial`) as far as it is
    /// intact, say what was skipped, and exit 0 (without it such a file exits 1).
    #[arg(long)]
    salvage: bool,
}

impl SpectrumCmd {
    /// Reads, analyses, writes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let (lo, hi) = RESOLUTION_RANGE_HZ;
        if !(lo..=hi).contains(&self.resolution_hz) {
            return Err(Origin::default()
                .invalid(
                    "--resolution-hz",
                    self.resolution_hz,
                    &format!("[{lo}, {hi}] Hz"),
                )
                .into());
        }
        let controller = match &self.controller_from {
            Some(p) => Some(crate::args::controller_from(p)?),
            None => None,
        };
        let mut sink = SpectrumSink::new(SpectrumOptions {
            resolution_hz: self.resolution_hz,
            from_s: self.from_s,
            to_s: self.to_s,
            controller,
            swaps: runner::operator_log::OperatorLog::read(&self.file)?.swaps,
        });
        let read = runner::recording::inspect_with(&self.file, &mut sink)?
            .intact(&self.file, self.salvage)?;
        let s = sink.finish()?;
        let title = self
            .file
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let written =
            reports::spectrum::write(&s, &title, &self.out_dir).map_err(StudyError::from)?;
        if self.json {
            print_json(&s);
            return Ok(ExitCode::SUCCESS);
        }
        println!(
            "Spectrum of {} ({}): {} samples at {:.0} Hz from {:.3} s, {:.2} Hz bins, {} segments",
            self.file.display(),
            read.read,
            s.samples,
            s.sample_rate_hz,
            s.from_s,
            s.resolution_hz,
            s.segments
        );
        println!("  made for {}; {}", s.made_for.describe(), s.controller);
        if let Some(c) = s.predicted_with.as_ref().filter(|c| **c != s.controller) {
            println!("  budget predicted with {c}");
        }
        for t in &s.swapped_at_s {
            println!("  controller swapped in at {t:.3} s (servo ctl load)");
        }
        if let Some(n) = &s.window_note {
            println!("  note: {n}");
        }
        if let Some(n) = &s.prediction_note {
            println!("  no budget overlay: {n}");
        }
        println!(
            "  {:<17} {:>34} {:>34} {:>34}",
            "band (Hz)",
            "following error (nm RMS)",
            "true error (nm RMS)",
            "control output (mV RMS)"
        );
        println!(
            "  {:<17} {:>9} {:>9} {:>14}  {:>9} {:>9} {:>14}  {:>9} {:>9} {:>14}",
            "",
            "recorded",
            "budget",
            "diff ± chance",
            "recorded",
            "budget",
            "diff ± chance",
            "recorded",
            "budget",
            "diff ± chance"
        );
        let rows = s
            .bands
            .iter()
            .map(|b| (format!("{:.0} – {:.0}", b.from_hz, b.to_hz), &b.rms))
            .chain([("all".to_string(), &s.total)]);
        for (name, rms) in rows {
            println!(
                "  {name:<17} {}  {}  {}",
                cells(Some(&rms.following_error_m), 1e9),
                cells(rms.true_error_m.as_ref(), 1e9),
                cells(Some(&rms.control_v), 1e3)
            );
        }
        print_written(&written);
        Ok(ExitCode::SUCCESS)
    }
}

/// `recorded budget diff ± chance` of one signal, scaled by `k`, blank where absent (chance:
/// the recorded RMS's 1σ scatter, what a difference is measured against).
fn cells(b: Option<&BandRms>, k: f64) -> String {
    let v = |x: Option<f64>, d: usize| x.map_or("–".into(), |x| format!("{:.*}", d, x * k));
    match b {
        Some(b) => format!(
            "{:>9} {:>9} {:>14}",
            v(Some(b.recorded), 4),
            v(b.predicted, 4),
            b.difference_percent.map_or("–".into(), |d| format!(
                "{d:+.1} ± {:.1} %",
                b.chance_percent
            ))
        ),
        None => format!("{:>9} {:>9} {:>14}", "–", "–", "–"),
    }
}
