//! `servo thesis`: the thesis's headline numbers beside this model's.

use crate::output::{points_bar, print_json, print_written, CliError};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;
use studies::thesis;
use studies::StudyError;

/// Every headline number of thesis Chapters 5–8 beside this model's value
///
/// For the same experiment as the thesis (budgets, re-tuned sweeps, an H2 synthesis, intermittent and machining
/// simulations; ≈ 7 s), with the section and the reason for any difference. Writes
/// `thesis.md` (the thesis map's table in the book) and `thesis.json`.
/// Example: servo thesis
#[derive(Args, Debug)]
pub struct ThesisCmd {
    /// Output directory.
    #[arg(long, default_value = "thesis")]
    out_dir: PathBuf,
    /// Print the rows as JSON.
    #[arg(long)]
    json: bool,
}

impl ThesisCmd {
    /// Computes, writes and prints.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let bar = points_bar(7, "comparing", "experiments");
        let comparison = thesis::comparison(&mut |done, _| bar.set_position(done as u64));
        bar.finish_and_clear();
        let comparison = comparison?;
        let written = thesis::write(&comparison, &self.out_dir).map_err(StudyError::from)?;
        if self.json {
            print_json(&comparison);
            return Ok(ExitCode::SUCCESS);
        }
        println!("Thesis vs this model (`servo thesis`):");
        print!("{}", thesis::markdown(&comparison));
        print_written(&written);
        Ok(ExitCode::SUCCESS)
    }
}
