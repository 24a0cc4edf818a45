//! `servo synth h2`: design an H2-optimal controller and write a controller file.

use crate::args::PlantArgs;
use crate::output::{print_json, print_margins, CliError};
use clap::{Args, ValueEnum};
use runner::Plan;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::synth::{self, SynthRequest, SynthWeights};

/// Design an H2-optimal controller and write a controller file (thesis Ch. 6).
///
/// `h2`: the H2-optimal controller on the simulator's exact discrete model at the configured
/// servo rate (thesis Ch. 6): minimises the true tool error given the sensor, current, base
/// and converter noise, knowing the loop delay; writes a controller file for
/// `servo run --controller ss --ss-file FILE`.
/// Example: servo synth h2 --rate 20000 --mass heavy --out h2.toml
#[derive(Args, Debug)]
pub struct SynthCmd {
    /// Method (only `h2` so far).
    #[arg(value_enum)]
    method: SynthMethod,
    #[command(flatten)]
    plant: PlantArgs,
    /// Weight of 1 V of command against 1 nm of tool error (ρ, nm/V): larger = gentler.
    /// Default 1 (exact); with `--weights thesis` it weighs a volt above the Wu corner,
    /// default 1000 (loop-gain crossover ≈ 1 kHz on the heavy stage; thesis: 870 Hz).
    #[arg(value_parser = crate::args::finite, long)]
    effort_weight: Option<f64>,
    /// Scale of the sensor noise the exact design assumes (RMS; 1 = the plant's, H2-optimal):
    /// below 1 the design trusts the sensor more and closes a faster loop. `servo study`'s
    /// `h2-bandwidth` family records the scale that met its bandwidth (column design_value).
    #[arg(value_parser = crate::args::finite, long, default_value_t = 1.0)]
    sensor_noise_scale: f64,
    /// Reduce the controller to this many states by balanced truncation (thesis Table 6-1:
    /// 8, 13; default: full order).
    #[arg(long)]
    order: Option<usize>,
    /// Design problem.
    #[arg(long, value_enum, default_value = "exact")]
    weights: Weights,
    /// Controller file to write.
    #[arg(short, long, default_value = "h2.toml")]
    out: PathBuf,
    /// Replace the output file if it exists.
    #[arg(long)]
    overwrite: bool,
    /// Print the design's predictions as JSON.
    #[arg(long)]
    json: bool,
}

/// Synthesis methods.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum SynthMethod {
    /// H2-optimal output feedback (discrete, exact model).
    H2,
}

/// The H2 design problem.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum Weights {
    /// The simulator's exact discrete model and noise; true tool error (nm) and ρ·u penalised.
    Exact,
    /// §6.3 / Fig 6-3: the continuous model with We (eq 6-3, Ms of eq 6-4 at ξ = 0.707), ρ·Wu
    /// (eq 6-5), Ws, Wi, Wg, Wfc, discretised with the loop delay.
    Thesis,
}

impl SynthCmd {
    /// Designs, writes the file and predicts the loop it closes.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let SynthMethod::H2 = self.method;
        let plan = Plan::new(&self.plant.load()?)?;
        let weights = match self.weights {
            Weights::Exact => SynthWeights::Exact {
                effort_weight: self.effort_weight.unwrap_or(1.0),
                sensor_noise_scale: self.sensor_noise_scale,
            },
            Weights::Thesis => SynthWeights::Thesis {
                effort_weight: self.effort_weight.unwrap_or(1000.0),
            },
        };
        let request = SynthRequest {
            weights,
            order: self.order,
        };
        let s = synth::synthesize(&plan, &request)?;
        crate::output::write_result(&self.out, &s.design.to_toml(), self.overwrite)?;
        let p = &s.prediction;
        for w in &p.warnings {
            eprintln!("warning: {w}");
        }
        if self.json {
            print_json(&serde_json::json!({ "prediction": p, "file": self.out }));
            return Ok(ExitCode::SUCCESS);
        }
        if let Some((full, hankel, bound)) = &s.reduction {
            let shown: Vec<String> = hankel.iter().take(16).map(|h| format!("{h:.2e}")).collect();
            println!(
                "Hankel singular values of the {full}-state controller: {} …",
                shown.join(" ")
            );
            println!(
                "  kept {} states; H∞ error bound of the controller {bound:.3e}",
                p.states
            );
            if let Some(asked) = self.order.filter(|&o| o > p.states) {
                println!(
                    "  (asked for {asked}: the controller's minimal realisation has {} states — the other Hankel singular values are below n·ε·σ_max: states no input reaches or no output sees)",
                    p.states
                );
            }
        }
        println!(
            "H2 controller: {} states at {:.0} Hz (thesis §6.4.1: 27)",
            p.states, p.sample_rate_hz
        );
        println!(
            "  closed loop: spectral radius {:.6}, bandwidth {:.0} Hz",
            p.spectral_radius, p.bandwidth_hz
        );
        print_margins(&s.plan);
        println!(
            "  output scales allowed while running: {:.4}..={:.4}",
            p.stability.low(),
            p.stability.high()
        );
        println!(
            "  predicted RMS: following {:.3} nm, true {:.3} nm",
            p.following_rms_m * 1e9,
            p.true_rms_m * 1e9
        );
        // The same plant flags the design was made with: the file refuses any other plant.
        let out = &self.out;
        println!(
            "  wrote {} — run it: servo run --controller ss --ss-file {}{}",
            out.display(),
            out.display(),
            self.plant.flags()
        );
        Ok(ExitCode::SUCCESS)
    }
}
