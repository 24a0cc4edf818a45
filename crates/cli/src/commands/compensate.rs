//! `servo compensate`: the next cut's compensation from a registered measurement.

use crate::args::PrescriptionCutArgs;
use crate::output::{print_json, print_written, CliError, BAD_INPUT};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::measured::compensate::{next_compensation, CompensationOptions, NextCompensation};

/// Make the next cut's compensation from a measured part.
///
/// Adds the residual `servo register` wrote in the part's frame (`part_error.csv`), scaled by
/// `--gain` and smoothed by a Gaussian low-pass of standard deviation `--lowpass-mm`, node by
/// node to the compensation the configuration's prescription already holds (its
/// `[compensation]`, if any); regenerates the tool path with the result and checks it against
/// the stage as `servo toolpath` does (stroke, DAC, slope against the clearance, the nose; its
/// prediction in `compensation.json`). Writes `compensation.json` and, when the path stays within
/// the stage, `compensation.csv` (load it as the prescription's `[compensation]` for the next
/// cut) and a picture into `--out-dir`; a path beyond the stage writes no grid and exits 2.
/// With `--previous-residual` (the last cycle's `part_error.csv`) it says when a cycle no
/// longer helps (the residual's RMS fell by less than 10 %).
/// Example: servo compensate -c cut.toml --residual register/part_error.csv --gain 0.8
#[derive(Args, Debug)]
pub struct CompensateCmd {
    #[command(flatten)]
    cut: PrescriptionCutArgs,
    /// The registered residual in the part's frame (`servo register`'s part_error.csv).
    #[arg(long)]
    residual: PathBuf,
    /// The previous cycle's residual, for the stopping rule.
    #[arg(long)]
    previous_residual: Option<PathBuf>,
    /// The share of the residual added (0, 1.5].
    #[arg(long, default_value_t = 1.0, value_parser = crate::args::positive)]
    gain: f64,
    /// Standard deviation of the Gaussian low-pass on the residual in mm (0: none).
    #[arg(long, default_value_t = 0.0, value_parser = crate::args::finite)]
    lowpass_mm: f64,
    /// Radius bands of the tool path's check.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u16).range(1..=100))]
    bands: u16,
    /// Directory for compensation.json, compensation.csv and the picture.
    #[arg(long, default_value = "compensate")]
    out_dir: PathBuf,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

impl CompensateCmd {
    /// Plans, accumulates, checks, writes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let plan = self.cut.plan()?;
        let options = CompensationOptions {
            gain: self.gain,
            lowpass_m: self.lowpass_mm * 1e-3,
        };
        let next = next_compensation(
            &plan,
            &self.residual,
            self.previous_residual.as_deref(),
            &options,
            usize::from(self.bands),
        )?;
        let within = next.toolpath.feasibility.exceeded.is_empty();
        let written = reports::measured::write_cycle(&next, within, &self.out_dir)
            .map_err(studies::StudyError::from)?;
        if self.json {
            print_json(&next);
        } else {
            print(&next);
            print_written(&written);
        }
        Ok(if within {
            ExitCode::SUCCESS
        } else {
            ExitCode::from(BAD_INPUT)
        })
    }
}

/// `f`'s PV and RMS after piston and tilt.
fn nm(f: &metrology::Form) -> String {
    format!(
        "{:.2} nm PV, {:.3} nm RMS",
        f.tilt_removed.pv_m * 1e9,
        f.tilt_removed.rms_m * 1e9
    )
}

/// The report as lines.
fn print(s: &NextCompensation) {
    println!(
        "Compensation from {} (gain {}, low-pass σ {} mm)",
        s.residual_file,
        s.options.gain,
        s.options.lowpass_m * 1e3
    );
    println!(
        "  measured residual      {} after piston and tilt",
        nm(&s.residual)
    );
    if let Some(p) = &s.previous_residual {
        println!("  previous residual      {}", nm(p));
    }
    match &s.previous {
        Some(p) => println!("  previous compensation  {}", nm(p)),
        None => println!("  previous compensation  none"),
    }
    println!("  next compensation      {}", nm(&s.next));
    let f = &s.toolpath.feasibility;
    println!(
        "  tool path with it: FTS stroke {:.3} µm",
        f.fts_stroke_m * 1e6
    );
    if f.exceeded.is_empty() {
        println!("  within the stage everywhere");
    }
    for e in &f.exceeded {
        println!("  EXCEEDED {e} (no compensation.csv written)");
    }
    if s.stop {
        println!("  STOP: this cycle's residual fell by less than 10 % of the last one's: another cycle will not help");
    }
}
