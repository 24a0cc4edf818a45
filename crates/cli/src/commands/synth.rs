//! `servo synth h2`: design an H2-optimal controller and write a controller file.

use crate::args::PlantArgs;
use crate::output::{print_json, print_margins, CliError};
use clap::{Args, ValueEnum};
use runner::config::{ControllerConfig, ControllerKind, Origin};
use runner::Plan;
use servo_runtime::MAX_SS_ORDER;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::budget::Budget;
use studies::synth::{self, ThesisWeights};
use studies::StudyError;

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
    #[arg(long)]
    effort_weight: Option<f64>,
    /// Scale of the sensor noise the exact design assumes (RMS; 1 = the plant's, H2-optimal):
    /// below 1 the design trusts the sensor more and closes a faster loop. `servo study`'s
    /// `h2-bandwidth` family records the scale that met its bandwidth (column design_value).
    #[arg(long, default_value_t = 1.0)]
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

/// What `servo synth` predicts for the loop its controller closes.
#[derive(Debug, serde::Serialize)]
struct Prediction {
    states: usize,
    sample_rate_hz: f64,
    spectral_radius: f64,
    bandwidth_hz: f64,
    following_rms_m: f64,
    true_rms_m: f64,
    file: PathBuf,
}

impl SynthCmd {
    /// Designs, writes the file and predicts the loop it closes.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let SynthMethod::H2 = self.method;
        let scale = self.sensor_noise_scale;
        if !(scale > 0.0 && scale.is_finite()) {
            return Err(Origin::default()
                .invalid(
                    "--sensor-noise-scale",
                    scale,
                    "> 0 (1: the plant's sensor noise)",
                )
                .into());
        }
        let plan = Plan::new(&self.plant.load()?)?;
        let mut design = match self.weights {
            Weights::Exact => synth::h2_design_with(
                &plan,
                self.effort_weight.unwrap_or(1.0),
                self.sensor_noise_scale,
            )?,
            Weights::Thesis => synth::thesis_design(
                &plan,
                &ThesisWeights::default(),
                self.effort_weight.unwrap_or(1000.0),
            )?,
        };
        let full = design.controller.nx();
        let writable = full.min(MAX_SS_ORDER);
        if let Some(n) = self.order.filter(|n| !(1..=writable).contains(n)) {
            return Err(Origin::default()
                .invalid(
                    "--order",
                    n,
                    &format!(
                        "1..={writable} states (the design has {full}; a controller file holds at most {MAX_SS_ORDER})"
                    ),
                )
                .into());
        }
        if self.order.is_none() && full > MAX_SS_ORDER {
            return Err(Origin::default()
                .invalid(
                    "--order",
                    "none (full order)",
                    &format!(
                        "1..={MAX_SS_ORDER} states: the full-order design has {full}, more than a controller file holds"
                    ),
                )
                .into());
        }
        if let Some(n) = self.order {
            let (reduced, hankel, bound) = design.reduced(n)?;
            if !self.json {
                let shown: Vec<String> =
                    hankel.iter().take(16).map(|h| format!("{h:.2e}")).collect();
                println!(
                    "Hankel singular values of the {}-state controller: {} …",
                    design.controller.nx(),
                    shown.join(" ")
                );
                println!("  kept {n} states; H∞ error bound of the controller {bound:.3e}");
            }
            design = reduced;
        }
        let out = &self.out;
        crate::output::write_result(out, &design.to_toml(), self.overwrite)?;
        // Predict what it does with the budget of the loop it closes.
        let with = plan.with_controller(ControllerConfig {
            kind: ControllerKind::Ss,
            ss_file: Some(std::fs::canonicalize(out).unwrap_or(out.to_owned())),
            ..plan.config.controller.clone()
        })?;
        let cl = &with.closed_loop;
        let b = Budget::new(cl, 400).map_err(StudyError::from)?;
        let p = Prediction {
            states: design.controller.nx(),
            sample_rate_hz: design.sample_rate_hz,
            spectral_radius: cl.spectral_radius(),
            bandwidth_hz: b.bandwidth_hz,
            following_rms_m: b.following_rms_m,
            true_rms_m: b.true_rms_m,
            file: out.clone(),
        };
        if self.json {
            print_json(&p);
            return Ok(ExitCode::SUCCESS);
        }
        println!(
            "H2 controller: {} states at {:.0} Hz (thesis §6.4.1: 27)",
            p.states, p.sample_rate_hz
        );
        println!(
            "  closed loop: spectral radius {:.6}, bandwidth {:.0} Hz",
            p.spectral_radius, p.bandwidth_hz
        );
        print_margins(&with);
        println!(
            "  predicted RMS: following {:.3} nm, true {:.3} nm",
            p.following_rms_m * 1e9,
            p.true_rms_m * 1e9
        );
        // The same plant flags the design was made with: the file refuses any other plant.
        println!(
            "  wrote {} — run it: servo run --controller ss --ss-file {}{}",
            out.display(),
            out.display(),
            self.plant.flags()
        );
        Ok(ExitCode::SUCCESS)
    }
}
