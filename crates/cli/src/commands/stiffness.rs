//! `servo stiffness`: dynamic compliance at the tool with acceleration feedback.

use crate::args::{AccelArgs, PlantArgs};
use crate::output::{print_json, print_written, CliError};
use clap::Args;
use runner::Plan;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::intermittent::THESIS_KAS;
use studies::stiffness::{self, ComplianceCurve};
use studies::StudyError;

/// Dynamic compliance X/dF at the tool with acceleration feedback (eq 7-9).
///
/// Thesis eq 7-9, Table 7-1: analytic and from the simulator's sampled loop, for a list of
/// Ka, PID gains fixed or scaled by 1/Kg (§7.4.1).
/// Example: servo stiffness --kas 0,0.5,1,4 --kg-scaling --mass heavy
#[derive(Args, Debug)]
pub struct StiffnessCmd {
    #[command(flatten)]
    plant: PlantArgs,
    #[command(flatten)]
    accel: AccelArgs,
    /// Acceleration gains (V/V; default §7.5's 0, 0.5, 1, 4).
    #[arg(long, value_delimiter = ',')]
    kas: Option<Vec<f64>>,
    /// Frequencies from 10 Hz to this (Hz), log-spaced.
    #[arg(value_parser = crate::args::finite, long, default_value_t = 10000.0)]
    to: f64,
    /// Output directory for CSV, JSON, PNG and SVG.
    #[arg(long, default_value = "stiffness")]
    out_dir: PathBuf,
    /// Print the curves as JSON.
    #[arg(long)]
    json: bool,
}

impl StiffnessCmd {
    /// Computes, writes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let mut l = self.plant.load()?;
        self.accel.apply(&mut l.config.controller);
        let plan = Plan::new(&l)?;
        let kg = plan.config.controller.kg_scaling;
        let freqs = lti::spectral::log_space(10.0, self.to, 200);
        let kas = self.kas.clone().unwrap_or(THESIS_KAS.to_vec());
        let curves = stiffness::compliance(&plan, &kas, kg, &freqs)?;
        let written =
            reports::stiffness::write(&curves, &self.out_dir).map_err(StudyError::from)?;
        if self.json {
            print_json(&curves);
            return Ok(ExitCode::SUCCESS);
        }
        print_table(&curves, kg);
        print_written(&written);
        Ok(ExitCode::SUCCESS)
    }
}

fn print_table(curves: &[ComplianceCurve], kg_scaling: bool) {
    println!(
        "Dynamic compliance at the tool (eq 7-9), {} PID gains:",
        if kg_scaling { "Kg-scaled" } else { "fixed" }
    );
    let at = |c: &ComplianceCurve, f: f64| {
        let i = c
            .freq_hz
            .iter()
            .position(|&x| x >= f)
            .unwrap_or(c.freq_hz.len() - 1);
        c.sampled_m_per_n[i] * 1e6
    };
    println!(
        "  {:>5} {:>8} {:>10} {:>10} {:>10} {:>10} {:>10}  (µm/N)",
        "Ka", "PID ×", "10 Hz", "100 Hz", "1 kHz", "5 kHz", "Δ dB"
    );
    for c in curves {
        let worst = c
            .analytic_m_per_n
            .iter()
            .zip(&c.sampled_m_per_n)
            .map(|(a, b)| (20.0 * libm::log10(a / b)).abs())
            .fold(0.0, f64::max);
        println!(
            "  {:>5} {:>8.3} {:>10.4} {:>10.4} {:>10.4} {:>10.4} {:>10.3}{}",
            c.ka,
            c.pid_scale,
            at(c, 10.0),
            at(c, 100.0),
            at(c, 1000.0),
            at(c, 5000.0),
            worst,
            if c.stable() {
                String::new()
            } else {
                format!("  UNSTABLE (spectral radius {:.4})", c.spectral_radius)
            }
        );
    }
}
