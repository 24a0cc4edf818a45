//! `servo spindle-errors`: three-probe spindle error separation on simulated data.

use crate::output::{print_json, print_written, CliError};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::spindle::{self, Recovery, SpindleStudy};
use studies::StudyError;

/// Separate spindle error motion from artefact form (thesis Appendix D)
///
/// On simulated three-probe data: a known artefact and spindle motion measured with the three angle
/// sets of Table D-1; reports how well each set, the thesis's frequency-domain
/// modification and the least-squares synthesis recover both.
/// Example: servo spindle-errors --probe-noise-m 0.3e-9
#[derive(Args, Debug)]
pub struct SpindleErrorsCmd {
    /// Samples per revolution.
    #[arg(long, default_value_t = 10_000)]
    per_rev: usize,
    /// Revolutions averaged.
    #[arg(long, default_value_t = 32)]
    revolutions: usize,
    /// Highest harmonic analysed (UPR).
    #[arg(long, default_value_t = 100)]
    max_harmonic: usize,
    /// RMS of the simulated artefact form in m.
    #[arg(value_parser = crate::args::finite, long, default_value_t = 20e-9)]
    artefact_rms_m: f64,
    /// RMS of the simulated synchronous spindle motion per axis in m.
    #[arg(value_parser = crate::args::finite, long, default_value_t = 30e-9)]
    motion_rms_m: f64,
    /// RMS of the asynchronous motion in m.
    #[arg(value_parser = crate::args::finite, long, default_value_t = 5e-9)]
    asynchronous_rms_m: f64,
    /// RMS of the probe noise in m.
    #[arg(value_parser = crate::args::finite, long, default_value_t = 0.3e-9)]
    probe_noise_m: f64,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Directory for the results.
    #[arg(long, default_value = "spindle")]
    out_dir: PathBuf,
    /// Print the result as JSON.
    #[arg(long)]
    json: bool,
}

impl SpindleErrorsCmd {
    /// Simulates, separates, writes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let s = SpindleStudy {
            per_rev: self.per_rev,
            revolutions: self.revolutions,
            max_harmonic: self.max_harmonic,
            artefact_rms_m: self.artefact_rms_m,
            motion_rms_m: self.motion_rms_m,
            asynchronous_rms_m: self.asynchronous_rms_m,
            probe_noise_rms_m: self.probe_noise_m,
            seed: self.seed,
        };
        s.validate()?;
        let (report, profiles) = spindle::study(&s);
        let written = reports::spindle::write(&report, &profiles, s.max_harmonic, &self.out_dir)
            .map_err(StudyError::from)?;
        if self.json {
            print_json(&report);
            return Ok(ExitCode::SUCCESS);
        }
        let nm = |v: f64| v * 1e9;
        println!(
            "Three-probe separation (Appendix D): artefact {:.2} nm RMS, X {:.2} nm, Y {:.2} nm; {} revolutions × {} samples, probe noise {:.2} nm",
            nm(report.truth_rms_m[0]),
            nm(report.truth_rms_m[1]),
            nm(report.truth_rms_m[2]),
            s.revolutions,
            s.per_rev,
            nm(s.probe_noise_rms_m)
        );
        println!("  RMS error of the recovered          artefact        X        Y   (nm)");
        let row = |name: String, r: &Recovery| {
            println!(
                "  {name:<34} {:>8.3} {:>8.3} {:>8.3}",
                nm(r.artefact_rms_error_m),
                nm(r.x_rms_error_m),
                nm(r.y_rms_error_m)
            )
        };
        for (i, set) in report.sets.iter().enumerate() {
            row(
                format!(
                    "set #{} (min |H| {:.3} at {} UPR)",
                    i + 1,
                    set.min_weighting,
                    set.min_weighting_upr
                ),
                &set.alone,
            );
            row(format!("set #{} modified", i + 1), &set.modified);
        }
        row("least-squares synthesis".into(), &report.synthesised);
        println!(
            "  predicted noise floor of the synthesis {:.3} nm; spread between the sets {:.3} → {:.3} nm after modification",
            nm(report.predicted_noise_m),
            nm(report.spread_m[0]),
            nm(report.spread_m[1])
        );
        print_written(&written);
        Ok(ExitCode::SUCCESS)
    }
}
