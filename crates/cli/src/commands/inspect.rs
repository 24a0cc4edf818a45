//! `servo inspect`: the summary of a recording, and the form report of a machining run.

use super::machine::print_form;
use crate::output::{print_json, print_summary, CliError};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

/// Recompute and print the summary of a recording. Example: servo inspect run.mcap
#[derive(Args, Debug)]
pub struct InspectCmd {
    /// The MCAP file written by `servo run`.
    file: PathBuf,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
}

impl InspectCmd {
    /// Reads, recomputes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let (loaded, rec) = runner::recording::read_run(&self.file)?;
        let summary = runner::recording::summarise(&loaded, &rec);
        let form = studies::form::from_recording(&loaded, &rec)?.map(|a| a.report());
        if self.json {
            match form {
                Some(f) => print_json(&serde_json::json!({ "summary": summary, "form": f })),
                None => print_json(&summary),
            }
            return Ok(ExitCode::SUCCESS);
        }
        print_summary(&summary, false);
        if let Some(f) = &form {
            print_form(f);
        }
        Ok(ExitCode::SUCCESS)
    }
}
