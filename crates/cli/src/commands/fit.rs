//! `servo fit`: a rational model of a measured open-loop FRF, and the modes the plant lacks.

use crate::args::PlantArgs;
use crate::output::{print_json, print_written, CliError};
use clap::Args;
use runner::Plan;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::StudyError;

/// Fit a stable rational model to a measured open-loop FRF and add the modes the plant lacks.
///
/// Vector fitting in z (stable poles, each bin weighted by its uncertainty); the order is the
/// smallest whose residual is the measurement's noise, unless --order is given. The fit's
/// resonances are set beside the configured plant's (identify it first: `servo identify`);
/// a lightly damped one the plant lacks is fitted onto it as an extra mode and written, with
/// the plant, into a config fragment the other commands take (`--plant fitted.toml`).
/// Example: servo identify frf/frf.csv && servo fit frf/frf.csv --plant model.toml
#[derive(Args, Debug)]
pub struct FitCmd {
    /// FRF CSV as `servo frf --loop open` writes it (the uncertainty_m_per_v column is needed).
    file: PathBuf,
    #[command(flatten)]
    plant: PlantArgs,
    /// The plant with the extra modes found, as a config fragment (`--plant FILE`).
    #[arg(short, long, default_value = "fitted.toml")]
    out: PathBuf,
    /// Replace the output file if it exists.
    #[arg(long)]
    overwrite: bool,
    /// Fit this many poles (1–60) instead of choosing the order.
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=60))]
    order: Option<u8>,
    /// Largest order the search tries (2–60).
    #[arg(long, default_value_t = 30, value_parser = clap::value_parser!(u8).range(2..=60))]
    max_order: u8,
    /// Output directory for fit.csv, fit.json and the plot.
    #[arg(long, default_value = "fit")]
    out_dir: PathBuf,
    /// Print the result as JSON.
    #[arg(long)]
    json: bool,
}

impl FitCmd {
    /// Fits, writes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let plan = Plan::new(&self.plant.load()?)?;
        let nyquist_hz = plan.config.plant.timing.servo_rate_hz / 2.0;
        let frf =
            run_config::frf_file::read_frf(&self.file, nyquist_hz).map_err(StudyError::from)?;
        let fit = studies::fit::fit_frf(
            &plan,
            &frf,
            self.order.map(usize::from),
            usize::from(self.max_order),
        )?;
        let (lo, hi) = (frf.freq_hz[0], frf.freq_hz[frf.freq_hz.len() - 1]);
        let model = studies::frf::model_curve(&plan, studies::frf::FrfLoop::Open, lo, hi, 600)?;
        let written =
            reports::fit::write(&frf, &fit, &model, &self.out_dir).map_err(StudyError::from)?;
        crate::output::write_result(
            &self.out,
            &fit.model_toml(&plan, &frf.source),
            self.overwrite,
        )?;
        if self.json {
            print_json(&fit);
            return Ok(ExitCode::SUCCESS);
        }
        println!(
            "Rational fit of {} ({} bins): order {}, {:.1} % of the bins within their 95 % disk (95 % expected), weighted RMS {:.2} (1 is the noise)",
            self.file.display(),
            frf.freq_hz.len(),
            fit.order,
            100.0 * fit.within,
            fit.weighted_rms
        );
        for r in &fit.resonances {
            println!(
                "  resonance {:>8.1} Hz  ζ {:.4}  {}",
                r.hz,
                r.zeta,
                r.in_model
                    .as_deref()
                    .map_or("NOT in the plant model".to_owned(), |m| format!(
                        "the model's {m}"
                    ))
            );
        }
        for (m, site) in fit.extra_modes.iter().zip(&fit.sites) {
            println!(
                "  extra mode: {:.1} Hz (ζ {:.4}), zeros {:.1} Hz (ζ {:.4}), {:+.1} dB — added {}",
                m.hz,
                m.zeta,
                m.zero_hz,
                m.zero_zeta,
                m.peak_db(),
                studies::identify::describe_site(site)
            );
        }
        if fit.extra_modes.is_empty() {
            println!("  the plant model lacks no mode the measurement shows");
        }
        println!(
            "  wrote {} — the plant with its extra modes: servo tune --plant {0}, servo synth h2 --plant {0}",
            self.out.display()
        );
        print_written(&written);
        Ok(ExitCode::SUCCESS)
    }
}
