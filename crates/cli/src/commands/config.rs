//! `servo config`: the fully resolved configuration of a run.

use crate::args::RunArgs;
use crate::output::{print_json, CliError};
use clap::Args;
use runner::Plan;
use std::process::ExitCode;

/// Show the fully resolved configuration (every number) after the file and the flags.
///
/// The configuration is checked as a run would check it (every value, the stage, the
/// controller and any controller file or surface image). Example: servo config --dump --mass heavy
#[derive(Args, Debug)]
pub struct ConfigCmd {
    #[command(flatten)]
    run: RunArgs,
    /// Print the whole resolved configuration (the default action).
    #[arg(long)]
    dump: bool,
    /// As JSON instead of TOML.
    #[arg(long)]
    json: bool,
    /// Print the configuration's JSON Schema instead: every key with its type, default,
    /// description and (numbers) the range a run allows, as `x-allowed`.
    #[arg(long, conflicts_with_all = ["dump", "json"])]
    schema: bool,
}

impl ConfigCmd {
    /// Resolves, checks and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        if self.schema {
            print_json(&runner::schema::schema());
            return Ok(ExitCode::SUCCESS);
        }
        let plan = Plan::new(&self.run.load()?)?;
        if self.json {
            print_json(&plan.config);
        } else {
            print!("{}", plan.config.to_toml());
        }
        Ok(ExitCode::SUCCESS)
    }
}
