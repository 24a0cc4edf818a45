//! `servo budget`: the loop's error budget, and the bandwidth sweep of Fig 5-14.

use crate::args::{ControllerArgs, PlantArgs};
use crate::output::{points_bar, print_json, print_margins, print_written, CliError};
use clap::Args;
use runner::Plan;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::budget::Budget;
use studies::sweep::{self, Sweep, SweepTuning, THESIS_BANDWIDTHS_HZ};
use studies::StudyError;

/// Error budget of the loop: per-source RMS and PSD, CAS, bandwidth sweep (thesis §5.7.2).
///
/// Eq 5-13..5-17: each noise source's RMS and PSD in the following error (what the sensor
/// reports) and the true tool error, their CAS; with --sweep the RMS errors against
/// closed-loop bandwidth for both stage masses (Fig 5-14), the PID gains scaled together or
/// (--retune) re-tuned at every bandwidth as §5.6 did.
/// Example: servo budget --mass heavy --sweep --retune --validate 1
#[derive(Args, Debug)]
pub struct BudgetCmd {
    #[command(flatten)]
    plant: PlantArgs,
    #[command(flatten)]
    controller: ControllerArgs,
    /// Sweep the closed-loop bandwidth for the 0.074 and 0.174 kg stages (the PID gains scaled
    /// together, or re-tuned with --retune).
    #[arg(long)]
    sweep: bool,
    /// Re-tune the PID at every point instead of scaling the configured gains: the sweep's
    /// frequencies are then loop-gain crossovers, each PID shaped by the rule §5.6 cites
    /// (integrator at fc/10, lead from fc/3 to 3·fc, |L(fc)| = 1).
    #[arg(long, requires = "sweep")]
    retune: bool,
    /// Bandwidths of the sweep in Hz: −3 dB bandwidths, or loop-gain crossovers with --retune
    /// (default: Fig 5-14's).
    #[arg(long, value_delimiter = ',')]
    bandwidths: Option<Vec<f64>>,
    /// Also simulate every sweep point for this many seconds and print both.
    #[arg(value_parser = crate::args::finite, long, requires = "sweep")]
    validate: Option<f64>,
    /// Noise seed of the --validate simulations.
    #[arg(long, requires = "validate")]
    seed: Option<u64>,
    /// Output directory for CSV, JSON, PNG and SVG.
    #[arg(long, default_value = "budget")]
    out_dir: PathBuf,
    /// Frequency points of the spectra (log-spaced, 1 Hz to Nyquist).
    #[arg(long, default_value_t = 2000)]
    points: usize,
    /// Print the budget (and the sweeps) as JSON.
    #[arg(long)]
    json: bool,
}

impl BudgetCmd {
    /// Computes, writes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let mut l = self.plant.load()?;
        self.controller.apply(&mut l.config.controller);
        crate::args::set(&mut l.config.run.seed, self.seed);
        let plan = Plan::new(&l)?;
        let a = studies::budget::analyse(&plan, self.points)?;
        let (b, title) = (&a.budget, &a.title);
        let made = (&a.made_for, plan.controller.description.as_str());
        let written = reports::budget::write(b, title, made, a.margins.as_ref(), &self.out_dir)
            .map_err(StudyError::from)?;
        let sweeps = if self.sweep {
            Some(self.sweeps(&plan)?)
        } else {
            None
        };
        if self.json {
            print_json(&serde_json::json!({ "budget": b, "margins": a.margins, "sweeps": sweeps }));
            return Ok(ExitCode::SUCCESS);
        }
        print_budget(&plan, b, title);
        print_written(&written);
        if let Some(s) = &sweeps {
            print_sweeps(s, self.validate.is_some());
            print_written(&reports::sweep::write(s, &self.out_dir).map_err(StudyError::from)?);
        }
        Ok(ExitCode::SUCCESS)
    }

    fn sweeps(&self, plan: &Plan) -> Result<Vec<Sweep>, StudyError> {
        let targets = self
            .bandwidths
            .clone()
            .unwrap_or(THESIS_BANDWIDTHS_HZ.to_vec());
        let bar = points_bar(2 * targets.len(), "sweeping", "points");
        let tuning = if self.retune {
            SweepTuning::Retuned
        } else {
            SweepTuning::Scaled
        };
        let sweeps = sweep::thesis_sweeps(plan, &targets, tuning, self.validate, &mut |done, _| {
            bar.set_position(done as u64)
        });
        bar.finish_and_clear();
        sweeps
    }
}

fn print_budget(plan: &Plan, b: &Budget, title: &str) {
    println!("Error budget (thesis §5.7.2): {title}");
    println!(
        "  closed-loop bandwidth {:.1} Hz; RMS in nm, sources independent (powers add)",
        b.bandwidth_hz
    );
    print_margins(plan);
    println!("  {:<14} {:>10} {:>10}", "source", "following", "true");
    for c in &b.contributions {
        println!(
            "  {:<14} {:>10.4} {:>10.4}",
            c.source,
            c.following_rms_m * 1e9,
            c.true_rms_m * 1e9
        );
    }
    println!(
        "  {:<14} {:>10.4} {:>10.4}",
        "total",
        b.following_rms_m * 1e9,
        b.true_rms_m * 1e9
    );
}

fn print_sweeps(results: &[Sweep], validated: bool) {
    let how = match results.first().map(|s| s.tuning) {
        Some(SweepTuning::Retuned) => {
            "PID loop-shaped at each crossover (fc/10, fc/3, 3·fc)".to_owned()
        }
        _ => "PID gains scaled".to_owned(),
    };
    println!(
        "Bandwidth sweep (thesis Fig 5-14), {how}; RMS in nm (predicted{})",
        if validated { " / simulated" } else { "" }
    );
    for s in results {
        for p in &s.points {
            let sim = |v: Option<f64>| v.map_or(String::new(), |x| format!(" / {:.3}", x * 1e9));
            println!(
                "  {} {:>7.1} Hz (Kp {:.4}, Ki {:.1}, Kd {:.3e}): following {:.3}{}   true {:.3}{}",
                s.label,
                p.bandwidth_hz,
                p.pid.kp,
                p.pid.ki,
                p.pid.kd,
                p.predicted_following_m * 1e9,
                sim(p.simulated_following_m),
                p.predicted_true_m * 1e9,
                sim(p.simulated_true_m)
            );
        }
        for (target, reason) in &s.unreached {
            println!("  {} {target:>7.1} Hz: not reached — {reason}", s.label);
        }
        println!(
            "  {}: lowest following error at {}; lowest true error at {} (thesis: 874 Hz for 0.074 kg, 468 Hz for 0.174 kg)",
            s.label,
            s.optimum_following.describe(),
            s.optimum_true.describe()
        );
    }
}
