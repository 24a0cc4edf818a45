//! `servo identify`: the Table 5-2 stage parameters from an open-loop FRF.

use crate::args::PlantArgs;
use crate::output::{print_json, CliError};
use clap::Args;
use runner::Plan;
use std::path::PathBuf;
use std::process::ExitCode;

/// Identify the Table 5-2 stage parameters from an open-loop FRF (thesis §5.5.3).
///
/// Fits m1 + m2, k2, c2, m4, k4, c4 from an open-loop FRF CSV (as `servo frf --loop open`
/// writes), with the simulator's exact sampled model as the grey box, starting from the
/// configured stage; writes the identified plant as a config fragment (`--out`) that `servo
/// tune`, `servo synth` and `servo run` take with `-c`.
/// Example: servo frf --loop open --points 80 && servo identify frf/frf.csv && servo tune --plant model.toml
#[derive(Args, Debug)]
pub struct IdentifyCmd {
    /// FRF CSV with columns freq_hz, magnitude_m_per_v, phase_deg (clipped rows skipped).
    file: PathBuf,
    #[command(flatten)]
    plant: PlantArgs,
    /// The identified plant as a config fragment the other commands take (`-c FILE`).
    #[arg(short, long, default_value = "model.toml")]
    out: PathBuf,
    /// Replace the output file if it exists.
    #[arg(long)]
    overwrite: bool,
    /// Print the result as JSON.
    #[arg(long)]
    json: bool,
}

impl IdentifyCmd {
    /// Fits and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let plan = Plan::new(&self.plant.load()?)?;
        let nyquist_hz = plan.config.plant.timing.servo_rate_hz / 2.0;
        let frf = run_config::frf_file::read_frf(&self.file, nyquist_hz)
            .map_err(studies::StudyError::from)?;
        let id = studies::identify::identify_measured(&plan, &frf)?;
        let source = &frf.source;
        crate::output::write_result(&self.out, &id.model_toml(&plan, source), self.overwrite)?;
        if self.json {
            print_json(&id);
            return Ok(ExitCode::SUCCESS);
        }
        println!(
            "Grey-box fit to {} ({} points, {} iterations): fit {:.2} % (thesis §5.5.3: 97.7 %), {:.2} % on relative errors",
            self.file.display(),
            id.points,
            id.iterations,
            id.fit_percent,
            id.weighted_fit_percent
        );
        println!(
            "  {:<12} {:>13} {:>9} {:>13}",
            "Table 5-2", "fitted", "1σ", "start"
        );
        for i in 0..id.names.len() {
            println!(
                "  {:<12} {:>13.5e} {:>8.2}% {:>13.5e}",
                id.names[i],
                id.fitted[i],
                100.0 * id.rel_std[i],
                id.start[i]
            );
        }
        for m in &id.misfits {
            println!(
                "  NOT EXPLAINED by the four-mass model: {}: an unmodelled resonance or a disturbed measurement",
                band(m)
            );
        }
        println!("  {}", id.uncertainty_note());
        for (r, site) in id.extra_modes.iter().zip(&id.sites) {
            println!(
                "  fitted beside the stage: {} — in the model, {}",
                id.describe_mode(r),
                studies::identify::describe_site(site)
            );
        }
        for m in &id.left_out {
            println!("  left out of the fit with its modes: {}", band(m));
        }
        if id.extra_modes.is_empty() && !id.misfits.is_empty() {
            println!("  those points were left out of the fit");
        }
        println!(
            "  wrote {} — the identified plant: servo tune --plant {0}, servo synth h2 --plant {0}",
            self.out.display()
        );
        Ok(ExitCode::SUCCESS)
    }
}

/// A band of points the fit could not explain, as printed: `100 – 200 Hz (3 points, up to
/// +4.5 dB / 77 %)`.
fn band(m: &studies::identify::Misfit) -> String {
    format!(
        "{:.0} – {:.0} Hz ({} point{}, up to {:+.1} dB / {:.0} %)",
        m.from_hz,
        m.to_hz,
        m.points,
        if m.points == 1 { "" } else { "s" },
        m.worst_db,
        100.0 * m.worst_relative
    )
}
