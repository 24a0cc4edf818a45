//! `servo deploy`: the deployment a daemon embeds.

use crate::args::RunArgs;
use crate::output::{print_margins, CliError};
use clap::Args;
use runner::stall::{survivable, MAX_STALL_S};
use runner::{Plan, RunError};
use std::path::PathBuf;
use std::process::ExitCode;

/// Write the deployment a daemon embeds (`servo_runtime::Servo::from_file`).
///
/// Resolves the run configuration, designs what the loop needs offline (ZPETC feedforward),
/// checks the sampled closed loop on the plant model and stores its output-scale range, and
/// writes every coefficient with the plant and rate it was made for.
/// Example: servo deploy --controller accel --ka 1 --kg-scaling --mass heavy -o deploy.toml
#[derive(Args, Debug)]
pub struct DeployCmd {
    #[command(flatten)]
    run: RunArgs,
    /// Deployment file to write.
    #[arg(short, long, default_value = "deploy.toml")]
    out: PathBuf,
    /// Replace the output file if it exists.
    #[arg(long)]
    overwrite: bool,
}

impl DeployCmd {
    /// Checks, writes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let plan = Plan::new(&self.run.load()?)?;
        let (d, text) = runner::deploy::deployment_file(&plan)?;
        crate::output::write_result(&self.out, &text, self.overwrite)?;
        let s = d.stability.expect("a deployment is checked");
        println!("Deployment: {}", plan.controller.description);
        println!(
            "  closed loop stable on the plant model: spectral radius {:.6}",
            s.spectral_radius
        );
        print_margins(&plan);
        println!(
            "  output scales allowed while running: {:.4}..={:.4} (unstable below {:.4} and from {:.4})",
            s.low(),
            s.high(),
            s.unstable_below,
            s.unstable_above
        );
        print_survivable_stall(&plan)?;
        println!(
            "  wrote {} — embed it: Servo::from_file(\"{}\")",
            self.out.display(),
            self.out.display()
        );
        Ok(ExitCode::SUCCESS)
    }
}

/// The stall the stage rides out with the DAC held (a daemon's loop that stops: the DAC keeps
/// its last value), for the daemon's host to be qualified against.
fn print_survivable_stall(plan: &Plan) -> Result<(), CliError> {
    let (what, predicted) = match survivable(plan, plan.config.realtime.peer_timeout_s) {
        Ok(s) => match (s.physics_s(), s.physics_limit) {
            (Some(p), Some(limit)) => (
                format!("up to {:.1} µs ({})", p * 1e6, limit.describe()),
                true,
            ),
            _ => (format!("more than {:.0} ms", MAX_STALL_S * 1e3), true),
        },
        Err(RunError::StallAnalysis(why)) => (format!("not predicted: {why}"), false),
        Err(e) => return Err(e.into()),
    };
    println!(
        "  a stalled loop (DAC held): the stage rides out {what}; qualify the daemon's host with servo latency"
    );
    if predicted && plan.measured.is_some() {
        println!(
            "    (predicted on the plant model: a stall is a transient from the loop's state, which the measured FRF does not give)"
        );
    }
    Ok(())
}
