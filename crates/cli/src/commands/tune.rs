//! `servo tune`: the PID tuned for the largest integral gain under Ms, Mt and a bandwidth.

use crate::args::PlantArgs;
use crate::output::{print_json, CliError};
use clap::Args;
use runner::Plan;
use std::path::PathBuf;
use std::process::ExitCode;

/// Tune the PID (eq 7-8) for the largest integral gain under Ms, Mt and a bandwidth.
///
/// On the simulator's exact sampled plant: the largest integral gain (best low-frequency
/// disturbance rejection) with |S| ≤ Ms and |T| ≤ Mt everywhere and |T| ≥ −3 dB at the
/// bandwidth, by convex-concave programming (clarabel LPs); compared with the configured
/// (thesis Ch. 7) gains. Example: servo tune --bandwidth-hz 1000 --ms 1.5
#[derive(Args, Debug)]
pub struct TuneCmd {
    #[command(flatten)]
    plant: PlantArgs,
    /// Closed-loop bandwidth to reach (|T| ≥ −3 dB there), Hz.
    #[arg(value_parser = crate::args::finite, long, default_value_t = 1000.0)]
    bandwidth_hz: f64,
    /// Sensitivity peak bound Ms (1 < Ms < 10).
    #[arg(value_parser = crate::args::finite, long, default_value_t = 1.5)]
    ms: f64,
    /// Complementary sensitivity peak bound Mt (1 < Mt < 10).
    #[arg(value_parser = crate::args::finite, long, default_value_t = 1.3)]
    mt: f64,
    /// Run-config fragment with the tuned gains (`servo run -c FILE`).
    #[arg(short, long, default_value = "pid.toml")]
    out: PathBuf,
    /// Replace the output file if it exists.
    #[arg(long)]
    overwrite: bool,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

impl TuneCmd {
    /// Tunes, writes the fragment and prints the comparison.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let plan = Plan::new(&self.plant.load()?)?;
        let (ms, mt, bw) = (self.ms, self.mt, self.bandwidth_hz);
        let r = studies::tune::tune(&plan, bw, ms, mt)?;
        let out = &self.out;
        crate::output::write_result(out, &r.to_toml(), self.overwrite)?;
        if self.json {
            print_json(&r);
            return Ok(ExitCode::SUCCESS);
        }
        println!(
            "PID tuned for max ki with |S| ≤ {ms}, |T| ≤ {mt}, |T| ≥ −3 dB at {bw:.0} Hz ({} LPs), on the exact sampled plant:",
            r.iterations
        );
        println!(
            "  {:<10} {:>8} {:>9} {:>10} {:>7} {:>7} {:>9} {:>9} {:>11} {:>9}",
            "",
            "kp",
            "ki 1/s",
            "kd s",
            "max|S|",
            "max|T|",
            "cross Hz",
            "T bw Hz",
            "follow nm",
            "true nm"
        );
        for (name, p) in [("configured", &r.reference), ("tuned", &r.tuned)] {
            println!(
                "  {:<10} {:>8.4} {:>9.1} {:>10.3e} {:>7.3} {:>7.3} {:>9.0} {:>9.0} {:>11.3} {:>9.3}",
                name,
                p.kp,
                p.ki,
                p.kd,
                p.max_sensitivity,
                p.max_complementary,
                p.crossover_hz,
                p.bandwidth_hz,
                p.following_rms_m * 1e9,
                p.true_rms_m * 1e9
            );
        }
        println!(
            "  integral gain {:.2}× the configured one; wrote {} — run it: servo run -c {}",
            r.tuned.ki / r.reference.ki,
            out.display(),
            out.display()
        );
        Ok(ExitCode::SUCCESS)
    }
}
